"""Safety of the own tuning (issue 8 §7): what it learns of the drive before it moves it, the
settings it saves and puts back, the torque limit, software position limits 607Dh, following
error window and quick-stop deceleration it sets, and bringing the axis to rest before
anything is put back (services/tuning/own; docs/tuning.md "Travel window")."""

from __future__ import annotations

import contextlib
import math

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CONTROLWORD,
    CW_ENABLE,
    CW_HALT,
    ENCODER_INCREMENTS,
    ENCODER_REVOLUTIONS,
    FOLLOWING_ERROR_WINDOW,
    HALT_OPTION,
    MAX_PROFILE_VELOCITY,
    MAX_TORQUE,
    MODE,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    QUICK_STOP_DEC,
    QUICK_STOP_OPTION,
    RATED_TORQUE,
    SOFT_LIMIT_MAX,
    SOFT_LIMIT_MIN,
    VELOCITY,
    VELOCITY_THRESHOLD,
    Mode,
    State,
    decode_state,
)
from servodesk.domain.datatypes import Value
from servodesk.domain.tuning.travel import TravelBound, half_window
from servodesk.errors import ServodeskError, ValidationError
from servodesk.services.tuning.io import read_float
from servodesk.services.tuning.own.base import Drive, TuningBase, TuningFailed
from servodesk.services.tuning.travel import TravelGuard

PP = int(Mode.PROFILE_POSITION)
#: After a stop or a failure the axis must stand (606Ch within the velocity threshold 606Fh)
#: for this long, polled this often, before the settings are put back; at most REST_WAIT_S.
REST_STILL_S = 0.03
REST_POLL_S = 0.01
REST_WAIT_S = 2.0


