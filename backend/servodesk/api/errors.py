"""Mapping of the servodesk error tree to HTTP problem responses (never a bare 500)."""

from __future__ import annotations

import logging

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from servodesk.domain import profidrive
from servodesk.errors import (
    ConflictError,
    DriveStateError,
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    PdoRefused,
    ProfileError,
    ServodeskError,
    ValidationError,
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
    return 400


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
