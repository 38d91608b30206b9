"""The virtual PLC's OPC UA front end: an asyncua server laid out as :mod:`.points` says.

The endpoint is ``opc.tcp://HOST:PORT/fuelid/plc/``. Namespace :data:`~.points.OPCUA_NAMESPACE`
gets index 2 (index 1 is the server's application URI), so every point is the string NodeId
``ns=2;s=FuelLoop.<Name>`` under the object ``FuelLoop`` in ``Objects``:

* a variable per point of :data:`~.points.POINTS`, typed as the point is (float32 points as
  Double, the counters as UInt32, words as UInt16, analog-input counts as Int16); the write points
  (``ModeRequest``, ``SetpointRequest``, ``ManualCommand``, ``StagedKc``, ``StagedTi``, ``Apply``,
  ``Heartbeat``, ``ExcitationRequest``) are writable, the others read-only;
* ``FuelLoop.Ring``: the ring buffer, a Double array of ``ring_size × 5`` elements, the record of
  sample ``seq`` at elements ``5·(seq % size) … 5·(seq % size) + 4`` as (seq, command [V], flow
  [L/min], setpoint [L/min], excitation [V]); ``FuelLoop.RingHead`` (UInt32) is the newest
  record's seq.

Reads of ``Ring`` honour the OPC UA ``IndexRange`` (``"a:b"``, elements a…b inclusive), as a real
PLC's server does, so a client reads only the slots it needs (asyncua's own server ignores the
range and returns the whole array: :class:`_RangedAttributeService` adds it).

Security (optional): given a server certificate and private key, the server offers only
Basic256Sha256 endpoints (Sign and SignAndEncrypt) and refuses unsecured clients; it accepts any
client certificate (it is a test server: a real PLC keeps a trust list). Given ``users``
(user name → password), it accepts only those users (no anonymous sessions).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from asyncua import ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.server.address_space import AttributeService
from asyncua.server.internal_server import InternalServer
from asyncua.server.server import Server
from asyncua.server.user_managers import UserManager
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.status_codes import StatusCodes
from numpy.typing import NDArray

from fuelid.plc._codec import WordOrder
from fuelid.plc.virtual._frontend import Frontend, free_port
from fuelid.plc.virtual._points import (
    DEFAULT_RING_SIZE,
    OPCUA_NAMESPACE,
    OPCUA_PATH,
    OPCUA_RING,
    POINTS,
    RING_FIELDS,
    PointType,
)

# asyncua logs refused sessions and closed channels at WARNING/ERROR: keep them off stderr unless
# the application configures logging (then they propagate to its handlers).
logging.getLogger("asyncua").addHandler(logging.NullHandler())

APPLICATION_URI = "urn:fuelid:virtual-plc:server"
"""The server's application URI (namespace index 1; a server certificate must carry it)."""

VARIANT_OF: dict[PointType, ua.VariantType] = {
    "float32": ua.VariantType.Double,
    "uint32": ua.VariantType.UInt32,
    "uint16": ua.VariantType.UInt16,
    "int16": ua.VariantType.Int16,
}
"""The OPC UA type of each point type (float32 points are served as Double)."""

_INTEGER_RANGE: dict[ua.VariantType, tuple[int, int]] = {
    ua.VariantType.UInt32: (0, 2**32 - 1),
    ua.VariantType.UInt16: (0, 2**16 - 1),
    ua.VariantType.Int16: (-(2**15), 2**15 - 1),
}


def _variant(value: float, variant_type: ua.VariantType) -> ua.Variant:
    """A value as a Variant of the point's type (integers rounded and clipped to the type)."""
    if variant_type == ua.VariantType.Double:
        return ua.Variant(float(value), variant_type)
    low, high = _INTEGER_RANGE[variant_type]
    number = round(value) if math.isfinite(value) else 0
    return ua.Variant(min(max(int(number), low), high), variant_type)


def _node_id(name: str, index: int) -> ua.NodeId:
    """The string NodeId ``ns=index;s=name``."""
    return ua.NodeId(ua.String(name), ua.Int16(index))


def _parse_range(text: str) -> tuple[int, int] | None:
    """An OPC UA NumericRange of one dimension, ``"a"`` or ``"a:b"`` (a < b), else None."""
    first, _, last = text.partition(":")
    try:
        low = int(first)
        high = int(last) if last else low
    except ValueError:
        return None
    if low < 0 or high < low or (last and high == low):
        return None
    return low, high


