"""The live scope's drive-side recorder source (docs/scope.md "Drive-side recorder"): the
drive samples at its own rate into its recorder object and the scope uploads the filled
records (:class:`RecorderSource`), with the drive's own trigger where it has one."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.profile import RecorderSpec
from servodesk.errors import (
    NotFoundError,
    ServodeskError,
)

if TYPE_CHECKING:
    from servodesk.services.scope import ScopeService
    from servodesk.services.session import Session

from servodesk.services.scope_channels import ScopeChannel

log = logging.getLogger(__name__)

#: Sample time one free-running recording covers [s]: the upload of the next one waits for
#: it, so longer recordings mean fewer gaps but more latency.
#: Recorder status values (docs/scope.md: 0 idle, 1 waiting for the trigger, 2 recording, 3 done).
REC_IDLE, REC_WAITING, REC_RECORDING, REC_DONE = 0, 1, 2, 3

RECORD_SPAN_S = 0.1
#: Status polls while waiting for the drive's trigger [s] (the anchor's time is when the
#: poll saw the recording start: this bounds its error).
TRIGGER_POLL_S = 0.002


def recorder_of(session: Session) -> RecorderSpec | None:
    """The drive-side recorder of the session's drive, None when it has none.

    A ``sim_only`` recorder exists on the simulated twin only (profile ``recorder`` block).
    """
    spec = session.profile.recorder
    if spec is None or (spec.sim_only and not session.simulated):
        return None
    return spec


def recorder_info(session: Session) -> dict[str, Any]:
    """``GET /sessions/{sid}/recorder`` (docs/scope.md)."""
    spec = recorder_of(session)
    if spec is None:
        return {"present": False, "max_channels": 0, "rate_hz": 0.0, "depth": 0, "objects": []}
    own = range(spec.index, spec.object_index(RecorderSpec.TRIGGER_INDEX) + 1)
    objects = [
        str(address)
        for address, obj in session.profile.variables.items()
        if address.index not in own and RecorderSpec.recordable(obj)
    ]
    return {
        "present": True,
        "max_channels": spec.max_channels,
        "rate_hz": spec.rate_hz,
        "depth": spec.max_depth,
        "objects": objects,
        "section": spec.section,
    }


@dataclass(frozen=True)
class DriveTrigger:
    """The scope's level trigger handed to the drive's recorder (single and normal modes)."""

    channel: int  # Scope channel id; recorded as the recorder's channel 1.
    rising: bool
    level: int
    depth: int
    pre: int


class RecorderSource:
    """One session's ``recorder`` channels: record, upload, place and feed, over and over.

    Free running (roll, or a trigger the drive cannot take) it records RECORD_SPAN_S at a
    time, immediately; with the scope's level trigger on one of its channels it lets the drive
    wait for the crossing (single and normal captures), so the window is sampled at the
    recorder's rate however slow the upload is. Gaps between recordings stay gaps.
    """

    def __init__(
        self,
        session: Session,
        spec: RecorderSpec,
        channels: list[ScopeChannel],
        scope: ScopeService,
    ) -> None:
        self.session = session
        self.spec = spec
        self.scope = scope
        self.task: asyncio.Task[None] | None = None
        self.records = 0
        #: Seconds spent uploading and recording (the achieved duty cycle, for the status).
        self.upload_s = 0.0
        self.record_s = 0.0
        self.upload_bytes = 0
        if len(channels) > spec.max_channels:
            for ch in channels[spec.max_channels :]:
                ch.error = (
                    f"the drive's recorder has {spec.max_channels} channels; "
                    "this one gets no samples (use source sdo or pdo)"
                )
            channels = channels[: spec.max_channels]
        self.drive_trigger = self._drive_trigger(channels)
        if self.drive_trigger is not None:
            # The recorder's level trigger compares its channel 1 (docs/scope.md).
            first = next(c for c in channels if c.id == self.drive_trigger.channel)
            channels = [first, *[c for c in channels if c is not first]]
        self.channels = channels
        rates = [c.config.rate_hz for c in channels if c.config.rate_hz > 0]
        self.divider = max(1, round(spec.rate_hz / max(rates))) if rates else 1
        if self.drive_trigger is not None:
            self.divider = max(self.divider, self._window_divider())
        self.period = self.divider / spec.rate_hz

    def _address(self, offset: int, sub: int = 0) -> ObjectAddress:
        return ObjectAddress(self.spec.object_index(offset), sub)

    def status(self) -> dict[str, Any]:
        """How the recorder source fares: its rate, and the share of time it records (the
        rest goes to uploading by SDO)."""
        busy = self.record_s + self.upload_s
        return {
            "session": self.session.id,
            "channels": [c.id for c in self.channels],
            "sample_rate_hz": round(1.0 / self.period, 3),
            "drive_trigger": self.drive_trigger is not None,
            "records": self.records,
            "recording_share": round(self.record_s / busy, 3) if busy else None,
            "upload_bytes_per_s": round(self.upload_bytes / self.upload_s)
            if self.upload_s
            else None,
        }

    def _drive_trigger(self, channels: list[ScopeChannel]) -> DriveTrigger | None:
        tr = self.scope.trigger
        if tr.mode == "roll" or tr.kind != "level" or tr.slope == "either":
            return None
        ch = next((c for c in channels if c.id == tr.channel), None)
        if ch is None or not ch.spec.data_type.is_integer:
            return None
        return DriveTrigger(ch.id, tr.slope == "rising", math.ceil(tr.level), 0, 0)

    def _window_divider(self) -> int:
        """The smallest divider whose depth holds the trigger window."""
        need = self.scope.trigger.window_s * self.spec.rate_hz
        return max(1, math.ceil(need / self.spec.max_depth))

    def start(self) -> None:
        self.task = asyncio.get_running_loop().create_task(
            self._run(), name=f"scope recorder {self.session.id}"
        )

    async def stop(self) -> None:
        if self.task is not None:
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task
            self.task = None
        # Leave the drive's recorder idle (it keeps its last recording).
        with contextlib.suppress(ServodeskError):
            await self._write(self._address(RecorderSpec.CONTROL), 0)

    async def _write(self, address: ObjectAddress, value: int) -> None:
        spec = self.session.profile.spec(address)
        if spec is None:
            raise NotFoundError(f"recorder object {address} is not in the profile")
        await self.session.link.write(address, codec(spec.data_type).encode(value))

    async def _read_int(self, address: ObjectAddress) -> int:
        spec = self.session.profile.spec(address)
        raw = await self.session.link.read(address)
        v = codec(spec.data_type).decode(raw) if spec is not None else 0
        return int(v) if isinstance(v, int | float) else 0

    def _fail(self, message: str) -> None:
        for ch in self.channels:
            ch.error = message

    async def _configure(self) -> tuple[int, int]:
        """Write the recorder's objects; returns (depth, pre-trigger samples)."""
        spec = self.spec
        await self._write(self._address(RecorderSpec.CONTROL), 0)
        for n in range(1, spec.max_channels + 1):
            entry = 0
            if n <= len(self.channels):
                s = self.channels[n - 1].spec
                entry = s.index << 16 | s.subindex << 8 | s.data_type.bits
            await self._write(self._address(RecorderSpec.CHANNELS, n), entry)
        await self._write(self._address(RecorderSpec.DIVIDER), self.divider)
        dt = self.drive_trigger
        tr = self.scope.trigger
        if dt is None:
            depth = max(2, min(spec.max_depth, round(RECORD_SPAN_S / self.period)))
            pre = 0
            await self._write(self._address(RecorderSpec.TRIGGER), 0)
        else:
            depth = max(2, min(spec.max_depth, math.ceil(tr.window_s / self.period) + 1))
            pre = min(depth - 1, round(tr.pre * (depth - 1)))
            await self._write(self._address(RecorderSpec.TRIGGER), 1 if dt.rising else 2)
            await self._write(self._address(RecorderSpec.LEVEL), dt.level)
            await self._write(self._address(RecorderSpec.PRE_TRIGGER), pre)
        await self._write(self._address(RecorderSpec.DEPTH), depth)
        return depth, pre

    async def _run(self) -> None:
        try:
            depth, _pre = await self._configure()
        except ServodeskError as exc:
            self._fail(f"recorder: {exc.message}")
            return
        single = self.drive_trigger is not None and self.scope.trigger.mode == "single"
        while True:
            try:
                if await self._record_once(depth) and single:
                    return  # One triggered window; the drive keeps it (readable again).
            except asyncio.CancelledError:
                raise
            except ServodeskError as exc:
                self._fail(f"recorder: {exc.message}")
                await asyncio.sleep(0.5)
                with contextlib.suppress(ServodeskError):
                    depth, _pre = await self._configure()

    async def _record_once(self, depth: int) -> bool:
        """One recording: start, wait, upload, place. False when it was stopped elsewhere."""
        control = self._address(RecorderSpec.CONTROL)
        span = depth * self.period
        await self._write(control, 1)
        # The anchor: the time servodesk saw the recording start (docs/scope.md). Free
        # running, that is the start's confirmation; the first sample is the recorder's
        # sample 0. With the drive's trigger it is the first poll that sees it recording,
        # and the anchor is the trigger sample.
        anchor = time.time()
        started = time.monotonic()
        status = REC_RECORDING if self.drive_trigger is None else REC_WAITING
        while status == REC_WAITING:
            await asyncio.sleep(TRIGGER_POLL_S)
            status = await self._read_int(control)
            anchor = time.time()
            if status == REC_IDLE:
                return False  # Stopped from elsewhere: start over.
        rec_start = time.monotonic()
        await asyncio.sleep(max(0.0, span - (time.monotonic() - rec_start)))
        while status != REC_DONE:
            status = await self._read_int(control)
            if status == REC_IDLE:
                return False
            if status != REC_DONE:
                await asyncio.sleep(min(0.01, span / 4))
        t_done = time.monotonic()
        count = await self._read_int(self._address(RecorderSpec.COUNT))
        trig = await self._read_int(self._address(RecorderSpec.TRIGGER_INDEX))
        # By SDO block upload on CANopen (falling back to segmented for a drive that refuses
        # it; docs/scope.md "Block upload"), the plain read elsewhere.
        data = await self.session.link.read_large(self._address(RecorderSpec.DATA))
        self.upload_s += time.monotonic() - t_done
        self.upload_bytes += len(data)
        self.record_s += t_done - started
        self.records += 1
        self._place(data, count, trig if trig != 0xFFFFFFFF else 0, anchor)
        return True

    def _place(self, data: bytes, count: int, trigger_index: int, anchor: float) -> None:
        """Decode the DOMAIN and give every sample its time: the recorder's period from the
        anchor sample (never interpolated, never resampled)."""
        nch = len(self.channels)
        words = np.frombuffer(data, dtype="<u4")
        rows = len(words) // nch if nch else 0
        if rows != count:
            self._fail(
                f"recorder: {len(data)} bytes of data for {count} samples x {nch} channels; "
                "the recording is skipped"
            )
            return
        words = words[: rows * nch].reshape(rows, nch)
        t = anchor + (np.arange(rows, dtype=np.float64) - trigger_index) * self.period
        for i, ch in enumerate(self.channels):
            col = words[:, i]
            dt = ch.spec.data_type
            if dt is DataType.REAL32:
                v = col.view("<f4").astype(np.float64)
            elif dt.is_signed:
                # The word holds the value sign-extended to 32 bits.
                v = col.view("<i4").astype(np.float64)
            else:
                v = col.astype(np.float64)
            ch.error = None
            if rows > 1:
                ch.rate_hz = (rows - 1) / float(t[-1] - t[0])
            ch.buffer.add_many(t.tolist(), v.tolist())
