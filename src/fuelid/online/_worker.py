"""Window analysis in a worker process, so a fit never costs the recorder a sample.

The recorder reads the PLC's ring buffer in an asyncio loop; a window's fit is ~0.2–1 s of
mostly Python-level work that would hold the interpreter lock in a thread and, at a fast
sample rate or on a busy machine, let the PLC's ring overrun. :class:`WindowWorker` runs
:func:`analyse_window` in one worker process (``spawn``, so no lock or socket of the service is
inherited), keeping the analyser and its warm start there between windows; the service sends the
window's samples and the last accepted model, and gets the :class:`~fuelid.online._window.
WindowResult` back without its estimator object. ``isolate=False`` runs the same function in a
thread of the service (tests, or a platform without process pools).

A worker that dies (killed, out of memory) is replaced at the next window; that window is
rejected with the reason.
"""

from __future__ import annotations

import asyncio
import multiprocessing
import os
import threading
import time
from concurrent.futures import Executor, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from functools import partial

from fuelid.model import ProcessModel
from fuelid.online._settings import Online
from fuelid.online._window import WindowAnalyser, WindowPriors, WindowResult, window_priors
from fuelid.online.gates import WindowVerdict
from fuelid.store import SampleArrays


@dataclass(frozen=True)
class AnalyserSpec:
    """Everything that makes a window analyser, in a form a worker process can receive."""

    settings: Online
    priors: WindowPriors
    sample_time: float
    plant_path: str | None
    step_ls: bool = True


_CURRENT: tuple[AnalyserSpec, WindowAnalyser] | None = None
"""The worker's analyser (one per process), rebuilt when the spec changes."""


def _analyser(spec: AnalyserSpec) -> WindowAnalyser:
    global _CURRENT
    if _CURRENT is None or _CURRENT[0] != spec:
        _, k_plant = (
            window_priors(spec.plant_path, control_period=spec.priors.control_period)
            if spec.plant_path is not None
            else (None, None)
        )
        analyser = WindowAnalyser(
            spec.settings, spec.priors, spec.sample_time, k_plant=k_plant, step_ls=spec.step_ls
        )
        _CURRENT = (spec, analyser)
    return _CURRENT[1]


def analyse_window(
    spec: AnalyserSpec,
    samples: SampleArrays,
    t_from: float,
    t_to: float,
    ti_s: float,
    warm: ProcessModel | None,
) -> WindowResult:
    """Analyse one window with the (cached) analyser of ``spec``, warm-started from ``warm``.

    The analyser's own warm start (the last noise model) is kept when ``warm`` is the model it
    accepted last; the returned result carries no estimator object.
    """
    analyser = _analyser(spec)
    analyser.ti_s = ti_s
    if warm != analyser.last_model_:
        analyser.resume(warm)
    result = analyser.analyse(samples, t_from, t_to)
    analyser.accept(result)
    result.estimator = None
    return result


PARENT_POLL_S = 1.0
"""How often the worker checks that the service is still alive [s]."""


def _exit_with_parent(parent_pid: int) -> None:
    """In the worker: exit when the service is gone (a kill -9 runs no clean-up of the pool)."""

    def watch() -> None:
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent_pid:  # re-parented: the service died
                os._exit(0)

    threading.Thread(target=watch, name="fuelid-parent-watch", daemon=True).start()


class WindowWorker:
    """Runs :func:`analyse_window` in a worker process (or a thread with ``isolate=False``)."""

    def __init__(self, spec: AnalyserSpec, *, isolate: bool = True) -> None:
        self.spec = spec
        self.isolate = isolate
        self._executor: Executor | None = None

    def _pool(self) -> Executor | None:
        if self.isolate and self._executor is None:
            self._executor = ProcessPoolExecutor(
                max_workers=1,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_exit_with_parent,
                initargs=(os.getpid(),),
            )
        return self._executor

    async def analyse(
        self,
        samples: SampleArrays,
        t_from: float,
        t_to: float,
        ti_s: float,
        warm: ProcessModel | None,
    ) -> WindowResult:
        """The window's result; a crashed worker gives a rejected window with the reason."""
        job = partial(analyse_window, self.spec, samples, t_from, t_to, ti_s, warm)
        loop = asyncio.get_running_loop()
        try:
            return await loop.run_in_executor(self._pool(), job)
        except BrokenProcessPool:
            self.close()
            return WindowResult(
                t_from=t_from,
                t_to=t_to,
                verdict=WindowVerdict.of(["analysis failed: the worker process died"], {}),
                samples=len(samples),
                good_samples=0,
                T_fuel_C=None,
                u_mean=None,
                y_mean=None,
            )

    def close(self) -> None:
        """Stop the worker process."""
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None


__all__ = ["AnalyserSpec", "WindowWorker", "analyse_window"]
