"""Does the gain change with the operating point? The static gain per command band.

The model family is linear: one K for the whole log. The fuel loop is not: the pump's leakage
and the line's turbulent losses grow with the flow, so the reference plant's static gain falls
about 13 % from 1.25 V to 4.75 V. A linear model fitted to a log over such a range averages the
gains, and its residuals are coloured and correlate with the input (large steps at one end of
the range are over-predicted, at the other under-predicted). That is not noise colour, and a
second lag or an estimated dead time does not remove it: the residual warnings must say so
(issue 12, item 6).

Method (a Hammerstein model with the identified dynamics held). The command range is cut into
bands at the levels the command is held at (or, when it takes many values, at its quartiles);
the static map from command to flow is taken piecewise linear over the bands,

    f(u) = Σ_b K_b · w_b(u),   w_b(u) = clip(u, e_b, e_(b+1)) − e_b,

and the output is modelled as ``c + G₁(q)·f(u)`` plus the free response of each segment's
initial state, where G₁ is the fitted model with unit gain (its lags and delay held). Each
segment is simulated on its own from rest at its first command (as the output-error fit does).
The K_b and the offset c enter linearly: one least-squares solve gives them and their
covariance σ²(ΦᵀΦ)⁻¹. With one gain for all bands this is exactly the fitted linear model.

The gain varies significantly when the band gains differ by more than their uncertainty
explains (χ² test of one common gain, 1 % level) *and* by more than
:data:`VARIATION_THRESHOLD_PERCENT` of their mean: small but significant variations on a long,
quiet log are no reason to warn.

Both tests use the residuals of this band model too: when the band gains make the residuals
white, the nonlinearity explains the residual warnings of the linear fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import scipy.special
from numpy.typing import NDArray

from fuelid.identify._covariance import (
    ROW_BLOCK,
    least_squares,
    residual_ar,
    sandwich_covariance,
    white_covariance,
)
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel

FloatArray = NDArray[np.float64]

VARIATION_THRESHOLD_PERCENT = 5.0
"""Smallest variation of the band gains, (max − min)/mean [%], that is reported as one."""
SIGNIFICANCE = 0.01
"""Level of the χ² test of one common gain across the bands."""
MAX_BANDS = 4
"""Most command bands (the command's quartiles when it is held at more than five levels)."""
MIN_LEVEL_SAMPLES = 5
"""A command value held for fewer samples than this is a passing value, not a level."""


@dataclass(frozen=True)
class GainBand:
    """The static gain over one band of commands."""

    u_low: float
    """Lower edge of the band [input unit]."""
    u_high: float
    """Upper edge of the band [input unit]."""
    y: float
    """Steady output at the band's middle command, from the band model [output unit]."""
    K: float
    """Static gain over the band: the slope of the steady output [output unit / input unit]."""
    stderr: float
    """Standard error of K [output unit / input unit]."""

    @property
    def u(self) -> float:
        """Middle command of the band [input unit]."""
        return 0.5 * (self.u_low + self.u_high)

    def to_json(self) -> dict[str, float]:
        """``u``, ``u_low``, ``u_high``, ``y``, ``K``, ``stderr``."""
        return {
            "u": self.u,
            "u_low": self.u_low,
            "u_high": self.u_high,
            "y": self.y,
            "K": self.K,
            "stderr": self.stderr,
        }


@dataclass(frozen=True)
class NonlinearityCheck:
    """Band gains of one log and whether they vary (see the module docstring)."""

    bands: tuple[GainBand, ...]
    """The bands in increasing command."""
    p_value: float
    """P(χ² this large) for one gain common to all bands [-]."""
    residuals: FloatArray
    """Output minus the band model [output unit], one per sample."""

    @property
    def variation_percent(self) -> float:
        """(max − min)/mean of the band gains [%]."""
        K = np.array([b.K for b in self.bands])
        mean = float(np.mean(K))
        return 100.0 * float(np.ptp(K)) / abs(mean) if mean else math.inf

    @property
    def significant(self) -> bool:
        """The gains differ beyond their uncertainty and by more than the threshold."""
        return self.p_value < SIGNIFICANCE and self.variation_percent > VARIATION_THRESHOLD_PERCENT

    def warning(self, K_unit: str = "", u_unit: str = "") -> str:
        """The user's warning, from the lowest to the highest band."""
        lo, hi = self.bands[0], self.bands[-1]
        unit = f" {K_unit}" if K_unit else ""
        return (
            f"K varies {self.variation_percent:.0f} % with the command over this log "
            f"(K = {lo.K:.3g}{unit} at u ≈ {lo.u:.3g} {u_unit} … {hi.K:.3g} at u ≈ "
            f"{hi.u:.3g} {u_unit}): a nonlinearity the linear model averages; tune at the "
            "operating point, or identify on a log around it"
        )

    def to_json(self) -> dict[str, Any]:
        """``bands``, ``variation_percent``, ``p_value``, ``significant``, ``threshold_percent``."""
        return {
            "bands": [b.to_json() for b in self.bands],
            "variation_percent": self.variation_percent,
            "p_value": self.p_value,
            "significant": self.significant,
            "threshold_percent": VARIATION_THRESHOLD_PERCENT,
        }


def _edges(u: FloatArray, span_tolerance: float = 0.02) -> FloatArray:
    """Band edges: the levels the command is held at, at most ``MAX_BANDS + 1`` of them.

    A held level is a command value taken by at least :data:`MIN_LEVEL_SAMPLES` samples;
    levels closer than 2 % of the command's range are merged. When the held levels carry
    most (90 %) of the samples, the edges are those levels (the ones nearest the quartiles
    when there are many); a command that is not held at levels gets its quartiles.
    """
    values, counts = np.unique(u, return_counts=True)
    held = counts >= MIN_LEVEL_SAMPLES
    if counts[held].sum() < 0.9 * u.size:
        return np.unique(np.quantile(u, np.linspace(0.0, 1.0, MAX_BANDS + 1)))
    levels = values[held]
    span = float(np.ptp(u))
    merged = [float(levels[0])]
    for value in levels[1:]:
        if value - merged[-1] > span_tolerance * span:
            merged.append(float(value))
    edges = np.array(merged)
    if edges.size > MAX_BANDS + 1:
        targets = np.quantile(u, np.linspace(0.0, 1.0, MAX_BANDS + 1))
        edges = np.unique(edges[np.argmin(np.abs(edges[:, None] - targets[None, :]), axis=0)])
    return edges


def _band_inputs(u: FloatArray, edges: FloatArray) -> FloatArray:
    """w_b(u) = clip(u, e_b, e_(b+1)) − e_b, one column per band."""
    return np.clip(u[:, None], edges[None, :-1], edges[None, 1:]) - edges[None, :-1]


def _free_response_length(poles: FloatArray) -> int:
    """Samples after which every p^k has fallen below 1e-18 (as ``DiscreteLagModel.modes``)."""
    lengths = [math.ceil(-41.5 / math.log(p)) + 1 for p in poles if 0.0 < p < 1.0]
    return max(lengths, default=1) if all(0.0 <= p < 1.0 for p in poles) else 2**62


def gain_bands(data: IOData, model: ProcessModel) -> NonlinearityCheck | None:
    """Static gain per command band, with the dynamics of ``model`` held.

    Parameters
    ----------
    data : IOData
        The record (segments fitted jointly, each with its own initial state).
    model : ProcessModel
        The fitted model; only its lags and delay are used.

    Returns
    -------
    NonlinearityCheck or None
        None when the command has fewer than three levels (fewer than two bands), or when a
        band is never crossed by a command change within a segment.

    Examples
    --------
    A square-root static map (gain falling with the command) behind a first-order lag:

    >>> u = np.repeat([1.0, 2.0, 3.0, 4.0, 3.0, 2.0, 1.0], 400)
    >>> m = ProcessModel(K=1.0, T=1.0)
    >>> from fuelid.model import simulate_model
    >>> y = simulate_model(m, 10.0 * np.sqrt(u), 0.05)
    >>> check = gain_bands(IOData(u, y, 0.05), m)
    >>> [round(b.K, 3) for b in check.bands]  # chords of 10·√u
    [4.142, 3.178, 2.679]
    >>> check.significant, round(check.variation_percent)
    (True, 44)
    """
    u, y, h = data.u, data.y, data.sample_time
    if np.ptp(u) <= 0.0:
        return None
    edges = _edges(u)
    if edges.size < 3:
        return None
    bounds = data.segment_bounds()
    lows, highs = edges[:-1], edges[1:]
    # a band must be crossed by a change inside a segment, or its gain is not determined:
    # clip(u) to the band moves within a segment when the segment's range overlaps the band
    # (the bands' inputs are formed one at a time below, not as an N × bands matrix)
    moved = np.zeros(lows.size, dtype=bool)
    for a, b in bounds:
        u_min, u_max = float(np.min(u[a:b])), float(np.max(u[a:b]))
        moved |= np.minimum(u_max, highs) > np.maximum(u_min, lows)
    if not np.all(moved):
        return None
    discrete = discretise(model.time_constants, model.delay, h)
    n_bands, n_lags = lows.size, discrete.poles.size
    # Fortran order past a million rows: each column contiguous, for the blocked solve and the
    # sandwich's filters (a record up to it is computed exactly as before)
    order: Literal["C", "F"] = "F" if u.size > ROW_BLOCK else "C"
    Phi = np.zeros((u.size, n_bands + 1 + n_lags * len(bounds)), order=order)
    for j, (a, b) in enumerate(bounds):
        for band in range(n_bands):
            w = np.clip(u[a:b], lows[band], highs[band]) - lows[band]
            # from rest at the segment's first command; its level stays in the column
            Phi[a:b, band] = discrete.response(w - w[0]) + w[0]
        # the free responses only as far as they have not underflowed (Φ is zero beyond)
        rows = min(b - a, _free_response_length(discrete.poles))
        Phi[a : a + rows, n_bands + 1 + j * n_lags : n_bands + 1 + (j + 1) * n_lags] = (
            discrete.modes(rows)
        )
    Phi[:, n_bands] = 1.0
    beta = least_squares(Phi, y)
    residuals = np.asarray(y - Phi @ beta, dtype=float)
    dof = max(u.size - Phi.shape[1], 1)
    sigma = math.sqrt(float(residuals @ residuals) / dof)
    # coloured noise makes the white covariance several times too small, and a linear plant
    # then "varies" with the command: the sandwich with the residuals' spectrum, as oe's
    noise = residual_ar(residuals, bounds)
    cov = (
        # Φ is not needed after: filtered in place (a day's Φ is 200 MB)
        sandwich_covariance(Phi, noise, bounds, overwrite=True)[0]
        if noise.order > 0
        else white_covariance(Phi, sigma)[0]
    )
    K = beta[:n_bands]
    cov_K = cov[:n_bands, :n_bands]
    # χ² of one common gain: the differences of adjacent band gains against their covariance
    D = np.diff(np.eye(n_bands), axis=0)
    d = D @ K
    cov_d = D @ cov_K @ D.T
    try:
        statistic = float(d @ np.linalg.solve(cov_d, d))
        p_value = float(scipy.special.chdtrc(n_bands - 1, statistic))
    except np.linalg.LinAlgError:
        p_value = math.nan
    offset = float(beta[n_bands])
    middles = 0.5 * (edges[:-1] + edges[1:])
    steady = offset + _band_inputs(middles, edges) @ K
    se = np.sqrt(np.maximum(np.diag(cov_K), 0.0))
    bands = tuple(
        GainBand(float(lo), float(hi), float(yy), float(k), float(s))
        for lo, hi, yy, k, s in zip(edges[:-1], edges[1:], steady, K, se, strict=True)
    )
    return NonlinearityCheck(bands=bands, p_value=p_value, residuals=residuals)
