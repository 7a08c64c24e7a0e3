"""The dead-man glue: what happens when the holder of control is lost.

Every motion is handed to the dead-man's thread (services/deadman.py) when it starts; when
the holder's heartbeats are ``deadman_s`` old the thread puts a quick stop on the wire and
the loop does the orderly rest (:meth:`LostHolder._lost_operator`: halt, quick stop, the
``deadman`` message with its latencies). Losing the holder (its last bound socket closing,
release, force take) also brings the drive to Switch on disabled at standstill
(:meth:`LostHolder.make_safe`, docs/safety.md "Losing the holder makes the drive safe"). The
drive's own watchdog is armed while a dead-man is bound; a session closing and the backend
shutting down stop every motion the same way.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import Any

from servodesk.domain import cia402
from servodesk.errors import ServodeskError
from servodesk.services.deadman import thread_stop
from servodesk.services.motion.axis import ENERGISED, SAFE_STOP_S, Axis, Motion
from servodesk.services.motion.stopping import Stopping

log = logging.getLogger(__package__)  # One logger for the motion service, as before the split.


class LostHolder(Stopping):
    """The dead-man's stop, making a drive safe, the drive's watchdog, shutdown."""

    def _arm(self, axis: Axis, motion: Motion, loop: asyncio.AbstractEventLoop) -> None:
        """Hand the motion to the dead-man's thread: it stops the axis when the holder's
        heartbeats (services/control) are ``deadman_s`` old, without the event loop."""
        sid, control = axis.sid, self.control
        # The dead-man counts from when the motion really starts, not from the request: a
        # start that waited (the axis lock held while the last motion's settings are given
        # back at standstill) was otherwise stopped at once, its heartbeat older than the
        # deadline (bench_deadman: 1 run in 20, the stop before the client's last heartbeat).
        armed = time.monotonic()

        def last() -> float:
            return max(control.last_heartbeat(sid) or 0.0, motion.started, armed)

        def fired(since: float, sent: float | None) -> None:
            if not loop.is_closed():
                loop.call_soon_threadsafe(self._deadman_fired, axis, motion, since, sent)

        self._deadman.arm(
            motion,
            deadline_s=self.deadman_s,
            last=last,
            stop=thread_stop(axis.session),
            fired=fired,
        )

    def _deadman_fired(self, axis: Axis, motion: Motion, since: float, sent: float | None) -> None:
        """On the loop, after the thread's stop frame: the orderly rest of the stop."""
        if not motion.active:
            return
        ms = round((time.monotonic() - since) * 1000)
        self._spawn(
            self._lost_operator(
                axis,
                motion,
                f"no heartbeat from client {motion.owner!r} for {ms} ms",
                since,
                frame_at=sent,
            )
        )

    async def _lost_operator(
        self,
        axis: Axis,
        motion: Motion,
        reason: str,
        since: float,
        *,
        frame_at: float | None = None,
    ) -> None:
        """Dead-man: halt, then quick stop; report the latency from ``since``.

        ``frame_at``: when the dead-man's thread already put a quick stop on the wire
        (monotonic); the halt is then skipped by itself (the drive left Operation enabled)."""
        try:
            t0 = time.monotonic()
            axis.epoch += 1
            self._end(axis, motion, "deadman", reason)
            halted = await self._send_halt(axis, f"dead-man of {motion.owner}")
            t_halt = time.monotonic()
            await axis.session.command("quick_stop")
            t_stop = time.monotonic()
            async with axis.lock:
                if axis.rehalt:
                    axis.rehalt = False
                    await axis.session.command("quick_stop")
        except ServodeskError as exc:
            log.error("dead-man stop of %s failed: %s", axis.sid, exc.message)
            self.hub.publish(
                {
                    "type": "deadman",
                    "session": axis.sid,
                    "reason": reason,
                    "latency_ms": None,
                    "message": f"the stop could not be sent: {exc.message}",
                },
                session=axis.sid,
            )
            return
        first = t_halt if halted else t_stop
        if frame_at is not None:
            first = min(first, frame_at)
        msg = {
            "type": "deadman",
            "session": axis.sid,
            "reason": reason,
            "client": motion.owner,
            "latency_ms": round((first - since) * 1000.0, 1),
            "detect_ms": round((t0 - since) * 1000.0, 1),
            "quick_stop_ms": round((t_stop - since) * 1000.0, 1),
            "stop_frame_ms": None if frame_at is None else round((frame_at - since) * 1000.0, 1),
            "from": "dead-man thread" if frame_at is not None else "event loop",
        }
        log.warning("dead-man on %s: %s (%s ms)", axis.sid, reason, msg["latency_ms"])
        self.hub.publish(msg, session=axis.sid)

    # Clients and lifecycle ----------------------------------------------------------------

    def _control_bound(self, sid: str) -> None:
        """The holder's dead-man is on: arm the drive's own watchdog too (a dead PC)."""
        self._spawn(self._arm_watchdog(sid))

    async def _arm_watchdog(self, sid: str) -> None:
        try:
            session = self.manager.get(sid)
            await session.link.arm_watchdog()
        except ServodeskError as exc:
            log.warning("%s: the drive's watchdog was not armed: %s", sid, exc.message)
        self._publish_protection(sid)

    async def _disarm_watchdog(self, sid: str) -> None:
        try:
            session = self.manager.get(sid)
        except ServodeskError:
            return
        if session.link.watchdog is None:
            return
        try:
            await session.link.disarm_watchdog()
        except ServodeskError as exc:
            log.warning("%s: the drive's watchdog was not disarmed: %s", sid, exc.message)
        self._publish_protection(sid)

    def _publish_protection(self, sid: str) -> None:
        with contextlib.suppress(ServodeskError):
            self.hub.publish({"type": "protection", "session": sid, **self.protection(sid)})

    def _control_lost(self, sid: str, client: str, reason: str) -> None:
        """The holder is gone or changed (services/control): make the drive safe."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        task = loop.create_task(self.make_safe(sid, client, reason))
        self._background.add(task)
        task.add_done_callback(self._background.discard)
        self._safing[sid] = task

    async def settled(self, sid: str) -> None:
        """Wait until making the drive safe after a lost holder is done: a servo on or a
        motion of the next holder must not be undone by it a moment later."""
        task = self._safing.get(sid)
        if task is not None and not task.done():
            with contextlib.suppress(Exception):
                await asyncio.wait_for(asyncio.shield(task), SAFE_STOP_S + 2.0)

    async def make_safe(self, sid: str, client: str, reason: str) -> str | None:
        """Stop the axis and bring the drive to Switch on disabled; the state it ended in.

        The motion (if any) ends as the dead-man ends it: halt, then quick stop. The power
        stage is switched off only at standstill (or once the drive left Operation enabled
        by itself): disable voltage while the axis still brakes would let it coast (CiA 402-2
        §6.2, transition 12 from Quick stop active, 9 from Operation enabled). A drive that
        was never enabled is left alone. Nobody is in control meanwhile, so nothing the user
        asks can race it; a new holder's start waits for the axis lock.
        """
        since = time.monotonic()
        try:
            session = self.manager.get(sid)
        except ServodeskError:
            return None  # The session closed meanwhile: its close stopped the motion.
        axis = self._axis(sid)
        m = axis.motion
        moving = m is not None and m.active
        if m is not None and m.active:
            await self._lost_operator(axis, m, reason, since)
        try:
            state = cia402.decode_state(await self._statusword(axis))
            acted = moving or state in ENERGISED
            if state in ENERGISED:
                if state is cia402.State.OPERATION_ENABLED and not await self._standstill(axis):
                    await session.command("quick_stop")
                end = time.monotonic() + SAFE_STOP_S
                while not await self._standstill(axis):
                    if time.monotonic() > end:
                        break
                    await asyncio.sleep(0.02)  # Polling the drive: no event to wait on.
                await session.command("disable")
            final = cia402.decode_state(await self._statusword(axis))
        except ServodeskError as exc:
            log.error("making %s safe failed: %s", sid, exc.message)
            # To every client, not only the session's watchers: it is about control, which
            # every tab shows, and the holder's own tab may have closed.
            self.hub.publish(
                {
                    "type": "safe_state",
                    "session": sid,
                    "reason": reason,
                    "client": client,
                    "ok": False,
                    "message": f"the drive could not be disabled: {exc.message}",
                }
            )
            return None
        if self.control.owner(sid) is None or not self.control.info(sid, None)["bound"]:
            # Nobody's dead-man is on any more: the drive's own watchdog goes back too.
            await self._disarm_watchdog(sid)
        if acted:
            log.warning("%s: %s; the drive is now %s", sid, reason, final.value)
            # To every client, not only the session's watchers: it is about control, which
            # every tab shows, and the holder's own tab may have closed.
            self.hub.publish(
                {
                    "type": "safe_state",
                    "session": sid,
                    "reason": reason,
                    "client": client,
                    "ok": final is cia402.State.SWITCH_ON_DISABLED,
                    "state": final.value,
                    "message": f"{reason}: the axis was stopped and the drive disabled "
                    f"({final.value})",
                }
            )
        return final.value

    async def stop_session(self, sid: str, reason: str) -> None:
        """The session is about to close: stop its motion first."""
        await self._disarm_watchdog(sid)
        axis = self._axes.get(sid)
        if axis is None:
            return
        m = axis.motion
        if m is not None and m.active:
            with contextlib.suppress(ServodeskError):
                await self._stop_axis(axis, quick=True, state="stopped", message=reason)
        self._axes.pop(sid, None)

    async def shutdown(self) -> None:
        """Backend shutdown: every running motion is halted and quick-stopped."""
        for axis in list(self._axes.values()):
            m = axis.motion
            if m is not None and m.active:
                try:
                    await self._lost_operator(axis, m, "the server shuts down", time.monotonic())
                except ServodeskError:
                    log.exception("stopping %s at shutdown", axis.sid)
        for session in self.manager.all():
            await self._disarm_watchdog(session.id)
        # Stops already under way (a socket that just closed) finish; nothing else runs on.
        if self._background:
            await asyncio.wait(list(self._background), timeout=2.0)
        for axis in self._axes.values():
            if axis.motion is not None:
                self._cancel_tasks(axis.motion)
        self._deadman.close()

    # Status -------------------------------------------------------------------------------

    def protection(self, sid: str) -> dict[str, Any]:
        """What stops this drive when its operator is lost, as the Operation page shows it."""
        session = self.manager.get(sid)
        thread = thread_stop(session) is not None
        ms = round(self.deadman_s * 1000)
        path = "dead-man thread" if thread else "event loop"
        where = (
            f"servodesk's own thread sends the quick stop on the {session.link.fieldbus} link"
            if thread
            else f"the quick stop goes out through the event loop ({session.link.fieldbus} "
            "has no path beside it yet)"
        )
        return {
            "deadman_ms": ms,
            "stop_path": path,
            "drive_watchdog": session.link.watchdog,
            "summary": f"Heartbeats older than {ms} ms stop the axis: {where}. "
            + (
                f"If this PC dies: {session.link.watchdog}."
                if session.link.watchdog
                else "No drive-side watchdog is armed: if this PC dies, the drive's own "
                "communication settings decide."
            ),
        }
