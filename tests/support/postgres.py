"""A temporary PostgreSQL cluster for the central-store tests and the benchmark.

:class:`PgCluster` runs ``initdb -U fuelid --auth=trust`` into a fresh folder and ``pg_ctl``
on a free loopback port (``listen_addresses=127.0.0.1``, the socket in the cluster's folder),
stops it (``-m immediate``: a crash, for the outage tests) and restarts it, and removes the
folder at the end. The server refuses to run as root: as root the folder is given to the user
``postgres`` (or ``nobody``) and every server command runs through ``runuser -u USER --``.

The binaries: ``initdb`` on PATH, else Debian's ``/usr/lib/postgresql/<major>/bin`` (``make
test`` installs the ``postgresql`` package as root when neither exists). Without them
:func:`find_pg_bin` skips the test with the reason, except under CI (the ``CI`` variable set),
where it fails: CI must run the central-store tests (as :mod:`support.browser` does for
Chromium).
"""

from __future__ import annotations

import contextlib
import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

import pytest

from support.waiting import wait_until

START_TIMEOUT_S = 60
SERVER_USERS = ("postgres", "nobody")


def find_pg_bin() -> Path:
    """The folder of ``initdb`` and ``pg_ctl``; skips (fails under CI) when there is none."""
    found = shutil.which("initdb")
    if found and shutil.which("pg_ctl"):
        return Path(found).parent
    for candidate in sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), reverse=True):
        return Path(candidate).parent
    reason = "no PostgreSQL server binaries (initdb, pg_ctl) on this machine"
    if os.environ.get("CI"):
        pytest.fail(f"{reason}; CI must run the central-store tests (make postgres installs it)")
    pytest.skip(f"{reason}: run `make postgres` as root (apt-get install postgresql)")


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now (the server binds it a moment later)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class PgCluster:
    """A throw-away PostgreSQL cluster on 127.0.0.1 (see the module docstring).

    Parameters
    ----------
    bin_dir : Path
        Where ``initdb`` and ``pg_ctl`` are.
    settings : dict, optional
        Extra server settings (``-c name=value``).
    """

    def __init__(self, bin_dir: Path, settings: dict[str, str] | None = None) -> None:
        self.bin_dir = bin_dir
        self.settings = {
            "listen_addresses": "127.0.0.1",
            "fsync": "off",  # a test cluster: a crash of the machine may lose it
            "max_connections": "60",
            **(settings or {}),
        }
        self.port = free_port()
        # under /tmp itself, not pytest's tmp_path: pytest's folders are 0700 root, which the
        # server's user cannot enter
        self.root = Path(tempfile.mkdtemp(prefix="fuelid-pg-"))
        self.data = self.root / "data"
        self.log = self.root / "server.log"
        self.user: str | None = None
        if os.geteuid() == 0:
            self.user = next(u for u in SERVER_USERS if _has_user(u))
            owner = pwd.getpwnam(self.user)
            os.chown(self.root, owner.pw_uid, owner.pw_gid)
            os.chmod(self.root, 0o700)
        self._run("initdb", "-D", str(self.data), "-U", "fuelid", "--auth=trust", "-E", "UTF8")

    def _run(self, tool: str, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        command = [str(self.bin_dir / tool), *args]
        if self.user is not None:
            command = ["runuser", "-u", self.user, "--", *command]
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=START_TIMEOUT_S, check=False
        )
        if check and done.returncode != 0:
            log = self.log.read_text() if self.log.exists() else ""
            raise RuntimeError(f"{tool} failed: {done.stderr.strip()} {log[-2000:]}")
        return done

    def start(self) -> None:
        """Start the server and wait until it accepts connections."""
        options = " ".join(f"-c {k}={v}" for k, v in self.settings.items())
        options += f" -p {self.port} -k {self.root}"
        self._run("pg_ctl", "-D", str(self.data), "-o", options, "-w", "-l", str(self.log), "start")

    def stop(self, mode: str = "fast") -> None:
        """Stop the server; ``mode="immediate"`` is a crash (no checkpoint, clients cut)."""
        self._run("pg_ctl", "-D", str(self.data), "-m", mode, "-w", "stop", check=False)

    def restart_after_crash(self) -> None:
        """Start again after :meth:`stop` ``("immediate")`` (the server replays its WAL)."""
        wait_until(
            lambda: not (self.data / "postmaster.pid").exists(),
            START_TIMEOUT_S,
            "the crashed server's postmaster.pid to go",
            every=0.05,
        )
        self.start()

    def url(self, dbname: str = "postgres", user: str = "fuelid") -> str:
        """A libpq URL of a database of this cluster (trust: no password)."""
        return f"postgresql://{user}@127.0.0.1:{self.port}/{dbname}?connect_timeout=5"

    def create_database(self, name: str) -> str:
        """A new empty database (from ``template0``); its URL."""
        import psycopg

        with psycopg.connect(self.url(), autocommit=True) as con:
            con.execute(f'CREATE DATABASE "{name}" TEMPLATE template0')
        return self.url(name)

    def close(self) -> None:
        """Stop the server and remove its folder."""
        self.stop("immediate")
        shutil.rmtree(self.root, ignore_errors=True)


def _has_user(name: str) -> bool:
    with contextlib.suppress(KeyError):
        pwd.getpwnam(name)
        return True
    return False
