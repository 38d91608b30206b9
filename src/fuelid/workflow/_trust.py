"""What each figure about a loop rests on, and the facts the gains need from the user.

A tuning tool must never print an unsafe number as safe. Every figure fuelid prints about a loop
rests on one of these (:data:`Basis`): the user's identified model, the user's plant file, the
log itself, something the user gave (an option, the site file, a model file's recorded run),
or the built-in reference plant. A figure resting on the reference plant is not about the
user's loop: it is never printed beside the gains. This module is the one place that decides:

- :func:`control_period_from`: the PLC's PI period from an option, the site file or the model
  file's identify run, or a refusal: gains for the wrong period are wrong gains;
- :func:`spans_from`: the spans of the percent-of-span gains from an option, the site file or the
  user's plant file, or none (the %/% gains are then not printed, with the reason);
- :func:`undetermined`: the model's K, T or dead time whose 95 % interval is unbounded or wider
  than its value: no gains from such a model unless the user accepts it;
- :data:`Basis`: the names of what a figure rests on, as ``fuelid tune``'s and
  ``fuelid report``'s JSON give them beside each figure (the ``provenance`` object, documented
  on the page "What each number rests on").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal, get_args

from fuelid.errors import FuelidError
from fuelid.lti import check_control_period

Basis = Literal[
    "identified model",
    "model file",
    "plant file",
    "log",
    "option",
    "site file",
    "reference plant",
]
"""Where a figure comes from: the user's facts, or the built-in reference plant."""

USERS_FACTS: tuple[Basis, ...] = tuple(b for b in get_args(Basis) if b != "reference plant")
"""The bases a figure about the user's loop may rest on (all but the reference plant)."""


@dataclass(frozen=True)
class Fact:
    """A number the user gave, and where it was given."""

    value: float
    basis: Basis

    def to_json(self) -> dict[str, float | str]:
        """``{"value": ..., "basis": ...}``."""
        return {"value": self.value, "basis": self.basis}


NO_CONTROL_PERIOD = (
    "no control period: give --control-period SECONDS (how often the PLC runs its PI; 0 for a "
    "continuous controller), a site file (--site SITE.toml with [sampling] control_period_s) or "
    "a model file identified with --control-period: gains for another period are wrong gains"
)


def control_period_from(
    option: float | None,
    site: float | None = None,
    model_file: float | None = None,
) -> Fact:
    """The PLC's PI period h [s]: the option, else the site file's, else the model file's.

    Parameters
    ----------
    option : float or None
        ``--control-period`` [s].
    site : float or None
        The site file's ``[sampling] control_period_s`` [s], only when the file sets it.
    model_file : float or None
        The control period the model file's ``fuelid identify`` run was given [s].

    Raises
    ------
    FuelidError
        When none of the three gives one (:data:`NO_CONTROL_PERIOD`): fuelid assumes none; or
        when any that is given is negative, not finite or beyond 10 s
        (:func:`~fuelid.lti.check_control_period`, naming the source), used or not: a
        damaged value is refused, never passed over.

    Examples
    --------
    >>> control_period_from(None, site=0.1)
    Fact(value=0.1, basis='site file')
    >>> try:
    ...     control_period_from(None, model_file=-1.0)
    ... except FuelidError as exc:
    ...     print(exc)
    the model file's options.control_period must be 0 (continuous) or up to 10 s, got -1 s
    """
    sources = (
        (option, "option", "control period (--control-period)"),
        (site, "site file", "the site file's [sampling] control_period_s"),
        (model_file, "model file", "the model file's options.control_period"),
    )
    for value, _, name in sources:
        if value is not None:
            check_control_period(value, name)
    for value, basis, _ in sources:
        if value is not None:
            return Fact(float(value), basis)  # type: ignore[arg-type]
    raise FuelidError(NO_CONTROL_PERIOD)


def overridden(facts: dict[str, float | None], unit: str, kept: Fact) -> list[str]:
    """A note for each other source that gave a different value than the one ``kept``.

    ``facts`` maps a basis to the value it gives (None: gives none). Settled silently, a site
    file's 0.5 s over the model file's recorded 0.2 s would hide a mistake in one of them.

    Examples
    --------
    >>> overridden({"option": None, "site file": 0.5, "model file": 0.2}, "s",
    ...            Fact(0.5, "site file"))
    ["the model file gives 0.2 s, not the site file's 0.5 s used"]
    """
    return [
        f"the {basis} gives {value:g} {unit}, not the {kept.basis}'s {kept.value:g} {unit} used"
        for basis, value in facts.items()
        if value is not None and basis != kept.basis and not math.isclose(value, kept.value)
    ]


