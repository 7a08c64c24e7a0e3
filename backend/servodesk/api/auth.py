"""Authentication: who is calling, before any route runs (docs/security.md, "Users").

Two modes:

- **Single-user** (a loopback server without accounts, or ``serve --single-user`` on
  loopback): nothing is asked, the caller is :data:`~servodesk.api.identity.LOCAL` (who may do
  everything, like anyone at this machine's keyboard).
- **Login required** (beyond loopback, or on loopback once an account exists): every
  ``/api/`` request and WebSocket carries a login session's cookie (the browser) or
  ``Authorization: Bearer <API token>`` (scripts); the :class:`Caller` goes into
  ``scope["state"]`` for the routes (api/rights.py checks the role's right). The UI's own files
  and the login route pass without one, as the *anonymous* caller, who has no rights.

A credential is never taken from the URL: a request with ``?token=`` is refused (URLs end up
in logs, browser history and screenshots). Everything before the check reads the raw bytes of
the ASGI scope: a header that is not UTF-8, or a credential that is not ASCII, is a missing
credential (401; a WebSocket is accepted and closed with 4401), never a 500.
"""

from __future__ import annotations

import asyncio
import contextlib
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from typing import Any
from urllib.parse import unquote_to_bytes

from starlette.requests import HTTPConnection
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from servodesk.api.errors import close_code, refuse_websocket, send_error
from servodesk.api.identity import KEY, Caller
from servodesk.errors import ServodeskError, Unauthorized
from servodesk.services.logins import CLOSE_CODE, LoginService
from servodesk.services.users import UserStore
from servodesk.settings import Settings

#: The login session's cookie (HttpOnly, SameSite=Strict; Secure under TLS).
COOKIE = "servodesk_session"
#: The caller of a public route when a login is required: a role with no rights.
ANONYMOUS_ROLE = "anonymous"
#: Paths that need no login: the login itself (everything outside /api/ is the UI's files,
#: which must load to show the login page, and the API docs).
_PUBLIC_API = ("/api/v1/auth/login",)


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


@dataclass
class Auth:
    """The accounts, the login sessions and the mode: one per application."""

    settings: Settings
    users: UserStore
    logins: LoginService

    @property
    def single_user_flag(self) -> bool:
        return self.settings.single_user and self.settings.is_loopback

    def login_required(self) -> bool:
        """Single-user mode only on loopback, and only without accounts (or with the flag)."""
        if not self.settings.is_loopback:
            return True
        return not self.single_user_flag and self.users.has_accounts()

    def mode(self) -> str:
        return "login" if self.login_required() else "single-user"

    def describe(self) -> str:
        """One line for the console at start-up."""
        if self.login_required():
            return (
                f"logins required ({len(self.users.all())} accounts in "
                f"{self.settings.data_dir}; servodesk users list)"
            )
        if self.users.has_accounts():
            return "single-user mode (--single-user): no login on loopback although accounts exist"
        return "single-user mode (loopback, no accounts): no login"

    def enabled(self, name: str) -> bool:
        user = self.users.get(name)
        return user is not None and not user.disabled


def auth_of(conn: HTTPConnection | Any) -> Auth:
    app = conn.app if isinstance(conn, HTTPConnection) else conn
    found: Auth = app.state.servodesk.auth  # The AppState (api/state.py).
    return found


def _address(scope: Scope) -> str:
    client = scope.get("client")
    return str(client[0]) if client else ""


def cookie_header(secret: str, *, secure: bool, clear: bool = False) -> bytes:
    """The Set-Cookie of a login (or of a logout, ``clear``): no Max-Age, so the browser
    forgets it when it closes; the server's idle time-out ends it before that."""
    parts = [f"{COOKIE}={'' if clear else secret}", "HttpOnly", "SameSite=Strict", "Path=/"]
    if clear:
        parts.append("Max-Age=0")
    if secure:
        parts.append("Secure")
    return "; ".join(parts).encode("ascii")


