"""Backup, compare, restore and audit routes (docs/api.md, "Backup, compare, restore")."""

from __future__ import annotations

import json
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Header, Query, Request, Response

from servodesk.api.control_deps import ControlToken, WriteControl, operation
from servodesk.api.deps import AppState, StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.offload import in_worker, json_response
from servodesk.api.schemas import (
    ERROR_RESPONSES,
    AuditEntry,
    BackupCreate,
    BackupFile,
    BackupInfo,
    BackupPatch,
    CompareRequest,
    Comparison,
    PreflightOut,
    PreflightRequest,
    RestoreReport,
    RestoreRequest,
    SourceBackup,
    SourceDefaults,
    SourceDrive,
)
from servodesk.api.uploads import openapi_file_body, read_file
from servodesk.domain.paramset import ParameterSet
from servodesk.errors import NotFoundError, ValidationError
from servodesk.services.session import Session

router = APIRouter(tags=["backups"], responses=ERROR_RESPONSES)

#: X-Servodesk-Client: who makes the request, for the audit log (UI tab id, cli:user@host).
ClientHeader = Annotated[
    str | None,
    Header(
        alias="X-Servodesk-Client",
        max_length=64,
        pattern=r"^[A-Za-z0-9._:@-]+$",
        description="client id for the audit log",
    ),
]


@router.post("/sessions/{sid}/backups", status_code=201, operation_id="create_backup")
async def create_backup(sid: str, body: BackupCreate, state: StateDep) -> BackupInfo:
    """Read every configurable parameter of the drive into a new backup (progress on the WS)."""
    session = state.manager.get(sid)
    return BackupInfo.model_validate(await state.backups.backup(session, body.label, body.note))


@router.get("/backups", operation_id="list_backups")
async def list_backups(
    state: StateDep,
    drive: str | None = Query(None, max_length=200, description="drive_key"),
    profile: str | None = Query(None, max_length=200, description="profile id"),
) -> list[BackupInfo]:
    rows = state.backups.store.list_backups(drive, profile)
    return [BackupInfo.model_validate(r) for r in rows]


@router.post(
    "/backups/upload",
    status_code=201,
    operation_id="upload_backup",
    openapi_extra=openapi_file_body(json_too=True),
    response_model=BackupInfo,
)
async def upload_backup(
    request: Request,
    state: StateDep,
    filename: str = Query(min_length=1, max_length=255, description="x.json or x.dcf"),
    profile: str | None = Query(None, max_length=200, description="profile of a foreign DCF"),
) -> Response:
    """Store a backup file (servodesk JSON, or a DCF's ParameterValues): the file as
    multipart/form-data field ``file``, or a JSON backup as an application/json body."""
    body = await read_file(request, json_too=True)  # At most 32 MiB (api/uploads.py).
    if not body.strip():
        raise ValidationError("the request body is empty", field="body", hint="send the file")
    # Parsed, checked and stored in a worker: a 32 MiB file held the loop (api/offload.py).
    return await json_response(
        lambda: state.backups.import_bytes(body, filename, profile), BackupInfo, 201
    )


@router.get("/backups/{bid}", operation_id="get_backup", response_model=BackupFile)
async def get_backup(bid: str, state: StateDep) -> Response:
    def build() -> Any:
        data = state.backups.file_bytes(bid)
        state.backups.load(bid)  # Checks the file (schema, checksum) before it is shown.
        return json.loads(data)

    return await json_response(build, BackupFile)


@router.get(
    "/backups/{bid}/download",
    operation_id="download_backup",
    response_class=Response,
    responses={200: {"content": {"application/json": {}, "text/plain": {}, "text/csv": {}}}},
)
async def download_backup(
    bid: str,
    state: StateDep,
    format: Literal["json", "dcf", "csv"] = Query("json", description="json, dcf or csv"),
) -> Response:
    info = state.backups.info(bid)
    if format == "json":
        data, media, suffix = state.backups.file_bytes(bid), "application/json", "json"
    else:
        data, media, suffix = await in_worker(
            lambda: state.backups.export(state.backups.load(bid), format)
        )
    name = f"{bid}-{info['profile_id']}.{suffix}"
    return Response(
        content=data,
        media_type=media,
        headers={"Content-Disposition": content_disposition(name)},
    )


