"""The one exception hierarchy of fuelid.

Every error that bad input can cause is a :class:`FuelidError` (a :class:`ValueError`), so the
command line turns it into a one-line message and exit code 2, and library users can catch it
with a single ``except``.
"""

from __future__ import annotations


class FuelidError(ValueError):
    """Base class of every error fuelid raises on bad input or refused data."""


class ConfigError(FuelidError):
    """A plant configuration file is unreadable, incomplete or physically impossible."""


class OutOfRangeError(FuelidError):
    """A value lies outside the validity range of a correlation or a model."""


class DataError(FuelidError):
    """A data file or time series cannot be read, written or used."""


class NotExcitingError(DataError):
    """The data do not carry enough excitation to identify the requested model."""


class NotFittedError(FuelidError, AttributeError):
    """An estimator's fitted attribute or method was used before ``fit``.

    Also an :class:`AttributeError`, as in scikit-learn, so ``hasattr(estimator, "K_")`` is False
    before ``fit`` and attribute-probing tools (copy, pickle) keep working.
    """
