"""Tuning routes (issue 8): thin wrappers over services/tuning/jobs.py; shapes: docs/tuning.md.

Starting a tuning moves the axis: it needs control and the client's WebSocket (its dead-man
heartbeat), like a jog. Stopping is never refused, from any client. Undo and store write
parameters (control ownership, 409 naming the owner otherwise). Progress goes out as WebSocket
``tuning`` messages. AppState (api/state.py) stops running jobs first at shutdown (before
motion halts the axes and the sessions close).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Path, Query, Request

from servodesk.api.control_deps import ClientId, MotionControl, WriteControl
from servodesk.api.deps import StateDep
from servodesk.api.identity import caller_of
from servodesk.api.schemas import ERROR_RESPONSES, STORED_ID
from servodesk.api.schemas_tuning import (
    EmptyBody,
    StartRequest,
    StoredTuningResult,
    TuningInfo,
    TuningJob,
    TuningRecord,
    TuningResult,
    TuningStored,
    UndoRequest,
    UndoResult,
)
from servodesk.api.state import state_of
from servodesk.services.backup import drive_key
from servodesk.services.tuning.jobs import TuningService
from servodesk.services.tuning_store import MAX_HISTORY


def tuning_of(app: Any) -> TuningService:
    """The application's tuning service (AppState builds it and stops its jobs at shutdown)."""
    return state_of(app).tuning


router = APIRouter(tags=["tuning"], responses=ERROR_RESPONSES)


def _svc(request: Request) -> TuningService:
    return tuning_of(request.app)


# A job's bound and its error have keys some producers send only (api/schemas_tuning.py):
# every route answers the keys the service gave, no more.
@router.get("/sessions/{sid}/tuning", operation_id="tuning_info", response_model_exclude_unset=True)
async def tuning_info(sid: str, request: Request) -> TuningInfo:
    """``TuningInfo``: kind (builtin / gains / none), reason, modes, gains, inputs, job."""
    return TuningInfo.model_validate(await _svc(request).info(sid))


@router.post(
    "/sessions/{sid}/tuning/start",
    operation_id="tuning_start",
    status_code=202,
    response_model_exclude_unset=True,
)
async def tuning_start(
    sid: str, body: StartRequest, request: Request, client: MotionControl
) -> TuningJob:
    """Start a tuning job (moves the axis under the client's dead-man); 202 + the job."""
    job = await _svc(request).start(
        sid,
        client,
        mode=body.mode,
        travel_window_rev=body.travel_window_rev,
        torque_limit_pct=body.torque_limit_pct,
        move_torque_pct=body.move_torque_pct,
        user=caller_of(request).user,
    )
    return TuningJob.model_validate(job)


@router.post(
    "/sessions/{sid}/tuning/stop", operation_id="tuning_stop", response_model_exclude_unset=True
)
async def tuning_stop(
    sid: str, request: Request, client: ClientId, body: EmptyBody | None = None
) -> TuningJob:
    """Stop the job: never refused, from any client. The gains from before are put back."""
    return TuningJob.model_validate(await _svc(request).stop(sid, client))


@router.get(
    "/sessions/{sid}/tuning/result",
    operation_id="tuning_result",
    response_model_exclude_unset=True,
)
async def tuning_result(sid: str, request: Request) -> TuningResult:
    """The last job's ``TuningResult``; 404 when there is none."""
    return TuningResult.model_validate(_svc(request).result(sid))


# The store routes are plain functions: FastAPI runs them in its thread pool, so a store on a
# slow network never holds the event loop.
@router.get("/sessions/{sid}/tuning/results", operation_id="tuning_results")
def tuning_results(
    sid: str, state: StateDep, limit: int = Query(100, ge=1, le=MAX_HISTORY)
) -> list[TuningRecord]:
    """The tunings of this session's drive kept in the store (from every session and
    gateway), newest first; metadata only."""
    key = drive_key(state.manager.get(sid))
    return [TuningRecord.model_validate(r) for r in state.tuning_results.history(key, limit)]


@router.get(
    "/tuning/results/{rid}",
    operation_id="tuning_stored_result",
    response_model_exclude_unset=True,
)
def tuning_stored_result(
    rid: Annotated[str, Path(pattern=STORED_ID, description="the result's id (its list's)")],
    state: StateDep,
) -> StoredTuningResult:
    """One tuning kept in the store, with its ``TuningResult`` as it ended; 404 when the
    store has none of that id."""
    return StoredTuningResult.model_validate(state.tuning_results.get(rid))


@router.post("/sessions/{sid}/tuning/undo", operation_id="tuning_undo")
async def tuning_undo(
    sid: str, body: UndoRequest, request: Request, client: WriteControl
) -> UndoResult:
    """Gains back to before the last run or to the defaults (builtin: P11603)."""
    return UndoResult.model_validate(await _svc(request).undo(sid, client, body.to))


@router.post("/sessions/{sid}/tuning/store", operation_id="tuning_store")
async def tuning_store(
    sid: str, request: Request, client: WriteControl, body: EmptyBody | None = None
) -> TuningStored:
    """Store the parameters to non-volatile memory (only on this explicit call)."""
    return TuningStored.model_validate(await _svc(request).store(sid, client))
