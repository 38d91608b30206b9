"""Turbine flowmeter: a first-order lag plus a pure delay, with noise and a resolution.

The lag is the rotor's inertia and the meter's filtering; the delay τ is the meter's gate or
processing time plus the PLC's scan and sampling. It is not a transport delay: in an
incompressible line a flow change travels at the speed of sound (about 0.1 s per 100 m).
The turbine's lag shrinks as the flow grows (roughly T_f ∝ 1/q), so a fixed T_f is right near
the operating point it was calibrated at. See ``docs/explanation/physics.md`` §3.7.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import Field

from fuelid.plant._section import Section


@dataclass(frozen=True, slots=True)
class FlowmeterCoefficients:
    """The meter's dynamics in SI (:meth:`FlowmeterConfig.coefficients`)."""

    T_f: float
    """First-order lag [s]; 0 for none (the reading is then the line flow itself)."""
    delay: float
    """Pure delay τ, meter plus PLC [s]."""


class FlowmeterConfig(Section):
    """Flowmeter as the PLC sees it (TOML section ``[flowmeter]``)."""

    time_constant_s: float = Field(ge=0.0, le=60.0, description="first-order lag T_f [s]")
    delay_s: float = Field(ge=0.0, le=60.0, description="pure delay τ, meter plus PLC [s]")
    span_Lpm: float = Field(gt=0.0, description="full-scale flow of the meter's output [L/min]")
    noise_std_Lpm: float = Field(
        0.0, ge=0.0, description="standard deviation of white measurement noise [L/min]"
    )
    resolution_Lpm: float = Field(
        0.0, ge=0.0, description="quantisation step of the value the PLC reads (0: none) [L/min]"
    )

    def coefficients(self) -> FlowmeterCoefficients:
        """The meter's lag and delay in SI."""
        return FlowmeterCoefficients(T_f=self.time_constant_s, delay=self.delay_s)


def flowmeter_rate(q: float, q_m: float, T_f: float) -> float:
    r"""Rate of change of the meter's lagged flow (first-order lag).

    .. math:: T_f\,\dot q_m = q - q_m

    Parameters
    ----------
    q : float
        Flow through the meter [m³/s].
    q_m : float
        The meter's lagged flow [m³/s].
    T_f : float
        Lag [s], zero or positive.

    Returns
    -------
    float
        dq_m/dt [m³/s²]; 0 when T_f = 0: without a lag the reading is q itself and q_m is not
        used (see :func:`fuelid.plant._system.measured_state`).

    References
    ----------
    ``docs/explanation/physics.md`` §3.7; Baker, R. C., *Flow Measurement Handbook*, 2nd ed.,
    Cambridge University Press 2016 (the chapter on turbine flowmeters).

    Examples
    --------
    >>> flowmeter_rate(1.0e-3, 0.5e-3, 0.5)
    0.001
    >>> flowmeter_rate(1.0e-3, 0.5e-3, 0.0)
    0.0
    """
    return (q - q_m) / T_f if T_f > 0.0 else 0.0


def flowmeter_rate_partials(T_f: float) -> tuple[float, float]:
    r"""Partial derivatives of :func:`flowmeter_rate` (constant).

    .. math:: \left(\frac{\partial \dot q_m}{\partial q},\
              \frac{\partial \dot q_m}{\partial q_m}\right)
              = \left(\frac{1}{T_f},\ -\frac{1}{T_f}\right), \qquad (0, 0) \text{ for } T_f = 0

    Parameters
    ----------
    T_f : float
        Lag [s].

    Returns
    -------
    tuple of float
        (∂q̇_m/∂q, ∂q̇_m/∂q_m) [1/s].

    Examples
    --------
    >>> flowmeter_rate_partials(0.5)
    (2.0, -2.0)
    """
    if T_f > 0.0:
        return (1.0 / T_f, -1.0 / T_f)
    return (0.0, 0.0)


def measure_flow(
    q_lagged: ArrayLike,
    noise_std: float = 0.0,
    resolution: float = 0.0,
    rng: np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """What the PLC reads: the lagged, delayed flow plus white noise, then quantised.

    Parameters
    ----------
    q_lagged : array
        Flow after the meter's lag and delay [any flow unit].
    noise_std : float
        Standard deviation of additive white Gaussian noise [same unit].
    resolution : float
        Quantisation step [same unit]; 0 for none. Quantisation comes after the noise, as in a
        real A/D chain.
    rng : numpy.random.Generator, optional
        Source of the noise (seed it for reproducible logs).

    Returns
    -------
    ndarray
        Measured flow [same unit].

    Examples
    --------
    >>> measure_flow([10.04, 10.06, 20.0], resolution=0.1).tolist()
    [10.0, 10.100000000000001, 20.0]
    """
    y = np.array(q_lagged, dtype=float)
    if noise_std > 0.0:
        generator = rng if rng is not None else np.random.default_rng()
        y = y + generator.normal(0.0, noise_std, size=y.shape)
    if resolution > 0.0:
        y = np.round(y / resolution) * resolution
    return y
