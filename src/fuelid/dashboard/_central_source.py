"""One loop of the central store, read as the dashboard reads a store file (``LoopReader``).

The fleet page, the loop and window pages, the API and the stream read a central loop exactly as
they read a store file: :class:`CentralLoop` runs the SAME report functions (``status_json``,
``history_json``, ``window_json``, ``proposal_json`` of :mod:`fuelid.online`, through
:func:`~fuelid.dashboard._source.loop_status` and :func:`~fuelid.dashboard._source.loop_history`)
over two small views of the central rows, :class:`fuelid.central.CentralHistory` (a
:class:`~fuelid.store.LoopHistory`) and :class:`fuelid.central.CentralStoreView` (a
:class:`~fuelid.store.LoopStore`), so the shapes cannot drift apart. A loop whose store file
was replaced has several stores centrally; the newest one (by the central
``stores.last_seen``) is shown, as a central request is checked against it
(:func:`fuelid.central.file_central_request`).

**Liveness from the centre.** The site's service record arrives with every send (the liveness
row), so its beat is as old as the last send. The loop's state is judged as of the site's own
clock at that send (``site_wall``: the state the site itself would have shown then), and the
age of the contact decides whether that still holds: a liveness row older than
:data:`NO_CONTACT_SENDS` send intervals (at least :data:`NO_CONTACT_MIN_S`) means "no contact
with the site" (state ``no_contact``), never "service stopped": the site may run on while its
network is down. A service the site reported stopped (a clean stop) stays "stopped", said as
"service stopped at HH:MM:SS (N ago)": its age counts from the stop to now (the site's clock up
to its last send, then the contact's age on the centre's clock), not to the last sync.

**Samples.** The central store holds none: raw samples stay at the site. Without an archive
:meth:`CentralLoop.span` is None and the trend empty; with ``--archive DIR`` the trend reads the
loop's Parquet days (:class:`fuelid.archive.ArchiveLoop`), the level of detail computed
from them in numpy (min and max per bucket as the store's ``samples_lod``). Nothing is streamed
live from a central loop: the status is re-read every few seconds.

**Actions.** :meth:`CentralLoop.file_request` files a central request with what the page showed
of the proposal (status and history length); the site's service fetches it at its next sync,
files it locally and carries it out (:class:`fuelid.online.CentralLink`), or refuses it when the
proposal changed meanwhile; a request no site fetches before its expiry is never applied. The
test signal's start and stop are relayed like a revert (central schema version 4): the site
applies them as its own dashboard's (a start with no service running is refused, a stop is
done: the PLC holds the signal at 0). One request per proposal (and one of each kind that
refers to none: a revert, a start, a stop) waits at a time: a second is refused with a
one-line reason while the first waits (unfetched and unexpired, or fetched and being carried
out). The loop's central requests, with their expiry and outcome, are in ``status()["central"]
["requests"]``.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fuelid.central import (
    DEFAULT_EXPIRY_S,
    EXCITE_START_EXPIRY_S,
    CentralDB,
    CentralHistory,
    CentralStoreView,
    central_requests,
    file_central_request,
    liveness_row,
    newest_store,
    shown_store,
)
from fuelid.dashboard._source import (
    TREND_COLUMNS,
    loop_history,
    loop_status,
    service_plant_file,
)
from fuelid.dashboard._views import is_waiting
from fuelid.errors import FuelidError
from fuelid.io import format_age, format_time
from fuelid.store import SERVICE_KEY, SampleArrays, StoreError

__all__ = [
    "DEFAULT_SEND_EVERY_S",
    "NO_CONTACT_MIN_S",
    "NO_CONTACT_SENDS",
    "CentralLoop",
    "contact_link",
]

NO_CONTACT_SENDS = 3.0
"""A liveness row older than this many of the site's send intervals means no contact [-]."""
NO_CONTACT_MIN_S = 30.0
"""… and older than this at least [s of wall time] (a send of a long backlog takes a while)."""
DEFAULT_SEND_EVERY_S = 5.0
"""The send interval assumed when the site did not tell it (``[central] send_every_s``) [s]."""
CENTRAL_REQUESTS_SHOWN = 20
"""The newest central requests of a loop its status carries."""


