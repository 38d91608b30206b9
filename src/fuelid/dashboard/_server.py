"""Running the dashboard: its own process, uvicorn on one socket, the loops opened first.

:func:`serve` checks the bind address (:func:`~fuelid.dashboard._security.check_bind`), opens
every store (a refused one stops the start with the reason), binds the socket itself (so that
``port=0`` gets a free port and the address printed is the real one) and runs uvicorn until
SIGINT/SIGTERM. Behind a reverse proxy, uvicorn trusts ``X-Forwarded-*`` from 127.0.0.1 only.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType

from fuelid.dashboard._registry import Loops
from fuelid.dashboard._security import Security, check_bind
from fuelid.dashboard._users import UsersFile
from fuelid.errors import ConfigError

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "Beside", "serve"]

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8050


def _bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as error:
        sock.close()
        raise ConfigError(
            f"--host {host} --port {port}: cannot listen there ({error.strerror})"
        ) from None
    sock.listen(128)
    sock.set_inheritable(True)
    return sock


def serve(
    stores: Sequence[str | Path],
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    users: Path | None = None,
    allow_remote: bool = False,
    ssl_certfile: Path | None = None,
    ssl_keyfile: Path | None = None,
    on_ready: Callable[[str, list[str]], None] | None = None,
    central: str | None = None,
    archive: Path | None = None,
    trend_minutes: float = 10.0,
) -> None:
    """Serve the dashboard until interrupted.

    Parameters
    ----------
    stores : sequence of path
        Store files and folders of stores (watched for new ones).
    host, port : str, int
        Where to listen (loopback unless ``allow_remote``); port 0: a free port.
    users : Path, optional
        The users file (needed to log in; required with ``allow_remote``).
    allow_remote : bool
        Listen on a non-loopback address; every page then needs a login.
    ssl_certfile, ssl_keyfile : Path, optional
        TLS by uvicorn itself (else a reverse proxy in front, see the docs).
    on_ready : callable, optional
        Called with the URL and the loop ids once listening.
    central : str, optional
        The central store's libpq URL: its loops are shown beside the local stores.
    archive : Path, optional
        The raw archive (the folder ``fuelid archive`` writes) the central loops' trends read.
    trend_minutes : float
        The span the loop pages' live trend follows [min].

    Raises
    ------
    ConfigError
        A refused address, users file or store (one-line reason).
    """
    import uvicorn

    from fuelid.dashboard._app import create_app

    users_file = users if users is not None and Path(users).exists() else None
    check_bind(host, allow_remote, users_file)
    if users is not None and users_file is None:
        raise ConfigError(
            f"--users {users}: no such file (add a user with fuelid dashboard user add)"
        )
    if (ssl_certfile is None) != (ssl_keyfile is None):
        raise ConfigError("--ssl-certfile and --ssl-keyfile go together")
    if not stores and central is None:
        raise ConfigError("give --store (a store file or a folder of stores) or --central URL")
    if archive is not None and central is None:
        raise ConfigError("--archive goes with --central (the central loops' raw samples)")
    if archive is not None and not Path(archive).is_dir():
        raise ConfigError(f"--archive {archive}: no such folder")
    security = Security(UsersFile(users_file) if users_file else None, require_login=allow_remote)
    loops = open_loops(stores, central, archive)
    try:
        sock = _bind(host, port)
        app = create_app(loops, security, trend_minutes=trend_minutes)
        config = uvicorn.Config(
            app,
            log_level="warning",
            proxy_headers=True,
            forwarded_allow_ips="127.0.0.1",
            ssl_certfile=None if ssl_certfile is None else str(ssl_certfile),
            ssl_keyfile=None if ssl_keyfile is None else str(ssl_keyfile),
            timeout_graceful_shutdown=2,
        )
        server = uvicorn.Server(config)
        bound = sock.getsockname()
        scheme = "https" if ssl_certfile else "http"
        shown = f"[{bound[0]}]" if ":" in bound[0] else bound[0]
        if on_ready is not None:
            on_ready(f"{scheme}://{shown}:{bound[1]}/", loops.ids())
        server.run(sockets=[sock])
    finally:
        loops.close()


def open_loops(
    stores: Sequence[str | Path], central: str | None = None, archive: Path | None = None
) -> Loops:
    """The loops of the stores and, with ``central``, of the central store.

    Raises
    ------
    ConfigError
        A refused store, or a central store that cannot be reached or used (one line).
    """
    from fuelid.central import CentralError
    from fuelid.dashboard._central_loops import CentralLoops
    from fuelid.dashboard._registry import WATCH_EVERY_S

    fleet = None
    if central is not None:
        try:
            fleet = CentralLoops(central, archive=archive, every_s=WATCH_EVERY_S)
        except CentralError as error:
            raise ConfigError(f"--central: {error}") from None
    try:
        return Loops(stores, central=fleet, prefetch_reports=True)
    except BaseException:
        if fleet is not None:
            fleet.close()
        raise


class Beside:
    """``fuelid dashboard`` as a process of its own beside the online service.

    The service's process never serves a page (a browser must not cost the recorder a sample):
    this starts ``python -m fuelid dashboard --store STORE --port PORT`` with the same
    interpreter, its output going where the service's goes, and stops it (SIGINT, then a kill
    after a grace period) when the service stops.

    Parameters
    ----------
    store : str or Path
        The service's store file.
    port : int
        The dashboard's port (on 127.0.0.1).
    users : Path, optional
        The users file.
    """

    GRACE_S = 5.0

    def __init__(self, store: str | Path, port: int = DEFAULT_PORT, users: Path | None = None):
        args = [sys.executable, "-m", "fuelid", "dashboard", "--store", str(store)]
        args += ["--port", str(int(port)), "--beside-service"]
        if users is not None:
            args += ["--users", str(users)]
        self.args = args
        self.process: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> Beside:
        self.process = subprocess.Popen(self.args)
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        process, self.process = self.process, None
        if process is None or process.poll() is not None:
            return
        process.send_signal(signal.SIGINT)
        try:
            process.wait(self.GRACE_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
