"""Bus scan, sessions, object access and CiA 402 state routes."""

from __future__ import annotations

from dataclasses import asdict

from fastapi import APIRouter, Response

from servodesk.api.control_deps import CloseControl, StateControl, WriteControl
from servodesk.api.deps import StateDep
from servodesk.api.routes.system import profile_detail
from servodesk.api.schemas import ERROR_RESPONSES, ErrorOut, MessageOut
from servodesk.api.schemas_objects import (
    ObjectValueOut,
    ReadFailure,
    ReadRequest,
    ReadResults,
    RestoreDefaultsRequest,
    StoreResult,
    WriteRequest,
)
from servodesk.api.schemas_profiles import ProfileDetail
from servodesk.api.schemas_sessions import (
    DriveStateOut,
    ScanOut,
    ScanRequest,
    SessionCreate,
    SessionInfo,
    StateCommand,
)
from servodesk.domain.address import ObjectAddress
from servodesk.domain.values import ObjectValue
from servodesk.errors import ServodeskError
from servodesk.links.base import LinkParams
from servodesk.links.registry import link_for_interface

router = APIRouter(tags=["sessions"], responses=ERROR_RESPONSES)


def _value_out(v: ObjectValue) -> ObjectValueOut:
    d = asdict(v)
    del d["address"]  # asdict turned it into a mapping; use the object itself.
    a = v.address
    return ObjectValueOut(address=str(a), index=a.index, subindex=a.subindex, **d)


@router.post("/bus/scan", operation_id="scan_bus")
async def scan_bus(body: ScanRequest, state: StateDep) -> ScanOut:
    nodes = await state.manager.scan(str(body.interface), body.channel, body.bitrate, body.timeout)
    return ScanOut.model_validate({"nodes": nodes})


@router.get("/sessions", operation_id="list_sessions")
async def list_sessions(state: StateDep) -> list[SessionInfo]:
    return [SessionInfo.model_validate(s.info()) for s in state.manager.all()]


@router.post("/sessions", status_code=201, operation_id="open_session")
async def open_session(body: SessionCreate, state: StateDep) -> SessionInfo:
    params = LinkParams(
        interface=str(body.interface),
        channel=body.channel,
        bitrate=body.bitrate,
        node_id=body.node_id,
        timeout=state.settings.sdo_timeout,
    )
    session = await state.manager.open(
        params, body.profile, fieldbus=link_for_interface(params.interface)
    )
    state.audit.record(
        "config.session_opened",
        drive=session.id,
        details={
            "interface": params.interface,
            "channel": params.channel,
            "node_id": params.node_id,
            "profile": session.profile.id,
        },
    )
    return SessionInfo.model_validate(session.info())


@router.get("/sessions/{sid}", operation_id="get_session")
async def get_session(sid: str, state: StateDep) -> SessionInfo:
    return SessionInfo.model_validate(state.manager.get(sid).info())


@router.get("/sessions/{sid}/profile", operation_id="get_session_profile")
async def get_session_profile(sid: str, state: StateDep) -> ProfileDetail:
    """The session's profile: GET /profiles/{id} with the increment units rescaled to the
    drive's encoder when 608Fh reports another than the profile's (``encoder.rescaled``)."""
    return profile_detail(state.manager.get(sid).profile)


@router.delete("/sessions/{sid}", status_code=204, operation_id="close_session")
async def close_session(sid: str, state: StateDep, _: CloseControl) -> Response:
    await state.manager.close(sid)
    state.audit.record("config.session_closed", drive=sid)
    return Response(status_code=204)


@router.get("/sessions/{sid}/objects/{address}", operation_id="read_object")
async def read_object(sid: str, address: str, state: StateDep) -> ObjectValueOut:
    session = state.manager.get(sid)
    return _value_out(await session.read_object(ObjectAddress.parse(address)))


@router.put("/sessions/{sid}/objects/{address}", operation_id="write_object")
async def write_object(
    sid: str, address: str, body: WriteRequest, state: StateDep, client: WriteControl
) -> ObjectValueOut:
    session = state.manager.get(sid)
    addr = ObjectAddress.parse(address)
    # The client id (X-Servodesk-Client) goes to the audit log.
    return _value_out(
        await session.write_object(addr, body.value, body.raw_hex, client=client or "unknown")
    )


@router.post("/sessions/{sid}/read", operation_id="read_objects")
async def read_objects(sid: str, body: ReadRequest, state: StateDep) -> ReadResults:
    session = state.manager.get(sid)
    addresses = [ObjectAddress.parse(a) for a in body.addresses]
    results: list[ObjectValueOut | ReadFailure] = []
    for addr, r in zip(addresses, await session.read_many(addresses), strict=True):
        if isinstance(r, ServodeskError):
            results.append(
                ReadFailure(address=str(addr), error=ErrorOut.model_validate(r.to_dict()))
            )
        else:
            results.append(_value_out(r))
    return ReadResults(results=results)


@router.post("/sessions/{sid}/store", operation_id="store_parameters")
async def store_parameters(sid: str, state: StateDep, _: WriteControl) -> StoreResult:
    out = StoreResult(**await state.manager.get(sid).store())
    state.audit.record("write.store_eeprom", drive=sid, details=out.model_dump())
    return out


@router.post("/sessions/{sid}/restore-defaults", operation_id="restore_defaults")
async def restore_defaults(
    sid: str, body: RestoreDefaultsRequest, state: StateDep, _: WriteControl
) -> MessageOut:
    # The schema requires confirm: true (a request without it is a 422 naming the field).
    out = MessageOut(**await state.manager.get(sid).restore_defaults(body.reset))
    state.audit.record(
        "write.restore_defaults", drive=sid, message=out.message, details={"reset": body.reset}
    )
    return out


@router.get("/sessions/{sid}/state", operation_id="get_state")
async def get_state(sid: str, state: StateDep) -> DriveStateOut:
    st = await state.manager.get(sid).drive_state()
    return DriveStateOut.model_validate(asdict(st))


@router.post("/sessions/{sid}/state", operation_id="command_state")
async def command_state(
    sid: str, body: StateCommand, state: StateDep, _: StateControl
) -> DriveStateOut:
    st = await state.manager.get(sid).command(body.command)
    state.audit.record(
        "write.state_command", drive=sid, details={"command": body.command, "state": str(st.state)}
    )
    return DriveStateOut.model_validate(asdict(st))