@router.patch("/backups/{bid}", operation_id="update_backup")
async def update_backup(bid: str, body: BackupPatch, state: StateDep) -> BackupInfo:
    """Change the label or note in the store (the file itself never changes)."""
    return BackupInfo.model_validate(state.backups.store.update_backup(bid, body.label, body.note))


async def _source(
    state: AppState, src: SourceDrive | SourceBackup | SourceDefaults
) -> tuple[str, ParameterSet]:
    if isinstance(src, SourceDrive):
        session = state.manager.get(src.session)
        ps = await state.backups.read_set(session, operation="compare")
        return f"drive {session.id}", ps
    if isinstance(src, SourceBackup):
        return f"backup {src.id}", await in_worker(state.backups.load, src.id)
    return f"defaults of {src.profile}", state.backups.defaults(src.profile, src.node_id)


@router.post("/compare", operation_id="compare", response_model=Comparison)
async def compare(body: CompareRequest, state: StateDep) -> Response:
    """Drive vs backup, backup vs backup, drive vs profile defaults: what differs, grouped."""
    a = await _source(state, body.a)
    b = await _source(state, body.b)
    return await json_response(
        lambda: state.backups.compare(a, b, include_same=body.all), Comparison
    )


@router.post(
    "/sessions/{sid}/restore/preflight",
    operation_id="restore_preflight",
    response_model=PreflightOut,
)
async def restore_preflight(sid: str, body: PreflightRequest, state: StateDep) -> Response:
    """What a restore would do and every problem that stops it; writes nothing."""
    session = state.manager.get(sid)
    ps = await in_worker(state.backups.load, body.backup)
    pf, _ = await state.restores.preflight(session, ps, map_names=body.map_by_name)
    return await json_response(pf.to_dict, PreflightOut)


@router.post("/sessions/{sid}/restore", operation_id="restore")
async def restore(
    sid: str, body: RestoreRequest, state: StateDep, client: WriteControl
) -> RestoreReport:
    """Preflight, back the drive up, write in order with read-back, store when verified."""
    session = state.manager.get(sid)
    rep = await state.restores.restore(
        session,
        body.backup,
        dry_run=body.dry_run,
        store=body.store,
        force=body.force,
        map_by_name=body.map_by_name,
        client=client or "unknown",
    )
    return RestoreReport.model_validate(rep)


@router.get("/restores/{rid}", operation_id="get_restore")
async def get_restore(rid: str, state: StateDep) -> RestoreReport:
    return RestoreReport.model_validate(state.restores.report(rid))


def _session_for(state: AppState, rec: dict[str, Any]) -> Session:
    """The session of the restore's drive: the same session, else one on the same bus/node."""
    for s in state.manager.all():
        if s.id == rec["session"]:
            return s
    bus = rec["bus"]
    for s in state.manager.all():
        p = s.link.params
        if (p.interface, p.channel, p.node_id) == (
            bus.get("interface"),
            bus.get("channel"),
            bus.get("node_id"),
        ):
            return s
    raise NotFoundError(
        f"no open session for the drive of restore {rec['id']} (node {bus.get('node_id')} on "
        f"{bus.get('interface')} {bus.get('channel')})",
        hint="open a session for that drive, then resume",
    )


@router.post("/restores/{rid}/resume", operation_id="resume_restore")
async def resume_restore(
    rid: str, request: Request, state: StateDep, token: ControlToken
) -> RestoreReport:
    """Continue an interrupted restore: check every item, write what is missing."""
    rec = state.backups.store.get_restore(rid)
    session = _session_for(state, rec)
    # Writes need control of the drive, as every other write route (control_deps).
    holder = operation(request.app).control.check(session.id, token, "resuming the restore")
    return RestoreReport.model_validate(await state.restores.resume(rid, session, client=holder))


@router.get("/audit", operation_id="list_audit")
async def list_audit(
    state: StateDep,
    session: str | None = Query(None, max_length=200),
    limit: int = Query(100, ge=1, le=10_000),
) -> list[AuditEntry]:
    """Parameter writes made through servodesk, newest first."""
    return [AuditEntry.model_validate(r) for r in state.backups.store.list_audit(session, limit)]
