"""Which parameters the data determine: the Fisher information's rank, condition and null space.

The report works on the weighted output sensitivities J (∂ŷ/∂φ over σ, one column per estimated
quantity), made relative (log-space columns already are; the others are multiplied by the size of
their value), so that the singular value decomposition J = U·S·Vᵀ reads directly: along the unit
direction v_i of relative parameter changes the data determine the combination to a standard
deviation 1/s_i. A direction with 1/s_i above :data:`UNCERTAINTY_LIMIT` (0.5: a factor of e¹ᐟ²
either way) is not determined, and its large components name the parameters that trade against
each other; in log space v = (a, b, …) means θ₁^a·θ₂^b·… is what the data cannot fix. An exact
symmetry (a scale the outputs cannot see) gives s_i ≈ 0.

Two further measures are reported. Brun, Reichert & Künsch's collinearity index γ = 1/s_min of
the column-normalised J (Water Resources Research 37(4), 2001) is 1 for orthogonal sensitivities
and grows without bound as a combination becomes undetermined, whatever the noise level; two
parameters whose sensitivities correlate at ρ have γ = 1/√(1 − |ρ|) (ρ = 0.999: γ = 31.6). And
pairs whose sensitivity columns correlate above :data:`SENSITIVITY_CORRELATION_LIMIT` are named:
the data may pin them down only through the noise model's exactness, which real data do not have.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError

FloatArray = NDArray[np.float64]
STRUCTURAL_LIMIT = 1e-7
"""Singular values below this share of the largest are zero: the sensitivities are finite
differences through an ODE solver, exact to about 1e-8, so a symmetry shows as ~1e-9, not 0."""
UNCERTAINTY_LIMIT = 0.5
"""Relative standard deviation (log units) above which a combination counts as not determined."""
SENSITIVITY_CORRELATION_LIMIT = 0.999
"""|cos| between two sensitivity columns above which the pair is named as confounded."""
COMPONENT_SHARE = 0.15
"""A parameter belongs to an undetermined combination when its share of the null vector exceeds
this (components of a unit vector)."""
CHI2_95 = 3.841458820694124
"""χ²₁'s 95 % quantile: a rise of the weighted cost below it is not seen in the data."""
ESTIMATE_CORRELATION_LIMIT = 0.999
"""Estimates correlated beyond this are named: the data determine mostly their combination."""


@dataclass(frozen=True)
class UndeterminedCombination:
    """A direction in parameter space the data leave (nearly) free."""

    names: tuple[str, ...]
    weights: tuple[float, ...]
    """Components of the null vector (log-space exponents for log-scaled parameters)."""
    uncertainty: float
    """Standard deviation of the combination, relative (log units): 1/s_i."""

    def describe(self) -> str:
        """E.g. ``k1^0.58 · k2^-0.29 · k4^0.76`` (log-space exponents, normalised)."""
        return " · ".join(
            f"{name}^{weight:.2g}" for name, weight in zip(self.names, self.weights, strict=True)
        )


