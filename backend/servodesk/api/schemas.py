"""Request and response models of the REST API (the OpenAPI schema is generated from them)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, JsonValue, field_validator

from servodesk.links.registry import bus_interfaces, can_interfaces
from servodesk.services.homing import Outcome

Scalar = int | float | bool | str | None

#: The id of a record the store made for a report or a tuning's result (lower-case
#: ``report-20261207t142600z-a1b2c3``: a safe id of domain/ids.py without dots). One that is
#: not cannot exist, and the schema says so: a 422 naming the rule, not the lookup's 400.
STORED_ID = r"^[a-z0-9][a-z0-9_-]{0,63}$"


class ErrorOut(BaseModel):
    error: str = Field(description="Error class, e.g. ObjectAccessError")
    message: str
    hint: str | None = None
    field: str | None = None
    code: int | None = Field(default=None, description="Protocol code (SDO abort code, ...)")
    code_hex: str | None = None
    meaning: str | None = None
    protocol: str | None = None
    address: str | None = None


#: Error answers every route may give (documented so clients and schema checks know them).
ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {"model": ErrorOut, "description": text}
    for code, text in (
        (400, "Bad value or refused by the drive (with the protocol code)"),
        (401, "Not logged in: no valid session cookie or API token (docs/security.md)"),
        (
            403,
            "The role lacks the route's right (Forbidden), or a state change or WebSocket "
            "from a page of another origin",
        ),
        (404, "No such session, profile, object or node"),
        (409, "Not possible in the present state, or control held by another client"),
        (413, "The request body is larger than the route takes"),
        (415, "The body is not application/json (multipart/form-data for a file)"),
        (502, "Bus failure"),
        (504, "The drive did not answer in time"),
    )
}


class HealthOut(BaseModel):
    status: Literal["ok"]
    version: str
    simulation: bool
    links: dict[str, str | None]


class ProfileSummary(BaseModel):
    id: str
    name: str
    vendor: str
    fieldbus: str
    description: str | None
    objects: int
    variables: int
    errors: int
    modes: list[int]
    homing_methods: list[int]


class ImportedProfile(ProfileSummary):
    """POST /profiles/import: the new profile and what the import left out or changed."""

    warnings: list[str] = Field(
        default_factory=list,
        description="One line per thing the file holds that the profile does not (skipped "
        "modules, values outside their type, ...); docs/device-descriptions.md",
    )


class ObjectInfo(BaseModel):
    index: int
    subindex: int
    address: str
    name: str
    name_local: str | None
    data_type: str
    access: str
    pdo_mapping: str
    default: Scalar
    min: int | float | None
    max: int | float | None
    unit: str | None
    scale: float
    raw_unit: str | None
    group: str | None
    persist: bool
    process: bool
    description: str | None
    section: str | None
    values: dict[str, str] | None
    pnu: int | None
    symbol: str | None


class ErrorInfo(BaseModel):
    table: str
    code: int
    code_hex: str
    display: str | None
    name: str
    kind: str
    cause: str | None
    remedy: str | None
    section: str | None


class GroupInfo(BaseModel):
    id: str
    name: str
    name_local: str | None
    description: str | None


class QuirkInfo(BaseModel):
    id: str
    value: Any
    section: str | None
    note: str | None


class NetworkObjectInfo(BaseModel):
    #: Canonical address, as in ``object_list`` (``"0x1017:00"``).
    address: str
    note: str
    section: str


class NetworkRuleInfo(BaseModel):
    text: str
    section: str


class NetworkLedInfo(BaseModel):
    led: str
    state: str
    meaning: str
    section: str


class NetworkInfo(BaseModel):
    """How the family is addressed on its fieldbus (profile ``network:``, docs/profiles.md)."""

    summary: str
    section: str
    objects: list[NetworkObjectInfo]
    addressing: list[NetworkRuleInfo]
    leds: list[NetworkLedInfo]


class ProfileDetail(ProfileSummary):
    groups: list[GroupInfo]
    object_list: list[ObjectInfo]
    error_list: list[ErrorInfo]
    quirks: list[QuirkInfo]
    #: None: the profile documents no network section.
    network: NetworkInfo | None = None


_CAN_INTERFACES = can_interfaces()
_CAN_ENUM: list[JsonValue] = list(_CAN_INTERFACES)


class BusParams(BaseModel):
    model_config = ConfigDict(extra="forbid")

    interface: str = Field(
        default="virtual",
        description="python-can interface: virtual, udp_multicast, socketcan, pcan, kvaser, ...",
        json_schema_extra={"enum": _CAN_ENUM},
    )
    channel: str = Field(default="servodesk-sim", min_length=1, max_length=128)
    bitrate: int | None = Field(default=None, ge=10_000, le=1_000_000)

    @field_validator("interface")
    @classmethod
    def _known_interface(cls, v: str) -> str:
        if v not in _CAN_INTERFACES:
            raise ValueError(f"unknown CAN interface; python-can has {', '.join(_CAN_INTERFACES)}")
        return v


class ScanRequest(BusParams):
    """A scan of a CAN bus (SDO upload of 1000h to every node), or of an EtherCAT line
    (``interface`` ``ethercat``, ``channel`` the network interface: the slaves SOEM's
    config_init finds, node id = position + 1)."""

    interface: str = Field(
        default="virtual",
        description="python-can interface (virtual, udp_multicast, socketcan, pcan, ...) or "
        "ethercat",
        json_schema_extra={"enum": [*_CAN_ENUM, "ethercat"]},
    )
    timeout: float = Field(default=0.5, ge=0.05, le=3.0, description="Seconds to wait for answers")

    @field_validator("interface")
    @classmethod
    def _known_interface(cls, v: str) -> str:
        if v != "ethercat" and v not in _CAN_INTERFACES:
            raise ValueError(
                f"unknown interface; python-can has {', '.join(_CAN_INTERFACES)}, and "
                "ethercat scans an EtherCAT line (slmp and profinet have no scan: PROFINET "
                "devices are found by DCP, POST /dcp/identify)"
            )
        return v


class IdentityOut(BaseModel):
    vendor_id: int | None
    product_code: int | None
    revision: int | None
    serial: int | None
    device_name: str | None
    hardware_version: str | None
    software_version: str | None


class ScanNode(IdentityOut):
    node_id: int
    profile_id: str | None
    session_id: str | None


class ScanOut(BaseModel):
    nodes: list[ScanNode]


class DcpTarget(BaseModel):
    """A network interface to send PROFINET DCP on (layer 2: root or CAP_NET_RAW)."""

    model_config = ConfigDict(extra="forbid")

    nic: str = Field(
        min_length=1,
        max_length=15,
        pattern=r"^[A-Za-z0-9_.:@-]+$",
        description="The network interface the PROFINET devices are on, as `ip link` names it",
    )


class DcpIdentifyRequest(DcpTarget):
    timeout: float = Field(
        default=1.0, ge=0.1, le=10.0, description="Seconds to wait for the devices' answers"
    )
    name_of_station: str | None = Field(
        default=None, max_length=240, description="Only the device with this station name"
    )


class DcpDeviceOut(BaseModel):
    mac: str
    name_of_station: str | None
    ip: str | None
    netmask: str | None
    gateway: str | None
    ip_origin: str | None = Field(description='"not set", "static" or "dhcp"')
    ip_conflict: bool
    vendor_id: int | None
    device_id: int | None
    type_of_station: str | None
    roles: list[str]
    instance: int | None
    session_id: str | None = Field(
        description="The open PROFINET session at this device's address (its IP and port "
        "34964, or the port of serve --sim's twin), if any"
    )
    channel: str | None = Field(
        description="The channel to open a session with (its IP address; with the port where "
        "it is not 34964, as for serve --sim's twin); null without an address"
    )
    profile_id: str | None = Field(
        default=None,
        description="The profile whose dcp quirk names this vendor and device ID, if any",
    )


class DcpIdentifyOut(BaseModel):
    nic: str
    devices: list[DcpDeviceOut]
    malformed: int = Field(description="Answers that could not be read (not listed)")


class DcpDeviceRequest(DcpTarget):
    mac: str = Field(
        min_length=17,
        max_length=17,
        pattern=r"^[0-9A-Fa-f]{2}([:-][0-9A-Fa-f]{2}){5}$",
        description="The device's MAC address (00:30:11:aa:bb:cc)",
    )


class DcpIpSuite(BaseModel):
    model_config = ConfigDict(extra="forbid")

    ip: str = Field(max_length=15)
    netmask: str = Field(max_length=15)
    gateway: str = Field(default="0.0.0.0", max_length=15, description="0.0.0.0: none")


class DcpSetRequest(DcpDeviceRequest):
    name_of_station: str | None = Field(default=None, max_length=240)
    ip: DcpIpSuite | None = None
    permanent: bool = Field(
        default=True, description="Keep the setting over a power cycle (false: until then)"
    )


class DcpResetRequest(DcpDeviceRequest):
    mode: Literal[2, 8] = Field(
        description="2: station name and IP address to factory settings; 8: also the "
        "drive's parameters and point tables (004 §20.4.5)"
    )


class DcpDone(BaseModel):
    mac: str
    done: list[str] = Field(description="What the device acknowledged")


_BUS_INTERFACES = bus_interfaces()


class SessionCreate(BusParams):
    interface: str = Field(
        default="virtual",
        description="python-can interface for a CANopen drive (virtual, udp_multicast, "
        "socketcan, pcan, ...), slmp for a CC-Link IE TSN station reached by SLMP over UDP "
        "(channel host:port, node id = axis + 1), profinet for a PROFIdrive drive reached by "
        "PNIO-CM record access over UDP (channel host or host:port, node id = DO-ID), or "
        "ethercat for a slave of an EtherCAT line reached by CoE (channel the network "
        "interface, node id = slave position + 1)",
        json_schema_extra={"enum": list[JsonValue](_BUS_INTERFACES)},
    )
    node_id: int = Field(ge=1, le=127)

    @field_validator("interface")
    @classmethod
    def _known_interface(cls, v: str) -> str:
        if v not in _BUS_INTERFACES:
            raise ValueError(
                f"unknown interface; python-can has {', '.join(_CAN_INTERFACES)}, slmp "
                "reaches a CC-Link IE TSN station, profinet a PROFINET IO device and ethercat an "
                "EtherCAT line"
            )
        return v

    profile: str | None = Field(default=None, description="Profile id; null detects it from 1018h")


class EncoderOut(BaseModel):
    counts_per_rev: float = Field(
        description="Encoder counts per motor revolution that the session's engineering units "
        "(deg, rpm) of objects counted in increments are for"
    )
    source: Literal["608Fh", "profile"] = Field(
        description="608Fh: the drive's position encoder resolution (CiA 402-2 §6.9.4); "
        "profile: the profile's own (the drive has no 608Fh or reports 0)"
    )
    rescaled: bool = Field(
        description="The drive's encoder differs from the profile's: the session's scales differ "
        "from GET /profiles/{id}; GET /sessions/{sid}/profile has the session's"
    )


class SessionInfo(BaseModel):
    id: str
    node_id: int
    interface: str
    channel: str
    bitrate: int | None
    profile_id: str
    profile_name: str
    fieldbus: str
    link: str
    simulated: bool
    note: str | None
    identity: IdentityOut
    connected: bool
    state: str
    nmt_state: str
    dirty: list[str] = Field(
        description="Objects written through servodesk since the last store (they differ from "
        "the drive's non-volatile copy)"
    )
    encoder: EncoderOut


class ObjectValueOut(BaseModel):
    address: str
    index: int
    subindex: int
    name: str | None
    data_type: str | None
    access: str | None
    value: int | float | bool | str | None
    raw_hex: str
    engineering: float | None
    unit: str | None
    raw_unit: str | None
    value_text: str | None


class WriteRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    # bool first: pydantic would otherwise make true an int 1 before the kind is checked.
    value: bool | int | float | str | None = Field(
        default=None,
        description="Typed value of the object's kind: a number (integer, real), true/false "
        "or 0/1 (BOOLEAN), text (VISIBLE_STRING, UNICODE_STRING), hex text (OCTET_STRING, "
        "DOMAIN). A number in hex goes as raw_hex.",
    )
    raw_hex: str | None = Field(
        default=None, max_length=2048, description="Raw bytes, little-endian, as hex"
    )


class ReadRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    addresses: list[str] = Field(min_length=1, max_length=512)


class ReadFailure(BaseModel):
    address: str
    error: ErrorOut


class ReadResults(BaseModel):
    results: list[ObjectValueOut | ReadFailure]


class StoreResult(BaseModel):
    stored: int = Field(description="Dirty entries now saved")
    duration_s: float
    procedure: str


class RestoreDefaultsRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    confirm: Literal[True] = Field(
        description="Must be true: restoring defaults overwrites every setting"
    )
    reset: bool = Field(default=False, description="Reset the node afterwards so they apply")


class MessageOut(BaseModel):
    message: str


class StatusBit(BaseModel):
    bit: int
    name: str
    set: bool


class DriveStateOut(BaseModel):
    state: str
    statusword: int
    statusword_hex: str
    bits: list[StatusBit]
    mode: int | None
    mode_name: str | None
    position: int | None
    velocity: int | None
    position_unit: str | None
    velocity_unit: str | None
    position_eng: float | None
    velocity_eng: float | None
    position_raw_unit: str | None
    velocity_raw_unit: str | None
    error_code: int | None
    error: ErrorInfo | None
    nmt_state: str
    time: float


StateCommandName = Literal[
    "shutdown",
    "switch_on",
    "switch_on_enable",
    "enable_operation",
    "disable_operation",
    "disable_voltage",
    "quick_stop",
    "fault_reset",
    "enable",
    "disable",
]


class StateCommand(BaseModel):
    model_config = ConfigDict(extra="forbid")

    command: StateCommandName


# Operation: control and motion (issue 4) -----------------------------------------------------

_I32_MIN, _I32_MAX, _U32_MAX = -(2**31), 2**31 - 1, 2**32 - 1


class ControlRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    action: Literal["take", "release", "force_take"]
    confirm: bool = Field(
        default=False, description="Must be true for force_take when another client holds it"
    )


class ProtectionOut(BaseModel):
    deadman_ms: int = Field(description="Heartbeats older than this stop the axis")
    stop_path: Literal["dead-man thread", "event loop"] = Field(
        description="Where the dead-man's quick stop is sent from: its own thread straight "
        "onto the fieldbus, or the event loop (fieldbuses without such a path)"
    )
    drive_watchdog: str | None = Field(
        description="The drive's own watchdog armed by servodesk (a dead PC stops the axis), "
        "or null: none is armed"
    )
    summary: str = Field(description="One sentence for people")


class ControlOut(BaseModel):
    session: str
    owner: str | None = Field(description="Client id (label) of the holder, or null")
    user: str | None = Field(
        default=None,
        description='The account holding control ("local" in the single-user mode), or null',
    )
    since: float | None = Field(description="When it was taken (Unix time)")
    you: bool = Field(description="The request's X-Servodesk-Control token is the holder's")
    token: str | None = Field(
        default=None,
        description="The control token, only to its holder: send it as X-Servodesk-Control "
        "and bind a WebSocket with it",
    )
    bound: bool = Field(
        default=False, description="A WebSocket is bound to this control (the dead-man)"
    )
    orphaned: bool = Field(
        default=False,
        description="The holder's WebSocket closed: the drive was made safe and control "
        "lapses unless the holder binds a socket again within the grace time",
    )
    protection: ProtectionOut | None = Field(
        default=None, description="What stops this drive when its operator is lost"
    )


class JogRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    velocity: int = Field(
        description="Signed velocity, raw units (e.g. inc/s)", ge=_I32_MIN, le=_I32_MAX
    )
    acceleration: int = Field(
        description="Acceleration and deceleration, raw units", gt=0, le=_U32_MAX
    )


class MoveRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    mode: Literal["absolute", "relative"] = "absolute"
    target: int = Field(
        description="Target position or distance, raw units", ge=_I32_MIN, le=_I32_MAX
    )
    velocity: int | None = Field(
        default=None, description="Profile velocity 6081h", gt=0, le=_U32_MAX
    )
    acceleration: int | None = Field(default=None, description="6083h", gt=0, le=_U32_MAX)
    deceleration: int | None = Field(default=None, description="6084h", gt=0, le=_U32_MAX)
    immediate: bool = Field(
        default=True,
        description="Controlword bit 5: true replaces a running move (single set-point), "
        "false queues it after the running one (set of set-points)",
    )


class VelocityRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    velocity: int = Field(description="Target velocity 60FFh, raw units", ge=_I32_MIN, le=_I32_MAX)
    acceleration: int | None = Field(default=None, gt=0, le=_U32_MAX)
    deceleration: int | None = Field(default=None, gt=0, le=_U32_MAX)


class TorqueRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    torque: int = Field(
        description="Target torque 6071h, raw units (0.1 % of rated)", ge=_I32_MIN, le=_I32_MAX
    )
    slope: int | None = Field(default=None, description="Torque slope 6087h", gt=0, le=_U32_MAX)


class CyclicMotionRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    mode: Literal["csp", "csv", "cst"]
    waveform: Literal["sine", "ramp"] = "sine"
    amplitude: float = Field(
        ge=0, le=2**31 - 1, description="Around the start (csp) or 0 (csv, cst), raw units"
    )
    frequency: float = Field(gt=0, le=10, description="Hz")
    duration: float = Field(gt=0, le=60, description="Seconds (rounded up to whole periods)")


class StopRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")


class MotionStatusOut(BaseModel):
    session: str
    active: bool
    kind: Literal["jog", "move", "velocity", "torque", "cyclic", "homing", "tuning"] | None
    owner: str | None
    mode: int | None
    target: float | None
    state: str = Field(
        description="idle, running, reached, done, halted, stopped, deadman, timeout (homing) "
        "or error"
    )
    message: str


class UnitOut(BaseModel):
    raw_unit: str | None
    unit: str | None
    scale: float
    default: int | None = Field(
        default=None, description="the profile's default of the object (raw), where it has one"
    )
    ramp: Literal["rate", "time", "register"] | None = Field(
        default=None,
        description="acceleration only: the ramp objects hold a rate (units per s²), a time "
        "(ms to the rated speed) or a register (docs/api.md)",
    )


class LimitsOut(BaseModel):
    position_min: int | None = Field(description="607Dh:01 (null: no limit)")
    position_max: int | None = Field(description="607Dh:02 (null: no limit)")
    max_velocity: int | None = Field(description="607Fh")
    max_torque: int | None = Field(description="6072h")
    max_acceleration: int | None = Field(description="60C5h")
    max_deceleration: int | None = Field(description="60C6h")
    modes: list[int]
    mode_names: dict[str, str]
    units: dict[str, UnitOut]
    sources: dict[str, str] = Field(description="Where each limit was read")


# Backup, compare, restore (issue 5; docs/api.md, docs/backup.md) ---------------------------


class BackupCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    label: str = Field(default="", max_length=200)
    note: str = Field(default="", max_length=4000)


class BackupPatch(BaseModel):
    model_config = ConfigDict(extra="forbid")

    label: str | None = Field(default=None, max_length=200)
    note: str | None = Field(default=None, max_length=4000)


class BackupIdentity(BaseModel):
    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None
    serial: int | None = None
    device_name: str | None = None
    hardware_version: str | None = None
    software_version: str | None = None


class BackupBus(BaseModel):
    interface: str | None = None
    channel: str | None = None
    bitrate: int | None = None
    node_id: int | None = None


class UnreadableOut(BaseModel):
    """An object the drive refused when the set was read: the set lacks it."""

    address: str
    name: str
    code: int | None
    code_hex: str | None
    message: str


class BackupInfo(BaseModel):
    id: str
    time: str
    label: str
    note: str
    profile_id: str
    profile_version: str
    drive_key: str = Field(description="vendor-product-serial from 1018h, else profile@bus:node")
    identity: BackupIdentity
    firmware: str | None
    bus: BackupBus
    entries: int
    file: str = Field(description="File name in the data directory's backups/ folder")
    sha256: str
    source: str = Field(description="drive, upload or pre-restore (taken before a restore)")
    unreadable: list[UnreadableOut] = Field(
        default_factory=list,
        description="objects the drive refused when the backup was read (with the abort "
        "code and error text): the backup lacks them",
    )
    complete: bool = Field(
        default=True, description="false when the backup lacks unreadable objects"
    )


class BackupEntryOut(BaseModel):
    address: str
    name: str
    data_type: str
    raw_hex: str
    value: int | float | bool | str | None
    unit: str | None


class BackupProfileRef(BaseModel):
    id: str
    version: str


class BackupFile(BaseModel):
    format: Literal["servodesk-backup"]
    schema_version: Literal[1]
    tool: str
    time: str
    label: str
    note: str
    profile: BackupProfileRef
    drive_key: str
    identity: BackupIdentity
    firmware: str | None
    bus: BackupBus
    entries: list[BackupEntryOut]
    unreadable: list[UnreadableOut]
    checksum: str


class SourceDrive(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["drive"]
    session: str = Field(min_length=1, max_length=200)


class SourceBackup(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["backup"]
    id: str = Field(min_length=1, max_length=200)


class SourceDefaults(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["defaults"]
    profile: str = Field(min_length=1, max_length=200)
    node_id: int = Field(default=1, ge=1, le=127, description="resolves $NODEID defaults")


Source = Annotated[SourceDrive | SourceBackup | SourceDefaults, Field(discriminator="kind")]


class CompareRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    a: Source
    b: Source
    all: bool = Field(default=False, description="also list equal entries (kind 'same')")


class DifferenceOut(BaseModel):
    address: str
    name: str
    group: str | None
    unit: str | None
    raw_unit: str | None
    a_value: int | float | bool | str | None
    b_value: int | float | bool | str | None
    a_raw_hex: str | None
    b_raw_hex: str | None
    a_engineering: float | None
    b_engineering: float | None
    kind: Literal["changed", "only_a", "only_b", "same"]


class Comparison(BaseModel):
    a: str
    b: str
    equal: bool
    differences: list[DifferenceOut]
    same: int
    a_unreadable: list[UnreadableOut] = Field(
        default_factory=list, description="objects A lacks (unreadable): not compared"
    )
    b_unreadable: list[UnreadableOut] = Field(
        default_factory=list, description="objects B lacks (unreadable): not compared"
    )


class PreflightRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    backup: str = Field(min_length=1, max_length=200)
    map_by_name: bool = False


class ProblemOut(BaseModel):
    address: str | None
    name: str | None
    message: str
    hint: str | None


class MappingOut(BaseModel):
    address: str
    name: str
    target: str | None
    reason: str | None


class PreflightOut(BaseModel):
    ok: bool
    problems: list[ProblemOut]
    warnings: list[str]
    to_write: int
    unchanged: int
    read_only_skipped: int
    mapping: list[MappingOut] | None
    unreadable: list[UnreadableOut] = Field(
        default_factory=list,
        description="objects the backup lacks (unreadable when taken): a restore cannot set them",
    )


class RestoreRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    backup: str = Field(min_length=1, max_length=200)
    dry_run: bool = False
    store: bool = Field(default=True, description="store to non-volatile memory when verified")
    force: bool = Field(default=False, description="store even when items failed")
    map_by_name: bool = False


class RestoreCounts(BaseModel):
    written: int
    unchanged: int
    skipped: int
    failed: int
    pending: int
    would_write: int


class RestoreItemOut(BaseModel):
    address: str
    name: str
    status: Literal["written", "unchanged", "skipped_read_only", "failed", "pending", "would_write"]
    old_raw_hex: str | None
    new_raw_hex: str | None
    code: int | None
    code_hex: str | None
    meaning: str | None
    message: str | None


class RestoreStepOut(BaseModel):
    address: str
    raw_hex: str
    entry: str | None = Field(description="the item this write sets; null for procedure steps")
    why: str


class RestoreReport(BaseModel):
    id: str
    backup: str
    session: str
    time: str
    dry_run: bool
    finished: bool
    stored: bool
    interrupted: bool
    pre_backup: str | None
    message: str | None
    warnings: list[str]
    counts: RestoreCounts
    items: list[RestoreItemOut]
    steps: list[RestoreStepOut] = Field(description="the writes in order (a dry run: planned)")
    unreadable: list[UnreadableOut] = Field(
        default_factory=list,
        description="objects the backup lacks (unreadable when taken): this restore did not "
        "set them",
    )


class AuditEntry(BaseModel):
    time: float
    client: str
    session: str
    drive_key: str
    address: str
    name: str | None
    old_raw_hex: str | None
    new_raw_hex: str
    old_value: int | float | bool | str | None
    new_value: int | float | bool | str | None


# --- Homing and alarms (issue 4) ------------------------------------------------------------

HomingSignal = Literal["home_switch", "limit_negative", "limit_positive", "index"]


class HomingMethodOut(BaseModel):
    method: int
    name: str
    description: str
    uses: list[HomingSignal]
    direction: Literal["negative", "positive"] | None
    section: str | None
    equivalent: int | None = Field(
        default=None, description="vendor method: the CiA 402 method it is simulated as"
    )
    needs_enable: bool = Field(default=True, description="needs Operation enabled to start")


class HomingRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    method: int = Field(ge=-128, le=127)
    speed_switch: int | None = Field(default=None, ge=0, le=0xFFFFFFFF, description="6099h:01")
    speed_zero: int | None = Field(default=None, ge=0, le=0xFFFFFFFF, description="6099h:02")
    acceleration: int | None = Field(default=None, ge=0, le=0xFFFFFFFF, description="609Ah")
    offset: int | None = Field(default=None, ge=-(2**31), le=2**31 - 1, description="607Ch")
    max_travel: int | None = Field(
        default=None,
        gt=0,
        le=2**32 - 1,
        description="the span the searches may cover (position units) for the estimate; "
        "default: the software position limits 607Dh, or the twin's switches",
    )
    timeout_s: float | None = Field(
        default=None,
        gt=0,
        le=86400,
        description="halt and quick-stop the run after this many seconds; default: twice the "
        "estimate plus 30 s, within 60 s .. 1 h (300 s without an estimate)",
    )


class HomingBits(BaseModel):
    target_reached: bool
    homing_attained: bool
    homing_error: bool


class HomingPhaseOut(BaseModel):
    name: str
    distance: float = Field(description="position units")
    speed: float = Field(description="position units per s")
    seconds: float
    speed_object: str = Field(description='the object that sets the speed, e.g. "6099h:02"')


class HomingEstimateOut(BaseModel):
    seconds: float = Field(description="the longest a normal run takes from any start")
    phases: list[HomingPhaseOut]
    assumptions: list[str]


#: How a run ended, "running" while it lasts: the service's one list (services/homing.py).
HomingOutcome = Outcome


class HomingPlanOut(BaseModel):
    """What a run is expected to take: the estimate and the time-out (domain/homing.py)."""

    estimate_s: float | None
    estimate: HomingEstimateOut | None
    basis: str = Field(description="where the travel came from, or why there is no estimate")
    travel: float | None
    speed_switch: float | None = Field(description="6099h:01 in position units per s")
    speed_zero: float | None = Field(description="6099h:02 in position units per s")
    acceleration: float | None = Field(description="609Ah in position units per s²")
    timeout_s: float
    timeout_source: Literal["user", "estimate", "default"]
    warnings: list[str]


class HomingRunOut(HomingPlanOut):
    id: int
    method: int
    active: bool
    outcome: HomingOutcome = Field(
        description="how the run ended (running while it lasts): the motion's end, not only "
        "the statusword (docs/api.md)"
    )
    message: str
    watched: bool = Field(description="a motion under the client's dead-man")
    started_at: float = Field(description="Unix time")
    elapsed_s: float
    phase: str | None = Field(description="what statusword bits 13/12/10 say (mode 6 only)")


class HomingStatus(BaseModel):
    session: str
    method: int | None
    state: Literal["idle", "running", "attained", "error"]
    position: int | None
    statusword_bits: HomingBits
    message: str
    run: HomingRunOut | None = Field(
        default=None, description="the last run started through servodesk on this session"
    )


class EmcyLogEntry(BaseModel):
    model_config = ConfigDict(populate_by_name=True)

    time: float | None
    code: int
    code_hex: str
    name: str | None
    cause: str | None
    remedy: str | None
    # "register" would shadow a BaseModel attribute; the JSON key stays "register".
    error_register: int = Field(alias="register", description="error register (1001h)")


class AlarmHistoryEntry(BaseModel):
    source: str = Field(description='"1003h" or the family object, e.g. "0x2A00:01"')
    index: int
    code: int
    code_hex: str
    name: str
    cause: str | None
    remedy: str | None
    time_h: int | None = None


class AlarmsOut(BaseModel):
    session: str
    current: ErrorInfo | None
    state: str
    emcy_log: list[EmcyLogEntry]
    history: list[AlarmHistoryEntry]
    reset_procedure: str
    can_clear_history: bool
    #: POST /alarms/reset: what the reset did (nothing is sent outside Fault, CiA 402-2 §6.2.1).
    message: str | None = None


class ClearHistoryRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    confirm: Literal[True] = Field(description="Must be true: the history is gone afterwards")


# 3D viewer (issue 4 item 6) -------------------------------------------------------------------


class ViewerAxisOut(BaseModel):
    session: str
    kind: Literal["rotary", "linear"]
    scale: float = Field(description="Counts per revolution (rotary) or per mm (linear)")
    scale_unit: Literal["counts/rev", "counts/mm"]
    source: Literal["user", "profile", "default"] = Field(
        description="Who chose the stage: PUT /viewer/axes, the profile (6064h in mm), or the "
        "default (a rotary motor with the profile's counts per revolution)"
    )
    limits: list[int] | None = Field(
        default=None, description="Software position limits 607Dh [min, max] in counts, if on"
    )


class ViewerOut(BaseModel):
    enabled: bool = Field(description="False when SERVODESK_VIEWER_PORT is 0")
    running: bool
    url: str | None = Field(description="Address of the viser client page (embed it in an iframe)")
    port: int | None = Field(description="Port the viewer is bound to (on the backend's host)")
    clients: int = Field(description="Browsers connected to the viewer now")
    rate_hz: float = Field(description="Scene update rate")
    error: str | None = Field(default=None, description="Why an enabled viewer is not running")
    axes: list[ViewerAxisOut]


class ViewerAxisRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["rotary", "linear"]
    scale: float | None = Field(
        default=None,
        gt=0,
        description="Counts per revolution (rotary) or per mm (linear); omitted: keep the "
        "present scale (rotary: the profile's counts per revolution)",
    )
