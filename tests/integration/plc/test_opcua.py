"""OPC UA (issue 14): the virtual PLC's asyncua server and the OpcUaSource adapter, on loopback.

Plain asyncua clients written here check the server's node map (not through fuelid's adapter);
the adapter is checked against the server: scaling, ring slices, one-request writes, unknown
NodeIds, an unreachable endpoint, a server restart, Basic256Sha256 and user names.
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Awaitable, Callable, Coroutine, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest

pytest.importorskip("asyncua", reason="the OPC UA tests need asyncua: pip install 'fuelid[plc]'")

from asyncua import ua
from asyncua.client.client import Client
from asyncua.crypto import cert_gen
from asyncua.ua.uaerrors import UaError
from cryptography import x509
from cryptography.hazmat.primitives.serialization import (
    BestAvailableEncryption,
    Encoding,
    PrivateFormat,
)
from cryptography.x509.oid import ExtendedKeyUsageOID

from fuelid.errors import ConfigError
from fuelid.plc.adapters import LinkError, OpcUaSource, open_source
from fuelid.plc.site import SiteConfig, load_site
from fuelid.plc.virtual._frontend import free_port
from fuelid.plc.virtual._opcua_server import APPLICATION_URI, VARIANT_OF, OpcUaFrontend
from fuelid.plc.virtual._points import OPCUA_NAMESPACE, OPCUA_RING, POINTS
from support.waiting import await_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

T = TypeVar("T")
RING_SIZE = 64
LIMIT_S = 15.0  # each test's bound

VALUES = {
    "seq": 4321,
    "flow": 61.5,
    "command": 3.25,
    "setpoint": 60.0,
    "fuel_temperature": 21.0,
    "mode": 1,
    "status": 0,
    "kc": 0.04,
    "ti": 2.5,
    "echo": 6,
    "flow_counts": 13824,  # half of 27648: 60 L/min
    "fuel_temperature_counts": 20736,  # three quarters: 50 °C
    "ring_head": 9,
    "ring_size": RING_SIZE,
}
"""What the fake engine publishes (engineering values; counts as counts)."""


def ring_records(first: int, last: int) -> dict[int, np.ndarray]:
    """Records of samples first…last: seq, command [V], flow and setpoint [L/min], excitation."""
    return {
        seq % RING_SIZE: np.array([seq, 2.0 + 0.01 * seq, 40.0 + 0.1 * seq, 50.0, 0.125])
        for seq in range(first, last + 1)
    }


def run(coro: Coroutine[Any, Any, T]) -> T:
    """Run a test body in a fresh event loop, bounded in time."""
    return asyncio.run(asyncio.wait_for(coro, LIMIT_S))


class ServerThread:
    """An OpcUaFrontend serving from its own event loop in a thread (shared by several tests)."""

    def __init__(self, frontend: OpcUaFrontend) -> None:
        self.frontend = frontend
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)

    def call(self, make: Callable[[], Awaitable[T]]) -> T:
        async def wrapped() -> T:
            return await make()

        return asyncio.run_coroutine_threadsafe(wrapped(), self.loop).result(LIMIT_S)

    def __enter__(self) -> ServerThread:
        self.thread.start()
        self.call(self.frontend.start)
        return self

    def __exit__(self, *exc: object) -> None:
        self.call(self.frontend.stop)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(LIMIT_S)
        self.loop.close()

    def publish(self, values: Mapping[str, float], ring: Mapping[int, np.ndarray]) -> None:
        self.call(lambda: self.frontend.publish(values, ring))


@pytest.fixture(scope="module")
def served() -> Iterator[ServerThread]:
    """A plain (unsecured) virtual-PLC server with the fake engine's values and 10 records."""
    with ServerThread(OpcUaFrontend("127.0.0.1", 0, ring_size=RING_SIZE)) as server:
        server.publish(VALUES, ring_records(0, 9))
        yield server


