"""Operation routes: control ownership, motion (jog, move, velocity, torque, cyclic), limits.

AppState (api/state.py) stops every running motion when the backend shuts down, after the
tuning jobs and before the scope, the viewer and the sessions.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request

from servodesk.api.control_deps import (
    ClientId,
    ControlToken,
    MotionControl,
    OperationDep,
    RequiredClientId,
)
from servodesk.api.identity import caller_of
from servodesk.api.rights import demand
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_motion import (
    ControlOut,
    ControlRequest,
    CyclicMotionRequest,
    JogRequest,
    LimitsOut,
    MotionStatusOut,
    MoveRequest,
    StopRequest,
    TorqueRequest,
    VelocityRequest,
)
from servodesk.domain.roles import Right

router = APIRouter(tags=["operation"], responses=ERROR_RESPONSES)


def _status(d: dict[str, Any]) -> MotionStatusOut:
    return MotionStatusOut.model_validate(d)


@router.get("/sessions/{sid}/control", operation_id="get_control")
async def get_control(sid: str, op: OperationDep, token: ControlToken) -> ControlOut:
    op.motion.manager.get(sid)  # 404 for an unknown session.
    return ControlOut.model_validate(
        {**op.control.info(sid, token), "protection": op.motion.protection(sid)}
    )


@router.post("/sessions/{sid}/control", operation_id="set_control")
async def set_control(
    sid: str,
    body: ControlRequest,
    op: OperationDep,
    client: RequiredClientId,
    token: ControlToken,
    request: Request,
) -> ControlOut:
    """Take, release or force-take control. Taking answers with the control token (only to
    the taker): send it as ``X-Servodesk-Control`` with every request that changes the drive,
    and bind a WebSocket with it for the dead-man. Control belongs to the caller's account:
    another user is refused (409 naming the holder); only an administrator (the
    ``force_control`` right) may force-take it from another user."""
    op.motion.manager.get(sid)
    who = caller_of(request)
    if body.action == "take":
        token = op.control.take(sid, client, token, who.user)
    elif body.action == "release":
        op.control.release(sid, token)
    else:
        holder = op.control.holder_user(sid)
        if holder is not None and holder != who.user:
            demand(who, Right.FORCE_CONTROL)
        token = op.control.force_take(sid, client, body.confirm, token, who.user)
    return ControlOut.model_validate(
        {**op.control.info(sid, token), "protection": op.motion.protection(sid)}
    )


@router.post("/sessions/{sid}/motion/jog", operation_id="jog")
async def jog(
    sid: str, body: JogRequest, op: OperationDep, client: MotionControl
) -> MotionStatusOut:
    return _status(await op.motion.jog(sid, client, body.velocity, body.acceleration))


@router.post("/sessions/{sid}/motion/move", operation_id="move")
async def move(
    sid: str, body: MoveRequest, op: OperationDep, client: MotionControl
) -> MotionStatusOut:
    return _status(
        await op.motion.move(
            sid,
            client,
            relative=body.mode == "relative",
            target=body.target,
            velocity=body.velocity,
            acceleration=body.acceleration,
            deceleration=body.deceleration,
            immediate=body.immediate,
        )
    )


@router.post("/sessions/{sid}/motion/velocity", operation_id="run_velocity")
async def run_velocity(
    sid: str, body: VelocityRequest, op: OperationDep, client: MotionControl
) -> MotionStatusOut:
    return _status(
        await op.motion.velocity(sid, client, body.velocity, body.acceleration, body.deceleration)
    )


@router.post("/sessions/{sid}/motion/torque", operation_id="run_torque")
async def run_torque(
    sid: str, body: TorqueRequest, op: OperationDep, client: MotionControl
) -> MotionStatusOut:
    return _status(await op.motion.torque(sid, client, body.torque, body.slope))


@router.post("/sessions/{sid}/motion/cyclic", operation_id="run_cyclic")
async def run_cyclic(
    sid: str, body: CyclicMotionRequest, op: OperationDep, client: MotionControl
) -> MotionStatusOut:
    return _status(
        await op.motion.cyclic(
            sid,
            client,
            mode_name=body.mode,
            waveform=body.waveform,
            amplitude=body.amplitude,
            frequency=body.frequency,
            duration=body.duration,
        )
    )


@router.post("/sessions/{sid}/motion/halt", operation_id="halt")
async def halt(
    sid: str, op: OperationDep, client: ClientId, body: StopRequest | None = None
) -> MotionStatusOut:
    """Halt (controlword bit 8): never refused, from any client."""
    return _status(await op.motion.halt(sid, client))


@router.post("/sessions/{sid}/motion/stop", operation_id="quick_stop")
async def quick_stop(
    sid: str, op: OperationDep, client: ClientId, body: StopRequest | None = None
) -> MotionStatusOut:
    """Quick stop: never refused, from any client."""
    return _status(await op.motion.stop(sid, client))


@router.get("/sessions/{sid}/motion", operation_id="get_motion")
async def get_motion(sid: str, op: OperationDep) -> MotionStatusOut:
    return _status(op.motion.status(sid))


@router.get("/sessions/{sid}/limits", operation_id="get_limits")
async def get_limits(sid: str, op: OperationDep) -> LimitsOut:
    lim = await op.motion.limits(sid)
    return LimitsOut.model_validate(lim.as_dict())
