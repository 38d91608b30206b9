"""How many threads the linear-algebra library may use: one, for fuelid's kind of work.

fuelid multiplies long vectors and many small or thin matrices (identification, frequency
responses over plant variants, closed-loop checks). One thread does that at memory speed, while a
multi-threaded BLAS on a busy two-core machine (a PLC's industrial PC, CI) spends most of its time
waiting for its other thread: measured 60× slower for the residual correlations of one hour of
50 Hz data under load.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = [
    "single_threaded_blas",
]


@functools.cache
def _blas_controller() -> Any:
    """Found once: scanning the loaded BLAS libraries costs tens of milliseconds."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the enclosed numpy work with BLAS on one thread (restored afterwards).

    Examples
    --------
    >>> import numpy as np
    >>> with single_threaded_blas():
    ...     float(np.ones(3) @ np.ones(3))
    3.0
    """
    with _blas_controller().limit(limits=1, user_api="blas"):
        yield
