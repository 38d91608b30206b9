"""A real browser and the dashboard's processes for the page tests.

Debian's Chromium (``make test`` installs it as root) driven by Playwright, which is given the
executable's path: its Python client does not read a browser path from the environment and
would look for a build of its own. Without Chromium the tests skip with the reason, except under
CI (the ``CI`` variable set), where they fail: CI must run them.

The dashboard and the online service run as processes of their own, as in a control room:
``fuelid dashboard --port 0`` prints the address it got; ``fuelid online --virtual`` runs a
virtual PLC and the service.
"""

from __future__ import annotations

import math
import os
import queue
import shutil
import signal
import sqlite3
import subprocess
import sys
import threading
import time
import urllib.parse
from collections.abc import Iterator, Sequence
from contextlib import closing, contextmanager, suppress
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import pytest

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
START_TIMEOUT_S = 60.0
STREAM_ALLOWANCE_S = 0.5
"""Wall time a committed sample may take to reach the page's trend [s].

The dashboard's feed reads the store every 0.2 s (``fuelid.dashboard._stream.POLL_S``); the event
then crosses the loopback and is drawn. A sample committed longer ago than this must be on the
page (:func:`look_at_trend`).
"""
LAG_BAND_S = 10.0
"""A following trend's newest sample at most this far behind the store's [s of plant time]
(those committed :data:`STREAM_ALLOWANCE_S` before the look: at 20x a commit, once a second, is
20 s of plant time)."""
NETWORK_FAILURES = (
    "ERR_CONNECTION_REFUSED",
    "ERR_INCOMPLETE_CHUNKED_ENCODING",
    "ERR_EMPTY_RESPONSE",  # a request the dashboard was answering when it was killed
    "ERR_CONNECTION_RESET",  # one sent as it was killed: the kernel resets the connection
)
"""Console errors a page logs while its dashboard is gone (the stream's retries): expected then."""