class AuthMiddleware:
    def __init__(self, app: ASGIApp, auth: Auth) -> None:
        self.app = app
        self.auth = auth

    def _identify(self, scope: Scope) -> Caller | None:
        """The caller by API token or session cookie; None: no valid credential."""
        auth_header, cookie = b"", b""
        for name, value in scope.get("headers", []):
            key = name.lower()
            if key == b"authorization":
                auth_header = value
            elif key == b"cookie":
                cookie = value
        address = _address(scope)
        if auth_header:
            if auth_header[:7].lower() != b"bearer ":
                return None
            found = self.auth.users.verify_token(auth_header[7:].strip())
            if found is None:
                return None
            user, _ = found
            return Caller(user.name, user.role, None, address)
        if cookie:
            try:
                jar = SimpleCookie(cookie.decode("latin-1"))
            except CookieError:
                return None
            if COOKIE not in jar:
                return None
            session = self.auth.logins.lookup(
                jar[COOKIE].value.encode("latin-1"), touch=scope["type"] == "http"
            )
            if session is None:
                return None
            account = self.auth.users.get(session.user)
            if account is None or account.disabled:
                self.auth.logins.end(session.id, "the account is disabled or removed")
                return None
            return Caller(account.name, account.role, session.id, address)
        return None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        if not self.auth.login_required():
            await self.app(scope, receive, send)  # Single-user: the caller is LOCAL.
            return
        # The decoded path, as the router matches it (raw_path would let /%61pi/... pass).
        path = str(scope.get("path", ""))
        state = scope.setdefault("state", {})
        if not path.startswith("/api/") or path in _PUBLIC_API:
            state[KEY] = Caller("", ANONYMOUS_ROLE, None, _address(scope))
            await self.app(scope, receive, send)
            return
        in_url = any(
            k in (b"token", b"access_token") for k, _ in _query(scope.get("query_string", b""))
        )
        try:
            who = None if in_url else self._identify(scope)
        except ServodeskError as exc:
            # The accounts' store cannot be read (a central store that is away: 503 naming
            # it), answered as the error it is rather than a bare 500.
            if scope["type"] == "websocket":
                await refuse_websocket(scope, receive, send, close_code(exc), exc.message)
            else:
                await send_error(send, exc)
            return
        if who is None:
            if in_url:
                refused = Unauthorized(
                    "credentials are never accepted in the URL (?token=)",
                    hint="send Authorization: Bearer <API token>, or log in in the browser",
                )
            else:
                refused = Unauthorized(
                    "log in first: this request has no valid login session or API token",
                    hint="POST /api/v1/auth/login, or send Authorization: Bearer <API token> "
                    "(docs/security.md)",
                )
            if scope["type"] == "websocket":
                # docs/api.md: close code 4401 (accepted first: an HTTP 403 to the upgrade
                # would tell a browser page nothing).
                await refuse_websocket(scope, receive, send, CLOSE_CODE, refused.message)
                return
            # RFC 6750 §3: a 401 names the scheme it wants.
            await send_error(send, refused, [(b"www-authenticate", b"Bearer")])
            return
        state[KEY] = who
        if scope["type"] == "websocket":
            await self._websocket(scope, receive, send, who)
            return
        await self.app(scope, receive, send)

    async def _websocket(self, scope: Scope, receive: Receive, send: Send, who: Caller) -> None:
        """Run the socket so that ending its login session closes it at once: its handler
        then sees a disconnect, and services/control.py makes its drives safe."""
        ended = asyncio.Event()
        reason = ["session ended"]
        closed = [False]

        def close(why: str) -> None:
            reason[0] = why
            ended.set()

        async def guarded_send(message: Message) -> None:
            if closed[0]:
                return  # The socket was closed for the ended session; its sender is late.
            await send(message)

        async def guarded_receive() -> Message:
            if not ended.is_set():
                recv = asyncio.ensure_future(receive())
                wait = asyncio.ensure_future(ended.wait())
                done, _ = await asyncio.wait({recv, wait}, return_when=asyncio.FIRST_COMPLETED)
                if recv in done:
                    wait.cancel()
                    return recv.result()
                recv.cancel()
            if not closed[0]:
                closed[0] = True
                with contextlib.suppress(Exception):
                    text = reason[0].encode()[:123].decode("utf-8", "ignore")
                    await send({"type": "websocket.close", "code": CLOSE_CODE, "reason": text})
            return {"type": "websocket.disconnect", "code": CLOSE_CODE}

        logins = self.auth.logins
        key = logins.attach(who.session, who.user, close)
        try:
            await self.app(scope, guarded_receive, guarded_send)
        finally:
            logins.detach(who.session, who.user, key)
