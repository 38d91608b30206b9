r"""Every console example in the docs runs, and prints what the page says it prints.

The convention (written for page authors in docs/reference/index.md, "Console examples"):

- a fenced block with the language ``console`` runs: each line starting ``$ `` is a command
  (``fuelid …`` runs as ``python -m fuelid …`` of this checkout, ``python`` is the test's
  interpreter, anything else runs in bash; a line ending in `` \`` continues on the next);
  the lines after it up to the next ``$ `` are its expected output (stdout and stderr as a
  terminal shows them), compared line by line with trailing spaces stripped. A line ``...``
  matches any number of lines; ``...`` inside a line matches any text. A command with no output
  lines is not checked for output, only for its exit code: 0, or N given by a last line
  ``[exit N]``;
- every ``console`` block of one page runs in order in one fresh temporary folder, where
  ``examples/``, ``docs/examples/`` and ``reference_plant.toml`` (the packaged reference plant)
  are at hand; what a command starts in the background (``&``) is stopped when its line ends;
- a block that must not run has ``<!-- illustrative: why -->`` on the line before its fence; a
  long one ``<!-- slow -->`` (docs/reference/index.md says which): it runs in the slow set
  only (``make test-slow``).

A failure names the page, the line, the command and shows the difference.
"""

from __future__ import annotations

import contextlib
import difflib
import functools
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
REFERENCE_PLANT = ROOT / "src" / "fuelid" / "data" / "reference_plant.toml"
#: a command that takes longer than this is stuck, not slow
TIMEOUT_S = 600

