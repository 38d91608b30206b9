"""The online service's history in the store (issue 15): SQLite files in tmp_path.

Every test name says ``store`` so that ``pytest -k store`` runs them with the store's tests.
"""

from __future__ import annotations

import json
import math
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from fuelid.store import (
    PROPOSAL_TRANSITIONS,
    SCHEMA_VERSION,
    OnlineHistory,
    Sample,
    SampleWriter,
    SQLiteStore,
    StoreError,
    build_at,
    tag_map_hash,
)

T0 = 1_700_000_000.0  # UTC seconds
SITE = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}
MODEL = {"kind": "FOPDT", "K": 12.5, "T": 0.42, "L": 0.08, "cov": [[1e-4, 0.0], [0.0, 2e-4]]}


def _store(path: Path) -> SQLiteStore:
    return SQLiteStore(path, period_s=0.02, **SITE)


@pytest.fixture
def history(tmp_path: Path):
    with _store(tmp_path / "loop.db") as store, OnlineHistory(store) as history:
        yield history


def _window(history: OnlineHistory, k: int, accepted: bool = True, **kw):
    args = {
        "t_from": T0 + 300.0 * k,
        "t_to": T0 + 300.0 * k + 600.0,
        "accepted": accepted,
        "reason": "all gates passed" if accepted else "too little excitation",
        "T_fuel": 20.0 + k,
        "u_mean": 2.5,
        "detail": {"fit": 90.0 + k, "gates": {"excitation": accepted}},
        "model": {**MODEL, "K": 12.0 + k},
        "time": T0 + 300.0 * k + 601.0,
    }
    return history.add_window(**{**args, **kw})


def _gains(kc: float, ti: float) -> dict[str, float]:
    return {"Kc": kc, "Ti": ti}


def test_store_windows_and_models_round_trip(history: OnlineHistory) -> None:
    assert history.last_window() is None
    assert history.windows() == []
    assert _window(history, 0) == (1, 1)
    assert _window(history, 1, accepted=False) == (2, None)  # a refused window keeps no model
    assert _window(history, 2, model=None) == (3, None)  # accepted without a model
    assert _window(history, 3) == (4, 2)
    rows = history.windows()
    assert [w["id"] for w in rows] == [1, 2, 3, 4]
    first = rows[0]
    assert abs(first.pop("wall_time") - time.time()) < 60.0  # the wall clock when written
    assert first == {
        "id": 1,
        "t_from": T0,
        "t_to": T0 + 600.0,
        "time": T0 + 601.0,
        "accepted": True,
        "reason": "all gates passed",
        "T_fuel": 20.0,
        "u_mean": 2.5,
        "model_id": 1,
        "detail": {"fit": 90.0, "gates": {"excitation": True}},
    }
    assert rows[1]["accepted"] is False
    assert rows[1]["model_id"] is None
    last = history.last_window()
    assert last is not None
    assert last["id"] == 4
    assert [w["id"] for w in history.windows(limit=2)] == [3, 4]  # the newest two, oldest first
    assert [w["id"] for w in history.windows(t_from=T0 + 900.0)] == [2, 3, 4]  # by window end
    assert [w["id"] for w in history.windows(T0 + 900.0, T0 + 1500.0)] == [2, 3]
    models = history.accepted_models()
    assert [m["id"] for m in models] == [1, 2]
    assert models[1]["wall_time"] is not None
    assert {k: v for k, v in models[1].items() if k != "wall_time"} == {
        "id": 2,
        "window_id": 4,
        "time": T0 + 1501.0,
        "t_from": T0 + 900.0,
        "t_to": T0 + 1500.0,
        "T_fuel": 23.0,
        "model": {**MODEL, "K": 15.0},
    }
    assert history.accepted_models(limit=1) == [models[1]]
    assert history.model(1) == models[0]
    assert history.model(99) is None
    counts = history.counts()
    assert (counts["windows"], counts["accepted"], counts["models"]) == (4, 3, 2)