def find_chromium() -> str:
    """The Chromium executable; skips (fails under CI) when there is none."""
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    reason = "no Chromium on this machine"
    if os.environ.get("CI"):
        pytest.fail(f"{reason}; CI must run the browser tests (make test installs it as root)")
    pytest.skip(f"{reason}: install it (apt-get install chromium) to run the browser tests")


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("PYTHONUNBUFFERED", "1")
    src = str(Path(__file__).resolve().parents[2] / "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    return env


class Process:
    """A fuelid command in the background; its output lines kept (stdout and stderr)."""

    def __init__(self, args: Sequence[str], cwd: Path) -> None:
        self.args = [sys.executable, "-m", "fuelid", *args]
        self.proc = subprocess.Popen(
            self.args,
            cwd=cwd,
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.output: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.output.append(line.rstrip("\n"))
            self.lines.put(line.rstrip("\n"))

    def wait_for(self, predicate: Any, timeout: float = START_TIMEOUT_S) -> str:
        """The first output line for which ``predicate(line)`` holds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.2)
            except queue.Empty:
                if self.proc.poll() is not None:
                    break
                continue
            if predicate(line):
                return line
        raise AssertionError(
            f"{' '.join(self.args[2:])}: no expected line within {timeout} s "
            f"(exit {self.proc.poll()}); output:\n" + "\n".join(self.output[-40:])
        )

    def wait(self, timeout: float) -> int:
        """Wait for the process to end by itself (killed past the timeout); its exit code."""
        with suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout)
        return self.stop(signal.SIGKILL)

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 20.0) -> int:
        """Signal the process and wait for it (killed past the timeout); its exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self._reader.join(5)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        return int(self.proc.returncode)


@contextmanager
def dashboard(cwd: Path, *args: str, port: int = 0) -> Iterator[tuple[Process, str]]:
    """``fuelid dashboard --port PORT ARGS`` running; yields the process and its base URL.

    ``port`` 0 (the default) lets the dashboard bind a free one; a port a killed dashboard had
    (:func:`port_of` its URL) starts it again on the same address, as a control room's restart
    does (it binds with ``SO_REUSEADDR``: the killed one's connections do not hold the port).
    """
    proc = Process(["dashboard", "--port", str(port), *args], cwd)
    try:
        line = proc.wait_for(lambda s: s.startswith("dashboard: http"))
        yield proc, line.split()[1].rstrip("/")
    finally:
        proc.stop(signal.SIGINT)


def port_of(base: str) -> int:
    """The port of a dashboard's base URL (``http://127.0.0.1:41234``)."""
    port = urllib.parse.urlsplit(base).port
    assert port is not None, base
    return port


@contextmanager
def virtual_service(cwd: Path, store: Path, *args: str) -> Iterator[Process]:
    """``fuelid online --virtual --store STORE ARGS`` running (stopped at the end)."""
    proc = Process(["online", "--virtual", "--store", str(store), *args], cwd)
    try:
        yield proc
    finally:
        proc.stop(signal.SIGINT)


@contextmanager
def browser_pages(
    n: int, width: int = 1400, height: int = 1000
) -> Iterator[tuple[list[Any], list[str]]]:
    """``n`` pages in headless Chromium, and the list their console errors go to.

    Each page has a browser context of its own (its own cookies and connections): to the
    dashboard, separate browsers.
    """
    executable = find_chromium()
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=executable, args=["--no-sandbox"])
        try:
            errors: list[str] = []
            pages = []
            for _ in range(n):
                context = browser.new_context(viewport={"width": width, "height": height})
                page = context.new_page()
                page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
                page.on("pageerror", lambda e: errors.append(f"uncaught: {e}"))
                page.on("requestfailed", _say_request_failed)
                pages.append(page)
            yield pages, errors
        finally:
            browser.close()


def _say_request_failed(request: Any) -> None:
    # the console line names no request: a failure report shows which one, and when
    print(
        f"{time.strftime('%H:%M:%S')} request failed: {request.method} {request.url}: "
        f"{request.failure}"
    )


@contextmanager
def browser_page(width: int = 1400, height: int = 1000) -> Iterator[tuple[Any, list[str]]]:
    """A Playwright page in headless Chromium, and the list its console errors go to."""
    with browser_pages(1, width, height) as (pages, errors):
        yield pages[0], errors


def wait_until(page: Any, expression: str, timeout: float = 30.0) -> Any:
    """Poll a JavaScript expression until it is truthy; its value.

    Not Playwright's ``wait_for_function``: that evaluates a string with ``eval``, which the
    dashboard's Content-Security-Policy (``script-src 'self'``) rightly refuses.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = page.evaluate(expression)
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{expression!r} still false after {timeout} s")
        page.wait_for_timeout(100)


def wait_ready(page: Any, timeout: float = 30.0) -> None:
    """Wait until the page's script says it has drawn (``<body data-ready="1">``)."""
    wait_until(page, "document.body.dataset.ready === '1'", timeout)


# --- what a loop page shows --------------------------------------------------------------------


def iso_seconds(text: str | None) -> float | None:
    """An ISO time the page wrote (``2026-11-27T08:15:03.400Z``) in s UTC; None when empty."""
    if not text:
        return None
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


def _read_store(store: Path, sql: str, args: Sequence[Any] = ()) -> Any:
    """One row of a query on a store a service is writing (read only, waits for its lock)."""
    with closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=10.0)) as con:
        return con.execute(sql, tuple(args)).fetchone()


def store_newest(store: Path, committed_before: float | None = None) -> float | None:
    """The store's newest sample [plant s UTC].

    With ``committed_before`` [wall s UTC]: the newest of those committed by then (looked for
    among the newest 10 min of plant time).
    """
    if committed_before is None:
        (newest,) = _read_store(store, "SELECT max(time) FROM samples")
    else:
        (newest,) = _read_store(
            store,
            "SELECT max(time) FROM samples WHERE time > "
            "(SELECT max(time) FROM samples) - 600 AND wall_time <= ?",
            (committed_before,),
        )
    return None if newest is None else float(newest)


def store_last_commit(store: Path) -> float | None:
    """The wall time the newest sample was committed [s UTC] (``samples.wall_time``)."""
    (wall,) = _read_store(
        store,
        "SELECT wall_time FROM samples WHERE time = (SELECT max(time) FROM samples)",
    )
    return None if wall is None else float(wall)


