r"""How far the loop may be from the identified model: a bound from the residuals' spectrum.

An output-error fit leaves residuals r = y − ŷ. The part of r that the command explains is the
model's misfit: y = G·(1 + Δ)·u + v, so r = G·Δ·u + v. Its frequency response is estimated from
the cross-spectrum of the command and the residuals (Welch's averaged periodograms, the H1
estimator, Bendat & Piersol, *Random Data*, 4th ed., 2010, §9.2):

    Ĝ_r(jω) = Φ_ur(ω)/Φ_uu(ω),   γ²(ω) = |Φ_ur|²/(Φ_uu·Φ_rr),

with the random error of Ĝ_r bounded at about 95 % by

    ε(ω) = 2.45·√(Φ_rr·(1 − γ²)/(n_d·Φ_uu))

(2.45 = √χ²₂(0.95): the error of a complex estimate has two degrees of freedom; n_d the number of
averaged segments). The relative model error is then bounded by

    ℓ(ω) = (|Ĝ_r(jω)| + ε(ω))/|G(jω)|,

a multiplicative uncertainty |Δ(jω)| ≤ ℓ(ω) that holds where the log excites the loop; where it
does not, ε grows and ℓ says so. The estimate Δ̂ = Ĝ_r/G keeps its phase: the loop's error lies
within ε/|G| of Δ̂, and :func:`fuelid.tuning._frequency.robust_peak` turns that disk into the
worst Ms the log does not rule out. The estimate assumes open-loop data (the command does not
react to the noise), as the output-error fit itself does.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from fuelid.model import ProcessModel

FloatArray = NDArray[np.float64]

CONFIDENCE_FACTOR = math.sqrt(5.991464547107979)
"""√χ²₂(0.95): the 95 % radius of a complex estimate's error, in standard deviations."""
MAX_RADIUS = 0.5
"""Largest error radius of Δ̂ [-] at which the log still bounds the misfit (±50 % of the loop)."""
MIN_AVERAGES = 4
"""Fewest averaged segments for a bound: fewer give an estimate too rough to mean anything."""
MAX_SEGMENT = 2**16
"""Longest Welch segment [samples] (22 min at 50 Hz), unless the model needs a longer one
(:data:`CORNER_RESOLUTION`). A longer segment only resolves frequencies far below the loop's,
and thins the averages: on a day at 50 Hz the rule of :data:`MIN_AVERAGES` alone gave 2²⁰
samples, 7 averages and 524,288 frequencies (a 72 MB JSON) where this gives 130 averages,
an error radius √(130/7) ≈ 4 times smaller, and 32,768 frequencies."""
CORNER_RESOLUTION = 100.0
"""The lowest frequency resolved lies at least this factor below the model's corner
1/(T + T2 + T_f + θ) [-]: a slow model (or fast sampling) lengthens the segment past
:data:`MAX_SEGMENT` as far as that needs."""


