"""Bus scan, sessions, object access and CiA 402 state routes."""

from __future__ import annotations

from dataclasses import asdict

from fastapi import APIRouter, Response

from servodesk.api.deps import StateDep
from servodesk.api.schemas import (
    DriveStateOut,
    ErrorOut,
    ObjectValueOut,
    ScanOut,
    ScanRequest,
    SessionCreate,
    SessionInfo,
    StateCommand,
    WriteRequest,
)
from servodesk.domain.address import ObjectAddress
from servodesk.domain.values import ObjectValue
from servodesk.links.base import LinkParams

router = APIRouter(tags=["sessions"])

_ERRORS: dict[int | str, dict[str, object]] = {
    code: {"model": ErrorOut} for code in (400, 404, 409, 502, 504)
}


def _value_out(v: ObjectValue) -> ObjectValueOut:
    d = asdict(v)
    addr: ObjectAddress = d.pop("address")
    return ObjectValueOut(address=str(addr), index=addr.index, subindex=addr.subindex, **d)


@router.post("/bus/scan", operation_id="scan_bus", responses=_ERRORS)
async def scan_bus(body: ScanRequest, state: StateDep) -> ScanOut:
    nodes = await state.manager.scan(body.interface, body.channel, body.bitrate, body.timeout)
    return ScanOut.model_validate({"nodes": nodes})


@router.get("/sessions", operation_id="list_sessions")
async def list_sessions(state: StateDep) -> list[SessionInfo]:
    return [SessionInfo.model_validate(s.info()) for s in state.manager.all()]


@router.post("/sessions", status_code=201, operation_id="open_session", responses=_ERRORS)
async def open_session(body: SessionCreate, state: StateDep) -> SessionInfo:
    params = LinkParams(
        interface=body.interface,
        channel=body.channel,
        bitrate=body.bitrate,
        node_id=body.node_id,
        timeout=state.settings.sdo_timeout,
    )
    session = await state.manager.open(params, body.profile)
    return SessionInfo.model_validate(session.info())


@router.get("/sessions/{sid}", operation_id="get_session", responses=_ERRORS)
async def get_session(sid: str, state: StateDep) -> SessionInfo:
    return SessionInfo.model_validate(state.manager.get(sid).info())


@router.delete("/sessions/{sid}", status_code=204, operation_id="close_session", responses=_ERRORS)
async def close_session(sid: str, state: StateDep) -> Response:
    await state.manager.close(sid)
    return Response(status_code=204)


@router.get("/sessions/{sid}/objects/{address}", operation_id="read_object", responses=_ERRORS)
async def read_object(sid: str, address: str, state: StateDep) -> ObjectValueOut:
    session = state.manager.get(sid)
    return _value_out(await session.read_object(ObjectAddress.parse(address)))


@router.put("/sessions/{sid}/objects/{address}", operation_id="write_object", responses=_ERRORS)
async def write_object(
    sid: str, address: str, body: WriteRequest, state: StateDep
) -> ObjectValueOut:
    session = state.manager.get(sid)
    addr = ObjectAddress.parse(address)
    return _value_out(await session.write_object(addr, body.value, body.raw_hex))


@router.get("/sessions/{sid}/state", operation_id="get_state", responses=_ERRORS)
async def get_state(sid: str, state: StateDep) -> DriveStateOut:
    st = await state.manager.get(sid).drive_state()
    return DriveStateOut.model_validate(asdict(st))


@router.post("/sessions/{sid}/state", operation_id="command_state", responses=_ERRORS)
async def command_state(sid: str, body: StateCommand, state: StateDep) -> DriveStateOut:
    st = await state.manager.get(sid).command(body.command)
    return DriveStateOut.model_validate(asdict(st))
