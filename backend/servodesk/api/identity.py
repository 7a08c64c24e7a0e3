"""Who is making a request: the one place the rest of the API asks.

The authentication middleware (users, sessions, API tokens: docs/security.md) puts a
:class:`Caller` into the ASGI scope's ``state`` under :data:`KEY` before any route runs.
Routes, the audit log and control ask :func:`caller_of`; none of them reads cookies or
headers itself. Where no middleware set one (the loopback server's zero-setup single-user
mode), the caller is :data:`LOCAL`, who may do everything, as anyone at this machine's
keyboard may.
"""

from __future__ import annotations

from dataclasses import dataclass

from starlette.requests import HTTPConnection

#: The key in ``scope["state"]`` (what ``request.state.<KEY>`` reads).
KEY = "servodesk_identity"


@dataclass(frozen=True)
class Caller:
    """The authenticated caller.

    ``user`` is the account name (``"local"`` in single-user mode), ``role`` one of the roles
    of :mod:`servodesk.domain.roles` once users exist, ``session`` the login session's id (None
    for single-user mode and API tokens), ``address`` the peer's IP address as the socket saw
    it (audit records name it: IEC 62443-4-2 CR 2.8 asks for the source of each event).
    """

    user: str
    role: str
    session: str | None = None
    address: str = ""


#: The caller on a loopback server without accounts.
LOCAL = Caller(user="local", role="administrator")


def caller_of(conn: HTTPConnection) -> Caller:
    """The caller of this request or WebSocket (:data:`LOCAL` when nobody authenticated)."""
    found = conn.scope.get("state", {}).get(KEY)
    if isinstance(found, Caller):
        return found
    client = conn.client
    return Caller(LOCAL.user, LOCAL.role, None, client.host if client else "")
