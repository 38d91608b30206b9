"""A test signal designed from the loop's own model: the smallest that lets a window identify.

The signal s is added to the PI's output by the PLC (``[write.excitation]``) and held over each
control period h. In closed loop the PI answers it: the plant's input moves by u_s = S·s, S =
1/(1 + C·G) the input sensitivity at the control instants
(:func:`fuelid.tuning._linearloop.input_sensitivity`), and the flow by y_s = G·u_s. The PI's
integral cancels a slow signal (S(1) = 0), so what reaches the flow is band-pass.

**Information.** The window's estimator in AUTO is the direct prediction-error method: it
predicts the flow from the measured command, ŷ = G(p)·u. The signal's part of u is u_s, so the
sensitivity of the prediction to a parameter p is J_p = (∂G/∂p)·u_s, on the samples' grid
(``period_s``). With the output noise v = H·e (H = 1/A(q), the autoregressive model of the
window's residuals, :func:`fuelid.identify._covariance.residual_ar`) the Fisher information of the
free parameters is I = (A·J)ᵀ(A·J)/σ_e² (Ljung 1999, §9.4: Cov p̂ ≈ I⁻¹ for the prediction-error
estimate with the right noise model). The free parameters are those the window fits: K, T, T2
when the model has it, the dead time unless the plant file fixes it, and the output offset. The
loop's own noise also moves u (through the PI) and adds a little information; the design does
not count it, so its standard errors are upper bounds of what the signal alone gives.

Everything scales with the amplitude a: I ∝ a², se(K) ∝ 1/a, the added flow variance ∝ a². The
smallest amplitude that meets a window's gates is therefore

- se(K)/|K| ≤ m·``max_rel_stderr_K`` and se(T)/T ≤ m·``max_rel_stderr_T`` (m =
  :data:`DESIGN_MARGIN`: the bounds are met by the expected errors with room for a window's own
  scatter);
- the validation fit ≥ ``min_fit_percent`` + :data:`FIT_MARGIN_PERCENT`: the window's fit is the
  free-run simulation's, 100·(1 − σ_v/σ_y), so the flow's variance over the window must reach
  (σ_v/(1 − fit))²; it is the quiet loop's flow variance plus a²·mean(y_s²).

**The sequence.** A generalized binary noise (GBN, Tulleken 1990): ±a held per control period,
switching with probability h/T_sw at each period, so its mean hold is T_sw. It runs in a burst of
``burst_s`` at the start of the window and is zero after it. For each candidate T_sw
(:data:`HOLD_MULTIPLES` of h) the design computes, for that very (seeded) sequence, the unit
amplitude's information and added flow variance, then the amplitude each gate needs; it keeps the
T_sw whose needed amplitude adds the least flow variance. A fast sequence is rejected by the
loop's own filtering (little of it reaches the flow), a slow one by the PI's integral and it
correlates K with T (a step's information is mostly in its settled value): the best hold sits
near the closed loop's bandwidth, and the design finds it by computing rather than by rule.

**Cost**, stated before a signal starts: the added flow standard deviation over the window
(√mean(a²·y_s²)) [L/min] and the IAE the signal adds per window, Σ|a·y_s|·Δt [(L/min)·s], on
the model in closed loop with the gains in force.

References
----------
L. Ljung, *System Identification: Theory for the User* (2nd ed., 1999), §9.4 (asymptotic
covariance), §13.4 (closed-loop identification), §14 (experiment design). H. J. A. F. Tulleken,
"Generalized binary noise test-signal concept for improved identification-experiment design",
*Automatica* 26 (1990) 37–49.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import FuelidError
from fuelid.identify import ResidualAR, residual_ar
from fuelid.lti import discretise
from fuelid.model import ProcessModel
from fuelid.tuning import PISettings, input_sensitivity

FloatArray = NDArray[np.float64]

DESIGN_MARGIN = 0.8
"""The design aims the expected standard errors at this share of the gates' bounds [-]."""
FIT_MARGIN_PERCENT = 2.0
"""The design aims the expected validation fit this far above ``min_fit_percent`` [%]."""
HOLD_MULTIPLES = (2, 3, 5, 8, 13, 21, 34, 55, 89)
"""Candidate mean holds T_sw of the GBN, in control periods (2: a random binary sequence)."""
MIN_HOLDS_PER_BURST = 2.0
"""A candidate hold is tried only when the burst is this many holds long [-]."""
SEEDS_PER_HOLD = 6
"""Sequences tried per hold: a short burst of long holds is a few switches, and which few
matters (the best of these is kept, its seed stored)."""
RELATIVE_STEP = 1e-4
"""Relative step of the central differences of the lags' sensitivities [-]."""
Bound = Literal["K", "T", "fit", "amplitude"]