@dataclass(frozen=True)
class TrendLook:
    """One look at the loop page's live trend, beside the store it draws.

    Attributes
    ----------
    wall : float
        When [wall s UTC].
    following : bool
        ``#trend[data-following]`` is "1".
    newest, range_end : float or None
        ``data-newest`` and ``data-range-end`` [plant s UTC].
    points : int
        ``data-points``: the points the trend holds.
    store_newest : float or None
        The store's newest sample, read just after the look [plant s UTC].
    store_settled : float or None
        The store's newest sample committed :data:`STREAM_ALLOWANCE_S` before the look.
    """

    wall: float
    following: bool
    newest: float | None
    range_end: float | None
    points: int
    store_newest: float | None
    store_settled: float | None

    @property
    def lag_s(self) -> float:
        """How far the page is behind the samples it must have [plant s] (NaN when unknown)."""
        if self.newest is None or self.store_settled is None:
            return math.nan
        return self.store_settled - self.newest

    @property
    def gap_s(self) -> float:
        """How far the page is behind the store's newest sample [plant s] (NaN when unknown)."""
        if self.newest is None or self.store_newest is None:
            return math.nan
        return self.store_newest - self.newest


def look_at_trend(page: Any, store: Path) -> TrendLook:
    """What ``#trend`` says now, and the store's newest samples (:class:`TrendLook`)."""
    shown = page.evaluate(
        "(() => { const d = document.getElementById('trend').dataset;"
        " return [d.following, d.newest, d.rangeEnd, d.points]; })()"
    )
    wall = time.time()
    return TrendLook(
        wall=wall,
        following=shown[0] == "1",
        newest=iso_seconds(shown[1]),
        range_end=iso_seconds(shown[2]),
        points=int(shown[3] or 0),
        store_newest=store_newest(store),
        store_settled=store_newest(store, wall - STREAM_ALLOWANCE_S),
    )


def following_faults(look: TrendLook, before: TrendLook | None) -> list[str]:
    """What is wrong with a look at a trend that must follow the store (empty: nothing).

    It follows (``data-following`` "1"), its axis ends at its newest sample, that sample is at
    most :data:`LAG_BAND_S` behind the samples committed :data:`STREAM_ALLOWANCE_S` before the
    look and not ahead of the store, and it is newer than at the look ``before``.
    """
    faults = []
    if not look.following:
        faults.append("not following")
    if look.newest is None or look.range_end is None:
        return [*faults, "no sample drawn"]
    if abs(look.range_end - look.newest) > 0.002:  # the ISO times carry milliseconds
        faults.append(f"the axis ends {look.range_end - look.newest:+.3f} s from the newest")
    if not look.lag_s <= LAG_BAND_S:
        faults.append(f"{look.lag_s:.1f} s of plant time behind the store")
    if look.store_newest is None or look.newest > look.store_newest + 0.002:
        faults.append("ahead of the store")
    if before is not None and before.newest is not None and not look.newest > before.newest:
        faults.append("not advancing")
    return faults


def page_chips(page: Any) -> dict[str, tuple[str, str]]:
    """The loop page's chips: name → (level, text without the "name: " prefix)."""
    rows = page.evaluate(
        "Array.from(document.querySelectorAll('#chips .chip')).map((c) => "
        "[c.title, Array.from(c.classList).filter((k) => k !== 'chip')[0] || '', c.textContent])"
    )
    return {name: (level, text.removeprefix(f"{name}: ")) for name, level, text in rows}


def heap_used(cdp: Any) -> dict[str, float]:
    """The tab's JavaScript heap after a garbage collection, and its DOM counters.

    ``performance.memory`` cannot run a collection first; the DevTools protocol can
    (``HeapProfiler.collectGarbage``, then ``Runtime.getHeapUsage``). ``cdp``: a session from
    ``page.context.new_cdp_session(page)``. Keys: ``used_MB``, ``total_MB``, ``nodes``,
    ``listeners``.
    """
    cdp.send("HeapProfiler.collectGarbage")
    usage = cdp.send("Runtime.getHeapUsage")
    counters = cdp.send("Memory.getDOMCounters")
    return {
        "used_MB": usage["usedSize"] / 1e6,
        "total_MB": usage["totalSize"] / 1e6,
        "nodes": float(counters["nodes"]),
        "listeners": float(counters["jsEventListeners"]),
    }
