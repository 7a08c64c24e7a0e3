"""Live scope routes (issue 7): thin wrappers over services/scope.py; shapes: docs/scope.md.

Kept captures (issue 49, docs/scope.md "Kept captures") are the store's
(services/capture_store.py): kept from a drive's session, listed per drive (from every session
and gateway, as the stored tuning results are), read as JSON or CSV, attached to the drive's
commissioning reports, and deleted only with a reason that the audit log keeps. Their rights
are the backups' (api/rights.py).

The scope belongs to the application (its channels may come from several sessions), so its
routes sit under ``/scope``; only the drive-side recorder's description is per session. The
scope reads the drives and never changes the axis (a recorder's configuration objects are
the only writes), so no route needs control ownership. The binary stream is
api/scope_ws.py. AppState (api/state.py) stops the acquisition before the sessions close.
"""

from __future__ import annotations

import asyncio
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query, Request
from fastapi.responses import Response

from servodesk.api.control_deps import ClientId
from servodesk.api.deps import StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.identity import caller_of
from servodesk.api.offload import in_process
from servodesk.api.schemas import ERROR_RESPONSES, STORED_ID
from servodesk.api.schemas_scope import (
    CaptureDelete,
    CaptureInfo,
    CaptureKeep,
    CapturePatch,
    ChannelsIn,
    RecorderInfo,
    RunIn,
    ScopeRecording,
    ScopeStatus,
    StoredCapture,
    TriggerIn,
)
from servodesk.api.state import state_of
from servodesk.api.uploads import openapi_file_body, read_file
from servodesk.domain import scope as core
from servodesk.services import scope as scopesvc
from servodesk.services.backup import drive_key
from servodesk.services.capture_store import MAX_LIST
from servodesk.services.scope import ScopeService
from servodesk.services.scope_channels import parse_channel
from servodesk.services.scope_recorder import recorder_info


def scope_of(app: Any) -> ScopeService:
    """The application's scope (AppState builds it and stops it at shutdown)."""
    return state_of(app).scope


router = APIRouter(tags=["scope"], responses=ERROR_RESPONSES)


@router.get("/scope", operation_id="scope_status")
async def scope_status(request: Request) -> ScopeStatus:
    return ScopeStatus.model_validate(scope_of(request.app).status())


@router.put("/scope/channels", operation_id="scope_set_channels")
async def scope_set_channels(body: ChannelsIn, request: Request, state: StateDep) -> ScopeStatus:
    # The sessions first: a channel of a session that does not exist is a 404 naming it,
    # whatever else is wrong with the request.
    for c in body.channels:
        state.manager.get(c.session)
    configs = [parse_channel(c.model_dump()) for c in body.channels]
    return ScopeStatus.model_validate(await scope_of(request.app).set_channels(configs))


@router.put("/scope/trigger", operation_id="scope_set_trigger")
async def scope_set_trigger(body: TriggerIn, request: Request) -> ScopeStatus:
    trigger = core.Trigger(**body.model_dump())
    return ScopeStatus.model_validate(await scope_of(request.app).set_trigger(trigger))


@router.post("/scope/run", operation_id="scope_run")
async def scope_run(body: RunIn, request: Request) -> ScopeStatus:
    return ScopeStatus.model_validate(await scope_of(request.app).run(body.action))


# A capture's channels carry the display settings only when still configured, and the window
# only when the trigger gave one (ScopeRecording, api/reply.py).
@router.get("/scope/capture", operation_id="scope_capture", response_model_exclude_unset=True)
async def scope_capture(request: Request) -> ScopeRecording:
    return ScopeRecording.model_validate(scope_of(request.app).capture())


@router.get("/scope/export", operation_id="scope_export", response_class=Response)
async def scope_export(
    request: Request,
    format: Annotated[Literal["csv", "mdf4"], Query()] = "csv",
    window: Annotated[Literal["capture", "buffer"], Query()] = "buffer",
) -> Response:
    # The file is formatted in a worker (api/offload.py): a long buffer held the loop.
    data, media, filename = await scope_of(request.app).export_off_loop(format, window)
    return Response(
        data,
        media_type=media,
        headers={"Content-Disposition": content_disposition(filename)},
    )


@router.post(
    "/scope/import",
    operation_id="scope_import",
    openapi_extra=openapi_file_body(),
    # Documentation only: the answer is the worker's JSON bytes, as they are.
    response_model=ScopeRecording,
)
async def scope_import(
    request: Request,
    filename: Annotated[str, Query(min_length=1, max_length=255)] = "recording.csv",
) -> Response:
    """Open a recording file (CSV or MDF4), sent as multipart/form-data field ``file``."""
    body = await read_file(request)  # At most 64 MiB (api/uploads.py).
    # Parsed and turned into JSON in the documents' process: a 10 MB CSV held the loop (and,
    # in a thread, the GIL) for seconds (api/offload.py).
    data = await in_process(scopesvc.import_recording_json, body, filename)
    return Response(data, media_type="application/json")