@dataclass(frozen=True)
class DesignGoal:
    """What the next window must show: the ``[online]`` gates the design aims under."""

    max_rel_stderr_K: float = 0.05
    max_rel_stderr_T: float = 0.2
    min_fit_percent: float = 80.0

    @classmethod
    def of(cls, online: Any) -> DesignGoal:
        """The goal of an ``[online]`` table (:class:`fuelid.online._settings.Online`)."""
        return cls(online.max_rel_stderr_K, online.max_rel_stderr_T, online.min_fit_percent)


@dataclass(frozen=True)
class LoopNoise:
    """The quiet loop's noise, as the window's estimator will meet it.

    Parameters
    ----------
    ar : ResidualAR
        The autoregressive model A(q)·v = e of the output noise v [L/min] at ``period_s``
        (:func:`fuelid.identify._covariance.residual_ar` of a window's output errors).
    sd : float
        σ_v, the output noise's standard deviation about the model [L/min].
    flow_sd : float
        σ_y, the flow's standard deviation over a quiet window [L/min] (in closed loop the PI's
        answer to the noise; about σ_v for a slow loop and white meter noise).
    """

    ar: ResidualAR
    sd: float
    flow_sd: float

    @classmethod
    def white(cls, sd: float) -> LoopNoise:
        """White output noise of standard deviation ``sd`` [L/min] (the flow's the same)."""
        return cls(ResidualAR(np.array([1.0]), float(sd), {0: 0.0}), float(sd), float(sd))

    @classmethod
    def of_window(
        cls,
        model: ProcessModel,
        u: ArrayLike,
        y: ArrayLike,
        setpoint: ArrayLike,
        period_s: float,
    ) -> LoopNoise:
        """Measured on a window's longest stretch of finite samples.

        The output noise is what the model leaves of the flow, v = y − G·(u − u₀) − its mean;
        the flow's spread is that of the control error y − setpoint (of y where no setpoint
        is recorded).

        Parameters
        ----------
        model : ProcessModel
            The current model.
        u, y, setpoint : array
            Command [V], flow and setpoint [L/min], one per sample (NaN where bad).
        period_s : float
            The samples' period [s].

        Raises
        ------
        FuelidError
            With fewer than :data:`MIN_NOISE_SAMPLES` finite samples in a row.
        """
        uu, yy = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
        sp = np.asarray(setpoint, dtype=float)
        start, stop = _longest_finite(uu, yy)
        if stop - start < MIN_NOISE_SAMPLES:
            raise FuelidError(
                f"too few samples in a row to measure the noise ({stop - start} < "
                f"{MIN_NOISE_SAMPLES})"
            )
        uu, yy, sp = uu[start:stop], yy[start:stop], sp[start:stop]
        v = yy - _response(model, uu - uu[0], period_s)
        v = v - np.mean(v)
        error = yy - sp if np.all(np.isfinite(sp)) else yy - np.mean(yy)
        return cls(residual_ar(v), float(np.std(v)), float(np.std(error - np.mean(error))))


MIN_NOISE_SAMPLES = 500
"""Fewest samples in a row the noise is measured on (10 s at 50 Hz) [-]."""


def _longest_finite(u: FloatArray, y: FloatArray) -> tuple[int, int]:
    """[start, stop) of the longest run of samples with finite u and y."""
    good = np.r_[False, np.isfinite(u) & np.isfinite(y), False]
    edges = np.flatnonzero(np.diff(good.astype(np.int8)))
    if edges.size == 0:
        return 0, 0
    starts, stops = edges[::2], edges[1::2]
    best = int(np.argmax(stops - starts))
    return int(starts[best]), int(stops[best])


