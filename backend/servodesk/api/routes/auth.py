"""Login, logout, who am I; accounts, login sessions and API tokens (docs/api.md, "Users").

The right each route needs is in api/rights.py like every other route's: the login is
public, one's own session and API tokens need ``read``, everything about other accounts
``manage_users``.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from typing import Annotated

from fastapi import APIRouter, Path, Request, Response
from fastapi.responses import JSONResponse

from servodesk.api.auth import Auth, auth_of, cookie_header
from servodesk.api.identity import caller_of
from servodesk.api.schemas import ERROR_RESPONSES, ErrorOut
from servodesk.api.schemas_auth import (
    LoginRequest,
    LoginSessionOut,
    MeOut,
    TokenCreate,
    TokenCreated,
    TokenOut,
    UserCreate,
    UserOut,
    UserPatch,
)
from servodesk.api.state import state_of
from servodesk.domain.roles import rights_of
from servodesk.errors import ConflictError, LockedOut, Unauthorized
from servodesk.services.audit import Actor

UserName = Annotated[str, Path(max_length=64)]

# The login sweeper (idle sessions end) is started and stopped by AppState (api/state.py).
router = APIRouter(prefix="/auth", tags=["auth"], responses=ERROR_RESPONSES)


def _audit(
    request: Request,
    event: str,
    *,
    who: Actor | None = None,
    ok: bool = True,
    message: str = "",
    details: dict[str, object] | None = None,
) -> None:
    """Record an access-control or user-administration event (docs/security.md, Audit log):
    never a password or a token's secret."""
    state_of(request.app).audit.record(event, who=who, ok=ok, message=message, details=details)


def _me(request: Request, auth: Auth) -> MeOut:
    who = caller_of(request)
    return MeOut(
        user=who.user,
        role=who.role,
        rights=sorted(r.value for r in rights_of(who.role)),
        mode=auth.mode(),
        session=who.session,
        idle_timeout_s=auth.logins.idle_s,
    )


@router.post(
    "/login",
    operation_id="login",
    responses={429: {"model": ErrorOut, "description": "Locked after too many failed logins"}},
)
async def login(body: LoginRequest, request: Request) -> JSONResponse:
    """Log in: sets the session cookie (HttpOnly, SameSite=Strict, Secure under TLS)."""
    auth = auth_of(request)
    address = request.client.host if request.client else ""
    who = Actor(body.user, address)
    try:
        auth.logins.check_locked(body.user, address)
    except LockedOut as exc:
        _audit(request, "access.login_refused", who=who, ok=False, message=exc.message)
        return _locked(exc)
    user = await asyncio.to_thread(auth.users.verify_password, body.user, body.password)
    if user is None:
        auth.logins.failed(body.user, address)
        _audit(request, "access.login_failed", who=who, ok=False, message="wrong password")
        try:
            auth.logins.check_locked(body.user, address)
        except LockedOut as exc:
            _audit(request, "access.locked_out", who=who, ok=False, message=exc.message)
        raise Unauthorized(
            "wrong user name or password (or the account is disabled)",
            hint="after 5 failures in a row the account is locked for a while",
        )
    auth.logins.succeeded(body.user, address)
    session, secret = auth.logins.start(user.name, address)
    _audit(request, "access.login", who=who, details={"session": session.id, "role": user.role})
    out = MeOut(
        user=user.name,
        role=user.role,
        rights=sorted(r.value for r in rights_of(user.role)),
        mode=auth.mode(),
        session=session.id,
        idle_timeout_s=auth.logins.idle_s,
    )
    response = JSONResponse(out.model_dump())
    secure = request.url.scheme == "https"
    response.headers.append("set-cookie", cookie_header(secret, secure=secure).decode())
    return response


def _locked(exc: LockedOut) -> JSONResponse:
    # RFC 6585 §4: 429 with Retry-After (seconds).
    wait = max(1, int(exc.until - time.time()) + 1)
    return JSONResponse(exc.to_dict(), status_code=429, headers={"Retry-After": str(wait)})


@router.post("/logout", status_code=204, operation_id="logout")
async def logout(request: Request) -> Response:
    """End this login session (its WebSockets close) and clear the cookie."""
    auth = auth_of(request)
    who = caller_of(request)
    if who.session is not None:
        with contextlib.suppress(Exception):
            auth.logins.end(who.session, "logged out")
    response = Response(status_code=204)
    secure = request.url.scheme == "https"
    response.headers.append("set-cookie", cookie_header("", secure=secure, clear=True).decode())
    return response


