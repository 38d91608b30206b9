"""Long records (a day at 50 Hz): fitted on spread-out stretches, or searched there and polished.

The output-error fit's search (the coarse grid, the local searches from its best points, one per
structure) evaluates Σε² a few hundred times, and its covariance and residual tests pass over
the record a few dozen times more. On a day at 50 Hz (4.3 M samples, 0.1 s per evaluation)
the search alone is over a minute. For a record over :data:`LONG_RECORD` samples the fit
therefore works on a **copy** made of :data:`SEARCH_STRETCHES` stretches spread evenly over the
record (:func:`search_copy`, :data:`SEARCH_SAMPLES` samples in all, each stretch a segment with
its own initial state). What it does with the copy depends on ``full_record``:

- By default (``OutputError(full_record=False)``) the copy **is** the fitting record: the
  estimates, their standard errors (the copy's own covariance, the sandwich when its residuals
  call for it), the order choice (BIC on the copy) and the residual tests are the copy's, as
  for any record of :data:`SEARCH_SAMPLES` samples. The whole record is used only where it is
  cheap and says what the copy cannot: the fit % (the kept model simulated over every sample,
  K held, the offset and each segment's initial state fitted by least squares:
  :func:`whole_record_fit`) and the lead (causality) check. The statistics: the copy's
  estimator is the output-error estimator of its own samples, consistent, with its own
  Cramér–Rao-scale covariance; its standard errors are about √(N/n) times the whole record's
  (N samples, n in the copy: 6.6 for a day at 50 Hz), and they are the right ones for the
  estimates reported. What it assumes beyond a whole-record fit: the loop is the same over the
  day, so stretches spread evenly sample the day's operating points and fuel temperatures as
  the whole record does, and a slow drift is averaged as the whole-record fit averages it.
- With ``full_record=True`` the copy only **searches**, and the whole record **polishes** the
  copy's optimum (:func:`polish`): the printed estimates, standard errors, fit and tests are the
  whole record's (the behaviour before the copy fit became the default).

With ``full_record=True``, why the copy's optimum is a good enough start, and why the polish
ends at the whole record's optimum:

- The copy samples the same plant over the same day, so its optimum estimates the same
  parameters; its standard errors are about √(N/M) times the whole record's (N samples, M in
  the copy): 6.6 for a day at 50 Hz. Its optimum is therefore a few of the whole record's
  standard errors from the whole record's, and in absolute terms as close as a 30-minute log
  gets (0.5 % of T on the day of the benchmark), whatever N is. The basin of the optimum
  (the region where Gauss–Newton converges) is set by how nonlinear ŷ is in T, T2 and θ,
  tens of percent of T: the start is deep inside it.
- The polish is Gauss–Newton on the whole record from there, with the exact gradient of the
  variable-projection cost (−(∂Φβ/∂p)ᵀε at fixed β, Golub & Pereyra 1973) and Kaufman's
  approximation of the Hessian, so its fixed point is the whole record's stationary point, not
  the copy's. It stops when the next Gauss–Newton step is under :data:`POLISH_TOLERANCE` of a
  standard error (the white σ̂²(JᵀJ)⁻¹ one, the smallest this fit reports) in every parameter:
  what is left to gain then moves no printed digit of an estimate or of its standard error.
  Each step shrinks the distance to the optimum by about the relative curvature over the step
  (under 1 % here), so two or three steps do.
- The standard errors come from the Jacobian and the residuals at that optimum on the whole
  record (:meth:`~fuelid.identify._oe.OutputError.fit`'s ``_store``), as for a short record,
  for the orders the order rule reads a covariance of: the one BIC prefers, and the one kept
  when that is the other. The BIC of every order is its whole-record residuals'; an order whose
  covariance was not needed has its standard errors marked as not computed
  (:meth:`~fuelid.identify._order.Candidate.without_covariance`): on a day at 50 Hz each costs
  over a second and a quarter of a gigabyte, and no number of the kept model depends on it.

A polish that does not converge within :data:`MAX_POLISH_STEPS` (a start outside the basin: a
copy that misses what only some stretches show) falls back to the local search on the whole
record from the copy's optimum, the slow path of short records.

Shorter records are searched on themselves, exactly as before: for them the search costs
seconds at most.

References: G. H. Golub, V. Pereyra, "The differentiation of pseudo-inverses and nonlinear
least squares problems whose variables separate", *SIAM J. Numer. Anal.* 10 (1973) 413–432;
L. Kaufman, "A variable projection method for solving separable nonlinear least squares
problems", *BIT* 15 (1975) 49–57.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.identify._segments import MIN_SEGMENT_SAMPLES
from fuelid.identify._variable_projection import (
    LinearFit,
    Structure,
    add_free_responses,
    n_modes,
    regressors,
    solve_linear,
)
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]

LONG_RECORD = 500_000
"""Samples above which the search runs on a copy and the whole record only polishes [-]
(10 000 s at 50 Hz; below it a whole search costs seconds at most)."""
SEARCH_SAMPLES = 100_000
"""Samples of the search copy [-]: its standard errors are √(N/M) times the whole record's."""
SEARCH_STRETCHES = 8
"""Stretches of the search copy, spread evenly over the record [-]: the copy sees the day's
operating points and fuel temperatures, not one hour of them."""
POLISH_TOLERANCE = 0.01
"""The polish stops when its next Gauss–Newton step is under this many (white) standard errors
in every parameter [-]."""
MAX_POLISH_STEPS = 8
"""Gauss–Newton steps of the polish before it gives up and the whole-record search runs [-]."""
SENSITIVITY_STEP = 1e-5
"""Relative step of the central differences of Φβ in the search vector (log T, log T2, θ) [-]."""


