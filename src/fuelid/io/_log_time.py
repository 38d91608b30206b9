"""A log's time column as seconds: numbers, or date-time stamps as historians write them.

Historians and PLC panels export local time with or without a UTC offset, through the clock
changes, in many forms (``2026-03-28 01:58:30,104``, ``28.03.2026 01:58:30``,
``28-Mar-26 01:58:30``, ``03/28/2026 01:58:30 AM``). :func:`stamps_to_seconds` turns them into
seconds on one steady clock, UTC, or refuses them with a one-line
:class:`~fuelid.errors.DataError`:

* **explicit offsets** (``+01:00``, ``Z``), the same or changing within the log (a log through a
  clock change), are converted to UTC;
* **local stamps without an offset** are placed in the zone given (``StampFormat.timezone``, an
  IANA name; ``--timezone`` or a site file's ``[site] timezone``): the hour repeated at the
  autumn change is told apart by the rows' order (the first pass is summer time) or refused
  naming its rows; the hour skipped in spring is no gap. Without a zone they are read as a
  clock that never changes, and an hour-long step back (the autumn change) is refused;
* **the form** is guessed (ISO 8601, ``yyyy/mm/dd``, ``dd.mm.yyyy``, ``dd-Mon-yy``, slashed
  dates with or without AM/PM) or given as strptime codes (``StampFormat.time_format``,
  ``--time-format``). A slashed date whose day and month the stamps cannot tell apart (no field
  above 12) is read day first, or month first with AM/PM, and a note says which.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

import numpy as np
import pandas as pd

from fuelid.errors import DataError
from fuelid.io.tables import to_float
from fuelid.io.timeseries import FloatArray

__all__ = ["ANY_STAMPS", "StampFormat", "check_timezone", "stamps_to_seconds"]

_OFFSET = re.compile(r"(?:Z|[+-]\d{2}:?\d{2})$")
_SLASHED = re.compile(r"^(\d{1,2})/(\d{1,2})/(\d{2,4})[ T]")
_MONTH_NAME = re.compile(r"^\d{1,2}-[A-Za-z]{3}-\d{2,4}[ T]")
_AM_PM = re.compile(r"\s*[AaPp]\.?[Mm]\.?$")
CLOCK_CHANGE_S = 3600.0
"""The step of a daylight-saving clock change [s]."""
SAMPLE_STAMPS = 2000
"""Stamps looked at to guess the form."""


@dataclass(frozen=True)
class StampFormat:
    """How to read date-time stamps: the zone of stamps without an offset, their form.

    ``timezone`` is an IANA name (``Europe/Berlin``); ``time_format`` strptime codes
    (``%d-%b-%y %H:%M:%S``). None: no zone (a clock that never changes), the form guessed.
    """

    timezone: str | None = None
    time_format: str | None = None


ANY_STAMPS = StampFormat()
"""No zone, the form guessed: stamps read as they come."""


def check_timezone(name: str) -> ZoneInfo:
    """The zone of an IANA name, or a DataError naming the form expected.

    Examples
    --------
    >>> check_timezone("Europe/Berlin").key
    'Europe/Berlin'
    """
    try:
        return ZoneInfo(name.strip())
    except (ZoneInfoNotFoundError, ValueError):
        raise DataError(
            f"time zone {name!r} is not an IANA name (such as 'UTC', 'Europe/Berlin' or "
            "'America/Chicago')"
        ) from None


def stamps_to_seconds(
    series: pd.Series, form: StampFormat, name: str, source: str, notes: list[str]
) -> tuple[FloatArray, str | None]:
    """Time in seconds; date-time stamps become seconds from the first valid stamp (UTC).

    Returns the times (NaN where a cell is not a time) and the first stamp as text, or None
    when the column holds plain numbers.
    """
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        return _seconds(_in_utc(pd.Series(series), form, name, source, notes))
    if pd.api.types.is_numeric_dtype(series.dtype):
        if form.time_format is None:
            return to_float(series), None
        series = _digits(series)  # stamps of digits only (20260328015830) read as numbers
    text = series.astype(str).str.strip()
    if form.time_format is None:
        numbers = to_float(series)
        filled = int(np.count_nonzero(text.to_numpy() != ""))
        if 2 * int(np.count_nonzero(~np.isnan(numbers))) >= filled:
            return numbers, None  # mostly plain numbers (bad cells among them are refused later)
    stamps = _parse(text, form, name, source, notes)
    return _seconds(_in_utc(stamps, form, name, source, notes))


def _digits(series: pd.Series) -> pd.Series:
    """A numeric column as the text of its digits, for a time format to read."""
    if pd.api.types.is_integer_dtype(series.dtype):
        return series.astype("int64").astype(str)
    return series.map(lambda value: format(value, "f").rstrip("0").rstrip("."))


def _parse(
    text: pd.Series, form: StampFormat, name: str, source: str, notes: list[str]
) -> pd.Series:
    """The stamps as datetimes (NaT where a cell is not one), offsets kept as UTC."""
    filled = text[text != ""]
    sample = filled.iloc[:SAMPLE_STAMPS]
    sample = sample[sample.str.contains(r"\d")]  # not a row of units above the stamps
    with_offset = sample.str.contains(_OFFSET)
    if with_offset.any() and not with_offset.all():
        row = int(sample.index[int(np.argmin(with_offset.to_numpy()))]) + 1
        raise DataError(
            f"{source}: column {name!r} mixes stamps with and without a UTC offset (data row "
            f"{row}: {sample.loc[row - 1]!r}): export them all with offsets, or all without"
        )
    utc = bool(with_offset.any())
    if form.time_format is not None:
        return _parse_with_format(text, form.time_format, utc, name, source)
    if sample.empty:
        return pd.Series(pd.NaT, index=text.index)
    return _parse_guessed(text, sample, utc, notes)


def _parse_with_format(
    text: pd.Series, time_format: str, utc: bool, name: str, source: str
) -> pd.Series:
    """Stamps in the strptime form given; refused when the first one does not match it.

    A form without ``%f`` reads stamps with fractions of a second too (``.104`` or ``,104``).
    """
    try:
        if "%f" in time_format:
            stamps = pd.to_datetime(text, format=time_format, errors="coerce", utc=utc)
        else:
            decimal = text.str.replace(r"(\d{1,2}:\d{2}:\d{2}),(\d+)", r"\1.\2", regex=True)
            stamps = _strptime(decimal, time_format, utc)
    except ValueError as error:
        raise DataError(
            f"time format {time_format!r} is not valid strptime codes: {error}"
        ) from None
    valid = text != ""
    if valid.any() and stamps[valid].isna().iloc[0]:
        row = int(np.flatnonzero(valid.to_numpy())[0]) + 1
        raise DataError(
            f"{source}: column {name!r} data row {row} ({text.iloc[row - 1]!r}) does not match "
            f"the time format {time_format!r} (strptime codes such as %d.%m.%Y %H:%M:%S)"
        )
    return pd.Series(stamps, index=text.index)


def _parse_guessed(text: pd.Series, sample: pd.Series, utc: bool, notes: list[str]) -> pd.Series:
    """Stamps in a form guessed from the first ones: ISO 8601 and its regional cousins."""
    first = str(sample.iloc[0])
    fraction = text.str.replace(r"(\d{1,2}:\d{2}:\d{2}),(\d+)", r"\1.\2", regex=True)
    if _MONTH_NAME.match(first):
        year = "%Y" if re.match(r"^\d{1,2}-[A-Za-z]{3}-\d{4}", first) else "%y"
        clock = _clock(first, bool(_AM_PM.search(first)))
        return _strptime(fraction, f"%d-%b-{year} {clock}", utc)
    slashed = _SLASHED.match(first)
    if slashed and len(slashed.group(3)) in (2, 4):
        return _strptime(fraction, _slashed_form(sample, notes), utc)
    iso = fraction.str.replace(
        r"^(\d{4})/(\d{1,2})/(\d{1,2})", r"\1-\2-\3", regex=True
    ).str.replace(r"^(\d{1,2})\.(\d{1,2})\.(\d{4})", r"\3-\2-\1", regex=True)
    return pd.Series(pd.to_datetime(iso, format="ISO8601", errors="coerce", utc=utc))


def _slashed_form(sample: pd.Series, notes: list[str]) -> str:
    """The strptime form of ``dd/mm/yyyy`` or ``mm/dd/yyyy`` stamps, from their fields.

    A first field above 12 is a day, a second one a month's day; when no stamp tells (every
    field up to 12), AM/PM says month first (the US form), otherwise day first, with a note.
    """
    fields = sample.str.extract(_SLASHED).astype(float)
    am_pm = bool(sample.str.contains(_AM_PM).any())
    year = "%Y" if len(str(sample.iloc[0]).split("/")[2].split()[0]) == 4 else "%y"
    clock = _clock(str(sample.iloc[0]), False).replace("%H", "%I" if am_pm else "%H")
    if (fields[0] > 12).any():
        day_first = True
    elif (fields[1] > 12).any():
        day_first = False
    else:
        day_first = not am_pm
        order = "day/month" if day_first else "month/day (with AM/PM)"
        other = _slashed(not day_first, year, clock, am_pm)
        notes.append(
            f"date stamps like {sample.iloc[0]!r} read as {order}: no day above 12 tells the "
            f"order; give --time-format '{other}' if that is wrong"
        )
    return _slashed(day_first, year, clock, am_pm)


def _clock(stamp: str, am_pm: bool) -> str:
    """The strptime form of a stamp's time of day: with seconds or without, 24 h or AM/PM.

    Examples
    --------
    >>> _clock("28/03/2026 13:58", False), _clock("3/28/2026 1:58:30 PM", True)
    ('%H:%M', '%I:%M:%S %p')
    """
    seconds = re.search(r"\d{1,2}:\d{2}:\d{2}", stamp) is not None
    hours = "%I" if am_pm else "%H"
    return f"{hours}:%M" + (":%S" if seconds else "") + (" %p" if am_pm else "")


def _slashed(day_first: bool, year: str, clock: str, am_pm: bool) -> str:
    """The strptime form of a slashed date: ``%d/%m/%Y %H:%M:%S`` and its cousins."""
    date = f"%d/%m/{year}" if day_first else f"%m/%d/{year}"
    return f"{date} {clock}" + (" %p" if am_pm else "")


def _strptime(text: pd.Series, form: str, utc: bool) -> pd.Series:
    """Stamps in ``form`` (without fractions of a second), fractions of a second allowed."""
    fraction = text.str.extract(r"(\.\d+)", expand=False).fillna("")
    whole = text.str.replace(r"\.\d+", "", regex=True).str.replace(
        r"\s*([AaPp])\.?([Mm])\.?$", r" \1\2", regex=True
    )
    stamps = pd.to_datetime(whole, format=form, errors="coerce", utc=utc)
    seconds = pd.to_numeric("0" + fraction, errors="coerce").fillna(0.0)
    micro = pd.to_timedelta(np.round(seconds.to_numpy(dtype=float) * 1e6), unit="us")
    return pd.Series(stamps + micro, index=text.index)


def _in_utc(
    stamps: pd.Series, form: StampFormat, name: str, source: str, notes: list[str]
) -> pd.Series:
    """Stamps on one steady clock: offsets as read, local ones placed in the zone given.

    A clock that still steps back by an hour is refused, and an hour-long jump forward of
    local stamps without a zone is named (the clock changes, :func:`_check_hour_steps`).
    """
    if stamps.dt.tz is not None:
        if form.timezone is not None:
            notes.append(
                f"time stamps carry UTC offsets: the time zone {form.timezone} is not needed"
            )
        elif stamps.notna().any():
            notes.append("time stamps with UTC offsets converted to UTC")
        steady = pd.Series(stamps.dt.tz_convert("UTC"))
        _check_hour_steps(steady, stamps, "with their UTC offsets", name, source, notes)
        return steady
    if form.timezone is None:
        _check_hour_steps(stamps, stamps, None, name, source, notes)
        return stamps
    steady = _localised(stamps, form.timezone, name, source, notes)
    _check_hour_steps(steady, stamps, f"in {form.timezone}", name, source, notes)
    return steady


def _localised(
    stamps: pd.Series, timezone: str, name: str, source: str, notes: list[str]
) -> pd.Series:
    """Local stamps in ``timezone`` as UTC; the repeated autumn hour told apart by row order."""
    zone = check_timezone(timezone)
    try:
        local = stamps.dt.tz_localize(zone, ambiguous="infer", nonexistent="raise")
    except Exception as error:  # pytz-style AmbiguousTimeError / NonExistentTimeError
        raise DataError(_localisation_refusal(stamps, zone, name, source, error)) from None
    notes.append(f"local time stamps in {zone.key} converted to UTC")
    return pd.Series(local.dt.tz_convert("UTC"))


def _localisation_refusal(
    stamps: pd.Series, zone: ZoneInfo, name: str, source: str, error: Exception
) -> str:
    """The one line for local stamps the zone cannot place: skipped or repeated, unordered."""
    skipped = (
        stamps.dt.tz_localize(zone, ambiguous="NaT", nonexistent="NaT").isna() & stamps.notna()
    )
    if "NonExistent" in type(error).__name__ or "nonexistent" in str(error).lower():
        rows = np.flatnonzero(skipped.to_numpy()) + 1
        return (
            f"{source}: column {name!r} data row {int(rows[0]) if rows.size else '?'} "
            f"({stamps.iloc[int(rows[0]) - 1] if rows.size else ''}) does not exist in "
            f"{zone.key}: it lies in the hour skipped at the spring clock change; is the log "
            f"in standard time all year? then give a fixed-offset zone ({_fixed_zone(zone)})"
        )
    rows = np.flatnonzero(skipped.to_numpy()) + 1
    where = f"data rows {int(rows[0])} to {int(rows[-1])}" if rows.size else "its rows"
    return (
        f"{source}: column {name!r}: the stamps in the hour repeated at the autumn clock change "
        f"in {zone.key} ({where}) cannot be told apart by their order: export in UTC or with "
        "UTC offsets"
    )


def _fixed_zone(zone: ZoneInfo) -> str:
    """The fixed-offset IANA zone of ``zone``'s standard time: ``Etc/GMT+5`` for UTC−5.

    Examples
    --------
    >>> _fixed_zone(ZoneInfo("America/New_York")), _fixed_zone(ZoneInfo("Europe/Berlin"))
    ('Etc/GMT+5 for UTC−5', 'Etc/GMT-1 for UTC+1')
    """
    offsets = [zone.utcoffset(datetime(2026, month, 1)) for month in (1, 7)]
    hours = min(offset.total_seconds() for offset in offsets if offset is not None) / 3600.0
    if hours != int(hours):
        return "an Etc/GMT zone of its standard offset"
    sign = "-" if hours > 0 else "+"  # IANA's Etc/GMT zones count west as positive
    shown = f"UTC+{int(hours)}" if hours >= 0 else f"UTC−{int(-hours)}"
    return f"Etc/GMT{sign}{abs(int(hours))} for {shown}"


def _check_hour_steps(
    steady: pd.Series,
    written: pd.Series,
    placed: str | None,
    name: str,
    source: str,
    notes: list[str],
) -> None:
    """Refuse a clock that steps back by an hour; name an hour-long jump forward.

    ``steady`` are the stamps on the clock they were placed on, ``written`` as read, ``placed``
    how they were placed (None: local, no zone given). A step back by an hour is the autumn
    clock change: without a zone the zone is missing, with one it is the wrong zone.
    """
    valid = steady.dropna()
    if valid.size < 2:
        return
    steps = np.diff((steady - valid.iloc[0]).dt.total_seconds().to_numpy(dtype=float))
    hour = np.abs(np.abs(steps) - CLOCK_CHANGE_S) <= 0.1 * CLOCK_CHANGE_S
    back = np.flatnonzero(hour & (steps < 0.0))
    if back.size:
        i = int(back[0])
        stamps = f"{written.iloc[i]} then {written.iloc[i + 1]}"
        why = (
            "local time through the autumn clock change; give the log's time zone (--timezone, "
            "an IANA name such as Europe/Berlin or Australia/Sydney) or export in UTC"
            if placed is None
            else f"even {placed}: is that the zone the log was written in?"
        )
        raise DataError(
            f"{source}: column {name!r} steps back by an hour at data row {i + 2} ({stamps}): {why}"
        )
    ahead = np.flatnonzero(hour & (steps > 0.0))
    if ahead.size:
        i = int(ahead[0])
        why = (
            "if that is the spring clock change, give the log's time zone (--timezone) and the "
            "hour is no gap"
            if placed is None
            else f"even {placed}: if the log was written in another zone, the hour is no gap"
        )
        notes.append(
            f"the time stamps jump forward by an hour between data rows {i + 1} and {i + 2} "
            f"({written.iloc[i]} then {written.iloc[i + 1]}): {why}"
        )


def _seconds(stamps: pd.Series) -> tuple[FloatArray, str | None]:
    """Seconds from the first valid stamp (NaN for NaT) and that stamp as text."""
    valid = stamps.dropna()
    if valid.empty:
        return np.full(len(stamps), np.nan), None
    start = valid.iloc[0]
    seconds = (stamps - start).dt.total_seconds()
    return np.asarray(seconds.to_numpy(dtype=float, na_value=np.nan), dtype=np.float64), str(start)
