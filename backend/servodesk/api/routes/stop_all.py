"""The global stop: one request quick-stops every axis the caller controls (issue 48).

The header's STOP ALL button and its keyboard shortcut (docs/ui.md "Global stop") send
``POST /motion/stop-all``. It is the per-session quick stop (``motion/stop``: controlword
"quick stop", CiA 402-2 §6.2 transitions 7, 10, 11, the drive ramps down with its quick-stop
ramp 6085h) sent to every open session whose control belongs to the caller's account, from
any of its tabs or scripts (services/control.py: control belongs to a user). Like every stop
it is never refused for lack of control (docs/safety.md): it needs only the ``read`` right
(api/rights.py), and it takes no control token.

The stops go out concurrently: a drive that answers slowly (an SDO time-out, a link being
re-established) never delays the stop of the next one. The answer waits at most
:data:`ANSWER_WAIT_S`; a stop still under way then is reported ``pending`` and goes on in the
background until the drive answers or its link gives up (it is never cancelled).
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any, Literal

from fastapi import APIRouter, Request
from pydantic import BaseModel, Field

from servodesk.api.control_deps import ClientId, OperationDep
from servodesk.api.identity import caller_of
from servodesk.api.schemas import ERROR_RESPONSES
from servodesk.api.schemas_motion import MotionStatusOut
from servodesk.errors import ServodeskError

log = logging.getLogger(__name__)

router = APIRouter(tags=["operation"], responses=ERROR_RESPONSES)

#: How long the answer waits for the drives (s). Longer than an SDO round trip with its
#: retries on a healthy link, short enough that the person sees at once which axes answered.
ANSWER_WAIT_S = 2.0

#: Stops still running after the answer went: kept referenced until they end (an unreferenced
#: task may be collected before it finishes).
_BACKGROUND: set[asyncio.Task[dict[str, Any]]] = set()


class StopAllItem(BaseModel):
    session: str
    result: Literal["stopped", "failed", "pending"] = Field(
        description="stopped: the quick stop was sent and the motion ended; failed: the drive "
        "could not be reached (message says why); pending: still being sent when the answer "
        f"went ({ANSWER_WAIT_S:g} s), it goes on"
    )
    motion: MotionStatusOut | None = None
    message: str | None = None
    hint: str | None = None


class StopAllOut(BaseModel):
    user: str = Field(description="the account whose axes were stopped")
    sessions: list[StopAllItem] = Field(
        description="every session whose control the caller's account holds, in session order"
    )
    stopped: int
    failed: int
    pending: int


def _late(task: asyncio.Task[dict[str, Any]]) -> None:
    """A stop that outlived the answer ended: its failure goes to the log."""
    if not task.cancelled() and task.exception() is not None:
        log.error("a stop-all quick stop that outlived its answer failed: %s", task.exception())


@router.post("/motion/stop-all", operation_id="stop_all")
async def stop_all(request: Request, op: OperationDep, client: ClientId) -> StopAllOut:
    """Quick stop every axis the caller's account holds control of, all at once: never
    refused, no control token needed. Per session: stopped, failed (why) or pending."""
    who = caller_of(request)
    label = f"stop all from {client or 'unknown'}"
    sids = [s.id for s in op.motion.manager.all() if op.control.holder_user(s.id) == who.user]
    tasks = {sid: asyncio.create_task(op.motion.stop(sid, label)) for sid in sids}
    for task in tasks.values():
        # Referenced until it ends, even when this request is cancelled (the client left).
        _BACKGROUND.add(task)
        task.add_done_callback(_BACKGROUND.discard)
    if tasks:
        await asyncio.wait(tasks.values(), timeout=ANSWER_WAIT_S)
    items: list[StopAllItem] = []
    for sid, task in tasks.items():
        if not task.done():
            task.add_done_callback(_late)
            items.append(
                StopAllItem(
                    session=sid,
                    result="pending",
                    message=f"the drive did not answer within {ANSWER_WAIT_S:g} s; "
                    "the quick stop is still being sent",
                    hint="watch the axis; stop it at the machine if it keeps moving",
                )
            )
            continue
        exc = task.exception()
        if exc is None:
            items.append(
                StopAllItem(
                    session=sid,
                    result="stopped",
                    motion=MotionStatusOut.model_validate(task.result()),
                )
            )
        elif isinstance(exc, ServodeskError):
            items.append(
                StopAllItem(session=sid, result="failed", message=exc.message, hint=exc.hint)
            )
        else:
            log.error("stop-all of %s failed", sid, exc_info=exc)
            items.append(
                StopAllItem(
                    session=sid,
                    result="failed",
                    message=f"{type(exc).__name__}: {exc}",
                    hint="stop the axis at the machine (QUICK STOP or the emergency stop)",
                )
            )
    return StopAllOut(
        user=who.user,
        sessions=items,
        stopped=sum(i.result == "stopped" for i in items),
        failed=sum(i.result == "failed" for i in items),
        pending=sum(i.result == "pending" for i in items),
    )
