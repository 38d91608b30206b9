"""The site file: one fuel loop as its PLC exposes it (protocol, endpoint, sampling, tag map).

A TOML file, validated with pydantic; a bad file is refused with the key and the reason
(:class:`~fuelid.errors.ConfigError`, exit code 2 at the command line). The shape (issue 14) is a
contract: keys may be added, none renamed. Example (docs/reference/site-file.md)::

    [site]
    name = "tunnel 2 fuel loop"
    [plc]
    protocol = "modbus"          # modbus | opcua | s7 | replay
    host = "127.0.0.1"
    port = 5020
    device_id = 1
    word_order = "little"        # 32-bit values: big = ABCD, little = CDAB
    byte_swap = false
    [sampling]
    period_s = 0.02
    control_period_s = 1.0
    [tags.command]
    address = "hr:100"
    type = "float32"
    unit = "V"
    [tags.flow]
    address = "ir:20"
    type = "int16"
    raw = [0, 27648]
    eng = [0.0, 120.0]
    unit = "L/min"

Addresses are in each protocol's own syntax: Modbus ``ir:N`` (input register), ``hr:N`` (holding
register), ``coil:N``, ``di:N`` (discrete input), N the 0-based protocol address as on the wire
(not 30001/40001-style register numbers); OPC UA NodeIds ``ns=2;s=FuelLoop.Flow`` (or ``i=``,
``g=``, ``b=``); S7 ``DB1.DBD0`` (32-bit), ``DB1.DBW4`` (16-bit), ``DB1.DBX8.3`` (a bit); replay:
the column of the log it plays. Only ``flow`` and ``command`` are required: a PLC that exposes less
still records, and :meth:`SiteConfig.missing` says what is missing.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from fuelid.errors import ConfigError, validation_reason
from fuelid.lti import check_control_period
from fuelid.plc._site_addresses import REGISTERS_OF as REGISTERS_OF  # re-exported
from fuelid.plc._site_addresses import check_address, check_overlaps, check_ring
from fuelid.plc._site_fleet import Archive, Central

TagType = Literal["float32", "int16", "uint16", "int32", "uint32", "bool"]
Protocol = Literal["modbus", "opcua", "s7", "replay"]

READ_ROLES = (
    "flow",
    "command",
    "setpoint",
    "fuel_temperature",
    "mode",
    "kc",
    "ti",
    "seq",
    "excitation",
    "run",
)
"""Roles of the read tags: y, u, the setpoint, the fuel temperature, MAN/AUTO (0/1), the PI's
gains as applied, the sample sequence counter (uint32), the test signal the PLC actually added
to its PI's output (after its clamp and zeroing, V) and the wind-tunnel run flag (1 during a
run; any type)."""
WRITE_ROLES = ("kc", "ti", "apply", "echo", "heartbeat", "excitation")
"""Roles of the write side: staged gains, the apply word and its echo, the advisor's heartbeat,
and the test signal the PLC adds to its PI's output (V; ``[excitation]``)."""
REQUIRED_ROLES = ("flow", "command")

ROLE_UNITS: dict[str, tuple[str, ...]] = {
    "command": ("V",),
    "flow": ("L/min",),
    "setpoint": ("L/min",),
    "fuel_temperature": ("degC",),
    "excitation": ("V",),
}
"""The engineering unit a read role must be in (after scaling): the gains are per V and L/min,
and the test signal is a share of the command."""
WRITE_ROLE_UNITS: dict[str, tuple[str, ...]] = {"excitation": ("V",)}
"""The engineering unit a write role must be in: ``[excitation] amplitude`` is in V."""


