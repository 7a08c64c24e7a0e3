"""Tuning motions (services/tuning/, services/tuning/own/): a motion of kind ``tuning``
under the client's dead-man, the profile-position moves it makes, and its end.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CW_ENABLE,
    CW_IMMEDIATE,
    CW_NEW_SETPOINT,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    SW_SETPOINT_ACK,
    SW_TARGET_REACHED,
    TARGET_POSITION,
)
from servodesk.domain.datatypes import Value
from servodesk.errors import DriveStateError
from servodesk.services.motion.axis import (
    PP,
    Axis,
    Motion,
)
from servodesk.services.motion.limits import check_position, encode_writes, need_mode, read_int
from servodesk.services.motion.start import StartTemplate


class TuningMotions(StartTemplate):
    """Start, move and end a tuning motion."""

    # Tuning motion (services/tuning/) ----------------------------------------------------

    async def start_tuning_motion(
        self,
        sid: str,
        client: str,
        *,
        window: tuple[int, int] | None,
        message: str,
        on_end: Callable[[Motion], None] | None = None,
    ) -> Motion:
        """Begin a motion of kind ``tuning`` under the client's dead-man, like a jog.

        Nothing moves yet. With ``window`` (lowest and highest position the tuning may reach),
        the window is checked against the software position limits (607Dh) and the target
        range, and the mode becomes profile position: the tuning then moves the axis with
        :meth:`tuning_move`. Without it the mode is left alone (servodesk's own tuning excites
        the axis through the drive's test signal while the loops hold it). A missing
        heartbeat, the socket closing, losing control, a halt, a quick stop or the drive
        leaving Operation enabled end the motion (the axis is halted and, for the dead-man,
        quick-stopped) and call ``on_end``.
        """
        started = time.monotonic()
        axis = self._axis(sid)
        if window is not None:
            need_mode(axis, PP, "the tuning motion")
            lim = await self.limits(sid)
            for end in window:
                check_position(float(end), lim, "travel_window_rev")
            encode_writes(axis, [(TARGET_POSITION, window[0]), (TARGET_POSITION, window[1])])
        async with self._starting(axis):
            await self._require_enabled(axis)
            if window is not None:
                await self._ensure_mode(axis, PP, client)
            motion = Motion(
                "tuning", client, PP if window is not None else 0, None, started, message=message
            )
            if on_end is not None:
                motion.on_end.append(on_end)
            self._begin(axis, motion)
        return motion

    async def tuning_move(
        self,
        sid: str,
        motion: Motion,
        target: int,
        *,
        velocity: int | None = None,
        acceleration: int | None = None,
        deceleration: int | None = None,
        timeout: float = 30.0,
        must_reach: bool = True,
    ) -> int:
        """One absolute profile-position move of a tuning motion; returns the position once
        the drive reports the target reached (statusword bit 10, set-point acknowledge 0).

        Raises :class:`DriveStateError` when the motion ended meanwhile (dead-man, stop) or
        the target is not reached within ``timeout`` seconds; with ``must_reach`` False it
        returns the position then instead (a drive tuning itself may hunt around the target
        for a while: the next move must still come).
        """
        axis = self._axis(sid)
        self._still_tuning(axis, motion)
        lim = await self.limits(sid)
        check_position(float(target), lim, "target")
        plan: list[tuple[ObjectAddress, Value]] = []
        if velocity is not None:
            plan.append((PROFILE_VELOCITY, velocity))
        if acceleration is not None:
            plan.append((PROFILE_ACC, acceleration))
        if deceleration is not None:
            plan.append((PROFILE_DEC, deceleration))
        plan.append((TARGET_POSITION, target))
        writes = encode_writes(axis, plan)
        bits = CW_ENABLE | CW_IMMEDIATE
        who = motion.owner
        async with self._starting(axis) as epoch:
            self._still_tuning(axis, motion)
            await self._write_all(axis, writes, who)
            await self._controlword(axis, bits, who)
            await self._go(axis, epoch, bits | CW_NEW_SETPOINT, who)
            acked = await self._wait_bits(axis, SW_SETPOINT_ACK, True, 0.3)
            await self._controlword(axis, bits, who)
            if not acked:
                raise DriveStateError(
                    "the drive did not acknowledge the set-point (statusword bit 12)",
                    hint="check the drive's error code and the mode of operation",
                )
        axis.last_target = float(target)
        motion.target = float(target)
        end = time.monotonic() + timeout
        while True:
            self._still_tuning(axis, motion)
            sw = await self._statusword(axis)
            if sw & SW_TARGET_REACHED and not sw & SW_SETPOINT_ACK:
                return await read_int(axis.session, POSITION) or 0
            if time.monotonic() > end:
                if not must_reach:
                    return await read_int(axis.session, POSITION) or 0
                raise DriveStateError(
                    f"the axis did not reach {target} within {timeout:g} s",
                    hint="check the drive's speed, ramps and torque limit",
                )
            await asyncio.sleep(0.01)

    async def end_tuning_motion(self, sid: str, motion: Motion, state: str, message: str) -> None:
        """End a tuning motion that finished its moves (the axis stands; nothing is sent)."""
        axis = self._axis(sid)
        self._end(axis, motion, state, message)

    @staticmethod
    def _still_tuning(axis: Axis, motion: Motion) -> None:
        if axis.motion is not motion or not motion.active:
            raise DriveStateError(
                f"the tuning motion ended ({motion.state}: {motion.message})",
                hint="start the tuning again once the cause is cleared",
            )
