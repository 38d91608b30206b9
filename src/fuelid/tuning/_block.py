"""The PLC's PI block: its form and units, and the one conversion of PI gains to and from them.

fuelid's PI gains are in the ideal (standard, ISA) form C(s) = Kc·(1 + 1/(Ti·s)) and engineering
units, Kc [V per L/min] and Ti [s] (:class:`~fuelid.tuning._rules.PISettings`). A PLC block may
hold them otherwise: in the parallel form Kp + Ki/s, with the gain in percent of span per percent
of span, with the integral time (or gain) per minute. :class:`BlockForm` says which (the site
file's ``[controller]`` table, :class:`fuelid.plc.site.Controller`, read by
:meth:`BlockForm.of`); :func:`to_block` and :func:`from_block` convert; :func:`block_units` names
the units of the block's two numbers. :func:`percent_of_span` is the one statement of the %/%
gain, Kc·y_span/u_span, that :meth:`~fuelid.tuning._rules.PISettings.plc_form` also uses.

The tuning layer reads no site file: :meth:`BlockForm.of` takes any object (or mapping) with the
``[controller]`` table's names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from fuelid.errors import FuelidError

SECONDS_PER_MINUTE = 60.0
"""Seconds in a minute, for ``integral_unit = "min"`` [s/min]."""

Form = Literal["ideal", "parallel"]
GainUnits = Literal["engineering", "percent"]
IntegralUnit = Literal["s", "min"]

_FORMS = ("ideal", "parallel")
_GAIN_UNITS = ("engineering", "percent")
_INTEGRAL_UNITS = ("s", "min")


@dataclass(frozen=True)
class BlockForm:
    """How a PLC's PI block holds its two numbers (kc, ti).

    Attributes
    ----------
    form : {"ideal", "parallel"}
        ``ideal``: kc = Kc, ti = Ti, u = Kc·(e + (1/Ti)·∫e dt); ``parallel``: kc = Kp, ti = **Ki**
        = Kp/Ti, the integral gain, u = Kp·e + Ki·∫e dt.
    gain_units : {"engineering", "percent"}
        ``engineering``: V per L/min; ``percent``: % of drive span per % of meter span.
    integral_unit : {"s", "min"}
        Ti in s or min (ideal), or Ki per s or per min (parallel).
    u_span : float or None
        Drive span [V] (4 V for a 1–5 V signal); needed by percent gains.
    y_span : float or None
        Meter span [L/min] (the flowmeter's full scale); needed by percent gains.

    Examples
    --------
    >>> BlockForm()
    BlockForm(form='ideal', gain_units='engineering', integral_unit='s', u_span=None, y_span=None)
    >>> BlockForm(gain_units="percent", u_span=4.0)
    Traceback (most recent call last):
    ...
    fuelid.errors.FuelidError: percent gains need both spans (u_span_V, y_span_Lpm), got 4.0, None
    """

    form: Form = "ideal"
    gain_units: GainUnits = "engineering"
    integral_unit: IntegralUnit = "s"
    u_span: float | None = None
    y_span: float | None = None

    def __post_init__(self) -> None:
        for name, value, allowed in (
            ("form", self.form, _FORMS),
            ("gain_units", self.gain_units, _GAIN_UNITS),
            ("integral_unit", self.integral_unit, _INTEGRAL_UNITS),
        ):
            if value not in allowed:
                raise FuelidError(f"block {name} is one of {', '.join(allowed)}, not {value!r}")
        for name, span in (("u_span", self.u_span), ("y_span", self.y_span)):
            if span is not None and not (math.isfinite(span) and span > 0.0):
                raise FuelidError(f"the block's {name} must be positive and finite, got {span}")
        if self.gain_units == "percent" and (self.u_span is None or self.y_span is None):
            raise FuelidError(
                "percent gains need both spans (u_span_V, y_span_Lpm), "
                f"got {self.u_span}, {self.y_span}"
            )

    @classmethod
    def of(cls, controller: Any) -> BlockForm:
        """The block form of a site file's ``[controller]`` table, or of anything named like it.

        Parameters
        ----------
        controller : object or mapping
            Anything with ``form``, ``gain_units``, ``integral_unit``, ``u_span_V`` and
            ``y_span_Lpm`` (attributes, or keys of a mapping such as the service record's
            ``controller``); a missing name takes the table's default.

        Examples
        --------
        >>> b = BlockForm.of({"form": "parallel", "gain_units": "percent", "u_span_V": 4.0,
        ...                   "y_span_Lpm": 100.0, "integral_unit": "min"})
        >>> b.form, b.gain_units, b.integral_unit, b.u_span, b.y_span
        ('parallel', 'percent', 'min', 4.0, 100.0)
        """
        if isinstance(controller, Mapping):
            get = controller.get
        else:

            def get(name: str, default: Any = None) -> Any:
                return getattr(controller, name, default)

        u_span, y_span = get("u_span_V"), get("y_span_Lpm")
        return cls(
            form=get("form") or "ideal",
            gain_units=get("gain_units") or "engineering",
            integral_unit=get("integral_unit") or "s",
            u_span=None if u_span is None else float(u_span),
            y_span=None if y_span is None else float(y_span),
        )

    @property
    def minutes(self) -> bool:
        """True when the block's integral is per minute."""
        return self.integral_unit == "min"

    @property
    def spans(self) -> tuple[float, float]:
        """(u_span [V], y_span [L/min]); refused when either is not given."""
        if self.u_span is None or self.y_span is None:
            raise FuelidError("percent gains need both spans (u_span_V, y_span_Lpm)")
        return self.u_span, self.y_span


def percent_of_span(Kc: float, u_span: float, y_span: float) -> float:
    """An engineering gain in percent of span per percent of span: Kc·y_span/u_span [%/%].

    The one statement of the %/% gain: :func:`to_block` and
    :meth:`~fuelid.tuning._rules.PISettings.plc_form` both call it.

    Parameters
    ----------
    Kc : float
        Proportional gain [V per L/min].
    u_span : float
        Drive span [V].
    y_span : float
        Meter span [L/min].

    Examples
    --------
    >>> percent_of_span(0.05, 4.0, 100.0)
    1.25
    """
    return Kc * y_span / u_span


def _engineering(kc: float, block: BlockForm) -> float:
    """The block's proportional gain in V per L/min: the inverse of :func:`percent_of_span`."""
    if block.gain_units == "percent":
        u_span, y_span = block.spans
        return kc * u_span / y_span
    return kc


def _time_scale(block: BlockForm) -> float:
    """Seconds per integral unit of the block [s]."""
    return SECONDS_PER_MINUTE if block.minutes else 1.0


def _positive(**values: float) -> None:
    bad = {k: v for k, v in values.items() if not (math.isfinite(v) and v > 0.0)}
    if bad:
        shown = ", ".join(f"{k}={v}" for k, v in values.items())
        raise FuelidError(f"PI gains must be positive and finite, got {shown}")


def from_block(kc: float, ti: float, block: BlockForm) -> tuple[float, float]:
    """Gains as the PLC's block holds them → ideal form in engineering units (Kc, Ti).

    The block's two numbers ``kc`` and ``ti`` mean, by ``block``:

    - ``form = "ideal"``: kc = Kc, ti = Ti, u = Kc·(e + (1/Ti)·∫e dt);
    - ``form = "parallel"``: kc = Kp, ti = **Ki** = Kp/Ti, the integral gain,
      u = Kp·e + Ki·∫e dt (the ``ti`` field holds Ki, not a time: Kc = Kp, Ti = Kp/Ki);
    - ``gain_units = "percent"``: Kp or Kc in % of drive span per % of meter span,
      Kc [V per L/min] = kc·u_span_V/y_span_Lpm; ``"engineering"``: V per L/min as is;
    - ``integral_unit = "min"``: Ti in minutes (ideal) or Ki per minute (parallel), else
      seconds; Ti [s] = 60·ti (ideal) or 60·kc/ti (parallel).

    Parameters
    ----------
    kc : float
        The block's proportional gain, in ``gain_units``.
    ti : float
        The block's integral time (ideal) in ``integral_unit``, or integral gain (parallel) in
        ``gain_units`` per ``integral_unit``.
    block : BlockForm
        The block's form and units (:meth:`BlockForm.of` of the site's ``[controller]``).

    Returns
    -------
    tuple of float
        (Kc [V per L/min], Ti [s]).

    Raises
    ------
    FuelidError
        On a gain that is not positive and finite.

    Examples
    --------
    1.25 %/% with spans 4 V and 100 L/min is 0.05 V per L/min; Ki = 2.5 %/% per minute is
    Ti = 1.25/2.5 min = 30 s:

    >>> b = BlockForm(form="parallel", gain_units="percent", u_span=4.0, y_span=100.0,
    ...               integral_unit="min")
    >>> Kc, Ti = from_block(1.25, 2.5, b)
    >>> round(Kc, 12), round(Ti, 12)
    (0.05, 30.0)
    """
    _positive(kc=kc, ti=ti)
    Kc = _engineering(kc, block)
    # parallel: Ti = Kp/Ki, both in the block's units (the spans cancel)
    Ti = (kc / ti if block.form == "parallel" else ti) * _time_scale(block)
    return Kc, Ti


def to_block(Kc: float, Ti: float, block: BlockForm) -> tuple[float, float]:
    """Ideal-form engineering gains → the (kc, ti) the PLC's block takes.

    The inverse of :func:`from_block` (see there for what kc and ti mean in each form).

    Parameters
    ----------
    Kc : float
        Proportional gain [V per L/min].
    Ti : float
        Integral time [s].
    block : BlockForm
        The block's form and units.

    Returns
    -------
    tuple of float
        (kc, ti): Kc or Kp in ``gain_units``; Ti in ``integral_unit`` (ideal) or Ki in
        ``gain_units`` per ``integral_unit`` (parallel).

    Raises
    ------
    FuelidError
        On a gain that is not positive and finite.

    Examples
    --------
    >>> b = BlockForm(gain_units="percent", u_span=4.0, y_span=100.0)
    >>> to_block(0.05, 2.0, b)
    (1.25, 2.0)
    """
    _positive(Kc=Kc, Ti=Ti)
    kc = percent_of_span(Kc, *block.spans) if block.gain_units == "percent" else Kc
    ti_block = Ti / _time_scale(block)
    if block.form == "parallel":
        return kc, kc / ti_block
    return kc, ti_block


def block_units(block: BlockForm) -> dict[str, str]:
    """The units of the block's two numbers, by what its registers hold: ``{"Kc", "Ti"}``.

    ``Kc`` is the proportional gain: ``"%/%"`` (``gain_units = "percent"``) or ``"V per L/min"``;
    ``Ti`` is the integral time in ``"s"`` or ``"min"`` (ideal form) or, in the parallel form,
    the integral gain Ki (the ``ti`` register holds Ki): the gain's unit per ``s`` or ``min``.

    Examples
    --------
    >>> block_units(BlockForm())
    {'Kc': 'V per L/min', 'Ti': 's'}
    >>> block_units(BlockForm(form="parallel", gain_units="percent", u_span=4.0, y_span=100.0,
    ...                       integral_unit="min"))
    {'Kc': '%/%', 'Ti': '%/% per min'}
    """
    kc = "%/%" if block.gain_units == "percent" else "V per L/min"
    if block.form == "parallel":
        return {"Kc": kc, "Ti": f"{kc} per {block.integral_unit}"}
    return {"Kc": kc, "Ti": block.integral_unit}


__all__ = [
    "SECONDS_PER_MINUTE",
    "BlockForm",
    "block_units",
    "from_block",
    "percent_of_span",
    "to_block",
]
