"""Mapping of the servodesk error tree to HTTP problem responses (never a bare 500)."""

from __future__ import annotations

import json
import logging

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import Receive, Scope, Send

from servodesk.domain import profidrive
from servodesk.errors import (
    ConflictError,
    DriveStateError,
    Forbidden,
    HostNotAllowed,
    LinkError,
    LinkTimeoutError,
    LockedOut,
    NotFoundError,
    ObjectAccessError,
    OriginNotAllowed,
    PayloadTooLarge,
    PdoRefused,
    ProfileError,
    ServodeskError,
    ToolMissing,
    Unauthorized,
    Unavailable,
    UnsupportedMediaType,
    ValidationError,
    WorkerFailed,
)

log = logging.getLogger(__name__)

# SDO abort codes that mean "not now" rather than "not this": 409.
_STATE_ABORTS = {0x08000021, 0x08000022}
# SDO abort codes that mean "no such object / subindex": 404.
_MISSING_ABORTS = {0x06020000, 0x06090011}


def status_for(exc: ServodeskError) -> int:
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, ConflictError | DriveStateError):
        return 409
    if isinstance(exc, Forbidden):
        return 403
    if isinstance(exc, WorkerFailed | ToolMissing | Unavailable):
        return 503  # RFC 9110 §15.6.4: the server cannot now; the next try may work.
    if isinstance(exc, ObjectAccessError):
        if exc.protocol == "profidrive":
            # PROFIdrive error numbers (004 §20.4.2): no such parameter / subindex / drive
            # object, or not in this operating state.
            if exc.code in profidrive.MISSING:
                return 404
            return 409 if exc.code in profidrive.STATE else 400
        if exc.protocol == "dcp":
            # DCP BlockError (docs/profinet.md): 5 set not possible by local reasons, 6 in
            # operation: the device's state, not the request, is in the way.
            return 409 if exc.code in (5, 6) else 400
        if exc.protocol == "pnio":
            return 502  # The device refused the record access itself (docs/profinet.md).
        if exc.code in _MISSING_ABORTS:
            return 404
        return 409 if exc.code in _STATE_ABORTS else 400
    if isinstance(exc, PdoRefused):
        return 422  # docs/pdo.md: {"detail", "problems": [...]}
    if isinstance(exc, ValidationError | ProfileError):
        return 400
    if isinstance(exc, LinkTimeoutError):
        return 504
    if isinstance(exc, LinkError):
        return 502
    # The request checks of docs/security.md (RFC 9110 §15.5.2, §15.5.4, §15.5.14, §15.5.16).
    if isinstance(exc, Unauthorized):
        return 401
    if isinstance(exc, LockedOut):
        return 429  # RFC 6585 §4, with Retry-After (services/users.py, lock-out)
    if isinstance(exc, OriginNotAllowed):
        return 403
    if isinstance(exc, PayloadTooLarge):
        return 413
    if isinstance(exc, UnsupportedMediaType):
        return 415
    if isinstance(exc, HostNotAllowed):
        return 400
    return 400


#: WebSocket close codes of refused upgrades (RFC 6455 §7.4.2: 4000-4999 are the
#: application's): the HTTP status + 4000, as 4401 for a missing token (docs/api.md).
def close_code(exc: ServodeskError) -> int:
    return 4000 + status_for(exc)


async def refuse_websocket(
    scope: Scope, receive: Receive, send: Send, code: int, reason: str
) -> None:
    """Accept the upgrade, then close it with ``code`` and ``reason``.

    Refusing the upgrade itself would give the client only an HTTP 403 and a browser page
    only close code 1006; accepted and closed, it sees why. Accepted with the subprotocol
    the client asked for, since a browser drops a socket that answers without it. Nothing
    else is sent on it.
    """
    message = await receive()
    if message["type"] != "websocket.connect":
        return
    offered = scope.get("subprotocols") or []
    await send({"type": "websocket.accept", "subprotocol": offered[0] if offered else None})
    # A close frame's reason has room for 123 bytes (RFC 6455 §5.5).
    text = reason.encode("utf-8")[:123].decode("utf-8", errors="ignore")
    await send({"type": "websocket.close", "code": code, "reason": text})


async def send_error(
    send: Send, exc: ServodeskError, headers: list[tuple[bytes, bytes]] | None = None
) -> None:
    """Answer ``exc`` as its JSON error from plain ASGI middleware, which runs outside the
    exception handlers :func:`install` registers (they see only what the routes raise)."""
    body = json.dumps(exc.to_dict()).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status_for(exc),
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                *(headers or []),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})


def install(app: FastAPI) -> None:
    @app.exception_handler(ServodeskError)
    async def _servodesk(_: Request, exc: ServodeskError) -> JSONResponse:
        return JSONResponse(exc.to_dict(), status_code=status_for(exc))

    @app.exception_handler(RequestValidationError)
    async def _invalid(_: Request, exc: RequestValidationError) -> JSONResponse:
        errs = exc.errors()
        first = errs[0] if errs else {"loc": (), "msg": "invalid request"}
        loc = [str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path")]
        where = ".".join(loc)
        msg = f"{where}: {first.get('msg')}" if where else str(first.get("msg"))
        if len(errs) > 1:
            msg += f" (and {len(errs) - 1} more problems)"
        body = {
            "error": "ValidationError",
            "message": msg,
            "field": where or None,
            "hint": "see the request schema at /docs",
        }
        return JSONResponse(body, status_code=422)

    @app.exception_handler(StarletteHTTPException)
    async def _http(_: Request, exc: StarletteHTTPException) -> JSONResponse:
        name = {401: "Unauthorized", 404: "NotFoundError", 405: "MethodNotAllowed"}.get(
            exc.status_code, "HTTPError"
        )
        return JSONResponse(
            {"error": name, "message": str(exc.detail)},
            status_code=exc.status_code,
            headers=getattr(exc, "headers", None),
        )

    @app.exception_handler(Exception)
    async def _unexpected(_: Request, exc: Exception) -> JSONResponse:
        # A bug: log it with its traceback for us, give the user a plain message.
        log.exception("unexpected error")
        return JSONResponse(
            {
                "error": "InternalError",
                "message": f"unexpected error: {type(exc).__name__}",
                "hint": "this is a servodesk bug; the server log has the details",
            },
            status_code=500,
        )