class _Table(BaseModel):
    """A table of the site file: unknown keys are refused (a typo must not pass), immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class SiteInfo(_Table):
    """``[site]``: which loop this is."""

    name: str = Field(min_length=1, description="a name for the loop (stored with every sample)")
    plant: str | None = Field(None, description="the loop's plant TOML, when there is one")
    timezone: str = Field(
        "UTC", description="IANA time zone of the times shown as text (stored times are UTC)"
    )
    loop_id: str | None = Field(
        None,
        pattern=r"^[a-z0-9-]{1,40}$",
        description="the loop's id in its store (default: from the name)",
    )

    @field_validator("timezone")
    @classmethod
    def _known_timezone(cls, value: str) -> str:
        from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

        try:
            ZoneInfo(value)
        except (ZoneInfoNotFoundError, ValueError):
            raise ValueError(
                f"{value!r} is not an IANA time zone name (such as 'UTC' or 'Europe/Zurich')"
            ) from None
        return value


class PlcEndpoint(_Table):
    """``[plc]``: the protocol and where to reach the PLC."""

    protocol: Protocol
    host: str = "127.0.0.1"
    port: int | None = Field(None, ge=1, le=65535, description="default: the protocol's")
    device_id: int = Field(1, ge=0, le=255, description="Modbus unit id")
    word_order: Literal["big", "little"] = Field(
        "big", description="32-bit values: big = ABCD (high word first), little = CDAB"
    )
    byte_swap: bool = Field(False, description="swap the two bytes of every register (BADC)")
    endpoint: str | None = Field(None, description="OPC UA endpoint URL, opc.tcp://host:port/...")
    rack: int = Field(0, ge=0, le=7, description="S7 rack")
    slot: int = Field(1, ge=0, le=31, description="S7 slot")
    path: str | None = Field(None, description="replay: the CSV/Parquet log to play")
    speed: float = Field(1.0, gt=0.0, le=1000.0, description="replay: times real time")
    security_policy: Literal["None", "Basic256Sha256"] = Field(
        "None", description="OPC UA: the secure channel's policy"
    )
    security_mode: Literal["Sign", "SignAndEncrypt"] = Field(
        "SignAndEncrypt", description="OPC UA with Basic256Sha256: sign only, or sign and encrypt"
    )
    certificate: str | None = Field(
        None, description="OPC UA: this client's certificate (DER or PEM file)"
    )
    private_key: str | None = Field(None, description="OPC UA: its private key (PEM or DER file)")
    private_key_password_env: str | None = Field(
        None, description="OPC UA: environment variable holding the private key's password"
    )
    server_certificate: str | None = Field(
        None, description="OPC UA: the server's certificate, pinned (default: as it announces)"
    )
    username: str | None = Field(None, min_length=1, description="OPC UA: user name")
    password_env: str | None = Field(
        None, min_length=1, description="OPC UA: environment variable holding the password"
    )

    @model_validator(mode="before")
    @classmethod
    def _no_password_in_file(cls, data: Any) -> Any:
        if isinstance(data, dict) and "password" in data:
            raise ValueError(
                "password: a password does not belong in a site file (it is copied and hashed "
                "with the data); put it in an environment variable and name that variable with "
                "password_env"
            )
        return data

    @model_validator(mode="after")
    def _endpoint_for_protocol(self) -> PlcEndpoint:
        if self.protocol == "opcua" and not (self.endpoint or "").startswith("opc.tcp://"):
            raise ValueError('opcua needs endpoint = "opc.tcp://host:port/path"')
        if self.protocol == "replay" and not self.path:
            raise ValueError("replay needs path = the log to play")
        self._opcua_security()
        return self

    def _opcua_security(self) -> None:
        """Refuse OPC UA security keys that are incomplete, contradictory or on another protocol."""
        keys = (
            "security_policy",
            "security_mode",
            "certificate",
            "private_key",
            "private_key_password_env",
            "server_certificate",
            "username",
            "password_env",
        )
        given = [key for key in keys if key in self.model_fields_set]
        if self.protocol != "opcua":
            if given:
                raise ValueError(f'{given[0]}: only for protocol = "opcua"')
            return
        if self.security_policy == "None":
            unsecured = ("security_policy", "username", "password_env")
            files = [key for key in given if key not in unsecured]
            if files:
                raise ValueError(
                    f'{files[0]}: only with security_policy = "Basic256Sha256" (the channel '
                    'is unsecured with security_policy = "None")'
                )
        elif self.certificate is None or self.private_key is None:
            raise ValueError(
                'security_policy = "Basic256Sha256" needs certificate and private_key (this '
                "client's application-instance certificate, trusted by the server)"
            )
        if (self.username is None) != (self.password_env is None):
            raise ValueError(
                "username and password_env go together (password_env names the environment "
                "variable that holds the password)"
            )

    @property
    def default_port(self) -> int:
        """The protocol's usual port: Modbus TCP 502, S7 (ISO-on-TCP) 102; OPC UA 4840."""
        return {"modbus": 502, "s7": 102, "opcua": 4840, "replay": 0}[self.protocol]


