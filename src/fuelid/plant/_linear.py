"""Linearisation of the plant about an operating point, and its reduction to the model family.

The full linear model has five states (drive lag, shaft, pump-outlet pressure, line flow,
flowmeter lag) plus the meter's dead time. It is reduced to the article's equivalent model

    G(s) = K·e^(−τs) / ((T·s + 1)(T_f·s + 1))

as follows: K is the exact static gain of the full model; T_f and τ are the flowmeter's
(calibration prior, taken from the config); T is the least-squares fit of the reduced model's unit
step response to the full model's on a uniform grid over three settling times. The fast motor and
hydraulic poles are thereby lumped into T. T2 = 0 (first-order process).

A plant without a meter lag (``flowmeter.time_constant_s = 0``) reads the line flow q directly;
its linear model drops the meter state and has four states, and its reduced model has T_f = 0.
See ``docs/explanation/physics.md`` §7.

python-control is imported only inside the methods that return or use its objects: importing it
takes about a second, which the command line should not pay for every plant it loads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from fuelid import lti
from fuelid.model import ProcessModel
from fuelid.plant._config import PlantConfig
from fuelid.plant._system import (
    STATE_NAMES,
    OperatingPoint,
    check_command,
    input_jacobian,
    measured_state,
    plant_coefficients,
    plant_jacobian,
    steady_state,
)
from fuelid.units import LPM_PER_M3S

if TYPE_CHECKING:
    import control

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class EquivalentModel:
    """The reduced model of a linearised plant and how well it matches."""

    model: ProcessModel
    """K [(L/min)/V], T [s], T2 = 0, T_f and delay [s] from the flowmeter prior."""
    settling_time: float
    """98 % settling time of the full linearised plant, delay included [s]."""
    model_settling_time: float
    """98 % settling time of the reduced model [s]."""
    fit_rms: float
    """RMS difference of the unit step responses over the fit window, relative to K [-]."""
    fit_window: float
    """Length of the window used for the least-squares fit of T [s]."""


@dataclass(frozen=True)
class LinearPlant:
    """Linearised plant from command u [V] to measured flow [L/min], dead time explicit.

    ``A, B, C, D`` act on deviations of the SI state named in ``states`` (``[f, ω_m, p, q, q_m]``,
    without ``q_m`` when the meter has no lag) from the operating point; ``C`` converts the
    measured flow to L/min, so ``B`` is per volt and gains come out in (L/min)/V.
    """

    A: FloatArray
    B: FloatArray
    C: FloatArray
    D: FloatArray
    delay: float
    operating_point: OperatingPoint
    states: tuple[str, ...] = STATE_NAMES
    """Names of the states, in the order of the rows of A."""

    def to_state_space(self) -> control.StateSpace:
        """Delay-free part as a :class:`control.StateSpace` (the dead time is ``.delay``)."""
        import control  # slow to import: only where its objects are wanted

        return control.ss(self.A, self.B, self.C, self.D)

    def to_control(self) -> control.TransferFunction:
        """Delay-free part as a :class:`control.TransferFunction` (the dead time is ``.delay``).

        The dead time is deliberately not Padé-approximated; apply
        ``control.pade(plant.delay, n)`` explicitly if a rational approximation is wanted.
        """
        import control

        tf = control.ss2tf(self.to_state_space())
        # ss2tf leaves rounding residue (~1e-13) in the numerator's high-order terms: drop it
        num = np.asarray(tf.num[0][0], dtype=float)
        num[np.abs(num) < 1e-9 * np.max(np.abs(num))] = 0.0
        return control.tf(np.trim_zeros(num, "f"), tf.den[0][0])

    @property
    def static_gain(self) -> float:
        """Exact static gain −C·A⁻¹·B + D [(L/min)/V].

        What :func:`control.dcgain` computes (a test checks they agree), solved with numpy here
        because importing python-control costs about 0.3 s and loads matplotlib, and every
        command that checks gains over fuel temperature calls this for each plant case.
        """
        x = np.linalg.solve(self.A, self.B)
        return float((self.D - self.C @ x)[0, 0])

    def step_response(self, t: FloatArray) -> FloatArray:
        """Response to a unit (1 V) step at t = 0, dead time included [L/min]."""
        return lti.step_response(self.A, self.B, self.C, float(self.D[0, 0]), t, self.delay)

    def settling_time(self, band: float = lti.SETTLING_BAND) -> float:
        """98 % (for ``band`` = 0.02) settling time of the step response, delay included [s]."""
        return lti.step_settling_time(self.A, self.B, self.C, float(self.D[0, 0]), self.delay, band)

    def equivalent_model(self, band: float = lti.SETTLING_BAND) -> EquivalentModel:
        """Reduce to K·e^(−τs)/((T·s+1)(T_f·s+1)) (see the module docstring for the method)."""
        K = self.static_gain
        settle = self.settling_time(band)
        window = 3.0 * settle
        t = np.arange(0.0, window, 0.01, dtype=np.float64)
        y_full = self.step_response(t)
        T_f = self._meter_lag()

        def model(T: float) -> ProcessModel:
            return ProcessModel(K=K, T=T, T_f=T_f, delay=self.delay)

        def cost(log_T: float) -> float:
            err = model(float(np.exp(log_T))).step_response(t) - y_full
            return float(err @ err)

        # search in log T: scale-free and keeps T positive
        best = scipy.optimize.minimize_scalar(
            cost,
            bounds=(np.log(1e-3), np.log(window)),
            method="bounded",
            options={"xatol": 1e-9},
        )
        reduced = model(float(np.exp(best.x)))
        rms = float(np.sqrt(best.fun / t.size)) / abs(K)
        return EquivalentModel(
            model=reduced,
            settling_time=settle,
            model_settling_time=reduced.settling_time(band),
            fit_rms=rms,
            fit_window=window,
        )

    def _meter_lag(self) -> float:
        """T_f [s] from the meter's row of A (−1/T_f); 0 without a meter state."""
        if "q_m" not in self.states:
            return 0.0
        i = self.states.index("q_m")
        a = -float(self.A[i, i])
        return 1.0 / a if a > 0.0 else 0.0


def linearise(config: PlantConfig, u: float, T_fuel: float) -> LinearPlant:
    """Linearise the plant about its steady state for command ``u`` and fuel temperature.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    u : float
        Command [V], inside the drive's signal range.
    T_fuel : float
        Fuel temperature [K].

    Returns
    -------
    LinearPlant
        From u [V] to measured flow [L/min], with the meter's dead time kept explicit. Without a
        meter lag (T_f = 0) the reading is the line flow and the meter state is left out, so that
        A stays non-singular.

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
    >>> lin = linearise(load_plant_config(), u=1.25, T_fuel=293.15)
    >>> lin.static_gain > 0 and lin.delay == load_plant_config().flowmeter.delay_s
    True
    """
    c = plant_coefficients(config, T_fuel)
    check_command(u, c)
    op = steady_state(u, c)
    A = plant_jacobian(0.0, op.state, u, c)
    B = input_jacobian(u, c)
    # without a meter lag the reading is q and q_m (the last state) is no dynamics at all: its
    # row and column of A are zero, so it is dropped
    states = STATE_NAMES if c.meter.T_f > 0.0 else STATE_NAMES[:-1]
    keep = len(states)
    C = np.zeros((1, keep))
    C[0, measured_state(c)] = LPM_PER_M3S
    return LinearPlant(
        A=A[:keep, :keep].copy(),
        B=B[:keep].copy(),
        C=C,
        D=np.zeros((1, 1)),
        delay=c.delay,
        operating_point=op,
        states=states,
    )
