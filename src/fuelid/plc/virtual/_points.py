"""The virtual PLC's points: one table, three protocols (``plant serve --print-site`` prints it).

Every point has a Modbus address (0-based, on the wire), an OPC UA string NodeId and an S7
address. The layouts mirror each other: the S7 byte offset is twice the Modbus register address,
input registers in DB1 and holding registers in DB2. 32-bit values go high word first (ABCD),
unless the server is started with another word order. What the PC reads (input registers, DB1)
the PLC writes; what the PC writes (holding registers, DB2) the PLC reads at its next scan.

Examples
--------
>>> POINTS["flow"].modbus, POINTS["flow"].opcua, POINTS["flow"].s7
('ir:2', 'FuelLoop.Flow', 'DB1.DBD4')
>>> ring_slot_register(0), ring_slot_register(1)
(1000, 1010)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

OPCUA_NAMESPACE = "urn:fuelid:virtual-plc"
"""The namespace URI of the OPC UA nodes (its index is 2 on the virtual PLC)."""
OPCUA_PATH = "/fuelid/plc/"
"""The OPC UA endpoint's path: ``opc.tcp://127.0.0.1:PORT/fuelid/plc/``."""

S7_READ_DB = 1
"""DB of what the PC reads (the mirror of the input registers)."""
S7_WRITE_DB = 2
"""DB of what the PC writes (the mirror of the holding registers)."""

RING_HEAD_REGISTER = 100
"""``ir:100`` uint32: the sequence number of the newest ring record."""
RING_SIZE_REGISTER = 102
"""``ir:102`` uint16: the number of records in the ring."""
RING_FIRST_REGISTER = 1000
"""``ir:1000``: slot 0 of the ring; the record of sample ``seq`` is in slot ``seq % size``."""
RING_FIELDS = ("seq", "command", "flow", "setpoint", "excitation")
"""A record: seq (uint32), then the VFD command [V], the flow and the setpoint [L/min] and the
test signal applied [V] (float32)."""
RING_RECORD_REGISTERS = 2 * len(RING_FIELDS)
"""Registers per record (2 per field: 10)."""
DEFAULT_RING_SIZE = 2048
"""Records in the ring: 41 s at 50 Hz in real time (the S7 DB, 2000 + 20·2048 = 42 960 bytes,
stays under 64 KiB)."""

FLOW_COUNTS = (0.0, 27648.0, 0.0, 120.0)
"""The flow's Siemens-style analog input: 0…27648 counts = 0…120 L/min (raw0, raw1, eng0, eng1)."""
FUEL_TEMPERATURE_COUNTS = (0.0, 27648.0, -40.0, 80.0)
"""The fuel temperature's analog input: 0…27648 counts = −40…80 °C."""

PointType = Literal["float32", "int16", "uint16", "uint32"]
Access = Literal["read", "write"]


@dataclass(frozen=True)
class Point:
    """One value the virtual PLC exposes."""

    name: str
    register: int
    type: PointType
    access: Access
    unit: str
    opcua_name: str
    meaning: str

    @property
    def modbus(self) -> str:
        """The Modbus address: ``ir:N`` for what the PC reads, ``hr:N`` for what it writes."""
        return f"{'ir' if self.access == 'read' else 'hr'}:{self.register}"

    @property
    def opcua(self) -> str:
        """The OPC UA string NodeId's identifier (the namespace is :data:`OPCUA_NAMESPACE`)."""
        return self.opcua_name

    @property
    def s7(self) -> str:
        """The S7 address: DB1 (read) or DB2 (write), byte offset twice the register."""
        db = S7_READ_DB if self.access == "read" else S7_WRITE_DB
        size = "D" if self.type in ("float32", "uint32") else "W"
        return f"DB{db}.DB{size}{2 * self.register}"


def _p(name: str, register: int, type_: PointType, access: Access, unit: str, opcua: str,
       meaning: str) -> Point:  # fmt: skip
    return Point(name, register, type_, access, unit, f"FuelLoop.{opcua}", meaning)


