"""Login sessions: the browser's cookie, idle time-out, termination, lock-out.

IEC 62443-4-2 CR 2.5 (session lock after inactivity), CR 2.6 (remote session termination),
CR 1.11 (unsuccessful login attempts) at SL 2:

- A login makes a session: a public id (for lists, the audit log and ``DELETE``) and a
  256-bit secret that only the cookie carries; the server keeps the secret's SHA-256.
  Sessions live in memory: a restart logs everyone out.
- A session unused (no HTTP request) for ``idle_s`` ends; WebSocket traffic does not count
  (the UI sends heartbeats by itself, not the user).
- Ending a session (logout, an administrator, idle, the account disabled or removed) closes
  its WebSockets at once: a socket that was a drive's dead-man closes, and
  services/control.py stops that user's motion and disables the drive.
- :data:`MAX_FAILURES` failed logins in a row for an account lock it for ``lockout_s``;
  :data:`MAX_FAILURES_PER_ADDRESS` from one address (whatever names it tries) lock that
  address. A locked login is refused even with the right password.
"""

from __future__ import annotations

import asyncio
import hashlib
import hmac
import logging
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from servodesk.errors import LockedOut, NotFoundError

log = logging.getLogger(__name__)

MAX_FAILURES = 5
MAX_FAILURES_PER_ADDRESS = 20

#: What a closed WebSocket is told (docs/api.md): the login is gone, log in again.
CLOSE_CODE = 4401


@dataclass
class LoginSession:
    id: str
    user: str
    address: str
    created: float
    last_seen: float  # time.time() of the last HTTP request
    #: Closers of this session's open WebSockets (each closes its socket with 4401).
    sockets: dict[int, Callable[[str], None]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "user": self.user,
            "address": self.address,
            "created": self.created,
            "last_seen": self.last_seen,
            "websockets": len(self.sockets),
        }


@dataclass
class _Failures:
    count: int = 0
    until: float = 0.0


def _digest(secret: str) -> str:
    return hashlib.sha256(secret.encode("ascii", "replace")).hexdigest()