def contact_link(
    link: dict[str, Any],
    liveness: dict[str, Any] | None,
    service: Any,
    now: float | None,
    tz: str,
) -> dict[str, Any]:
    """The link as seen from the centre: the site's state at its last send, or no contact.

    Parameters
    ----------
    link : dict
        :func:`fuelid.online._liveness.link_json` as of the site's clock at its last send.
    liveness : dict or None
        The liveness row (None: the site never told its liveness).
    service : dict or None
        The service record the site sent.
    now : float or None
        The wall clock now [s UTC]; None: the contact's age on the central store's own clock
        (``now() - updated``: no skew between the dashboard's clock and the database's).
    tz : str
        The loop's time zone (for the time of the last sync in the text).

    Returns
    -------
    dict
        ``link`` with ``contact_wall`` (the central time of the last send [wall s UTC]),
        ``contact_age_s`` and ``no_contact_after_s`` [s]; with no contact ``state``
        "no_contact", its ``text``, and ``state_at_contact`` (the state then); a service the
        site said stopped: the stop's time and ``stopped_age_s`` (from the stop to now [s]).
    """
    if liveness is None:
        return {
            **link,
            "state": "no_contact",
            "state_at_contact": None,
            "contact_wall": None,
            "contact_age_s": None,
            "no_contact_after_s": None,
            "text": "no contact with the site yet (it never sent its liveness)",
        }
    updated = float(liveness["updated"])
    age = max(0.0, (now - updated) if now is not None else float(liveness["contact_age_s"]))
    every = liveness.get("send_every_s") or DEFAULT_SEND_EVERY_S
    limit = max(NO_CONTACT_SENDS * float(every), NO_CONTACT_MIN_S)
    out = {**link, "contact_wall": updated, "contact_age_s": age, "no_contact_after_s": limit}
    # the site said its service stopped (or never ran): nothing more is expected from it
    told_stopped = not isinstance(service, dict) or service.get("stopped") is not None
    stopped_at = _stop_time(service)
    if told_stopped and link.get("state") == "stopped" and stopped_at is not None:
        # a clean stop is a fact, not a state as of the sync: its age runs from the stop to
        # now, the site's clock up to its last send plus the contact's age on the centre's
        site_wall = float(liveness.get("site_wall") or updated)
        since = (site_wall - stopped_at) + age
        out["text"] = (
            f"service stopped at {_clock_time(stopped_at, tz, since)} "
            f"({format_age(since)} ago, wall clock)"
        )
        out["stopped_age_s"] = since
        return out
    if age <= limit or (told_stopped and link.get("state") == "stopped"):
        out["text"] = f"{link.get('text')}, as of the site's last sync {format_age(age)} ago"
        return out
    return {
        **out,
        "state": "no_contact",
        "state_at_contact": link.get("state"),
        "since": updated,
        "text": (
            f"no contact with the site for {format_age(age)} (last sync "
            f"{format_time(updated, tz)}, wall clock; then: {link.get('text')})"
        ),
    }


def _stop_time(service: Any) -> float | None:
    """The wall time the site's service said it stopped [s UTC]; None when it did not."""
    if not isinstance(service, dict):
        return None
    value = service.get("stopped")
    if isinstance(value, int | float) and math.isfinite(value):
        return float(value)
    return None


def _clock_time(t: float, tz: str, age: float) -> str:
    """``HH:MM:SS ZONE`` within the day, the date as well when older.

    >>> _clock_time(1_795_767_303.4, "UTC", 72.0)
    '08:15:03 UTC'
    >>> _clock_time(1_795_767_303.4, "UTC", 200_000.0)
    '2026-11-27 08:15:03 UTC'
    """
    text = format_time(t, tz)
    return text if age >= 86_400.0 else text.split(" ", 1)[1]