class Safety(TuningBase):
    """The drive learnt, the settings saved, the safety settings made and given back."""

    async def _learn(self) -> Drive:
        io = self.io
        prof = io.profile
        rate_addr = self.spec.loop_rate_address
        rate = (
            await read_float(io, rate_addr)
            if rate_addr is not None
            else (prof.recorder.rate_hz if prof.recorder else 0.0)
        )
        if not rate > 0.0:
            raise TuningFailed("the drive reports no servo loop rate")
        if await self._has(ENCODER_INCREMENTS):
            inc = await read_float(io, ENCODER_INCREMENTS)
            revs = (
                await read_float(io, ENCODER_REVOLUTIONS)
                if await self._has(ENCODER_REVOLUTIONS)
                else 1.0
            )
            cpr = inc / max(revs, 1.0)
        else:
            cpr = float(prof.simulation.counts_per_rev)
        if await self._has(RATED_TORQUE):
            rated = await read_float(io, RATED_TORQUE) * 1e-3  # 6076h is in mN m.
        else:
            rated = prof.simulation.rated_torque
        limit = rated * self.request.torque_limit_pct / 100.0
        if await self._has(MAX_TORQUE):
            drive_max = await read_float(io, MAX_TORQUE) * 1e-3 * rated
            if drive_max > 0.0:
                limit = min(limit, drive_max)
        current = self._current_loop_hz
        addr = self.spec.current_loop_address
        if current is None and addr is not None:
            current = await read_float(io, addr)
        p0 = int(await read_float(io, POSITION))
        half = self.request.half_window_counts
        if half is None:
            half = half_window(self.request.travel_window_rev, cpr)
        bound = TravelBound(p0, half)
        if await self._has(SOFT_LIMIT_MIN) and await self._has(SOFT_LIMIT_MAX):
            lo = await read_float(io, SOFT_LIMIT_MIN)
            hi = await read_float(io, SOFT_LIMIT_MAX)
            # Both 0 switches the limits off (CiA 402-2 §6.5.4).
            if lo < hi and (bound.low < lo or bound.high > hi):
                raise ValidationError(
                    f"the travel window {self.request.travel_window_rev:g} rev (±{half} around "
                    f"{p0}: {bound.low}..{bound.high}) does not fit the software limits "
                    f"{lo:.0f}..{hi:.0f} (607Dh)",
                    field="travel_window_rev",
                    hint="move the axis away from the limit or give a smaller window",
                )
        vmax = math.inf
        if await self._has(MAX_PROFILE_VELOCITY):
            vmax = await read_float(io, MAX_PROFILE_VELOCITY) or math.inf
        move = limit
        if self.request.move_torque_pct is not None:
            move = rated * self.request.move_torque_pct / 100.0
        self._guard = TravelGuard(bound)
        self._demand = float(p0)
        self._rest_speed = 0.01 * cpr
        if await self._has(VELOCITY_THRESHOLD):
            self._rest_speed = await read_float(io, VELOCITY_THRESHOLD) or self._rest_speed
        self._gains_now = await self.read_gains()
        return Drive(rate, cpr, rated, limit, current, p0, bound, vmax, move, home=p0)

    async def _save_settings(self) -> list[tuple[ObjectAddress, Value]]:
        saved: list[tuple[ObjectAddress, Value]] = []
        for a in (
            MODE,
            FOLLOWING_ERROR_WINDOW,
            MAX_TORQUE,
            SOFT_LIMIT_MIN,
            SOFT_LIMIT_MAX,
            PROFILE_VELOCITY,
            PROFILE_ACC,
            PROFILE_DEC,
            QUICK_STOP_DEC,
        ):
            spec = self.io.profile.spec(a)
            if spec is not None and spec.access.readable and spec.access.writable:
                saved.append((a, await self.io.read(a)))
        return saved

    async def _restore_settings(self, saved: list[tuple[ObjectAddress, Value]]) -> None:
        for a, v in saved:
            await self.io.write(a, v)

    async def _write_if(self, address: ObjectAddress, value: Value) -> None:
        spec = self.io.profile.spec(address)
        if spec is not None and spec.access.writable:
            await self.io.write(address, value)

    def _writable(self, address: ObjectAddress) -> bool:
        spec = self.io.profile.spec(address)
        return spec is not None and spec.access.writable

    async def _set_safety(self, drive: Drive) -> None:
        """Before the first move: the user's torque limit, the drive's software position
        limits 607Dh at the travel bound, a following error window as wide as the travel
        window, and what a stop brakes with (module docstring)."""
        await self._write_if(
            MAX_TORQUE, max(1, round(drive.limit_torque / drive.rated_torque * 1e3))
        )
        b = drive.bound
        if self._writable(SOFT_LIMIT_MIN) and self._writable(SOFT_LIMIT_MAX):
            # CiA 402-2 §6.5.4: the drive limits every target to 607Dh:01..02 (min = max = 0
            # switches them off; a bound of at least one count either side never is 0..0).
            # The backstop behind servodesk's own planning: a target outside never reaches
            # the axis, whatever computed it.
            await self.io.write(SOFT_LIMIT_MIN, b.low)
            await self.io.write(SOFT_LIMIT_MAX, b.high)
            self._notes.append(
                f"the drive's software position limits 607Dh were {b.low} .. {b.high} (the "
                f"travel bound) from before the first move, and are back as they were"
            )
        else:
            self._notes.append(
                f"{self.io.profile.name} has no writable software position limits (607Dh): only "
                f"servodesk's own bound ({b.low} .. {b.high}) applied, not the drive's"
            )
        await self._write_if(FOLLOWING_ERROR_WINDOW, round(drive.width))
        await self.io.write(MODE, PP)
        self._qs_writable = self._writable(QUICK_STOP_DEC)
        self._qs_dec = None
        guard = self._guard
        assert guard is not None
        guard.stop_deceleration = await self._stop_deceleration()

    async def _stop_deceleration(self) -> float | None:
        """The gentlest ramp a dead-man stop may brake with where servodesk cannot raise it
        [counts/s²] (TravelGuard.stop_deceleration). The dead-man halts (controlword bit 8,
        605Dh) and then quick-stops (605Ah) the axis (services/motion/); CiA 402-2 §6.3.4:
        options 1 (and 5) brake on the profile deceleration 6084h, which each move sets to its
        own, 2 (and 6) on the quick-stop deceleration 6085h, which :meth:`_move` raises to the
        move's own where it is writable, 3, 4, 7, 8 at the current or voltage limit. Option 0
        lets the axis coast: the result's notes say that its run-out is not bounded."""
        options: dict[ObjectAddress, int] = {}
        for a in (QUICK_STOP_OPTION, HALT_OPTION):
            if await self._has(a):
                with contextlib.suppress(ServodeskError):
                    options[a] = int(await read_float(self.io, a))
        if options.get(QUICK_STOP_OPTION) == 0:
            self._notes.append(
                "the quick stop option (605Ah = 0) lets the axis coast: a dead-man stop's "
                "run-out is the machine's friction and is not bounded by the travel window"
            )
        # Without 605Ah a drive's quick stop is taken to brake on 6085h (CiA 402-2's default).
        qs = options.get(QUICK_STOP_OPTION, 2)
        on_qs_ramp = qs in (2, 6) or options.get(HALT_OPTION) == 2
        if not on_qs_ramp or self._qs_writable or not await self._has(QUICK_STOP_DEC):
            return None
        dec = await read_float(self.io, QUICK_STOP_DEC)
        self._notes.append(
            f"the quick-stop deceleration 6085h ({dec:.0f} counts/s²) is not writable: each "
            f"move's reserve includes the run-out of a stop on it"
        )
        return dec

    async def _come_to_rest(self) -> None:
        """Halt the axis (controlword bit 8 with 605Dh's ramp: at the move's own deceleration;
        only in Operation enabled, where 0x010F cannot enable a drive, as services/motion/
        sends it) and wait until it stands, at most :data:`REST_WAIT_S`: after a stop, a
        dead-man (whose quick stop has the drive out of Operation enabled already) or a
        failure, before anything is put back."""
        if decode_state(await self._statusword()) is State.OPERATION_ENABLED:
            await self.io.write(CONTROLWORD, CW_ENABLE | CW_HALT)
        if not await self._has(VELOCITY):
            return
        still = 0.0
        began = self.io.now()
        while still < REST_STILL_S and self.io.now() - began < REST_WAIT_S:
            speed = abs(await read_float(self.io, VELOCITY))
            still = still + REST_POLL_S if speed <= self._rest_speed else 0.0
            await self.io.sleep(REST_POLL_S)
