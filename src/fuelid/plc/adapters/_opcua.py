"""OPC UA link (asyncua): the site's tags as NodeIds, read and written one request each.

* :meth:`OpcUaSource.read` sends every read tag in **one** Read request (one service call, one
  answer: the values of one server moment), with each value's StatusCode kept: a NodeId the
  server does not know is a :class:`~fuelid.errors.ConfigError` naming the site-file key, any
  other bad status gives NaN (the recorder flags it).
* :meth:`OpcUaSource.read_write_side` reads write-side roles back in one Read request, the same
  way: the PLC's ``echo`` of the apply number (a read-only node) and what the write area holds.
* :meth:`OpcUaSource.read_ring` reads only the needed slots of the ring array with an
  ``IndexRange`` ("a:b"); a server that ignores ranges (asyncua's own) sends the whole array,
  which is sliced here, and one that refuses them is read whole from then on.
* :meth:`OpcUaSource.write` sends all roles in **one** Write request, each value as the node's
  own DataType (read once at connect: a Double written to a Float node is refused by most
  servers), the apply word last, and without timestamps (Siemens servers refuse writes that carry
  a SourceTimestamp).
* Polling, not subscriptions, and ``auto_reconnect`` off: a dropped link makes the next request
  raise :class:`~fuelid.plc.adapters._base.LinkError` at once (asyncua's reconnect supervisor
  would hold requests for up to a minute), and the recorder reconnects with :meth:`connect`, one
  attempt each, with its own backoff.
* Security (site keys ``security_policy``, ``security_mode``, ``certificate``, ``private_key``,
  ``server_certificate``, ``username``, ``password_env``): Basic256Sha256 with Sign or
  SignAndEncrypt; the client's application URI is taken from its certificate (servers check that
  they match); the password comes from the environment variable that ``password_env`` names.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Awaitable, Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

from asyncua import ua
from asyncua.client.client import Client
from asyncua.crypto import security_policies, uacrypto
from asyncua.ua import status_codes
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.status_codes import StatusCodes
from asyncua.ua.uaerrors import UaError, UaStatusCodeError
from cryptography import x509

from fuelid.errors import ConfigError
from fuelid.plc.adapters._base import LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig, Tag

_T = TypeVar("_T")

# asyncua logs every refused session and closed channel at WARNING/ERROR; without this, Python's
# last-resort handler would print them to stderr beside fuelid's one-line messages. An
# application that configures logging still receives them (they propagate to its handlers).
logging.getLogger("asyncua").addHandler(logging.NullHandler())

LINK_ERRORS: tuple[type[BaseException], ...] = (OSError, TimeoutError, UaError)
"""What asyncua raises when the link is down, drops or times out (ConnectionError is an
OSError; a status-code error of a whole service call is a UaError)."""

_USER_REFUSED = {
    StatusCodes.BadUserAccessDenied,
    StatusCodes.BadIdentityTokenInvalid,
    StatusCodes.BadIdentityTokenRejected,
}
_CERTIFICATE_REFUSED = {
    StatusCodes.BadSecurityChecksFailed,
    StatusCodes.BadCertificateInvalid,
    StatusCodes.BadCertificateUntrusted,
    StatusCodes.BadCertificateUriInvalid,
    StatusCodes.BadCertificateTimeInvalid,
    StatusCodes.BadCertificateRevoked,
    StatusCodes.BadSecurityPolicyRejected,
}
_RANGE_REFUSED = {StatusCodes.BadIndexRangeInvalid, StatusCodes.BadIndexRangeNoData}

_INTEGER_TYPES: dict[ua.VariantType, tuple[int, int]] = {
    ua.VariantType.SByte: (-(2**7), 2**7 - 1),
    ua.VariantType.Byte: (0, 2**8 - 1),
    ua.VariantType.Int16: (-(2**15), 2**15 - 1),
    ua.VariantType.UInt16: (0, 2**16 - 1),
    ua.VariantType.Int32: (-(2**31), 2**31 - 1),
    ua.VariantType.UInt32: (0, 2**32 - 1),
    ua.VariantType.Int64: (-(2**63), 2**63 - 1),
    ua.VariantType.UInt64: (0, 2**64 - 1),
}
_FLOAT_TYPES = (ua.VariantType.Float, ua.VariantType.Double)


def status_name(code: int) -> str:
    """The name of an OPC UA status code (``BadNodeIdUnknown``), or its hex value."""
    name, _ = status_codes.get_name_and_doc(code)
    return name if name and not name.startswith("UnknownUserDefined") else f"0x{code:08X}"


def _node_id(address: str, key: str) -> ua.NodeId:
    """The NodeId of a site-file address (``ns=2;s=FuelLoop.Flow``)."""
    try:
        return ua.NodeId.from_string(address)
    except (ValueError, UaError) as exc:
        raise ConfigError(f"{key}: {address!r} is not an OPC UA NodeId ({exc})") from None


def _number(value: Any) -> float:
    """A value read from the server as a float (bools 0/1); NaN if it is not a number."""
    if isinstance(value, bool | int | float):
        return float(value)
    return math.nan


class OpcUaSource(PlcSource):
    """A PLC's OPC UA server, as the site file maps it (``protocol = "opcua"``).

    Parameters
    ----------
    site : SiteConfig
        The site file; ``plc.endpoint`` is the server's URL (``opc.tcp://host:port/path``) and the
        tag addresses are NodeIds (``ns=2;s=FuelLoop.Flow``).

    Attributes
    ----------
    timeout_s : float
        Time a request may take before the link counts as down [s].
    """

    timeout_s: float = 2.0

    def __init__(self, site: SiteConfig) -> None:
        super().__init__(site)
        if site.plc.endpoint is None:  # the site file's validator requires it for opcua
            raise ConfigError('plc.endpoint: opcua needs endpoint = "opc.tcp://host:port/path"')
        self.endpoint: str = site.plc.endpoint
        self._read_ids = {
            role: _node_id(tag.address, f"tags.{role}.address") for role, tag in site.tags.items()
        }
        self._write_ids = {
            role: _node_id(tag.address, f"write.{role}.address") for role, tag in site.write.items()
        }
        ring = site.ring
        self._head_id = _node_id(ring.head, "ring.head") if ring is not None else None
        self._ring_id = _node_id(ring.address, "ring.address") if ring is not None else None
        self._read_request = ua.ReadParameters(
            NodesToRead=[
                ua.ReadValueId(NodeId=node, AttributeId=AttributeIds.Value)
                for node in self._read_ids.values()
            ]
        )
        self._write_types: dict[str, ua.VariantType] = {}
        self._ranges = True  # whether the server answers IndexRange reads
        self._client: Client | None = None

    @property
    def where(self) -> str:
        """The endpoint in words, for messages (``opcua opc.tcp://127.0.0.1:4840/path``)."""
        return f"opcua {self.endpoint}"

    # -- the link ------------------------------------------------------------------------------

    async def connect(self) -> None:
        """Open a session (one attempt) and check that every mapped NodeId exists.

        Raises
        ------
        LinkError
            The server cannot be reached or does not answer in :attr:`timeout_s`.
        ConfigError
            A NodeId the server does not have (naming the site-file key), a security policy or
            mode it does not offer, a refused certificate or user, a missing certificate file or
            password variable.
        """
        await self.close()
        client = Client(self.endpoint, timeout=self.timeout_s)
        client.name = client.description = "fuelid"
        try:
            await self._secure(client)
            await client.connect()
        except ConfigError:
            await _disconnect(client)
            raise
        except LINK_ERRORS as exc:
            await _disconnect(client)
            raise self._connect_error(exc) from None
        self._client = client
        try:
            await self._check_nodes()
        except BaseException:
            await self.close()
            raise

    async def close(self) -> None:
        """Close the session (never raises)."""
        client, self._client = self._client, None
        if client is not None:
            await _disconnect(client)

    async def _secure(self, client: Client) -> None:
        """Apply the site's security keys to a new client (before it connects)."""
        plc = self.site.plc
        if plc.username is not None and plc.password_env is not None:
            password = os.environ.get(plc.password_env)
            if password is None:
                raise ConfigError(
                    f"plc.password_env: the environment variable {plc.password_env} is not set "
                    f"(it holds the password of user {plc.username!r})"
                )
            client.set_user(plc.username)
            client.set_password(password)
        if plc.security_policy == "None":
            return
        files = {
            "certificate": plc.certificate,
            "private_key": plc.private_key,
            "server_certificate": plc.server_certificate,
        }
        for key, name in files.items():
            if name is not None and not Path(name).is_file():
                raise ConfigError(f"plc.{key}: {name!r} is not a file")
        assert plc.certificate is not None  # the site validator requires both
        assert plc.private_key is not None
        key_password = None
        if plc.private_key_password_env is not None:
            key_password = os.environ.get(plc.private_key_password_env)
            if key_password is None:
                raise ConfigError(
                    f"plc.private_key_password_env: the environment variable "
                    f"{plc.private_key_password_env} is not set"
                )
        try:
            certificate = await uacrypto.load_certificate(plc.certificate)
        except ValueError as exc:
            raise ConfigError(
                f"plc.certificate: {plc.certificate!r} is unreadable ({exc})"
            ) from None
        uri = _application_uri(certificate)
        if uri is not None:
            client.application_uri = uri
        mode = getattr(ua.MessageSecurityMode, plc.security_mode)
        try:
            await client.set_security(
                security_policies.SecurityPolicyBasic256Sha256,
                certificate=plc.certificate,
                private_key=plc.private_key,
                private_key_password=key_password,
                server_certificate=plc.server_certificate,
                mode=mode,
            )
        except (ValueError, TypeError) as exc:
            raise ConfigError(
                f"plc.private_key: {plc.private_key!r} is unreadable or does not fit the "
                f"certificate ({exc})"
            ) from None

    def _connect_error(self, exc: BaseException) -> ConfigError | LinkError:
        """A one-line error for a failed connect: ConfigError when retrying cannot help."""
        plc = self.site.plc
        if isinstance(exc, UaStatusCodeError):
            code = exc.code
            if code in _USER_REFUSED and plc.username is None:
                return ConfigError(
                    f"plc.username: {self.where} refuses an anonymous session "
                    f"({status_name(code)}): give username and password_env"
                )
            if code in _USER_REFUSED:
                return ConfigError(
                    f"plc.username: {self.where} refuses user {plc.username!r} "
                    f"({status_name(code)}: wrong user name or password?)"
                )
            if code in _CERTIFICATE_REFUSED:
                return ConfigError(
                    f"plc.certificate: {self.where} refuses this client's certificate "
                    f"({status_name(code)}; is it in the server's trust list?)"
                )
        if isinstance(exc, UaError) and "No matching endpoints" in str(exc):
            wanted = (
                "no security"
                if plc.security_policy == "None"
                else f"{plc.security_policy} {plc.security_mode}"
            )
            return ConfigError(
                f"plc.security_policy: {self.where} offers no endpoint with {wanted}"
            )
        if isinstance(exc, UaError) and "anonymous" in str(exc).lower():
            return ConfigError(
                f"plc.username: {self.where} accepts no anonymous session: give username and "
                "password_env"
            )
        return LinkError(f"{self.where}: cannot connect ({_reason(exc)})")

    async def _check_nodes(self) -> None:
        """Read every mapped node's DataType in one request: unknown NodeIds are config errors."""
        keys: list[tuple[str, ua.NodeId]] = [
            *((f"tags.{role}", node) for role, node in self._read_ids.items()),
            *((f"write.{role}", node) for role, node in self._write_ids.items()),
        ]
        if self._head_id is not None and self._ring_id is not None:
            keys += [("ring.head", self._head_id), ("ring.address", self._ring_id)]
        client = self._connected()
        results = await self._call(
            client.uaclient.read_attributes([node for _, node in keys], AttributeIds.DataType)
        )
        for (key, node), result in zip(keys, results, strict=True):
            self._check_status(result, key, node)
        for role, result in zip(self._write_ids, results[len(self._read_ids) :], strict=False):
            data_type = result.Value.Value if result.Value is not None else None
            self._write_types[role] = _variant_type(data_type, f"write.{role}")

    def _connected(self) -> Client:
        if self._client is None:
            raise LinkError(f"{self.where}: not connected")
        return self._client

    async def _call(self, request: Awaitable[_T]) -> _T:
        """Await one service call; a link failure closes the session and raises LinkError."""
        try:
            return await request
        except LINK_ERRORS as exc:
            await self.close()
            raise LinkError(f"{self.where}: link lost ({_reason(exc)})") from None

    @staticmethod
    def _check_status(result: ua.DataValue | ua.StatusCode, key: str, node: ua.NodeId) -> bool:
        """Whether a result is good; raises ConfigError for a NodeId the server does not know."""
        status = result if isinstance(result, ua.StatusCode) else result.StatusCode
        if status is None or status.is_good():
            return True
        if status.value in (StatusCodes.BadNodeIdUnknown, StatusCodes.BadNodeIdInvalid):
            raise ConfigError(
                f"{key}: the server has no node {node.to_string()} ({status_name(status.value)})"
            )
        return False

    # -- reading -------------------------------------------------------------------------------

    async def read(self) -> Reading:
        """Read every read tag in one Read request and scale it to engineering units.

        Raises
        ------
        LinkError
            No answer, a dropped link or a timeout.
        ConfigError
            A NodeId the server does not have (naming the site-file key).
        """
        values, raw, received = await self._read_nodes(
            self._read_request, self._read_ids, self.site.tags, "tags"
        )
        return Reading(values=values, raw=raw, received=received)

    async def read_write_side(self, roles: Sequence[str]) -> dict[str, float]:
        """Read write-side roles back (e.g. ``echo``) in one Read request, scaled like :meth:`read`.

        Parameters
        ----------
        roles : sequence of str
            Roles of ``[write.*]`` (``kc``, ``ti``, ``apply``, ``echo``, ``heartbeat``).

        Returns
        -------
        dict of str to float
            Role → engineering value; NaN where the node's status is bad or its value is not a
            number.

        Raises
        ------
        ConfigError
            A role the write side does not map (``write.<role>``), or a NodeId the server does
            not have.
        LinkError
            Not connected, no answer, a dropped link or a timeout.
        """
        tags = self._write_side_tags(roles)
        if not tags:
            return {}
        ids = {role: self._write_ids[role] for role in tags}
        request = ua.ReadParameters(
            NodesToRead=[
                ua.ReadValueId(NodeId=node, AttributeId=AttributeIds.Value) for node in ids.values()
            ]
        )
        values, _, _ = await self._read_nodes(request, ids, tags, "write")
        return values

    async def _read_nodes(
        self,
        request: ua.ReadParameters,
        ids: Mapping[str, ua.NodeId],
        tags: Mapping[str, Tag],
        side: str,
    ) -> tuple[dict[str, float], dict[str, float], float]:
        """One Read request of ``ids`` (in order): engineering and raw values, and when [s]."""
        client = self._connected()
        results = await self._call(client.uaclient.read(request))
        received = time.time()
        values: dict[str, float] = {}
        raw: dict[str, float] = {}
        for (role, node), result in zip(ids.items(), results, strict=True):
            good = self._check_status(result, f"{side}.{role}", node)
            number = _number(result.Value.Value) if good and result.Value is not None else math.nan
            raw[role] = number
            values[role] = tags[role].to_engineering(number)
        return values, raw, received

    async def read_ring_head(self) -> int:
        """The sequence number of the newest ring record (``[ring] head``, a UInt32 node)."""
        client = self._connected()
        if self._head_id is None:
            raise NotImplementedError("the site file maps no [ring]")
        item = ua.ReadValueId(NodeId=self._head_id, AttributeId=AttributeIds.Value)
        (result,) = await self._call(client.uaclient.read(ua.ReadParameters(NodesToRead=[item])))
        value = result.Value.Value if result.Value is not None else None
        if not self._check_status(result, "ring.head", self._head_id) or not isinstance(
            value, int | float
        ):
            raise LinkError(f"{self.where}: ring.head has no value ({_status_of(result)})")
        return int(value) & 0xFFFFFFFF

    async def read_ring(self, first_slot: int, count: int) -> list[RingRecord]:
        """Records of slots ``first_slot … first_slot + count − 1`` of the ring array.

        The ring node is a Double array of ``size × len(fields)`` elements; one Read request
        with the IndexRange of the slots, or of the whole array where the server has no ranges.
        """
        ring = self.site.ring
        if ring is None or self._ring_id is None:
            raise NotImplementedError("the site file maps no [ring]")
        if count <= 0:
            return []
        if first_slot < 0 or first_slot + count > ring.size:
            raise ValueError(
                f"slots {first_slot}…{first_slot + count - 1} are not in 0…{ring.size - 1}"
            )
        width = len(ring.fields)
        low, high = first_slot * width, (first_slot + count) * width - 1
        array = await self._read_array(f"{low}:{high}" if self._ranges else "")
        if self._ranges and array is None:  # the server refuses ranges: read it whole from now
            self._ranges = False
            array = await self._read_array("")
        if array is None:
            raise LinkError(f"{self.where}: the ring array has no value")
        if len(array) == (high - low + 1):
            block = array
        elif len(array) >= ring.size * width:  # the whole array: the server ignored the range
            block = array[low : high + 1]
        else:
            raise ConfigError(
                f"ring: the server's array has {len(array)} elements, the site file says "
                f"{ring.size} records of {width} fields"
            )
        records = []
        for index in range(count):
            record = block[index * width : (index + 1) * width]
            seq = record[0]
            records.append(
                RingRecord(
                    seq=int(seq) & 0xFFFFFFFF if math.isfinite(seq) else 0,
                    values={
                        name: float(value)
                        for name, value in zip(ring.fields[1:], record[1:], strict=True)
                    },
                )
            )
        return records

    async def _read_array(self, index_range: str) -> list[float] | None:
        """The ring array (or the part ``index_range``); None if the server refuses the range."""
        assert self._ring_id is not None
        client = self._connected()
        item = ua.ReadValueId(
            NodeId=self._ring_id, AttributeId=AttributeIds.Value, IndexRange=index_range or None
        )
        (result,) = await self._call(client.uaclient.read(ua.ReadParameters(NodesToRead=[item])))
        if result.StatusCode is not None and result.StatusCode.value in _RANGE_REFUSED:
            return None
        if not self._check_status(result, "ring.address", self._ring_id):
            raise LinkError(f"{self.where}: the ring array is unreadable ({_status_of(result)})")
        value = result.Value.Value if result.Value is not None else None
        if not isinstance(value, list):
            raise ConfigError(f"ring.address: {self._ring_id.to_string()} is not an array")
        return [_number(element) for element in value]

    # -- writing -------------------------------------------------------------------------------

    async def write(self, values: Mapping[str, float]) -> None:
        """Write roles (engineering units) in one Write request, the apply word last.

        Raises
        ------
        LinkError
            The request did not get through (it may or may not have been applied).
        ConfigError
            A role the site file does not map, a value the node's type cannot hold, or a node the
            server refuses to write (naming the key and the status).
        """
        client = self._connected()
        roles = sorted(values, key=lambda role: role == "apply")
        items = []
        for role in roles:
            if role not in self._write_ids:
                mapped = ", ".join(self._write_ids) or "none"
                raise ConfigError(f"write.{role}: not in the site file (mapped: {mapped})")
            tag = self.site.write[role]
            variant = _to_variant(
                tag.to_raw(values[role]), self._write_types[role], f"write.{role}"
            )
            items.append(
                ua.WriteValue(
                    NodeId=self._write_ids[role],
                    AttributeId=AttributeIds.Value,
                    Value=ua.DataValue(variant),
                )
            )
        if not items:
            return
        results = await self._call(client.uaclient.write(ua.WriteParameters(NodesToWrite=items)))
        for role, status in zip(roles, results, strict=True):
            if not self._check_status(status, f"write.{role}", self._write_ids[role]):
                raise ConfigError(
                    f"write.{role}: {self.where} refuses the write to "
                    f"{self._write_ids[role].to_string()} ({status_name(status.value)})"
                )


def _variant_type(data_type: Any, key: str) -> ua.VariantType:
    """The VariantType to write to a node of DataType ``data_type`` (a NodeId in namespace 0)."""
    if isinstance(data_type, ua.NodeId) and data_type.NamespaceIndex == 0:
        identifier = data_type.Identifier
        if isinstance(identifier, int) and identifier in ua.VariantType._value2member_map_:
            variant = ua.VariantType(identifier)
            if (
                variant in _INTEGER_TYPES
                or variant in _FLOAT_TYPES
                or variant == ua.VariantType.Boolean
            ):
                return variant
    shown = data_type.to_string() if isinstance(data_type, ua.NodeId) else repr(data_type)
    raise ConfigError(f"{key}: the node's DataType {shown} is not a number or a Boolean")


def _to_variant(raw: float, variant_type: ua.VariantType, key: str) -> ua.Variant:
    """A raw value as a Variant of the node's type (integers rounded; out of range refused)."""
    if variant_type in _FLOAT_TYPES:
        return ua.Variant(float(raw), variant_type)
    if not math.isfinite(raw):
        raise ConfigError(f"{key}: {raw} cannot be written to an integer node")
    if variant_type == ua.VariantType.Boolean:
        return ua.Variant(bool(round(raw)), variant_type)
    low, high = _INTEGER_TYPES[variant_type]
    number = round(raw)
    if not low <= number <= high:
        raise ConfigError(
            f"{key}: {raw:g} does not fit the node's {variant_type.name} ({low}…{high})"
        )
    return ua.Variant(number, variant_type)


def _application_uri(certificate: x509.Certificate) -> str | None:
    """The URI SubjectAltName of a certificate (the application URI it was issued to)."""
    try:
        names = certificate.extensions.get_extension_for_class(x509.SubjectAlternativeName)
    except x509.ExtensionNotFound:
        return None
    uris = names.value.get_values_for_type(x509.UniformResourceIdentifier)
    return uris[0] if uris else None


def _status_of(result: ua.DataValue) -> str:
    return status_name(result.StatusCode.value) if result.StatusCode is not None else "no status"


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


async def _disconnect(client: Client) -> None:
    """Disconnect a client whatever state it is in (never raises)."""
    try:
        await client.disconnect()
    except Exception:
        client.disconnect_socket()
