"""The live scope's drive-side recorder source (docs/scope.md "Drive-side recorder"): the
drive samples at its own rate into its recorder object and the scope uploads what it filled
(:class:`RecorderSource`), with the drive's own trigger where it has one: while it records,
by the stream objects (docs/scope.md "Streaming while recording"), or, from a drive without
them, each whole recording once it is done."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import struct
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.profile import RecorderSpec
from servodesk.errors import (
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
)

if TYPE_CHECKING:
    from servodesk.services.scope import ScopeService
    from servodesk.services.session import Session

from servodesk.services.scope_channels import ScopeChannel

log = logging.getLogger(__name__)

#: Recorder status values (docs/scope.md: 0 idle, 1 waiting for the trigger, 2 recording, 3 done).
REC_IDLE, REC_WAITING, REC_RECORDING, REC_DONE = 0, 1, 2, 3

#: Sample time one free-running recording covers when it is uploaded whole [s]: the upload of
#: the next one waits for it, so longer recordings mean fewer gaps but more latency.
RECORD_SPAN_S = 0.1
#: ... and when it is streamed [s]: the latency no longer grows with it; each restart leaves
#: a gap of about one read, and each start places the samples from a new anchor (a drive
#: whose clock runs slower than the wall clock, a twin on a loaded machine, drifts by a
#: share of this at most; docs/scope.md "Streaming while recording").
STREAM_SPAN_S = 0.5
#: The shortest time between two reads of the stream data [s]: each read costs the block
#: upload's three round trips however few samples it brings, and the latency is this plus
#: the read's own time.
STREAM_READ_S = 0.02
#: Free running, a read that brings more than this [s] of samples (the bus carries less than
#: the recorder takes, so each read brings more than the last) is followed by a skip to the
#: newest samples: a gap, as between whole recordings, rather than a latency that grows with
#: the recording. A triggered window is never cut.
STREAM_MAX_LAG_S = 0.05
#: The stream data's header (docs/scope.md): first sample index, status, channels, reserved.
STREAM_HEADER = struct.Struct("<IBBH")
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
    own = range(spec.index, spec.object_index(RecorderSpec.STREAM_DATA) + 1)
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


class StreamRefused(Exception):
    """The drive refused its recorder's stream objects: upload whole recordings instead."""