class _RangedAttributeService(AttributeService):
    """asyncua's attribute service with ``IndexRange`` on Value reads of one-dimensional arrays."""

    def read(self, params: ua.ReadParameters) -> list[ua.DataValue]:
        results = super().read(params)
        for index, item in enumerate(params.NodesToRead):
            if item.IndexRange and item.AttributeId == AttributeIds.Value:
                results[index] = _slice(results[index], item.IndexRange)
        return results


def _slice(value: ua.DataValue, index_range: str) -> ua.DataValue:
    """Elements ``index_range`` of an array value (OPC UA Part 4, 7.22 NumericRange)."""
    if value.StatusCode is not None and not value.StatusCode.is_good():
        return value
    bounds = _parse_range(index_range)
    if bounds is None:
        return ua.DataValue(StatusCode=ua.StatusCode(ua.UInt32(StatusCodes.BadIndexRangeInvalid)))
    array = value.Value.Value if value.Value is not None else None
    if not isinstance(array, list) or bounds[0] >= len(array):
        return ua.DataValue(StatusCode=ua.StatusCode(ua.UInt32(StatusCodes.BadIndexRangeNoData)))
    part = array[bounds[0] : bounds[1] + 1]
    assert value.Value is not None  # an array was found in it just above
    return ua.DataValue(
        ua.Variant(part, value.Value.VariantType, is_array=True),
        SourceTimestamp=value.SourceTimestamp,
        ServerTimestamp=value.ServerTimestamp,
    )


class _Users(UserManager):
    """Accepts only the configured user names with their passwords (no anonymous sessions)."""

    def __init__(self, users: Mapping[str, str]) -> None:
        self._users = dict(users)

    def get_user(
        self,
        iserver: InternalServer,
        username: str | None = None,
        password: str | None = None,
        certificate: Any = None,
    ) -> User | None:
        if username is not None and self._users.get(username) == password:
            return User(role=UserRole.User, name=username)
        return None


