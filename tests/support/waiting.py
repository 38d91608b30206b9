"""Waiting for something to happen, with a deadline: the one home of the tests' polls.

A test that needs something to have happened (a server up, a row committed, a state changed)
polls for that condition with :func:`wait_until` (or :func:`await_until` in a coroutine) rather
than sleeping a fixed time: a fixed sleep is too short on a loaded machine (the test fails for no
reason) and too long everywhere else (the suite waits for nothing). Past its deadline the wait
fails naming what it waited for.

A ``time.sleep`` left in a test is the behaviour under test, and says so in a comment: a link
held down for a stated time longer than the recorder's poll, a random (seeded) point to kill a
process at, a producer's pace, or the window of a negative check (nothing happens during it: a
shorter window can only let the test pass without checking, never fail it for no reason).
"""

from __future__ import annotations

import asyncio
import inspect
import time
from collections.abc import Awaitable, Callable
from typing import TypeVar

T = TypeVar("T")

POLL_S = 0.02
"""How often a condition is looked at [s]: short against every deadline of the tests."""


def _described(what: str | Callable[[], str]) -> str:
    return what() if callable(what) else what


def wait_until(
    condition: Callable[[], T],
    timeout: float,
    what: str | Callable[[], str],
    *,
    every: float = POLL_S,
) -> T:
    """Poll ``condition()`` until it is truthy; its value.

    Parameters
    ----------
    condition : callable
        Looked at every ``every`` seconds, once more at the deadline.
    timeout : float
        The deadline [s]; past it an ``AssertionError`` names ``what``.
    what : str or callable
        What is waited for ("the writer's first commit"), or a function giving it at the
        deadline (to add the state seen then, such as a process's output).
    every : float
        The poll period [s].
    """
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {_described(what)}")
        time.sleep(every)


async def await_until(
    condition: Callable[[], T | Awaitable[T]],
    timeout: float,
    what: str | Callable[[], str],
    *,
    every: float = POLL_S,
) -> T:
    """:func:`wait_until` in a coroutine: ``condition`` may be a coroutine function too."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if inspect.isawaitable(value):
            value = await value
        if value:
            return value  # type: ignore[return-value]  # awaited above when it was awaitable
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {_described(what)}")
        await asyncio.sleep(every)
