"""FastAPI dependencies for control: who may change a drive, who may energise and move it.

The rules live in :mod:`servodesk.services.control`; here they are applied to requests. The
authority is the control token (``X-Servodesk-Control``) that taking control returned; the
client id (``X-Servodesk-Client``) is only a label. Every route that changes a drive takes
:data:`WriteControl` (controlword writes: also the dead-man), the state route
:data:`StateControl` (servo on: also the dead-man; quick stop is never refused), motion,
homing and tuning :data:`MotionControl` (control and a bound WebSocket). Each is refused with
409 naming the holder and nothing reaches the bus.
"""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import Depends, Header, Request

from servodesk.api.identity import caller_of
from servodesk.api.state import AppState, state_of
from servodesk.domain.address import ObjectAddress
from servodesk.errors import ValidationError
from servodesk.services.control import CONTROL_HEADER

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


def operation(app: Any) -> AppState:
    """The application's state (api/state.py), for its control and motion services
    (``operation(app).control``, ``.motion``): it builds and stops them."""
    return state_of(app)


def get_operation(request: Request) -> AppState:
    return state_of(request.app)


OperationDep = Annotated[AppState, Depends(get_operation)]


#: The control token ``take`` returned: the authority for every request that changes a drive.
ControlHeader = Annotated[
    str | None,
    Header(
        alias=CONTROL_HEADER,
        max_length=64,
        pattern=r"^[A-Za-z0-9_-]+$",
        description="The control token POST /control returned (take / force_take)",
    ),
]

#: Writes of these objects energise or command the drive directly (CiA 402-2 §6.2.1: the
#: controlword's enable bits): they need the dead-man like servo on does.
_ENERGISING_OBJECTS = {0x6040}
#: State commands that lead towards Switched on / Operation enabled (CiA 402-2 §6.2, figure 9
#: transitions 3, 4, 16) or walk there: power on the motor, so they need the dead-man.
_ENERGISING_COMMANDS = {"switch_on", "switch_on_enable", "enable_operation", "enable"}


def _label(client: str | None, holder: str) -> str:
    """The audit log's name for the request: the holder's label (it presented the token)."""
    return holder if not client or client == holder else f"{holder} (as {client})"


def _user(request: Request) -> str:
    """The account of the request: control is held by a user, and only their requests may
    use its token (api/identity.py)."""
    return caller_of(request).user


def _energising_write(request: Request) -> bool:
    raw = request.path_params.get("address")
    if not isinstance(raw, str):
        return False
    try:
        return ObjectAddress.parse(raw).index in _ENERGISING_OBJECTS
    except (ValueError, ValidationError):
        return False  # The route answers the bad address itself.


async def require_write(
    sid: str,
    request: Request,
    x_servodesk_client: ClientHeader = None,
    x_servodesk_control: ControlHeader = None,
) -> AsyncIterator[str]:
    """The write needs control (the controlword also the dead-man); re-read limits after it."""
    op = operation(request.app)
    if _energising_write(request):
        label = await _energise(
            sid, request, x_servodesk_client, x_servodesk_control, "writing the controlword"
        )
    else:
        op.motion.manager.get(sid)  # An unknown session is a 404 before anything else.
        holder = op.control.check(sid, x_servodesk_control, "this write", _user(request))
        label = _label(x_servodesk_client, holder)
    op.motion.invalidate_limits(sid)
    try:
        yield label
    finally:
        op.motion.invalidate_limits(sid)


async def require_state_command(
    sid: str,
    request: Request,
    x_servodesk_client: ClientHeader = None,
    x_servodesk_control: ControlHeader = None,
) -> AsyncIterator[str]:
    """State commands need control, servo on the dead-man too; quick stop is never refused."""
    command = None
    with contextlib.suppress(Exception):  # A bad body is the route's 422, not ours.
        body = await request.json()
        command = body.get("command") if isinstance(body, dict) else None
    op = operation(request.app)
    if command == "quick_stop":
        yield x_servodesk_client or "unknown"
        return
    if command in _ENERGISING_COMMANDS:
        yield await _energise(sid, request, x_servodesk_client, x_servodesk_control, f"{command!r}")
        return
    op.motion.manager.get(sid)  # An unknown session is a 404 before anything else.
    holder = op.control.check(sid, x_servodesk_control, f"{command!r}", _user(request))
    yield _label(x_servodesk_client, holder)


async def require_close(
    sid: str,
    request: Request,
    x_servodesk_client: ClientHeader = None,
    x_servodesk_control: ControlHeader = None,
) -> AsyncIterator[str | None]:
    """Closing a session someone holds needs their control; its motion stops first."""
    op = operation(request.app)
    if op.control.owner(sid) is not None:
        op.control.check(sid, x_servodesk_control, "closing the session", _user(request))
    await op.motion.stop_session(sid, "the session is being closed")
    try:
        yield x_servodesk_client
    finally:
        op.control.forget_session(sid)


async def _energise(
    sid: str, request: Request, client: str | None, token: str | None, what: str
) -> str:
    """Control and a bound, open WebSocket (the dead-man), once the drive is made safe after
    a lost holder (MotionService.settled)."""
    op = operation(request.app)
    op.motion.manager.get(sid)  # An unknown session is a 404 before anything else.
    holder = op.control.check_energise(sid, token, what, _user(request))
    await op.motion.settled(sid)
    return _label(client, holder)


async def require_motion(
    sid: str,
    request: Request,
    x_servodesk_client: ClientHeader = None,
    x_servodesk_control: ControlHeader = None,
) -> str:
    """Motion (jog, moves, homing, tuning) needs control and the dead-man."""
    return await _energise(sid, request, x_servodesk_client, x_servodesk_control, "motion")


async def require_energise(
    sid: str,
    request: Request,
    x_servodesk_client: ClientHeader = None,
    x_servodesk_control: ControlHeader = None,
) -> str:
    """Process data servodesk produces (cyclic outputs: the controlword, the targets) can
    energise and move the drive like the controlword written by SDO: control and the
    dead-man; the limits are read again after it."""
    label = await _energise(sid, request, x_servodesk_client, x_servodesk_control, "cyclic outputs")
    operation(request.app).motion.invalidate_limits(sid)
    return label


def control_token(x_servodesk_control: ControlHeader = None) -> str | None:
    return x_servodesk_control


def client_id(x_servodesk_client: ClientHeader = None) -> str | None:
    return x_servodesk_client


def required_client_id(x_servodesk_client: RequiredClientHeader) -> str:
    return x_servodesk_client


WriteControl = Annotated[str, Depends(require_write, scope="function")]
StateControl = Annotated[str, Depends(require_state_command, scope="function")]
CloseControl = Annotated[str | None, Depends(require_close, scope="function")]
MotionControl = Annotated[str, Depends(require_motion)]
EnergiseControl = Annotated[str, Depends(require_energise)]
ClientId = Annotated[str | None, Depends(client_id)]
RequiredClientId = Annotated[str, Depends(required_client_id)]
ControlToken = Annotated[str | None, Depends(control_token)]
