"""``fuelid online``: the online service at the command line, and what it has done.

``fuelid online --config SITE.toml`` runs the service in the foreground (records as ``fuelid
record``, identifies a gated window every ``identify_every_s`` of data time, tracks K(T),
proposes PI gains, writes them when the site allows), with structured log lines and a status
line on stderr; Ctrl-C or SIGTERM stop it cleanly. ``--virtual`` starts the virtual PLC in the
same command (AUTO, wind-tunnel runs, the fuel cycling −10…+45 °C over a day) at a speed-up, so
the whole adaptive story plays in minutes.

``status``, ``history``, ``approve``, ``reject`` and ``revert`` read or mark the store (its
SQLite file is shared with a running service: every change is committed at once). Every failure
is one line on stderr and exit code 2.
"""

from __future__ import annotations

from fuelid.cli.online import _decide, _run, _show  # noqa: F401 - they register the commands
from fuelid.cli.online._app import app
from fuelid.cli.online._run import check_window_length
from fuelid.cli.online._show import status_lines
from fuelid.online import log_record

__all__ = ["app", "check_window_length", "log_record", "status_lines"]
