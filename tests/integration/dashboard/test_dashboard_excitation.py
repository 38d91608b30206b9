"""The test signal on the dashboard (issue 40): its line, its live note, its buttons, its note.

Each store is made here with the store's own API (no virtual run: the tests take a second): a
few samples, the service's record (``settings.excitation`` with ``possible``), the exciter's
state record (``online_state`` key "excitation") and its events, as a service that ran a burst
leaves them. A live service is played by a thread that beats and carries out the requests as
the service's beat does (:func:`fuelid.online._requests.consume_requests`).

The loop page and its re-read parts must show the same line (the one ``fuelid online status``
prints), the running burst's note and the events' texts; a viewer gets no buttons and a 403;
an engineer's start files an ``excite_start`` request with who and why, a start without a
reason is refused and files nothing, a start with no service running is refused in one line;
the fleet says "exciting" for a loop whose signal runs, and only then.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.dashboard import CSRF_HEADER, Loops, Security, UsersFile, create_app
from fuelid.dashboard._stream import changed_topics
from fuelid.online import consume_requests
from fuelid.online.excitation import REQUEST_KEY, STATE_KEY
from fuelid.store import SERVICE_KEY, Event, OnlineHistory, Sample, SQLiteStore

T0 = 1_767_225_600.0  # 2026-01-01T00:00:00Z, plant time
PERIOD_S = 0.02
N = 3000  # 60 s of samples
LOOP = "line-x"
STARTED = T0 + 18.0  # the burst's start: 42 s before the newest sample
DESIGN = {
    "kind": "gbn",
    "amplitude_V": 0.15,
    "hold_s": 8.0,
    "control_period_s": 0.1,
    "burst_s": 180.0,
    "window_s": 600.0,
    "seed": 7,
    "periods": 1800,
    "expected_rel_stderr": {"K": 0.03, "T": 0.1},
    "expected_fit_percent": 84.0,
    "added_flow_sd_Lpm": 0.08,
    "iae_per_window": 21.5,
    "needed_V": {"K": 0.1},
    "bound": "K",
}
REASON = "requested by eve: K unknown after the fuel change"
START_TEXT = (
    f"{REASON}; GBN ±0.15 V, mean hold 8 s, for 180 s; expected se(K) 3.0 %, se(T) 10.0 %, "
    "fit 84 %; cost +0.08 L/min sd, IAE 21.5 (L/min)·s per window"
)
END_TEXT = "the burst is done; the register is 0"
RUNNING_LINE = "exciting: ±0.15 V, 1 of 1 windows, cost +0.08 L/min sd"


def _service_record(*, running: bool, possible: bool = True) -> dict[str, Any]:
    now = time.time()
    return {
        "pid": 1,
        "host": "test",
        "started": now - 60.0,
        "beat": now if running else now - 3600.0,
        "beat_every_s": 2.0,
        "stopped": None if running else now - 3000.0,
        "settings": {
            "write_back": "approve",
            "timezone": "UTC",
            "window_s": 600.0,
            "excitation": {
                "mode": "when_unidentified",
                "target": "output",
                "amplitude": 0.2,
                "max_share": 0.3,
                "wait_after_move_s": None,
                "margin_to_limits": None,
                "possible": possible,
            },
        },
    }


def _exciter_record(*, running: bool) -> dict[str, Any]:
    burst = {"started": STARTED, "reason": REASON, "who": "eve", "design": DESIGN}
    earlier = {
        **burst,
        "started": T0 - 900.0,
        "reason": 'mode "always"',
        "who": "service",
        "ended": T0 - 720.0,
        "end_reason": "the burst is done",
    }
    return {
        "mode": "when_unidentified",
        "amplitude_V": 0.2,
        "state": "running" if running else "idle",
        "running": burst if running else None,
        "held": None,
        "last_start": STARTED,
        "bursts": [earlier],
    }


def make_store(path: Path, *, signal: bool, service: bool, possible: bool = True) -> Path:
    """A store as a service leaves it: samples, its record, the exciter's record and events.

    ``signal``: a burst runs (else the last one ended); ``service``: the service's beat is
    fresh (else it stopped an hour ago).
    """
    samples = [
        Sample(T0 + PERIOD_S * k, k, 2.0, 40.0, 40.0, 20.0, 1, excitation=0.0) for k in range(N)
    ]
    events = [Event(T0 - 900.0, "excitation_start", 'mode "always"; GBN ±0.15 V')]
    events.append(Event(T0 - 720.0, "excitation_end", END_TEXT))
    events.append(Event(STARTED, "excitation_start", START_TEXT))
    with SQLiteStore(
        path, site_name="tunnel 2 fuel loop", tag_map_hash="ab12", period_s=PERIOD_S, loop_id=LOOP
    ) as store:
        store.append(samples, events)
        with OnlineHistory(store) as history:
            history.add_window(
                t_from=T0,
                t_to=T0 + 59.0,
                accepted=False,
                reason="no excitation (no setpoint move, no command step)",
                T_fuel=20.0,
                u_mean=2.0,
                detail={
                    "excitation": {
                        "amplitude_V": 0.15,
                        "share": 0.7,
                        "added_flow_sd_Lpm": 0.07,
                        "added_iae": 18.0,
                    }
                },
            )
            history.set_state(SERVICE_KEY, _service_record(running=service, possible=possible))
            history.set_state(STATE_KEY, _exciter_record(running=signal))
    return path


@contextmanager
def live_service(path: Path) -> Iterator[None]:
    """A service's beat for the store: fresh beats, the waiting requests carried out."""
    stop = threading.Event()

    def beat() -> None:
        with SQLiteStore(path) as store, OnlineHistory(store) as history:
            while not stop.is_set():
                history.beat()
                consume_requests(history, "approve")
                stop.wait(0.05)

    thread = threading.Thread(target=beat, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(5.0)


@contextmanager
def dashboard(path: Path, users: UsersFile | None = None) -> Iterator[TestClient]:
    loops = Loops([path])
    try:
        security = Security(users, require_login=False)
        yield TestClient(create_app(loops, security))
    finally:
        loops.close()


def login(client: TestClient, name: str, token: str) -> str:
    """Log in; the session's CSRF token."""
    client.post("/login", data={"name": name, "token": token, "next": "/"})
    return str(client.get("/api/whoami").json()["csrf"])


@pytest.fixture
def users(tmp_path: Path) -> tuple[UsersFile, str, str]:
    """A users file with an engineer (eve) and a viewer (vic), and their tokens."""
    file = UsersFile(tmp_path / "users.json")
    return file, file.add("eve", "engineer"), file.add("vic", "viewer")


# --- what the page shows ----------------------------------------------------------------------


def test_the_loop_page_and_its_parts_show_the_line_and_the_running_burst(tmp_path: Path) -> None:
    db = make_store(tmp_path / "loop.db", signal=True, service=True)
    with dashboard(db) as client:
        page = client.get(f"/loops/{LOOP}").text
        parts = client.get(f"/loops/{LOOP}/parts").json()
    now = parts["html"]["now"]
    assert now in page  # one template for both
    assert set(parts["html"]) == {"proposals", "now", "windows", "events"}
    assert f'data-state="running">{RUNNING_LINE}</p>' in now
    # the live note: amplitude and hold, how long of the burst, expected, cost, the reason
    assert "±0.15 V (GBN) added to the PI output, mean hold 8 s" in now
    assert '<span id="excitation-elapsed">42 s of 3 min</span>' in now
    assert f'data-started="{STARTED}"' in now
    assert "se(K) 3.0 %, se(T) 10.0 %, fit 84 %" in now
    assert "+0.08 L/min sd, IAE 21.5 (L/min)·s per window" in now
    assert f"{REASON} <small>(by eve)</small>" in now
    # the last burst, and the events part with the bursts' own texts
    assert "the burst is done" in now
    events = parts["html"]["events"]
    assert START_TEXT in events
    assert END_TEXT in events
    # the note beside the loop's chips, and in the status event's data (the stream's topic)
    assert f'title="test signal">{RUNNING_LINE}</span>' in page
    assert parts["status"]["excitation"]["exciting"] is True
    # nobody logged in (require_login off, no users): no buttons
    assert 'data-kind="excite_start"' not in page
    assert 'data-kind="excite_stop"' not in page


def test_an_idle_signal_says_how_the_last_burst_ended_and_what_was_measured(
    tmp_path: Path,
) -> None:
    db = make_store(tmp_path / "loop.db", signal=False, service=True)
    with dashboard(db) as client:
        now = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
    assert (
        "when_unidentified, idle; last burst ±0.15 V, ended: the burst is done; "
        "measured +0.07 L/min sd in window 1"
    ) in now
    assert 'id="excitation-running"' not in now


def test_a_service_stopped_mid_burst_is_not_shown_exciting(tmp_path: Path) -> None:
    db = make_store(tmp_path / "loop.db", signal=True, service=False)
    with dashboard(db) as client:
        now = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
        fleet = client.get("/").text
    assert "the service stopped mid-burst: the PLC zeroes the signal" in now
    assert 'id="excitation-running"' not in now
    assert "exciting" not in fleet.replace('"exciting"', "")  # the hint names the word only


# --- the actions and their rights -------------------------------------------------------------


def test_a_viewer_gets_no_buttons_and_a_403(tmp_path: Path, users: Any) -> None:
    file, _, viewer = users
    db = make_store(tmp_path / "loop.db", signal=False, service=True)
    with dashboard(db, file) as client:
        assert (
            client.post(f"/api/loops/{LOOP}/excitation/start", data={"why": "x"}).status_code == 401
        )
        csrf = login(client, "vic", viewer)
        page = client.get(f"/loops/{LOOP}").text
        parts = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
        for action in ("start", "stop"):
            answer = client.post(
                f"/api/loops/{LOOP}/excitation/{action}",
                data={"why": "x"},
                headers={CSRF_HEADER: csrf},
            )
            assert answer.status_code == 403, action
        requests = client.get(f"/api/loops/{LOOP}/requests").json()["requests"]
    for html in (page, parts):
        assert "excite_start" not in html
        assert "excite_stop" not in html
    assert "Starting and stopping the test signal need an engineer's login." in parts
    assert requests == []


def test_an_engineers_start_files_an_excite_start_request_with_who_and_why(
    tmp_path: Path, users: Any
) -> None:
    file, engineer, _ = users
    db = make_store(tmp_path / "loop.db", signal=False, service=True)
    url = f"/api/loops/{LOOP}/excitation/start"
    with live_service(db), dashboard(db, file) as client:
        csrf = login(client, "eve", engineer)
        now = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
        assert client.post(url, data={"why": "x"}).status_code == 403  # no CSRF token
        missing = client.post(url, data={"why": "  "}, headers={CSRF_HEADER: csrf})
        assert client.get(f"/api/loops/{LOOP}/requests").json()["requests"] == []
        answer = client.post(url, data={"why": "K unknown"}, headers={CSRF_HEADER: csrf})
        requests = client.get(f"/api/loops/{LOOP}/requests").json()["requests"]
    # the start is offered (possible, the service runs, none runs), the stop is not
    assert 'data-kind="excite_start"' in now
    assert "start a test signal</button>" in now
    assert "at most ±0.2 V added to the PI output" in now
    assert 'data-kind="excite_stop"' not in now
    assert missing.status_code == 422
    assert "a reason (form field why) is required" in missing.json()["detail"]
    assert answer.status_code == 200, answer.text
    request = answer.json()["request"]
    assert (request["kind"], request["who"], request["why"]) == ("excite_start", "eve", "K unknown")
    assert request["proposal_id"] is None
    assert request["origin"] == "dashboard"
    assert request["status"] == "done"
    assert answer.json()["next"].startswith("start requested: the service starts the signal")
    assert [r["id"] for r in requests] == [request["id"]]
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        left = history.state(REQUEST_KEY)  # what the running service's exciter takes
    assert (left["action"], left["who"], left["why"]) == ("start", "eve", "K unknown")


def test_an_engineer_stops_a_running_signal_without_a_reason(tmp_path: Path, users: Any) -> None:
    file, engineer, _ = users
    db = make_store(tmp_path / "loop.db", signal=True, service=True)
    with live_service(db), dashboard(db, file) as client:
        csrf = login(client, "eve", engineer)
        now = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
        answer = client.post(
            f"/api/loops/{LOOP}/excitation/stop", data={}, headers={CSRF_HEADER: csrf}
        )
    assert 'data-kind="excite_stop"' in now
    assert 'data-kind="excite_start"' not in now
    assert answer.status_code == 200, answer.text
    request = answer.json()["request"]
    assert (request["kind"], request["who"], request["status"]) == ("excite_stop", "eve", "done")
    assert request["why"] == "(no reason given)"


def test_with_no_service_a_start_is_not_offered_and_refused_in_one_line(
    tmp_path: Path, users: Any
) -> None:
    file, engineer, _ = users
    db = make_store(tmp_path / "loop.db", signal=False, service=False)
    with dashboard(db, file) as client:
        csrf = login(client, "eve", engineer)
        now = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
        answer = client.post(
            f"/api/loops/{LOOP}/excitation/start", data={"why": "try"}, headers={CSRF_HEADER: csrf}
        )
        requests = client.get(f"/api/loops/{LOOP}/requests").json()["requests"]
    assert 'data-kind="excite_start"' not in now
    assert "No test signal can be started: no service runs to carry it." in now
    assert answer.status_code == 409
    assert answer.json()["error"] == "no service runs: nothing would carry the signal"
    assert [(r["kind"], r["who"], r["why"], r["status"]) for r in requests] == [
        ("excite_start", "eve", "try", "refused")
    ]


def test_a_site_without_a_register_offers_no_start(tmp_path: Path, users: Any) -> None:
    file, engineer, _ = users
    db = make_store(tmp_path / "loop.db", signal=False, service=True, possible=False)
    with dashboard(db, file) as client:
        login(client, "eve", engineer)
        now = client.get(f"/loops/{LOOP}/parts").json()["html"]["now"]
    assert 'data-kind="excite_start"' not in now
    assert "the site file gives no [write.excitation] register" in now


# --- the fleet and the stream -----------------------------------------------------------------


def test_the_fleet_says_exciting_for_a_running_signal_only(tmp_path: Path) -> None:
    running = make_store(tmp_path / "running.db", signal=True, service=True)
    idle = make_store(tmp_path / "idle.db", signal=False, service=True)
    with dashboard(running) as client:
        page = client.get("/").text
        (row,) = client.get("/api/loops").json()["loops"]
    assert f'<span class="chip note exciting" title="test signal">{RUNNING_LINE}</span>' in page
    assert row["excitation"]["exciting"] is True
    assert row["excitation"]["text"] == RUNNING_LINE
    assert "test signal" not in {c["name"] for c in row["chips"]}  # a note, not a chip
    with dashboard(idle) as client:
        page = client.get("/").text
        (row,) = client.get("/api/loops").json()["loops"]
    assert "chip note exciting" not in page
    assert row["excitation"]["exciting"] is False


def test_a_burst_that_starts_is_an_excitation_event_of_the_stream(tmp_path: Path) -> None:
    db = make_store(tmp_path / "loop.db", signal=False, service=True)
    with dashboard(db) as client:
        before = client.get(f"/loops/{LOOP}/parts").json()["status"]
        with SQLiteStore(db) as store, OnlineHistory(store) as history:
            history.set_state(STATE_KEY, _exciter_record(running=True))
        after = client.get(f"/loops/{LOOP}/parts").json()["status"]
    # the counts did not move: the change is the exciter's record, its own topic
    assert before["counts"] == after["counts"]
    assert "excitation" in changed_topics(before, after)
