"""A guarded command runs with BLAS on one thread for the whole of its body."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from threadpoolctl import threadpool_info, threadpool_limits


def test_guarded_commands_run_with_blas_on_one_thread(monkeypatch: pytest.MonkeyPatch):
    import fuelid.blas
    from fuelid.cli._common import guarded

    entered: list[str] = []
    real = fuelid.blas.single_threaded_blas

    @contextmanager
    def spy() -> Iterator[None]:
        entered.append("in")
        with real():
            yield
        entered.append("out")

    monkeypatch.setattr(fuelid.blas, "single_threaded_blas", spy)

    @guarded
    def command() -> list[int]:
        assert entered == ["in"]
        return [info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"]

    # the suite runs BLAS on one thread (tests/conftest.py): lift that here, so the one thread
    # seen inside the command is the command's own doing
    with threadpool_limits(limits=2, user_api="blas"):
        threads = command()
    assert entered == ["in", "out"]
    assert threads
    assert set(threads) == {1}
