"""Fan-out of session events to WebSocket clients.

Each subscriber has its own bounded queue; when a client cannot keep up, the oldest
message is dropped and the subscriber's ``dropped`` count grows, so a slow client never
slows the drive, the backend or the other clients.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from servodesk.domain.address import ObjectAddress

Message = dict[str, Any]


@dataclass(eq=False)
class Subscriber:
    queue: asyncio.Queue[Message] = field(default_factory=lambda: asyncio.Queue(maxsize=256))
    sessions: set[str] = field(default_factory=set)
    dropped: int = 0

    def offer(self, msg: Message) -> None:
        while True:
            try:
                self.queue.put_nowait(msg)
                return
            except asyncio.QueueFull:
                try:
                    self.queue.get_nowait()
                    self.dropped += 1
                except asyncio.QueueEmpty:  # pragma: no cover - raced with the consumer
                    pass


#: The audit log: called after every successful ``Session.write_object`` with the session,
#: the address, the bytes before (None when unreadable), the bytes written and the client id.
AuditSink = Callable[[Any, ObjectAddress, bytes | None, bytes, str], None]


class EventHub:
    """The application's fan-out: WebSocket subscribers, and the audit sink for writes."""

    def __init__(self) -> None:
        self._subs: set[Subscriber] = set()
        self.audit: AuditSink | None = None

    def subscribe(self) -> Subscriber:
        sub = Subscriber()
        self._subs.add(sub)
        return sub

    def unsubscribe(self, sub: Subscriber) -> None:
        self._subs.discard(sub)

    def publish(self, msg: Message, session: str | None = None) -> None:
        """Send to every subscriber (``session`` None) or those following ``session``."""
        for sub in list(self._subs):
            if session is None or session in sub.sessions:
                sub.offer(msg)

    def watchers(self, session: str) -> int:
        return sum(1 for s in self._subs if session in s.sessions)
