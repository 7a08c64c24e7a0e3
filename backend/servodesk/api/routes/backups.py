"""Backup, compare, restore and audit routes (docs/api.md, "Backup, compare, restore")."""

from __future__ import annotations

import json
import time
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Header, Query, Request, Response

from servodesk.api import backup_documents
from servodesk.api.control_deps import ControlToken, WriteControl, operation
from servodesk.api.deps import AppState, StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.identity import caller_of
from servodesk.api.offload import file_answer, in_process, in_worker, json_response
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_backups import (
    AuditEntry,
    BackupCreate,
    BackupFile,
    BackupInfo,
    BackupPatch,
    CompareRequest,
    Comparison,
    PlantBackupCreate,
    PlantBackupItem,
    PlantBackupReport,
    PreflightOut,
    PreflightRequest,
    RestoreReport,
    RestoreRequest,
    SourceBackup,
    SourceDefaults,
    SourceDrive,
)
from servodesk.api.uploads import openapi_file_body, read_file
from servodesk.errors import ConflictError, NotFoundError, ServodeskError, ValidationError
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
    info = BackupInfo.model_validate(await state.backups.backup(session, body.label, body.note))
    state.audit.record(
        "backup.taken", drive=sid, details={"backup": info.id, "entries": info.entries}
    )
    return info


@router.post("/backups/plant", operation_id="create_plant_backup")
async def create_plant_backup(body: PlantBackupCreate, state: StateDep) -> PlantBackupReport:
    """A backup of every open drive (or of ``sessions``), the drives read at once: requests
    to different drives interleave on a CAN bus and run side by side on the others. Each
    drive's result is its own item; one that fails leaves the others saved."""
    if body.sessions is None:
        sessions = state.manager.all()
        if not sessions:
            raise ConflictError(
                "no session is open: nothing to back up", hint="open the drives first"
            )
    else:
        # Named twice is the same drive: backed up once, in the order first named.
        names = list(dict.fromkeys(body.sessions))
        sessions = [state.manager.get(sid) for sid in names]  # 404 names a stranger
    t0 = time.monotonic()
    results = await state.backups.backup_many(sessions, body.label, body.note)
    items: list[PlantBackupItem] = []
    for session, r in zip(sessions, results, strict=True):
        if isinstance(r, ServodeskError):
            items.append(
                PlantBackupItem(session=session.id, ok=False, error=r.message, hint=r.hint)
            )
            continue
        info = BackupInfo.model_validate(r)
        state.audit.record(
            "backup.taken", drive=session.id, details={"backup": info.id, "entries": info.entries}
        )
        items.append(PlantBackupItem(session=session.id, ok=True, backup=info))
    saved = sum(1 for i in items if i.ok)
    return PlantBackupReport(
        items=items,
        saved=saved,
        failed=len(items) - saved,
        duration_s=round(time.monotonic() - t0, 3),
    )


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
    out = await json_response(
        lambda: state.backups.import_bytes(body, filename, profile), BackupInfo, 201
    )
    state.audit.record(
        "backup.uploaded",
        details={"backup": json.loads(bytes(out.body))["id"], "filename": filename},
    )
    return out


@router.get("/backups/{bid}", operation_id="get_backup", response_model=BackupFile)
async def get_backup(bid: str, state: StateDep) -> Response:
    # Checked and rendered in the documents' worker process (api/backup_documents.py).
    return await file_answer(backup_documents.checked_json, state.backups.stored(bid))


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
    info = BackupInfo.model_validate(state.backups.store.update_backup(bid, body.label, body.note))
    state.audit.record(
        "backup.labelled", details={"backup": bid, **body.model_dump(exclude_none=True)}
    )
    return info


async def _source(
    state: AppState, src: SourceDrive | SourceBackup | SourceDefaults
) -> tuple[backup_documents.Side, str]:
    """A compare side as the worker takes it (a stored backup by its file, not its set),
    and its profile's id."""
    if isinstance(src, SourceDrive):
        session = state.manager.get(src.session)
        ps = await state.backups.read_set(session, operation="compare")
        return (f"drive {session.id}", ps), ps.profile_id
    if isinstance(src, SourceBackup):
        f = state.backups.stored(src.id)
        return (f"backup {src.id}", f), f.profile_id
    ps = state.backups.defaults(src.profile, src.node_id)
    return (f"defaults of {src.profile}", ps), ps.profile_id


@router.post("/compare", operation_id="compare", response_model=Comparison)
async def compare(body: CompareRequest, state: StateDep) -> Response:
    """Drive vs backup, backup vs backup, drive vs profile defaults: what differs, grouped."""
    a, pa = await _source(state, body.a)
    b, pb = await _source(state, body.b)
    # Backups are opened, compared and rendered in the documents' worker process.
    return await file_answer(
        backup_documents.comparison_json, a, b, state.backups.profiles_for(pa, pb), body.all
    )


@router.post(
    "/sessions/{sid}/restore/preflight",
    operation_id="restore_preflight",
    response_model=PreflightOut,
)
async def restore_preflight(sid: str, body: PreflightRequest, state: StateDep) -> Response:
    """What a restore would do and every problem that stops it; writes nothing."""
    session = state.manager.get(sid)
    f = state.backups.stored(body.backup)
    # The file is parsed in the documents' worker; the server reads only the drive.
    plan = await in_process(backup_documents.targets, f, session.profile, body.map_by_name)
    facts = await state.restores.facts(session, plan.targets)
    return await file_answer(backup_documents.preflight_json, f, facts, body.map_by_name)


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
    state.audit.record(
        "restore.done",
        drive=sid,
        ok=_restored(rep),
        message=str(rep.get("message") or ""),
        details=_restore_facts(rep),
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
    holder = operation(request.app).control.check(
        session.id, token, "resuming the restore", caller_of(request).user
    )
    rep = await state.restores.resume(rid, session, client=holder)
    state.audit.record(
        "restore.resumed",
        drive=session.id,
        ok=_restored(rep),
        message=str(rep.get("message") or ""),
        details=_restore_facts(rep),
    )
    return RestoreReport.model_validate(rep)


def _restored(rep: dict[str, Any]) -> bool:
    """A restore the audit log records as a success: it ran to its end, uninterrupted."""
    return bool(rep.get("finished")) and not rep.get("interrupted")


def _restore_facts(rep: dict[str, Any]) -> dict[str, Any]:
    keys = ("id", "backup", "dry_run", "finished", "stored", "interrupted", "pre_backup", "counts")
    return {k: rep.get(k) for k in keys}


@router.get("/audit/writes", operation_id="list_parameter_writes")
async def list_parameter_writes(
    state: StateDep,
    session: str | None = Query(None, max_length=200),
    limit: int = Query(100, ge=1, le=10_000),
) -> list[AuditEntry]:
    """Parameter writes made through servodesk with their old and new values, newest first
    (GET /audit has every audited event; this list was GET /audit before issue 45)."""
    return [AuditEntry.model_validate(r) for r in state.backups.store.list_audit(session, limit)]
