"""Live scope routes (issue 7): thin wrappers over services/scope.py; shapes: docs/scope.md.

The scope belongs to the application (its channels may come from several sessions), so its
routes sit under ``/scope``; only the drive-side recorder's description is per session. The
scope reads the drives and never changes the axis (a recorder's configuration objects are
the only writes), so no route needs control ownership. The binary stream is
api/scope_ws.py. AppState (api/state.py) stops the acquisition before the sessions close.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response

from servodesk.api.deps import StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.offload import in_process
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_scope import (
    ChannelsIn,
    RecorderInfo,
    RunIn,
    ScopeRecording,
    ScopeStatus,
    TriggerIn,
)
from servodesk.api.state import state_of
from servodesk.api.uploads import openapi_file_body, read_file
from servodesk.domain import scope as core
from servodesk.services import scope as scopesvc
from servodesk.services.scope import ScopeService


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
    configs = [scopesvc.parse_channel(c.model_dump()) for c in body.channels]
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
    return RecorderInfo.model_validate(scopesvc.recorder_info(state.manager.get(sid)))
