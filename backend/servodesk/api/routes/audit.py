"""The audit log's routes: list with filters, verify the hash chain, export (docs/api.md,
"Audit log"; docs/security.md, "Audit log")."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime
from typing import Annotated, Literal

from fastapi import APIRouter, Query
from fastapi.responses import StreamingResponse
from starlette.concurrency import run_in_threadpool

from servodesk.api.deps import StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_audit import AuditRecord, AuditVerdict
from servodesk.services.audit import Category

router = APIRouter(tags=["audit"], responses=ERROR_RESPONSES)

#: A time filter: ISO 8601 (``2026-12-07T08:00:00Z``); without a zone it is UTC.
Instant = Annotated[datetime | None, Query(description="ISO 8601; without a zone: UTC")]


def _utc(t: datetime | None) -> datetime | None:
    """A filter time in UTC (naive: UTC). One past the years UTC can hold (9999-12-31T23:00
    at -05:00) is the end (or start) of time: it matches what such a bound would."""
    if t is None:
        return None
    aware = t if t.tzinfo is not None else t.replace(tzinfo=UTC)
    try:
        return aware.astimezone(UTC)
    except OverflowError:
        edge = datetime.max if t.year > 1 else datetime.min
        return edge.replace(tzinfo=UTC)


@router.get("/audit", operation_id="list_audit")
async def list_audit(
    state: StateDep,
    category: Category | None = None,
    user: str | None = Query(None, max_length=200),
    drive: str | None = Query(None, max_length=200),
    event: str | None = Query(None, max_length=100),
    since: Instant = None,
    until: Instant = None,
    before: int | None = Query(
        None, ge=1, le=2**62, description="only records older than this seq"
    ),
    limit: int = Query(200, ge=1, le=10_000),
) -> list[AuditRecord]:
    """Audit records matching every filter given, newest first."""
    # since after until is an empty window, not an error: it lists nothing.
    since, until = _utc(since), _utc(until)
    rows = await run_in_threadpool(
        state.audit.query,
        category=category,
        user=user,
        drive=drive,
        event=event,
        since=since,
        until=until,
        before=before,
        limit=limit,
    )
    return [AuditRecord.model_validate(r) for r in rows]


@router.get("/audit/verify", operation_id="verify_audit")
async def verify_audit(state: StateDep) -> AuditVerdict:
    """Recompute the hash chain: ok, or the first record that was altered, removed or moved."""
    verdict = await run_in_threadpool(state.audit.verify)
    return AuditVerdict.model_validate(verdict.to_dict())


@router.get(
    "/audit/export",
    operation_id="export_audit",
    response_class=StreamingResponse,
    responses={
        200: {
            "content": {"application/x-ndjson": {}, "text/csv": {}},
            "description": "every record from since, oldest first, with its hashes",
        }
    },
)
async def export_audit(
    state: StateDep,
    format: Literal["jsonl", "csv"] = "jsonl",
    since: Instant = None,
) -> StreamingResponse:
    """The audit log as a download (JSON lines or CSV), oldest first."""
    since = _utc(since)
    await run_in_threadpool(state.audit.flush)
    chunks: Iterator[str] = state.audit.export(format, since)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return StreamingResponse(
        chunks,  # Iterated in the thread pool by Starlette: the loop is not held.
        media_type="application/x-ndjson" if format == "jsonl" else "text/csv; charset=utf-8",
        headers={"Content-Disposition": content_disposition(f"servodesk-audit-{stamp}.{format}")},
    )
