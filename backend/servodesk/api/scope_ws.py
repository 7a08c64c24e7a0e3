"""The scope's binary WebSocket, ``/api/v1/scope/ws`` (subprotocol ``servodesk.scope.v1``).

Frames are docs/scope.md's wire format (domain/scope_wire.py): samples, captures and status.
Each socket gets its own :class:`~servodesk.services.scope.ScopeClient` queue; this module's
sender task is the only thing that awaits the socket, so a client that reads slowly (or not
at all) fills only its own queue, whose oldest frames are then dropped and counted. The token
check of api/auth.py applies as to every WebSocket (the middleware sees the upgrade request).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging

from fastapi import APIRouter, WebSocket, WebSocketDisconnect

from servodesk.api.routes.scope import scope_of
from servodesk.domain.scope_wire import SUBPROTOCOL

log = logging.getLogger(__name__)

router = APIRouter()


@router.websocket("/scope/ws")
async def scope_socket(ws: WebSocket) -> None:
    offered = ws.scope.get("subprotocols") or []
    if offered and SUBPROTOCOL not in offered:
        await ws.accept()
        await ws.close(code=4000, reason=f"this server speaks {SUBPROTOCOL}; reload the page")
        return
    await ws.accept(subprotocol=SUBPROTOCOL if offered else None)
    service = scope_of(ws.app)
    client = service.connect()

    async def sender() -> None:
        while not client.closed:
            frame = await client.get()
            if frame is None:
                break
            await ws.send_bytes(frame)
        with contextlib.suppress(Exception):
            await ws.close(code=1001, reason="servodesk is shutting down")

    send_task = asyncio.create_task(sender(), name="scope ws sender")
    try:
        while True:
            # Nothing is expected from the client; reading tells when it goes away.
            msg = await ws.receive()
            if msg["type"] == "websocket.disconnect":
                break
    except WebSocketDisconnect:
        pass
    finally:
        service.disconnect(client)
        send_task.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await send_task
