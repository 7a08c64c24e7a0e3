"""Control ownership of drive sessions, connected clients and their heartbeats.

One client holds control of a session at a time; everyone else watches (DESIGN.md, "Rules that
hold everywhere"). A client is a browser tab or a script, named by the id it sends in the
``X-Servodesk-Client`` header and the ``client`` query parameter of the WebSocket.

The rules, as a commissioning engineer expects them:

- Nobody holds control: any client may write objects, send state commands, store and restore
  (a script or a second tab that only sets parameters need not take control first).
- A client holds control: writes and state commands from every other client are refused with
  409 naming the owner. Halt, quick stop (``motion/halt``, ``motion/stop``, the ``quick_stop``
  state command) are never refused: anyone who sees the axis move may stop it.
- Motion (jog, moves, velocity, torque, cyclic) needs control AND a live WebSocket of the same
  client, because its dead-man heartbeat arrives over that socket.
- ``take`` when another client holds control is refused (409 naming the owner); ``force_take``
  needs ``confirm: true``. Taking control away, releasing it, or the owner's last WebSocket
  closing stops the motion the owner started.
- Control stays with a client whose WebSockets all closed for ``grace_s`` (a page reload keeps
  it), then it is released. A client that never opened a WebSocket (a script) keeps control
  until it releases it or someone force-takes it.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from servodesk.errors import ConflictError, ValidationError
from servodesk.services.events import EventHub

log = logging.getLogger(__name__)

#: Called as ``listener(session, previous_owner, reason)`` when a client loses control.
LostListener = Callable[[str, str, str], None]
#: Called as ``listener(client)`` when a client's last WebSocket closed.
GoneListener = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class Holder:
    client: str
    since: float  # time.time() when control was taken


class ControlService:
    """Who holds which session, which clients are connected, and their last heartbeats."""

    def __init__(self, hub: EventHub, *, grace_s: float = 5.0) -> None:
        self.hub = hub
        self.grace_s = grace_s
        self._holders: dict[str, Holder] = {}
        self._sockets: dict[str, int] = {}
        self._heartbeats: dict[tuple[str, str], float] = {}
        self._release_timers: dict[str, asyncio.TimerHandle] = {}
        self._lost: list[LostListener] = []
        self._gone: list[GoneListener] = []

    # Listeners --------------------------------------------------------------------------

    def on_lost(self, listener: LostListener) -> None:
        self._lost.append(listener)

    def on_gone(self, listener: GoneListener) -> None:
        self._gone.append(listener)

    # Ownership --------------------------------------------------------------------------

    def owner(self, sid: str) -> str | None:
        h = self._holders.get(sid)
        return h.client if h else None

    def info(self, sid: str, client: str | None) -> dict[str, Any]:
        h = self._holders.get(sid)
        return {
            "session": sid,
            "owner": h.client if h else None,
            "since": h.since if h else None,
            "you": h is not None and client is not None and h.client == client,
        }

    def take(self, sid: str, client: str) -> None:
        h = self._holders.get(sid)
        if h is not None and h.client != client:
            raise ConflictError(
                f"client {h.client!r} holds control of {sid}",
                hint='ask them to release it, or send {"action": "force_take", "confirm": true}',
            )
        if h is None:
            self._set(sid, client)

    def force_take(self, sid: str, client: str, confirm: bool) -> None:
        h = self._holders.get(sid)
        if h is not None and h.client != client and not confirm:
            raise ConflictError(
                f"client {h.client!r} holds control of {sid}; taking it over stops the "
                "motion it started and needs confirmation",
                hint='send {"action": "force_take", "confirm": true} to go ahead',
            )
        if h is not None and h.client == client:
            return
        self._set(sid, client)
        if h is not None:
            self._notify_lost(sid, h.client, f"control taken over by client {client!r}")

    def release(self, sid: str, client: str) -> None:
        h = self._holders.get(sid)
        if h is None:
            return
        if h.client != client:
            raise ConflictError(
                f"client {h.client!r} holds control of {sid}, not {client!r}",
                hint="only the owner can release control; force_take takes it over",
            )
        self._set(sid, None)
        self._notify_lost(sid, client, f"client {client!r} released control")

    def forget_session(self, sid: str) -> None:
        """The session closed: nobody holds it any more."""
        if self._holders.pop(sid, None) is not None:
            self._publish(sid)
        for key in [k for k in self._heartbeats if k[1] == sid]:
            del self._heartbeats[key]

    def _set(self, sid: str, client: str | None) -> None:
        if client is None:
            self._holders.pop(sid, None)
        else:
            self._holders[sid] = Holder(client, time.time())
        log.info("control of %s: %s", sid, client or "released")
        self._publish(sid)

    def _publish(self, sid: str) -> None:
        h = self._holders.get(sid)
        # Everyone sees who holds control (not only the session's watchers): the session list
        # of every tab shows it.
        self.hub.publish(
            {
                "type": "control",
                "session": sid,
                "owner": h.client if h else None,
                "since": h.since if h else None,
            }
        )

    def _notify_lost(self, sid: str, client: str, reason: str) -> None:
        for cb in list(self._lost):
            try:
                cb(sid, client, reason)
            except Exception:  # A listener's bug must not keep control in a half state.
                log.exception("control listener failed")

    # Checks used by the API -------------------------------------------------------------

    def check_write(self, sid: str, client: str | None) -> None:
        """Writes are refused only when another client holds control."""
        h = self._holders.get(sid)
        if h is not None and h.client != client:
            raise ConflictError(
                f"client {h.client!r} holds control of {sid}; this write was not sent",
                hint="take control first (they must release it, or use force_take)",
            )

    def check_motion(self, sid: str, client: str | None) -> str:
        """Motion needs control and a live WebSocket of the same client (the dead-man)."""
        if not client:
            raise ValidationError(
                "motion needs a client id",
                field="X-Servodesk-Client",
                hint="send the header X-Servodesk-Client: <id> and connect the WebSocket "
                "with ?client=<id>",
            )
        h = self._holders.get(sid)
        if h is None:
            raise ConflictError(
                f"nobody holds control of {sid}; motion needs control",
                hint='take control first: POST /control {"action": "take"}',
            )
        if h.client != client:
            raise ConflictError(
                f"client {h.client!r} holds control of {sid}; motion refused",
                hint="only the client holding control can start motion",
            )
        if not self._sockets.get(client):
            raise ConflictError(
                f"client {client!r} has no open WebSocket; motion needs its dead-man heartbeat",
                hint=f"connect /api/v1/ws?client={client} and send heartbeats every 100 ms",
            )
        return client

    # Clients and heartbeats -------------------------------------------------------------

    def connected(self, client: str) -> bool:
        return self._sockets.get(client, 0) > 0

    def socket_opened(self, client: str) -> None:
        self._sockets[client] = self._sockets.get(client, 0) + 1
        timer = self._release_timers.pop(client, None)
        if timer is not None:
            timer.cancel()

    def socket_closed(self, client: str) -> None:
        n = self._sockets.get(client, 0) - 1
        if n > 0:
            self._sockets[client] = n
            return
        self._sockets.pop(client, None)
        for key in [k for k in self._heartbeats if k[0] == client]:
            del self._heartbeats[key]
        # Motion stops at once (the tab is gone); control is kept a moment for a reload.
        for cb in list(self._gone):
            try:
                cb(client)
            except Exception:
                log.exception("client listener failed")
        if any(h.client == client for h in self._holders.values()):
            loop = asyncio.get_running_loop()
            self._release_timers[client] = loop.call_later(self.grace_s, self._release_gone, client)

    def _release_gone(self, client: str) -> None:
        self._release_timers.pop(client, None)
        if self.connected(client):
            return
        for sid, h in list(self._holders.items()):
            if h.client == client:
                self._set(sid, None)

    def heartbeat(self, client: str, sid: str) -> None:
        self._heartbeats[(client, sid)] = time.monotonic()

    def last_heartbeat(self, client: str, sid: str) -> float | None:
        return self._heartbeats.get((client, sid))

    def close(self) -> None:
        for timer in self._release_timers.values():
            timer.cancel()
        self._release_timers.clear()
