"""Whether the calibrated plant fits the logs as well as their noise allows.

A fit can converge and every parameter be determined while the model explains little of the data:
a command in % of output taken for volts, a flow in the wrong unit, a parameter held at a wrong
file value. Its estimates then absorb the error and their intervals stay narrow, so they are not
to be trusted, however well "determined".

The criterion comes from each log's own data: its flow noise is the sample-to-sample level
:func:`fuelid.greybox._fitting.noise_level` (1.4826·MAD(Δy)/√2, blind to the steps themselves),
the level the gray-box estimator calls its noise floor; a model that is right but for that noise
leaves residuals near it, and reaches the fit 100·(1 − σ/rms(y − ȳ)) % (what the noise allows).
Residuals over :data:`MISFIT_NOISE_RATIO` times the noise, on the fitted part or on the held-out
end of any log, are a misfit: the estimator's own threshold for suspecting a wrong model or a
local minimum (:data:`fuelid.greybox.SUSPECT_NOISE_RATIO`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.greybox import SUSPECT_NOISE_RATIO, Record, noise_level

MISFIT_NOISE_RATIO = SUSPECT_NOISE_RATIO
"""Flow residuals above this multiple of a log's own noise level mean the model does not fit."""


@dataclass(frozen=True)
class LogFit:
    """How closely the calibrated plant follows one log's flow, against its noise."""

    name: str
    noise: float
    """The log's flow noise, sample to sample [L/min]."""
    residual: float
    """RMS flow residual on the fitted part [L/min]."""
    heldout_residual: float | None
    """RMS flow residual on the held-out end [L/min] (None: nothing held out)."""
    allowed_fit_percent: float
    """The fit a model exact but for the noise reaches on the fitted part [%]."""
    allowed_heldout_fit_percent: float | None

    @property
    def ratio(self) -> float:
        """The larger residual (fitted part or held-out end) over the noise [-]."""
        worst = max(self.residual, self.heldout_residual or 0.0)
        return worst / self.noise if self.noise > 0.0 else math.inf

    @property
    def misfit(self) -> bool:
        """True when the residuals exceed :data:`MISFIT_NOISE_RATIO` times the noise."""
        return self.ratio > MISFIT_NOISE_RATIO

    def to_json(self) -> dict[str, Any]:
        """``{"log", "noise_std", "residual_rms", "heldout_residual_rms", "ratio", ...}``."""
        return {
            "log": self.name,
            "noise_std": self.noise,
            "residual_rms": self.residual,
            "heldout_residual_rms": self.heldout_residual,
            "ratio": self.ratio,
            "allowed_fit_percent": self.allowed_fit_percent,
            "allowed_heldout_fit_percent": self.allowed_heldout_fit_percent,
            "misfit": self.misfit,
        }


def _rms(values: NDArray[np.float64]) -> float:
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite**2))) if finite.size else math.nan


def _allowed(y: NDArray[np.float64], noise: float) -> float:
    finite = y[np.isfinite(y)]
    spread = float(np.sqrt(np.mean((finite - finite.mean()) ** 2))) if finite.size else 0.0
    return 100.0 * (1.0 - noise / spread) if spread > 0.0 else -math.inf


def judge_fit(
    records: Sequence[Record],
    simulated: Sequence[NDArray[np.float64]],
    fitted_samples: Sequence[int],
) -> list[LogFit]:
    """Each record's flow residuals (column 0) against its own noise level.

    Parameters
    ----------
    records : sequence of Record
        The logs, whole.
    simulated : sequence of ndarray
        Each whole log simulated with the calibrated plant (flow first).
    fitted_samples : sequence of int
        How many leading samples of each log the fit used; the rest is the held-out end.
    """
    fits = []
    for record, model, n_fit in zip(records, simulated, fitted_samples, strict=True):
        y = record.y[:, 0]
        error = y - model[:, 0]
        noise = float(noise_level(record.y[:, :1])[0])
        held = n_fit < record.n_samples
        fits.append(
            LogFit(
                name=record.name,
                noise=noise,
                residual=_rms(error[:n_fit]),
                heldout_residual=_rms(error[n_fit:]) if held else None,
                allowed_fit_percent=_allowed(y[:n_fit], noise),
                allowed_heldout_fit_percent=_allowed(y[n_fit:], noise) if held else None,
            )
        )
    return fits


def misfit_message(fits: Sequence[LogFit], fit_percent: Sequence[dict[str, float | None]]) -> str:
    """The one-line finding for the logs the model does not fit ("" when it fits them all)."""
    parts = []
    for judged, fits_of_log in zip(fits, fit_percent, strict=True):
        if not judged.misfit:
            continue
        fit = (
            f"fit {fits_of_log['flow']:.1f} % where the noise allows "
            f"{judged.allowed_fit_percent:.1f} %"
        )
        held = fits_of_log.get("heldout_flow")
        if held is not None and judged.allowed_heldout_fit_percent is not None:
            fit += (
                f", held-out end {held:.1f} % where it allows "
                f"{judged.allowed_heldout_fit_percent:.1f} %"
            )
        parts.append(
            f"{judged.name}: {fit} (flow residuals {judged.ratio:.1f}× the log's noise of "
            f"{judged.noise:.3g} L/min)"
        )
    if not parts:
        return ""
    return (
        "the calibrated model does not fit the data, so its parameters are not to be trusted: "
        + "; ".join(parts)
        + f" (a fit within {MISFIT_NOISE_RATIO:g}× the noise is expected); check the command's "
        "and the flow's units and scaling (--input-scale, --output-scale), the parameters held "
        "at their file values, the fuel temperatures, and that each log starts at rest"
    )
