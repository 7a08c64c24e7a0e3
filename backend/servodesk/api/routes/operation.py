"""Homing and alarm routes (issue 4): thin wrappers over services/homing.py and alarms.py.

Starting homing goes through the motion service (services/motion/), which watches the run
with the client's dead-man heartbeat like a jog.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from servodesk.api.control_deps import MotionControl, OperationDep, WriteControl
from servodesk.api.deps import StateDep
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_homing import (
    AlarmsOut,
    ClearHistoryRequest,
    HomingMethodOut,
    HomingPlanOut,
    HomingRequest,
    HomingStatus,
)
from servodesk.services import alarms, homing

router = APIRouter(tags=["operation"], responses=ERROR_RESPONSES)


@router.get("/sessions/{sid}/homing/methods", operation_id="homing_methods")
async def homing_methods(sid: str, state: StateDep) -> list[HomingMethodOut]:
    profile = state.manager.get(sid).profile
    return [HomingMethodOut.model_validate(m) for m in homing.methods(profile)]


@router.post("/sessions/{sid}/homing", operation_id="start_homing")
async def start_homing(
    sid: str, body: HomingRequest, op: OperationDep, client: MotionControl
) -> HomingStatus:
    """Start homing; a run that moves the axis lives under the client's dead-man (a jog's)."""
    out = await op.motion.home(
        sid,
        client,
        body.method,
        speed_switch=body.speed_switch,
        speed_zero=body.speed_zero,
        acceleration=body.acceleration,
        offset=body.offset,
        max_travel=body.max_travel,
        timeout_s=body.timeout_s,
    )
    return HomingStatus.model_validate(out)


U32 = 0xFFFFFFFF


@router.get("/sessions/{sid}/homing/plan", operation_id="homing_plan")
async def homing_plan(
    sid: str,
    op: OperationDep,
    method: Annotated[int, Query(ge=-128, le=127)],
    speed_switch: Annotated[int | None, Query(ge=0, le=U32)] = None,
    speed_zero: Annotated[int | None, Query(ge=0, le=U32)] = None,
    acceleration: Annotated[int | None, Query(ge=0, le=U32)] = None,
    max_travel: Annotated[int | None, Query(gt=0, le=U32)] = None,
    timeout_s: Annotated[float | None, Query(gt=0, le=86400)] = None,
) -> HomingPlanOut:
    """The estimate and the time-out a run with these settings would get (reads the drive's
    speeds where none are given; writes nothing, needs no control)."""
    session = op.motion.manager.get(sid)
    lim = await op.motion.limits(sid)
    p = await homing.plan(
        session,
        method,
        speed_switch=speed_switch,
        speed_zero=speed_zero,
        acceleration=acceleration,
        max_travel=max_travel,
        timeout_s=timeout_s,
        limits=(lim.position_min, lim.position_max),
    )
    return HomingPlanOut.model_validate(p.as_dict())


@router.get("/sessions/{sid}/homing", operation_id="homing_status")
async def homing_status(sid: str, state: StateDep) -> HomingStatus:
    return HomingStatus.model_validate(await homing.status(state.manager.get(sid)))


@router.get("/sessions/{sid}/alarms", operation_id="get_alarms")
async def get_alarms(sid: str, state: StateDep) -> AlarmsOut:
    return AlarmsOut.model_validate(await alarms.alarms(state.manager.get(sid)))


@router.post("/sessions/{sid}/alarms/reset", operation_id="reset_alarms")
async def reset_alarms(sid: str, state: StateDep, client: WriteControl) -> AlarmsOut:
    out = AlarmsOut.model_validate(await alarms.reset(state.manager.get(sid), client=client))
    state.audit.record("write.alarm_reset", drive=sid, details={"client": client})
    return out


@router.post("/sessions/{sid}/alarms/clear-history", operation_id="clear_alarm_history")
async def clear_alarm_history(
    sid: str, body: ClearHistoryRequest, state: StateDep, client: WriteControl
) -> AlarmsOut:
    session = state.manager.get(sid)
    out = AlarmsOut.model_validate(await alarms.clear_history(session, body.confirm, client))
    state.audit.record("write.alarm_history_cleared", drive=sid, details={"client": client})
    return out
