"""``fuelid online`` and its subcommands (issue 15, items 7 and 8, "Bad input").

status and history read a store populated directly through :class:`OnlineHistory`; approve,
reject and revert mark it; every bad input is one line on stderr and exit code 2; one short run
against the virtual PLC (``--virtual``) ends with windows in the store.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest

from fuelid.cli import main
from fuelid.plc import site_identity
from fuelid.plc.site import load_site
from fuelid.store import Event, OnlineHistory, Sample, SQLiteStore
from support.waiting import wait_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

T0 = 1_790_000_000.0
HEALTH = {
    "time_in_auto": 1.0,
    "time_at_limits": 0.0,
    "oscillation": {"oscillating": False},
    "iae_per_unit_step_s": 0.52,
    "harris": {"index": 0.83},
    "sensor": {"stuck": False, "noise_Lpm": 0.05},
}


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    for needle in needles:
        assert needle in lines[0], lines[0]


def site_file(tmp_path: Path, filename: str = "site.toml", *, extra: str = "", **kw: Any) -> Path:
    """A site file of a virtual PLC (no server needed to read a store)."""
    from fuelid.plc.virtual import site_text

    path = tmp_path / filename
    text = site_text(
        "modbus",
        "127.0.0.1",
        5020,
        store_url=f"sqlite:///{tmp_path / 'loop.db'}",
        kc=0.04,
        ti=1.4,
        **kw,
    )
    path.write_text(text + extra)
    return path


def _fitted(K: float, se: float) -> dict[str, Any]:
    return {
        "model": {"K": K, "T": 1.2, "T2": 0.0, "T_f": 0.3, "delay": 0.2},
        "stderr": {"K": se, "T": 0.02, "T2": None, "T_f": None, "delay": None},
        "ci95": {
            "K": [K - 1.96 * se, K + 1.96 * se],
            "T": [1.16, 1.24],
            "T2": None,
            "T_f": None,
            "delay": None,
        },
        "method": "pem",
        "fit_percent": 92.0,
    }


def _add_window(
    history: OnlineHistory, k: int, *, accepted: bool, T: float, K: float = 14.0
) -> tuple[int, int | None]:
    t_from, t_to = T0 + 60.0 * k, T0 + 60.0 * k + 120.0
    reason = "passed every gate" if accepted else "no excitation: no setpoint change"
    detail: dict[str, Any] = {
        "start": t_from,
        "end": t_to,
        "accepted": accepted,
        "reason": reason,
        "mode": "AUTO",
        "fuel_temperature": T,
        "gates": {"accepted": accepted, "reason": reason, "reasons": [] if accepted else [reason]},
        "health": HEALTH,
    }
    model = None
    if accepted:
        fitted = _fitted(K, 0.02)
        detail.update(fitted)
        model = {
            **fitted,
            "T_fuel": T,
            "u_mean": 2.5,
            "events": [t_from + 10.0],
            "plant_K": 14.0,
            "window_end": t_to,
        }
    return history.add_window(
        t_from=t_from,
        t_to=t_to,
        accepted=accepted,
        reason=reason,
        T_fuel=T,
        u_mean=2.5,
        detail=detail,
        model=model,
        time=t_to + 0.5,
    )


@pytest.fixture
def populated(tmp_path: Path) -> tuple[Path, Path]:
    """A store of the site file's site: 3 accepted windows, 1 rejected, 1 proposal, events."""
    site = site_file(tmp_path)
    db = tmp_path / "loop.db"
    identity = site_identity(load_site(site))
    with SQLiteStore(db, period_s=0.02, **identity) as store:
        # plant time just after the last window (T0 + 300 s): the proposal is fresh (a service
        # supersedes one whose windows are more than 6 windows of data old); the wall clock of
        # the commit says the samples are fresh
        store.append(
            [Sample(T0 + 301.0 + 0.02 * i, i, 2.5, 40.0, 40.0, 20.0, 1) for i in range(50)],
            [Event(T0 + 10.0, "link_down", "timeout"), Event(T0 + 12.0, "link_up", "")],
        )
        with OnlineHistory(store) as history:
            _add_window(history, 0, accepted=True, T=10.0, K=14.2)
            _add_window(history, 1, accepted=True, T=20.0, K=14.0)
            _add_window(history, 2, accepted=False, T=25.0)
            _, model_id = _add_window(history, 3, accepted=True, T=30.0, K=13.8)
            history.add_proposal(
                model_id=model_id,
                old={"Kc": 0.04, "Ti": 1.4},
                new={"Kc": 0.045, "Ti": 1.36},
                detail={
                    "reason": "2 independent windows agree",
                    "Ms": {"newest": 1.5, "tuned_for": 1.55},
                },
                time=T0 + 301.0,
                who="online",
                why="rules passed",
            )
    return site, db


