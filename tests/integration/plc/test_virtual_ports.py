"""The virtual PLC binds port 0 itself and reports the port it got (issue 24).

A port picked beforehand (bind 0, close, bind again) can be taken by another process in
between; tests running in parallel then fail at random. Asked for no port, every front end lets
the OS choose as it binds and the runner reports the bound port.
"""

from __future__ import annotations

import importlib.util
import socket

import pytest

from fuelid.plc.virtual import VirtualPlcThread

LIBRARIES = {"modbus": "pymodbus", "opcua": "asyncua", "s7": "snap7"}


def _served(port: int) -> bool:
    """Whether a server listens on the port (it cannot be bound again; no client is left open)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        try:
            sock.bind(("127.0.0.1", port))
        except OSError:
            return True
        return False


@pytest.mark.parametrize("protocol", sorted(LIBRARIES))
def test_virtual_plc_binds_port_0_and_reports_the_bound_port(protocol: str) -> None:
    if importlib.util.find_spec(LIBRARIES[protocol]) is None:
        pytest.skip(f"{LIBRARIES[protocol]} is not installed (the plc extra)")
    with VirtualPlcThread(protocol, port=None, speed=1.0, seed=1) as virtual:
        port = virtual.port
        assert port > 0
        assert virtual.frontend is not None
        assert virtual.frontend.port == port
        assert f"port = {port}" in virtual.site_text()
        assert _served(port)
        virtual.stop_link()
        virtual.start_link()  # the link comes back on the same port
        assert virtual.port == port
        assert _served(port)
