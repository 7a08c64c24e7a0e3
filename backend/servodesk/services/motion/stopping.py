"""Stopping an axis: halt (controlword bit 8) and quick stop, by anyone, always.

A stop bumps the axis's epoch first: a start already past its checks sees it and does not
send its "go", or, when its "go" went out after the stop began, the stop sends its commands
again (``Axis.rehalt``).
"""

from __future__ import annotations

import time
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.cia402 import CW_ENABLE, CW_HALT
from servodesk.services.motion.axis import (
    Axis,
    Motion,
)
from servodesk.services.motion.base import MotionBase


class Stopping(MotionBase):
    """Halt and quick stop of an axis, and the end of its motion with them."""

    # Stopping -----------------------------------------------------------------------------

    async def halt(self, sid: str, client: str | None) -> dict[str, Any]:
        """Halt (controlword bit 8): any client, always; the axis stays enabled."""
        axis = self._axis(sid)
        sent = await self._stop_axis(
            axis, quick=False, state="halted", message="halted", who=client or "unknown"
        )
        if not sent:
            st = axis.motion
            if st is None or not st.active:
                axis.motion = Motion("halt", client or "", 0, None, time.monotonic(), False)
                axis.motion.state = "idle"
                axis.motion.message = (
                    "not in Operation enabled: nothing to halt (the halt bit is only sent "
                    "there, where it cannot enable the drive)"
                )
        return self.status(sid)

    async def stop(self, sid: str, client: str | None) -> dict[str, Any]:
        """Quick stop: any client, always."""
        axis = self._axis(sid)
        await self._stop_axis(
            axis,
            quick=True,
            state="stopped",
            message="quick stop",
            halt=False,
            who=client or "unknown",
        )
        return self.status(sid)

    async def _send_halt(self, axis: Axis, who: str) -> bool:
        """Controlword bit 8, only in Operation enabled (elsewhere 0x010F could enable)."""
        sw = await self._statusword(axis)
        if cia402.decode_state(sw) is not cia402.State.OPERATION_ENABLED:
            return False
        await self._controlword(axis, CW_ENABLE | CW_HALT, who)
        return True

    async def _stop_axis(
        self,
        axis: Axis,
        *,
        quick: bool,
        state: str,
        message: str,
        halt: bool = True,
        who: str = "servodesk",
    ) -> bool:
        """End the motion and stop the axis: halt, then quick stop when asked."""
        axis.epoch += 1
        motion = axis.motion
        if motion is not None and motion.active:
            self._end(axis, motion, state, message)
        elif motion is not None:
            motion.state, motion.message = state, message
        sent = False
        s = axis.session
        try:
            if halt:
                sent = await self._send_halt(axis, who)
            if quick:
                await s.command("quick_stop")
                sent = True
        finally:
            # A start that was already past its checks may have sent its "go" after us.
            async with axis.lock:
                if axis.rehalt:
                    axis.rehalt = False
                    if halt:
                        await self._send_halt(axis, who)
                    if quick:
                        await s.command("quick_stop")
        self._publish(axis)
        return sent
