"""The site file that points at a virtual PLC: every role it has, in its protocol's addresses.

:func:`site_text` writes it (``fuelid plant serve --site-out``, the tests, the online demo); the
addresses come from the virtual PLC's point map (:mod:`fuelid.plc.virtual._points`).
"""

from __future__ import annotations

from fuelid.errors import ConfigError
from fuelid.plc._codec import WordOrder
from fuelid.plc.virtual._points import (
    DEFAULT_RING_SIZE,
    OPCUA_PATH,
    OPCUA_RING,
    POINTS,
    RING_FIELDS,
    RING_FIRST_REGISTER,
    RING_HEAD_REGISTER,
    S7_READ_DB,
)

__all__ = ["PROTOCOLS", "site_text"]

PROTOCOLS = ("modbus", "opcua", "s7")
"""The protocols the virtual PLC speaks."""


def site_text(
    protocol: str,
    host: str,
    port: int,
    *,
    period_s: float = 0.02,
    control_period_s: float = 1.0,
    word_order: WordOrder = "big",
    byte_swap: bool = False,
    ring_size: int = DEFAULT_RING_SIZE,
    store_url: str | None = None,
    kc: float | None = None,
    ti: float | None = None,
    name: str = "virtual fuel loop",
    plant: str | None = None,
) -> str:
    """The site file (TOML) of a virtual PLC at ``host:port`` speaking ``protocol``.

    ``plant`` is the plant TOML the virtual PLC runs (``[site] plant``), when not the reference.

    Every role the virtual PLC has: the read tags (with ``flow`` as the float32 reading), the
    sequence counter, the test signal applied (``excitation``) and the run flag (``run``), the
    ring (seq, command, flow, setpoint, excitation), the write side (staged gains, apply, echo,
    heartbeat, the test signal ``excitation`` it adds to its PI output) and the
    ``[controller]`` table (ideal form, engineering units, Ti in s, the commissioning gains
    ``kc`` and ``ti`` when given).

    Examples
    --------
    >>> text = site_text("modbus", "127.0.0.1", 5020)
    >>> 'address = "ir:2"' in text and 'head = "ir:100"' in text
    True
    """
    if protocol not in PROTOCOLS:
        raise ConfigError(f"protocol {protocol!r}: the virtual PLC speaks {', '.join(PROTOCOLS)}")

    def address(point: str) -> str:
        p = POINTS[point]
        if protocol == "modbus":
            return p.modbus
        if protocol == "opcua":
            return f"ns=2;s={p.opcua}"
        return p.s7

    lines = [
        "# the virtual PLC of `fuelid plant serve` (generated)",
        "[site]",
        f"name = {_toml_str(name)}",
        *([f"plant = {_toml_str(plant)}"] if plant is not None else []),
        "",
        "[plc]",
        f'protocol = "{protocol}"',
        f"host = {_toml_str(host)}",
        f"port = {int(port)}",
    ]
    if protocol == "modbus":
        lines += [
            "device_id = 1",
            f'word_order = "{word_order}"',
            f"byte_swap = {_bool(byte_swap)}",
        ]
    elif protocol == "opcua":
        lines.append(f"endpoint = {_toml_str(f'opc.tcp://{_url_host(host)}:{port}{OPCUA_PATH}')}")
    else:
        lines += ["rack = 0", "slot = 1"]
    lines += [
        "",
        "[sampling]",
        f"period_s = {period_s!r}",
        f"control_period_s = {control_period_s!r}",
    ]
    read_tags = {
        "command": ("command", "V"),
        "flow": ("flow", "L/min"),
        "setpoint": ("setpoint", "L/min"),
        "fuel_temperature": ("fuel_temperature", "degC"),
        "mode": ("mode", ""),
        "kc": ("kc", "V per L/min"),
        "ti": ("ti", "s"),
        "seq": ("seq", ""),
        "excitation": ("excitation", "V"),
        "run": ("run", ""),
    }
    write_tags = {
        "kc": ("staged_kc", "V per L/min"),
        "ti": ("staged_ti", "s"),
        "apply": ("apply", ""),
        "echo": ("echo", ""),
        "heartbeat": ("heartbeat", ""),
        "excitation": ("excitation_request", "V"),
    }
    for table, tags in (("tags", read_tags), ("write", write_tags)):
        for role, (point, unit) in tags.items():
            lines += [
                "",
                f"[{table}.{role}]",
                f'address = "{address(point)}"',
                f'type = "{POINTS[point].type}"',
            ]
            if unit:
                lines.append(f"unit = {_toml_str(unit)}")
    if protocol == "modbus":
        head, slot0 = f"ir:{RING_HEAD_REGISTER}", f"ir:{RING_FIRST_REGISTER}"
    elif protocol == "opcua":
        head, slot0 = f"ns=2;s={POINTS['ring_head'].opcua}", f"ns=2;s={OPCUA_RING}"
    else:
        head = POINTS["ring_head"].s7
        slot0 = f"DB{S7_READ_DB}.DBD{2 * RING_FIRST_REGISTER}"
    fields = ", ".join(f'"{f}"' for f in RING_FIELDS)
    lines += [
        "",
        "[ring]",
        f'head = "{head}"',
        f'address = "{slot0}"',
        f"size = {int(ring_size)}",
        f"fields = [{fields}]",
        "",
        "[controller]",
        'form = "ideal"',
        'gain_units = "engineering"',
        'integral_unit = "s"',
    ]
    if kc is not None:
        lines.append(f"kc = {float(kc)!r}")
    if ti is not None:
        lines.append(f"ti = {float(ti)!r}")
    if store_url is not None:
        lines += ["", "[store]", f"url = {_toml_str(store_url)}"]
    return "\n".join(lines) + "\n"


def _toml_str(value: str) -> str:
    escaped = value.replace("\\", "\\\\").replace('"', '\\"')
    return f'"{escaped}"'


def _bool(value: bool) -> str:
    return "true" if value else "false"


def _url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host
