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
from servodesk.api.deps import AppState

log = logging.getLogger(__name__)

router = APIRouter()

SUBPROTOCOL = "servodesk.v1"
PROTOCOL = 1
#: Client ids as the X-Servodesk-Client header takes them.
_CLIENT_ID = re.compile(r"^[A-Za-z0-9._:@-]{1,64}$")


@router.websocket("/ws")
async def websocket(ws: WebSocket) -> None:
    state: AppState = ws.app.state.servodesk
    offered = ws.scope.get("subprotocols") or []
    if offered and SUBPROTOCOL not in offered:
        await ws.accept()
        await ws.close(code=4000, reason=f"this server speaks {SUBPROTOCOL}; reload the page")
        return
    await ws.accept(subprotocol=SUBPROTOCOL if offered else None)
    sub = state.hub.subscribe()
    sessions = state.manager
    # Which client this socket belongs to (?client=<id>), for control and the dead-man
    # heartbeat; a socket without one gets an id, told in the hello message.
    client = ws.query_params.get("client") or ""
    if not _CLIENT_ID.match(client):
        client = f"tab-{secrets.token_hex(4)}"
    control = operation(ws.app).control
    control.socket_opened(client)

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
            text = await ws.receive_text()
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
                # Dead-man: motion this client started runs while these arrive.
                control.heartbeat(client, sid)
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
        control.socket_closed(client)  # Stops the motion this client started.