class Sampling(_Table):
    """``[sampling]``: how often the PC reads, and how often the PLC runs its PI."""

    period_s: float = Field(0.02, gt=0.0, le=10.0)
    control_period_s: float = Field(1.0)

    @field_validator("control_period_s")
    @classmethod
    def _control_period(cls, value: float) -> float:
        # the one check of every control period; 0 (continuous) is then refused below: the
        # PLC's PI cannot run faster than the samples it is read with
        check_control_period(value, "the PLC's PI period")
        return value

    @model_validator(mode="after")
    def _control_not_faster(self) -> Sampling:
        if self.control_period_s < self.period_s:
            raise ValueError(
                f"control_period_s ({self.control_period_s:g} s) is shorter than period_s "
                f"({self.period_s:g} s): the samples must be at least as fast as the PLC's PI"
            )
        return self


Pair = Annotated[list[float], Field(min_length=2, max_length=2)]


class Tag(_Table):
    """One value the PLC exposes: where it is, its type, and how raw maps to engineering units."""

    address: str = Field(min_length=1)
    type: TagType = "float32"
    raw: Pair | None = Field(None, description="raw values of two points, e.g. [0, 27648]")
    eng: Pair | None = Field(None, description="their engineering values, e.g. [0.0, 120.0]")
    unit: str = ""
    valid: Pair | None = Field(
        None, description="engineering range outside which a value is flagged bad"
    )

    @model_validator(mode="after")
    def _scaling(self) -> Tag:
        if (self.raw is None) != (self.eng is None):
            raise ValueError("give raw and eng together (a linear scaling needs both points)")
        if self.raw is not None and self.raw[0] == self.raw[1]:
            raise ValueError("raw needs two different values")
        if self.eng is not None and self.eng[0] == self.eng[1]:
            raise ValueError("eng needs two different values")
        if self.valid is not None and not self.valid[0] < self.valid[1]:
            raise ValueError("valid needs low < high")
        if self.type == "bool" and self.raw is not None:
            raise ValueError("a bool tag has no scaling")
        return self

    def to_engineering(self, raw: float) -> float:
        """The engineering value of a raw value (linear through the two points)."""
        if self.raw is None or self.eng is None:
            return float(raw)
        (r0, r1), (e0, e1) = self.raw, self.eng
        return e0 + (float(raw) - r0) * (e1 - e0) / (r1 - r0)

    def to_raw(self, value: float) -> float:
        """The raw value of an engineering value (the inverse of :meth:`to_engineering`)."""
        if self.raw is None or self.eng is None:
            return float(value)
        (r0, r1), (e0, e1) = self.raw, self.eng
        return r0 + (float(value) - e0) * (r1 - r0) / (e1 - e0)


RING_FIELDS = ("seq", "command", "flow", "setpoint", "excitation")
"""Roles a ring-buffer record may hold; ``seq`` (uint32) first, the others float32 in engineering
units (V, L/min; ``excitation``, the test signal applied, in V, optional and after the others)."""
RING_DEFAULT_FIELDS = ("seq", "command", "flow", "setpoint")
"""A record's fields when ``[ring] fields`` is not given (the layout before ``excitation``)."""


class Ring(_Table):
    """``[ring]``: the PLC's ring buffer of samples, read in blocks (no sample lost or doubled).

    The PLC writes the record of sample ``seq`` into slot ``seq % size`` every sample period, in
    one scan, so a record is scan-consistent (u and y of the same instant), and ``head`` holds the
    sequence number of the newest record. A record is ``fields`` in order: the sequence number as
    a uint32, then each other field as a float32 in engineering units (V, L/min); 2 registers
    each on Modbus, 4 bytes each in an S7 DB, one element each of an OPC UA Double array. The
    default is :data:`RING_DEFAULT_FIELDS`; ``excitation`` (the test signal applied, V) is
    optional, usually the last field.
    """

    head: str = Field(min_length=1, description="address of the newest record's seq (uint32)")
    address: str = Field(min_length=1, description="address of slot 0 (the first record)")
    size: int = Field(ge=2, le=65536, description="records in the ring")
    fields: list[str] = Field(default_factory=lambda: list(RING_DEFAULT_FIELDS))

    @model_validator(mode="after")
    def _layout(self) -> Ring:
        if not self.fields or self.fields[0] != "seq":
            raise ValueError("fields must start with seq (the record's sequence number)")
        unknown = sorted(set(self.fields) - set(RING_FIELDS))
        if unknown or len(set(self.fields)) != len(self.fields):
            raise ValueError(f"fields: each of {', '.join(RING_FIELDS)} at most once")
        if "flow" not in self.fields or "command" not in self.fields:
            raise ValueError("fields: a record needs command and flow (u and y)")
        return self

    @property
    def record_registers(self) -> int:
        """16-bit registers (Modbus) of one record: 2 per field."""
        return 2 * len(self.fields)