@dataclass(frozen=True)
class IdentifiabilityReport:
    """What the data determine, for the estimated quantities ``names``."""

    names: tuple[str, ...]
    singular_values: tuple[float, ...]
    """Singular values of the column-normalised weighted sensitivities, largest first."""
    rank: int
    """Numerical rank of the Fisher information (:data:`STRUCTURAL_LIMIT`)."""
    condition_number: float
    """Condition number of the normalised Fisher information (γ² · s_max²)."""
    collinearity_index: float
    """γ = 1/s_min of the normalised sensitivities (1 = orthogonal; inf = singular)."""
    undetermined: tuple[UndeterminedCombination, ...]
    confounded_pairs: tuple[tuple[str, str, float], ...]
    """Pairs whose sensitivities correlate above :data:`SENSITIVITY_CORRELATION_LIMIT`."""
    zero_sensitivity: tuple[str, ...]
    """Quantities the outputs do not depend on at all."""
    advice: tuple[str, ...] = field(default=())
    unconfirmed: tuple[tuple[tuple[str, ...], float], ...] = field(default=())
    """Combinations the sensitivities say no data determine but the simulation contradicts
    (names, the simulated cost's rise over a step of ±10 % along it): a switch or a clip the
    sensitivities do not follow at this point, not a property of the model."""

    @property
    def identifiable(self) -> bool:
        """True when every estimated quantity is determined by the data."""
        return not (self.undetermined or self.confounded_pairs or self.zero_sensitivity)

    @property
    def undetermined_names(self) -> tuple[str, ...]:
        """Every name in an undetermined combination, a confounded pair or without sensitivity."""
        names: list[str] = list(self.zero_sensitivity)
        for combination in self.undetermined:
            names.extend(combination.names)
        for first, second, _ in self.confounded_pairs:
            names.extend((first, second))
        return tuple(dict.fromkeys(names))

    def with_advice(self, advice: Sequence[str]) -> IdentifiabilityReport:
        """The same report with advice on what data would determine the rest."""
        return replace(self, advice=tuple(advice))

    def contradicted(self, rises: Mapping[tuple[str, ...], float]) -> IdentifiabilityReport:
        """The report without the combinations the simulation contradicts (``rises``).

        They move to ``unconfirmed``; confounded pairs inside one go with it.
        """
        if not rises:
            return self
        gone = [set(names) for names in rises]
        return replace(
            self,
            undetermined=tuple(c for c in self.undetermined if c.names not in rises),
            confounded_pairs=tuple(
                pair for pair in self.confounded_pairs if not any(set(pair[:2]) <= g for g in gone)
            ),
            unconfirmed=tuple((names, float(rise)) for names, rise in rises.items()),
        )

    def unconfirmed_message(self) -> str:
        """One line on the combinations the simulation contradicts (empty when none)."""
        if not self.unconfirmed:
            return ""
        parts = [
            f"{', '.join(names)} (a step of ±10 % along it moves the simulated weighted cost by "
            f"{rise:.3g})"
            for names, rise in self.unconfirmed
        ]
        return (
            "the sensitivities at the estimate say the data do not determine "
            + "; ".join(parts)
            + ", but the simulated fit does change along it: they miss a switch or a clip here "
            "(not a property of the model), so these parameters get no standard error; "
            "--profile NAME gives an interval from simulations alone"
        )

    def message(self) -> str:
        """One line naming what the data do not determine (empty when all is determined)."""
        if self.identifiable:
            return ""
        parts = []
        if self.zero_sensitivity:
            parts.append(f"the outputs do not depend on {', '.join(self.zero_sensitivity)}")
        said: set[frozenset[str]] = set()
        for combination in self.undetermined:
            members = frozenset(combination.names)
            if members in said:  # a second direction among the same names: named once
                continue
            said.add(members)
            if len(combination.names) == 1:
                parts.append(
                    f"{combination.names[0]} is not determined "
                    f"(±{_percent(combination.uncertainty)})"
                )
            else:
                parts.append(
                    f"{', '.join(combination.names)} trade against each other (only a "
                    f"combination is determined: ±{_percent(combination.uncertainty)})"
                )
        for first, second, rho in self.confounded_pairs:
            if not any(first in c.names and second in c.names for c in self.undetermined):
                parts.append(f"{first} and {second} have sensitivities correlated at {rho:.4f}")
        if self.undetermined or self.zero_sensitivity:
            lead = "the data do not determine every parameter: "
        else:  # each is determined, but only by the model being exactly right
            lead = "the data hardly tell some parameters apart: "
        text = lead + "; ".join(parts)
        if self.advice:
            text += " (" + "; ".join(self.advice) + ")"
        return text

    def to_json(self) -> dict[str, Any]:
        """The report as plain JSON types."""
        return {
            "identifiable": self.identifiable,
            "parameters": list(self.names),
            "rank": self.rank,
            "n_estimated": len(self.names),
            "condition_number": _finite_or_none(self.condition_number),
            "collinearity_index": _finite_or_none(self.collinearity_index),
            "uncertainty_limit": UNCERTAINTY_LIMIT,
            "singular_values": list(self.singular_values),
            "undetermined": [
                {
                    "parameters": list(c.names),
                    "direction": dict(zip(c.names, c.weights, strict=True)),
                    "relative_uncertainty": _finite_or_none(c.uncertainty),
                    "combination": c.describe(),
                }
                for c in self.undetermined
            ],
            "confounded_pairs": [
                {"parameters": [a, b], "sensitivity_correlation": rho}
                for a, b, rho in self.confounded_pairs
            ],
            "zero_sensitivity": list(self.zero_sensitivity),
            "undetermined_parameters": list(self.undetermined_names),
            "advice": list(self.advice),
            "unconfirmed": [
                {"parameters": list(names), "simulated_cost_rise": _finite_or_none(rise)}
                for names, rise in self.unconfirmed
            ],
        }


