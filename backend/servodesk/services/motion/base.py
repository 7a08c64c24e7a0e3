"""The motion service's state and what every part of it shares: the axes, their cached limits,
the bus reads, how a motion ends (its tasks cancelled, the dead-man disarmed, the borrowed
settings given back, listeners told, the audit record) and the status the clients see.

:class:`MotionBase` is the root of :class:`~servodesk.services.motion.MotionService`'s parts
(one class per seam: stopping, the monitor, the dead-man glue, the start template, the
motion commands, cyclic set-points, tuning motions); the service's ``__init__``
(services/motion/service.py) sets the attributes declared here.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import Any

from servodesk.domain.cia402 import CONTROLWORD, STATUSWORD, VELOCITY, VELOCITY_THRESHOLD
from servodesk.errors import ServodeskError
from servodesk.services.control import ControlService
from servodesk.services.deadman import DeadmanWatch
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.motion.axis import (
    DEFAULT_STANDSTILL,
    FAILED,
    SAFE_STOP_S,
    Axis,
    Motion,
    audit_facts,
)
from servodesk.services.motion.limits import Limits, read_int, read_limits

log = logging.getLogger(__package__)  # One logger for the motion service, as before the split.


class MotionBase:
    """State and shared steps of the motion service (set by ``MotionService.__init__``)."""

    manager: SessionManager
    control: ControlService
    hub: EventHub
    deadman_s: float
    watchdog_period: float
    cyclic_period: float
    _axes: dict[str, Axis]
    _background: set[asyncio.Task[Any]]
    _safing: dict[str, asyncio.Task[str | None]]
    _deadman: DeadmanWatch

    # Axes and limits ----------------------------------------------------------------------

    def _axis(self, sid: str) -> Axis:
        session = self.manager.get(sid)
        axis = self._axes.get(sid)
        if axis is None or axis.session is not session:
            axis = Axis(session)
            self._axes[sid] = axis
        return axis

    def invalidate_limits(self, sid: str) -> None:
        """A write went (or goes) to the drive: read the limits again before the next use."""
        axis = self._axes.get(sid)
        if axis is not None:
            axis.limits = None
            axis.limits_gen += 1

    async def limits(self, sid: str) -> Limits:
        axis = self._axis(sid)
        if axis.limits is not None:
            return axis.limits
        gen = axis.limits_gen
        lim = await read_limits(axis.session)
        if axis.limits_gen == gen:
            axis.limits = lim
        return lim

    # Bus helpers --------------------------------------------------------------------------

    async def _statusword(self, axis: Axis) -> int:
        return await read_int(axis.session, STATUSWORD) or 0

    async def _standstill(self, axis: Axis) -> bool:
        s = axis.session
        threshold = DEFAULT_STANDSTILL
        if s.profile.spec(VELOCITY_THRESHOLD) is not None:
            with contextlib.suppress(ServodeskError):
                threshold = await read_int(s, VELOCITY_THRESHOLD) or threshold
        v = await read_int(s, VELOCITY) if s.profile.spec(VELOCITY) else 0
        return abs(v or 0) <= threshold

    async def _give_back(self, axis: Axis) -> None:
        """Put back the settings the ended motion wrote (6081h, 6083h, 6084h, 6098h, ...).

        Issue "Motion safety" item 6: after a jog the CTMM04x's 6081h read 819 instead of the
        5000 the user had saved, and the next "Save to EEPROM" stored it with the user's own
        edit. They go back once the axis stands (a halt ramps down with 6084h, CiA 402-2
        §6.4.3) and not while another motion runs (that one gives them back when it ends). A
        setting that cannot be put back stays marked as written since the last save, and the
        clients are told which."""
        async with axis.lock:
            if not axis.borrowed or (axis.motion is not None and axis.motion.active):
                return
            end = time.monotonic() + SAFE_STOP_S
            with contextlib.suppress(ServodeskError):
                while not await self._standstill(axis):
                    if time.monotonic() > end:
                        break
                    await asyncio.sleep(0.02)  # Polling the drive: no event to wait on.
            given: list[str] = []
            kept: list[str] = []
            for address, (raw, _was_dirty) in list(axis.borrowed.items()):
                del axis.borrowed[address]
                if raw is None:
                    axis.session.dirty.add(address)
                    kept.append(f"{address}: it could not be read before the motion")
                    continue
                try:
                    await axis.session.write_raw(address, raw)
                    given.append(str(address))
                except ServodeskError as exc:
                    axis.session.dirty.add(address)
                    kept.append(f"{address}: {exc.message}")
            log.info("%s: settings given back %s, kept %s", axis.sid, given, kept)
            self.hub.publish(
                {"type": "motion_settings", "session": axis.sid, "restored": given, "kept": kept},
                session=axis.sid,
            )
            if kept:
                self.hub.publish({"type": "sessions_changed"})

    async def _controlword(self, axis: Axis, word: int, who: str) -> None:
        await axis.session.write_object(CONTROLWORD, word, client=who)

    async def _wait_bits(self, axis: Axis, mask: int, on: bool, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while True:
            sw = await self._statusword(axis)
            if bool(sw & mask) == on:
                return True
            if time.monotonic() > end:
                return False
            await asyncio.sleep(0.002)

    # How a motion ends ------------------------------------------------------------------

    @staticmethod
    def _cancel_tasks(motion: Motion) -> None:
        me = asyncio.current_task()
        for t in motion.tasks:
            if t is not me:
                t.cancel()

    def _end(self, axis: Axis, motion: Motion, state: str, message: str) -> None:
        if not motion.active:
            return
        motion.active = False
        motion.state = state
        motion.message = message
        self._deadman.disarm(motion)
        self._cancel_tasks(motion)
        if axis.borrowed:
            self._spawn(self._give_back(axis))
        log.info("motion on %s ended: %s (%s)", axis.sid, state, message)
        self._notify_end(motion)
        self._publish(axis)
        # After the listeners (a tuning's stop): the record is queued, it never waits on the
        # database (services/audit.py). A stop's reason is its message.
        self.control.audit.record(
            "motion.stopped",
            drive=axis.sid,
            ok=state not in FAILED,
            message=message,
            details={**audit_facts(motion), "state": state},
        )

    @staticmethod
    def _notify_end(motion: Motion) -> None:
        listeners, motion.on_end = motion.on_end, []
        for cb in listeners:
            try:
                cb(motion)
            except Exception:  # A listener's bug must not keep the axis from stopping.
                log.exception("motion end listener failed")

    def _spawn(self, coro: Any) -> None:
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        task: asyncio.Task[None] = loop.create_task(coro)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    # Status -------------------------------------------------------------------------------

    def status(self, sid: str) -> dict[str, Any]:
        axis = self._axes.get(sid)
        if axis is None:
            self.manager.get(sid)  # 404 for an unknown session.
        m = axis.motion if axis is not None else None
        if m is None:
            return {
                "session": sid,
                "active": False,
                "kind": None,
                "owner": None,
                "mode": None,
                "target": None,
                "state": "idle",
                "message": "",
            }
        return {
            "session": sid,
            "active": m.active,
            "kind": m.kind if m.kind != "halt" else None,
            "owner": m.owner or None,
            "mode": m.mode or None,
            "target": m.target,
            "state": m.state,
            "message": m.message,
        }

    def _publish(self, axis: Axis) -> None:
        self.hub.publish({"type": "motion", **self.status(axis.sid)}, session=axis.sid)
