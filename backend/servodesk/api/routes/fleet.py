"""The fleet's routes: every drive the store knows, plant tags, approved backups, drift
(docs/api.md "Fleet and drift", docs/deployment.md).

The store routes are plain functions: FastAPI runs them in its thread pool, so a store on a
slow network never holds the event loop.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request

from servodesk.api.deps import StateDep
from servodesk.api.identity import caller_of
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_fleet import (
    PRINTABLE,
    ApproveRequest,
    ClearApprovalRequest,
    DriftResult,
    DriftStateName,
    FleetDrive,
    FleetPage,
    GatewayOut,
    PlantTagRequest,
)
from servodesk.errors import ValidationError
from servodesk.services.fleet import MAX_PAGE

router = APIRouter(tags=["fleet"], responses=ERROR_RESPONSES)


@router.get("/fleet", operation_id="list_fleet")
def list_fleet(
    state: StateDep,
    q: str = Query(
        "", max_length=200, pattern=PRINTABLE, description="text in the tag, key, serial or profile"
    ),
    drift: Annotated[
        DriftStateName | None, Query(description="only drives in this drift state")
    ] = None,
    gateway: str | None = Query(
        None, max_length=64, pattern=PRINTABLE, description="only drives of this gateway"
    ),
    offset: int = Query(0, ge=0, le=10_000_000),
    limit: int = Query(100, ge=1, le=MAX_PAGE),
) -> FleetPage:
    """Every drive the store knows (from every gateway's backups and connections), tagged
    drives first; filtered and one page at a time."""
    page = state.fleet.fleet(q=q, drift=drift, gateway=gateway, offset=offset, limit=limit)
    return FleetPage.model_validate(page)


@router.get("/fleet/gateways", operation_id="list_gateways")
def list_gateways(state: StateDep) -> list[GatewayOut]:
    """The gateways that share this store, with when each was last seen."""
    return [GatewayOut.model_validate(g) for g in state.fleet.gateways()]


@router.put("/fleet/tag", operation_id="set_plant_tag")
def set_plant_tag(body: PlantTagRequest, state: StateDep) -> FleetDrive:
    """Give a drive its plant tag (unique), or clear it (tag null or empty)."""
    old = state.fleet.drive(body.drive)
    drive = FleetDrive.model_validate(state.fleet.set_tag(body.drive, body.tag or None))
    state.audit.record(
        "config.plant_tag",
        drive=drive.session,
        message=f"plant tag {old['plant_tag'] or '-'} -> {drive.plant_tag or '-'}",
        details={"drive_key": drive.drive_key, "old": old["plant_tag"], "new": drive.plant_tag},
    )
    return drive


@router.put("/fleet/approved", operation_id="approve_backup")
def approve_backup(body: ApproveRequest, request: Request, state: StateDep) -> FleetDrive:
    """Make a backup the drive's approved ("golden") one: who and when are recorded, the
    reason is required. Drift checks compare the drive with it from now on."""
    backup = state.backups.info(body.backup)
    who = caller_of(request)
    drive = FleetDrive.model_validate(
        state.fleet.approve(body.drive, backup, by=who.user, reason=body.reason)
    )
    state.audit.record(
        "backup.approved",
        drive=drive.session,
        message=body.reason.strip(),
        details={"drive_key": drive.drive_key, "backup": body.backup},
    )
    return drive


@router.delete("/fleet/approved", operation_id="clear_approval")
def clear_approval(body: ClearApprovalRequest, state: StateDep) -> FleetDrive:
    """The drive has no approved backup any more; the reason is required and audited. Its
    drift state is unknown until a backup is approved again; 409 when it has none."""
    reason = body.reason.strip()
    if not reason:
        raise ValidationError(
            "clearing an approval needs a reason",
            field="reason",
            hint="say why the drive has no reference any more (e.g. 'drive rebuilt')",
        )
    old = state.fleet.drive(body.drive)
    drive = FleetDrive.model_validate(state.fleet.clear_approval(body.drive))
    state.audit.record(
        "backup.approval_cleared",
        drive=drive.session,
        message=reason,
        details={
            "drive_key": drive.drive_key,
            "backup": (old["approved"] or {}).get("backup"),
        },
    )
    return drive


@router.post("/sessions/{sid}/drift", operation_id="check_drift")
async def check_drift(sid: str, state: StateDep) -> DriftResult:
    """Compare the connected drive with its approved backup now; the result is recorded
    (and the webhook notified when parameters differ)."""
    session = state.manager.get(sid)
    return DriftResult.model_validate(await state.drift.check(session))


@router.get("/fleet/drift", operation_id="list_drift")
def list_drift(
    state: StateDep,
    drive: str | None = Query(
        None, max_length=200, pattern=PRINTABLE, description="drive_key or plant tag"
    ),
    limit: int = Query(100, ge=1, le=1000),
) -> list[DriftResult]:
    """Drift check results, newest first."""
    return [DriftResult.model_validate(r) for r in state.fleet.drift_results(drive, limit)]
