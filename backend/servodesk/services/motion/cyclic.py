"""Cyclic set-points: a backend set-point generator in csp, csv or cst.

Without PDOs the backend writes the set-point by SDO every ``cyclic_period`` seconds (into
the RPDO output image when cyclic data carries it) and the drive interpolates between them;
the waveform's time is counted in set-points, so a stall of the backend stretches it rather
than stepping the set-point (services/motion/__init__.py, "Choices").
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from typing import Any

from servodesk.domain.cia402 import (
    CW_ENABLE,
    POSITION,
    TARGET_POSITION,
    TARGET_TORQUE,
    TARGET_VELOCITY,
)
from servodesk.domain.datatypes import DataType, codec
from servodesk.errors import ServodeskError, ValidationError
from servodesk.services.motion.axis import (
    CSP,
    CSV,
    CYCLIC_MODES,
    Motion,
)
from servodesk.services.motion.limits import (
    check_abs,
    check_position,
    encode_writes,
    need_mode,
    read_int,
)
from servodesk.services.motion.start import StartTemplate

log = logging.getLogger(__package__)  # One logger for the motion service, as before the split.


class CyclicSetpoints(StartTemplate):
    """The cyclic generator (families that list mode 8, 9 or 10)."""

    async def cyclic(
        self,
        sid: str,
        client: str,
        *,
        mode_name: str,
        waveform: str,
        amplitude: float,
        frequency: float,
        duration: float,
    ) -> dict[str, Any]:
        """A backend set-point generator in csp, csv or cst (families that list the mode)."""
        started = time.monotonic()
        axis = self._axis(sid)
        s = axis.session
        mode = CYCLIC_MODES[mode_name]
        need_mode(axis, mode, f"the cyclic {mode_name} generator")
        lim = await self.limits(sid)
        if frequency * self.cyclic_period > 0.1:
            raise ValidationError(
                f"frequency {frequency:g} Hz is too high for set-points every "
                f"{self.cyclic_period * 1000:g} ms (at most {0.1 / self.cyclic_period:g} Hz)",
                field="frequency",
                hint="lower the frequency",
            )
        # Peak rate of change of the waveform per unit amplitude.
        slope = 2 * math.pi * frequency if waveform == "sine" else 4 * frequency
        periods = max(1, math.ceil(duration * frequency - 1e-9))
        run_s = periods / frequency
        if mode == CSP:
            position = await read_int(s, POSITION) or 0
            check_position(position + amplitude, lim, "amplitude")
            check_position(position - amplitude, lim, "amplitude")
            check_abs(amplitude * slope, lim.max_velocity, "max_velocity", "peak velocity", lim)
            address = TARGET_POSITION
        elif mode == CSV:
            check_abs(amplitude, lim.max_velocity, "max_velocity", "amplitude", lim)
            check_abs(
                amplitude * slope,
                lim.max_acceleration,
                "max_acceleration",
                "peak acceleration",
                lim,
            )
            address, position = TARGET_VELOCITY, 0
        else:
            check_abs(amplitude, lim.max_torque, "max_torque", "amplitude", lim)
            address, position = TARGET_TORQUE, 0
        spec = s.profile.spec(address)
        encode_writes(
            axis, [(address, round(position + amplitude)), (address, round(position - amplitude))]
        )

        def wave(t: float) -> float:
            x = frequency * t
            if waveform == "sine":
                return math.sin(2 * math.pi * x)
            return 2 / math.pi * math.asin(math.sin(2 * math.pi * x))  # Triangle, starts at 0.

        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            if mode == CSP:
                # HIWIN 000 quirk csp_align_target_before_enable: 607Ah = 6064h before csp.
                position = await read_int(s, POSITION) or 0
            await s.write_object(address, position, client=client)
            await self._ensure_mode(axis, mode, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            motion = Motion(
                "cyclic",
                client,
                mode,
                amplitude,
                started,
                message=f"{mode_name} {waveform} ±{amplitude:g} at {frequency:g} Hz for "
                f"{run_s:g} s",
            )
            base = position
            data_codec = codec(spec.data_type if spec else DataType.INTEGER32)
            running_message = motion.message

            async def generate() -> None:
                # write_raw: by SDO, or into the RPDO output image when cyclic data carries
                # the set-point (services/cyclic.py).
                write = s.write_raw
                period = self.cyclic_period
                due = time.monotonic()
                k = 0
                stalls: list[float] = []

                def stalled() -> str:
                    # What the user sees in the motion's status, running and ended: the
                    # waveform is not the one asked for when the stream stalled.
                    if not stalls:
                        return ""
                    return (
                        f"; the set-point stream stalled {len(stalls)} x (longest "
                        f"{max(stalls) * 1000:.0f} ms, {sum(stalls) * 1000:.0f} ms in all): "
                        "the drive held the set-point, the waveform ran that much longer"
                    )

                try:
                    while motion.active:
                        k += 1
                        due += period
                        late = time.monotonic() - due
                        if late > period:
                            # The backend stalled: the waveform is stretched by the stall (the
                            # drive holds the last set-point) instead of skipping ahead, so the
                            # set-point never steps by more than one period's change.
                            log.warning(
                                "the %s set-point stream stalled for %.0f ms; the waveform "
                                "resumes where it stopped",
                                mode_name,
                                late * 1000,
                            )
                            due += late
                            stalls.append(late)
                            motion.message = running_message + stalled()
                            self._publish(axis)
                        await asyncio.sleep(max(0.0, due - time.monotonic()))
                        # The waveform's time is counted in periods, not read off the clock.
                        t = k * period
                        if t >= run_s:
                            break
                        value = round(base + amplitude * wave(t))
                        await write(address, data_codec.encode(value))
                    if motion.active:
                        await write(address, data_codec.encode(base))
                        self._end(axis, motion, "done", f"{mode_name} {waveform} done{stalled()}")
                except ServodeskError as exc:
                    self._end(
                        axis,
                        motion,
                        "error",
                        f"set-point stream failed: {exc.message}{stalled()}",
                    )

            self._begin(axis, motion, generate)
        return self.status(sid)
