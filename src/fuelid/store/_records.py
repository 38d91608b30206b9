"""The records of a store: samples, events, re-flags, what a store holds, and its error.

Plain values shared by the store's interface (:mod:`fuelid.store._base`), its SQLite
implementation, the schema and the writer. Times are UTC seconds since the Unix epoch [s]; u in
V, y and the setpoint in L/min, the fuel temperature in °C (as the PLC gives it).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from enum import IntEnum
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.io.jsonsafe import json_ready

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class StoreError(FuelidError):
    """A store cannot be opened, belongs to another site, or refuses a write (one-line reason)."""


class Quality(IntEnum):
    """Quality of a sample, stored as its integer code."""

    OK = 0
    """Every value read fresh and in range."""
    STALE = 1
    """The PLC did not update the values since the last sample."""
    LINK_DOWN = 2
    """No answer from the PLC: the values are not measurements."""
    BAD_VALUE = 3
    """A value was NaN, infinite or out of its tag's range."""


EVENT_KINDS = (
    "link_down",
    "link_up",
    "gap",
    "gain_change",
    "restart",
    "site_mismatch",
    "prune",
)
"""Event kinds fuelid writes; others are stored as given (the column is free text)."""


class Sample(NamedTuple):
    """One sample as stored (the order is the column order of the ``samples`` table).

    Parameters
    ----------
    time : float
        Sample time, UTC seconds since the epoch [s].
    seq : int or None
        Sequence number (the PLC's counter, unwrapped to a monotonic integer by the recorder),
        None without a counter. A sample already stored with the same ``seq`` (or, without one,
        the same ``time``) is ignored, so a restart that re-sends samples adds no duplicates.
    u : float
        Input, the VFD command [V] (NaN when not measured).
    y : float
        Output, the flow [L/min].
    setpoint : float
        Flow setpoint [L/min] (NaN when the PLC does not expose it).
    fuel_temperature : float
        Fuel temperature [°C] (NaN when not exposed).
    mode : int or None
        0 = MAN, 1 = AUTO, None when not exposed.
    quality : int
        A :class:`Quality` code.
    excitation : float
        The test signal the PLC applied to its PI's output, read back [V] (NaN when not
        recorded; since store schema 5).
    run : int or None
        1 during a wind-tunnel run, else 0; None when not recorded (since store schema 5).
    """

    time: float
    seq: int | None
    u: float
    y: float
    setpoint: float = math.nan
    fuel_temperature: float = math.nan
    mode: int | None = None
    quality: int = Quality.OK
    excitation: float = math.nan
    run: int | None = None


_SAMPLE_COLUMNS = Sample._fields
SAMPLE_COLUMNS_SQL = ", ".join(Sample._fields)
"""The samples table's columns in :class:`Sample` order, for a ``SELECT`` whose rows
:meth:`SampleArrays.from_rows` reads (time, seq, u, y, …, quality, excitation, run): one list,
so a column added to the samples reaches every reader."""
"""The columns of a sample, in order (those of :class:`SampleArrays` too)."""


class Requalify(NamedTuple):
    """A change of quality of stored samples, applied in the writer's order (after the inserts).

    Samples with ``t_from <= time <= t_to`` [s UTC] whose quality is :attr:`Quality.OK` get
    ``quality``; samples already flagged keep their flag. The recorder uses it to flag the
    first seconds of a stuck flow once the stretch is recognised as stuck, so that it never
    holds samples back from the store.

    Parameters
    ----------
    t_from, t_to : float
        First and last sample time of the stretch [s UTC], both included.
    quality : int
        The new :class:`Quality` code.
    """

    t_from: float
    t_to: float
    quality: int = Quality.BAD_VALUE


class StateValue(NamedTuple):
    """A value for the store's ``online_state`` table, written in the writer's order.

    The recorder keeps the PLC's gains as read there (:mod:`fuelid.plc._gain_reading`), so that
    another process (the dashboard, ``fuelid online status``) can read them. The row's ``time``
    is the wall clock of the commit; put any plant time inside the value.

    Parameters
    ----------
    key : str
        The ``online_state`` key (non-empty); a later value replaces an earlier one.
    text : str
        The value as JSON text (:meth:`of` encodes it, NaN and ±inf as null).
    """

    key: str
    text: str

    @classmethod
    def of(cls, key: str, value: Any) -> StateValue:
        """``value`` under ``key``, encoded now: a value without a JSON form fails the caller.

        Not the writer's thread, whose error would only surface at its next call.

        Raises
        ------
        StoreError
            An empty key or a value without a JSON form.

        Examples
        --------
        >>> StateValue.of("plc_gains", {"kc": 0.05, "ti": float("nan")})
        StateValue(key='plc_gains', text='{"kc":0.05,"ti":null}')
        """
        if not isinstance(key, str) or not key:
            raise StoreError(f"a state key is a non-empty string, got {key!r}")
        try:
            plain = json_ready(value)
        except TypeError as error:
            raise StoreError(f"state {key!r} cannot be stored as JSON: {error}") from None
        return cls(key, json.dumps(plain, allow_nan=False, separators=(",", ":")))


class Event(NamedTuple):
    """One event of the recording.

    Parameters
    ----------
    time : float
        UTC seconds since the epoch [s].
    kind : str
        One of :data:`EVENT_KINDS` (link_down, link_up, gap, gain_change, restart, …).
    detail : str
        Free text (a reason, the gains, the gap's length).
    """

    time: float
    kind: str
    detail: str = ""


def _unknown() -> FloatArray:
    """A column not given: filled with NaN to the samples' length by ``__post_init__``."""
    return np.empty(0, dtype=np.float64)