@dataclass(frozen=True)
class SignalDesign:
    """A designed test signal, with what it is expected to give and to cost."""

    kind: str
    """"gbn" (designed) or "prbs" (a maximum-length sequence, for comparison)."""
    amplitude_V: float
    """±a, the signal's level [V]."""
    hold_s: float
    """Mean hold T_sw [s] (the PRBS's clock)."""
    control_period_s: float
    """h [s]: the signal changes at the PLC's scans only."""
    burst_s: float
    """How long the signal runs [s], from the start of a window."""
    window_s: float
    """The window it is designed for [s]."""
    seed: int
    """The GBN's seed: the sequence is reproducible from the design."""
    levels: FloatArray = field(repr=False)
    """±1 per control period over the burst: the signal is ``amplitude_V·levels``."""
    expected_rel_stderr: dict[str, float]
    """Expected relative standard error by parameter ("K", "T") at this amplitude [-]."""
    expected_fit_percent: float
    """Expected validation fit of the window [%]."""
    added_flow_sd_Lpm: float
    """√mean of the flow the signal adds, over the window [L/min]."""
    iae_per_window: float
    """Σ|added flow|·Δt over the window [(L/min)·s]."""
    needed_V: dict[str, float]
    """The amplitude each gate needs ("K", "T", "fit") [V]."""
    bound: Bound
    """What set the amplitude: a gate, or the site's ``amplitude`` cap."""

    @property
    def reaches_goal(self) -> bool:
        """True when the amplitude meets every gate (it was not capped below one)."""
        return self.bound != "amplitude"

    def values(self) -> FloatArray:
        """The signal per control period over the burst [V]."""
        return self.amplitude_V * self.levels

    def to_json(self) -> dict[str, Any]:
        """The design as stored with its events (the sequence by its seed, not its values)."""
        return {
            "kind": self.kind,
            "amplitude_V": self.amplitude_V,
            "hold_s": self.hold_s,
            "control_period_s": self.control_period_s,
            "burst_s": self.burst_s,
            "window_s": self.window_s,
            "seed": self.seed,
            "periods": int(self.levels.size),
            "expected_rel_stderr": dict(self.expected_rel_stderr),
            "expected_fit_percent": self.expected_fit_percent,
            "added_flow_sd_Lpm": self.added_flow_sd_Lpm,
            "iae_per_window": self.iae_per_window,
            "needed_V": dict(self.needed_V),
            "bound": self.bound,
        }


@dataclass(frozen=True)
class UnitResponse:
    """What a sequence does at unit amplitude over one window (the design's raw numbers)."""

    rel_stderr: dict[str, float]
    """Relative standard errors at 1 V [-] (they scale as 1/a)."""
    added_variance: float
    """mean(y_s²) over the window at 1 V [(L/min)²] (scales as a²)."""
    iae: float
    """Σ|y_s|·Δt over the window at 1 V [(L/min)·s] (scales as a)."""


def gbn_levels(periods: int, hold_periods: float, seed: int) -> FloatArray:
    """A generalized binary noise: ±1 per period, switching with probability 1/hold each period.

    A hold of 2 (the shortest) is a random binary sequence, white at the period.

    Examples
    --------
    >>> x = gbn_levels(10_000, 5.0, seed=1)
    >>> sorted(set(x.tolist())), round(float(np.mean(x[1:] != x[:-1])), 2)
    ([-1.0, 1.0], 0.2)
    """
    rng = np.random.default_rng(seed)
    switches = rng.random(periods) < 1.0 / max(hold_periods, 2.0)
    switches[0] = False
    sign = 1.0 if rng.random() < 0.5 else -1.0
    return sign * np.where(np.cumsum(switches) % 2 == 0, 1.0, -1.0)


def prbs_levels(periods: int, clock_periods: int = 1) -> FloatArray:
    """A maximum-length binary sequence, ±1, each bit held ``clock_periods`` periods.

    The shortest register whose period covers the burst (scipy.signal.max_len_seq).

    Examples
    --------
    >>> x = prbs_levels(31)
    >>> x.size, int(np.sum(x))
    (31, 1)
    """
    bits = math.ceil(periods / clock_periods)
    nbits = max(2, math.ceil(math.log2(bits + 1)))
    sequence, _ = scipy.signal.max_len_seq(nbits, length=bits)
    levels = 2.0 * sequence.astype(float) - 1.0
    return np.repeat(levels, clock_periods)[:periods]


def _free_parameters(model: ProcessModel, delay_free: bool) -> list[str]:
    names = ["K", "T"] + (["T2"] if model.T2 > 0.0 else [])
    return names + (["delay"] if delay_free else [])


def _response(model: ProcessModel, u: FloatArray, period_s: float) -> FloatArray:
    """The model's flow deviation for the input deviation ``u`` on the samples' grid [L/min]."""
    lags = discretise(model.time_constants, model.delay, period_s)
    return model.K * lags.response(u)


def _sensitivities(
    model: ProcessModel, u: FloatArray, period_s: float, names: list[str]
) -> tuple[FloatArray, FloatArray]:
    """(y_s, J): the flow for ``u`` and ∂ŷ/∂p for each name, then the offset's column."""
    y = _response(model, u, period_s)
    columns = []
    for name in names:
        if name == "K":
            columns.append(y / model.K)
            continue
        value = getattr(model, name)
        step = max(RELATIVE_STEP * value, period_s * 1e-3)
        up = _response(_with(model, name, value + step), u, period_s)
        down = _response(_with(model, name, max(value - step, 0.0)), u, period_s)
        columns.append((up - down) / (value + step - max(value - step, 0.0)))
    columns.append(np.ones_like(y))
    return y, np.column_stack(columns)


