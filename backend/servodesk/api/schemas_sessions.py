"""Models of the bus and its sessions: the bus parameters, the scan of a CAN bus or EtherCAT
line, opening a session on a drive (SessionCreate, SessionInfo with its identity from 1018h and
encoder), and the drive's CiA 402 state and state commands (CiA 402-2 §6.2)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, JsonValue, field_validator

from servodesk.api.schemas_profiles import ErrorInfo
from servodesk.links.registry import bus_interfaces, can_interfaces

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
    ar: str | None = Field(
        default=None,
        description="PROFINET: the application relations the session holds with the drive "
        "(the supervisor AR of parameter access; the IO controller AR while cyclic data runs)",
    )
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
