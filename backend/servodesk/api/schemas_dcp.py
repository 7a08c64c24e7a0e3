"""Models of PROFINET DCP (POST /dcp/identify, /dcp/set, /dcp/reset): finding PROFINET IO
devices on a network interface and setting their station name and IP suite (layer 2)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


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