def _with(model: ProcessModel, name: str, value: float) -> ProcessModel:
    fields = {k: getattr(model, k) for k in ("K", "T", "T2", "T_f", "delay")}
    fields[name] = value
    return ProcessModel(**fields)


def unit_response(
    model: ProcessModel,
    pi: PISettings,
    levels: ArrayLike,
    noise: LoopNoise,
    *,
    period_s: float,
    window_s: float,
    delay_free: bool = True,
) -> UnitResponse:
    """The information and the added flow of a ±1 V sequence over one window.

    Parameters
    ----------
    model : ProcessModel
        The current model of the loop (K [(L/min)/V], lags and dead time [s]).
    pi : PISettings
        The gains in force (ideal form, Kc [V per L/min], Ti [s], the PLC's period h [s]).
    levels : array
        The signal per control period [V] (here ±1), from the start of the window.
    noise : LoopNoise
        The quiet loop's noise.
    period_s : float
        The samples' period [s] (a whole fraction of h).
    window_s : float
        The window [s].
    delay_free : bool
        The window estimates the dead time (False: the plant file fixes it).
    """
    h = pi.control_period
    per = round(h / period_s)
    periods = math.ceil(window_s / h)
    s = np.zeros(periods)
    given = np.asarray(levels, dtype=float)[:periods]
    s[: given.size] = given
    num, den = input_sensitivity(model, pi)
    if np.any(np.abs(np.roots(den)) >= 1.0):
        raise FuelidError("the loop with the gains in force is unstable on the model: no signal")
    u = np.repeat(scipy.signal.lfilter(num, den, s), per)[: round(window_s / period_s)]
    names = _free_parameters(model, delay_free)
    y, J = _sensitivities(model, u, period_s, names)
    white = scipy.signal.lfilter(noise.ar.a, [1.0], J, axis=0)
    information = white.T @ white / noise.ar.sigma_e**2
    try:
        covariance = np.linalg.inv(information)
    except np.linalg.LinAlgError:
        covariance = np.full_like(information, np.inf)
    se = np.sqrt(np.clip(np.diag(covariance), 0.0, np.inf))
    rel = {
        name: float(se[i] / abs(getattr(model, name)))
        for i, name in enumerate(names)
        if name in ("K", "T")
    }
    return UnitResponse(rel, float(np.mean(y * y)), float(np.sum(np.abs(y)) * period_s))


def needed_amplitudes(unit: UnitResponse, noise: LoopNoise, goal: DesignGoal) -> dict[str, float]:
    """The smallest amplitude each gate needs [V] (inf when none reaches it).

    Examples
    --------
    >>> unit = UnitResponse({"K": 0.01, "T": 0.02}, added_variance=4.0, iae=0.0)
    >>> need = needed_amplitudes(unit, LoopNoise.white(0.1), DesignGoal())
    >>> round(need["K"], 3), round(need["T"], 3)
    (0.25, 0.125)
    """
    need = {
        name: unit.rel_stderr[name] / (DESIGN_MARGIN * bound)
        for name, bound in (("K", goal.max_rel_stderr_K), ("T", goal.max_rel_stderr_T))
    }
    fit = min(goal.min_fit_percent + FIT_MARGIN_PERCENT, 99.0) / 100.0
    wanted = (noise.sd / (1.0 - fit)) ** 2  # the flow's variance the fit needs
    missing = max(wanted - noise.flow_sd**2, 0.0)
    need["fit"] = math.sqrt(missing / unit.added_variance) if unit.added_variance > 0 else math.inf
    return need


