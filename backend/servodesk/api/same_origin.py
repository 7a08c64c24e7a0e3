"""Requests only from this server's own pages: Host, Origin and Content-Type checks.

A browser lets any web page send requests to http://127.0.0.1:8000: a form post or a
``fetch(..., {mode: "no-cors"})`` reaches the server, and a WebSocket is not bound by the
same-origin policy at all. With DNS rebinding (a name of the attacker's that resolves to
127.0.0.1 after the page loaded) the page can even read the answers. So, before any route
(docs/security.md):

- Host must be a name the server answers to (``hosts.HostPolicy``): 400 otherwise. A
  rebinding page always sends its own name.
- Origin, when present, on every state-changing request (POST, PUT, PATCH, DELETE) and every
  WebSocket must be one of those names with the server's own port: 403 (a WebSocket is
  accepted and closed with 4403). Browsers send Origin on all of these (Fetch standard
  §3.1, RFC 6455 §4.1); scripts and the CLI send none and pass.
- A state-changing request's body must be application/json (or multipart/form-data where a
  file is uploaded, ``api/uploads.py``): 415. JSON is not a type a form or a no-cors fetch
  may send (Fetch standard, CORS-safelisted request-header), so a page of another origin
  would need a CORS preflight, which this server never grants.

Everything is read from the raw ASGI header bytes: nothing here can fail on a header that is
not UTF-8 (or Latin-1, or anything else).
"""

from __future__ import annotations

from starlette.types import ASGIApp, Receive, Scope, Send

from servodesk.api.errors import close_code, refuse_websocket, send_error
from servodesk.api.uploads import media_type, takes_file
from servodesk.errors import HostNotAllowed, OriginNotAllowed, RequestRefused, UnsupportedMediaType
from servodesk.hosts import HostPolicy, split_host, split_origin

#: RFC 9110 §9.2.1: every method but these may change state.
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS", "TRACE"})

_HOSTS_HINT = (
    "open servodesk by the address it printed at start-up (localhost, 127.0.0.1), or add the "
    "name to SERVODESK_ALLOWED_HOSTS"
)


class SameOriginGuard:
    def __init__(self, app: ASGIApp, policy: HostPolicy, port: int) -> None:
        self.app = app
        self.policy = policy
        #: The configured port, for a server whose ASGI scope does not say (a Unix socket).
        self.port = port

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        try:
            self.check(scope)
        except RequestRefused as exc:
            if scope["type"] == "websocket":
                await refuse_websocket(scope, receive, send, close_code(exc), exc.message)
            else:
                await send_error(send, exc)
            return
        await self.app(scope, receive, send)

    def check(self, scope: Scope) -> None:
        headers: dict[bytes, list[bytes]] = {}
        for name, value in scope.get("headers", []):
            headers.setdefault(name.lower(), []).append(value)
        self._host(headers.get(b"host", []))
        changes = scope["type"] == "websocket" or scope.get("method", "GET") not in SAFE_METHODS
        if changes:
            self._origin(headers.get(b"origin", []), scope)
        if changes and scope["type"] == "http":
            self._content_type(headers, scope["path"])

    def _host(self, values: list[bytes]) -> None:
        if not values:
            return  # HTTP/1.0 without Host: not a browser (HTTP/1.1 requires it, h11 checks).
        host = split_host(values[0]) if len(values) == 1 else None
        if host is None:
            raise HostNotAllowed("the Host header is not one host name", hint=_HOSTS_HINT)
        if not self.policy.host_ok(*host):
            raise HostNotAllowed(
                f"this server does not answer to the name {host[0][:100]!r}", hint=_HOSTS_HINT
            )

    def _origin(self, values: list[bytes], scope: Scope) -> None:
        if not values:
            return  # Not a browser: a script or the CLI.
        origin = split_origin(values[0]) if len(values) == 1 else None
        server = scope.get("server") or (None, None)
        port = server[1] if isinstance(server[1], int) else self.port
        if origin is None or not self.policy.origin_ok(origin[1], origin[2], port):
            what = values[0][:100].decode("ascii", errors="replace")
            raise OriginNotAllowed(
                f"a page of {what} may not change anything here (a cross-site request)",
                hint="use servodesk's own pages, or a script (which sends no Origin); a page "
                "served by another of your servers needs its name:port in "
                "SERVODESK_ALLOWED_HOSTS",
            )

    def _content_type(self, headers: dict[bytes, list[bytes]], path: str) -> None:
        kinds = headers.get(b"content-type", [])
        kind = media_type(kinds[0]) if len(kinds) == 1 else ("several" if kinds else None)
        if kind is None:
            length = headers.get(b"content-length", [b"0"])[0].strip()
            if length in (b"0", b"") and b"transfer-encoding" not in headers:
                return  # No body (a DELETE, a POST of a command without parameters).
        if kind == "application/json" or (kind == "multipart/form-data" and takes_file(path)):
            return
        accepted = "application/json" + (" or multipart/form-data" if takes_file(path) else "")
        raise UnsupportedMediaType(
            f"this request's body must be {accepted}, not {kind or 'without a Content-Type'}",
            hint="send Content-Type: application/json with a JSON body"
            + (", or the file as multipart/form-data field 'file'" if takes_file(path) else ""),
        )
