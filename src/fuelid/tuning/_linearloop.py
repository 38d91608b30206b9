"""The PLC's sampled PI on the process model: the fast, exact, linear closed loop.

The sampled closed loop is a rational filter at the control instants (exact zero-order hold and
fractional delay, :mod:`fuelid.lti`); the output between the instants is computed on a finer grid
with the same held command, so overshoot between samples is not missed. No limits: this is the
fast path of the checks over fuel temperature and of the uncertainty sweep
(docs/explanation/tuning.md, section 6).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from fuelid.lti import discretise, modified_z
from fuelid.model import ProcessModel
from fuelid.tuning._metrics import (
    SETTLING_BAND,
    StepMetrics,
    disturbance_metrics,
    setpoint_step_metrics,
)
from fuelid.tuning._rules import PISettings

if TYPE_CHECKING:
    from fuelid.tuning._frequency import StateSpacePlant

FloatArray = NDArray[np.float64]
CONTINUOUS_PERIOD = 0.02
"""Period [s] at which a continuous controller (control period 0) is simulated."""


@dataclass(frozen=True)
class LinearResponse:
    """Unit setpoint step and unit input-disturbance step of the linear closed loop."""

    time: FloatArray
    """Times [s] (a fine grid, between the control instants too)."""
    setpoint_response: FloatArray
    """Output after a unit setpoint step at t = 0 [output unit]."""
    setpoint_command: FloatArray
    """Controller output (held) for the setpoint step [input unit]."""
    disturbance_response: FloatArray
    """Output deviation after a unit step at the plant input at t = 0."""
    setpoint: StepMetrics
    disturbance: StepMetrics


MAX_LINEAR_STEPS = 50_000
"""Most control periods the linear closed loop is simulated for."""


def _loop_time_scale(model: ProcessModel, pi: PISettings) -> float:
    """Ti, or the closed loop's time constant Ti/(K·Kc) when the loop is detuned below that."""
    return max(pi.Ti, pi.Ti / (abs(model.K) * pi.Kc))


def linear_period(model: ProcessModel, pi: PISettings) -> float:
    """Step [s] of the linear closed loop.

    The control period; for a continuous controller 0.02 s, coarser for a slow loop so that its
    delay and lags span at most about 500 steps.
    """
    if pi.control_period > 0.0:
        return pi.control_period
    scale = model.delay + sum(model.time_constants) + _loop_time_scale(model, pi)
    return max(CONTINUOUS_PERIOD, scale / 500.0)


def step_duration(model: ProcessModel, pi: PISettings) -> float:
    """How long the closed loop's steps are simulated [s]: ten of its slowest times, and more."""
    scale = _loop_time_scale(model, pi) + model.delay + sum(model.time_constants)
    return 10.0 * scale + 20.0 * linear_period(model, pi)