def site_text(url: str, *, plc_extra: str = "", setpoint: str = "FuelLoop.Setpoint") -> str:
    """A site file for the virtual PLC over OPC UA."""
    return f"""\
[site]
name = "opcua test loop"
[plc]
protocol = "opcua"
endpoint = "{url}"
{plc_extra}
[tags.flow]
address = "ns=2;s=FuelLoop.FlowCounts"
type = "int16"
raw = [0, 27648]
eng = [0.0, 120.0]
unit = "L/min"
[tags.command]
address = "ns=2;s=FuelLoop.Command"
unit = "V"
[tags.setpoint]
address = "ns=2;s={setpoint}"
unit = "L/min"
[tags.fuel_temperature]
address = "ns=2;s=FuelLoop.FuelTemperatureCounts"
type = "int16"
raw = [0, 27648]
eng = [-40.0, 80.0]
unit = "degC"
[tags.mode]
address = "ns=2;s=FuelLoop.Mode"
type = "uint16"
[tags.kc]
address = "ns=2;s=FuelLoop.Kc"
[tags.ti]
address = "ns=2;s=FuelLoop.Ti"
[tags.seq]
address = "ns=2;s=FuelLoop.Seq"
type = "uint32"
[write.kc]
address = "ns=2;s=FuelLoop.StagedKc"
[write.ti]
address = "ns=2;s=FuelLoop.StagedTi"
[write.apply]
address = "ns=2;s=FuelLoop.Apply"
type = "uint32"
[write.heartbeat]
address = "ns=2;s=FuelLoop.Heartbeat"
type = "uint16"
[ring]
head = "ns=2;s=FuelLoop.RingHead"
address = "ns=2;s={OPCUA_RING}"
size = {RING_SIZE}
fields = ["seq", "command", "flow", "setpoint", "excitation"]
"""


def site_for(tmp_path: Path, url: str, **kwargs: str) -> SiteConfig:
    path = tmp_path / "site.toml"
    path.write_text(site_text(url, **kwargs), encoding="utf-8")
    return load_site(path)


# -- (a) the server's node map, seen by a plain asyncua client --------------------------------


def test_plain_client_sees_the_node_map(served: ServerThread) -> None:
    frontend = served.frontend
    written = {
        "mode_request": 1,
        "setpoint_request": 55.5,
        "manual_command": 2.75,
        "staged_kc": 0.05,
        "staged_ti": 3.0,
        "apply": 7,
        "heartbeat": 12,
        "excitation_request": -0.125,
    }

    async def body() -> None:
        async with Client(frontend.url, timeout=2) as client:
            assert await client.get_namespace_index(OPCUA_NAMESPACE) == 2
            flow = await client.nodes.objects.get_child(["2:FuelLoop", "2:Flow"])  # browse path
            assert flow.nodeid == ua.NodeId.from_string("ns=2;s=FuelLoop.Flow")
            description = await flow.read_description()
            assert description.Text == "flowmeter reading y (noise, quantisation) [L/min]"
            for name, point in POINTS.items():
                node = client.get_node(f"ns=2;s={point.opcua}")
                assert await node.read_data_type_as_variant_type() == VARIANT_OF[point.type], name
                access = await node.read_attribute(ua.AttributeIds.UserAccessLevel)
                assert access.Value is not None
                writable = bool(access.Value.Value & ua.AccessLevel.CurrentWrite.mask)
                assert writable == (point.access == "write"), name
                if name in VALUES:
                    assert await node.read_value() == pytest.approx(VALUES[name]), name
            for name, value in written.items():
                node = client.get_node(f"ns=2;s={POINTS[name].opcua}")
                await node.write_value(ua.Variant(value, VARIANT_OF[POINTS[name].type]))
            with pytest.raises(UaError, match=r"BadUserAccessDenied|BadNotWritable"):
                await client.get_node("ns=2;s=FuelLoop.Flow").write_value(
                    ua.Variant(1.0, ua.VariantType.Double)
                )
            ring = await client.get_node(f"ns=2;s={OPCUA_RING}").read_value()
            assert len(ring) == 5 * RING_SIZE
            assert ring[5 * 9 : 5 * 10] == pytest.approx([9, 2.09, 40.9, 50.0, 0.125])
            part = await client.get_node(f"ns=2;s={OPCUA_RING}").read_attribute(
                ua.AttributeIds.Value, indexrange="15:24"
            )
            assert part.Value is not None
            assert part.Value.Value == pytest.approx(
                [3, 2.03, 40.3, 50.0, 0.125, 4, 2.04, 40.4, 50.0, 0.125]
            )

    run(body())
    collected = served.call(frontend.collect)
    assert collected == pytest.approx(written)