# --- status and history ---------------------------------------------------------------------


def test_status_json_has_the_documented_keys_and_values(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    site, db = populated
    code, out, err = run(capsys, "online", "status", "--store", str(db), "--json")
    assert code == 0, err
    status = json.loads(out)
    for key in (
        "site",
        "link",
        "last_window",
        "current_model",
        "k_trend",
        "pending_proposals",
        "loop_health",
        "counts",
        "write_back",
        "last_write",
        "units",
        "fuelid_version",
        "options",
    ):
        assert key in status, key
    assert status["site"]["name"] == "virtual fuel loop"
    # no service ever ran on this store: stopped, whatever the samples' age (issue "one clock")
    assert status["link"]["state"] == "stopped"
    assert status["link"]["service"] == "never started"
    assert status["service"] is None
    assert status["timezone"] == "UTC"
    assert status["requests"] == []
    assert status["link"]["age_s"] < 30.0
    last = status["last_window"]
    assert last["id"] == 4
    assert last["accepted"] is True
    assert last["start"] == T0 + 180.0
    assert last["end"] == T0 + 300.0
    assert last["fuel_temperature"] == 30.0
    assert last["mode"] == "AUTO"
    assert last["model"]["K"] == 13.8
    assert last["gates"]["accepted"] is True
    assert last["ci95"]["K"] == pytest.approx([13.8 - 0.0392, 13.8 + 0.0392])
    current = status["current_model"]
    assert current["model"]["K"] == 13.8
    assert current["fuel_temperature"] == 30.0
    assert current["stderr"]["K"] == 0.02
    trend = status["k_trend"]
    assert trend["available"] is True
    assert trend["mode"] == "ratio"
    assert trend["n"] == 3
    assert trend["ratio"]["slope"] < 0.0  # K falls from 14.2 to 13.8 over 10…30 °C
    assert trend["at_newest"]["K"] == pytest.approx(13.8, abs=0.05)
    assert [p["id"] for p in status["pending_proposals"]] == [1]
    pending = status["pending_proposals"][0]
    assert pending["old"] == {"Kc": 0.04, "Ti": 1.4}
    assert pending["new"] == {"Kc": 0.045, "Ti": 1.36}
    assert pending["Ms"] == 1.55
    assert status["loop_health"] == HEALTH
    assert status["counts"]["windows"] == 4
    assert status["counts"]["accepted"] == 3
    assert status["last_write"] is None
    # with the site file: the same store, the write-back setting and the gains' units known
    code, out, err = run(capsys, "online", "status", "--config", str(site), "--json")
    assert code == 0, err
    status = json.loads(out)
    assert status["write_back"]["setting"] == "off"
    assert status["write_back"]["setting_from"] == "site file"
    assert status["gains_units"] == {"Kc": "V per L/min", "Ti": "s"}
    assert status["pending_proposals"][0]["gain_units"] == {"Kc": "V per L/min", "Ti": "s"}
    # a running service's record: the link is up, and the write-back known without --config
    _beating(db, write_back="approve", timezone="Europe/Zurich")
    code, out, err = run(capsys, "online", "status", "--store", str(db), "--json")
    assert code == 0, err
    status = json.loads(out)
    assert status["link"]["state"] == "up"  # a sample 2 s old (wall clock), the service beats
    assert status["service"]["state"] == "running"
    assert status["service"]["beat_age_s"] < 10.0
    assert status["write_back"]["setting"] == "approve"
    assert status["write_back"]["setting_from"] == "service"
    assert status["timezone"] == "Europe/Zurich"
    pending = status["pending_proposals"][0]
    assert pending["target"] is None  # the proposal recorded no target
    assert pending["gain_units"] == {"Kc": "V per L/min", "Ti": "s"}


def _beating(db: Path, **settings: Any) -> None:
    """Write a service record as a running service would (a beat now)."""
    from fuelid.tuning import BlockForm, block_units

    wall = time.time()
    controller = {"form": "ideal", "gain_units": "engineering", "integral_unit": "s"}
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        history.set_state(
            "service",
            {
                "pid": 1,
                "host": "test",
                "version": "0",
                "started": wall,
                "beat": wall,
                "beat_every_s": 2.0,
                "stopped": None,
                "settings": {
                    **settings,
                    "controller": controller,
                    "gain_units": block_units(BlockForm.of(controller)),
                },
            },
        )


def test_status_text_is_a_few_aligned_lines(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    _, db = populated
    code, out, err = run(capsys, "online", "status", "--store", str(db))
    assert code == 0, err
    lines = out.strip().splitlines()
    names = [line.split()[0] for line in lines]
    assert names == [
        "site",
        "link",
        "window",
        "model",
        "step-ls",
        "K(T)",
        "proposals",
        "requests",
        "health",
        "writes",
        "counts",
    ]
    text = out
    assert "accepted: passed every gate" in text
    assert "K = 13.8 ± 0.02 (L/min)/V" in text
    assert "#1 pending: Kc 0.04 → 0.045" in text
    assert "service never started" in text
    assert "oscillating no" in text
    assert "Harris index 0.83" in text


def test_status_gives_the_plcs_gains_as_the_recorder_kept_them(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """``plc_gains``: null until the recorder keeps a reading, then in both units, timed."""
    from fuelid.plc import PLC_GAINS_KEY
    from fuelid.store import SampleWriter

    site, db = populated
    code, out, err = run(capsys, "online", "status", "--config", str(site), "--json")
    assert code == 0, err
    assert json.loads(out)["plc_gains"] is None
    read_at = T0 + 301.5
    reading = {"kc": 0.05, "ti": 1.2, "units": "block", "time": read_at, "wall_time": time.time()}
    identity = site_identity(load_site(site))
    with SQLiteStore(db, period_s=0.02, **identity) as opened, SampleWriter(opened) as writer:
        writer.set_state(PLC_GAINS_KEY, reading)  # as the recorder does: the store's one writer
    code, out, err = run(capsys, "online", "status", "--config", str(site), "--json")
    assert code == 0, err
    gains = json.loads(out)["plc_gains"]
    assert (gains["Kc"], gains["Ti"], gains["time"]) == (0.05, 1.2, read_at)
    assert gains["units"] == {"Kc": "V per L/min", "Ti": "s"}  # the site's [controller]
    assert gains["ideal"] == {"Kc": 0.05, "Ti": 1.2}
    assert gains["wall_time"] <= time.time()
    # without the site file nor a service record the block's form is unknown: no conversion
    code, out, err = run(capsys, "online", "status", "--store", str(db), "--json")
    gains = json.loads(out)["plc_gains"]
    assert (gains["Kc"], gains["units"], gains["ideal"]) == (0.05, None, None)
    code, out, err = run(capsys, "online", "status", "--config", str(site))
    assert code == 0, err
    (line,) = [line for line in out.splitlines() if line.startswith("PLC gains")]
    assert line == (
        "PLC gains  Kc 0.05 V per L/min, Ti 1.2 s, read at 2026-09-21 14:18:21 UTC "
        "(the kc, ti tags)"
    )


def test_history_json_windows_proposals_events(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    _, db = populated
    code, out, err = run(capsys, "online", "history", "--store", str(db), "--json")
    assert code == 0, err
    data = json.loads(out)
    for key in ("windows", "proposals", "events", "writes", "k_trend", "counts", "units"):
        assert key in data
    windows = data["windows"]
    assert [w["accepted"] for w in windows] == [True, True, False, True]
    for w in windows:
        for key in (
            "start",
            "end",
            "accepted",
            "reason",
            "fuel_temperature",
            "model",
            "stderr",
            "ci95",
        ):
            assert key in w
    assert windows[0]["model"] == {"K": 14.2, "T": 1.2, "T2": 0.0, "T_f": 0.3, "delay": 0.2}
    assert windows[0]["stderr"]["K"] == 0.02
    assert len(windows[0]["ci95"]["K"]) == 2
    assert windows[2]["model"] is None
    assert windows[2]["reason"].startswith("no excitation")
    assert windows[2]["fuel_temperature"] == 25.0
    (proposal,) = data["proposals"]
    assert proposal["id"] == 1
    assert proposal["status"] == "pending"
    assert proposal["time"] == T0 + 301.0
    assert proposal["old"] == {"Kc": 0.04, "Ti": 1.4}
    assert proposal["new"] == {"Kc": 0.045, "Ti": 1.36}
    assert proposal["Ms"] == 1.55
    assert proposal["reason"] == "2 independent windows agree"
    assert proposal["history"][0]["who"] == "online"
    assert [(e["kind"], e["detail"]) for e in data["events"]] == [
        ("link_down", "timeout"),
        ("link_up", ""),
    ]
    code, out, err = run(capsys, "online", "history", "--store", str(db))
    assert code == 0, err
    assert "4 windows, 3 accepted" in out
    assert "1 proposals" in out


def test_history_plot_writes_a_png(
    populated: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import matplotlib.image

    _, db = populated
    png = tmp_path / "history.png"
    code, _out, err = run(capsys, "online", "history", "--store", str(db), "--plot", str(png))
    assert code == 0, err
    assert png.stat().st_size > 0
    image = matplotlib.image.imread(png)
    assert image.ndim == 3
    assert image.shape[0] > 500
    code, _out, err = run(capsys, "online", "history", "--store", str(db), "--plot", str(png))
    assert_one_line_error(code, err, "exists", "--force")


def test_plot_of_an_empty_history_still_draws(tmp_path: Path) -> None:
    from fuelid.plots import plot_online_history

    out = plot_online_history({"windows": [], "proposals": [], "writes": []}, tmp_path / "e.png")
    assert out.stat().st_size > 0


# --- approve, reject, revert -----------------------------------------------------------------


def _status_of(db: Path, proposal_id: int) -> dict[str, Any]:
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        found = history.proposal(proposal_id)
    assert found is not None
    return found


def test_approve_marks_the_proposal_and_a_second_approve_is_refused(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    site, db = populated
    code, out, err = run(
        capsys,
        "online",
        "approve",
        "1",
        "--config",
        str(site),
        "--who",
        "alice",
        "--why",
        "looks right",
    )
    assert code == 0, err
    assert "approved" in out
    assert "alice" in out
    assert 'write_back is "off"' in out
    proposal = _status_of(db, 1)
    assert proposal["status"] == "approved"
    assert proposal["history"][-1]["who"] == "alice"
    assert proposal["history"][-1]["why"] == "looks right"
    code, out, err = run(capsys, "online", "approve", "1", "--store", str(db))
    assert_one_line_error(code, err, "proposal 1 is approved: it cannot be approved")
    # no service runs: each command filed a request and applied it at once, with its outcome
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        requests = history.requests()
    assert [(r["kind"], r["origin"], r["status"]) for r in requests] == [
        ("approve", "cli", "done"),
        ("approve", "cli", "refused"),
    ]
    assert requests[0]["who"] == "alice"
    assert requests[1]["outcome"] == "proposal 1 is approved: it cannot be approved"
    assert all(r["done_wall"] is not None for r in requests)


def test_status_says_why_no_proposal_comes_when_turned_down_gains_are_held(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    # the service files no proposal whose gains a person rejected (or that were reverted): the
    # status says so, with the proposal it points at, instead of "none"
    _, db = populated
    code, out, err = run(capsys, "online", "reject", "1", "--store", str(db), "--why", "no")
    assert code == 0, err
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        history.set_state("held_proposal", {"id": 1, "status": "rejected", "Kc": 0.045, "Ti": 1.36})
    code, out, err = run(capsys, "online", "status", "--store", str(db), "--json")
    assert code == 0, err
    held = json.loads(out)["held_proposal"]
    assert held == {"id": 1, "status": "rejected", "Kc": 0.045, "Ti": 1.36}
    code, out, err = run(capsys, "online", "status", "--store", str(db))
    assert code == 0, err
    (line,) = [line for line in out.splitlines() if line.startswith("proposals")]
    assert "none filed: the newest evidence points at the gains of #1 (rejected)" in line


def test_reject_then_approve_is_an_illegal_transition(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    import getpass

    _, db = populated
    code, _out, err = run(capsys, "online", "reject", "1", "--store", str(db))
    assert code == 0, err
    proposal = _status_of(db, 1)
    assert proposal["status"] == "rejected"
    assert proposal["history"][-1]["who"] == getpass.getuser()  # the OS user by default
    code, _out, err = run(capsys, "online", "approve", "1", "--store", str(db))
    assert_one_line_error(code, err, "proposal 1 is rejected: it cannot be approved")


def test_an_unknown_proposal_is_exit_2(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    _, db = populated
    for verb in ("approve", "reject"):
        code, _out, err = run(capsys, "online", verb, "99", "--store", str(db))
        assert_one_line_error(code, err, "no proposal 99")


def test_revert_leaves_a_request_for_the_running_service(
    populated: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    _, db = populated
    code, out, err = run(
        capsys, "online", "revert", "--store", str(db), "--who", "bob", "--why", "loop sluggish"
    )
    assert code == 0, err
    assert "revert requested by bob" in out
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        request = history.state("revert_requested")
    assert request["who"] == "bob"
    assert request["why"] == "loop sluggish"
    assert request["time"] > T0
    code, out, err = run(capsys, "online", "status", "--store", str(db), "--json")
    assert json.loads(out)["write_back"]["revert_requested"]["who"] == "bob"


# --- bad input -------------------------------------------------------------------------------


def test_a_missing_store_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for verb in (("status",), ("history",), ("approve", "1"), ("revert",)):
        code, _out, err = run(capsys, "online", *verb, "--store", str(tmp_path / "none.db"))
        assert_one_line_error(code, err, "none.db", "no such store")
    code, _out, err = run(capsys, "online", "status")
    assert_one_line_error(code, err, "--config", "--store")


def test_a_store_of_another_site_is_refused(
    populated: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, db = populated
    other = site_file(tmp_path, "other.toml", name="tunnel 3")
    for verb in (("status",), ("history", "--json"), ("approve", "1")):
        code, _out, err = run(capsys, "online", *verb, "--config", str(other), "--store", str(db))
        assert_one_line_error(code, err, "belongs to site 'virtual fuel loop'", "tunnel 3")
    assert _status_of(db, 1)["status"] == "pending"  # nothing changed
    # the service itself refuses it too, before it connects to any PLC
    code, _out, err = run(
        capsys, "online", "--config", str(other), "--store", str(db), "--duration", "1"
    )
    assert_one_line_error(code, err, "belongs to site")


def test_write_back_without_write_tags_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = site_file(tmp_path).read_text()
    cut = text.index("[write.kc]")
    rest = text[cut:]
    kept = rest[rest.index("[ring]") :]
    bad = tmp_path / "bad.toml"
    bad.write_text(text[:cut] + kept + '\n[online]\nwrite_back = "approve"\n')
    code, _out, err = run(capsys, "online", "--config", str(bad), "--duration", "1")
    assert_one_line_error(code, err, "write_back = 'approve' needs the write side", "write.kc")


def test_a_window_shorter_than_the_settling_time_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from importlib import resources

    from fuelid.plant import LinearPlant

    plant = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
    site = site_file(
        tmp_path, plant=plant, extra="\n[online]\nwindow_s = 120\nidentify_every_s = 60\n"
    )
    monkeypatch.setattr(LinearPlant, "settling_time", lambda self, band=0.02: 900.0)
    code, _out, err = run(capsys, "online", "--config", str(site), "--duration", "1")
    assert_one_line_error(code, err, "window_s = 120 s", "settling time 900 s")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--virtual", "--speed", "0"), "--speed must be within (0, 1000]"),
        (("--virtual", "--speed", "-5"), "--speed must be within (0, 1000]"),
        (("--virtual", "--hours", "0"), "--hours must be a positive"),
        (("--virtual", "--hours", "-1"), "--hours must be a positive"),
        (("--duration", "0"), "--duration must be a positive"),
        ((), "give --config SITE.toml"),
    ],
)
def test_bad_run_options_are_exit_2(
    args: tuple[str, ...], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _out, err = run(capsys, "online", *args)
    assert_one_line_error(code, err, needle)


def test_a_bad_online_table_for_the_virtual_run_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "online.toml"
    bad.write_text("[online]\nidentify_every_s = 5\n")
    code, _out, err = run(capsys, "online", "--virtual", "--config", str(bad))
    assert_one_line_error(code, err, "online.identify_every_s")


@pytest.mark.parametrize(
    ("site", "needle"),
    [
        ('loop_id = "Bad_ID"', "site.loop_id"),
        ('timezone = "Mars/Olympus"', "site.timezone"),
    ],
)
def test_a_bad_site_key_for_the_virtual_run_names_the_users_file(
    site: str, needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # issue 39: the error named the site file --virtual writes in a temporary folder
    config = tmp_path / "loop.toml"
    config.write_text(f'[site]\nname = "tunnel 2"\n{site}\n')
    store = tmp_path / "loop.db"
    code, _out, err = run(
        capsys, "online", "--virtual", "--config", str(config), "--store", str(store)
    )
    assert_one_line_error(code, err, str(config), needle)
    assert "virtual-site.toml" not in err
    assert "fuelid-online-" not in err
    assert not store.exists()  # refused before anything started


def test_log_records_are_json_objects() -> None:
    from fuelid.online import log_record
    from fuelid.profiles.runs import demo_run_profile, demo_temperature

    record = log_record('event kind=revert detail="IAE 4.16 s > 1.5 × 2.58 s (by service)"')
    assert record["event"] == "event"
    assert record["kind"] == "revert"
    assert record["detail"] == "IAE 4.16 s > 1.5 × 2.58 s (by service)"
    profile = demo_run_profile()
    values = [profile.at(t) for t in range(0, int(profile.cycle_s))]
    assert min(values) >= 20.0
    assert max(values) <= 53.0
    _times, temperatures = demo_temperature(86400.0)
    assert min(temperatures) == pytest.approx(-10.0)
    assert max(temperatures) == pytest.approx(45.0)


# --- a short real run -------------------------------------------------------------------------


def test_a_short_virtual_run_fills_the_store_with_windows(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    from importlib import resources

    # --config gives the loop its name, id and plant file (which the virtual PLC simulates)
    plant = tmp_path / "line7_plant.toml"
    plant.write_text(resources.files("fuelid.data").joinpath("reference_plant.toml").read_text())
    online = tmp_path / "online.toml"
    online.write_text(
        '[site]\nname = "Tunnel 7"\nloop_id = "line-7"\nplant = "line7_plant.toml"\n'
        "[online]\nidentify_every_s = 60\nwindow_s = 120\n"
    )
    db = tmp_path / "virtual.db"
    started = time.monotonic()
    code, out, err = run(
        capsys,
        "online",
        "--virtual",
        "--speed",
        "50",
        "--hours",
        "0.1",
        "--store",
        str(db),
        "--config",
        str(online),
        "--json-log",
        "--seed",
        "3",
    )
    wall = time.monotonic() - started
    assert code == 0, err
    assert wall < 60.0
    assert str(db.resolve()) in out
    assert "windows" in out
    records = [json.loads(line) for line in err.splitlines() if line.startswith("{")]
    assert any(r["event"] == "window" for r in records), err
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        assert history.counts()["windows"] >= 1
        assert store.info().rows > 10_000
        assert (store.site_name, store.loop_id) == ("Tunnel 7", "line-7")
        assert history.state("service")["settings"]["plant_file"] == str(plant.resolve())
        # every fitted window says which orders it compared and why it kept one
        fitted = [w["detail"] for w in history.windows() if w["detail"].get("model")]
        for detail in fitted:
            structure = detail["structure"]
            assert [c["order"] for c in structure["compared"]] == [1, 2]
            assert structure["chosen_order"] in (1, 2)
            assert structure["reason"].startswith(f"order {structure['chosen_order']}")
    code, out, err = run(capsys, "online", "status", "--store", str(db), "--json")
    assert code == 0, err
    assert json.loads(out)["last_window"] is not None


def _committed_samples(db: Path) -> int:
    """The samples a reader sees in a store being written (0 before its schema is committed)."""
    import sqlite3

    if not db.exists():
        return 0
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5.0)
    try:
        return int(con.execute("SELECT count(*) FROM samples").fetchone()[0])
    except sqlite3.OperationalError:
        return 0
    finally:
        con.close()


def test_sigterm_stops_the_virtual_run_cleanly_with_a_summary(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys

    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    db = tmp_path / "sig.db"
    child = subprocess.Popen(
        [sys.executable, "-m", "fuelid", "online", "--virtual", "--speed", "50", "--hours", "1",
         "--store", str(db)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert child.stderr is not None
        for line in child.stderr:  # wait until the service records
            if "connected to" in line:
                break
        # the store's rows checked below, committed before the signal (a commit a second)
        wait_until(lambda: _committed_samples(db) > 1000, 60.0, "1000 samples committed")
        child.send_signal(signal.SIGTERM)
        out, err = child.communicate(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 0, err
    assert "Traceback" not in err
    assert "online: stopped after" in out
    assert str(db.resolve()) in out
    with SQLiteStore(db) as store:
        assert store.info().rows > 1000


def test_the_link_state_follows_the_service_the_newest_link_event_and_the_wall_clock(
    tmp_path: Path,
) -> None:
    # issue "one clock": the state is judged on the wall clock and the service record, never
    # on the samples' plant time (here T0, years away from the wall clock)
    from fuelid.online import link_json

    site = site_file(tmp_path)
    identity = site_identity(load_site(site))
    with SQLiteStore(tmp_path / "link.db", period_s=0.02, **identity) as store:
        never = link_json(store)
        assert (never["state"], never["service"]) == ("stopped", "never started")
        wall = time.time()
        record = {"started": wall, "beat": wall, "stopped": None}
        assert link_json(store, now=wall + 1.0, service=record)["state"] == "no_data"
        store.append([Sample(T0, 0, 2.5, 40.0)], [Event(T0 + 1.0, "link_down", "timeout")])
        wall = time.time()
        record["beat"] = wall
        assert link_json(store, now=wall + 1.0, service=record)["state"] == "link_down"
        store.append([Sample(T0 + 3.0, 1, 2.5, 40.0)], [Event(T0 + 3.0, "link_up", "")])
        wall = time.time()
        record["beat"] = wall
        up = link_json(store, now=wall + 2.0, service=record)
        assert up["state"] == "up"
        assert up["service"] == "running"
        assert up["age_s"] == pytest.approx(2.0, abs=0.5)  # the wall age of the newest sample
        assert up["newest_sample"] == T0 + 3.0  # its plant time
        assert up["last_event"]["kind"] == "link_up"
        # the recorder silent for 40 s while the service beats: the link is down
        late = link_json(store, now=wall + 40.0, service={**record, "beat": wall + 39.0})
        assert late["state"] == "link_down"
        # a service killed (no beat for 11 s) or stopped cleanly: stopped, nothing else trusted
        killed = link_json(store, now=wall + 11.0, service=record)
        assert (killed["state"], killed["service"]) == ("stopped", "stopped")
        assert "no beat for" in killed["text"]
        clean = link_json(store, now=wall + 1.0, service={**record, "stopped": wall + 0.5})
        assert clean["state"] == "stopped"