class Controller(_Table):
    """``[controller]``: how the PLC's PI block reads its gains, so none is written wrongly."""

    form: Literal["ideal", "parallel"] = "ideal"
    gain_units: Literal["engineering", "percent"] = Field(
        "engineering", description="V per L/min, or percent of span per percent of span"
    )
    integral_unit: Literal["s", "min"] = "s"
    u_span_V: float | None = Field(None, gt=0.0, description="drive span [V] of percent gains")
    y_span_Lpm: float | None = Field(
        None, gt=0.0, description="meter span [L/min] of percent gains"
    )
    kc: float | None = Field(None, gt=0.0, description="commissioning gain, in gain_units")
    ti: float | None = Field(None, gt=0.0, description="commissioning integral, in integral_unit")

    @model_validator(mode="after")
    def _spans_for_percent(self) -> Controller:
        if self.gain_units == "percent" and (self.u_span_V is None or self.y_span_Lpm is None):
            raise ValueError("percent gains need u_span_V and y_span_Lpm (the spans of the block)")
        return self


class Store(_Table):
    """``[store]``: where samples go."""

    url: str = Field("sqlite:///fuelid.db", pattern=r"^sqlite:///.+")
    retention_days: float = Field(
        30.0, gt=0.0, description="raw samples kept this long [d]; older ones thinned"
    )
    thin_to_s: float | None = Field(
        1.0, gt=0.0, description="of older samples keep one per this period [s]; none: delete"
    )


class Excitation(_Table):
    """``[excitation]``: a small test signal on the PI's output, to identify a loop that sits still.

    The online service writes the signal to ``[write.excitation]``; the PLC adds it to its PI's
    output after its own clamp, zeroes it (and clears the request) when fuelid's heartbeat is
    stale, best also in MAN and during a run, and reports what it applied in
    ``[tags.excitation]``. With ``mode`` other than ``"off"`` the
    site file needs ``[write.excitation]``, ``[write.heartbeat]``, ``[tags.excitation]``,
    ``[tags.mode]`` and ``amplitude`` (:class:`SiteConfig` checks them), and the service runs
    the heartbeat whatever ``[online] write_back`` says.
    """

    mode: Literal["off", "when_unidentified", "always"] = Field(
        "off",
        description="off: on request only; when_unidentified: when the newest window could "
        "not identify the loop and nothing else holds K now; always",
    )
    target: Literal["output"] = Field(
        "output", description="the signal is added to the PI's output (a setpoint may follow)"
    )
    amplitude: float | None = Field(
        None,
        gt=0.0,
        allow_inf_nan=False,
        description="the largest signal fuelid may ask for [V]; required unless mode is off",
    )
    max_share: float = Field(
        0.3, gt=0.0, le=1.0, description="the largest share of time with a signal (0 < x <= 1)"
    )
    wait_after_move_s: float | None = Field(
        None,
        ge=0.0,
        allow_inf_nan=False,
        description="after a setpoint move, a mode change or a gain write, wait this long "
        "before a signal [s]; None: one settling time of the current model",
    )
    margin_to_limits: float | None = Field(
        None,
        ge=0.0,
        allow_inf_nan=False,
        description="no signal while the command is within this of the drive's limits [V]; "
        "None: twice the amplitude",
    )

    @model_validator(mode="after")
    def _amplitude_when_on(self) -> Excitation:
        if self.mode != "off" and self.amplitude is None:
            raise ValueError(
                f"amplitude is required with mode = {self.mode!r} (the largest signal fuelid "
                "may ask for, in V)"
            )
        return self


