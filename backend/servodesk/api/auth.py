"""Token check for servers bound to a non-loopback address.

The token comes as ``Authorization: Bearer ...``, as ``?token=...`` (WebSocket, first page
load) or from the cookie set on that first load, so the UI's own asset requests pass.

Everything before the check works on the raw bytes of the ASGI scope and compares bytes
with ``hmac.compare_digest``: a header that is not UTF-8, or a token that is not ASCII
(which ``compare_digest`` refuses as ``str``), is a wrong token (401), never a 500.
"""

from __future__ import annotations

import hmac
from http.cookies import CookieError, SimpleCookie
from urllib.parse import unquote_to_bytes

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from servodesk.api.errors import refuse_websocket, send_error
from servodesk.errors import Unauthorized

COOKIE = "servodesk_token"


def _query(raw: bytes) -> list[tuple[bytes, bytes]]:
    """The query string's parameters, percent-decoded to bytes (never to text, where "%C3%A9"
    or "%FF" would fail: parse_qsl on bytes can only give ASCII back)."""
    out = []
    for part in raw.split(b"&"):
        key, _, value = part.partition(b"=")
        out.append(
            (unquote_to_bytes(key.replace(b"+", b" ")), unquote_to_bytes(value.replace(b"+", b" ")))
        )
    return out


class TokenMiddleware:
    def __init__(self, app: ASGIApp, token: str) -> None:
        self.app = app
        self.token = token
        self._token = token.encode("utf-8")

    def _is_token(self, candidate: bytes) -> bool:
        return hmac.compare_digest(candidate, self._token)

    def _found(self, scope: Scope) -> tuple[bool, bool]:
        """(authorised, came from the query string)."""
        auth, cookie = b"", b""
        for name, value in scope.get("headers", []):
            key = name.lower()
            if key == b"authorization":
                auth = value
            elif key == b"cookie":
                cookie = value
        if auth[:7].lower() == b"bearer " and self._is_token(auth[7:].strip()):
            return True, False
        for key, value in _query(scope.get("query_string", b"")):
            if key == b"token" and self._is_token(value):
                return True, True
        if cookie:
            try:
                jar = SimpleCookie(cookie.decode("latin-1"))
            except CookieError:
                jar = SimpleCookie()
            if COOKIE in jar and self._is_token(jar[COOKIE].value.encode("latin-1")):
                return True, False
        return False, False

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        ok, from_query = self._found(scope)
        if not ok:
            if scope["type"] == "websocket":
                # docs/api.md: close code 4401 (accepted first: an HTTP 403 to the upgrade
                # would tell a browser page nothing).
                await refuse_websocket(scope, receive, send, 4401, "token required")
                return
            refused = Unauthorized(
                "this server requires a token",
                hint="open the URL printed at start-up (it has ?token=...) or send "
                "Authorization: Bearer <token>",
            )
            # RFC 6750 §3: a 401 names the scheme it wants.
            await send_error(send, refused, [(b"www-authenticate", b"Bearer")])
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
