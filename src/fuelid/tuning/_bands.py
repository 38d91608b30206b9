"""One PI over the command bands a log shows: the range check without a plant file.

Without the user's plant file nothing says how the loop changes with fuel temperature or over
the drive's range, except the log itself: the identification measures the static gain K per
band of commands it visited (:mod:`fuelid.identify._nonlinearity`, ``diagnostics.nonlinearity``),
with its standard error. The gains are checked on the identified model with K moved to each
band's 95 % interval ends; the dynamics (T, T2, T_f, delay) stay the model's, since one log
does not measure them per band, and the temperature dependence stays unknown. The bands are in
the identification's units (K in output per input unit).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from fuelid.model import ProcessModel
from fuelid.tuning._frequency import robustness
from fuelid.tuning._linearloop import MisfitFunction, linear_closed_loop, misfit_overshoot
from fuelid.tuning._rules import PISettings

Z95 = 1.959963984540054
"""Two-sided 95 % quantile of the normal distribution."""


@dataclass(frozen=True)
class CommandBand:
    """The static gain the log shows over one band of commands."""

    u_low: float
    """Lower edge of the band [V]."""
    u_high: float
    """Upper edge of the band [V]."""
    K: float
    """Static gain over the band [(L/min)/V]."""
    stderr: float | None
    """Its standard error [(L/min)/V]; None when not known."""

    @classmethod
    def from_json(cls, row: Mapping[str, Any]) -> CommandBand:
        """From one row of ``diagnostics.nonlinearity.bands``."""
        se = row.get("stderr")
        return cls(
            u_low=float(row["u_low"]),
            u_high=float(row["u_high"]),
            K=float(row["K"]),
            stderr=None if se is None or not math.isfinite(float(se)) else float(se),
        )

    def gains(self) -> tuple[float, ...]:
        """K at the ends of its 95 % interval (K itself when the error is not known)."""
        if self.stderr is None:
            return (self.K,)
        return (self.K - Z95 * self.stderr, self.K + Z95 * self.stderr)


@dataclass(frozen=True)
class BandCase:
    """One PI on the model with one band's gain."""

    band: CommandBand
    K: float
    """The gain evaluated [(L/min)/V]: one end of the band's interval."""
    Ms: float
    gain_margin: float
    phase_margin_deg: float
    overshoot_percent: float
    stable: bool

    def to_json(self) -> dict[str, Any]:
        """One row: the band's edges, the gain and the figures."""
        return {
            "u_low": self.band.u_low,
            "u_high": self.band.u_high,
            "K": self.K,
            "Ms": self.Ms,
            "gain_margin": self.gain_margin,
            "phase_margin_deg": self.phase_margin_deg,
            "overshoot_percent": self.overshoot_percent,
            "stable": self.stable,
        }


@dataclass(frozen=True)
class BandCheck:
    """One PI over the log's command bands: the worst case is what matters."""

    cases: list[BandCase]

    @property
    def u_range(self) -> tuple[float, float]:
        """The commands the bands cover [V]."""
        return min(c.band.u_low for c in self.cases), max(c.band.u_high for c in self.cases)

    @property
    def worst_Ms(self) -> float:
        """Largest Ms over the bands [-]."""
        return max(c.Ms for c in self.cases)

    @property
    def worst_overshoot(self) -> float:
        """Largest setpoint overshoot over the bands [%]."""
        return max(c.overshoot_percent for c in self.cases)

    @property
    def worst_gain_margin(self) -> float:
        """Smallest gain margin over the bands [-]."""
        return min(c.gain_margin for c in self.cases)

    @property
    def all_stable(self) -> bool:
        """Every band's case closed-loop stable."""
        return all(c.stable for c in self.cases)

    def to_json(self) -> dict[str, Any]:
        """The documented ``command_band_check`` JSON object.

        ``temperature`` says what it tells of fuel temperature: nothing, the log is at one.
        """
        return {
            "basis": "log",
            "u_range": list(self.u_range),
            "worst_Ms": self.worst_Ms,
            "worst_overshoot_percent": self.worst_overshoot,
            "worst_gain_margin": self.worst_gain_margin,
            "all_stable": self.all_stable,
            "temperature": "the log's own: these bands say nothing of other fuel temperatures",
            "cases": [c.to_json() for c in self.cases],
        }


def band_check(
    pi: PISettings,
    model: ProcessModel,
    bands: Iterable[CommandBand],
    misfit: tuple[MisfitFunction, float] | None = None,
) -> BandCheck | None:
    """``pi`` on ``model`` with K at each band's 95 % interval ends; None without a band.

    With ``misfit`` (the model's error the log shows and the frequency up to which it holds),
    each case's overshoot is the larger of the model's and that of the model with the misfit
    (:func:`~fuelid.tuning._linearloop.misfit_overshoot`): the dynamics the model leaves out
    shape the overshoot as much as the gain does.

    Examples
    --------
    The worked SIMC example (K = 1, T = 2 s, θ = 1 s: Kc = 1, Ti = 2 s, Ms ≈ 1.59) on a band
    whose gain is 20 % higher is less robust:

    >>> pi = PISettings(rule="simc", Kc=1.0, Ti=2.0, control_period=0.0)
    >>> check = band_check(pi, ProcessModel(K=1.0, T=2.0, delay=1.0),
    ...                    [CommandBand(1.0, 2.0, 1.0, None), CommandBand(2.0, 3.0, 1.2, None)])
    >>> round(check.cases[0].Ms, 2), check.worst_Ms > check.cases[0].Ms
    (1.59, True)

    """
    cases = []
    for band in bands:
        for K in band.gains():
            if not K > 0.0:  # an interval reaching zero gain: the loop opens, no figure
                continue
            variant = replace(model, K=K)
            r = robustness(variant, pi)
            step = linear_closed_loop(variant, pi)
            overshoot = step.setpoint.overshoot_percent
            if misfit is not None and r.stable:
                with_misfit = misfit_overshoot(model, pi, misfit[0], misfit[1], K / model.K)
                overshoot = max(overshoot, with_misfit if with_misfit is not None else 0.0)
            cases.append(
                BandCase(
                    band=band,
                    K=K,
                    Ms=r.Ms,
                    gain_margin=r.gain_margin,
                    phase_margin_deg=r.phase_margin_deg,
                    overshoot_percent=overshoot if r.stable else math.inf,
                    stable=r.stable,
                )
            )
    return BandCheck(cases=cases) if cases else None