@router.get("/me", operation_id="me")
async def me(request: Request) -> MeOut:
    return _me(request, auth_of(request))


# Accounts (manage_users) ----------------------------------------------------------------


def _user_out(u: object) -> UserOut:
    return UserOut.model_validate(u, from_attributes=True)


@router.get("/users", operation_id="list_users")
async def list_users(request: Request) -> list[UserOut]:
    return [_user_out(u) for u in auth_of(request).users.all()]


@router.post("/users", status_code=201, operation_id="create_user")
async def create_user(body: UserCreate, request: Request) -> UserOut:
    users = auth_of(request).users
    made = await asyncio.to_thread(users.add, body.name, body.role.value, body.password)
    _audit(request, "user.created", details={"account": made.name, "role": made.role})
    return _user_out(made)


@router.patch("/users/{name}", operation_id="update_user")
async def update_user(name: UserName, body: UserPatch, request: Request) -> UserOut:
    """Change an account's role, password or disable it; a disabled account's sessions end."""
    auth = auth_of(request)
    auth.users.require(name)
    if body.password is not None:
        await asyncio.to_thread(auth.users.set_password, name, body.password)
        _audit(request, "user.password_set", details={"account": name})
    if body.role is not None:
        auth.users.set_role(name, body.role.value)
        _audit(request, "user.role_set", details={"account": name, "role": body.role.value})
    if body.disabled is not None:
        auth.users.set_disabled(name, body.disabled)
        event = "user.disabled" if body.disabled else "user.enabled"
        _audit(request, event, details={"account": name})
        if body.disabled:
            auth.logins.end_user(name, f"account disabled by {caller_of(request).user!r}")
    return _user_out(auth.users.require(name))


@router.delete("/users/{name}", status_code=204, operation_id="delete_user")
async def delete_user(name: UserName, request: Request) -> Response:
    auth = auth_of(request)
    if name == caller_of(request).user:
        raise ConflictError("you cannot remove your own account", hint="another administrator can")
    auth.users.remove(name)
    _audit(request, "user.removed", details={"account": name})
    auth.logins.end_user(name, f"account removed by {caller_of(request).user!r}")
    return Response(status_code=204)


# Login sessions (manage_users) -----------------------------------------------------------


@router.get("/sessions", operation_id="list_login_sessions")
async def list_login_sessions(request: Request) -> list[LoginSessionOut]:
    return [LoginSessionOut.model_validate(s.to_dict()) for s in auth_of(request).logins.all()]


@router.delete("/sessions/{session_id}", status_code=204, operation_id="end_login_session")
async def end_login_session(
    session_id: Annotated[str, Path(max_length=64)], request: Request
) -> Response:
    """End a login session now: its WebSockets close, so the drives it was the dead-man of
    stop (services/control.py) and its control lapses."""
    auth_of(request).logins.end(session_id, f"ended by {caller_of(request).user!r}")
    return Response(status_code=204)


# API tokens of the caller (read) ---------------------------------------------------------


def _token_owner(request: Request) -> str:
    who = caller_of(request)
    if auth_of(request).users.get(who.user) is None:
        raise ConflictError(
            "API tokens belong to accounts; the single-user mode has none",
            hint="servodesk users add NAME --role ROLE, then log in as NAME",
        )
    return who.user


@router.get("/tokens", operation_id="list_tokens")
async def list_tokens(request: Request) -> list[TokenOut]:
    user = _token_owner(request)
    return [TokenOut.model_validate(t.to_dict()) for t in auth_of(request).users.tokens(user)]


@router.post("/tokens", status_code=201, operation_id="create_token")
async def create_token(body: TokenCreate, request: Request) -> TokenCreated:
    """A new API token of the caller, for scripts: the secret is in this answer only."""
    user = _token_owner(request)
    token, secret = auth_of(request).users.create_token(user, body.label)
    _audit(request, "user.token_created", details={"token": token.id, "label": token.label})
    return TokenCreated.model_validate({**token.to_dict(), "secret": secret})


@router.delete("/tokens/{token_id}", status_code=204, operation_id="delete_token")
async def delete_token(token_id: Annotated[str, Path(max_length=64)], request: Request) -> Response:
    user = _token_owner(request)
    auth_of(request).users.delete_token(user, token_id)
    _audit(request, "user.token_revoked", details={"token": token_id})
    return Response(status_code=204)
