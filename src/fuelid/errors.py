"""The one exception hierarchy of fuelid.

Every error that bad input can cause is a :class:`FuelidError` (a :class:`ValueError`), so the
command line turns it into a one-line message and exit code 2, and library users can catch it
with a single ``except``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

__all__ = [
    "VALUE_ERROR_PREFIX",
    "ConfigError",
    "DataError",
    "FuelidError",
    "NotExcitingError",
    "NotFittedError",
    "OutOfRangeError",
    "plain_reason",
    "validation_reason",
]


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


VALUE_ERROR_PREFIX = "Value error, "
"""What pydantic (and typer, which converts options with it) puts before the message of a
``ValueError`` raised by a validator: noise to the reader, removed by :func:`plain_reason`."""


def plain_reason(message: str) -> str:
    """A validation message without pydantic's ``"Value error, "`` prefix, wherever it sits.

    Examples
    --------
    >>> plain_reason("Invalid value for '--rule': Value error, 'foo' is not one of 'simc'.")
    "Invalid value for '--rule': 'foo' is not one of 'simc'."
    """
    return message.replace(VALUE_ERROR_PREFIX, "")


def validation_reason(error: Mapping[str, Any]) -> str:
    """One pydantic validation error (an item of ``ValidationError.errors()``) in plain words.

    Without its location (the caller names the file and key). A key that is missing or
    unknown says so; a value outside a fixed set of choices names the value and the choices;
    a validator's own message is kept without pydantic's prefix; any other message gets the
    value that was found.

    Examples
    --------
    >>> validation_reason({"type": "literal_error", "input": "foo",
    ...     "msg": "Input should be 'simc' or 'amigo'", "ctx": {"expected": "'simc' or 'amigo'"}})
    "'foo' is not one of the known choices: simc, amigo"
    >>> validation_reason({"type": "value_error", "msg": "Value error, T must be positive"})
    'T must be positive'
    >>> validation_reason({"type": "greater_than", "msg": "Input should be greater than 0",
    ...     "input": -1.0})
    'Input should be greater than 0 (got -1.0)'
    """
    kind = str(error.get("type", ""))
    if kind == "missing":
        return "missing required key"
    if kind == "extra_forbidden":
        return "unknown key"
    message = plain_reason(str(error.get("msg", "")))
    if kind in {"literal_error", "enum"} and "input" in error:
        expected = str((error.get("ctx") or {}).get("expected", ""))
        choices = re.findall(r"'([^']*)'", expected)
        if choices:
            return f"{error['input']!r} is not one of the known choices: {', '.join(choices)}"
    if kind not in {"value_error", "model_type"} and "input" in error:
        message += f" (got {error['input']!r})"
    return message
