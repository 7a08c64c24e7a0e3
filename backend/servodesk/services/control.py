"""Control of drive sessions: who may change a drive, and the connection that keeps it safe.

One person holds control of a session at a time; everyone else watches (DESIGN.md, "Rules that
hold everywhere"). This module is the one place that says what needs control; the API applies
it through :mod:`servodesk.api.control_deps` and nothing else decides.

The rules, as a commissioning engineer at a live machine needs them:

- **Everything that can energise, move or change the drive needs control**: state requests,
  motion, homing, tuning, object and parameter writes, restore, PDO apply and cyclic outputs,
  alarm reset, save to EEPROM and restore defaults. Reads never do. Without it the request is
  refused with 409 naming the holder (or saying nobody holds it) and nothing reaches the bus.
- **Stopping is never refused**: halt, quick stop (``motion/halt``, ``motion/stop``, the
  ``quick_stop`` state command) and stopping a tuning: anyone who sees the axis move may stop
  it.
- **Control is a server-issued token, not a name.** ``take`` answers with a random token
  (128 bits, :func:`secrets.token_urlsafe`); every request that needs control presents it in
  the ``X-Servodesk-Control`` header. The client id (``X-Servodesk-Client``) is only a label
  for people and the audit log: knowing it gives nothing (before 2026-12-07 it was the
  authority, and a second tab that sent the holder's id could move the axis).
- **The dead-man belongs to a connection.** A WebSocket binds itself to control by sending the
  token (``{"type": "bind", "session", "token"}``); only heartbeats from a bound socket count.
  Energising (servo on, the controlword) and motion need a bound, open socket, because nothing
  else would stop the axis if the holder vanished. A second socket opened with the holder's
  client id is just a watcher.
- **Losing the holder makes the drive safe.** When the holder's last bound socket closes, or
  control is released, taken over or lapses, the listeners stop the motion (quick stop) and
  bring the drive to Switch on disabled (:class:`~servodesk.services.motion.MotionService`).
  Control itself is kept ``grace_s`` for a page reload: a new socket that binds with the same
  token within it keeps control (the drive stays disabled: the user enables it again). After
  that it is released.
- ``take`` when another holds control is refused (409 naming the holder); ``force_take`` needs
  ``confirm: true`` and makes the previous holder's drive safe as above. ``take`` by the holder
  (its token presented) returns the same token.
- A holder that never bound a socket (a script) keeps control until it releases it or someone
  force-takes it; it may write parameters but not energise or move.
"""

from __future__ import annotations

import asyncio
import hmac
import logging
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from servodesk.errors import ConflictError
from servodesk.services.audit import DISCARD, Recorder
from servodesk.services.events import EventHub

log = logging.getLogger(__name__)

#: Called as ``listener(session, previous_holder, reason)`` when the holder of a session is
#: gone or changed: the drive is to be made safe (motion stopped, drive disabled).
LostListener = Callable[[str, str, str], None]

#: Called as ``listener(session)`` when a holder's first socket is bound (the dead-man is on).
BoundListener = Callable[[str], None]

#: The header that carries the control token.
CONTROL_HEADER = "X-Servodesk-Control"


@dataclass(slots=True)
class Holder:
    client: str  # The label the holder gave (X-Servodesk-Client), for people and the audit log.
    token: str
    since: float  # time.time() when control was taken
    #: Connections bound to this control; empty for a script without a socket.
    connections: set[str] = field(default_factory=set)
    #: A bound socket existed and all closed: the drive was made safe, control waits for a
    #: rebind until the timer releases it.
    orphaned: bool = False
    #: The account that took control (api/identity.py; "local" in the single-user mode):
    #: only that user's requests may use the token, and people see this name.
    user: str = ""


@dataclass(slots=True)
class Connection:
    """One WebSocket (or the CLI's in-process stand-in) as the server knows it."""

    id: str
    client: str
    bound: set[str] = field(default_factory=set)  # Sessions this connection is the dead-man of.