class LoginService:
    def __init__(self, *, idle_s: float, lockout_s: float) -> None:
        self.idle_s = idle_s
        self.lockout_s = lockout_s
        self._by_digest: dict[str, LoginSession] = {}
        self._by_id: dict[str, LoginSession] = {}
        self._accounts: dict[str, _Failures] = {}
        self._addresses: dict[str, _Failures] = {}
        #: Sockets authenticated by an API token, per user (ended when the user is).
        self._token_sockets: dict[str, dict[int, Callable[[str], None]]] = {}
        self._next_socket = 0
        #: Called as ``on_end(session, reason)`` when a session ends (the audit log).
        self.on_end: Callable[[LoginSession, str], None] | None = None

    # Lock-out ---------------------------------------------------------------------------

    def check_locked(self, user: str, address: str) -> None:
        now = time.time()
        for what, table, key in (
            (f"the account {user!r}", self._accounts, user),
            (f"logins from {address}", self._addresses, address),
        ):
            f = table.get(key)
            if f is not None and f.until > now:
                stamp = time.strftime("%H:%M:%S", time.localtime(f.until))
                raise LockedOut(
                    f"{what} is locked after too many failed logins, until {stamp} "
                    f"({int(f.until - now) + 1} s)",
                    until=f.until,
                    hint="wait, or ask an administrator to set a new password",
                )

    def failed(self, user: str, address: str) -> None:
        now = time.time()
        for table, key, limit in (
            (self._accounts, user, MAX_FAILURES),
            (self._addresses, address, MAX_FAILURES_PER_ADDRESS),
        ):
            f = table.setdefault(key, _Failures())
            if f.until and f.until <= now:  # A past lock-out: count afresh.
                f.count, f.until = 0, 0.0
            f.count += 1
            if f.count >= limit:
                f.until = now + self.lockout_s
                log.warning(
                    "logins locked for %s s: %r after %d failures", self.lockout_s, key, f.count
                )

    def succeeded(self, user: str, address: str) -> None:
        self._accounts.pop(user, None)
        f = self._addresses.get(address)
        if f is not None and f.until <= time.time():
            self._addresses.pop(address, None)

    # Sessions ---------------------------------------------------------------------------

    def start(self, user: str, address: str) -> tuple[LoginSession, str]:
        """A new session of ``user``: it and the secret for the cookie."""
        secret = secrets.token_urlsafe(32)
        now = time.time()
        s = LoginSession(secrets.token_urlsafe(9), user, address, now, now)
        self._by_digest[_digest(secret)] = s
        self._by_id[s.id] = s
        log.info("login: %r from %s (session %s)", user, address, s.id)
        return s, secret

    def lookup(self, secret: bytes, *, touch: bool) -> LoginSession | None:
        """The live session of cookie value ``secret``; an idle one ends here."""
        try:
            text = secret.decode("ascii")
        except UnicodeDecodeError:
            return None
        digest = _digest(text)
        found = None
        for key, s in self._by_digest.items():  # Constant-time compare of each digest.
            if hmac.compare_digest(key, digest):
                found = s
        if found is None:
            return None
        now = time.time()
        if now - found.last_seen > self.idle_s:
            self.end(found.id, "idle time-out")
            return None
        if touch:
            found.last_seen = now
        return found

    def get(self, sid: str) -> LoginSession:
        s = self._by_id.get(sid)
        if s is None:
            raise NotFoundError(f"no login session {sid!r}", hint="GET /api/v1/auth/sessions")
        return s

    def all(self) -> list[LoginSession]:
        return sorted(self._by_id.values(), key=lambda s: s.created)

    def end(self, sid: str, reason: str) -> LoginSession:
        """End session ``sid`` and close its WebSockets (their dead-man drives stop)."""
        s = self.get(sid)
        self._by_id.pop(sid, None)
        for key, other in list(self._by_digest.items()):
            if other is s:
                del self._by_digest[key]
        log.info("session %s of %r ended: %s", sid, s.user, reason)
        if self.on_end is not None:
            try:
                self.on_end(s, reason)
            except Exception:  # The audit log's problem must not keep a session open.
                log.exception("session end listener failed")
        for close in list(s.sockets.values()):
            close(f"session ended: {reason}")
        s.sockets.clear()
        return s

    def end_user(self, user: str, reason: str) -> int:
        """End every session of ``user`` and close the sockets of their API tokens."""
        ended = [s.id for s in self.all() if s.user == user]
        for sid in ended:
            self.end(sid, reason)
        for close in list(self._token_sockets.pop(user, {}).values()):
            close(f"session ended: {reason}")
        return len(ended)

    def sweep(self, enabled: Callable[[str], bool]) -> None:
        """End idle sessions and those whose account is gone or disabled (a CLI in another
        process may have done it)."""
        now = time.time()
        for s in self.all():
            if now - s.last_seen > self.idle_s:
                self.end(s.id, "idle time-out")
            elif not enabled(s.user):
                self.end(s.id, "the account is disabled or removed")
        for user in list(self._token_sockets):
            if not enabled(user):
                self.end_user(user, "the account is disabled or removed")

    # WebSockets -------------------------------------------------------------------------

    def attach(self, session: str | None, user: str, close: Callable[[str], None]) -> int:
        """Register an open WebSocket of ``session`` (None: an API token of ``user``)."""
        self._next_socket += 1
        key = self._next_socket
        s = self._by_id.get(session) if session else None
        if s is not None:
            s.sockets[key] = close
        else:
            self._token_sockets.setdefault(user, {})[key] = close
        return key

    def detach(self, session: str | None, user: str, key: int) -> None:
        s = self._by_id.get(session) if session else None
        if s is not None:
            s.sockets.pop(key, None)
        self._token_sockets.get(user, {}).pop(key, None)

    async def run_sweeper(self, enabled: Callable[[str], bool], every_s: float = 2.0) -> None:
        while True:
            await asyncio.sleep(every_s)
            try:
                self.sweep(enabled)
            except Exception:  # A bug here must not end the sweeper.
                log.exception("session sweep failed")
