"""FastAPI dependencies for control ownership: who may write, who may move the axis.

The rules live in :mod:`servodesk.services.control`; here they are applied to requests. A
client names itself with the ``X-Servodesk-Client`` header. Mutating session routes take
:data:`WriteControl` (refused with 409 naming the owner when another client holds control),
the state route :data:`StateControl` (quick stop is never refused), motion routes
:data:`MotionControl` (control and a live WebSocket needed).
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import Depends, Header, Request

from servodesk.api.deps import AppState
from servodesk.services.control import ControlService
from servodesk.services.motion import MotionService

#: The client id header: any printable id up to 64 characters (a tab's random id).
ClientHeader = Annotated[
    str | None,
    Header(
        max_length=64,
        pattern=r"^[A-Za-z0-9._:@-]+$",
        description="Id of the client (browser tab or script) making the request",
    ),
]
#: The same header where the route cannot work without it (control, motion).
RequiredClientHeader = Annotated[
    str,
    Header(
        max_length=64,
        pattern=r"^[A-Za-z0-9._:@-]+$",
        description="Id of the client (browser tab or script): the one its WebSocket uses",
    ),
]


@dataclass
class Operation:
    control: ControlService
    motion: MotionService


def operation(app: Any) -> Operation:
    """The application's control and motion services (created on first use)."""
    op: Operation | None = getattr(app.state, "servodesk_operation", None)
    if op is None:
        state: AppState = app.state.servodesk
        control = ControlService(state.hub)
        motion = MotionService(
            state.manager,
            control,
            state.hub,
            deadman_s=state.settings.deadman_ms / 1000.0,
        )
        op = Operation(control, motion)
        app.state.servodesk_operation = op
    return op


def get_operation(request: Request) -> Operation:
    return operation(request.app)


OperationDep = Annotated[Operation, Depends(get_operation)]


async def require_write(
    sid: str, request: Request, x_servodesk_client: ClientHeader = None
) -> AsyncIterator[str | None]:
    """Refuse the write when another client holds control; re-read limits after it."""
    op = operation(request.app)
    op.control.check_write(sid, x_servodesk_client)
    op.motion.invalidate_limits(sid)
    try:
        yield x_servodesk_client
    finally:
        op.motion.invalidate_limits(sid)


async def require_state_command(
    sid: str, request: Request, x_servodesk_client: ClientHeader = None
) -> AsyncIterator[str | None]:
    """Like :func:`require_write`, except that quick stop is never refused."""
    command = None
    with contextlib.suppress(Exception):  # A bad body is the route's 422, not ours.
        body = await request.json()
        command = body.get("command") if isinstance(body, dict) else None
    if command != "quick_stop":
        operation(request.app).control.check_write(sid, x_servodesk_client)
    yield x_servodesk_client


async def require_close(
    sid: str, request: Request, x_servodesk_client: ClientHeader = None
) -> AsyncIterator[str | None]:
    """Closing a session someone else controls is refused; its motion stops first."""
    op = operation(request.app)
    op.control.check_write(sid, x_servodesk_client)
    await op.motion.stop_session(sid, "the session is being closed")
    try:
        yield x_servodesk_client
    finally:
        op.control.forget_session(sid)


def require_motion(sid: str, request: Request, x_servodesk_client: RequiredClientHeader) -> str:
    """Motion needs control and a live WebSocket of the same client."""
    op = operation(request.app)
    op.motion.manager.get(sid)  # An unknown session is a 404 before anything else.
    return op.control.check_motion(sid, x_servodesk_client)


def client_id(x_servodesk_client: ClientHeader = None) -> str | None:
    return x_servodesk_client


def required_client_id(x_servodesk_client: RequiredClientHeader) -> str:
    return x_servodesk_client


WriteControl = Annotated[str | None, Depends(require_write, scope="function")]
StateControl = Annotated[str | None, Depends(require_state_command, scope="function")]
CloseControl = Annotated[str | None, Depends(require_close, scope="function")]
MotionControl = Annotated[str, Depends(require_motion)]
ClientId = Annotated[str | None, Depends(client_id)]
RequiredClientId = Annotated[str, Depends(required_client_id)]
