"""The control-room dashboard (``fuelid dashboard``): FastAPI pages over the loops' stores.

A process of its own (never the recorder's): it opens each loop's store, or the central store of
many loops (``--central``), reads every loop through one interface, :class:`LoopReader`, and
serves the fleet, loop and window pages, the JSON API under ``/api/`` and one live stream per
page. It writes nothing into a store but the requests people file (approve, reject, revert),
which the running service carries out; on a central loop they are central requests, relayed to
the site's service at its next sync. Beside a store file, in ``<store>.reports/``, it keeps the
windows' HTML reports it made, for its next run (a cache: safe to delete at any time).

The public API: :class:`LoopReader` and :class:`SQLiteLoop` (one loop's data),
:class:`CentralLoop` (one loop of the central store) and :class:`CentralLoops` (its loops,
polled), :class:`Loops` (the loops by id, a folder watched), :func:`create_app` (the FastAPI
application) and :func:`serve` (uvicorn on a socket), :class:`Beside` (the dashboard as a
process beside the online service), and the logins: :class:`Security` (users, sessions, the
login limit and the CSRF check, whose header is :data:`CSRF_HEADER`) over a
:class:`UsersFile`. ``create_app`` and ``serve`` need the ``dashboard`` extra (FastAPI,
uvicorn); the rest only fuelid's own dependencies and tsdownsample for the trend.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

from fuelid.dashboard._registry import Loops
from fuelid.dashboard._source import LoopReader, SQLiteLoop

if TYPE_CHECKING:
    from fuelid.dashboard._app import create_app
    from fuelid.dashboard._central_loops import CentralLoops
    from fuelid.dashboard._central_source import CentralLoop
    from fuelid.dashboard._security import CSRF_HEADER, Security
    from fuelid.dashboard._server import Beside, serve
    from fuelid.dashboard._users import UsersFile

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_app": ["create_app"],
        "_central_loops": ["CentralLoops"],
        "_central_source": ["CentralLoop"],
        "_security": ["CSRF_HEADER", "Security"],
        "_server": ["Beside", "serve"],
        "_users": ["UsersFile"],
    },
)[0]

__all__ = [
    "CSRF_HEADER",
    "Beside",
    "CentralLoop",
    "CentralLoops",
    "LoopReader",
    "Loops",
    "SQLiteLoop",
    "Security",
    "UsersFile",
    "create_app",
    "serve",
]
