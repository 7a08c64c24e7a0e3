"""PROFINET DCP routes: find the devices on a network interface, set a station name or IP
address, flash a device's LED, reset it to factory settings (docs/profinet.md, "DCP").

The work, and the audit of what a device acknowledged, is services/dcp.py's; the client's
label is the X-Servodesk-Client header.
"""

from __future__ import annotations

from dataclasses import asdict

from fastapi import APIRouter

from servodesk.api.control_deps import ClientHeader
from servodesk.api.deps import StateDep
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_dcp import (
    DcpDeviceOut,
    DcpDeviceRequest,
    DcpDone,
    DcpIdentifyOut,
    DcpIdentifyRequest,
    DcpResetRequest,
    DcpSetRequest,
)
from servodesk.domain import dcp

router = APIRouter(prefix="/dcp", tags=["profinet"], responses=ERROR_RESPONSES)


@router.post("/identify", operation_id="dcp_identify")
async def dcp_identify(body: DcpIdentifyRequest, state: StateDep) -> DcpIdentifyOut:
    """Every PROFINET device on ``nic`` that answers a DCP Identify within ``timeout``."""
    found = await state.dcp.identify(body.nic, body.timeout, body.name_of_station)
    return DcpIdentifyOut(
        nic=body.nic,
        devices=[
            DcpDeviceOut.model_validate(
                {
                    **asdict(f.device),
                    "session_id": f.session_id,
                    "roles": list(f.device.roles),
                    "channel": f.channel,
                    "profile_id": f.profile_id,
                }
            )
            for f in found.devices
        ],
        malformed=found.malformed,
    )


def _done(mac: str, done: list[str]) -> DcpDone:
    return DcpDone(mac=dcp.mac_text(dcp.mac_bytes(mac)), done=done)


@router.post("/set", operation_id="dcp_set")
async def dcp_set(
    body: DcpSetRequest, state: StateDep, x_servodesk_client: ClientHeader = None
) -> DcpDone:
    """Set a device's station name and / or IP suite (checked before anything is sent)."""
    ip = (body.ip.ip, body.ip.netmask, body.ip.gateway) if body.ip is not None else None
    done = await state.dcp.set_station(
        body.nic,
        body.mac,
        name=body.name_of_station,
        ip=ip,
        permanent=body.permanent,
        client=x_servodesk_client,
    )
    return _done(body.mac, done)


@router.post("/signal", operation_id="dcp_signal")
async def dcp_signal(body: DcpDeviceRequest, state: StateDep) -> DcpDone:
    """Flash the device's LED (the LECSN-T's Network Status LED blinks green, 004 §20.2.3)."""
    return _done(body.mac, await state.dcp.signal(body.nic, body.mac))


@router.post("/reset", operation_id="dcp_reset")
async def dcp_reset(
    body: DcpResetRequest, state: StateDep, x_servodesk_client: ClientHeader = None
) -> DcpDone:
    """Reset to factory (004 §20.4.5): the station name becomes "" and the IP 0.0.0.0; mode 8
    also restores the drive's parameters. The device is unreachable until it gets an
    address again."""
    return _done(body.mac, await state.dcp.reset(body.nic, body.mac, body.mode, x_servodesk_client))
