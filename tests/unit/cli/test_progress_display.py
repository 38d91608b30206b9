"""The progress display of identify and report (issue 38): a bar or spinner on a terminal only.

``progress_display`` shows the stage that runs (reading, gridding, fitting, testing, the report's
stages) with a bar when the library counts the stage's steps, on stderr, and nothing with
``--quiet`` or when stderr is not a terminal. The stages of ``fuelid identify`` are announced in
order, and the fit's steps counted.
"""

from __future__ import annotations

import io
import json
import time
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.cli._common import progress_display, read_log
from fuelid.identify import IdentifyOptions, StepDisplay
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence
from fuelid.workflow import IDENTIFY_STAGES, identify_log
from support.waiting import wait_until


@pytest.fixture(scope="module")
def short_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate(load_plant_config(), step_sequence([1.0, 2.0, 1.5, 3.0], dwell=20.0), seed=4)
    return run.to_log().write(tmp_path_factory.mktemp("log") / "short.csv")


class Recorder:
    """A progress display that keeps what it is told."""

    def __init__(self) -> None:
        self.stages: list[str] = []
        self.steps: list[tuple[str, int, int, str]] = []

    def __call__(self, stage: str) -> None:
        self.stages.append(stage)

    def step(self, done: int, total: int, what: str = "") -> None:
        self.steps.append((self.stages[-1], done, total, what))


def _terminal() -> tuple[Console, io.StringIO]:
    out = io.StringIO()
    return Console(file=out, force_terminal=True, width=100), out


def test_identify_announces_its_stages_in_order_and_counts_the_fits_steps(
    short_log: Path,
) -> None:
    seen = Recorder()
    assert isinstance(seen, StepDisplay)
    data = read_log(short_log, "t_s", "u_V", "q_Lpm", None, None, None, progress=seen)
    identify_log(data, IdentifyOptions(control_period=1.0), progress=seen)
    assert tuple(seen.stages) == IDENTIFY_STAGES
    fitting = IDENTIFY_STAGES[2]
    # order auto on a short record: each order's search, then its standard errors
    assert [(stage, done, total) for stage, done, total, _ in seen.steps] == [
        (fitting, k, 4) for k in range(4)
    ]
    assert [what for *_, what in seen.steps] == [
        "order 1: search",
        "order 1: standard errors",
        "order 2: search",
        "order 2: standard errors",
    ]


def test_a_plain_callback_gets_the_stages_only(short_log: Path) -> None:
    seen: list[str] = []
    data = read_log(short_log, "t_s", "u_V", "q_Lpm", None, None, None, progress=seen.append)
    identify_log(data, IdentifyOptions(control_period=1.0), progress=seen.append)
    assert tuple(seen) == IDENTIFY_STAGES


def test_the_display_shows_the_stage_and_its_bar_on_a_terminal() -> None:
    console, out = _terminal()
    with progress_display(console=console, show_after=0.0) as stage:
        assert isinstance(stage, StepDisplay)
        stage("fitting the model")
        stage.step(1, 4, "order 1: standard errors")  # type: ignore[attr-defined]
        # the display refreshes ten times a second, in its own thread
        wait_until(lambda: "1/4" in out.getvalue(), 10.0, "the stage's bar on the terminal")
    shown = out.getvalue()
    assert "fitting the model: order 1: standard errors" in shown
    assert "1/4" in shown


def test_the_display_waits_before_it_shows_a_stage() -> None:
    console, out = _terminal()
    with progress_display(console=console, show_after=60.0) as stage:
        stage("reading the log")
        time.sleep(0.3)  # a negative check's window: three refreshes (0.1 s) that show nothing
    assert "reading the log" not in out.getvalue()


@pytest.mark.parametrize("quiet", [True, False])
def test_the_display_is_silent_with_quiet_or_off_a_terminal(quiet: bool) -> None:
    out = io.StringIO()
    # quiet on a terminal, or not quiet on a file: nothing either way
    console = Console(file=out, force_terminal=quiet)
    with progress_display(quiet, console=console, show_after=0.0) as stage:
        assert not isinstance(stage, StepDisplay)  # the library then counts no steps
        stage("fitting the model")
        time.sleep(0.2)  # a negative check's window: two refreshes (0.1 s) that show nothing
    assert out.getvalue() == ""


@pytest.mark.parametrize("command", ["identify", "report"])
def test_quiet_is_an_option_and_json_stays_one_object(
    command: str, short_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # TTY_COMPATIBLE=1 makes rich treat stderr as a terminal; --quiet keeps it silent all the same
    monkeypatch.setenv("TTY_COMPATIBLE", "1")
    args = [command, str(short_log), "--control-period", "1", "--json", "-q"]
    if command == "report":
        args += ["--out", str(tmp_path / "r.html"), "--band-width", "35", "--flow-bands", "1"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.stderr
    payload, end = json.JSONDecoder().raw_decode(result.stdout)
    assert result.stdout[end:] == "\n"
    assert "units" in payload
    assert all(line.startswith(("warning: ", "note: ")) for line in result.stderr.splitlines())