def _check_excitation(site: SiteConfig) -> None:
    """With ``[excitation]`` on, the registers that carry and watch the signal must be mapped.

    The PLC zeroes the signal on a stale heartbeat and in MAN, and reports what it applied.
    """
    mode = site.excitation.mode
    if mode == "off":
        return
    on = f"with excitation on ([excitation] mode = {mode!r})"
    if "excitation" not in site.write:
        raise ValueError(
            f"write.excitation is required {on} (the register the PLC adds to its PI's output)"
        )
    if "heartbeat" not in site.write:
        raise ValueError(
            "write.heartbeat: the PLC zeroes the signal when fuelid's heartbeat is stale: "
            f"[write.heartbeat] is required {on}"
        )
    if "excitation" not in site.tags:
        raise ValueError(
            f"tags.excitation is required {on} (the signal the PLC applied, after its clamp "
            "and zeroing)"
        )
    if "mode" not in site.tags:
        raise ValueError(f"tags.mode is required {on} (no signal in MAN needs to know the mode)")


ENGINEERING_GAIN_UNITS = ("V per L/min", "V/(L/min)")
PERCENT_GAIN_UNITS = ("%/%", "% per %", "percent")


def _check_gain_units(site: SiteConfig) -> None:
    """The kc tags' units must say what ``[controller] gain_units`` says.

    A gain read or written in the wrong unit is off by the span ratio (25x for 4 V / 100 L/min).
    """
    c = site.controller
    if c is None:
        return
    expected = ENGINEERING_GAIN_UNITS if c.gain_units == "engineering" else PERCENT_GAIN_UNITS
    for side, tags in (("tags", site.tags), ("write", site.write)):
        tag = tags.get("kc")
        if tag is not None and tag.unit and tag.unit not in expected:
            raise ValueError(
                f'{side}.kc.unit: "{tag.unit}", but [controller] gain_units = "{c.gain_units}" '
                f'(say unit = "{expected[0]}", or change gain_units)'
            )


class SiteConfig(_Table):
    """A whole site file as the PLC side reads it (every table but ``[online]``).

    Cross-checks between tables, each refused with a one-line reason naming the key: the roles
    known, flow and command present, addresses in the protocol's syntax, the units of the roles
    that have one, the ring's layout, the gain units of ``[controller]``, and what
    ``[excitation]`` on needs (``write.excitation``, ``write.heartbeat``, ``tags.excitation``,
    ``tags.mode``). With excitation on, the heartbeat runs whatever ``[online] write_back`` says
    (the PLC zeroes the signal when it is stale).

    ``[online]`` is the online service's table: :class:`fuelid.online._settings.ServiceSite`
    (this class with ``online``) reads and checks it, the write side it needs included; here it
    is passed over, so that the PLC side does not depend on the service's settings.
    """

    site: SiteInfo
    plc: PlcEndpoint
    sampling: Sampling = Field(default_factory=Sampling)
    tags: dict[str, Tag]
    write: dict[str, Tag] = Field(default_factory=dict)
    ring: Ring | None = None
    controller: Controller | None = None
    store: Store = Field(default_factory=Store)
    excitation: Excitation = Field(default_factory=Excitation)
    archive: Archive | None = None
    central: Central | None = None

    @model_validator(mode="before")
    @classmethod
    def _online_is_the_services(cls, data: Any) -> Any:
        if isinstance(data, dict) and "online" in data and "online" not in cls.model_fields:
            return {key: value for key, value in data.items() if key != "online"}
        return data

    @model_validator(mode="after")
    def _tag_map(self) -> SiteConfig:
        for side, tags, roles in (
            ("tags", self.tags, READ_ROLES),
            ("write", self.write, WRITE_ROLES),
        ):
            unknown = sorted(set(tags) - set(roles))
            if unknown:
                raise ValueError(
                    f"{side}.{unknown[0]}: unknown role; {side} are {', '.join(roles)}"
                )
        missing = [role for role in REQUIRED_ROLES if role not in self.tags]
        if missing:
            raise ValueError(f"tags.{missing[0]} is required (the {_meaning(missing[0])})")
        for side, tags in (("tags", self.tags), ("write", self.write)):
            for role, tag in tags.items():
                check_address(self.plc.protocol, tag, f"{side}.{role}")
        for side, tags, role_units in (
            ("tags", self.tags, ROLE_UNITS),
            ("write", self.write, WRITE_ROLE_UNITS),
        ):
            for role, units in role_units.items():
                found = tags.get(role)
                if found is not None and found.unit not in units:
                    why = "the test signal is" if role == "excitation" else "the gains are computed"
                    raise ValueError(
                        f"{side}.{role}.unit: {found.unit or 'none'!s}, but {why} in "
                        f"{units[0]}: scale the raw value with raw = [...] and eng = [...] and "
                        f'say unit = "{units[0]}"'
                    )
        seq = self.tags.get("seq")
        if seq is not None and seq.type != "uint32":
            raise ValueError("tags.seq.type: the sequence counter is a uint32")
        if self.ring is not None:
            check_ring(self.plc.protocol, self.ring)
        check_overlaps(self.plc.protocol, self.tags, "tags")
        check_overlaps(self.plc.protocol, self.write, "write")
        _check_gain_units(self)
        _check_excitation(self)
        return self

    def missing(self) -> list[str]:
        """What the PLC does not expose, each with what it costs (empty when everything is)."""
        costs = {
            "setpoint": "closed-loop excitation cannot be told from noise",
            "fuel_temperature": "models are not placed on the K(T) curve",
            "mode": "MAN and AUTO cannot be told apart",
            "kc": "the applied gains are unknown",
            "ti": "the applied gains are unknown",
            "seq": "sample times are receipt times; a lost sample is a missed deadline",
        }
        if self.excitation.mode != "off":  # without a signal, a run changes nothing
            costs["run"] = "a wind-tunnel run cannot be told: no signal is held off during a run"
        exposed = set(self.tags) | set(self.ring.fields if self.ring is not None else ())
        return [f"{role}: {cost}" for role, cost in costs.items() if role not in exposed]