@dataclass(frozen=True)
class LongRecordSearch:
    """What a long record's fit did: where it searched, and how the polish went."""

    samples: int
    """Samples of the whole record [-]."""
    copy_samples: int
    """Samples of the search copy [-]."""
    stretches: int
    """Stretches (segments) of the copy [-]."""
    polish_steps: int
    """Gauss–Newton steps on the whole record [-]."""
    converged: bool
    """The polish met :data:`POLISH_TOLERANCE` (False: the whole-record search took over)."""
    fitted_on: str = "full record"
    """"copy" (the default fit: estimates, standard errors and tests are the copy's, no polish)
    or "full record" (``full_record=True``: the copy only searched)."""

    def to_json(self) -> dict[str, Any]:
        """The JSON of one order's long-record fit (:func:`long_record_json` merges the orders)."""
        return {
            "samples": self.samples,
            "copy_samples": self.copy_samples,
            "stretches": self.stretches,
            "polish_steps": self.polish_steps,
            "converged": self.converged,
            "fitted_on": self.fitted_on,
        }


def is_long(data: IOData) -> bool:
    """True for a record the search runs on a copy of (over :data:`LONG_RECORD` samples)."""
    return data.n_samples > LONG_RECORD


def search_copy(data: IOData, samples: int | None = None, stretches: int | None = None) -> IOData:
    """``stretches`` stretches of ``data``, ``samples`` in all, spread evenly, as segments.

    The first stretch starts at the record's first sample (so a given pre-record input still
    applies to it); a stretch that crosses a gap is cut there, and a piece shorter than
    :data:`~fuelid.identify._segments.MIN_SEGMENT_SAMPLES` left out. Each piece is a segment
    of the copy, fitted with its own initial state. ``samples`` and ``stretches`` default to
    :data:`SEARCH_SAMPLES` and :data:`SEARCH_STRETCHES`.

    Examples
    --------
    >>> d = IOData(np.arange(1000.0), np.zeros(1000), 0.5)
    >>> c = search_copy(d, samples=300, stretches=3)
    >>> c.n_samples, c.segment_starts, c.segment_t0, float(c.u[100])
    (300, (100, 200), (225.0, 450.0), 450.0)
    """
    samples = SEARCH_SAMPLES if samples is None else samples
    stretches = SEARCH_STRETCHES if stretches is None else stretches
    n, h = data.n_samples, data.sample_time
    # never overlapping: a sample counted twice would weigh twice
    length = max(min(samples, n) // stretches, MIN_SEGMENT_SAMPLES)
    firsts = np.linspace(0, max(n - length, 0), stretches).round().astype(int)
    edges = data.segment_bounds()
    seg_t0 = (data.t0, *data.segment_t0)
    pieces: list[tuple[int, int, float]] = []  # (start, stop, time of start)
    for first in np.unique(firsts):
        for (a, b), t0 in zip(edges, seg_t0, strict=True):
            start, stop = max(a, int(first)), min(b, int(first) + length)
            if stop - start >= MIN_SEGMENT_SAMPLES:
                pieces.append((start, stop, t0 + h * (start - a)))
    index = np.concatenate([np.arange(a, b) for a, b, _ in pieces])
    starts = np.cumsum([b - a for a, b, _ in pieces])[:-1]
    return IOData(
        data.u[index],
        data.y[index],
        h,
        t0=pieces[0][2],
        segment_starts=tuple(int(s) for s in starts),
        segment_t0=tuple(t for _, _, t in pieces[1:]),
    )


def whole_record_fit(
    st: Structure,
    K: float,
    T: float,
    T2: float,
    delay: float,
    data: IOData,
    u_ref: float,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> tuple[FloatArray, FloatArray]:
    """(β, ŷ) of a model fitted on the copy over the whole record ``data``.

    K, T, T2 and θ are held at the copy's; the offset and each segment's initial state are
    fitted by least squares on ``data`` (linear, one pass): the fitted state
    (``initial="fitted"``) of the whole record, from which its fit % is scored and a held-out
    part continued. β is laid out as the whole record's own fit's (K first).
    """
    Phi = regressors(
        st, T, T2, delay, data.u, data.sample_time, u_ref, data.segment_bounds(), numerics=numerics
    )
    rest = solve_linear(Phi[:, 1:], data.y - K * Phi[:, 0])
    return np.r_[K, rest.beta], data.y - rest.residual


@dataclass(frozen=True)
class Polished:
    """The polish's end: the search vector, the linear fit there, the steps taken."""

    z: FloatArray
    fit: LinearFit
    steps: int
    converged: bool
    sensitivities: FloatArray | None
    """∂(Φβ)/∂p at ``fit`` for p = T, (T2), (θ): the stored fit's Jacobian columns (None when
    the polish did not converge)."""


def polish(
    data: IOData,
    st: Structure,
    evaluate: Callable[[FloatArray], LinearFit],
    z0: FloatArray,
    bounds: tuple[FloatArray, FloatArray],
    u_ref: float,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> Polished:
    """Gauss–Newton on the whole record from ``z0`` until its step is negligible.

    Negligible: under :data:`POLISH_TOLERANCE` of a standard error in every parameter (module
    docstring). ``evaluate(z)`` is the linear fit on ``data`` at the search vector z = [log T,
    (log T2), (θ)]; ``bounds`` (lower, upper) box z. The gradient is exact at every step; the
    Hessian is Kaufman's JᵀJ at the start, kept (over a few standard errors it changes by a
    percent, which slows each step's contraction by as much, and forming it costs as much as
    the gradient). A step that does not lower Σε² is halved (up to four times);
    ``converged`` is False when the tolerance was not met within :data:`MAX_POLISH_STEPS`
    steps or no halving helped. ``numerics``: how the model is discretised.
    """
    lo, hi = bounds
    z = np.clip(np.asarray(z0, dtype=float), lo, hi)
    fit = evaluate(z)
    sens: FloatArray | None = _sensitivities(data, st, z, fit.beta, u_ref, numerics)
    assert sens is not None
    hessian = _projected_gram(fit.Phi, sens)
    try:
        # the white covariance of the nonlinear parameters (the linear ones profiled out)
        variance = np.diag(np.linalg.inv(hessian)) * fit.sse / max(data.n_samples, 1)
    except np.linalg.LinAlgError:
        return Polished(z, fit, 0, False, None)
    se = np.sqrt(np.maximum(variance, 1e-300))
    for steps in range(MAX_POLISH_STEPS + 1):
        if sens is None:  # at the point the last step reached
            sens = _sensitivities(data, st, z, fit.beta, u_ref, numerics)
        # ∇(½Σε²) = −(∂Φβ/∂z)ᵀε at fixed β: exact, as ε ⊥ Φ
        step = -np.linalg.solve(hessian, -(sens.T @ fit.residual))
        if np.all(np.abs(step) <= POLISH_TOLERANCE * se):
            return Polished(z, fit, steps, True, _per_parameter(sens, z, st))
        # the point's regressors and sensitivities are not kept beside the trial's (a day's
        # are 140 and 100 MB): only its Σε²
        cost = fit.sse
        del fit
        sens = None
        for _ in range(5 if steps < MAX_POLISH_STEPS else 0):
            trial = np.clip(z + step, lo, hi)
            fit = evaluate(trial)
            if fit.sse < cost:
                z = trial
                break
            step = 0.5 * step
        else:  # no lower point along the step, or too many steps: the search takes over
            return Polished(z, evaluate(z), steps, False, None)
    raise AssertionError("unreachable")  # pragma: no cover


def _projected_gram(Phi: FloatArray, sens: FloatArray) -> FloatArray:
    """JᵀJ of Kaufman's J = −P⊥·sens, without forming J (a day's N × 3 is 100 MB).

    JᵀJ = SᵀS − (ΦᵀS)ᵀ(ΦᵀΦ)⁻¹(ΦᵀS), Φ's columns scaled as in
    :func:`~fuelid.identify._variable_projection.projected_jacobian`. The difference loses the
    digits S shares with Φ's span; the polish needs JᵀJ only for its steps' direction and its
    standard errors' size, not to the last digit.
    """
    G = Phi.T @ Phi
    scale = np.sqrt(np.diag(G))
    scale[scale == 0.0] = 1.0
    C = (Phi.T @ sens) / scale[:, None]
    try:
        inner = C.T @ np.linalg.solve(G / np.outer(scale, scale), C)
    except np.linalg.LinAlgError:
        inner = C.T @ np.linalg.lstsq(G / np.outer(scale, scale), C, rcond=None)[0]
    return np.asarray(sens.T @ sens - inner, dtype=float)


def _per_parameter(sens: FloatArray, z: FloatArray, st: Structure) -> FloatArray:
    """∂/∂T from ∂/∂log T (divided by T), in place: the lags are searched in logs."""
    for i in range(st.order):
        sens[:, i] /= math.exp(float(z[i]))
    return sens


def _sensitivities(
    data: IOData,
    st: Structure,
    z: FloatArray,
    beta: FloatArray,
    u_ref: float,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """∂(Φβ)/∂z at fixed β by central differences of the simulated output (N × len(z)).

    With β fixed at the linear fit's, −(∂Φβ/∂z)ᵀε is the exact gradient of the projected cost
    (ε ⊥ Φ), so the polish's fixed point is the whole record's optimum. Central, with a step
    of :data:`SENSITIVITY_STEP`: the sampled model's coefficients carry rounding errors that
    the slow poles amplify into a smooth error of the response, which correlates with a
    misfit's residuals; a forward difference with a step of 1e-7 turned it into a gradient
    error of several hundredths of a standard error on the day of the benchmark.

    The differences of :func:`~fuelid.identify._variable_projection.fitted_output` (the same
    to rounding), with what is the same up and down left out: the offset β₁ and a later
    segment's level. Each simulation is filtered into the column in place from the input
    deviations (formed once), the free responses added only where they have not
    underflowed: on a day at 50 Hz half the passes over the record of two ``fitted_output``
    calls per parameter.
    """
    import scipy.signal  # fuelid.lti's rule: imported where it is used

    h, bounds = data.sample_time, data.segment_bounds()
    deviation = np.empty(data.n_samples)
    for j, (a, b) in enumerate(bounds):
        np.subtract(data.u[a:b], u_ref if j == 0 else float(data.u[a]), out=deviation[a:b])
    n_lags = sum(1 for tc in (*st.unpack(z)[:2], st.T_f) if tc > 0.0)
    out = np.zeros((data.n_samples, z.size), order="F")
    for i in range(z.size):
        dz = SENSITIVITY_STEP * max(abs(float(z[i])), 1.0 if i < st.order else h)
        models = []
        for sign in (1.0, -1.0):
            trial = z.copy()
            trial[i] += sign * dz
            T, T2, delay = st.unpack(trial)
            lags = [tc for tc in (T, T2, st.T_f) if tc > 0.0]
            models.append((sign, discretise(lags, delay, h, numerics)))
        col = 2
        for j, (a, b) in enumerate(bounds):
            m = n_modes(st, n_lags, j)
            column = out[a:b, i]
            for sign, model in models:
                shift = min(model.shift, b - a)
                column[shift:] += scipy.signal.lfilter(
                    sign * beta[0] * model.b, model.a, deviation[a : b - shift]
                )
                add_free_responses(column, model.poles[:m], sign * beta[col : col + m])
            column /= 2.0 * dz
            col += m
    return out


def long_record_json(searches: dict[int, LongRecordSearch]) -> dict[str, Any] | None:
    """The JSON ``long_record`` of an identification: None for a record fitted on itself.

    ``{"samples", "copy_samples", "stretches", "polish_steps" (by order), "converged",
    "fitted_on"}``; a fit on the copy has no polish (``polish_steps`` empty, ``converged``
    true).
    """
    if not searches:
        return None
    first = next(iter(searches.values()))
    on_copy = first.fitted_on == "copy"
    return {
        "samples": first.samples,
        "copy_samples": first.copy_samples,
        "stretches": first.stretches,
        "polish_steps": {} if on_copy else {str(o): s.polish_steps for o, s in searches.items()},
        "converged": all(s.converged for s in searches.values()),
        "fitted_on": first.fitted_on,
    }


def long_record_note(info: dict[str, Any] | None, sample_time: float | None = None) -> str | None:
    """One line saying how a long record was fitted, from its JSON ``long_record`` (or None).

    ``sample_time`` [s] gives the stretches' length in the note of a fit on the copy.

    Examples
    --------
    >>> info = {"samples": 4320001, "copy_samples": 100000, "stretches": 8,
    ...         "polish_steps": {}, "converged": True, "fitted_on": "copy"}
    >>> print(long_record_note(info, 0.02))  # doctest: +NORMALIZE_WHITESPACE
    fitted on a copy of the record: 100,000 of 4,320,001 samples in 8 stretches of 250 s
    spread evenly over it; the estimates, standard errors and tests are the copy's (the whole
    record's standard errors would be about 6.6× smaller), the fit % is the whole record's;
    --full-record fits every sample (slower)
    >>> info |= {"polish_steps": {"1": 3, "2": 2}, "fitted_on": "full record"}
    >>> print(long_record_note(info))  # doctest: +NORMALIZE_WHITESPACE
    long record: the search ran on 100,000 samples in 8 stretches spread over it, and
    Gauss–Newton polished its optimum on all 4,320,001 (3 steps for order 1, 2 for order
    2): the estimates, standard errors and fit are the whole record's
    """
    if info is None:
        return None
    if info.get("fitted_on", "full record") == "copy":
        return _copy_note(info, sample_time)
    steps = ", ".join(
        f"{n} step{'s' if n != 1 else ''} for order {order}" if i == 0 else f"{n} for order {order}"
        for i, (order, n) in enumerate(info["polish_steps"].items())
    )
    how = (
        f"Gauss–Newton polished its optimum on all {info['samples']:,} ({steps})"
        if info["converged"]
        else f"the whole record's own search went on from there (the polish on all "
        f"{info['samples']:,} did not converge)"
    )
    return (
        f"long record: the search ran on {info['copy_samples']:,} samples in "
        f"{info['stretches']} stretches spread over it, and {how}: the estimates, standard "
        "errors and fit are the whole record's"
    )


def _copy_note(info: dict[str, Any], sample_time: float | None) -> str:
    """:func:`long_record_note` of a fit on the copy."""
    n, total, k = info["copy_samples"], info["samples"], info["stretches"]
    length = ""
    if sample_time is not None and k > 0:
        seconds = n / k * sample_time
        # gaps cut stretches: then their mean length
        about = "" if k == SEARCH_STRETCHES else "about "
        shown = f"{seconds:,.0f}" if seconds >= 10.0 else f"{seconds:.3g}"
        length = f" of {about}{shown} s"
    return (
        f"fitted on a copy of the record: {n:,} of {total:,} samples in {k} stretches{length} "
        "spread evenly over it; the estimates, standard errors and tests are the copy's (the "
        f"whole record's standard errors would be about {math.sqrt(total / n):.1f}× smaller), "
        "the fit % is the whole record's; --full-record fits every sample (slower)"
    )


__all__ = [
    "LONG_RECORD",
    "SEARCH_SAMPLES",
    "SEARCH_STRETCHES",
    "LongRecordSearch",
    "Polished",
    "is_long",
    "long_record_json",
    "long_record_note",
    "polish",
    "search_copy",
    "whole_record_fit",
]