def _closed_loop_polynomials(
    model: ProcessModel, pi: PISettings, h: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """(r→u numerator, d→u numerator, characteristic polynomial, plant b, plant a) in z⁻¹."""
    d = discretise(model.time_constants, model.delay, h)
    gn = np.concatenate((np.zeros(d.shift), model.K * d.b))
    r_to_u, d_to_u, char = _loop_polynomials(gn, d.a, pi, h)
    return r_to_u, d_to_u, char, d.b, d.a


def _loop_polynomials(
    gn: FloatArray, gd: FloatArray, pi: PISettings, h: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(r→u numerator, d→u numerator, characteristic polynomial) in z⁻¹: the PI on gn/gd.

    The plant gn/gd is sampled at the PI's period h, in z⁻¹, the delay's whole samples in gn.
    """
    cn = np.array(pi.velocity_coefficients(h))
    cd = np.array([1.0, -1.0])
    n = max(gn.size, gd.size) + 1
    char = np.zeros(n)
    a1 = np.convolve(cd, gd)
    a2 = np.convolve(cn, gn)
    char[: a1.size] += a1
    char[: a2.size] += a2
    # u = C·S·r and, for a load d at the plant input, u = −C·G·S·d
    r_to_u = np.convolve(cn, gd)
    d_to_u = -np.convolve(cn, gn)
    return r_to_u, d_to_u, char


def input_sensitivity(model: ProcessModel, pi: PISettings) -> tuple[FloatArray, FloatArray]:
    """S = 1/(1 + C·G) at the PLC's control instants: (numerator, denominator) in z⁻¹.

    The plant input's response to a signal added to the PI's output (the PI sees the flow, not
    the signal: u = C·(r − y) + s, y = G·u, so u = S·s). Exact ZOH and fractional delay, as
    :func:`linear_closed_loop`; the denominator is the loop's characteristic polynomial.

    Raises
    ------
    FuelidError
        If the PI is continuous (``control_period`` 0): the signal is held per control period.

    Examples
    --------
    The PI's integral rejects a constant signal: S(1) = 0.

    >>> from fuelid.tuning import simc
    >>> model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    >>> num, den = input_sensitivity(model, simc(model, control_period=1.0))
    >>> round(float(np.sum(num) / np.sum(den)), 12)
    0.0
    """
    from fuelid.errors import FuelidError

    if not pi.control_period > 0.0:
        raise FuelidError("a signal added to the PI's output needs the PLC's control period")
    h = pi.control_period
    d = discretise(model.time_constants, model.delay, h)
    gn = np.concatenate((np.zeros(d.shift), model.K * d.b))
    _, _, char = _loop_polynomials(gn, d.a, pi, h)
    return np.convolve([1.0, -1.0], d.a), char


def linear_closed_loop(
    model: ProcessModel, pi: PISettings, duration: float | None = None, oversample: int = 10
) -> LinearResponse:
    """Setpoint and load-disturbance step responses of PI ``pi`` on the process ``model``.

    The controller output follows from the closed loop at the control instants (exact ZOH,
    fractional delay included); the plant output is then computed on a grid ``oversample`` times
    finer with the same held command, so overshoot between samples is not missed. A continuous
    controller is simulated at 0.02 s (coarser for a slow loop, :func:`linear_period`).

    Examples
    --------
    >>> from fuelid.tuning import simc
    >>> model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    >>> res = linear_closed_loop(model, simc(model, control_period=1.0))
    >>> 0.0 <= res.setpoint.overshoot_percent < 20.0 and res.setpoint.settling_time < 15.0
    True
    """
    h = linear_period(model, pi)
    if duration is None:
        duration = step_duration(model, pi)
    n = min(max(math.ceil(duration / h), 4), MAX_LINEAR_STEPS)
    r_to_u, d_to_u, char, _, _ = _closed_loop_polynomials(model, pi, h)
    ones = np.ones(n)
    u_r = scipy.signal.lfilter(r_to_u, char, ones)
    u_d = scipy.signal.lfilter(d_to_u, char, ones)
    m = oversample if pi.control_period > 0.0 else 1
    fine = discretise(model.time_constants, model.delay, h / m)
    t = np.arange(n * m, dtype=np.float64) * (h / m)
    y_r = model.K * fine.response(np.repeat(u_r, m))
    y_d = model.K * fine.response(np.repeat(u_d, m) + 1.0)
    return _response(t, np.repeat(u_r, m), y_r, y_d, abs(model.K))


def _response(
    t: FloatArray, command: FloatArray, y_r: FloatArray, y_d: FloatArray, gain: float
) -> LinearResponse:
    """The steps with their metrics; ``gain`` the plant's static gain [output per input unit]."""
    return LinearResponse(
        time=t,
        setpoint_response=y_r,
        setpoint_command=command,
        disturbance_response=y_d,
        setpoint=setpoint_step_metrics(t, y_r, 0.0, 1.0),
        # recovered: within 2 % of what the unit load would do to the output without control
        disturbance=disturbance_metrics(t, y_d, 0.0, 1.0, band=SETTLING_BAND * gain),
    )


def sampled_plant(plant: StateSpacePlant, h: float) -> tuple[FloatArray, FloatArray]:
    """(numerator, denominator) in z⁻¹ of a state-space plant with dead time under a ZOH at h.

    The modified z-transform (:func:`fuelid.lti.modified_z`): x[k+1] = A_d·x[k] + Γ₀·u[k−d]
    + Γ₁·u[k−d−1], y = C·x, so Y/U = z^(−d)·C(zI − A_d)⁻¹(Γ₀ + Γ₁z⁻¹); strictly proper (no
    feedthrough D, which no plant here has).
    """
    A = np.asarray(plant.A, dtype=float)
    C = np.asarray(plant.C, dtype=float).reshape(1, -1)
    mz = modified_z(A, np.asarray(plant.B, dtype=float), h, plant.delay)
    zero = np.zeros((1, 1))
    num0, den = scipy.signal.ss2tf(mz.Ad, mz.G0, C, zero)
    num1, _ = scipy.signal.ss2tf(mz.Ad, mz.G1, C, zero)
    # degree-n polynomials in z over z^n are the same coefficients in z⁻¹; Γ₁ is one sample later
    numerator = np.r_[num0[0], 0.0] + np.r_[0.0, num1[0]]
    return np.r_[np.zeros(mz.shift), numerator], np.asarray(den, dtype=float)


def full_order_closed_loop(
    plant: StateSpacePlant, pi: PISettings, duration: float, oversample: int = 10
) -> LinearResponse:
    """The unit setpoint and load steps of ``pi`` on a state-space plant with dead time.

    As :func:`linear_closed_loop`, on the full linearisation (a
    :class:`~fuelid.plant._linear.LinearPlant`, a model file's ``linear_model``) instead of its
    reduction: the overshoot beside the Ms computed on the same plant. ``duration`` [s].
    """
    h = pi.control_period if pi.control_period > 0.0 else CONTINUOUS_PERIOD
    n = min(max(math.ceil(duration / h), 4), MAX_LINEAR_STEPS)
    gn, gd = sampled_plant(plant, h)
    r_to_u, d_to_u, char = _loop_polynomials(gn, gd, pi, h)
    ones = np.ones(n)
    u_r = scipy.signal.lfilter(r_to_u, char, ones)
    u_d = scipy.signal.lfilter(d_to_u, char, ones)
    m = oversample if pi.control_period > 0.0 else 1
    fine_n, fine_d = sampled_plant(plant, h / m)
    t = np.arange(n * m, dtype=np.float64) * (h / m)
    y_r = scipy.signal.lfilter(fine_n, fine_d, np.repeat(u_r, m))
    y_d = scipy.signal.lfilter(fine_n, fine_d, np.repeat(u_d, m) + 1.0)
    return _response(t, np.repeat(u_r, m), y_r, y_d, abs(float(np.sum(gn) / np.sum(gd))))


MisfitFunction = Callable[[FloatArray], tuple[NDArray[np.complex128], FloatArray]]
"""ω [rad/s] → (Δ̂(jω), its radius): a model's relative error (fuelid.identify._misfit)."""


def misfit_overshoot(
    model: ProcessModel,
    pi: PISettings,
    misfit: MisfitFunction,
    up_to: float,
    gain_scale: float = 1.0,
) -> float | None:
    """The setpoint overshoot [%] of the sampled PI on the loop G·(1 + Δ̂), at the control instants.

    Δ̂(jω) is the model's error the log shows (its point estimate, up to ``up_to`` [rad/s], none
    beyond), ``gain_scale`` a factor on the model's gain (a command band's). The closed loop's
    frequency response at the instants, T = L/(1 + L) with L = C(e^(jωh))·G_zoh·(1 + Δ̂)·scale,
    is turned into its step response by an inverse FFT over at least twice the step's duration
    (its impulse response has decayed by then: no time aliasing). None for a continuous PI.

    Examples
    --------
    No error: the model's own overshoot at the instants (the worked SIMC example, h = 1 s).

    >>> from fuelid.tuning import simc
    >>> model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    >>> pi = simc(model, control_period=1.0)
    >>> none = lambda w: (0j * w, 0.0 * w)
    >>> a = misfit_overshoot(model, pi, none, 10.0)
    >>> b = linear_closed_loop(model, pi, oversample=1).setpoint.overshoot_percent
    >>> abs(a - b) < 0.01
    True
    """
    from fuelid.tuning._frequency import controller_response, process_response

    h = pi.control_period
    if not h > 0.0:
        return None
    n = 2 ** math.ceil(math.log2(max(1024.0, 2.0 * step_duration(model, pi) / h)))
    w = 2.0 * math.pi * np.arange(1, n // 2 + 1) / (n * h)
    delta, _ = misfit(w)
    plant = process_response(model, w, h) * gain_scale * (1.0 + np.where(w <= up_to, delta, 0.0))
    loop = controller_response(pi, w) * plant
    # the integrator makes L infinite at ω = 0: the closed loop passes the step exactly there
    closed = np.concatenate([[1.0], loop / (1.0 + loop)])
    step = np.cumsum(np.fft.irfft(closed, n))
    return 100.0 * max(float(np.max(step)) - 1.0, 0.0)


def closed_loop_poles(model: ProcessModel, pi: PISettings) -> FloatArray:
    """Magnitudes of the closed-loop poles at the control instants (all < 1 when stable)."""
    h = linear_period(model, pi)
    char = _closed_loop_polynomials(model, pi, h)[2]
    return np.asarray(np.abs(np.roots(np.trim_zeros(char, "b"))), dtype=np.float64)