def test_publish_writes_the_ring_before_the_head_and_restarts_keep_the_port(
    tmp_path: Path,
) -> None:
    frontend = OpcUaFrontend("127.0.0.1", 0, ring_size=RING_SIZE)

    async def body() -> None:
        await frontend.start()
        port = frontend.port
        assert port > 0
        await frontend.publish({**VALUES, "ring_head": 70}, ring_records(65, 70))
        async with Client(frontend.url, timeout=2) as client:
            ring = await client.get_node(f"ns=2;s={OPCUA_RING}").read_value()
            assert ring[5 * (70 % RING_SIZE)] == 70  # slot 6: wrapped around
            assert await client.get_node("ns=2;s=FuelLoop.RingHead").read_value() == 70
        await frontend.stop()
        await frontend.start()
        assert frontend.port == port
        async with Client(frontend.url, timeout=2) as client:
            assert await client.get_node("ns=2;s=FuelLoop.RingHead").read_value() == 70
        await frontend.stop()

    run(body())


# -- (b) OpcUaSource against the server ------------------------------------------------------


def test_source_reads_scaled_values_in_one_request(
    served: ServerThread, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    site = site_for(tmp_path, served.frontend.url)
    source = open_source(site)
    assert isinstance(source, OpcUaSource)
    assert source.where == f"opcua {served.frontend.url}"

    async def body() -> None:
        async with source:
            assert source._client is not None
            calls = 0
            read = source._client.uaclient.read

            async def counted(params: ua.ReadParameters) -> list[ua.DataValue]:
                nonlocal calls
                calls += 1
                return await read(params)

            monkeypatch.setattr(source._client.uaclient, "read", counted)
            reading = await source.read()
            assert calls == 1
        assert reading.values == pytest.approx(
            {
                "flow": 60.0,
                "command": 3.25,
                "setpoint": 60.0,
                "fuel_temperature": 50.0,
                "mode": 1.0,
                "kc": 0.04,
                "ti": 2.5,
                "seq": 4321.0,
            }
        )
        assert reading.raw["flow"] == 13824.0
        assert reading.raw["fuel_temperature"] == 20736.0
        assert reading.received > 0.0

    run(body())


async def check_ring(url: str, tmp_path: Path) -> list[tuple[str, int]]:
    """Read the ring's head and slices; the (IndexRange, elements answered) of each read."""
    source = OpcUaSource(site_for(tmp_path, url))
    reads: list[tuple[str, int]] = []
    async with source:
        assert source._client is not None
        read = source._client.uaclient.read

        async def recorded(params: ua.ReadParameters) -> list[ua.DataValue]:
            results = await read(params)
            for item, result in zip(params.NodesToRead, results, strict=True):
                if item.NodeId.Identifier == OPCUA_RING:
                    assert result.Value is not None
                    reads.append((item.IndexRange, len(result.Value.Value)))
            return results

        source._client.uaclient.read = recorded  # type: ignore[method-assign]
        assert await source.read_ring_head() == 9
        records = await source.read_ring(3, 4)
        assert [record.seq for record in records] == [3, 4, 5, 6]
        assert records[1].values == pytest.approx(
            {"command": 2.04, "flow": 40.4, "setpoint": 50.0, "excitation": 0.125}
        )
        assert await source.read_ring(5, 0) == []
        (last,) = await source.read_ring(RING_SIZE - 1, 1)
        assert last.seq == 0  # never written
        with pytest.raises(ValueError, match="not in 0"):
            await source.read_ring(RING_SIZE - 1, 2)  # the caller splits at the wrap
    return reads


def test_source_reads_ring_slices_by_index_range(served: ServerThread, tmp_path: Path) -> None:
    reads = run(check_ring(served.frontend.url, tmp_path))
    assert reads == [("15:34", 20), (f"{5 * RING_SIZE - 5}:{5 * RING_SIZE - 1}", 5)]


def test_source_slices_the_whole_ring_from_a_server_without_ranges(tmp_path: Path) -> None:
    frontend = OpcUaFrontend("127.0.0.1", 0, ring_size=RING_SIZE, index_range=False)

    async def body() -> list[tuple[str, int]]:
        await frontend.start()
        try:
            await frontend.publish({"ring_head": 9}, ring_records(0, 9))
            return await check_ring(frontend.url, tmp_path)
        finally:
            await frontend.stop()

    reads = run(body())
    assert [answered for _, answered in reads] == [5 * RING_SIZE, 5 * RING_SIZE]


def test_source_writes_gains_and_apply_in_one_request(
    served: ServerThread, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    source = OpcUaSource(site_for(tmp_path, served.frontend.url))
    requests: list[list[str]] = []

    async def body() -> None:
        async with source:
            assert source._client is not None
            write = source._client.uaclient.write

            async def recorded(params: ua.WriteParameters) -> list[ua.StatusCode]:
                requests.append([item.NodeId.Identifier for item in params.NodesToWrite])
                return await write(params)

            monkeypatch.setattr(source._client.uaclient, "write", recorded)
            await source.write({"apply": 8, "kc": 0.06, "ti": 4.5})
            with pytest.raises(ConfigError, match=r"write\.echo: not in the site file"):
                await source.write({"echo": 1})
            with pytest.raises(ConfigError, match=r"write\.apply: -1 does not fit .*UInt32"):
                await source.write({"apply": -1})

    run(body())
    # one request, staged gains first and the apply word last, each in the node's own type
    assert requests == [["FuelLoop.StagedKc", "FuelLoop.StagedTi", "FuelLoop.Apply"]]
    collected = served.call(served.frontend.collect)
    assert collected["staged_kc"] == pytest.approx(0.06)
    assert collected["staged_ti"] == pytest.approx(4.5)
    assert collected["apply"] == 8


def test_unknown_node_id_is_a_config_error_naming_the_key(
    served: ServerThread, tmp_path: Path
) -> None:
    source = OpcUaSource(site_for(tmp_path, served.frontend.url, setpoint="FuelLoop.Nope"))

    async def body() -> None:
        with pytest.raises(ConfigError) as caught:
            await source.connect()
        message = str(caught.value)
        assert "tags.setpoint" in message
        assert "ns=2;s=FuelLoop.Nope" in message
        assert "BadNodeIdUnknown" in message
        assert "\n" not in message
        assert source._client is None  # closed again

    run(body())


def test_unreachable_endpoint_is_a_link_error(tmp_path: Path) -> None:
    url = f"opc.tcp://127.0.0.1:{free_port()}/fuelid/plc/"  # nothing listens there
    source = OpcUaSource(site_for(tmp_path, url))

    async def body() -> None:
        with pytest.raises(LinkError) as caught:
            await source.connect()
        assert str(caught.value).startswith(f"opcua {url}: cannot connect")
        assert "\n" not in str(caught.value)
        with pytest.raises(LinkError, match="not connected"):
            await source.read()

    run(body())


def test_server_restart_is_a_link_error_then_reconnect_works(tmp_path: Path) -> None:
    frontend = OpcUaFrontend("127.0.0.1", 0, ring_size=RING_SIZE)

    async def body() -> None:
        await frontend.start()
        try:
            await frontend.publish(VALUES, {})
            source = OpcUaSource(site_for(tmp_path, frontend.url))
            async with source:
                assert (await source.read()).values["seq"] == 4321
                await frontend.stop()
                with pytest.raises(LinkError, match=f"opcua {frontend.url}"):
                    await source.read()
                with pytest.raises(LinkError, match="cannot connect"):
                    await source.connect()  # still down
                await frontend.start()
                await frontend.publish({"seq": 4322}, {})
                await source.connect()
                assert (await source.read()).values["seq"] == 4322
        finally:
            await frontend.stop()

    run(body())


# -- (c) security: Basic256Sha256 and user names ---------------------------------------------


def make_certificate(directory: Path, name: str, uri: str, usage: ExtendedKeyUsageOID) -> Path:
    """A self-signed application-instance certificate (DER) and its key (PEM), as UaExpert makes."""
    key = cert_gen.generate_private_key()
    names: list[x509.GeneralName] = [
        x509.UniformResourceIdentifier(uri),
        x509.DNSName(socket.gethostname()),
        x509.DNSName("localhost"),
    ]
    certificate = cert_gen.generate_self_signed_app_certificate(key, name, {}, names, [usage])
    (directory / f"{name}.pem").write_bytes(cert_gen.dump_private_key_as_pem(key))
    (directory / f"{name}.der").write_bytes(certificate.public_bytes(Encoding.DER))
    return directory / name


@pytest.fixture(scope="module")
def certificates(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    directory = tmp_path_factory.mktemp("pki")
    return {
        "server": make_certificate(
            directory, "server", APPLICATION_URI, ExtendedKeyUsageOID.SERVER_AUTH
        ),
        "client": make_certificate(
            directory, "client", "urn:fuelid:test:client", ExtendedKeyUsageOID.CLIENT_AUTH
        ),
    }


@pytest.fixture(scope="module")
def secured(certificates: dict[str, Path]) -> Iterator[ServerThread]:
    """A server offering only Basic256Sha256 endpoints, for user 'operator' only."""
    server = certificates["server"]
    frontend = OpcUaFrontend(
        "127.0.0.1",
        0,
        ring_size=RING_SIZE,
        certificate=server.with_suffix(".der"),
        private_key=server.with_suffix(".pem"),
        users={"operator": "correct horse"},
    )
    with ServerThread(frontend) as running:
        running.publish(VALUES, ring_records(0, 9))
        yield running


def secure_keys(certificates: dict[str, Path], mode: str, user: str = "operator") -> str:
    client = certificates["client"]
    return (
        f'security_policy = "Basic256Sha256"\nsecurity_mode = "{mode}"\n'
        f'certificate = "{client.with_suffix(".der")}"\n'
        f'private_key = "{client.with_suffix(".pem")}"\n'
        f'username = "{user}"\npassword_env = "FUELID_TEST_OPCUA_PASSWORD"\n'
    )


@pytest.mark.parametrize("mode", ["SignAndEncrypt", "Sign"])
def test_basic256sha256_with_certificates_and_user_works(
    secured: ServerThread,
    certificates: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    mode: str,
) -> None:
    monkeypatch.setenv("FUELID_TEST_OPCUA_PASSWORD", "correct horse")
    site = site_for(tmp_path, secured.frontend.url, plc_extra=secure_keys(certificates, mode))
    source = OpcUaSource(site)

    async def body() -> None:
        async with source:
            assert source._client is not None
            assert source._client.security_policy.Mode == getattr(ua.MessageSecurityMode, mode)
            assert source._client.application_uri == "urn:fuelid:test:client"  # from the cert
            assert (await source.read()).values["flow"] == pytest.approx(60.0)
            await source.write({"kc": 0.07})

    run(body())
    assert served_value(secured, "staged_kc") == pytest.approx(0.07)


def test_encrypted_private_key_with_its_password_variable(
    secured: ServerThread, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    key = cert_gen.generate_private_key()
    names: list[x509.GeneralName] = [x509.UniformResourceIdentifier("urn:fuelid:test:locked")]
    certificate = cert_gen.generate_self_signed_app_certificate(
        key, "locked", {}, names, [ExtendedKeyUsageOID.CLIENT_AUTH]
    )
    (tmp_path / "locked.der").write_bytes(certificate.public_bytes(Encoding.DER))
    encryption = BestAvailableEncryption(b"key secret")
    (tmp_path / "locked.pem").write_bytes(
        key.private_bytes(Encoding.PEM, PrivateFormat.PKCS8, encryption)
    )
    monkeypatch.setenv("FUELID_TEST_OPCUA_PASSWORD", "correct horse")
    monkeypatch.setenv("FUELID_TEST_KEY_PASSWORD", "key secret")
    keys = secure_keys({"client": tmp_path / "locked"}, "SignAndEncrypt")
    keys += 'private_key_password_env = "FUELID_TEST_KEY_PASSWORD"\n'
    source = OpcUaSource(site_for(tmp_path, secured.frontend.url, plc_extra=keys))

    async def body() -> None:
        async with source:
            assert (await source.read()).values["mode"] == 1.0

    run(body())


def served_value(server: ServerThread, name: str) -> float:
    return server.call(server.frontend.collect)[name]


def test_unsecured_clients_are_refused_by_a_secured_server(
    secured: ServerThread, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("FUELID_TEST_OPCUA_PASSWORD", "correct horse")
    url = secured.frontend.url
    keys = 'username = "operator"\npassword_env = "FUELID_TEST_OPCUA_PASSWORD"\n'
    source = OpcUaSource(site_for(tmp_path, url, plc_extra=keys))

    async def body() -> None:
        plain = Client(url, timeout=2)
        plain.set_user("operator")
        plain.set_password("correct horse")
        with pytest.raises(UaError, match="No matching endpoints"):
            await plain.connect()
        await plain.disconnect()
        with pytest.raises(ConfigError, match=r"plc\.security_policy: .* no endpoint with no"):
            await source.connect()

    run(body())


@pytest.mark.parametrize(
    ("user", "password", "match"),
    [
        ("operator", "wrong", r"plc\.username: .* refuses user 'operator' \(Bad"),
        ("intruder", "correct horse", r"plc\.username: .* refuses user 'intruder' \(Bad"),
    ],
)
def test_wrong_user_or_password_is_refused(
    secured: ServerThread,
    certificates: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    user: str,
    password: str,
    match: str,
) -> None:
    monkeypatch.setenv("FUELID_TEST_OPCUA_PASSWORD", password)
    keys = secure_keys(certificates, "SignAndEncrypt", user=user)
    source = OpcUaSource(site_for(tmp_path, secured.frontend.url, plc_extra=keys))

    async def body() -> None:
        with pytest.raises(ConfigError, match=match):
            await source.connect()
        assert source._client is None

    run(body())


def test_anonymous_session_is_refused_when_users_are_required(
    secured: ServerThread, certificates: dict[str, Path], tmp_path: Path
) -> None:
    client = certificates["client"]
    keys = (
        'security_policy = "Basic256Sha256"\n'
        f'certificate = "{client.with_suffix(".der")}"\n'
        f'private_key = "{client.with_suffix(".pem")}"\n'
    )
    source = OpcUaSource(site_for(tmp_path, secured.frontend.url, plc_extra=keys))

    async def body() -> None:
        with pytest.raises(ConfigError, match=r"plc\.username"):
            await source.connect()

    run(body())


def test_missing_password_variable_is_a_config_error(
    secured: ServerThread,
    certificates: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("FUELID_TEST_OPCUA_PASSWORD", raising=False)
    keys = secure_keys(certificates, "Sign")
    source = OpcUaSource(site_for(tmp_path, secured.frontend.url, plc_extra=keys))

    async def body() -> None:
        with pytest.raises(ConfigError, match="FUELID_TEST_OPCUA_PASSWORD is not set"):
            await source.connect()

    run(body())


# -- the site file's security keys -----------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        ('security_policy = "Basic256Sha256"', "needs certificate and private_key"),
        ('certificate = "c.der"\nprivate_key = "k.pem"', "certificate: only with security_policy"),
        ('password = "hunter2"', "does not belong in a site file"),
        ('username = "operator"', "username and password_env go together"),
        ('security_mode = "Fast"', "security_mode"),
        ('security_policy = "Basic128Rsa15"', "security_policy"),
    ],
)
def test_site_security_keys_are_checked(tmp_path: Path, extra: str, match: str) -> None:
    path = tmp_path / "site.toml"
    path.write_text(site_text("opc.tcp://127.0.0.1:4840/x", plc_extra=extra), encoding="utf-8")
    with pytest.raises(ConfigError, match=match):
        load_site(path)


def test_security_keys_only_for_opcua(tmp_path: Path) -> None:
    path = tmp_path / "site.toml"
    text = (
        '[site]\nname = "m"\n[plc]\nprotocol = "modbus"\nusername = "x"\npassword_env = "Y"\n'
        '[tags.flow]\naddress = "ir:0"\nunit = "L/min"\n[tags.command]\naddress = "ir:2"\n'
        'unit = "V"\n'
    )
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match='username: only for protocol = "opcua"'):
        load_site(path)


# -- (d) end to end: the virtual PLC over OPC UA -----------------------------------------------


async def ring_after(client: Client, first_seq: int, count: int) -> list[list[float]]:
    """Ring records ``first_seq … first_seq + count − 1``, read with a plain client (polled)."""
    head_node = client.get_node("ns=2;s=FuelLoop.RingHead")
    size = await client.get_node("ns=2;s=FuelLoop.RingSize").read_value()
    assert count <= size

    async def written() -> bool:
        return bool(await head_node.read_value() >= first_seq + count - 1)

    # half the body's bound (LIMIT_S, two steps), so that this message, not a bare timeout, says why
    await await_until(written, 7.0, f"ring records up to {first_seq + count - 1}", every=0.05)
    ring = await client.get_node(f"ns=2;s={OPCUA_RING}").read_value()
    records = [
        ring[5 * (seq % size) : 5 * (seq % size) + 5] for seq in range(first_seq, first_seq + count)
    ]
    assert [int(record[0]) for record in records] == list(range(first_seq, first_seq + count))
    return records


def test_virtual_plc_manual_step_gives_the_plant_info_gain() -> None:
    from fuelid.plant import load_plant_config
    from fuelid.plc.virtual import VirtualPlcThread
    from fuelid.units import celsius_to_kelvin
    from fuelid.workflow import plant_info

    u_mid, du = 3.0, 0.2
    K = plant_info(load_plant_config(), celsius_to_kelvin(20.0), u_mid).to_json()["model"]["K"]
    settle, average = 500, 250  # samples: 10 s of plant time to settle (T95 ≈ 5.3 s), 5 s mean

    async def step_to(client: Client, u: float) -> float:
        """Write the manual command, let the flow settle, the mean flow [L/min] of the ring."""
        head = await client.get_node("ns=2;s=FuelLoop.RingHead").read_value()
        await client.get_node("ns=2;s=FuelLoop.ManualCommand").write_value(
            ua.Variant(u, ua.VariantType.Double)
        )
        records = await ring_after(client, head + settle, average)
        assert all(record[1] == pytest.approx(u) for record in records)  # the command held
        return float(np.mean([record[2] for record in records]))

    async def body(url: str) -> tuple[float, float]:
        async with Client(url, timeout=2) as client:
            await client.get_node("ns=2;s=FuelLoop.ModeRequest").write_value(
                ua.Variant(0, ua.VariantType.UInt16)
            )
            low = await step_to(client, u_mid - du / 2)
            high = await step_to(client, u_mid + du / 2)
            assert await client.get_node("ns=2;s=FuelLoop.Mode").read_value() == 0  # MAN
            return low, high

    with VirtualPlcThread(protocol="opcua", port=None, speed=20.0, seed=1) as virtual:
        url = f"opc.tcp://127.0.0.1:{virtual.port}/fuelid/plc/"
        low, high = run(body(url))
    assert (high - low) / du == pytest.approx(K, rel=0.02)


def test_virtual_plc_site_file_works_with_the_adapter(tmp_path: Path) -> None:
    from fuelid.plc.virtual import VirtualPlcThread

    with VirtualPlcThread(protocol="opcua", port=None, speed=20.0, seed=1) as virtual:
        path = tmp_path / "site.toml"
        path.write_text(virtual.site_text(), encoding="utf-8")
        source = open_source(load_site(path))
        kc0, ti0 = virtual.plc.kc0, virtual.plc.ti0
        kc, ti = 2.0 * kc0, 0.5 * ti0  # within the PLC's limits (0.1–10 × commissioning)

        async def body() -> None:
            async with source:
                reading = await source.read()
                assert reading.values["mode"] == 0.0  # MAN
                assert (reading.values["kc"], reading.values["ti"]) == pytest.approx((kc0, ti0))
                head = await source.read_ring_head()
                (record,) = await source.read_ring(head % virtual.plc.ring_size, 1)
                assert record.seq == head
                assert set(record.values) == {"command", "flow", "setpoint", "excitation"}
                await source.write({"heartbeat": 1})  # an advisor is alive
                await source.write({"kc": kc, "ti": ti, "apply": 1, "heartbeat": 2})

                async def applied() -> bool:  # at the next control period
                    return bool((await source.read()).values["kc"] != pytest.approx(kc0))

                await await_until(applied, 10.0, "the staged gains applied", every=0.05)
                reading = await source.read()
                assert (reading.values["kc"], reading.values["ti"]) == pytest.approx((kc, ti))

        run(body())