class RecorderSource:
    """One session's ``recorder`` channels: record, upload, place and feed, over and over.

    Free running (roll, or a trigger the drive cannot take) it records STREAM_SPAN_S at a
    time (RECORD_SPAN_S when uploaded whole), immediately; with the scope's level trigger on
    one of its channels it lets the drive wait for the crossing (single and normal captures),
    so the window is sampled at the recorder's rate however slow the upload is. Where the
    drive has the stream objects, the filled part is read while the rest records and its
    samples handed on as they come; otherwise each recording is uploaded once it is done.
    Gaps between recordings stay gaps.
    """

    #: Stream while recording where the drive can (the bench turns it off for its baseline,
    #: the whole-recording upload, in the same run).
    streaming_enabled = True

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
        self._since = time.monotonic()
        self._pre = 0
        #: The last stream read's distance behind the newest sample [s] (None: not streamed).
        self.stream_lag_s: float | None = None
        #: Times the stream skipped ahead, behind by more than STREAM_MAX_LAG_S.
        self.skipped = 0
        self.streaming = self.streaming_enabled and all(
            session.profile.spec(self._address(offset)) is not None
            for offset in (RecorderSpec.STREAM_POSITION, RecorderSpec.STREAM_DATA)
        )
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
        """How the recorder source fares: its rate, whether it streams, and the share of
        the wall time the drive records (the rest: restarts, and uploads of whole ones)."""
        wall = time.monotonic() - self._since
        return {
            "session": self.session.id,
            "channels": [c.id for c in self.channels],
            "sample_rate_hz": round(1.0 / self.period, 3),
            "drive_trigger": self.drive_trigger is not None,
            "streaming": self.streaming,
            "records": self.records,
            "recording_share": round(min(1.0, self.record_s / wall), 3) if self.records else None,
            "stream_skips": self.skipped,
            "stream_lag_s": round(self.stream_lag_s, 4) if self.stream_lag_s is not None else None,
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
            span = STREAM_SPAN_S if self.streaming else RECORD_SPAN_S
            depth = max(2, min(spec.max_depth, round(span / self.period)))
            pre = 0
            await self._write(self._address(RecorderSpec.TRIGGER), 0)
        else:
            depth = max(2, min(spec.max_depth, math.ceil(tr.window_s / self.period) + 1))
            pre = min(depth - 1, round(tr.pre * (depth - 1)))
            await self._write(self._address(RecorderSpec.TRIGGER), 1 if dt.rising else 2)
            await self._write(self._address(RecorderSpec.LEVEL), dt.level)
            await self._write(self._address(RecorderSpec.PRE_TRIGGER), pre)
        await self._write(self._address(RecorderSpec.DEPTH), depth)
        self._pre = pre
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
                once = self._stream_once if self.streaming else self._record_once
                if await once(depth) and single:
                    return  # One triggered window; the drive keeps it (readable again).
            except asyncio.CancelledError:
                raise
            except StreamRefused as exc:
                log.info("%s: %s; whole recordings from now on", self.session.id, exc)
                self.streaming = False
                with contextlib.suppress(ServodeskError):
                    depth, _pre = await self._configure()
            except ServodeskError as exc:
                self._fail(f"recorder: {exc.message}")
                await asyncio.sleep(0.5)
                with contextlib.suppress(ServodeskError):
                    depth, _pre = await self._configure()

    async def _start_recording(self) -> tuple[float, float, int] | None:
        """Start a recording and wait for the drive's trigger: (anchor, monotonic start,
        status), None when the recorder was stopped from elsewhere."""
        control = self._address(RecorderSpec.CONTROL)
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
                return None
        return anchor, started, status

    async def _stream_once(self, depth: int) -> bool:
        """One recording, streamed: the filled part read every STREAM_READ_S while the rest
        records, each read's samples placed and handed on at once. False when it was
        stopped elsewhere."""
        first_ever = self.records == 0
        begun = await self._start_recording()
        if begun is None:
            return False
        anchor, started, _status = begun
        trigger_index = self._pre if self.drive_trigger is not None else 0
        data = self._address(RecorderSpec.STREAM_DATA)
        nch = len(self.channels)
        expect = 0  # Index of the next sample wanted: no gap, no duplicate.
        skips = self.drive_trigger is None
        while True:
            t_read = time.monotonic()
            try:
                chunk = await self.session.link.read_large(data)
            except ObjectAccessError as exc:
                if first_ever and expect == 0:
                    raise StreamRefused(f"stream data refused ({exc.message})") from exc
                raise
            self.upload_s += time.monotonic() - t_read
            self.upload_bytes += len(chunk)
            if len(chunk) < STREAM_HEADER.size:
                raise ServodeskError(f"recorder: stream data of {len(chunk)} bytes, no header")
            first, status, channels, _ = (int(x) for x in STREAM_HEADER.unpack_from(chunk))
            body = chunk[STREAM_HEADER.size :]
            if channels != nch or len(body) % (4 * nch):
                raise ServodeskError(
                    f"recorder: stream data for {channels} channels, {len(body)} bytes; "
                    f"{nch} channels recorded"
                )
            rows = len(body) // (4 * nch)
            if first > expect:
                # An answer lost after the drive moved on (a cancelled upload): read again
                # from the first sample not received (the recording keeps it).
                await self._write(self._address(RecorderSpec.STREAM_POSITION), expect)
                continue
            # Samples already received (a rewind that overlapped them) are never fed twice.
            skip = expect - first
            if rows > skip:
                words = np.frombuffer(body, dtype="<u4").reshape(rows, nch)[skip:]
                self._feed(words, expect, trigger_index, anchor)
                expect = first + rows
            # How old the newest sample is when it is handed on.
            self.stream_lag_s = time.time() - anchor - (expect - 1 - trigger_index) * self.period
            if status in (REC_DONE, REC_IDLE):
                self.record_s += time.monotonic() - started
                self.records += 1
                return status == REC_DONE
            if skips and rows * self.period > STREAM_MAX_LAG_S:
                # The read brought more than the stream may lag: the drive records faster
                # than the bus carries, and the next read would bring more still. Skip to
                # the drive's own fill level (its count, not the wall clock: a drive whose
                # clock runs slow is not behind).
                count = await self._read_int(self._address(RecorderSpec.COUNT))
                target = count - round(STREAM_READ_S / self.period)
                if target > expect:
                    await self._write(self._address(RecorderSpec.STREAM_POSITION), target)
                    expect = target
                    self.skipped += 1
            await asyncio.sleep(max(0.0, STREAM_READ_S - (time.monotonic() - t_read)))

    async def _record_once(self, depth: int) -> bool:
        """One recording: start, wait, upload, place. False when it was stopped elsewhere."""
        control = self._address(RecorderSpec.CONTROL)
        span = depth * self.period
        begun = await self._start_recording()
        if begun is None:
            return False  # Stopped from elsewhere: start over.
        anchor, started, status = begun
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
        self._feed(words[: rows * nch].reshape(rows, nch), 0, trigger_index, anchor)

    def _feed(self, words: np.ndarray, first: int, trigger_index: int, anchor: float) -> None:
        """Samples ``first``.. of the recording (rows x channels of INTEGER32 words) to the
        channels' buffers, each at the recorder's period from the anchor's sample."""
        rows = len(words)
        index = np.arange(first, first + rows, dtype=np.float64)
        t = anchor + (index - trigger_index) * self.period
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
            ch.rate_hz = 1.0 / self.period
            ch.buffer.add_many(t.tolist(), v.tolist())
