"""The one warning of a module's old path: what the deprecation shims of 0.2.0 call on import.

A module that moved keeps a shim at its old path (``fuelid.simulate`` for
:mod:`fuelid.plant.simulate`, …): it re-exports the moved module's names and calls
:func:`warn_moved` once, when it is first imported, so that a user's script keeps working and is
told where the module went.
"""

from __future__ import annotations

import sys
import warnings

# importlib.import_module's frame between a caller and the import system. warnings.warn skips
# the import system's own frames (<frozen importlib._bootstrap...>) when it counts stacklevel,
# but not this one.
_IMPORT_MODULE_FILES = ("importlib/__init__.py", "importlib\\__init__.py")


def _importer_stacklevel() -> int:
    """The ``stacklevel`` that points past the import machinery at the line that imported the shim.

    Counted as :func:`warnings.warn` counts it from :func:`warn_moved` (level 1 is ``warn_moved``,
    2 the shim's module body, then the importer, the import system's frames skipped). The warning
    is then attributed to the user's module, so Python's default filter shows it for a script
    run as ``__main__`` (and hides it for a third-party module).
    """
    level = 3
    frame = sys._getframe(3)  # 0 this function, 1 warn_moved, 2 the shim, 3 on: its importer
    while frame.f_back is not None:
        filename = frame.f_code.co_filename
        if filename.endswith(_IMPORT_MODULE_FILES):
            level += 1
        elif not ("importlib" in filename and "_bootstrap" in filename):
            break
        frame = frame.f_back
    return level


def warn_moved(old: str, new: str) -> None:
    """Warn once (per import of the shim) that module ``old`` moved to ``new``.

    Parameters
    ----------
    old : str
        The deprecated dotted path, e.g. ``"fuelid.simulate"``.
    new : str
        Where the module lives now, e.g. ``"fuelid.plant.simulate"``.
    """
    warnings.warn(
        f"{old} moved to {new} in fuelid 0.2.0; import {new} instead "
        f"(the old path will be removed in a future release)",
        DeprecationWarning,
        stacklevel=_importer_stacklevel(),
    )


def warn_renamed(owner: object, old: str, new: str = "to_json") -> None:
    """Warn that method ``old`` of ``owner``'s class is now ``new`` (fuelid 0.2.0).

    Every result object serialises itself with ``to_json()``; the ``to_dict()`` and ``as_dict()``
    of 0.1 stay, for one minor version, as aliases that call this and then ``to_json()``.

    Parameters
    ----------
    owner : object
        The instance whose old method was called.
    old : str
        The old method's name, e.g. ``"as_dict"``.
    new : str
        Its new name.
    """
    name = type(owner).__name__
    warnings.warn(
        f"{name}.{old}() is renamed {name}.{new}() in fuelid 0.2.0; call {new}() instead "
        f"(the old name will be removed in a future release)",
        DeprecationWarning,
        stacklevel=3,
    )
