"""PDO mapping and cyclic data routes (issue 6): thin wrappers over services/pdo.py.

Reading, validating and planning change nothing and need no control; applying a mapping,
starting or stopping cyclic data and setting outputs are writes (control ownership, 409
naming the owner otherwise). Shapes: docs/pdo.md.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import Response

from servodesk.api.control_deps import EnergiseControl, WriteControl, require_energise
from servodesk.api.deps import StateDep
from servodesk.api.downloads import content_disposition
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_pdo import (
    ApplyRequest,
    OutputsRequest,
    PdoApplyReport,
    PdoCyclicRequest,
    PdoCyclicStatus,
    PdoLayout,
    PdoMappable,
    PdoPlan,
    PdoTemplateOut,
    PdoValidation,
    PdoView,
)
from servodesk.devdesc.pdo_export import export as export_pdo
from servodesk.services import pdo as pdosvc
from servodesk.services.control import CONTROL_HEADER

router = APIRouter(tags=["pdo"], responses=ERROR_RESPONSES)


def _body(layout: PdoLayout) -> dict[str, Any]:
    return layout.model_dump(exclude_none=True, exclude={"dry_run"})


@router.get("/sessions/{sid}/pdo", operation_id="pdo_view")
async def pdo_view(sid: str, state: StateDep) -> PdoView:
    return PdoView.model_validate(await pdosvc.view(state.manager.get(sid)))


@router.get("/sessions/{sid}/pdo/mappable", operation_id="pdo_mappable")
async def pdo_mappable(sid: str, state: StateDep) -> PdoMappable:
    return PdoMappable.model_validate(pdosvc.mappable(state.manager.get(sid)))


@router.get("/sessions/{sid}/pdo/templates", operation_id="pdo_templates")
async def pdo_templates(sid: str, state: StateDep) -> list[PdoTemplateOut]:
    return [PdoTemplateOut.model_validate(t) for t in pdosvc.templates(state.manager.get(sid))]


@router.post("/sessions/{sid}/pdo/templates/{template_id}", operation_id="pdo_from_template")
async def pdo_from_template(sid: str, template_id: str, state: StateDep) -> PdoView:
    return PdoView.model_validate(await pdosvc.from_template(state.manager.get(sid), template_id))


@router.post("/sessions/{sid}/pdo/validate", operation_id="pdo_validate")
async def pdo_validate(sid: str, body: PdoLayout, state: StateDep) -> PdoValidation:
    return PdoValidation.model_validate(await pdosvc.check(state.manager.get(sid), _body(body)))


@router.post("/sessions/{sid}/pdo/plan", operation_id="pdo_plan")
async def pdo_plan(sid: str, body: PdoLayout, state: StateDep) -> PdoPlan:
    plan = await pdosvc.make_plan(state.manager.get(sid), _body(body))
    return PdoPlan.model_validate(
        {"steps": [pdosvc.step_dict(s) for s in plan.steps], "touched": list(plan.touched)}
    )


# rollback_error is in a failed apply's report only (api/reply.py).
@router.post(
    "/sessions/{sid}/pdo/apply", operation_id="pdo_apply", response_model_exclude_unset=True
)
async def pdo_apply(
    sid: str, body: ApplyRequest, state: StateDep, client: WriteControl
) -> PdoApplyReport:
    out = await pdosvc.apply(
        state.manager.get(sid), _body(body), dry_run=body.dry_run, client=client
    )
    if not body.dry_run:
        state.audit.record(
            "write.pdo_apply",
            drive=sid,
            details={"client": client, "steps": len(out.get("steps", []))},
        )
    return PdoApplyReport.model_validate(out)


_MEDIA = {
    "json": "application/json",
    "csv": "text/csv",
    "dcf": "text/plain",
    "esi": "application/xml",
}


@router.get(
    "/sessions/{sid}/pdo/export",
    operation_id="pdo_export",
    response_class=Response,
    responses={
        200: {
            "description": "the layout as a file (CSV, DCF, ESI XML or JSON)",
            # The JSON export is a document (domain/pdo_json.py), the others text files.
            "content": {
                m: {"schema": {"type": "object"} if m == "application/json" else {"type": "string"}}
                for m in _MEDIA.values()
            },
        }
    },
)
async def pdo_export(
    sid: str,
    state: StateDep,
    format: Annotated[Literal["json", "csv", "dcf", "esi"], Query()] = "csv",
) -> Response:
    session = state.manager.get(sid)
    config = await pdosvc.read_config(session)
    text = export_pdo(session.profile, config, format, session.link.params.node_id)
    ext = {"esi": "xml"}.get(format, format)
    return Response(
        text,
        media_type=_MEDIA[format],
        headers={"Content-Disposition": content_disposition(f"{sid}-pdo.{ext}")},
    )


# The cyclic status has keys only some answers send (PdoCyclicStatus, api/reply.py).
@router.get(
    "/sessions/{sid}/pdo/cyclic",
    operation_id="pdo_cyclic_status",
    response_model_exclude_unset=True,
)
async def pdo_cyclic_status(sid: str, state: StateDep) -> PdoCyclicStatus:
    return PdoCyclicStatus.model_validate(pdosvc.cyclic_status(state.manager.get(sid)))


@router.post(
    "/sessions/{sid}/pdo/cyclic", operation_id="pdo_cyclic_start", response_model_exclude_unset=True
)
async def pdo_cyclic_start(
    sid: str, body: PdoCyclicRequest, request: Request, state: StateDep, client: WriteControl
) -> PdoCyclicStatus:
    if body.outputs:
        # servodesk then produces the RPDOs: the controlword among them (control_deps).
        await require_energise(
            sid,
            request,
            request.headers.get("X-Servodesk-Client"),
            request.headers.get(CONTROL_HEADER),
        )
    out = await pdosvc.start_cyclic(
        state.manager.get(sid), body.sync_period_ms, body.outputs, body.sync, body.telegram
    )
    facts: dict[str, object] = {
        "sync_period_ms": body.sync_period_ms,
        "outputs": body.outputs,
        "sync": body.sync,
    }
    if body.telegram is not None:
        facts["telegram"] = body.telegram
    state.audit.record("write.cyclic_started", drive=sid, details=facts)
    return PdoCyclicStatus.model_validate(out)


@router.delete(
    "/sessions/{sid}/pdo/cyclic", operation_id="pdo_cyclic_stop", response_model_exclude_unset=True
)
async def pdo_cyclic_stop(sid: str, state: StateDep, client: WriteControl) -> PdoCyclicStatus:
    out = await pdosvc.stop_cyclic(state.manager.get(sid))
    state.audit.record("write.cyclic_stopped", drive=sid)
    return PdoCyclicStatus.model_validate(out)


@router.put(
    "/sessions/{sid}/pdo/cyclic/outputs",
    operation_id="pdo_cyclic_outputs",
    response_model_exclude_unset=True,
)
async def pdo_cyclic_outputs(
    sid: str, body: OutputsRequest, state: StateDep, client: EnergiseControl
) -> PdoCyclicStatus:
    return PdoCyclicStatus.model_validate(pdosvc.set_outputs(state.manager.get(sid), body.values))
