"""Token check for servers bound to a non-loopback address.

The token comes as ``Authorization: Bearer ...``, as ``?token=...`` (WebSocket, first page
load) or from the cookie set on that first load, so the UI's own asset requests pass.
"""

from __future__ import annotations

import hmac
from http.cookies import SimpleCookie
from urllib.parse import parse_qs

from starlette.types import ASGIApp, Message, Receive, Scope, Send

COOKIE = "servodesk_token"


class TokenMiddleware:
    def __init__(self, app: ASGIApp, token: str) -> None:
        self.app = app
        self.token = token

    def _found(self, scope: Scope) -> tuple[bool, bool]:
        """(authorised, came from the query string)."""
        headers = {k.decode().lower(): v.decode() for k, v in scope.get("headers", [])}
        auth = headers.get("authorization", "")
        if auth.lower().startswith("bearer ") and hmac.compare_digest(auth[7:].strip(), self.token):
            return True, False
        query = parse_qs(scope.get("query_string", b"").decode())
        for t in query.get("token", []):
            if hmac.compare_digest(t, self.token):
                return True, True
        cookie = SimpleCookie(headers.get("cookie", ""))
        if COOKIE in cookie and hmac.compare_digest(cookie[COOKIE].value, self.token):
            return True, False
        return False, False

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        ok, from_query = self._found(scope)
        if not ok:
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 4401, "reason": "token required"})
                return
            body = (
                b'{"error":"Unauthorized","message":"this server requires a token",'
                b'"hint":"open the URL printed at start-up (it has ?token=...) or send '
                b'Authorization: Bearer <token>"}'
            )
            await send(
                {
                    "type": "http.response.start",
                    "status": 401,
                    "headers": [
                        (b"content-type", b"application/json"),
                        (b"www-authenticate", b"Bearer"),
                    ],
                }
            )
            await send({"type": "http.response.body", "body": body})
            return
        if not from_query or scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_cookie(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                headers.append(
                    (
                        b"set-cookie",
                        f"{COOKIE}={self.token}; HttpOnly; SameSite=Strict; Path=/".encode(),
                    )
                )
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_cookie)
