"""What every command shares: error handling at the edge, JSON output, provenance, units."""

from __future__ import annotations

import functools
import hashlib
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import typer

from fuelid import __version__
from fuelid.errors import FuelidError
from fuelid.fuel import T0 as KELVIN

P = ParamSpec("P")
R = TypeVar("R")

EXIT_BAD_INPUT = 2


def fail(message: str) -> typer.Exit:
    """Print a one-line reason on stderr and return the exit for bad input (code 2)."""
    one_line = " ".join(str(message).split())
    typer.echo(f"error: {one_line}", err=True)
    return typer.Exit(EXIT_BAD_INPUT)


def guarded(command: Callable[P, R]) -> Callable[P, R]:
    """Turn every :class:`FuelidError` raised by a command into a one-line message and exit 2."""

    @functools.wraps(command)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return command(*args, **kwargs)
        except FuelidError as exc:
            raise fail(str(exc)) from None

    return wrapper


def _clean(value: Any) -> Any:
    """JSON-safe copy: non-finite floats become null (JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


def emit_json(payload: dict[str, Any]) -> None:
    """Print exactly one JSON object on stdout."""
    sys.stdout.write(json.dumps(_clean(payload), indent=2, allow_nan=False) + "\n")


def warn(message: str) -> None:
    """A warning on stderr (never on stdout, which may carry JSON)."""
    typer.echo(f"warning: {message}", err=True)


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (provenance of results)."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def provenance(options: dict[str, Any], input_file: Path | None = None) -> dict[str, Any]:
    """The provenance block every JSON result carries."""
    return {
        "fuelid_version": __version__,
        "input_sha256": file_sha256(input_file) if input_file is not None else None,
        "options": options,
    }


def celsius_to_kelvin(t_degC: float) -> float:
    """Fuel temperature at the edge [°C] to SI [K]."""
    if not math.isfinite(t_degC):
        raise FuelidError(f"fuel temperature must be finite, got {t_degC}")
    return t_degC + KELVIN
