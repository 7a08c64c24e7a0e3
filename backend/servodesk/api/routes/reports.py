"""Commissioning reports (issue 49; docs/report.md, docs/api.md "Reports").

``POST /sessions/{sid}/report`` reads the drive and makes a report (HTML, recorded in the
store with its content hash); ``GET /reports/{id}`` is its metadata, ``.html`` the document
as it was made, ``.pdf`` the same printed by the server's Chromium (the first print is kept,
so every download of it is the same file and verifies).

A report holds the drive's audit extract (who did what): reading one needs the audit log's
right, making one also the backup right (it reads every parameter as a backup does).
"""

from __future__ import annotations

import asyncio
from typing import Annotated, Any

from fastapi import APIRouter, Path, Request, Response

from servodesk.api.deps import StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.identity import caller_of
from servodesk.api.rights import require
from servodesk.api.schemas import ERROR_RESPONSES, STORED_ID
from servodesk.api.schemas_report import ReportInfo
from servodesk.domain.roles import Right
from servodesk.services.report_pdf import print_pdf

router = APIRouter(tags=["reports"], responses=ERROR_RESPONSES)

ReportId = Annotated[str, Path(pattern=STORED_ID, description="the report's id (POST's answer)")]

#: The report's page may not fetch anything nor run anything, wherever it is opened from
#: (its CJK font, where it has one, is inline: services/report_html.py).
_CSP = "default-src 'none'; style-src 'unsafe-inline'; img-src data:; font-src data:; sandbox"


def _info(meta: dict[str, Any]) -> ReportInfo:
    rid = meta["id"]
    return ReportInfo.model_validate(
        {
            **meta,
            "url": f"/api/v1/reports/{rid}.html",
            "pdf_url": f"/api/v1/reports/{rid}.pdf",
        }
    )


@router.post(
    "/sessions/{sid}/report",
    status_code=201,
    operation_id="create_report",
    dependencies=[require(Right.BACKUP)],
)
async def create_report(sid: str, request: Request, state: StateDep) -> ReportInfo:
    """Read the drive and make its commissioning report (progress on the WebSocket as
    operation ``report``); the report is recorded in the store with its content hash."""
    session = state.manager.get(sid)
    who = caller_of(request)
    meta = await state.reports.make(session, by=who.user)
    state.audit.record(
        "backup.report",
        drive=sid,
        message=f"commissioning report {meta['id']}",
        details={"report": meta["id"], "drive_key": meta["drive_key"], "sha256": meta["sha256"]},
    )
    return _info(meta)


@router.get(
    "/reports/{rid}.html",
    operation_id="report_html",
    response_class=Response,
    responses={200: {"content": {"text/html": {}}}},
)
def report_html(rid: ReportId, state: StateDep) -> Response:
    """The report's HTML document, byte for byte as it was made."""
    data = state.reports.reports.html(rid)
    return Response(
        content=data,
        media_type="text/html; charset=utf-8",
        headers={
            "Content-Disposition": content_disposition(f"{rid}.html", "inline"),
            "Content-Security-Policy": _CSP,
        },
    )


@router.get(
    "/reports/{rid}.pdf",
    operation_id="report_pdf",
    response_class=Response,
    responses={200: {"content": {"application/pdf": {}}}},
)
async def report_pdf(rid: ReportId, state: StateDep) -> Response:
    """The report printed as PDF by the server's Chromium (503 naming what to install when
    it has none); printed once, then the same file on every request."""
    store = state.reports.reports
    pdf = await asyncio.to_thread(store.pdf, rid)
    if pdf is None:
        html = await asyncio.to_thread(store.html, rid)
        printed = await asyncio.to_thread(print_pdf, html)
        pdf = await asyncio.to_thread(store.set_pdf, rid, printed)
    return Response(
        content=pdf,
        media_type="application/pdf",
        headers={"Content-Disposition": content_disposition(f"{rid}.pdf", "inline")},
    )


@router.get("/reports/{rid}", operation_id="get_report")
def get_report(rid: ReportId, state: StateDep) -> ReportInfo:
    """A report's metadata: drive, when, by whom, its hashes, where the documents are."""
    return _info(state.reports.reports.get(rid))