class CentralLoop:
    """One loop of the central store as a :class:`~fuelid.dashboard._source.LoopReader`.

    Parameters
    ----------
    db : CentralDB
        The central store (shared by every central loop of the dashboard).
    loop_id : str
        The loop.
    archive : Path, optional
        The raw archive the trend reads (the folder ``fuelid archive`` writes); None: no samples.
    expires_s : float
        How long a request filed here waits for the site [s of wall time].
    """

    def __init__(
        self,
        db: CentralDB,
        loop_id: str,
        *,
        archive: Path | None = None,
        expires_s: float = DEFAULT_EXPIRY_S,
    ) -> None:
        self.db = db
        self.loop_id = loop_id
        self.archive_root = archive
        self.expires_s = float(expires_s)
        self._archive: Any = None
        self._archive_note: str | None = None

    # --- the central rows ---------------------------------------------------------------

    def _views(self) -> tuple[CentralHistory, CentralStoreView, dict[str, Any] | None]:
        store = shown_store(self.db, self.loop_id)
        live = liveness_row(self.db, store["store_uuid"])
        history = CentralHistory(self.db, store["store_uuid"], live or {})
        return history, CentralStoreView(self.db, store, live or {}), live

    # --- LoopReader -----------------------------------------------------------------------

    def identity(self) -> dict[str, Any]:
        """The loop's identity, as a store file's and with where its samples are.

        ``loop_id``, ``site_name``, ``schema_version``, ``store_uuid``, ``period_s``, and
        ``source`` ("central") with ``samples_note`` (where the raw samples are).
        """
        with self.db.reading():
            store = shown_store(self.db, self.loop_id)
            live = liveness_row(self.db, store["store_uuid"]) or {}
        period = live.get("period_s")
        if period is None:
            sampling = ((live.get("service") or {}).get("settings") or {}).get("sampling") or {}
            period = sampling.get("period_s")
        return {
            "loop_id": self.loop_id,
            "site_name": store["site_name"],
            "schema_version": live.get("schema_version"),
            "store_uuid": store["store_uuid"],
            "period_s": period,
            "source": "central",
            "samples_note": self.samples_note(),
        }

    def status(self, now_wall: float | None = None) -> dict[str, Any]:
        """The loop now, by :func:`~fuelid.dashboard._source.loop_status` over the central rows.

        The state is judged as of the site's clock at its last send (:func:`contact_link`);
        ``central`` is the centre's view of the sync (the last contact, the backlog the site
        reported, the loop's central requests with their expiry and outcome).
        """
        with self.db.reading():
            history, view, live = self._views()
            as_of = _time.time() if now_wall is None else float(now_wall)
            if live is not None:
                as_of = float(live.get("site_wall") or live["updated"])
            out = loop_status(history, view, self.loop_id, as_of)
            requests = central_requests_of(self.db, self.loop_id)
        tz = str(out.get("timezone") or "UTC")
        now = None if now_wall is None else float(now_wall)
        out["link"] = contact_link(out["link"], live, history.state(SERVICE_KEY), now, tz)
        live = live or {}
        out["central"] = {
            "read_from": "central store",
            "contact_wall": live.get("updated"),
            "site_wall": live.get("site_wall"),
            "send_every_s": live.get("send_every_s"),
            "backlog_rows": live.get("backlog_rows"),
            "backlog_oldest_wall": live.get("backlog_oldest_wall"),
            "last_send_wall": live.get("last_send_wall"),
            "requests": requests,
        }
        return out

    def plant_file(self) -> str | None:
        """The plant file the site's service named (a path on the site's host, rarely here)."""
        with self.db.reading():
            history, _, _ = self._views()
            return service_plant_file(history)

    def history(self, windows: int | None = None) -> dict[str, Any]:
        """Everything the service did, by :func:`~fuelid.dashboard._source.loop_history`."""
        with self.db.reading():
            history, view, _ = self._views()
            return loop_history(history, view, self.loop_id, windows)

    def recent_events(self, limit: int) -> list[dict[str, Any]]:
        """The newest ``limit`` events the site sent, oldest first."""
        with self.db.reading():
            _, view, _ = self._views()
            rows = view.read_event_rows()
        return [
            {"time": r["time"], "kind": r["kind"], "detail": r["detail"]}
            for r in rows[-int(limit) :]
        ]

    def window(self, window_id: int) -> dict[str, Any] | None:
        """One window's row (``detail`` parsed); None when absent."""
        with self.db.reading():
            history, _, _ = self._views()
            return history.window(window_id)

    def recent_windows(self, limit: int) -> list[dict[str, Any]]:
        """The newest ``limit`` windows' rows, oldest first."""
        with self.db.reading():
            history, _, _ = self._views()
            return history.windows(limit=int(limit))

    def windows_of_models(self, model_ids: Sequence[int]) -> list[dict[str, Any]]:
        """The first window naming each of ``model_ids`` (one row per model), by id."""
        with self.db.reading():
            history, _, _ = self._views()
            return history.windows_of_models(model_ids)

    def requests(self) -> list[dict[str, Any]]:
        """The site's requests as its last send told them, oldest first.

        A request relayed from here has origin ``central:<id>`` there.
        """
        with self.db.reading():
            history, _, _ = self._views()
            return history.requests()

    def file_request(
        self,
        kind: str,
        proposal_id: int | None,
        who: str,
        why: str,
        seen: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """File a central request for the site's service to carry out (a relay, never a write).

        ``seen`` is the proposal as the page showed it (``status``, ``history_len``): the site
        refuses the request when the proposal changed since. The row comes back ``waiting``
        with its ``expires`` [wall s UTC] and ``relayed`` True.
        """
        seen = seen or {}

        def file(con: Any) -> dict[str, Any]:
            _refuse_a_second(con, self.loop_id, kind, proposal_id)
            return file_central_request(
                con,
                self.loop_id,
                kind,
                proposal_id,
                who,
                why,
                seen_status=seen.get("status"),
                seen_history_len=seen.get("history_len"),
                origin="dashboard",
                expires_s=(
                    min(self.expires_s, EXCITE_START_EXPIRY_S)
                    if kind == "excite_start"
                    else self.expires_s
                ),
            )

        return {**self.db.call(file), "relayed": True}

    # --- samples: the raw archive, when given ---------------------------------------------

    def _archive_loop(self) -> Any:
        if self.archive_root is None:
            return None
        if self._archive is None:
            from fuelid.archive import ArchiveLoop

            try:
                self._archive = ArchiveLoop(self.archive_root, self.loop_id)
                self._archive_note = None
            except StoreError as error:
                self._archive_note = " ".join(str(error).split())
                return None
        return self._archive

    def samples_note(self) -> str:
        """Where this loop's raw samples are, in one sentence."""
        if self.archive_root is None:
            return (
                "Raw samples stay at the site; start the dashboard with --archive DIR to draw "
                "them from the raw archive."
            )
        if self._archive_loop() is None:
            return f"No samples: {self._archive_note}"
        return (
            f"Samples from the raw archive {self.archive_root} (as far as it was archived; "
            "nothing is streamed live from a central loop)."
        )

    def span(self) -> tuple[float, float] | None:
        """First and newest archived sample time [plant s]; None without an archive."""
        archive = self._archive_loop()
        if archive is None:
            return None
        first, last = archive.first_time(), archive.last_time()
        return None if first is None or last is None else (float(first), float(last))

    def samples(self, t_from: float, t_to: float) -> SampleArrays:
        """Archived samples with ``t_from <= time < t_to`` [plant s]; none without an archive."""
        archive = self._archive_loop()
        if archive is None:
            return SampleArrays.from_rows([])
        out: SampleArrays = archive.read(t_from, t_to)
        return out

    def lod(self, level: int, t_from: float, t_to: float) -> dict[str, np.ndarray[Any, Any]]:
        """Min and max per bucket of ``level`` s of the archived samples (as ``samples_lod``)."""
        start = math.floor(t_from / level) * level
        raw = self.samples(start, t_to)
        t = np.asarray(raw.time, dtype=np.float64)
        bucket = np.floor(t / level) * level
        keys, starts, counts = np.unique(bucket, return_index=True, return_counts=True)
        out: dict[str, np.ndarray[Any, Any]] = {
            "bucket": keys.astype(np.float64),
            "n": counts.astype(np.float64),
            "bad": (
                np.add.reduceat((np.asarray(raw.quality) != 0).astype(np.float64), starts)
                if keys.size
                else np.zeros(0)
            ),
        }
        for name in TREND_COLUMNS:
            values = np.asarray(getattr(raw, name), dtype=np.float64)
            if keys.size:
                with np.errstate(invalid="ignore"):  # an all-NaN bucket is NaN (SQL's NULL)
                    out[f"{name}_min"] = np.fmin.reduceat(values, starts)
                    out[f"{name}_max"] = np.fmax.reduceat(values, starts)
            else:
                out[f"{name}_min"] = out[f"{name}_max"] = np.zeros(0)
        return out

    def cursor(self) -> int:
        """0: nothing is streamed from a central loop."""
        return 0

    def samples_after(self, cursor: int, limit: int) -> tuple[int, SampleArrays]:
        """No samples: the central store has none to stream (the archive is not live)."""
        return int(cursor), SampleArrays.from_rows([])

    def close(self) -> None:
        """Nothing of its own to close (the connection is the dashboard's)."""


_WHAT = {
    "revert": "a revert",
    "excite_start": "a start of the test signal",
    "excite_stop": "a stop of the test signal",
}
"""What a request that refers to no proposal is for, in the refusal of a second one."""


def _refuse_a_second(con: Any, loop_id: str, kind: str, proposal_id: int | None) -> None:
    """Refuse a request while one for the same proposal (or kind) still waits for the site.

    Two requests for one proposal would both be carried out or refused in turn; the person who
    filed the second one most likely did not see the first (its buttons are disabled meanwhile).

    Raises
    ------
    FuelidError
        A request for it waits (one line: which, by whom, until when).
    """
    store = newest_store(con, loop_id)
    now = _time.time()
    for r in central_requests(con, loop_id, "waiting"):
        same = r["proposal_id"] == proposal_id and (proposal_id is not None or r["kind"] == kind)
        if same and r.get("store_uuid") in (None, store) and is_waiting(r, now):
            what = _WHAT.get(kind, kind) if proposal_id is None else f"proposal #{proposal_id}"
            raise FuelidError(
                f"request {r['id']} ({r['kind']} by {r['who']}) for {what} already waits for "
                f"the site (expires {format_time(r['expires'], 'UTC')}, wall clock): one at a time"
            )


def central_requests_of(db: CentralDB, loop_id: str) -> list[dict[str, Any]]:
    """The loop's newest central requests, oldest first (times [wall s UTC])."""
    rows = db.call(lambda con: central_requests(con, loop_id))
    return rows[-CENTRAL_REQUESTS_SHOWN:]
