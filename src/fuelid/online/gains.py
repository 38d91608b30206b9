"""PI gains in the ideal (ISA) form and engineering units, and the PLC block's form and units.

:class:`Gains` holds Kc [V per L/min] and Ti [s]; :func:`controller_to_ideal` and
:func:`ideal_to_controller` convert from and to the form and units of the PLC's block
(``[controller]``, :class:`fuelid.plc.site.Controller`).
"""

import math
from dataclasses import dataclass
from typing import Any

from fuelid._deprecated import warn_renamed
from fuelid.errors import FuelidError
from fuelid.plc.site import Controller

SECONDS_PER_MINUTE = 60.0
"""Seconds in a minute, for ``integral_unit = "min"`` [s/min]."""


@dataclass(frozen=True)
class Gains:
    """Ideal-form PI gains C(s) = Kc·(1 + 1/(Ti·s)) in engineering units.

    Attributes
    ----------
    Kc : float
        Proportional gain [V per L/min], > 0.
    Ti : float
        Integral (reset) time [s], > 0.
    """

    Kc: float
    Ti: float

    def __post_init__(self) -> None:
        for name in ("Kc", "Ti"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise FuelidError(f"PI gain {name} must be positive and finite, got {value}")

    def to_dict(self, *args: Any, **kwargs: Any) -> dict[str, float]:
        """Deprecated name of :meth:`to_json` (fuelid 0.2.0)."""
        warn_renamed(self, "to_dict")
        return self.to_json(*args, **kwargs)

    def to_json(self) -> dict[str, float]:
        """``{"Kc": ..., "Ti": ...}`` [V per L/min, s].

        Examples
        --------
        >>> Gains(0.05, 2.0).to_json()
        {'Kc': 0.05, 'Ti': 2.0}
        """
        return {"Kc": float(self.Kc), "Ti": float(self.Ti)}


def _gain_scale(controller: Controller) -> float:
    """Engineering gain per gain of the block: u_span/y_span for percent, else 1 [V per L/min]."""
    if controller.gain_units == "percent":
        if controller.u_span_V is None or controller.y_span_Lpm is None:
            raise FuelidError("percent gains need u_span_V and y_span_Lpm")
        return controller.u_span_V / controller.y_span_Lpm
    return 1.0


def _time_scale(controller: Controller) -> float:
    """Seconds per integral unit of the block [s]."""
    return SECONDS_PER_MINUTE if controller.integral_unit == "min" else 1.0


def controller_to_ideal(kc: float, ti: float, controller: Controller) -> Gains:
    """Gains as the PLC's block holds them → ideal form in engineering units.

    The block's two numbers ``kc`` and ``ti`` mean, by ``controller``:

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
    controller : Controller
        The site's ``[controller]`` table.

    Returns
    -------
    Gains
        Kc [V per L/min], Ti [s].

    Examples
    --------
    1.25 %/% with spans 4 V and 100 L/min is 0.05 V per L/min; Ki = 2.5 %/% per minute is
    Ti = 1.25/2.5 min = 30 s:

    >>> c = Controller(form="parallel", gain_units="percent", u_span_V=4.0, y_span_Lpm=100.0,
    ...                integral_unit="min")
    >>> g = controller_to_ideal(1.25, 2.5, c)
    >>> round(g.Kc, 12), round(g.Ti, 12)
    (0.05, 30.0)
    """
    if not (math.isfinite(kc) and kc > 0.0 and math.isfinite(ti) and ti > 0.0):
        raise FuelidError(f"the block's gains must be positive and finite, got kc={kc}, ti={ti}")
    Kc = kc * _gain_scale(controller)
    if controller.form == "parallel":
        Ti = kc / ti * _time_scale(controller)  # Ti = Kp/Ki, in the block's units: spans cancel
    else:
        Ti = ti * _time_scale(controller)
    return Gains(Kc=Kc, Ti=Ti)


def gain_units(controller: Controller | None) -> dict[str, str] | None:
    """The units of the block's two numbers, by what its registers hold: ``{"Kc", "Ti"}``.

    ``Kc`` is the proportional gain: ``"%/%"`` (``gain_units = "percent"``) or ``"V per L/min"``;
    ``Ti`` is the integral time in ``"s"`` or ``"min"`` (ideal form) or, in the parallel form,
    the integral gain Ki (the ``ti`` register holds Ki): the gain's unit per ``s`` or ``min``.
    None when the controller is unknown.

    Examples
    --------
    >>> gain_units(Controller())
    {'Kc': 'V per L/min', 'Ti': 's'}
    >>> gain_units(Controller(form="parallel", gain_units="percent", u_span_V=4.0,
    ...                       y_span_Lpm=100.0, integral_unit="min"))
    {'Kc': '%/%', 'Ti': '%/% per min'}
    """
    if controller is None:
        return None
    kc = "%/%" if controller.gain_units == "percent" else "V per L/min"
    if controller.form == "parallel":
        return {"Kc": kc, "Ti": f"{kc} per {controller.integral_unit}"}
    return {"Kc": kc, "Ti": controller.integral_unit}


def ideal_to_controller(gains: Gains, controller: Controller) -> tuple[float, float]:
    """Ideal-form engineering gains → the (kc, ti) the PLC's block takes.

    The inverse of :func:`controller_to_ideal` (see there for what kc and ti mean in each form).

    Parameters
    ----------
    gains : Gains
        Kc [V per L/min], Ti [s].
    controller : Controller
        The site's ``[controller]`` table.

    Returns
    -------
    tuple of float
        (kc, ti): Kc or Kp in ``gain_units``; Ti in ``integral_unit`` (ideal) or Ki in
        ``gain_units`` per ``integral_unit`` (parallel).

    Examples
    --------
    >>> c = Controller(gain_units="percent", u_span_V=4.0, y_span_Lpm=100.0)
    >>> kc, ti = ideal_to_controller(Gains(0.05, 2.0), c)
    >>> round(kc, 12), ti
    (1.25, 2.0)
    """
    kc = gains.Kc / _gain_scale(controller)
    ti_block = gains.Ti / _time_scale(controller)
    if controller.form == "parallel":
        return kc, kc / ti_block
    return kc, ti_block


__all__ = [
    "SECONDS_PER_MINUTE",
    "Gains",
    "controller_to_ideal",
    "gain_units",
    "ideal_to_controller",
]
