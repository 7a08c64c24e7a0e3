"""Taking control of a drive in tests (docs/api.md "Control and motion as built").

Every request that changes a drive needs the control token in ``X-Servodesk-Control``; servo
on, controlword writes, motion, homing and tuning start also need a WebSocket bound as the
dead-man. Tests on a WebSocket-capable Starlette ``TestClient`` use tests/operation/support.py
(``take``, ``bind``, ``take_and_enable``). These helpers serve the rest:

- :func:`take_control` / :func:`take_control_sync`: take control once and put the token on
  the client's default headers, so every later request of the client carries it.
- :func:`bind_in_process`: where an httpx ``AsyncClient`` on ``ASGITransport`` (which cannot
  open WebSockets) must switch the servo on, register a connection with the app's control
  service and bind it, as a WebSocket would (tests/operation/test_deadman.py does the same).
  It sends no heartbeats: only running motion needs them.
"""

from __future__ import annotations

from typing import Any

import httpx

from servodesk.api.control_deps import operation

CLIENT_HEADER = "X-Servodesk-Client"
CONTROL_HEADER = "X-Servodesk-Control"


def _control_url(client: httpx.AsyncClient | Any, sid: str) -> str:
    """The control route, relative to a client whose base URL may already end in /api/v1."""
    base = str(client.base_url).rstrip("/")
    prefix = "" if base.endswith("/api/v1") else "/api/v1"
    return f"{prefix}/sessions/{sid}/control"


async def take_control(client: httpx.AsyncClient, sid: str, who: str = "test-client") -> str:
    """Take control of ``sid`` as ``who``; the token, also set on ``client``'s headers.

    A client that already holds other sessions sends its token along and gets the same one
    back (one token per client), so this may be called for several sessions."""
    r = await client.post(
        _control_url(client, sid), json={"action": "take"}, headers={CLIENT_HEADER: who}
    )
    assert r.status_code == 200, r.text
    token: str = r.json()["token"]
    assert token
    client.headers[CONTROL_HEADER] = token
    return token


def take_control_sync(client: Any, sid: str, who: str = "test-client") -> str:
    """:func:`take_control` for a synchronous client (Starlette's ``TestClient``)."""
    r = client.post(
        _control_url(client, sid), json={"action": "take"}, headers={CLIENT_HEADER: who}
    )
    assert r.status_code == 200, r.text
    token: str = r.json()["token"]
    assert token
    client.headers[CONTROL_HEADER] = token
    return token


def bind_in_process(app: Any, sid: str, token: str, who: str = "test-client") -> str:
    """Bind an in-process connection as the dead-man of ``token``'s control of ``sid``; its
    connection id (``operation(app).control.disconnect(cid)`` is the socket closing)."""
    control = operation(app).control
    cid = control.connect(who)
    control.bind(cid, sid, token)
    return cid