_TABLE = (
    _p("seq", 0, "uint32", "read", "", "Seq", "sample counter, one per period of plant time"),
    _p("flow", 2, "float32", "read", "L/min", "Flow", "flowmeter reading y (noise, quantisation)"),
    _p(
        "command",
        4,
        "float32",
        "read",
        "V",
        "Command",
        "VFD command u applied (1–5 V, test signal included)",
    ),
    _p("setpoint", 6, "float32", "read", "L/min", "Setpoint", "flow setpoint in use"),
    _p("fuel_temperature", 8, "float32", "read", "degC", "FuelTemperature", "fuel temperature"),
    _p("mode", 10, "uint16", "read", "", "Mode", "0 = MAN, 1 = AUTO"),
    _p(
        "status",
        11,
        "uint16",
        "read",
        "",
        "Status",
        "bit 0 output at a limit, bit 1 heartbeat stale, bit 2 last staged set refused",
    ),
    _p("kc", 12, "float32", "read", "V per L/min", "Kc", "PI gain applied (ideal form)"),
    _p("ti", 14, "float32", "read", "s", "Ti", "PI integral time applied"),
    _p("echo", 16, "uint32", "read", "", "ApplyEcho", "apply number of the set applied (echo)"),
    _p(
        "flow_counts",
        18,
        "int16",
        "read",
        "counts",
        "FlowCounts",
        "flow as an analog input: 0…27648 = 0…120 L/min",
    ),
    _p(
        "fuel_temperature_counts",
        19,
        "int16",
        "read",
        "counts",
        "FuelTemperatureCounts",
        "fuel temperature as an analog input: 0…27648 = −40…80 °C",
    ),
    _p(
        "excitation",
        20,
        "float32",
        "read",
        "V",
        "Excitation",
        "test signal applied (after the PLC's clamp and zeroing)",
    ),
    _p("run", 22, "uint16", "read", "", "Run", "1 during a wind-tunnel run, else 0"),
    _p(
        "ring_head",
        RING_HEAD_REGISTER,
        "uint32",
        "read",
        "",
        "RingHead",
        "seq of the newest ring record",
    ),
    _p("ring_size", RING_SIZE_REGISTER, "uint16", "read", "", "RingSize", "records in the ring"),
    _p("mode_request", 0, "uint16", "write", "", "ModeRequest", "0 = MAN, 1 = AUTO"),
    _p(
        "setpoint_request",
        2,
        "float32",
        "write",
        "L/min",
        "SetpointRequest",
        "flow setpoint (ignored while a setpoint profile plays)",
    ),
    _p("manual_command", 4, "float32", "write", "V", "ManualCommand", "VFD command in MAN"),
    _p("staged_kc", 10, "float32", "write", "V per L/min", "StagedKc", "staged PI gain"),
    _p("staged_ti", 12, "float32", "write", "s", "StagedTi", "staged integral time"),
    _p(
        "apply",
        14,
        "uint32",
        "write",
        "",
        "Apply",
        "apply number: a new value applies the staged set at the next control period",
    ),
    _p(
        "heartbeat",
        20,
        "uint16",
        "write",
        "",
        "Heartbeat",
        "incremented by a connected advisor; staged sets are ignored when it is stale",
    ),
    _p(
        "excitation_request",
        22,
        "float32",
        "write",
        "V",
        "ExcitationRequest",
        "test signal the PLC adds to its PI output (clamped to its own limit, zeroed while the "
        "heartbeat is stale)",
    ),
)

POINTS: dict[str, Point] = {point.name: point for point in _TABLE}
"""Every point by name."""

OPCUA_RING = "FuelLoop.Ring"
"""The OPC UA ring: a Double array of ``size × 5`` (seq, command, flow, setpoint, excitation per
record)."""


def ring_slot_register(slot: int) -> int:
    """The first input register of ring slot ``slot``."""
    return RING_FIRST_REGISTER + RING_RECORD_REGISTERS * slot
