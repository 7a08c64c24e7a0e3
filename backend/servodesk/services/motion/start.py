"""The one start template every motion follows.

Checks first, with nothing sent (limits.py); then, under the axis lock (``_starting``, which
also hands the epoch a stop bumps): the drive must be in Operation enabled, the mode is set
(``_ensure_mode``, with the family's quirks), the motion's settings are written as borrowed
(given back when it ends), the controlword that starts it goes out only if no stop came
meanwhile (``_go``), and ``_begin`` ends the motion it replaces, arms the dead-man and starts
the monitor (and any set-point task). A start that fails after writing its settings gives
them back itself.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import AsyncIterator, Callable, Iterator
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import MODE, MODE_DISPLAY
from servodesk.domain.datatypes import Value
from servodesk.errors import ConflictError, DriveStateError
from servodesk.services.motion.axis import Axis, Motion, audit_facts
from servodesk.services.motion.limits import read_int
from servodesk.services.motion.lost_holder import LostHolder
from servodesk.services.motion.monitor import Monitor
from servodesk.services.session import BORROW

log = logging.getLogger(__package__)  # One logger for the motion service, as before the split.


class StartTemplate(LostHolder, Monitor):
    """The steps of a start, in the order every motion takes them."""

    async def _require_enabled(self, axis: Axis) -> int:
        sw = await self._statusword(axis)
        state = cia402.decode_state(sw)
        if state is not cia402.State.OPERATION_ENABLED:
            raise DriveStateError(
                f"the servo is off ({state.value}); motion needs Operation enabled",
                hint='servo on first: POST /state {"command": "enable"}',
            )
        return sw

    async def _ensure_mode(self, axis: Axis, mode: int, who: str) -> None:
        s = axis.session
        current = await read_int(s, MODE_DISPLAY)
        if current == mode:
            return
        p = s.profile
        moving = not await self._standstill(axis)
        if moving and p.quirk("mode_change_at_standstill"):
            raise DriveStateError(
                f"{p.name} changes the mode of operation only at standstill "
                "(quirk mode_change_at_standstill); the axis moves",
                hint="halt first, then start the motion again",
            )
        refused = p.quirk("mode_change_refused")
        states = refused.get("states", []) if isinstance(refused, dict) else []
        if "operation_enabled" in [str(x).lower() for x in states]:
            # The family refuses 6060h in Operation enabled: disable operation, set the mode,
            # enable again (at standstill only: disabling drops the holding torque).
            if moving:
                raise DriveStateError(
                    f"{p.name} refuses a mode change in Operation enabled and the axis moves",
                    hint="halt first, then start the motion again",
                )
            await s.command("disable_operation")
            await s.write_object(MODE, mode, client=who)
            await s.command("enable_operation")
        else:
            await s.write_object(MODE, mode, client=who)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            if await read_int(s, MODE_DISPLAY) == mode:
                return
            await asyncio.sleep(0.005)
        raise DriveStateError(
            f"the drive did not switch to {cia402.mode_name(mode)} (6061h)",
            hint="check the drive's error code and whether it allows this mode now",
        )

    async def _write_all(
        self, axis: Axis, writes: list[tuple[ObjectAddress, Value]], who: str
    ) -> None:
        with self._borrowing(axis):
            for address, value in writes:
                await axis.session.write_object(address, value, client=who)

    @staticmethod
    @contextlib.contextmanager
    def _borrowing(axis: Axis) -> Iterator[None]:
        """The settings written in this block are the motion's: given back when it ends."""
        token = BORROW.set(axis.borrowed)
        try:
            yield
        finally:
            BORROW.reset(token)

    @contextlib.asynccontextmanager
    async def _starting(self, axis: Axis) -> AsyncIterator[int]:
        try:
            async with axis.lock:
                yield axis.epoch
        finally:
            m = axis.motion
            if axis.borrowed and (m is None or not m.active):
                # The start failed after writing its settings: nothing runs to give them back.
                self._spawn(self._give_back(axis))

    async def _go(self, axis: Axis, epoch: int, word: int, who: str) -> None:
        """Send a controlword that starts motion, unless a stop came meanwhile."""
        if axis.epoch != epoch:
            raise ConflictError(
                "a halt or stop came while the motion was starting; it was not started",
                hint="start it again",
            )
        await self._controlword(axis, word, who)
        if axis.epoch != epoch:
            axis.rehalt = True

    def _begin(self, axis: Axis, motion: Motion, *extra: Callable[[], Any]) -> None:
        old = axis.motion
        if old is not None and old.active:
            self._cancel_tasks(old)
            old.active = False
            self._deadman.disarm(old)
            old.state, old.message = "replaced", f"replaced by {motion.kind}"
            self.control.audit.record(
                "motion.stopped", drive=axis.sid, message=old.message, details=audit_facts(old)
            )
            self._notify_end(old)
        axis.motion = motion
        loop = asyncio.get_running_loop()
        self._arm(axis, motion, loop)
        motion.tasks.append(
            loop.create_task(self._monitor(axis, motion), name=f"motion {axis.sid}")
        )
        for make in extra:
            motion.tasks.append(loop.create_task(make(), name=f"setpoints {axis.sid}"))
        log.info("%s on %s by %s: %s", motion.kind, axis.sid, motion.owner, motion.message)
        self.control.audit.record(
            "motion.started", drive=axis.sid, message=motion.message, details=audit_facts(motion)
        )
        self._publish(axis)
