"""The PLC's applied gains as the recorder reads them, kept in the store for other processes.

With ``[tags.kc]`` and ``[tags.ti]`` in the site file the recorder reads the gains the PLC's PI
block applies with every poll. The online service uses them in its own process (the recorder's
``latest``); the dashboard and ``fuelid online status`` run in others, so the store keeps the
latest reading under the ``online_state`` key :data:`PLC_GAINS_KEY`. Cheaply: only the first
reading of a recorder's run and each change (either gain by more than :data:`CHANGE_RTOL`,
as the ``gain_change`` event), never every poll; a reading that is not a number is not kept.

**Units: the block's.** The tags hold the two numbers as the PLC's block holds them (after the
tag's raw → eng scaling), in the form and units of the site's ``[controller]`` table
(:class:`fuelid.tuning._block.BlockForm`): ``kc`` in V per L/min or in %/% (the kc tag's
``unit`` must say which), ``ti`` the integral time in s or min, or in the parallel form the
integral *gain* Ki. They are the ideal form [V per L/min, s] only for the default block
(ideal, engineering, s). The stored value says so (``units = "block"``, with the tags' own
``unit`` strings); converting to the ideal form is the reader's
(:func:`fuelid.tuning._block.from_block`): the PLC layer computes nothing.

The stored value::

    {"kc": 0.05, "ti": 2.0,            # as read, in the block's units
     "units": "block", "tag_units": {"kc": "V per L/min", "ti": "s"},
     "time": 1.7e9,                    # plant time of the reading [s UTC]
     "wall_time": 1.7e9}               # wall clock when it arrived [s UTC]

``time`` is on the samples' time base (the sample the reading was taken at); since only changes
are kept, it is when these values were first seen, and they held at least until the newest
sample of that run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fuelid.plc.site import SiteConfig

__all__ = [
    "BLOCK_UNITS",
    "CHANGE_RTOL",
    "GAIN_ROLES",
    "PLC_GAINS_KEY",
    "GainReadings",
    "gain_change_text",
    "stamped",
]

PLC_GAINS_KEY = "plc_gains"
"""The ``online_state`` key of the newest reading of the PLC's kc and ti."""
GAIN_ROLES = ("kc", "ti")
"""The read roles of the block's two gains."""
CHANGE_RTOL = 1e-6
"""A gain that moves by more than this (relative) is a change [-]."""
BLOCK_UNITS = "block"
"""The ``units`` of a stored reading: the PLC block's, as ``[controller]`` names them."""


def _unit(site: SiteConfig, role: str) -> str:
    """The tag's own unit string, or words saying whose units they are."""
    tag = site.tags.get(role)
    return tag.unit if tag is not None and tag.unit else "(the block's units)"


def gain_change_text(
    new: Mapping[str, float], old: Mapping[str, float], units: Mapping[str, str]
) -> str:
    """``kc 0.05 → 0.08 V per L/min, ti 2 → 3 s``: the gains that changed; "" when none did.

    Parameters
    ----------
    new, old : mapping
        The roles' values now and before, in the block's units (a role missing or not a
        number on either side is not compared).
    units : mapping
        Each role's unit text.

    Examples
    --------
    >>> gain_change_text({"kc": 0.08, "ti": 2.0}, {"kc": 0.05, "ti": 2.0}, {"kc": "%/%"})
    'kc 0.05 → 0.08 %/%'
    """
    changes = []
    for role in GAIN_ROLES:
        now, before = new.get(role), old.get(role)
        if now is None or before is None or not math.isfinite(now):
            continue
        if not math.isclose(now, before, rel_tol=CHANGE_RTOL, abs_tol=0.0):
            changes.append(f"{role} {before:.6g} → {now:.6g} {units.get(role, '')}".rstrip())
    return ", ".join(changes)


class GainReadings:
    """Which readings of the PLC's kc and ti the store keeps: the first and each change.

    Parameters
    ----------
    site : SiteConfig
        The site file; readings are kept only when it reads both ``kc`` and ``ti``.

    Attributes
    ----------
    units : dict of str to str
        Each gain tag's unit text (the tag's ``unit``, else "(the block's units)").
    pending : dict or None
        A reading the recorder holds until the next sample gives its plant time.
    """

    def __init__(self, site: SiteConfig) -> None:
        self.active = all(role in site.tags for role in GAIN_ROLES)
        self.units = {role: _unit(site, role) for role in GAIN_ROLES}
        self.pending: dict[str, Any] | None = None
        self._kept: tuple[float, float] | None = None

    def new(self, values: Mapping[str, float], wall: float) -> dict[str, Any] | None:
        """The reading to keep, without its plant ``time``; None when it is not new.

        Parameters
        ----------
        values : mapping
            A reading's roles (engineering values, the block's units for kc and ti).
        wall : float
            When the reading arrived [s UTC wall clock].
        """
        if not self.active:
            return None
        kc, ti = (float(values.get(role, math.nan)) for role in GAIN_ROLES)
        if not (math.isfinite(kc) and math.isfinite(ti)):
            return None
        kept = self._kept
        if kept is not None and all(
            math.isclose(a, b, rel_tol=CHANGE_RTOL, abs_tol=0.0)
            for a, b in zip((kc, ti), kept, strict=True)
        ):
            return None
        self._kept = (kc, ti)
        return {
            "kc": kc,
            "ti": ti,
            "units": BLOCK_UNITS,
            "tag_units": dict(self.units),
            "wall_time": float(wall),
        }


def stamped(reading: Mapping[str, Any], t: float | None) -> dict[str, Any]:
    """The reading with its plant ``time`` [s UTC]: ``t``, or its wall time when None.

    None on a receipt time base, where the samples are timed by the wall clock too.

    Examples
    --------
    >>> stamped({"kc": 0.05, "wall_time": 10.0}, None)["time"], stamped({"wall_time": 1}, 7)["time"]
    (10.0, 7.0)
    """
    return {**reading, "time": float(reading["wall_time"] if t is None else t)}
