"""The virtual PLC's commissioning gains: the PI set it starts with, from the plant it runs.

The virtual PLC clamps staged gains to 0.1–10 times these and restores them when the advisor's
heartbeat goes stale (``restore_on_stale``), as a PLC keeps its commissioned set.
"""

from __future__ import annotations

from fuelid.plant import PlantConfig, linearise
from fuelid.tuning import half_rule, simc

__all__ = ["commissioning_gains"]


def commissioning_gains(
    config: PlantConfig, T_fuel: float, control_period_s: float
) -> tuple[float, float]:
    """Cautious SIMC PI gains (τc = 2θ) for the plant linearised at mid-range command.

    A commissioning engineer's set: SIMC (Skogestad 2003) with the closed-loop time constant
    twice the effective dead time (the half rule's θ plus h/2), which keeps the overshoot of
    setpoint steps of the reference plant to a few percent (τc = θ gives about 15 % with the
    1 s control period) and leaves an online tuner room to tighten it.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    T_fuel : float
        Fuel temperature [K].
    control_period_s : float
        The PLC's control period h [s] (adds h/2 to the effective dead time).

    Returns
    -------
    tuple of float
        Kc [V per L/min] and Ti [s], ideal form. For the reference plant at 20 °C and h = 1 s:
        Kc ≈ 0.042 V per L/min, Ti ≈ 1.42 s.

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
    >>> kc, ti = commissioning_gains(load_plant_config(), 293.15, 1.0)
    >>> round(kc, 4), round(ti, 3)
    (0.0424, 1.418)
    """
    u_mid = 0.5 * (config.vfd.u_min_V + config.vfd.u_max_V)
    model = linearise(config, u_mid, T_fuel).equivalent_model().model
    theta = half_rule(model, control_period_s).theta
    pi = simc(model, control_period_s, tau_c=2.0 * theta)
    return pi.Kc, pi.Ti