# section: a present recorder's only (RecorderInfo).
@router.get(
    "/sessions/{sid}/recorder", operation_id="scope_recorder", response_model_exclude_unset=True
)
async def scope_recorder(sid: str, state: StateDep) -> RecorderInfo:
    return RecorderInfo.model_validate(recorder_info(state.manager.get(sid)))


# Kept captures ------------------------------------------------------------------------------

CaptureId = Annotated[str, Path(pattern=STORED_ID, description="the capture's id (its list's)")]


@router.post("/sessions/{sid}/scope/captures", status_code=201, operation_id="keep_scope_capture")
async def keep_scope_capture(
    sid: str, body: CaptureKeep, request: Request, state: StateDep, client: ClientId
) -> CaptureInfo:
    """Keep the scope's last captured window (or its whole buffer) in the store as a capture
    of this session's drive, with a title and note; 404 when the scope has none."""
    session = state.manager.get(sid)
    # Taken on the loop (the scope's buffers change there); made JSON and stored in a thread.
    make, trigger = scope_of(request.app).kept(body.window)
    who = caller_of(request)

    def keep() -> dict[str, Any]:
        return state.captures.add(
            drive_key=drive_key(session),
            session=sid,
            title=body.title.strip(),
            note=body.note,
            by=who.user,
            client=client or "",
            window=body.window,
            recording=make(),
            trigger=trigger,
            attached=body.attach,
        )

    meta = await asyncio.to_thread(keep)
    state.audit.record(
        "backup.capture_kept",
        drive=sid,
        message=f"scope capture {meta['id']}: {meta['title']}",
        details={"capture": meta["id"], "drive_key": meta["drive_key"], "sha256": meta["sha256"]},
    )
    return CaptureInfo.model_validate(meta)


# The store routes below are plain functions: FastAPI runs them in its thread pool, so a store
# on a slow network never holds the event loop.
@router.get("/sessions/{sid}/scope/captures", operation_id="list_scope_captures")
def list_scope_captures(
    sid: str, state: StateDep, limit: int = Query(100, ge=1, le=MAX_LIST)
) -> list[CaptureInfo]:
    """The captures of this session's drive kept in the store (from every session and
    gateway), newest first; without their samples."""
    key = drive_key(state.manager.get(sid))
    return [CaptureInfo.model_validate(c) for c in state.captures.of_drive(key, limit)]


# Before /scope/captures/{cid}: an id has no ".", so "x.csv" is never one.
@router.get(
    "/scope/captures/{cid}.csv",
    operation_id="export_scope_capture",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def export_scope_capture(cid: CaptureId, state: StateDep) -> Response:
    """The kept capture as the scope's CSV (docs/scope.md "CSV"): opens again in the scope."""
    data, filename = state.captures.csv(cid)
    return Response(
        data,
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": content_disposition(filename)},
    )


@router.get(
    "/scope/captures/{cid}",
    operation_id="get_scope_capture",
    response_model_exclude_unset=True,
)
def get_scope_capture(cid: CaptureId, state: StateDep) -> StoredCapture:
    """One kept capture with every sample (raw, and each channel's scale to engineering
    units) and the trigger; 404 when the store has none of that id."""
    return StoredCapture.model_validate(state.captures.get(cid))


@router.patch("/scope/captures/{cid}", operation_id="attach_scope_capture")
def attach_scope_capture(cid: CaptureId, body: CapturePatch, state: StateDep) -> CaptureInfo:
    """Attach the capture to its drive's commissioning reports (every report made while it
    is attached shows it), or detach it."""
    meta = state.captures.set_attached(cid, body.attached)
    state.audit.record(
        "backup.capture_attached" if body.attached else "backup.capture_detached",
        drive=meta["session"],
        message=f"scope capture {cid}: {meta['title']}",
        details={"capture": cid, "drive_key": meta["drive_key"]},
    )
    return CaptureInfo.model_validate(meta)


@router.delete("/scope/captures/{cid}", operation_id="delete_scope_capture")
def delete_scope_capture(cid: CaptureId, body: CaptureDelete, state: StateDep) -> CaptureInfo:
    """Delete a kept capture, with the reason (the audit log keeps who, when, why and the
    capture's hash); the deleted capture's metadata."""
    meta = state.captures.delete(cid)
    state.audit.record(
        "backup.capture_deleted",
        drive=meta["session"],
        message=body.reason,
        details={
            "capture": cid,
            "drive_key": meta["drive_key"],
            "title": meta["title"],
            "sha256": meta["sha256"],
        },
    )
    return CaptureInfo.model_validate(meta)