@dataclass(frozen=True)
class _Experiment:
    """One loop, noise and window: the design's fixed inputs, against which sequences are tried."""

    model: ProcessModel
    pi: PISettings
    noise: LoopNoise
    goal: DesignGoal
    period_s: float
    window_s: float
    delay_free: bool

    def design(
        self, kind: str, levels: FloatArray, hold_s: float, seed: int, cap_V: float
    ) -> SignalDesign:
        """The sequence ``levels`` at the smallest amplitude meeting every gate, capped."""
        unit = unit_response(
            self.model, self.pi, levels, self.noise, period_s=self.period_s,
            window_s=self.window_s, delay_free=self.delay_free,
        )  # fmt: skip
        need = needed_amplitudes(unit, self.noise, self.goal)
        bound = cast(Bound, max(need, key=need.__getitem__))
        amplitude = need[bound]
        if not amplitude <= cap_V:
            amplitude, bound = cap_V, "amplitude"
        variance = self.noise.flow_sd**2 + amplitude**2 * unit.added_variance
        fit = 100.0 * (1.0 - self.noise.sd / math.sqrt(variance)) if variance > 0 else 0.0
        h = self.pi.control_period
        return SignalDesign(
            kind=kind,
            amplitude_V=float(amplitude),
            hold_s=hold_s,
            control_period_s=h,
            burst_s=levels.size * h,
            window_s=self.window_s,
            seed=seed,
            levels=levels,
            expected_rel_stderr={k: v / amplitude for k, v in unit.rel_stderr.items()},
            expected_fit_percent=fit,
            added_flow_sd_Lpm=amplitude * math.sqrt(unit.added_variance),
            iae_per_window=amplitude * unit.iae,
            needed_V=dict(need),
            bound=bound,
        )


def design_signal(
    model: ProcessModel,
    pi: PISettings,
    noise: LoopNoise,
    goal: DesignGoal,
    *,
    amplitude_cap_V: float,
    period_s: float,
    window_s: float,
    burst_s: float,
    delay_free: bool = True,
    seed: int = 0,
) -> SignalDesign:
    """The GBN test signal that meets the next window's gates at the least added flow variance.

    Parameters
    ----------
    model : ProcessModel
        The current model of the loop.
    pi : PISettings
        The gains in force, with the PLC's control period h [s].
    noise : LoopNoise
        The quiet loop's noise.
    goal : DesignGoal
        The window's gates (``[online]``).
    amplitude_cap_V : float
        The largest amplitude allowed (``[excitation] amplitude``) [V].
    period_s : float
        The samples' period [s].
    window_s : float
        The identification window [s].
    burst_s : float
        How long the signal may run in the window [s] (``max_share × window_s``).
    delay_free : bool
        Whether the window estimates the dead time.
    seed : int
        The GBN's seed.

    Returns
    -------
    SignalDesign
        Capped at ``amplitude_cap_V`` when a gate needs more (``bound`` "amplitude").

    Raises
    ------
    FuelidError
        If the loop is unstable on the model, or the burst is shorter than a few control
        periods.
    """
    h = pi.control_period
    periods = int(burst_s // h)
    if periods < MIN_HOLDS_PER_BURST * HOLD_MULTIPLES[0]:
        raise FuelidError(f"a burst of {burst_s:g} s holds fewer than four control periods")
    experiment = _Experiment(model, pi, noise, goal, period_s, window_s, delay_free)
    best: SignalDesign | None = None
    for multiple in HOLD_MULTIPLES:
        if periods < MIN_HOLDS_PER_BURST * multiple:
            break
        for candidate_seed in range(seed, seed + SEEDS_PER_HOLD):
            levels = gbn_levels(periods, multiple, candidate_seed)
            candidate = experiment.design(
                "gbn", levels, multiple * h, candidate_seed, amplitude_cap_V
            )
            if best is None or _cost(candidate) < _cost(best):
                best = candidate
    assert best is not None  # the shortest hold is always tried
    return best


def _cost(design: SignalDesign) -> tuple[bool, float, float]:
    """Order of preference: meets the gates, then the least added flow variance, then K's error.

    The flow's spread is compared to three digits: when the validation fit sets the amplitude
    every sequence adds the same variance, and the one that determines K best is kept.
    """
    rel_K = max(design.expected_rel_stderr.get("K", math.inf), 0.0)
    if design.reaches_goal:
        return (False, float(f"{design.added_flow_sd_Lpm:.3g}"), rel_K)
    return (True, rel_K, design.added_flow_sd_Lpm)


def prbs_design(
    model: ProcessModel,
    pi: PISettings,
    noise: LoopNoise,
    goal: DesignGoal,
    *,
    period_s: float,
    window_s: float,
    burst_s: float,
    delay_free: bool = True,
    clock_periods: int = 1,
) -> SignalDesign:
    """A PRBS of the same burst at the smallest amplitude that meets the same gates (uncapped).

    The comparison of ``benchmarks/bench_excitation.py``: a maximum-length sequence clocked at
    the control period, the usual default of a test signal.
    """
    h = pi.control_period
    periods = int(burst_s // h)
    levels = prbs_levels(periods, clock_periods)
    experiment = _Experiment(model, pi, noise, goal, period_s, window_s, delay_free)
    return experiment.design("prbs", levels, clock_periods * h, 0, math.inf)
