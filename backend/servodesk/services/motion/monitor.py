"""The monitor every motion runs while it lasts: the ends of motions the drive reports.

A move ends when the drive reports its target reached, a homing run when the statusword shows
homing attained, a homing error or an interruption (or its time-out passes), and any motion
when the drive leaves Operation enabled or stops answering. Continuous motion (jog, profile
velocity) is halted before a software position limit (:func:`~.limits.limit_ahead`).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time

from servodesk.domain import cia402
from servodesk.domain.cia402 import (
    MODE_DISPLAY,
    POSITION,
    SW_SETPOINT_ACK,
    SW_TARGET_REACHED,
    VELOCITY,
)
from servodesk.errors import LinkError, ServodeskError
from servodesk.services import homing
from servodesk.services.motion.axis import (
    HOMING_SETTLE_S,
    Axis,
    Motion,
)
from servodesk.services.motion.limits import LIMIT_GUARD_PERIOD, limit_ahead, read_int
from servodesk.services.motion.stopping import Stopping

log = logging.getLogger(__package__)  # One logger for the motion service, as before the split.


class Monitor(Stopping):
    """The monitor task of a running motion."""

    async def _monitor(self, axis: Axis, motion: Motion) -> None:
        """Ends a move at its target, a homing run at its end, and any motion when the drive
        leaves Operation enabled; halts continuous motion before a software position limit."""
        guard = motion.guard
        if motion.kind == "move":
            period = 0.02
        elif guard is not None:
            period = LIMIT_GUARD_PERIOD
        else:
            period = 0.05
        s = axis.session
        failures = 0
        last: tuple[float, int] | None = None
        seen_running = False
        settled_since: float | None = None
        while motion.active:
            await asyncio.sleep(period)
            try:
                sw = await self._statusword(axis)
                pos = await read_int(s, POSITION) if guard is not None else None
                now = time.monotonic()
                vel = await read_int(s, VELOCITY) if motion.read_velocity else None
                mode = await read_int(s, MODE_DISPLAY) if motion.kind == "homing" else None
            except LinkError as exc:
                failures += 1
                if failures >= 3:
                    self._end(axis, motion, "error", f"the drive does not answer: {exc.message}")
                    return
                continue
            except ServodeskError:
                continue
            failures = 0
            state = cia402.decode_state(sw)
            if state is not cia402.State.OPERATION_ENABLED:
                self._end(
                    axis, motion, "error", f"the drive left Operation enabled ({state.value})"
                )
                return
            if motion.kind == "move" and sw & SW_TARGET_REACHED and not sw & SW_SETPOINT_ACK:
                pos = await read_int(s, POSITION)
                self._end(axis, motion, "reached", f"target reached at {pos}")
                return
            if motion.kind == "homing":
                run = homing.current_run(s)
                if run is not None and run.timed_out(now):
                    # The run's time-out (the user's, or from the estimate): stop it as the
                    # dead-man does, halt (bit 4 low interrupts homing, CiA 402-2 §6.8.1)
                    # then quick stop, and say so.
                    late = run.timeout_message(now)
                    log.warning("homing on %s: %s", axis.sid, late)
                    await self._stop_for(
                        axis, motion, late, quick=True, state="timeout", who="homing time-out"
                    )
                    return
                hs = homing.decode(sw, mode)
                if hs == "running":
                    seen_running, settled_since = True, None
                    continue
                settled_since = settled_since if settled_since is not None else now
                if not seen_running and now - settled_since < HOMING_SETTLE_S:
                    continue
                where: int | None = None
                with contextlib.suppress(ServodeskError):
                    where = await read_int(s, POSITION)
                if hs == "attained":
                    self._end(axis, motion, "done", f"homing attained at {where}")
                elif hs == "error":
                    self._end(axis, motion, "error", f"homing error at {where} (bit 13)")
                else:
                    self._end(axis, motion, "halted", f"homing interrupted at {where}")
                return
            if guard is not None and pos is not None:
                why = limit_ahead(motion, guard, pos, vel, last, now)
                last = (now, pos)
                if why is not None and axis.motion is motion and motion.active:
                    log.warning("%s on %s: %s", motion.kind, axis.sid, why)
                    await self._stop_for(
                        axis,
                        motion,
                        why,
                        quick=False,
                        state="halted",
                        who="software position limit",
                    )
                    return

    async def _stop_for(
        self, axis: Axis, motion: Motion, why: str, *, quick: bool, state: str, who: str
    ) -> None:
        """The monitor stops the axis itself (halt, and quick stop when asked) for ``why``;
        a stop that cannot be sent ends the motion in error saying so."""
        try:
            await self._stop_axis(
                axis, quick=quick, state=state, message=why, who=f"servodesk ({who})"
            )
        except ServodeskError as exc:
            what = "stop" if quick else "halt"
            self._end(axis, motion, "error", f"{why}; the {what} failed: {exc.message}")
