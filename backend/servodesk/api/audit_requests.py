"""The audit log's view of requests: who is acting, and every request refused.

Outermost of the ASGI middleware (api/app.py), so it sees what the request checks inside it
refuse (Host, Origin, token or login, body size) as well as what the routes answer:

- It makes the request's caller the actor of every audit record made while the request (or a
  task it starts) runs: :func:`servodesk.services.audit.acting` with an identity read lazily,
  when a record is made, since the authentication middleware inside this one sets it
  (api/identity.py).
- Every answer with status 400-599, and every WebSocket closed with 4000-4999, is recorded
  as ``request.refused`` (IEC 62443-4-2 CR 2.8, "request errors") with its status, method and
  path: never the query string, the body or a header, which may carry a token or a password.
"""

from __future__ import annotations

from typing import Any

from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from servodesk.api.identity import caller_of
from servodesk.services.audit import AuditLog, as_actor

#: Paths longer than this are cut in the record (a 8 KiB URL must not fill the log).
MAX_PATH = 200


class _Caller:
    """The identity of a request, read when a record needs it (the auth middleware inside
    this one sets it after this one started)."""

    __slots__ = ("_conn",)

    def __init__(self, scope: Scope) -> None:
        self._conn = HTTPConnection(scope)

    @property
    def user(self) -> str:
        return caller_of(self._conn).user

    @property
    def address(self) -> str:
        return caller_of(self._conn).address


class AuditRequests:
    def __init__(self, app: ASGIApp, audit: AuditLog) -> None:
        self.app = app
        self.audit = audit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        caller = _Caller(scope)
        status: list[int] = []

        async def watch(message: Message) -> None:
            kind = message["type"]
            if kind == "http.response.start":
                status.append(int(message["status"]))
            elif kind == "websocket.close" and 4000 <= int(message.get("code", 1000)) <= 4999:
                status.append(int(message["code"]) - 4000)
            await send(message)

        with as_actor(caller):
            try:
                await self.app(scope, receive, watch)
            except Exception:
                if not status:
                    status.append(500)  # ServerErrorMiddleware (outside this one) answers.
                raise
            finally:
                if status and 400 <= status[0] <= 599:
                    self._refused(scope, caller, status[0])

    def _refused(self, scope: Scope, caller: _Caller, status: int) -> None:
        path = str(scope.get("path", ""))
        details: dict[str, Any] = {
            "status": status,
            "method": "WEBSOCKET" if scope["type"] == "websocket" else scope.get("method", ""),
            "path": path[:MAX_PATH] + ("..." if len(path) > MAX_PATH else ""),
        }
        self.audit.record(
            "request.refused",
            who=caller,
            ok=False,
            message=f"{status} {details['method']} {details['path']}",
            details=details,
        )
