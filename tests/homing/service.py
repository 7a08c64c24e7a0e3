"""The motion service on simulated drives, without the API: a session per twin on a virtual
CAN bus, the event hub's messages recorded, and a stand-in for the control service whose
holder and heartbeats the test sets (so these tests do not depend on how the API checks
control)."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from typing import Any

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.services.audit import DISCARD
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.motion import MotionService
from servodesk.services.session import Session
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.engine import SimulatedDrive


class StandInControl:
    """What the motion service asks of the control service: who holds a session, whether its
    dead-man is bound, the last heartbeat, and listeners for a lost holder. Listeners of other
    events (``on_bound``, ...) are taken and never called: these tests are about homing."""

    def __init__(self) -> None:
        self.holder: str | None = None
        self.beat: float | None = None
        self.lost: list[Callable[[str, str, str], None]] = []
        self.audit = DISCARD  # Motion records its start and end there (services/audit.py).

    def on_lost(self, cb: Callable[[str, str, str], None]) -> None:
        self.lost.append(cb)

    def __getattr__(self, name: str) -> Callable[[Any], None]:
        if name.startswith("on_"):
            return lambda cb: None
        raise AttributeError(name)

    def owner(self, sid: str) -> str | None:
        return self.holder

    def info(self, sid: str, token: str | None) -> dict[str, Any]:
        bound = self.holder is not None
        return {"session": sid, "owner": self.holder, "you": False, "bound": bound}

    def last_heartbeat(self, *args: str) -> float | None:
        return self.beat

    def lose(self, sid: str, new_holder: str | None, reason: str) -> None:
        """Control moves to ``new_holder`` (None: released); the old holder's motion stops."""
        old, self.holder = self.holder, new_holder
        for cb in list(self.lost):
            cb(sid, old or "", reason)


@dataclass
class Rig:
    motion: MotionService
    control: StandInControl
    session: Session
    drive: SimulatedDrive
    messages: list[dict[str, Any]] = field(default_factory=list)
    _beats: asyncio.Task[None] | None = None

    @property
    def sid(self) -> str:
        return self.session.id

    def of_type(self, kind: str) -> list[dict[str, Any]]:
        return [m for m in self.messages if m.get("type") == kind]

    def start_heartbeats(self, period: float = 0.05) -> None:
        async def beat() -> None:
            while True:
                self.control.beat = time.monotonic()
                await asyncio.sleep(period)

        self.control.beat = time.monotonic()
        self._beats = asyncio.get_running_loop().create_task(beat())

    def stop_heartbeats(self) -> None:
        if self._beats is not None:
            self._beats.cancel()
            self._beats = None

    async def enable(self, client: str = "A") -> None:
        self.control.holder = client
        st = await self.session.command("enable")
        assert st.state == "Operation enabled", st

    async def wait_until(self, pred: Callable[[], bool], timeout: float) -> bool:
        """Poll ``pred`` (the simulated drive's state: nothing to wait on) until it holds."""
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end:
                return False
            await asyncio.sleep(0.02)
        return True

    async def wait_motion_end(self, timeout: float) -> dict[str, Any]:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            st = self.motion.status(self.sid)
            if not st["active"]:
                return st
            await asyncio.sleep(0.02)
        st = self.motion.status(self.sid)
        raise AssertionError(f"the motion did not end in {timeout} s: {st}")


@contextlib.asynccontextmanager
async def rig(channel: str, profile_id: str, *, deadman_s: float = 1.0) -> AsyncIterator[Rig]:
    """One twin of ``profile_id`` (node 1) on ``channel``, its session and a motion service.

    Tests that are not about the dead-man keep its second (as tests/operation do), so that a
    starved heartbeat task on a busy 2-core machine does not stop their run."""
    catalog = ProfileCatalog()
    sim = await asyncio.to_thread(
        SimulatedBus.start, drives=[(profile_id, 1)], channel=channel, catalog=catalog
    )
    hub = EventHub()
    manager = SessionManager(catalog, hub, sdo_timeout=0.5)
    control = StandInControl()
    sub = hub.subscribe()
    recorder: asyncio.Task[None] | None = None
    try:
        session = await manager.open(
            LinkParams(interface="virtual", channel=channel, node_id=1, timeout=0.5),
            profile_id,
            simulated=True,
        )
        sub.sessions.add(session.id)
        motion = MotionService(manager, control, hub, deadman_s=deadman_s)  # type: ignore[arg-type]
        r = Rig(motion, control, session, sim.drives[0])

        async def record() -> None:
            while True:
                r.messages.append(await sub.queue.get())

        recorder = asyncio.get_running_loop().create_task(record())
        try:
            yield r
        finally:
            r.stop_heartbeats()
            with contextlib.suppress(Exception):
                await motion.shutdown()
    finally:
        if recorder is not None:
            recorder.cancel()
        hub.unsubscribe(sub)
        await manager.close_all()
        await asyncio.to_thread(sim.stop)