class ControlService:
    """Who holds which session, the connections bound to it, and their last heartbeats."""

    def __init__(self, hub: EventHub, *, grace_s: float = 5.0, audit: Recorder = DISCARD) -> None:
        self.hub = hub
        self.grace_s = grace_s
        self._holders: dict[str, Holder] = {}
        self._connections: dict[str, Connection] = {}
        #: Last heartbeat per session, from a connection bound to its holder (monotonic).
        #: Read from the dead-man's thread: a dict read of a float is atomic in CPython.
        self._heartbeats: dict[str, float] = {}
        self._release_timers: dict[str, asyncio.TimerHandle] = {}
        self._lost: list[LostListener] = []
        self._bound: list[BoundListener] = []
        #: The audit log (IEC 62443-4-2 CR 2.8: control taken, released, forced, lost).
        self.audit = audit

    # Listeners --------------------------------------------------------------------------

    def on_lost(self, listener: LostListener) -> None:
        self._lost.append(listener)

    def on_bound(self, listener: BoundListener) -> None:
        self._bound.append(listener)

    # Ownership --------------------------------------------------------------------------

    def owner(self, sid: str) -> str | None:
        h = self._holders.get(sid)
        return h.client if h else None

    def holder_user(self, sid: str) -> str | None:
        """The account holding control of ``sid`` (None: nobody holds it)."""
        h = self._holders.get(sid)
        return h.user if h else None

    def holds(self, sid: str, token: str | None) -> bool:
        h = self._holders.get(sid)
        return h is not None and _same(h.token, token)

    def info(self, sid: str, token: str | None) -> dict[str, Any]:
        h = self._holders.get(sid)
        you = h is not None and _same(h.token, token)
        return {
            "session": sid,
            "owner": h.client if h else None,
            "user": h.user if h else None,
            "since": h.since if h else None,
            "you": you,
            "token": h.token if (h is not None and you) else None,
            "bound": bool(h.connections) if h else False,
            "orphaned": h.orphaned if h else False,
        }

    def take(self, sid: str, client: str, token: str | None = None, user: str = "") -> str:
        """Take control; the holder presenting its token gets the same one back.

        A client that already holds control of other drives and presents that token gets
        the same token for this one too: one token per tab or script, however many axes it
        holds (an integrator commissions several at once)."""
        h = self._holders.get(sid)
        if h is not None:
            if _same(h.token, token) and h.user == user:
                return h.token
            raise ConflictError(
                f"{_who(h)} holds control of {sid}",
                hint='ask them to release it, or send {"action": "force_take", "confirm": true}',
            )
        new = self._set(sid, client, self._live(token, user), user)
        self.audit.record("control.taken", drive=sid, details={"client": client})
        return new

    def force_take(
        self, sid: str, client: str, confirm: bool, token: str | None = None, user: str = ""
    ) -> str:
        """Take control over (the caller's right to take it from another user is checked by
        the API: only an administrator may, api/routes/motion.py)."""
        h = self._holders.get(sid)
        if h is not None and _same(h.token, token) and h.user == user:
            return h.token
        if h is not None and not confirm:
            raise ConflictError(
                f"{_who(h)} holds control of {sid}; taking it over stops its motion, "
                "disables the drive and needs confirmation",
                hint='send {"action": "force_take", "confirm": true} to go ahead',
            )
        new = self._set(sid, client, self._live(token, user), user)
        if h is not None:
            self._notify_lost(sid, h.client, f"control taken over by {client!r}")
        # Recorded after the previous holder's drive was made safe (never in its way).
        self.audit.record(
            "control.forced" if h else "control.taken",
            drive=sid,
            details={"client": client, "previous": h.client if h is not None else None},
        )
        return new

    def release(self, sid: str, token: str | None) -> None:
        h = self._holders.get(sid)
        if h is None:
            return
        if not _same(h.token, token):
            raise ConflictError(
                f"{_who(h)} holds control of {sid}; only the holder can release it",
                hint="force_take takes it over",
            )
        self._drop(sid)
        self._notify_lost(sid, h.client, f"{h.client!r} released control")
        self.audit.record("control.released", drive=sid, details={"client": h.client})

    def forget_session(self, sid: str) -> None:
        """The session closed: nobody holds it any more."""
        h = self._holders.get(sid)
        if h is not None:
            self._drop(sid)
        for conn in self._connections.values():
            conn.bound.discard(sid)

    def _live(self, token: str | None, user: str = "") -> str | None:
        """``token`` when ``user`` holds control of some session with it now, else None."""
        for h in self._holders.values():
            if _same(h.token, token) and h.user == user:
                return h.token
        return None

    def _set(self, sid: str, client: str, token: str | None = None, user: str = "") -> str:
        token = token or secrets.token_urlsafe(16)
        self._holders[sid] = Holder(client, token, time.time(), user=user)
        self._heartbeats.pop(sid, None)
        log.info("control of %s: %s", sid, client)
        self._publish(sid)
        return token

    def _drop(self, sid: str) -> None:
        h = self._holders.pop(sid, None)
        self._heartbeats.pop(sid, None)
        timer = self._release_timers.pop(sid, None)
        if timer is not None:
            timer.cancel()
        if h is not None:
            for cid in h.connections:
                conn = self._connections.get(cid)
                if conn is not None:
                    conn.bound.discard(sid)
        log.info("control of %s: released", sid)
        self._publish(sid)

    def _publish(self, sid: str) -> None:
        h = self._holders.get(sid)
        # Everyone sees who holds control (not only the session's watchers): the session list
        # of every tab shows it. Never the token.
        self.hub.publish(
            {
                "type": "control",
                "session": sid,
                "owner": h.client if h else None,
                "user": h.user if h else None,
                "since": h.since if h else None,
                "bound": bool(h.connections) if h else False,
                "orphaned": h.orphaned if h else False,
            }
        )

    def _notify_lost(self, sid: str, client: str, reason: str) -> None:
        for cb in list(self._lost):
            try:
                cb(sid, client, reason)
            except Exception:  # A listener's bug must not keep control in a half state.
                log.exception("control listener failed")

    # The checks: the one rule -----------------------------------------------------------

    def check(
        self, sid: str, token: str | None, what: str = "this request", user: str | None = None
    ) -> str:
        """Control is needed: the token must be the holder's, presented by the holder's user
        (``user`` None: not checked, an in-process caller). Returns the holder's label."""
        h = self._holders.get(sid)
        if h is None:
            raise ConflictError(
                f"nobody holds control of {sid}; {what} needs control and was not sent",
                hint='take control first: POST /control {"action": "take"}, then send its '
                f"token in the {CONTROL_HEADER} header",
            )
        if not _same(h.token, token) or (user is not None and user != h.user):
            raise ConflictError(
                f"{_who(h)} holds control of {sid}; {what} was not sent",
                hint="only the holder of control can change the drive; they must release it, "
                "or use force_take",
            )
        return h.client

    def check_energise(
        self, sid: str, token: str | None, what: str = "this request", user: str | None = None
    ) -> str:
        """Control and a bound, open socket (the dead-man) are needed: servo on and motion."""
        client = self.check(sid, token, what, user)
        h = self._holders[sid]
        if not h.connections:
            raise ConflictError(
                f"{what} on {sid} needs a dead-man: no WebSocket is bound to your control",
                hint='connect /api/v1/ws, send {"type": "bind", "session": ..., "token": ...} '
                "and heartbeats every 100 ms",
            )
        return client

    # Connections and heartbeats ----------------------------------------------------------

    def connect(self, client: str) -> str:
        """A WebSocket opened: its server-issued connection id."""
        cid = secrets.token_urlsafe(12)
        self._connections[cid] = Connection(cid, client)
        return cid

    def bind(self, cid: str, sid: str, token: str | None, user: str | None = None) -> None:
        """Make connection ``cid`` the dead-man of the holder of ``sid`` (token needed)."""
        conn = self._connections.get(cid)
        if conn is None:
            raise ConflictError("this connection is closed", hint="reconnect the WebSocket")
        self.check(sid, token, "binding the dead-man", user)
        h = self._holders[sid]
        first = not h.connections
        h.connections.add(cid)
        conn.bound.add(sid)
        if h.orphaned:
            h.orphaned = False
            timer = self._release_timers.pop(sid, None)
            if timer is not None:
                timer.cancel()
            log.info("control of %s: %s is back (the drive stays disabled)", sid, h.client)
        self._heartbeats[sid] = time.monotonic()
        self._publish(sid)
        if first:
            for cb in list(self._bound):
                try:
                    cb(sid)
                except Exception:
                    log.exception("control listener failed")

    def disconnect(self, cid: str) -> None:
        """A WebSocket closed: the holders it was the last dead-man of lose their drive."""
        conn = self._connections.pop(cid, None)
        if conn is None:
            return
        for sid in list(conn.bound):
            h = self._holders.get(sid)
            if h is None:
                continue
            h.connections.discard(cid)
            if h.connections:
                continue
            h.orphaned = True
            self._heartbeats.pop(sid, None)
            reason = f"the WebSocket of {h.client!r} closed"
            self._notify_lost(sid, h.client, reason)
            self.audit.record("control.lost", drive=sid, ok=False, message=reason)
            try:
                loop = asyncio.get_running_loop()
            except RuntimeError:
                self._drop(sid)
                continue
            self._release_timers[sid] = loop.call_later(self.grace_s, self._lapse, sid, h.token)
            self._publish(sid)

    def _lapse(self, sid: str, token: str) -> None:
        self._release_timers.pop(sid, None)
        h = self._holders.get(sid)
        if h is not None and h.token == token and not h.connections:
            self._drop(sid)
            self.audit.record(
                "control.lapsed",
                drive=sid,
                message=f"no WebSocket came back within {self.grace_s:g} s",
                details={"client": h.client},
            )

    def heartbeat(self, cid: str, sid: str) -> bool:
        """A heartbeat from connection ``cid``; counts only when it is bound to ``sid``."""
        conn = self._connections.get(cid)
        if conn is None or sid not in conn.bound:
            return False
        self._heartbeats[sid] = time.monotonic()
        return True

    def last_heartbeat(self, sid: str) -> float | None:
        return self._heartbeats.get(sid)

    def close(self) -> None:
        for timer in self._release_timers.values():
            timer.cancel()
        self._release_timers.clear()


def _same(a: str, b: str | None) -> bool:
    """Compare tokens in constant time (a timing side channel must not reveal one)."""
    # surrogatepass: a token from a WebSocket's JSON may hold a lone surrogate; it is then
    # simply not the holder's, never an exception in the socket's handler.
    return b is not None and hmac.compare_digest(a.encode(), b.encode("utf-8", "surrogatepass"))


def _who(h: Holder) -> str:
    # The user is who people know; the client label tells their tabs apart.
    # In the single-user mode everyone is "local": the client label alone says who.
    if h.user and h.user != "local":
        return f"user {h.user!r} (client {h.client!r})"
    return f"client {h.client!r}"
