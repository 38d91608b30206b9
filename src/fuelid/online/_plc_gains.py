"""The PLC's gains as the recorder read them, as ``fuelid online status --json`` gives them.

The recorder keeps the newest reading of the site's ``[tags.kc]`` and ``[tags.ti]`` in the
store's state (:mod:`fuelid.plc._gain_reading`: the first reading and each change, in the PLC
block's units, with its plant and wall time). :func:`plc_gains_json` shapes it for the status
object's ``plc_gains``: the block's numbers and units, as ``current_gains_block`` has them, and
the same gains in the ideal form [V per L/min, s] when the site's ``[controller]`` is known.
"""

from __future__ import annotations

import math
from typing import Any

from fuelid.errors import FuelidError
from fuelid.tuning import BlockForm, block_units, from_block

__all__ = ["plc_gains_json"]


def _number(value: Any) -> float | None:
    """A finite float, else None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _ideal(kc: float, ti: float, block: BlockForm | None) -> dict[str, float] | None:
    """The block's (kc, ti) in the ideal form ``{"Kc", "Ti"}`` [V per L/min, s]; None if not."""
    if block is None:
        return None
    try:
        Kc, Ti = from_block(kc, ti, block)
    except (ValueError, FuelidError):  # a gain of 0 or below: the PLC's, but no PI's
        return None
    return {"Kc": Kc, "Ti": Ti}


def plc_gains_json(reading: Any, controller: Any = None) -> dict[str, Any] | None:
    """The status' ``plc_gains`` from the stored reading; None when there is none.

    Parameters
    ----------
    reading : dict or None
        The store's ``plc_gains`` state (:mod:`fuelid.plc._gain_reading`); None when the site
        reads no kc and ti tags or nothing was read yet.
    controller : Controller or None
        The site's ``[controller]`` (its form and units); None: unknown, then ``units`` and
        ``ideal`` are None.

    Returns
    -------
    dict or None
        ``Kc``, ``Ti`` (as read, the block's units), ``units`` (``{"Kc", "Ti"}``, the block's:
        :func:`~fuelid.tuning._block.block_units`), ``ideal`` (``{"Kc", "Ti"}`` [V per L/min,
        s], None when the controller is unknown or a gain is not positive), ``tag_units`` (the
        tags' own ``unit``), ``time`` [plant s UTC: the reading that first showed these
        values] and ``wall_time`` [wall s UTC: when it arrived].

    Examples
    --------
    >>> from fuelid.plc.site import Controller
    >>> c = Controller(gain_units="percent", u_span_V=4.0, y_span_Lpm=100.0, integral_unit="min")
    >>> out = plc_gains_json({"kc": 1.25, "ti": 0.5, "time": 10.0, "wall_time": 11.0}, c)
    >>> out["units"], out["ideal"]
    ({'Kc': '%/%', 'Ti': 'min'}, {'Kc': 0.05, 'Ti': 30.0})
    >>> plc_gains_json(None) is None
    True
    """
    if not isinstance(reading, dict):
        return None
    kc, ti = _number(reading.get("kc")), _number(reading.get("ti"))
    if kc is None or ti is None:
        return None
    try:
        block = None if controller is None else BlockForm.of(controller)
    except FuelidError:
        block = None
    return {
        "Kc": kc,
        "Ti": ti,
        "units": None if block is None else block_units(block),
        "ideal": _ideal(kc, ti, block),
        "tag_units": reading.get("tag_units"),
        "time": _number(reading.get("time")),
        "wall_time": _number(reading.get("wall_time")),
    }