class OpcUaFrontend(Frontend):
    """The virtual PLC's points on an OPC UA server (asyncua).

    Parameters
    ----------
    host : str
        Address to bind (127.0.0.1 unless the user allows remote clients).
    port : int
        TCP port; 0 picks a free one (then :attr:`port` says which, and restarts keep it).
    ring_size : int
        Records in the ring buffer (the ``Ring`` array holds ``5 × ring_size`` Doubles).
    word_order, byte_swap
        Ignored (Modbus only): OPC UA carries typed values.
    certificate, private_key : str or Path, optional
        The server's application-instance certificate (DER or PEM, its URI SubjectAltName
        :data:`APPLICATION_URI`) and private key (PEM). Given both, only Basic256Sha256 endpoints
        (Sign, SignAndEncrypt) are offered; given neither, only the unsecured one.
    users : mapping of str to str, optional
        User name → password. Given, only these users may open a session (no anonymous).
    index_range : bool
        Honour ``IndexRange`` on reads (as PLC servers do); False serves the whole array
        whatever the range, as asyncua's plain server does (to test clients' fallback).
    """

    protocol = "opcua"

    def __init__(
        self,
        host: str,
        port: int,
        *,
        ring_size: int = DEFAULT_RING_SIZE,
        word_order: WordOrder = "big",
        byte_swap: bool = False,
        certificate: str | Path | None = None,
        private_key: str | Path | None = None,
        users: Mapping[str, str] | None = None,
        index_range: bool = True,
    ) -> None:
        super().__init__(
            host, port, ring_size=ring_size, word_order=word_order, byte_swap=byte_swap
        )
        if (certificate is None) != (private_key is None):
            raise ValueError("give certificate and private_key together (Basic256Sha256)")
        self.certificate = certificate
        self.private_key = private_key
        self.users = dict(users) if users is not None else None
        self.index_range = index_range
        self._server: Server | None = None
        self._running = False
        self._index = 0
        self._ids = {
            name: _node_id(point.opcua, 0) for name, point in POINTS.items()
        }  # namespace filled in at init
        self._ring = np.zeros(ring_size * len(RING_FIELDS))
        self._ring_id = _node_id(OPCUA_RING, 0)

    @property
    def url(self) -> str:
        """The endpoint URL clients connect to."""
        host = f"[{self.host}]" if ":" in self.host else self.host  # IPv6
        return f"opc.tcp://{host}:{self.port}{OPCUA_PATH}"

    @property
    def namespace_index(self) -> int:
        """The index of :data:`~.points.OPCUA_NAMESPACE` (2 once started)."""
        return self._index

    async def _build(self) -> Server:
        """Create the server and its address space (about 1 s: asyncua loads the standard nodes)."""
        if self.port == 0:
            self.port = free_port(self.host)
        server = Server(user_manager=_Users(self.users) if self.users is not None else None)
        await server.init()
        if self.index_range:
            server.iserver.attribute_service = _RangedAttributeService(server.iserver.aspace)
        server.set_endpoint(self.url)
        server.set_server_name("fuelid virtual PLC")
        await server.set_application_uri(APPLICATION_URI)
        if self.certificate is not None and self.private_key is not None:
            await server.load_certificate(str(self.certificate))
            await server.load_private_key(str(self.private_key))
            server.set_security_policy(
                [
                    ua.SecurityPolicyType.Basic256Sha256_Sign,
                    ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
                ]
            )
        else:
            server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        if self.users is not None:
            server.set_identity_tokens([ua.UserNameIdentityToken])
        self._index = await server.register_namespace(OPCUA_NAMESPACE)
        loop = await server.nodes.objects.add_object(
            _node_id("FuelLoop", self._index), self._browse_name("FuelLoop")
        )
        for name, point in POINTS.items():
            node_id = _node_id(point.opcua, self._index)
            self._ids[name] = node_id
            browse_name = point.opcua.removeprefix("FuelLoop.")
            variable = await loop.add_variable(
                node_id, self._browse_name(browse_name), _variant(0.0, VARIANT_OF[point.type])
            )
            await variable.write_attribute(
                AttributeIds.Description,
                ua.DataValue(ua.Variant(ua.LocalizedText(_describe(point.unit, point.meaning)))),
            )
            if point.access == "write":
                await variable.set_writable()
        self._ring_id = _node_id(OPCUA_RING, self._index)
        await loop.add_variable(
            self._ring_id,
            self._browse_name("Ring"),
            ua.Variant(self._ring.tolist(), ua.VariantType.Double, is_array=True),
        )
        await server.write_attribute_value(
            self._ids["ring_size"], ua.DataValue(_variant(self.ring_size, ua.VariantType.UInt16))
        )
        return server

    def _browse_name(self, name: str) -> ua.QualifiedName:
        """A browse name in the virtual PLC's namespace (``2:Flow``)."""
        return ua.QualifiedName(ua.String(name), ua.UInt16(self._index))

    async def start(self) -> None:
        """Bind and serve (the first start builds the address space; a restart keeps it)."""
        if self._running:
            return
        if self._server is None:
            self._server = await self._build()
        await self._server.start()
        self._running = True

    async def stop(self) -> None:
        """Stop serving and release the port; the values stay for a :meth:`start` again."""
        if self._server is None or not self._running:
            return
        self._running = False
        await self._server.stop()

    async def publish(
        self, values: Mapping[str, float], ring: Mapping[int, NDArray[np.float64]]
    ) -> None:
        """Write ring records, then the read points (so ``RingHead`` never runs ahead).

        Parameters
        ----------
        values : mapping of str to float
            Point name → engineering value (V, L/min, °C, s; counters as numbers); names that
            are not read points of :data:`~.points.POINTS` are ignored.
        ring : mapping of int to array
            Slot → record ``[seq, command [V], flow [L/min], setpoint [L/min], excitation [V]]``.
        """
        if self._server is None:
            return
        if ring:
            width = len(RING_FIELDS)
            for slot, record in ring.items():
                start = (slot % self.ring_size) * width
                self._ring[start : start + width] = record[:width]
            await self._server.write_attribute_value(
                self._ring_id,
                ua.DataValue(ua.Variant(self._ring.tolist(), ua.VariantType.Double, is_array=True)),
            )
        for name, value in values.items():
            point = POINTS.get(name)
            if point is None or point.access != "read":
                continue
            await self._server.write_attribute_value(
                self._ids[name], ua.DataValue(_variant(value, VARIANT_OF[point.type]))
            )

    async def collect(self) -> dict[str, float]:
        """The write points as clients last left them (name → value, 0 before any write)."""
        if self._server is None:
            return {name: 0.0 for name, point in POINTS.items() if point.access == "write"}
        result: dict[str, float] = {}
        for name, point in POINTS.items():
            if point.access != "write":
                continue
            data = self._server.read_attribute_value(self._ids[name])
            value = data.Value.Value if data.Value is not None else None
            result[name] = float(value) if isinstance(value, int | float) else math.nan
        return result


def _describe(unit: str, meaning: str) -> str:
    return f"{meaning} [{unit}]" if unit else meaning