@dataclass(frozen=True)
class Spans:
    """The spans that turn V per L/min into %/%, or why there are none."""

    u_span: Fact | None
    """Drive signal span [V]."""
    y_span: Fact | None
    """Flowmeter span [L/min]."""

    @property
    def known(self) -> bool:
        """Both spans come from the user's facts."""
        return self.u_span is not None and self.y_span is not None

    @property
    def basis(self) -> Basis | list[Basis] | None:
        """What the %/% gains rest on: one basis, the two spans' when they differ, or None."""
        if self.u_span is None or self.y_span is None:
            return None
        if self.u_span.basis == self.y_span.basis:
            return self.u_span.basis
        return [self.u_span.basis, self.y_span.basis]

    @property
    def missing_reason(self) -> str | None:
        """Why the %/% gains are not given (None when both spans are known)."""
        missing = [
            text
            for fact, text in (
                (self.u_span, "the drive span (--u-span [V])"),
                (self.y_span, "the meter span (--flow-span [L/min])"),
            )
            if fact is None
        ]
        if not missing:
            return None
        return (
            f"spans not given: {' and '.join(missing)}, or a plant file (--config) or a site "
            "file with [controller] u_span_V and y_span_Lpm (--site)"
        )

    def to_json(self) -> dict[str, object]:
        """``{"u_span": Fact | null, "y_span": Fact | null, "reason": str | null}``."""
        return {
            "u_span": None if self.u_span is None else self.u_span.to_json(),
            "y_span": None if self.y_span is None else self.y_span.to_json(),
            "reason": self.missing_reason,
        }


def spans_from(
    u_option: float | None,
    y_option: float | None,
    site: tuple[float | None, float | None] = (None, None),
    plant_file: tuple[float, float] | None = None,
) -> Spans:
    """The drive [V] and meter [L/min] spans: options, else the site file's, else the plant file's.

    ``site`` is the site file's ``[controller]`` (u_span_V, y_span_Lpm); ``plant_file`` the
    user's plant file's (drive range, meter span), None when the built-in reference plant stands
    in: its spans are not the user's, so a span nothing gives stays unknown.

    Examples
    --------
    >>> spans_from(None, 30.0).missing_reason.startswith("spans not given: the drive span")
    True
    >>> spans_from(None, 30.0, plant_file=(4.0, 100.0)).u_span
    Fact(value=4.0, basis='plant file')
    """
    found: list[Fact | None] = []
    for index, option in enumerate((u_option, y_option)):
        candidates: tuple[tuple[float | None, Basis], ...] = (
            (option, "option"),
            (site[index], "site file"),
            (None if plant_file is None else plant_file[index], "plant file"),
        )
        found.append(next((Fact(float(v), b) for v, b in candidates if v is not None), None))
    return Spans(u_span=found[0], y_span=found[1])


DETERMINED_PARAMETERS = ("K", "T", "delay")
"""The parameters whose intervals decide whether a model can be tuned (issue 37)."""


def undetermined(
    model: Mapping[str, float],
    ci95: Mapping[str, tuple[float, float] | None],
    fixed: tuple[str, ...] = (),
) -> list[str]:
    """K, T or the dead time whose 95 % interval is unbounded or wider than the value itself.

    (The dead time's against the larger of its value and a tenth of T: :func:`_scale`.)

    Such a model says nothing about the loop: its gains would be a guess. Fixed (prior)
    parameters (``fixed``) are not judged; an estimated one without an interval (its standard
    error did not exist: the data do not determine it) is unbounded. A parameter absent from
    ``ci95`` is not judged (a model given by its numbers alone). Returns one phrase per
    parameter, e.g. ``"T = 0.005 s (95 % interval 2e-39 … 1.2e+34 s)"``; empty when the model
    is determined.

    Examples
    --------
    >>> undetermined({"K": 13.7, "T": 0.005}, {"K": (13.6, 13.8), "T": (2e-39, 1.2e34)})
    ['T = 0.005 s (95 % interval 2e-39 … 1.2e+34 s)']
    """
    found = []
    for name in DETERMINED_PARAMETERS:
        if name in fixed or name not in ci95 or name not in model:
            continue
        interval = ci95[name]
        value = model[name]
        unit = "(L/min)/V" if name == "K" else "s"
        if interval is None:
            found.append(
                f"{name} = {value:.3g} {unit} (no interval: its standard error is not finite)"
            )
            continue
        low, high = interval
        if not (math.isfinite(low) and math.isfinite(high)) or high - low > _scale(
            name, value, model
        ):
            found.append(
                f"{name} = {value:.3g} {unit} (95 % interval {low:.3g} … {high:.3g} {unit})"
            )
    return found


LEADING_RESPONSE = (
    "the flow moves before its command (diagnostics.lead): a reversed clock or swapped input "
    "and output columns; no model or gains from this log: check the time column and which "
    "column is the command (--input-col) and which the flow (--output-col)"
)
"""Why a log whose response leads its cause gives no model of the loop (never overridden)."""


DELAY_SCALE = 0.1
"""A dead time is judged against its value or a tenth of the main lag T, whichever is larger."""


def _scale(name: str, value: float, model: Mapping[str, float]) -> float:
    """The width an interval may have before its parameter is undetermined.

    The parameter's own value, except for the dead time, which may be nought: a dead time
    of 0 … 4 ms in a loop whose lag is 1.2 s is known well enough to tune it (the PI rules
    weigh θ against T), so its interval is judged against a tenth of T too.
    """
    if name == "delay" and "T" in model:
        return max(abs(value), DELAY_SCALE * abs(model["T"]))
    return abs(value)


def undetermined_refusal(found: list[str], what: str) -> str:
    """The one-line refusal (or, accepted, the warning) for an undetermined model."""
    return (
        f"{what} is not determined by its data: {'; '.join(found)}; gains from it would be a "
        "guess: give a log with larger or more command steps, or fix a prior"
    )


def undetermined_refusal_line(found: list[str], what: str) -> str:
    """The refusal with its way out, as a one-line error."""
    return undetermined_refusal(found, what) + " (--accept-undetermined to tune anyway)"