def _meaning(role: str) -> str:
    return {"flow": "flowmeter reading y", "command": "VFD command u"}.get(role, role)


def _describe(error: Any) -> str:
    location = ".".join(str(part) for part in error["loc"])
    message = validation_reason(error)
    return f"{location}: {message}" if location else message


SiteT = TypeVar("SiteT", bound=SiteConfig)


def load_site(path: str | Path) -> SiteConfig:
    """Read and validate a site file (the PLC side: ``[online]`` is passed over).

    The commands read it with :func:`fuelid.online._settings.load_service_site`, which checks
    ``[online]`` too.

    Raises
    ------
    ConfigError
        One line: the file, the key and the reason.
    """
    return load_site_as(path, SiteConfig)


def load_site_as(path: str | Path, model: type[SiteT]) -> SiteT:
    """Read a site file and validate it as ``model`` (:class:`SiteConfig` or a subclass).

    Raises
    ------
    ConfigError
        One line: the file, the key and the reason.
    """
    source = str(path)
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"site file {source!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read site file {source!r}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML ({exc})") from None
    if "vfd" in data and "plc" not in data:  # the other TOML file a newcomer has at hand
        raise ConfigError(
            f"{source} is a plant file (it has a [vfd] table); --config takes a site file"
        )
    try:
        site = model.model_validate(data)
    except ValidationError as exc:
        details = "; ".join(_describe(err) for err in exc.errors())
        raise ConfigError(f"{source}: {details}") from None
    return _relative_to(site, Path(path).resolve().parent, data)


def _relative_to(site: SiteT, folder: Path, data: dict[str, Any]) -> SiteT:
    """Relative paths written in the file, taken from the file's folder.

    ``[site] plant``, ``[store] url`` and ``[archive] dir`` must not depend on where the
    service happens to start (systemd starts it in /). The default store (no ``[store] url``)
    stays ``fuelid.db`` in the current folder.
    """
    plant = site.site.plant
    if plant is not None and not Path(plant).is_absolute():
        info = site.site.model_copy(update={"plant": str(folder / plant)})
        site = site.model_copy(update={"site": info})
    given = isinstance(data.get("store"), dict) and "url" in data["store"]
    location = site.store.url.removeprefix("sqlite:///")
    if given and not Path(location).is_absolute():
        store = site.store.model_copy(update={"url": f"sqlite:///{folder / location}"})
        site = site.model_copy(update={"store": store})
    if site.archive is not None and not Path(site.archive.dir).is_absolute():
        archive = site.archive.model_copy(update={"dir": str(folder / site.archive.dir)})
        site = site.model_copy(update={"archive": archive})
    return site
