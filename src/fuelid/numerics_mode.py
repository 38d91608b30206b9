"""The switch to fuelid's numerics as they were before issue 26 (the benchmark's "today" path).

:func:`reference_numerics` makes :func:`fuelid.lti.discretise` go through scipy's
``cont2discrete`` and ``ss2tf`` and the autocorrelations take one dot product per lag: the same
numbers to rounding, slower. :mod:`fuelid.lti` re-exports both names, their usual path.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["reference_numerics", "reference_numerics_on"]

_REFERENCE = ContextVar("fuelid_reference_numerics", default=False)


def reference_numerics_on() -> bool:
    """True inside :func:`reference_numerics`."""
    return _REFERENCE.get()


@contextmanager
def reference_numerics() -> Iterator[None]:
    """Run the numerics as they were before issue 26 (for the benchmark's "today" path).

    :func:`fuelid.lti.discretise` through scipy's ``cont2discrete`` and ``ss2tf``,
    autocorrelations over many lags by one dot product per lag
    (:mod:`fuelid.identify.diagnostics`): the same numbers to rounding, slower.
    ``WindowAnalyser(fast=False)`` runs inside it.
    """
    token = _REFERENCE.set(True)
    try:
        yield
    finally:
        _REFERENCE.reset(token)
