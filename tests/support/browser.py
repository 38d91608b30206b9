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

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import pytest

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
START_TIMEOUT_S = 60.0


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
def dashboard(cwd: Path, *args: str) -> Iterator[tuple[Process, str]]:
    """``fuelid dashboard --port 0 ARGS`` running; yields the process and its base URL."""
    proc = Process(["dashboard", "--port", "0", *args], cwd)
    try:
        line = proc.wait_for(lambda s: s.startswith("dashboard: http"))
        yield proc, line.split()[1].rstrip("/")
    finally:
        proc.stop(signal.SIGINT)


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
                pages.append(page)
            yield pages, errors
        finally:
            browser.close()


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