@dataclass(frozen=True)
class SampleArrays:
    """Samples read back, one array per column, sorted by time.

    ``seq`` and ``mode`` are −1 where the sample has none; missing real values are NaN.
    ``time`` [s UTC], ``u`` [V], ``y`` and ``setpoint`` [L/min], ``fuel_temperature`` [°C],
    ``quality`` the :class:`Quality` codes; ``excitation`` the test signal applied [V] and
    ``run`` the wind-tunnel run flag (0.0 or 1.0), both floats, NaN where not recorded (and
    all NaN when not given: a caller that builds arrays without them need not know them).
    """

    time: FloatArray
    seq: IntArray
    u: FloatArray
    y: FloatArray
    setpoint: FloatArray
    fuel_temperature: FloatArray
    mode: IntArray
    quality: IntArray
    excitation: FloatArray = field(default_factory=_unknown)
    run: FloatArray = field(default_factory=_unknown)

    def __post_init__(self) -> None:
        n = int(np.size(self.time))
        for name in ("excitation", "run"):
            if np.size(getattr(self, name)) == 0 and n:
                object.__setattr__(self, name, np.full(n, np.nan))

    def __len__(self) -> int:
        return int(self.time.size)

    def take(self, index: slice | NDArray[Any]) -> SampleArrays:
        """The samples at ``index`` (a slice, an index or a boolean array), every column.

        Examples
        --------
        >>> a = SampleArrays.from_rows([(1.0, 0, 2.0, 40.0, None, None, 1, 0, 0.1, 1)] * 3)
        >>> b = a.take(slice(1, 3))
        >>> len(b), b.excitation.tolist(), b.run.tolist()
        (2, [0.1, 0.1], [1.0, 1.0])
        """
        return type(self)(**{name: getattr(self, name)[index] for name in _SAMPLE_COLUMNS})

    @classmethod
    def from_rows(cls, rows: Sequence[Sequence[Any]]) -> SampleArrays:
        """Arrays from rows in :class:`Sample` column order (None for SQL NULL)."""

        def floats(i: int) -> FloatArray:
            return np.array([math.nan if r[i] is None else r[i] for r in rows], dtype=np.float64)

        def ints(i: int) -> IntArray:
            return np.array([-1 if r[i] is None else r[i] for r in rows], dtype=np.int64)

        return cls(
            time=floats(0),
            seq=ints(1),
            u=floats(2),
            y=floats(3),
            setpoint=floats(4),
            fuel_temperature=floats(5),
            mode=ints(6),
            quality=ints(7),
            excitation=floats(8),
            run=floats(9),
        )


@dataclass(frozen=True)
class StoreInfo:
    """What a store holds (``fuelid store info``).

    Attributes
    ----------
    path : str
        Where the store is (file or URL).
    site_name, tag_map_hash : str
        The site the store belongs to and the SHA-256 of its tag map.
    schema_version : int
        Version of the store's schema.
    rows : int
        Samples stored.
    t_first, t_last : float or None
        Time of the first and last sample [s UTC] (None when empty).
    span_s : float
        ``t_last − t_first`` [s].
    gaps : int
        Breaks in the sample stream: jumps of the sequence number, or, for samples without one,
        intervals longer than 1.5 sample periods (when the period is known).
    missing_samples : int
        Samples missing inside the sequence-number gaps. A PLC restart leaves one sequence
        number out on purpose (a break readers see), and its ``restart`` event is timed at the
        first sample after it: a jump of the sequence at a sample that carries a ``restart``
        event at its exact time counts one number less (a jump of exactly 2 there is a gap
        with no sample missing), so this agrees with the recorder's count of lost samples.
    quality : dict
        Samples per quality name.
    events : dict
        Events per kind (``link_down`` and ``link_up`` are the link events).
    size_bytes : int
        Size on disk [B] (for SQLite the file and its write-ahead log).
    """

    path: str
    site_name: str
    tag_map_hash: str
    schema_version: int
    rows: int
    t_first: float | None
    t_last: float | None
    span_s: float
    gaps: int
    missing_samples: int
    quality: dict[str, int] = field(default_factory=dict)
    events: dict[str, int] = field(default_factory=dict)
    size_bytes: int = 0

    def to_json(self) -> dict[str, Any]:
        """Plain dictionary with a ``units`` map (for ``--json``)."""
        out = asdict(self)
        out["units"] = {"t_first": "s", "t_last": "s", "span_s": "s", "size_bytes": "B"}
        return out


@dataclass(frozen=True)
class PruneResult:
    """What :meth:`SampleStore.prune` did: samples deleted and kept before the cutoff [s UTC].

    ``kept_thinned`` counts the old samples thinning kept; ``kept_unarchived`` those kept
    whole because their day is not archived yet (0 without an archive).
    """

    cutoff: float
    deleted: int
    kept_thinned: int
    kept_unarchived: int = 0


def tag_map_hash(tag_map: Mapping[str, Any] | str) -> str:
    """SHA-256 (hex) of a tag map, the identity of a site's wiring.

    Parameters
    ----------
    tag_map : mapping or str
        The tag map as a plain dictionary (hashed as JSON with sorted keys, so key order does not
        matter) or as a string (hashed as UTF-8).

    Examples
    --------
    >>> tag_map_hash({"flow": {"address": "ir:20"}}) == tag_map_hash('{"flow":{"address":"ir:20"}}')
    True
    """
    text = (
        tag_map
        if isinstance(tag_map, str)
        else json.dumps(tag_map, sort_keys=True, separators=(",", ":"), default=str)
    )
    return hashlib.sha256(text.encode("utf-8")).hexdigest()
