"""The one WebSocket endpoint: live state, EMCY and link events of subscribed sessions."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import re
import secrets
from typing import Any

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from servodesk import __version__
from servodesk.api.control_deps import operation
from servodesk.api.identity import identity_of
from servodesk.api.state import state_of
from servodesk.errors import ServodeskError

log = logging.getLogger(__name__)

router = APIRouter()

SUBPROTOCOL = "servodesk.v1"
PROTOCOL = 1
#: Client ids as the X-Servodesk-Client header takes them.
_CLIENT_ID = re.compile(r"^[A-Za-z0-9._:@-]{1,64}$")


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
    caller = identity_of(ws).user  # Only the holder's account may bind its control.

    def sessions_msg() -> dict[str, Any]:
        return {"type": "sessions", "sessions": [s.info() for s in sessions.all()]}

    async def sender() -> None:
        await ws.send_text(
            json.dumps(
                {
                    "type": "hello",
                    "version": __version__,
                    "protocol": PROTOCOL,
                    "client": client,
                    "connection": connection,
                }
            )
        )
        await ws.send_text(json.dumps(sessions_msg()))
        while True:
            msg = await sub.queue.get()
            if msg.get("type") == "sessions_changed":
                msg = sessions_msg()
            if sub.dropped:
                msg = {**msg, "dropped": sub.dropped}
            await ws.send_text(json.dumps(msg, default=str))

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
                await ws.send_text(
                    json.dumps(
                        {"type": "error", "message": "binary frames are not read; send JSON text"}
                    )
                )
                continue
            try:
                msg = json.loads(text)
                kind, sid = msg.get("type"), msg.get("session")
            except (ValueError, AttributeError):
                await ws.send_text(json.dumps({"type": "error", "message": "not a JSON object"}))
                continue
            if kind == "subscribe" and isinstance(sid, str):
                sub.sessions.add(sid)
                with contextlib.suppress(Exception):
                    s = sessions.get(sid)
                    if s.last_state is not None:
                        from dataclasses import asdict

                        sub.offer({"type": "state", "session": sid, **asdict(s.last_state)})
            elif kind == "unsubscribe" and isinstance(sid, str):
                sub.sessions.discard(sid)
            elif kind == "heartbeat" and isinstance(sid, str):
                # Dead-man: the holder's motion runs while these arrive on a bound socket.
                control.heartbeat(connection, sid)
            elif kind == "bind" and isinstance(sid, str):
                token = msg.get("token")
                try:
                    control.bind(connection, sid, token if isinstance(token, str) else None, caller)
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
            elif kind == "ping":
                sub.offer({"type": "pong", "time": msg.get("time")})
            else:
                await ws.send_text(
                    json.dumps({"type": "error", "message": f"unknown message type {kind!r}"})
                )
    except WebSocketDisconnect:
        pass
    finally:
        send_task.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await send_task
        state.hub.unsubscribe(sub)
        control.disconnect(connection)  # The drives it was the dead-man of are made safe.