def test_store_window_arguments_are_checked(history: OnlineHistory) -> None:
    with pytest.raises(StoreError, match="before t_from"):
        _window(history, 0, t_from=T0 + 10.0, t_to=T0)
    with pytest.raises(StoreError, match="finite"):
        _window(history, 0, t_to=math.inf)
    with pytest.raises(StoreError, match="cannot be stored as JSON"):
        _window(history, 0, detail={"what": object()})
    with pytest.raises(StoreError, match="non-negative"):
        history.windows(limit=-1)
    assert history.windows() == []  # nothing half-written


def test_store_nan_and_inf_are_stored_as_json_null(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    with _store(db) as store, OnlineHistory(store) as history:
        detail = {
            "fit": math.nan,
            "stderr": [1.0, math.inf, -math.inf],
            "np": np.float64("nan"),
            "arr": np.array([1.5, np.nan]),
            "n": np.int64(3),
            "flag": np.bool_(True),
        }
        window_id, model_id = _window(history, 0, T_fuel=math.nan, u_mean=math.inf, detail=detail)
        history.set_state("bad", {"Kc": math.nan})
        row = history.windows()[0]
        assert row["T_fuel"] is None
        assert row["u_mean"] is None
        expected = {
            "fit": None,
            "stderr": [1.0, None, None],
            "np": None,
            "arr": [1.5, None],
            "n": 3,
            "flag": True,
        }
        assert row["detail"] == expected
        assert history.state("bad") == {"Kc": None}
        model = history.model(model_id or 0)
        assert model is not None
        assert model["T_fuel"] is None
    con = sqlite3.connect(db)  # strict JSON on disk: any reader can parse it
    try:
        text = con.execute("SELECT detail FROM windows WHERE id = ?", (window_id,)).fetchone()[0]
        assert "NaN" not in text
        assert "Infinity" not in text
        assert json.loads(text) == expected
    finally:
        con.close()


def test_store_proposals_round_trip_and_follow_their_transitions(history: OnlineHistory) -> None:
    _, model_id = _window(history, 0)
    pid = history.add_proposal(
        model_id=model_id,
        old=_gains(0.8, 2.0),
        new=_gains(1.1, 1.6),
        detail={"rule": "simc", "Ms": 1.68, "windows": [1]},
        time=T0 + 700.0,
    )
    proposal = history.proposal(pid)
    wall = proposal.pop("wall_time")
    assert abs(wall - time.time()) < 60.0
    assert proposal == {
        "id": pid,
        "time": T0 + 700.0,
        "model_id": model_id,
        "status": "pending",
        "old": _gains(0.8, 2.0),
        "new": _gains(1.1, 1.6),
        "detail": {"rule": "simc", "Ms": 1.68, "windows": [1]},
        "history": [
            {"time": T0 + 700.0, "wall_time": wall, "status": "pending", "who": "online", "why": ""}
        ],
    }
    con = history._con
    assert con is not None
    assert con.execute("SELECT kc, ti FROM proposals WHERE id = ?", (pid,)).fetchone() == (1.1, 1.6)
    updated = history.set_proposal_status(
        pid, "approved", who="operator anna", why="looks fine", time=T0 + 800.0
    )
    assert updated["status"] == "approved"
    assert updated["history"][-1].pop("wall_time") >= wall
    assert updated["history"][-1] == {
        "time": T0 + 800.0,
        "status": "approved",
        "who": "operator anna",
        "why": "looks fine",
    }
    history.set_proposal_status(pid, "writing", who="online")
    final = history.set_proposal_status(pid, "applied", who="online", why="echo verified")
    assert [h["status"] for h in final["history"]] == ["pending", "approved", "writing", "applied"]
    assert final["new"] == _gains(1.1, 1.6)  # the rest is kept
    with pytest.raises(StoreError, match=f"^proposal {pid} is applied: it cannot be approved$"):
        history.set_proposal_status(pid, "approved", who="operator anna")
    assert history.proposal(pid) == final  # a refused transition changes nothing

    other = history.add_proposal(
        model_id=None, old=_gains(1.1, 1.6), new=_gains(1.2, 1.5), detail={}
    )
    history.set_proposal_status(other, "superseded", who="online", why="a newer model")
    assert [p["id"] for p in history.proposals()] == [pid, other]
    assert [p["id"] for p in history.proposals("applied")] == [pid]
    assert [p["id"] for p in history.proposals(["superseded", "pending"])] == [other]
    assert history.proposals([]) == []
    counts = history.counts()
    assert (counts["proposals"], counts["proposals_applied"]) == (2, 1)
    assert (counts["proposals_superseded"], counts["proposals_pending"]) == (1, 0)


@pytest.mark.parametrize(
    ("path", "refused"),
    [
        ([], "reverted"),  # pending → reverted: only an applied proposal can be reverted
        (["rejected"], "approved"),  # final
        (["approved", "writing"], "rejected"),  # writing ends applied or failed
        (["writing", "failed"], "writing"),  # final
        (["superseded"], "pending"),
        (["writing", "applied", "reverted"], "applied"),  # final
    ],
)
def test_store_proposal_transitions_refused_with_the_reason(
    history: OnlineHistory, path: list[str], refused: str
) -> None:
    pid = history.add_proposal(model_id=None, old=_gains(1.0, 2.0), new=_gains(1.2, 1.8), detail={})
    for status in path:
        history.set_proposal_status(pid, status, who="test")
    current = path[-1] if path else "pending"
    assert refused not in PROPOSAL_TRANSITIONS[current]
    with pytest.raises(StoreError, match=f"^proposal {pid} is {current}: it cannot be {refused}$"):
        history.set_proposal_status(pid, refused, who="test")


def test_store_every_allowed_proposal_transition_is_accepted(history: OnlineHistory) -> None:
    assert not PROPOSAL_TRANSITIONS["failed"]
    reach = {"pending": []}  # how to reach each status from pending
    reach.update(
        approved=["approved"],
        writing=["writing"],
        applied=["writing", "applied"],
    )
    for start, targets in PROPOSAL_TRANSITIONS.items():
        if start not in reach:
            continue
        for target in targets:
            pid = history.add_proposal(
                model_id=None, old=_gains(1.0, 1.0), new=_gains(1.0, 1.0), detail={}
            )
            for status in reach[start]:
                history.set_proposal_status(pid, status, who="test")
            assert history.set_proposal_status(pid, target, who="test")["status"] == target


def test_store_proposal_arguments_are_checked(history: OnlineHistory) -> None:
    with pytest.raises(StoreError, match="no proposal 7"):
        history.set_proposal_status(7, "approved", who="anna")
    pid = history.add_proposal(model_id=None, old=_gains(1.0, 2.0), new=_gains(1.2, 1.8), detail={})
    with pytest.raises(StoreError, match="unknown proposal status 'done'"):
        history.set_proposal_status(pid, "done", who="anna")
    with pytest.raises(StoreError, match="no model 5"):
        history.add_proposal(model_id=5, old=_gains(1.0, 2.0), new=_gains(1.0, 1.0), detail={})
    with pytest.raises(StoreError, match="'Kc' and 'Ti'"):
        history.add_proposal(model_id=None, old=_gains(1.0, 2.0), new={"Kc": 1.0}, detail={})
    with pytest.raises(StoreError, match="old gains"):
        history.add_proposal(model_id=None, old={}, new=_gains(1.0, 1.0), detail={})
    with pytest.raises(StoreError, match="finite"):
        history.add_proposal(
            model_id=None, old=_gains(1.0, 2.0), new=_gains(math.nan, 1.0), detail={}
        )
    assert history.proposal(99) is None
    assert [p["id"] for p in history.proposals()] == [pid]


def test_store_writes_record_intent_then_outcome(history: OnlineHistory) -> None:
    assert history.last_apply_seq() is None
    pid = history.add_proposal(model_id=None, old=_gains(1.0, 2.0), new=_gains(1.2, 1.8), detail={})
    wid = history.begin_write(
        kind="proposal",
        kc=1.2,
        ti=1.8,
        apply_seq=41,
        who="operator anna",
        why="approved",
        proposal_id=pid,
        time=T0 + 10.0,
    )
    intent = history.write(wid)
    assert intent == {
        "id": wid,
        "time": T0 + 10.0,
        "proposal_id": pid,
        "kind": "proposal",
        "kc": 1.2,
        "ti": 1.8,
        "apply_seq": 41,
        "status": "intent",
        "who": "operator anna",
        "why": "approved",
        "detail": {},
        "finished": None,
        "wall_time": intent["wall_time"],
        "finished_wall": None,
    }
    assert abs(intent["wall_time"] - time.time()) < 60.0
    assert history.unfinished_writes() == [intent]
    assert history.last_apply_seq() == 41  # an intent counts: the number is used
    with pytest.raises(StoreError, match=f"write {wid} .* is still an intent"):
        history.begin_write(kind="restore", kc=1.0, ti=2.0, apply_seq=42, who="x", why="y")
    done = history.finish_write(wid, "verified", {"echo": _gains(1.2, 1.8)}, time=T0 + 11.0)
    assert done["status"] == "verified"
    assert done["finished"] == T0 + 11.0
    assert done["detail"] == {"echo": _gains(1.2, 1.8)}
    assert history.unfinished_writes() == []
    with pytest.raises(StoreError, match=f"write {wid} is verified: only an intent"):
        history.finish_write(wid, "failed")
    with pytest.raises(StoreError, match="already used by write"):
        history.begin_write(kind="revert", kc=1.0, ti=2.0, apply_seq=41, who="x", why="y")
    second = history.begin_write(kind="revert", kc=1.0, ti=2.0, apply_seq=42, who="x", why="y")
    assert history.finish_write(second, "not_applied")["detail"] == {}
    assert [w["id"] for w in history.writes()] == [wid, second]
    assert [w["id"] for w in history.writes(limit=1)] == [second]
    assert history.last_apply_seq() == 42
    assert history.write(99) is None
    counts = history.counts()
    assert (counts["writes"], counts["writes_verified"], counts["writes_intent"]) == (2, 1, 0)


def test_store_write_arguments_are_checked(history: OnlineHistory) -> None:
    with pytest.raises(StoreError, match="unknown write kind"):
        history.begin_write(kind="tweak", kc=1.0, ti=1.0, apply_seq=1, who="x", why="y")
    with pytest.raises(StoreError, match="needs its proposal_id"):
        history.begin_write(kind="proposal", kc=1.0, ti=1.0, apply_seq=1, who="x", why="y")
    with pytest.raises(StoreError, match="no proposal 3"):
        history.begin_write(
            kind="proposal", kc=1.0, ti=1.0, apply_seq=1, who="x", why="y", proposal_id=3
        )
    with pytest.raises(StoreError, match="finite"):
        history.begin_write(kind="restore", kc=math.nan, ti=1.0, apply_seq=1, who="x", why="y")
    with pytest.raises(StoreError, match="integer"):
        history.begin_write(kind="restore", kc=1.0, ti=1.0, apply_seq=1.5, who="x", why="y")
    with pytest.raises(StoreError, match="no write 4"):
        history.finish_write(4, "verified")
    wid = history.begin_write(
        kind="restore", kc=1.0, ti=1.0, apply_seq=np.int64(7), who="x", why="y"
    )
    with pytest.raises(StoreError, match="not 'intent'"):
        history.finish_write(wid, "intent")
    assert history.writes()[0]["apply_seq"] == 7


def test_store_state_is_a_json_upsert(history: OnlineHistory) -> None:
    assert history.state("last_good") is None
    assert history.state("last_good", {"Kc": 1.0}) == {"Kc": 1.0}
    history.set_state("last_good", {"Kc": 0.8, "Ti": 2.0, "time": T0})
    history.set_state("schedule", [[10.0, 0.9], [30.0, 1.1]])
    history.set_state("last_good", {"Kc": 0.9, "Ti": 1.9, "time": T0 + 1.0})
    assert history.state("last_good") == {"Kc": 0.9, "Ti": 1.9, "time": T0 + 1.0}
    assert history.state("schedule") == [[10.0, 0.9], [30.0, 1.1]]
    history.set_state("note", None)
    assert history.state("note", "default") is None  # set to null is not absent
    with pytest.raises(StoreError, match="state key"):
        history.set_state("", 1)


def test_store_history_is_durable_and_seen_by_a_new_connection(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    with _store(db) as store, OnlineHistory(store) as history:
        wid = history.begin_write(kind="restore", kc=0.8, ti=2.0, apply_seq=5, who="x", why="y")
        with OnlineHistory(store) as other:  # another connection, history still open
            assert [w["id"] for w in other.unfinished_writes()] == [wid]
            other.set_state("k", 1)
        assert history.state("k") == 1
        _window(history, 0)
    with SQLiteStore(db) as reader, OnlineHistory(reader) as again:  # a fresh process-like open
        assert [w["id"] for w in again.unfinished_writes()] == [wid]
        assert again.counts()["windows"] == 1


def test_store_history_closes_cleanly(tmp_path: Path) -> None:
    with _store(tmp_path / "loop.db") as store:
        history = OnlineHistory(store)
        history.close()
        history.close()  # twice is fine
        with pytest.raises(StoreError, match="closed"):
            history.counts()


def test_store_sample_store_works_with_the_history_tables(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    build_at(str(db), 1, {**SITE, "period_s": "0.02"})  # schema 1: models and proposals only
    con = sqlite3.connect(db)
    con.executemany(
        "INSERT INTO samples VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        [Sample(T0 + 0.02 * k, k, 2.0, 40.0)[:8] for k in range(10)],  # the columns of v1
    )
    con.commit()
    tables = {r[0] for r in con.execute("SELECT name FROM sqlite_schema WHERE type = 'table'")}
    con.close()
    assert "windows" not in tables
    with _store(db) as store, OnlineHistory(store) as history:
        _window(history, 0)
        history.add_proposal(model_id=1, old=_gains(1.0, 2.0), new=_gains(1.1, 1.9), detail={})
    with _store(db) as store:  # the store opens, reads and reports as before
        info = store.info()
        assert info.rows == 10
        assert info.schema_version == SCHEMA_VERSION
        assert store.integrity_check() == "ok"
        assert len(store.read()) == 10
    con = sqlite3.connect(db)
    try:
        rows = con.execute("SELECT name, sql FROM sqlite_schema WHERE type = 'table'").fetchall()
        tables = dict(rows)
        assert {"windows", "writes", "online_state", "models", "proposals"} <= set(tables)
        assert all(
            sql.rstrip().endswith(("STRICT", "STRICT, WITHOUT ROWID")) for sql in tables.values()
        )
        assert con.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    finally:
        con.close()
    with _store(db) as store, OnlineHistory(store) as history:  # reopening creates nothing new
        assert history.counts()["windows"] == 1
        assert history.accepted_models()[0]["window_id"] == 1


CRASH = """
import os, sys
from fuelid.store import OnlineHistory, SQLiteStore
store = SQLiteStore(sys.argv[1], site_name=sys.argv[2], tag_map_hash=sys.argv[3])
history = OnlineHistory(store)
wid = history.begin_write(kind="restore", kc=0.75, ti=2.5, apply_seq=12, who="online",
                          why="restore last-known-good")
print(wid, flush=True)
os._exit(9)  # dies before the PLC write and before finish_write: no clean-up at all
"""


def test_store_an_intent_survives_a_crash_mid_write(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    _store(db).close()
    done = subprocess.run(
        [sys.executable, "-c", CRASH, str(db), SITE["site_name"], SITE["tag_map_hash"]],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 9, done.stderr
    wid = int(done.stdout.strip())
    with _store(db) as store, OnlineHistory(store) as history:
        assert store.integrity_check() == "ok"
        unfinished = history.unfinished_writes()
        assert [(w["id"], w["apply_seq"], w["kc"], w["ti"]) for w in unfinished] == [
            (wid, 12, 0.75, 2.5)
        ]
        assert history.last_apply_seq() == 12
        history.finish_write(wid, "not_applied", {"echo": "old gains"})  # reconciled
        assert history.unfinished_writes() == []


def test_store_history_and_sample_writer_share_the_file(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    n_samples, n_windows, n_threads = 3000, 40, 3
    with _store(db) as store, OnlineHistory(store) as history:
        errors: list[BaseException] = []

        def analyse(k0: int) -> None:
            try:
                for k in range(k0, n_windows, n_threads):
                    _window(history, k, accepted=k % 2 == 0)
                    history.set_state(f"thread{k0}", k)
                    history.counts()
            except BaseException as error:  # handed to the test
                errors.append(error)

        with SampleWriter(store, commit_interval_s=0.005) as writer:
            threads = [threading.Thread(target=analyse, args=(i,)) for i in range(n_threads)]
            for thread in threads:
                thread.start()
            for start in range(0, n_samples, 50):
                writer.put_many(
                    Sample(T0 + 0.02 * k, k, 2.0, 40.0) for k in range(start, start + 50)
                )
            for thread in threads:
                thread.join(30.0)
            writer.flush()
        assert errors == []
        assert store.info().rows == n_samples
        counts = history.counts()
        assert counts["windows"] == n_windows
        assert counts["accepted"] == counts["models"] == n_windows // 2
        ends = [w["t_to"] for w in history.windows()]
        assert ends == sorted(ends)
        assert len(store.read()) == n_samples


def test_an_approval_of_a_stale_proposal_is_refused_with_the_services_reason(
    tmp_path: Path,
) -> None:
    # the service supersedes an approved proposal whose newest window ended more than
    # RECENT_WINDOWS_SPAN (6) windows of data before the newest sample; approving one is refused
    # with that reason instead of reading "approved" and never being written
    from fuelid.online import submit_request

    with _store(tmp_path / "loop.db") as store, OnlineHistory(store) as history:
        _, model_id = _window(history, 0)  # ends at T0 + 600 s
        pid = history.add_proposal(
            model_id=model_id, old=_gains(1.0, 2.0), new=_gains(1.1, 1.9), detail={}
        )
        fresh = T0 + 600.0 + 6 * 600.0 - 10.0  # default window_s 600 s: 3,600 s span
        store.append([Sample(fresh, 1, 2.0, 40.0)])
        fresh_one = submit_request(store, history, "approve", pid, "ana", "", "cli", "approve")
        assert fresh_one["status"] == "done"
        history.set_proposal_status(pid, "rejected", who="ana", why="reset for the next case")
        pid = history.add_proposal(
            model_id=model_id, old=_gains(1.0, 2.0), new=_gains(1.1, 1.9), detail={}
        )
        store.append([Sample(fresh + 20.0, 2, 2.0, 40.0)])  # 3,610 s after the window: stale
        stale = submit_request(store, history, "approve", pid, "ana", "", "cli", "approve")
        assert stale["status"] == "refused"
        assert "out of date" in stale["outcome"]
        assert "3610 s of data" in stale["outcome"]
        assert history.proposal(pid)["status"] == "pending"  # type: ignore[index]
