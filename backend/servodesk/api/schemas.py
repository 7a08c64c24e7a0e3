"""Request and response models of the REST API (the OpenAPI schema is generated from them)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, JsonValue, field_validator

from servodesk.links.registry import can_interfaces

Scalar = int | float | bool | str | None


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
        (404, "No such session, profile, object or node"),
        (409, "Not possible in the present state, or control held by another client"),
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


class ProfileDetail(ProfileSummary):
    groups: list[GroupInfo]
    object_list: list[ObjectInfo]
    error_list: list[ErrorInfo]
    quirks: list[QuirkInfo]


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
    timeout: float = Field(default=0.5, ge=0.05, le=3.0, description="Seconds to wait for answers")


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


class SessionCreate(BusParams):
    node_id: int = Field(ge=1, le=127)
    profile: str | None = Field(default=None, description="Profile id; null detects it from 1018h")


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

    value: int | float | str | None = Field(
        default=None, description="Typed value (decimal, or text like 0x1F for integers)"
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

    confirm: bool = Field(description="Must be true: restoring defaults overwrites every setting")
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