def _percent(relative: float) -> str:
    return f"{100 * relative:.3g} %" if np.isfinite(relative) and relative < 1e3 else "unbounded"


def _finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def identifiability(
    sensitivities: FloatArray,
    names: Sequence[str],
    column_scale: FloatArray | None = None,
    report_only: Sequence[str] | None = None,
) -> IdentifiabilityReport:
    """Analyse weighted sensitivities J (rows: residuals over σ; columns: ``names``).

    Parameters
    ----------
    sensitivities : ndarray, shape (m, q)
        ∂(ŷ/σ)/∂φ.
    names : sequence of str
        One per column.
    column_scale : ndarray, shape (q,), optional
        Multiplies each column to make it a relative sensitivity (1 for log-space columns,
        the value's size otherwise); default all 1.
    report_only : sequence of str, optional
        Names to name in confounded pairs (e.g. leave out estimated initial states).

    Returns
    -------
    IdentifiabilityReport

    Examples
    --------
    Two columns that are the same up to scale cannot both be determined:

    >>> J = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    >>> report = identifiability(J, ["a", "b"])
    >>> report.identifiable, report.undetermined[0].names
    (False, ('a', 'b'))
    """
    jac = np.asarray(sensitivities, dtype=float)
    if column_scale is not None:
        jac = jac * np.asarray(column_scale, dtype=float)
    norms = np.sqrt(np.sum(jac**2, axis=0))
    scale = norms.max() if norms.size else 0.0
    zero = tuple(
        name for name, norm in zip(names, norms, strict=True) if norm <= 1e-12 * max(scale, 1e-300)
    )
    live = np.array([name not in zero for name in names], dtype=bool)
    live_names = [name for name, keep in zip(names, live, strict=True) if keep]
    if not live_names:
        return IdentifiabilityReport(tuple(names), (), 0, np.inf, np.inf, (), (), zero)
    relative = jac[:, live]
    normalised = relative / norms[live]
    s_norm = np.linalg.svd(normalised, compute_uv=False)
    _, s, vt = np.linalg.svd(relative, full_matrices=False)
    rank = int(np.sum(s > STRUCTURAL_LIMIT * s[0]))
    gamma = 1.0 / s_norm[-1] if s_norm[-1] > 0.0 else np.inf
    condition = (s_norm[0] / s_norm[-1]) ** 2 if s_norm[-1] > 0.0 else np.inf
    undetermined = []
    for value, vector in zip(s, vt, strict=True):
        singular = value <= STRUCTURAL_LIMIT * s[0]
        uncertainty = np.inf if singular or value <= 0.0 else 1.0 / value
        if uncertainty <= UNCERTAINTY_LIMIT:
            continue
        members = np.flatnonzero(np.abs(vector) > COMPONENT_SHARE)
        order = members[np.argsort(-np.abs(vector[members]))]
        sign = np.sign(vector[order[0]]) if len(order) else 1.0
        undetermined.append(
            UndeterminedCombination(
                tuple(live_names[i] for i in order),
                tuple(float(sign * vector[i]) for i in order),
                float(uncertainty),
            )
        )
    cosine = normalised.T @ normalised
    allowed = set(report_only) if report_only is not None else set(live_names)
    pairs = []
    for i in range(len(live_names)):
        for j in range(i + 1, len(live_names)):
            if live_names[i] in allowed and live_names[j] in allowed:
                rho = float(abs(cosine[i, j]))
                if rho > SENSITIVITY_CORRELATION_LIMIT:
                    pairs.append((live_names[i], live_names[j], rho))
    return IdentifiabilityReport(
        tuple(names),
        tuple(float(v) for v in s_norm),
        rank,  # of the information over every name: a zero column adds nothing
        float(condition),
        float(gamma),
        tuple(undetermined),
        tuple(pairs),
        zero,
    )


class NotIdentifiableError(FuelidError):
    """The data cannot determine some parameters whatever their values; ``report`` names them."""

    def __init__(self, report: IdentifiabilityReport) -> None:
        super().__init__(report.message())
        self.report = report


