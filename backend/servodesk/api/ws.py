"""The one WebSocket endpoint: live state, EMCY and link events of subscribed sessions.

Every message goes out through :func:`_send`, which validates it against ``ServerMessage``
(api/ws_messages.py): a message that is not in that union is logged and not sent. Client
frames are read as ``ClientMessage``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import re
import secrets
from collections.abc import Mapping
from dataclasses import asdict
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect
from pydantic import ValidationError

from servodesk import __version__
from servodesk.api.control_deps import operation
from servodesk.api.identity import caller_of
from servodesk.api.state import state_of
from servodesk.api.ws_messages import (
    BindRequest,
    HeartbeatMessage,
    PingMessage,
    RefusedMessage,
    SubscribeMessage,
    UnsubscribeMessage,
    decode,
    encode,
)
from servodesk.errors import ServodeskError

log = logging.getLogger(__name__)

router = APIRouter()

SUBPROTOCOL = "servodesk.v1"
PROTOCOL = 1
#: Client ids as the X-Servodesk-Client header takes them.
_CLIENT_ID = re.compile(r"^[A-Za-z0-9._:@-]{1,64}$")


async def _send(ws: WebSocket, msg: Mapping[str, Any]) -> None:
    """Send ``msg`` if it is a ``ServerMessage``; log and drop it otherwise (its publisher
    has a bug, and the socket carries on: one bad message must not cut a holder's dead-man)."""
    try:
        text = encode(msg)
    except RefusedMessage as exc:
        log.error("WebSocket message not sent: %s", exc)
        return
    await ws.send_text(text)


def _unreadable(exc: ValidationError) -> str:
    """A client frame's validation error for the person who sent it, in one line."""
    first = exc.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    return f"{where}: {first['msg']}" if where else first["msg"]


@router.websocket("/ws")
async def websocket(ws: WebSocket) -> None:
    state = state_of(ws.app)
    offered = ws.scope.get("subprotocols") or []
    if offered and SUBPROTOCOL not in offered:
        await ws.accept()
        await ws.close(code=4000, reason=f"this server speaks {SUBPROTOCOL}; reload the page")
        return
    await ws.accept(subprotocol=SUBPROTOCOL if offered else None)
    sub = state.hub.subscribe()
    sessions = state.manager
    # The label of the client this socket belongs to (?client=<id>), for people; a socket
    # without one gets one, told in the hello message. It gives no authority: the socket
    # becomes a holder's dead-man only by binding with the control token (services/control).
    client = ws.query_params.get("client") or ""
    if not _CLIENT_ID.match(client):
        client = f"tab-{secrets.token_hex(4)}"
    control = operation(ws.app).control
    connection = control.connect(client)
    caller = caller_of(ws).user  # Only the holder's account may bind its control.

    def sessions_msg() -> dict[str, Any]:
        return {"type": "sessions", "sessions": [s.info() for s in sessions.all()]}

    async def sender() -> None:
        await _send(
            ws,
            {
                "type": "hello",
                "version": __version__,
                "protocol": PROTOCOL,
                "client": client,
                "connection": connection,
            },
        )
        await _send(ws, sessions_msg())
        while True:
            msg = await sub.queue.get()
            if msg.get("type") == "sessions_changed":  # The hub's signal, not a message.
                msg = sessions_msg()
            if sub.dropped:
                msg = {**msg, "dropped": sub.dropped}
            await _send(ws, msg)

    send_task = asyncio.create_task(sender())
    try:
        while True:
            frame = await ws.receive()
            if frame["type"] == "websocket.disconnect":
                break
            text = frame.get("text")
            if text is None:
                # A binary frame (receive_text() would fail on it with a KeyError and drop
                # the socket): the protocol is JSON text frames; say so and keep the socket.
                await _send(
                    ws, {"type": "error", "message": "binary frames are not read; send JSON text"}
                )
                continue
            try:
                data = json.loads(text)
            except ValueError:
                data = None
            if not isinstance(data, dict):
                await _send(ws, {"type": "error", "message": "not a JSON object"})
                continue
            try:
                msg = decode(data)
            except ValidationError as exc:
                kind = data.get("type")
                tag = {"union_tag_invalid", "union_tag_not_found"}
                known = not any(e["type"] in tag for e in exc.errors())
                why = f"{kind!r}: {_unreadable(exc)}" if known else f"unknown message type {kind!r}"
                await _send(ws, {"type": "error", "message": why})
                continue
            if isinstance(msg, SubscribeMessage):
                sub.sessions.add(msg.session)
                with contextlib.suppress(Exception):
                    s = sessions.get(msg.session)
                    if s.last_state is not None:
                        sub.offer({"type": "state", "session": msg.session, **asdict(s.last_state)})
            elif isinstance(msg, UnsubscribeMessage):
                sub.sessions.discard(msg.session)
            elif isinstance(msg, HeartbeatMessage):
                # Dead-man: the holder's motion runs while these arrive on a bound socket.
                control.heartbeat(connection, msg.session)
            elif isinstance(msg, BindRequest):
                sid = msg.session
                try:
                    control.bind(connection, sid, msg.token, caller)
                except ServodeskError as exc:
                    sub.offer(
                        {
                            "type": "bind",
                            "session": sid,
                            "ok": False,
                            "message": exc.message,
                            "hint": exc.hint,
                        }
                    )
                else:
                    sub.offer({"type": "bind", "session": sid, "ok": True})
            elif isinstance(msg, PingMessage):
                sub.offer({"type": "pong", "time": msg.time})
    except WebSocketDisconnect:
        pass
    finally:
        send_task.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await send_task
        state.hub.unsubscribe(sub)
        control.disconnect(connection)  # The drives it was the dead-man of are made safe.