_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^`\s]*)")
_ILLUSTRATIVE = re.compile(r"^\s*<!--\s*illustrative:\s*(?P<why>.*?)\s*-->\s*$")
_SLOW = re.compile(r"^\s*<!--\s*slow\s*-->\s*$")
_EXIT = re.compile(r"^\[exit (?P<code>\d+)\]$")
_ANY_LINES = "..."


@dataclass
class Command:
    """One ``$ `` line of a block, its expected output and exit code."""

    line: int  # 1-based line of the ``$`` in the page
    text: str
    expected: list[str] = field(default_factory=list)
    exit_code: int = 0


@dataclass
class Block:
    """One ``console`` block: where it is, how it is marked, its commands."""

    page: Path
    line: int  # 1-based line of the opening fence
    commands: list[Command]
    illustrative: str | None = None  # the reason, when the block must not run
    slow: bool = False


def doc_pages() -> list[Path]:
    """README.md and every Markdown page under docs/ (the build's own code excluded)."""
    pages = [ROOT / "README.md"] if (ROOT / "README.md").exists() else []
    return pages + sorted(p for p in DOCS.rglob("*.md") if "hooks" not in p.parts)


def _commands(page: Path, first_line: int, lines: list[str]) -> list[Command]:
    commands: list[Command] = []
    continuing = False
    for offset, raw in enumerate(lines):
        line = raw.rstrip()
        if continuing and commands:
            commands[-1].text += "\n" + line
            continuing = line.endswith("\\")
        elif line.startswith("$ ") or line == "$":
            commands.append(Command(first_line + offset, line[2:]))
            continuing = line.endswith("\\")
        elif commands:
            commands[-1].expected.append(line)
        elif line.strip():
            raise ValueError(f"{page}:{first_line + offset}: output before the first '$ ' command")
    for command in commands:
        while command.expected and not command.expected[-1].strip():
            command.expected.pop()
        if command.expected and (match := _EXIT.match(command.expected[-1].strip())):
            command.exit_code = int(match.group("code"))
            command.expected.pop()
    return commands


def parse_blocks(page: Path) -> list[Block]:
    """The ``console`` blocks of a page, with their markers."""
    lines = page.read_text(encoding="utf-8").splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        opening = _FENCE.match(lines[i])
        if not opening:
            i += 1
            continue
        indent, fence, info = opening.group("indent", "fence", "info")
        end = i + 1
        while end < len(lines) and not lines[end].strip().startswith(fence):
            end += 1
        if info == "console":
            # the marker is on the line before the fence (blank lines between are tolerated)
            before = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            illustrative = _ILLUSTRATIVE.match(before)
            body = [ln[len(indent) :] if ln.startswith(indent) else ln for ln in lines[i + 1 : end]]
            blocks.append(
                Block(
                    page=page,
                    line=i + 1,
                    commands=_commands(page, i + 2, body),
                    illustrative=illustrative.group("why") if illustrative else None,
                    slow=bool(_SLOW.match(before)),
                )
            )
        i = end + 1
    return blocks


def _line_pattern(expected: str) -> re.Pattern[str]:
    return re.compile(".*".join(re.escape(part) for part in expected.split(_ANY_LINES)), re.DOTALL)


def output_matches(expected: list[str], actual: list[str]) -> bool:
    """Whether ``actual`` lines fit ``expected`` under the ``...`` rules."""

    @functools.cache
    def fits(i: int, j: int) -> bool:
        if i == len(expected):
            return j == len(actual)
        if expected[i].strip() == _ANY_LINES:  # any number of lines, none included
            return fits(i + 1, j) or (j < len(actual) and fits(i, j + 1))
        if j == len(actual):
            return False
        wanted = expected[i].rstrip()
        same = (
            _line_pattern(wanted).fullmatch(actual[j]) is not None
            if _ANY_LINES in wanted
            else wanted == actual[j]
        )
        return same and fits(i + 1, j + 1)

    return fits(0, 0)


def _workdir(tmp: Path) -> Path:
    """A fresh folder with the examples' inputs at hand, as the convention promises."""
    (tmp / "docs").mkdir()
    inputs = ((ROOT / "examples", tmp / "examples"), (DOCS / "examples", tmp / "docs" / "examples"))
    for source, target in inputs:
        if source.is_dir():
            shutil.copytree(source, target)
    shutil.copyfile(REFERENCE_PLANT, tmp / "reference_plant.toml")
    return tmp


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    src = str(ROOT / "src")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (src, env.get("PYTHONPATH")) if p)
    # a terminal of fixed width without colour, in UTC: the printed tables and times are stable
    env.update(COLUMNS="80", NO_COLOR="1", TERM="dumb", TZ="UTC", LC_ALL="C.UTF-8")
    env["FUELID_DOCS_PYTHON"] = sys.executable
    return env


# fuelid and python are this checkout's, whatever the PATH says
_PRELUDE = (
    'fuelid() { "$FUELID_DOCS_PYTHON" -m fuelid "$@"; }\n'
    'python() { "$FUELID_DOCS_PYTHON" "$@"; }\n'
    "set -o pipefail\n"
)


def _bash(text: str, cwd: Path, sessions: list[int]) -> tuple[int | None, str]:
    """Run ``text`` in bash; (exit code, or None after the timeout; stdout and stderr merged).

    The command gets a session of its own. Whatever it leaves running in the background (a
    virtual PLC started with ``&`` for the next commands to talk to) lives on until the page
    ends: its session id is appended to ``sessions``, which :func:`_run_page` stops. A command
    that runs over its time is stopped at once. The output goes to a file, not a pipe, which a
    background process could hold open.
    """
    with tempfile.TemporaryFile("w+", encoding="utf-8", errors="replace") as out:
        process = subprocess.Popen(
            ["bash", "-c", _PRELUDE + text],
            cwd=cwd,
            env=_environment(),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        code: int | None
        try:
            code = process.wait(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            code = None
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            process.wait()
        sessions.append(process.pid)
        out.seek(0)
        return code, out.read()


def run_command(command: Command, cwd: Path, page: str, sessions: list[int]) -> None:
    """Run one command in ``cwd`` and fail with the page, line, command and a diff."""
    code, output = _bash(command.text, cwd, sessions)
    if code is None:
        pytest.fail(f"{page}:{command.line}: `{command.text}` ran over {TIMEOUT_S} s")
    actual = [line.rstrip() for line in output.splitlines()]
    while actual and not actual[-1]:
        actual.pop()
    problems = []
    if code != command.exit_code:
        problems.append(f"exit code {code}, the page says {command.exit_code}")
    if command.expected and not output_matches(command.expected, actual):
        diff = difflib.unified_diff(command.expected, actual, "page", "actual", lineterm="")
        problems.append("output differs:\n" + "\n".join(diff))
    elif problems:
        problems.append("output:\n" + "\n".join(actual[-30:]))
    if problems:
        pytest.fail(f"{page}:{command.line}: $ {command.text}\n" + "\n".join(problems))


def _pages_with(slow: bool) -> list[Path]:
    found = []
    for page in doc_pages():
        blocks = [b for b in parse_blocks(page) if b.illustrative is None]
        if any(b.slow == slow for b in blocks):
            found.append(page)
    return found


def _run_page(page: Path, tmp: Path, include_slow: bool) -> None:
    cwd = _workdir(tmp)
    name = str(page.relative_to(ROOT))
    sessions: list[int] = []
    try:
        for block in parse_blocks(page):
            if block.illustrative is not None or (block.slow and not include_slow):
                continue
            for command in block.commands:
                run_command(command, cwd, name, sessions)
    finally:  # what the page's commands left running in the background stops with the page
        for session in sessions:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(session, signal.SIGKILL)


@pytest.mark.parametrize("page", _pages_with(slow=False), ids=lambda p: str(p.relative_to(ROOT)))
def test_console_examples_of_a_page_run_as_written(page: Path, tmp_path: Path) -> None:
    _run_page(page, tmp_path, include_slow=False)


@pytest.mark.slow
@pytest.mark.parametrize("page", _pages_with(slow=True), ids=lambda p: str(p.relative_to(ROOT)))
def test_slow_console_examples_run_as_written(page: Path, tmp_path: Path) -> None:
    # the whole page again, in order: a slow block may use what an earlier block wrote
    _run_page(page, tmp_path, include_slow=True)


def test_every_illustrative_block_says_why() -> None:
    unexplained = [
        f"{block.page.relative_to(ROOT)}:{block.line}"
        for page in doc_pages()
        for block in parse_blocks(page)
        if block.illustrative == ""
    ]
    assert not unexplained, f"<!-- illustrative: --> without a reason: {unexplained}"


def test_the_output_rules() -> None:
    assert output_matches(["a", "b"], ["a", "b"])
    assert not output_matches(["a", "b"], ["a", "b", "c"])
    assert output_matches(["a", "...", "d"], ["a", "b", "c", "d"])
    assert output_matches(["a", "...", "b"], ["a", "b"])  # no lines
    assert output_matches(["K = 13.4... (L/min)/V"], ["K = 13.41 (L/min)/V"])
    assert not output_matches(["K = 13.4... (L/min)/V"], ["K = 12.41 (L/min)/V"])
    assert output_matches(["..."], [])


def test_the_parser_reads_commands_output_exit_codes_and_markers(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "text\n\n```console\n$ fuelid --version\nfuelid ...\n$ fuelid nothing \\\n"
        "    --at-all\nerror: ...\n[exit 2]\n```\n\n<!-- illustrative: needs a PLC -->\n"
        "```console\n$ fuelid record --config site.toml\n```\n<!-- slow -->\n"
        "   ```console\n   $ sleep 1\n   ```\n",
        encoding="utf-8",
    )
    first, second, third = parse_blocks(page)
    assert [c.text for c in first.commands] == [
        "fuelid --version",
        "fuelid nothing \\\n    --at-all",
    ]
    assert first.commands[0].expected == ["fuelid ..."]
    assert (first.commands[1].expected, first.commands[1].exit_code) == (["error: ..."], 2)
    assert (first.commands[1].line, first.line) == (6, 3)
    assert second.illustrative == "needs a PLC"
    assert third.slow
    assert third.commands[0].text == "sleep 1"