def correlation_warning(first: str, second: str, rho: float) -> str:
    """The warning for two estimates that correlate near ±1."""
    return (
        f"{first} and {second} are estimated with correlation {rho:+.4f}: the data determine "
        "mostly a combination of them, and their intervals hold only if everything held fixed "
        "(and the model itself) is right"
    )


def structural_report(
    report: IdentifiabilityReport,
    structural: Sequence[UndeterminedCombination],
    free_names: Sequence[str],
    at: str = "",
    evidence: Mapping[tuple[str, ...], float] | None = None,
    hidden: Mapping[str, float] | None = None,
) -> IdentifiabilityReport:
    """The report of what no data of this kind determine, with advice on what to fix.

    ``structural`` are the combinations of ``report`` whose sensitivity vanishes to rounding;
    ``free_names`` the free parameters (the advice names no initial state); ``at`` where they
    were judged and ``evidence`` the largest rise of the simulated weighted cost a step of
    ±10 % along each made (the check that the sensitivities' claim holds); ``hidden`` the
    quantities without sensitivity whose simulated step does move the cost (by that much).
    """
    advice = []
    for combination in structural:
        parameters = [n for n in combination.names if n in free_names]
        if len(parameters) == 1:
            advice.append(
                f"no data of this kind determine {parameters[0]}: fix it at a known value, or "
                "start it where the records reach what it describes"
            )
        elif parameters:
            advice.append(
                f"no data of this kind determine {', '.join(parameters)} together: fix "
                f"one of them (e.g. {parameters[0]}) at a known value"
            )
        if parameters and evidence is not None and combination.names in evidence:
            advice[-1] += (
                f"; at {at or 'these values'} a step of ±10 % along it moves the simulated "
                f"weighted cost by {evidence[combination.names]:.2g} (a change under "
                f"{CHI2_95:.2f} is not seen)"
            )
    hidden = hidden or {}
    idle = [name for name in report.zero_sensitivity if name not in hidden]
    if idle:
        advice.append(
            f"fix {', '.join(idle)} or drop it from the model, or start it "
            "where the records reach what it describes (a limit or kink the simulation does not "
            "reach from the start values)"
        )
    for name, rise in hidden.items():
        advice.append(
            f"yet the simulation does depend on {name} (a step of ±10 % moves the simulated "
            f"weighted cost by {rise:.3g}): a switch (an if on a state) hides it from the "
            "sensitivities the fit steers by; declare the switch (switches = [g]) or write it as a "
            "kink (see the gray-box guide)"
        )
    return IdentifiabilityReport(
        report.names,
        report.singular_values,
        report.rank,
        report.condition_number,
        report.collinearity_index,
        tuple(structural),
        (),
        report.zero_sensitivity,
    ).with_advice(advice)


def describe_identifiability(report: Mapping[str, Any]) -> list[str]:
    """The report in its JSON form (:meth:`IdentifiabilityReport.to_json`) as text lines."""
    condition = report["condition_number"]
    gamma = report["collinearity_index"]
    lines = [
        f"identifiability: rank {report['rank']} of {report['n_estimated']} "
        f"({', '.join(report['parameters'])}); condition number "
        f"{'inf' if condition is None else f'{condition:.3g}'}; collinearity index "
        f"{'inf' if gamma is None else f'{gamma:.3g}'} (1: independent sensitivities)"
    ]
    combos = report["undetermined"]
    lines.append(
        "undetermined combinations: "
        + (
            "; ".join(
                f"{c['combination']} (±{100 * c['relative_uncertainty']:.3g} %)"
                if c["relative_uncertainty"] is not None
                else f"{c['combination']} (unbounded)"
                for c in combos
            )
            or "none"
        )
    )
    pairs = report["confounded_pairs"]
    lines.append(
        "confounded pairs: "
        + (
            "; ".join(
                f"{p['parameters'][0]}–{p['parameters'][1]} (sensitivity correlation "
                f"{p['sensitivity_correlation']:.4f})"
                for p in pairs
            )
            or "none"
        )
    )
    if report["zero_sensitivity"]:
        lines.append(f"no effect on the outputs: {', '.join(report['zero_sensitivity'])}")
    for item in report.get("unconfirmed", []):
        rise = item["simulated_cost_rise"]
        lines.append(
            f"undetermined by the sensitivities only: {', '.join(item['parameters'])} (the "
            f"simulated cost moves by {'inf' if rise is None else f'{rise:.3g}'} along it)"
        )
    return lines
