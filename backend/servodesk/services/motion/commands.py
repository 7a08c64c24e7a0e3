"""The motion commands in the profile modes: jog, profile velocity, profile torque, profile
position (one set-point, or one more of a set of set-points) and homing.

Each follows the start template (start.py): its checks against the family's modes and the
drive's limits (limits.py) before anything is sent, then the template's steps.
"""

from __future__ import annotations

import contextlib
import time
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CW_ENABLE,
    CW_IMMEDIATE,
    CW_NEW_SETPOINT,
    CW_RELATIVE,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    SW_SETPOINT_ACK,
    TARGET_POSITION,
    TARGET_TORQUE,
    TARGET_VELOCITY,
    TORQUE_SLOPE,
    VELOCITY,
)
from servodesk.domain.datatypes import Value
from servodesk.errors import ConflictError, DriveStateError, ValidationError
from servodesk.services import homing
from servodesk.services.motion.axis import (
    HM,
    PP,
    PV,
    TQ,
    Motion,
)
from servodesk.services.motion.limits import (
    check_abs,
    check_position,
    check_toward_limit,
    encode_writes,
    limit_guard,
    need_mode,
    read_int,
)
from servodesk.services.motion.start import StartTemplate


class ProfileMotions(StartTemplate):
    """Jog, velocity, torque, move and home."""

    # Motion commands ----------------------------------------------------------------------

    async def jog(self, sid: str, client: str, velocity: int, acceleration: int) -> dict[str, Any]:
        """Profile velocity at ``velocity`` while the client's heartbeats arrive."""
        started = time.monotonic()
        axis = self._axis(sid)
        need_mode(axis, PV, "jog")
        lim = await self.limits(sid)
        check_abs(velocity, lim.max_velocity, "max_velocity", "velocity", lim)
        check_abs(acceleration, lim.max_acceleration, "max_acceleration", "acceleration", lim)
        check_abs(acceleration, lim.max_deceleration, "max_deceleration", "acceleration", lim)
        writes = encode_writes(
            axis,
            [(PROFILE_ACC, acceleration), (PROFILE_DEC, acceleration), (TARGET_VELOCITY, velocity)],
        )
        await check_toward_limit(axis, lim, velocity, "velocity")
        guard = await limit_guard(axis, lim, velocity, acceleration, acceleration)
        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            await self._ensure_mode(axis, PV, client)
            await self._write_all(axis, writes, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            self._begin(
                axis,
                Motion("jog", client, PV, velocity, started, message=f"jog at {velocity}", **guard),
            )
        return self.status(sid)

    async def velocity(
        self,
        sid: str,
        client: str,
        velocity: int,
        acceleration: int | None,
        deceleration: int | None,
    ) -> dict[str, Any]:
        started = time.monotonic()
        axis = self._axis(sid)
        need_mode(axis, PV, "profile velocity")
        lim = await self.limits(sid)
        check_abs(velocity, lim.max_velocity, "max_velocity", "velocity", lim)
        plan: list[tuple[ObjectAddress, Value]] = []
        if acceleration is not None:
            check_abs(acceleration, lim.max_acceleration, "max_acceleration", "acceleration", lim)
            plan.append((PROFILE_ACC, acceleration))
        if deceleration is not None:
            check_abs(deceleration, lim.max_deceleration, "max_deceleration", "deceleration", lim)
            plan.append((PROFILE_DEC, deceleration))
        plan.append((TARGET_VELOCITY, velocity))
        writes = encode_writes(axis, plan)
        await check_toward_limit(axis, lim, velocity, "velocity")
        guard = await limit_guard(axis, lim, velocity, acceleration, deceleration)
        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            await self._ensure_mode(axis, PV, client)
            await self._write_all(axis, writes, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            self._begin(
                axis,
                Motion(
                    "velocity",
                    client,
                    PV,
                    velocity,
                    started,
                    message=f"velocity {velocity}",
                    **guard,
                ),
            )
        return self.status(sid)

    async def torque(self, sid: str, client: str, torque: int, slope: int | None) -> dict[str, Any]:
        started = time.monotonic()
        axis = self._axis(sid)
        need_mode(axis, TQ, "profile torque")
        lim = await self.limits(sid)
        check_abs(torque, lim.max_torque, "max_torque", "torque", lim)
        plan: list[tuple[ObjectAddress, Value]] = []
        if slope is not None:
            plan.append((TORQUE_SLOPE, slope))
        plan.append((TARGET_TORQUE, torque))
        writes = encode_writes(axis, plan)
        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            await self._ensure_mode(axis, TQ, client)
            await self._write_all(axis, writes, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            self._begin(
                axis, Motion("torque", client, TQ, torque, started, message=f"torque {torque}")
            )
        return self.status(sid)

    async def move(
        self,
        sid: str,
        client: str,
        *,
        relative: bool,
        target: int,
        velocity: int | None,
        acceleration: int | None,
        deceleration: int | None,
        immediate: bool,
    ) -> dict[str, Any]:
        """Profile position: one set-point, or one more of a set of set-points."""
        started = time.monotonic()
        axis = self._axis(sid)
        s = axis.session
        need_mode(axis, PP, "a move")
        lim = await self.limits(sid)
        plan: list[tuple[ObjectAddress, Value]] = []
        if velocity is not None:
            check_abs(velocity, lim.max_velocity, "max_velocity", "velocity", lim)
            plan.append((PROFILE_VELOCITY, velocity))
        if acceleration is not None:
            check_abs(acceleration, lim.max_acceleration, "max_acceleration", "acceleration", lim)
            plan.append((PROFILE_ACC, acceleration))
        if deceleration is not None:
            check_abs(deceleration, lim.max_deceleration, "max_deceleration", "deceleration", lim)
            plan.append((PROFILE_DEC, deceleration))
        moving_pp = (
            axis.motion is not None
            and axis.motion.active
            and axis.motion.kind == "move"
            and axis.last_target is not None
        )
        if relative:
            # CiA 402-2 §6.5: relative to the present target while a move runs, else to the
            # actual position (the drive's demand position at rest).
            base = (
                axis.last_target
                if moving_pp and axis.last_target is not None
                else float(await read_int(s, POSITION) or 0)
            )
            final = base + target
        else:
            final = float(target)
        check_position(final, lim, "target")
        plan.append((TARGET_POSITION, target))
        writes = encode_writes(axis, plan)
        q = s.profile.quirk("pp_set_point_buffer")
        reversal_rejected = (
            isinstance(q, dict) and q.get("change_immediately_reversal") == "rejected"
        )
        bits = CW_ENABLE | (CW_RELATIVE if relative else 0) | (CW_IMMEDIATE if immediate else 0)
        async with self._starting(axis) as epoch:
            sw = await self._require_enabled(axis)
            if not immediate and moving_pp and sw & SW_SETPOINT_ACK:
                raise ConflictError(
                    "the drive's set-point buffer is full (set-point acknowledge, statusword "
                    "bit 12, is still 1); a new set-point now would be discarded",
                    hint="wait until the running move is done, or send it with immediate: true",
                )
            if immediate and moving_pp and reversal_rejected:
                v = await read_int(s, VELOCITY) or 0
                pos = await read_int(s, POSITION) or 0
                if v * (final - pos) < 0:
                    raise ValidationError(
                        f"{s.profile.name} rejects a new target in the opposite direction "
                        "during a move (quirk pp_set_point_buffer)",
                        field="target",
                        hint="halt first, then move the other way",
                    )
            await self._ensure_mode(axis, PP, client)
            await self._write_all(axis, writes, client)
            # New set-point on the rising edge of bit 4 (CiA 402-2 §6.5.1); halt bit cleared.
            if axis.epoch != epoch:
                raise ConflictError("a halt or stop came while the move was starting")
            await self._controlword(axis, bits, client)
            await self._go(axis, epoch, bits | CW_NEW_SETPOINT, client)
            acked = await self._wait_bits(axis, SW_SETPOINT_ACK, True, 0.3)
            await self._controlword(axis, bits, client)  # Bit 4 back to 0 for the next set-point.
            if not acked:
                raise DriveStateError(
                    "the drive did not acknowledge the set-point (statusword bit 12)",
                    hint="check the drive's error code and the mode of operation",
                )
            kind = "relative" if relative else "absolute"
            axis.last_target = final
            if moving_pp and axis.motion is not None and not immediate:
                # The buffered set-point belongs to the running move: keep its watchdog.
                axis.motion.target = final
                axis.motion.message = f"{kind} move, next target {final:g} buffered"
                self._publish(axis)
            else:
                self._begin(
                    axis,
                    Motion("move", client, PP, final, started, message=f"{kind} move to {final:g}"),
                )
        return self.status(sid)

    async def home(
        self,
        sid: str,
        client: str,
        method: int,
        *,
        speed_switch: int | None = None,
        speed_zero: int | None = None,
        acceleration: int | None = None,
        offset: int | None = None,
        max_travel: int | None = None,
        timeout_s: float | None = None,
    ) -> dict[str, Any]:
        """Start a homing run (services/homing.py) under the client's dead-man, like a jog.

        A run on an enabled drive moves the axis: it is a motion of kind ``homing`` that ends
        when the statusword shows homing attained or a homing error (CiA 402-2 §6.8.1), and a
        missing heartbeat, the client's socket closing, losing control or the backend shutting
        down halt it (the halt bit interrupts homing) and then quick-stop it. So does its
        time-out (``timeout_s``; by default from the estimated duration, domain/homing.py),
        which ends it ``timeout``. However the motion ends, the run's end is published as the
        last ``homing`` message. A method the family runs without Operation enabled (quirk
        ``homing_without_enable``) on a drive that is not enabled does not move anything and
        is not watched.
        """
        started = time.monotonic()
        axis = self._axis(sid)
        s = axis.session
        lim = await self.limits(sid)
        # The estimate and the time-out before anything is sent (a bad timeout_s is refused).
        plan = await homing.plan(
            s,
            method,
            speed_switch=speed_switch,
            speed_zero=speed_zero,
            acceleration=acceleration,
            max_travel=max_travel,
            timeout_s=timeout_s,
            limits=(lim.position_min, lim.position_max),
        )
        async with self._starting(axis) as epoch:
            enabled = (
                cia402.decode_state(await self._statusword(axis)) is cia402.State.OPERATION_ENABLED
            )

            async def set_mode() -> None:
                await self._ensure_mode(axis, HM, client)

            async def go(word: int) -> None:
                await self._go(axis, epoch, word, client)

            # A watched run's settings (6098h, 6099h, 609Ah, 607Ch) are given back at its end.
            borrowing = self._borrowing(axis) if enabled else contextlib.nullcontext()
            with borrowing:
                await homing.begin(
                    s,
                    method,
                    speed_switch=speed_switch,
                    speed_zero=speed_zero,
                    acceleration=acceleration,
                    offset=offset,
                    client=client,
                    set_mode=set_mode if enabled else None,
                    go=go,
                    plan_=plan,
                    watched=enabled,
                )
            axis.last_target = None  # Homing moves the position's origin.
            run = homing.current_run(s)
            if enabled:
                motion = Motion("homing", client, HM, None, started, message=plan.summary())
                if run is not None:

                    def ended(m: Motion) -> None:
                        # Taken over or released: the halt was a loss of control.
                        lost = self.control.owner(sid) != m.owner
                        homing.end_with_motion(run, m.state, m.message, control_lost=lost)

                    motion.on_end.append(ended)
                self._begin(axis, motion)
        return await homing.status(s)