@dataclass(frozen=True)
class MisfitBound:
    """The model's relative error Δ(jω) = G_loop/G_model − 1: its estimate and a 95 % radius."""

    omega: FloatArray
    """Angular frequencies [rad/s], from the lowest the log resolves to the samples' Nyquist."""
    delta: NDArray[np.complex128]
    """Δ̂(jω) = Ĝ_r/G, the misfit's point estimate, with its phase [-]."""
    radius: FloatArray
    """ε/|G|: the estimate's error radius at about 95 % [-]."""
    averages: int
    """Segments averaged by Welch's method."""

    @property
    def excited_up_to(self) -> float:
        """The highest frequency below which the log fixes Δ within :data:`MAX_RADIUS` [rad/s].

        Above it the command has too little power for the residuals to say how wrong the model
        is; 0 when even the lowest frequency is not fixed.
        """
        loose = np.flatnonzero(self.radius > MAX_RADIUS)
        if loose.size == 0:
            return float(self.omega[-1])
        return 0.0 if loose[0] == 0 else float(self.omega[loose[0] - 1])

    @property
    def bound(self) -> FloatArray:
        """ℓ(ω) = |Δ̂| + radius: the bound on |Δ| whatever its phase [-]."""
        return np.asarray(np.abs(self.delta) + self.radius, dtype=float)

    def at(self, omega: FloatArray) -> tuple[NDArray[np.complex128], FloatArray]:
        """(Δ̂, radius) at other frequencies [rad/s]: linear in log ω, the end values held."""
        w = np.log(np.maximum(np.asarray(omega, dtype=float), self.omega[0]))
        grid = np.log(self.omega)
        delta = np.interp(w, grid, self.delta.real) + 1j * np.interp(w, grid, self.delta.imag)
        return delta, np.asarray(np.interp(w, grid, self.radius), dtype=float)

    def to_json(self) -> dict[str, Any]:
        """``omega`` [rad/s]; ``delta_re``, ``delta_im``, ``radius``, ``bound``; ``averages``."""
        return {
            "omega": self.omega.tolist(),
            "delta_re": self.delta.real.tolist(),
            "delta_im": self.delta.imag.tolist(),
            "radius": self.radius.tolist(),
            "bound": self.bound.tolist(),
            "excited_up_to": self.excited_up_to,
            "averages": self.averages,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> MisfitBound:
        """From :meth:`to_json`'s object."""
        return cls(
            omega=np.asarray(data["omega"], dtype=float),
            delta=np.asarray(data["delta_re"], dtype=float)
            + 1j * np.asarray(data["delta_im"], dtype=float),
            radius=np.asarray(data["radius"], dtype=float),
            averages=int(data["averages"]),
        )


def misfit_bound(
    u: FloatArray,
    residuals: FloatArray,
    h: float,
    model: ProcessModel,
    segment_starts: Sequence[int] = (),
) -> MisfitBound | None:
    """The bound ℓ(ω) from a log's command ``u`` and the fit's residuals, sampled every ``h``.

    Each segment between ``segment_starts`` gives its own periodograms (a gap breaks the
    record); segments shorter than one Welch segment are left out. The Welch segment is the
    largest power of two giving at least :data:`MIN_AVERAGES` halves-overlapped segments over the
    whole record, at most :data:`MAX_SEGMENT` samples unless the model's corner frequency needs
    more (:data:`CORNER_RESOLUTION`). None when the record is too short or the command never
    moves.

    Examples
    --------
    A model that is the loop itself: the bound is only the estimate's own error, small where
    the command has power.

    >>> rng = np.random.default_rng(1)
    >>> m = ProcessModel(K=2.0, T=1.0)
    >>> u = np.repeat(rng.choice([-1.0, 1.0], 400), 25)
    >>> b = misfit_bound(u, rng.normal(0.0, 0.05, u.size), 0.02, m)
    >>> delta, radius = b.at(np.array([0.5]))
    >>> bool(abs(delta[0]) + radius[0] < 0.05)
    True
    """
    u = np.asarray(u, dtype=float)
    r = np.asarray(residuals, dtype=float)
    bounds = np.r_[0, np.asarray(segment_starts, dtype=int), u.size]
    length = 2 ** math.floor(math.log2(max(u.size * 2 / (MIN_AVERAGES + 1), 2)))
    # the lowest frequency 1/(length·h) a decade or two below the corner 1/Στ is all the bound
    # needs; more resolution only costs averages (and a day's JSON)
    time_scale = sum(model.time_constants) + model.delay
    needed = 2 ** math.ceil(math.log2(max(2.0 * math.pi * CORNER_RESOLUTION * time_scale / h, 2)))
    length = min(length, max(MAX_SEGMENT, needed))
    spectra: list[tuple[FloatArray, FloatArray, NDArray[np.complex128], int]] = []
    frequencies: FloatArray | None = None
    for a, b in itertools.pairwise(bounds):
        if b - a < length:
            continue
        uu = u[a:b] - np.mean(u[a:b])
        rr = r[a:b] - np.mean(r[a:b])
        frequencies, p_uu = scipy.signal.welch(uu, fs=1.0 / h, nperseg=length)
        _, p_rr = scipy.signal.welch(rr, fs=1.0 / h, nperseg=length)
        _, p_ur = scipy.signal.csd(uu, rr, fs=1.0 / h, nperseg=length)
        spectra.append((p_uu, p_rr, p_ur, 2 * (b - a) // length - 1))
    if frequencies is None or not spectra:
        return None
    weights = np.array([n for *_, n in spectra], dtype=float)
    averages = int(weights.sum())
    if averages < MIN_AVERAGES:
        return None
    p_uu = np.average([s[0] for s in spectra], axis=0, weights=weights)
    p_rr = np.average([s[1] for s in spectra], axis=0, weights=weights)
    p_ur = np.average([s[2] for s in spectra], axis=0, weights=weights)
    keep = (frequencies > 0.0) & (p_uu > 0.0)
    if not np.any(keep):
        return None
    f, p_uu, p_rr, p_ur = frequencies[keep], p_uu[keep], p_rr[keep], p_ur[keep]
    coherence = np.clip(np.abs(p_ur) ** 2 / (p_uu * p_rr), 0.0, 1.0)
    g_r = p_ur / p_uu
    error = CONFIDENCE_FACTOR * np.sqrt(p_rr * (1.0 - coherence) / (averages * p_uu))
    omega = 2.0 * math.pi * f
    g = _model_response(model, omega)
    return MisfitBound(omega=omega, delta=g_r / g, radius=error / np.abs(g), averages=averages)


def _model_response(model: ProcessModel, omega: FloatArray) -> NDArray[np.complex128]:
    """G(jω) = K·e^(−jωθ)/Π(1 + jωT_i) of the continuous model."""
    s = 1j * omega
    lags = np.prod([1.0 + s * tc for tc in model.time_constants], axis=0)
    return np.asarray(model.K * np.exp(-s * model.delay) / lags, dtype=complex)
