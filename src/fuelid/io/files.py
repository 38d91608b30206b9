"""Writing files safely: atomic replacement, refusing to overwrite, CSV or Parquet by suffix.

A file fuelid writes is never half-written: it goes to a temporary file beside the target and is
renamed over it, so a crash or a full disk leaves the old file (or none), never a truncated one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pandas as pd

from fuelid.errors import DataError

TABLE_SUFFIXES = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet"}


def _publish(temporary: str, target: Path) -> None:
    """Give a finished temporary file the usual permissions and rename it onto the target.

    ``mkstemp`` creates files readable by their owner only; a log or a report is meant to be
    shared like any file the user creates, so the umask decides, as for ``open()``.
    """
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temporary, 0o666 & ~umask)
    os.replace(temporary, target)


def atomic_write_bytes(path: str | Path, payload: bytes) -> Path:
    """Write bytes to a temporary file beside ``path``, then rename: never a half-written file."""
    out = Path(path)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent or ".")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
        _publish(tmp_name, out)
    except BaseException:
        Path(tmp_name).unlink(missing_ok=True)
        raise
    return out


def table_format(path: str | Path) -> str:
    """``"csv"`` or ``"parquet"`` from a file name, or a :class:`DataError` naming the choices."""
    suffix = Path(path).suffix.lower()
    try:
        return TABLE_SUFFIXES[suffix]
    except KeyError:
        choices = ", ".join(TABLE_SUFFIXES)
        raise DataError(
            f"cannot tell the table format of {str(path)!r}: use one of the extensions {choices}"
        ) from None


def check_output_path(path: str | Path, overwrite: bool = False) -> Path:
    """Validate where a table will be written, before any work is done.

    Refuses an unknown extension, a missing folder, a folder given as the file, and an existing
    file unless ``overwrite`` (so a typo never destroys a log).
    """
    out = Path(path)
    table_format(out)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise DataError(f"output folder {str(parent)!r} does not exist")
    if out.is_dir():
        raise DataError(f"output path {str(out)!r} is a folder, not a file")
    if out.exists() and not overwrite:
        raise DataError(f"{str(out)!r} exists; pass --force to replace it")
    return out


def write_table(frame: pd.DataFrame, path: str | Path, overwrite: bool = False) -> Path:
    """Write a table atomically: to a temporary file beside the target, then renamed.

    A failed write never leaves a half-written file nor destroys an existing one.

    Parameters
    ----------
    frame : DataFrame
        The table.
    path : str or Path
        Target; ``.csv`` or ``.parquet``/``.pq``.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        The written file.
    """
    out = check_output_path(path, overwrite)
    fmt = table_format(out)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent or ".")
    os.close(fd)
    try:
        if fmt == "csv":
            frame.to_csv(tmp_name, index=False, float_format="%.10g")
        else:
            frame.to_parquet(tmp_name, index=False)
        _publish(tmp_name, out)
    except Exception:
        Path(tmp_name).unlink(missing_ok=True)
        raise
    return out
