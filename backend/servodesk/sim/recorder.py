"""The simulated drive's drive-side recorder: a trace function sampled at the plant rate.

Real drives record chosen signals inside the drive, far faster than any bus could carry them
live, and hand the recording over afterwards (Siemens "trace", Kollmorgen "recorder"). None
of servodesk's families documents one reachable over the fieldbus, so the profile's
``recorder:`` block (:class:`~servodesk.domain.profile.RecorderSpec`) gives the simulated
twin one, as ``sim_only`` objects at ``index + offset`` (docs/scope.md, "Simulated
drive-side recorder"; the generic twin uses 2F00h-2F0Bh):

====== ===================================================================================
+0 n   recorded object n (1..8): ``index << 16 | subindex << 8 | bits``, 0 = unused
+1     sample divider: a sample every n-th plant step (plant at 4 kHz: 1 -> 4 kHz)
+2     depth: samples per channel, the pre-trigger samples included (<= ``max_depth``)
+3     trigger: 0 immediate, 1 level on channel 1 rising, 2 falling
+4     trigger level (INTEGER32), compared with channel 1's value
+5     pre-trigger samples (< depth)
+6     control/status: write 1 start, 0 stop; read 0 idle, 1 waiting for the trigger,
       2 recording, 3 done
+7     data (DOMAIN, read by SDO upload): the samples oldest first, channel-interleaved,
       one INTEGER32 little-endian word per channel and sample
+8     samples per channel in the data (while running: recorded so far)
+9     index of the trigger sample in the data (FFFFFFFFh: no trigger yet)
+10    stream position: index in the data of the next sample +11 answers with (0 at the
       start; each read of +11 moves it past the samples it sent; write it to read again)
+11    stream data (DOMAIN, read while recording): an 8-byte header (UNSIGNED32 index of
       the first sample, UNSIGNED8 status as +6, UNSIGNED8 channels, 2 bytes 0), then the
       samples from the stream position up to those recorded when the read began, as +7
====== ===================================================================================

+10 and +11 are optional (a profile without them: a drive that only uploads whole
recordings, which the scope falls back to); docs/scope.md "Streaming while recording".

Choices (documented here once):

- Sampling happens after every plant sub-step (:meth:`SimulatedDrive.on_substep`): position
  6064h, velocity 606Ch and torque 6077h are the plant's state at that sub-step, following
  error 60F4h is the control cycle's position demand minus the sub-step's position (with the
  servo loop of a ``tuning.kind: gains`` profile: the loop's demand at that sub-step,
  interpolated across the cycle, docs/tuning.md); any other
  object is its latest value (set-points and parameters change once per control cycle at most).
  The first sample is the first plant step after the start. (With encoder noise, a test-only
  plant parameter, each reading of 6064h draws noise, as an SDO read of it does.)
- Channels are the non-zero sub-indexes in order; the data holds only those. A level trigger
  needs channel 1. Integer objects of up to 32 bits are stored as their value (UNSIGNED32
  wraps into the INTEGER32 word: read it back as unsigned); a REAL32 object is stored as its
  IEEE 754 bits (reinterpret the word as a float). 64-bit objects, strings and domains cannot
  be recorded (0609 0030h).
- A level trigger fires on the first sample that crosses the level in its direction with the
  previous sample on the other side (rising: previous < level <= sample; falling: previous >
  level >= sample), and only once ``pre`` samples are recorded: the trigger sample is always
  at index ``pre`` of the data and the window is never short of pre-trigger samples.
  An immediate trigger records from the first sample (trigger index 0, ``pre`` unused).
- The configuration objects are written in any NMT state, but refused with 0800 0022h while a
  recording runs (status 1 or 2); start checks the configuration as a whole (0800 0020h: no
  channel, a level trigger without channel 1, pre-trigger not below the depth). Writing 1
  while running starts over; writing 0 stops and keeps what was recorded (with no trigger yet:
  the pre-trigger samples, trigger index FFFFFFFFh).
- A recording stays readable until the next start. The recorder is RAM: NMT reset node
  (a power cycle) loses the configuration and the recording. Reading the data while running
  or with nothing recorded answers 0800 0024h (no data available).
- Streaming: the data's indexes are fixed once the recording runs (a level trigger's
  pre-trigger samples are the first ``pre``, the rest follow in order), so the filled part
  can be read while the rest records, as a real trace's ring read behind its write pointer.
  Waiting for the trigger, +11 sends no samples (the pre-trigger ring still turns). The
  header's first index lets the reader see a lost answer (the position moved on past samples
  it never got: a gap) and write +10 back; nothing is ever overwritten within a recording.
- Cost: idle, the recorder has no hook in the control cycle at all (the plant runs a cycle's
  sub-steps in one call); running, one call per plant sub-step.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from operator import call
from typing import TYPE_CHECKING

import numpy as np

from servodesk.domain.datatypes import DataType, Value
from servodesk.domain.profile import DeviceProfile, RecorderSpec

if TYPE_CHECKING:
    from servodesk.sim.engine import SimulatedDrive

IDLE, WAITING, RECORDING, DONE = 0, 1, 2, 3
NO_TRIGGER = 0xFFFFFFFF
#: The stream data's header: first sample index, status, channels, reserved (docs/scope.md).
STREAM_HEADER = struct.Struct("<IBBH")

TRIGGER_IMMEDIATE, TRIGGER_RISING, TRIGGER_FALLING = 0, 1, 2

#: CiA 301 abort codes the recorder answers with.
ABORT_VALUE = 0x06090030  # Invalid value for parameter.
ABORT_APPLICATION = 0x08000020  # Data cannot be transferred or stored to the application.
ABORT_STATE = 0x08000022  # ... because of the present device state.

#: (abort code, detail) of a refused write.
Refusal = tuple[int, str]
Getter = Callable[[], Value | None]


class Recorder:
    """The recorder of one :class:`~servodesk.sim.engine.SimulatedDrive` (built by it when
    the profile has a ``recorder:`` block). All methods run under the drive's lock."""

    def __init__(self, drive: SimulatedDrive, spec: RecorderSpec) -> None:
        self.drive = drive
        self.spec = spec
        base = spec.index
        self._first = base
        self._last = base + RecorderSpec.TRIGGER_INDEX
        self._control_index = base + RecorderSpec.CONTROL
        self._channels_index = base + RecorderSpec.CHANNELS
        self._stream_index = base + RecorderSpec.STREAM_POSITION
        #: The profile gives the drive the streaming objects (+10, +11): optional.
        self.streams = drive.has_object(self._stream_index) and drive.has_object(
            base + RecorderSpec.STREAM_DATA
        )
        if self.streams:
            self._last = base + RecorderSpec.STREAM_DATA
        #: Samples per second at divider 1: the drive's plant rate.
        self.rate_hz = 1.0 / drive.plant_period
        # The hook object is kept so that removing it finds the same bound method.
        self._hook = self._on_substep
        self.reset()

    # ------------------------------------------------------------------ engine interface

    def owns(self, index: int) -> bool:
        return self._first <= index <= self._last

    def live(self) -> dict[int, Getter]:
        """Getters of the read-only objects (status, data, count, trigger index) by key."""
        base = self._first
        getters: dict[int, Getter] = {
            (base + RecorderSpec.CONTROL) << 8: lambda: self.status,
            (base + RecorderSpec.DATA) << 8: self.data,
            (base + RecorderSpec.COUNT) << 8: lambda: self.count,
            (base + RecorderSpec.TRIGGER_INDEX) << 8: lambda: self.trigger_index,
        }
        if self.streams:
            getters[self._stream_index << 8] = lambda: self.stream_position
            getters[(base + RecorderSpec.STREAM_DATA) << 8] = self.stream_data
        return getters

    def write(self, index: int, subindex: int, value: Value) -> Refusal | None:
        """Check (and for the control object, act on) a write; the drive stores the value."""
        if index == self._control_index:
            if value == 1:
                return self._start()
            if value == 0:
                self.stop()
                return None
            return (ABORT_VALUE, "write 1 to start or 0 to stop the recorder")
        if index == self._stream_index:
            # Written while recording too: the reader rewinds after a lost answer.
            assert isinstance(value, int)
            self.stream_position = value
            return None
        if self._state in (WAITING, RECORDING):
            return (ABORT_STATE, "the recorder is running: write 0 to the control object first")
        if index == self._channels_index and subindex >= 1:
            assert isinstance(value, int)
            return self._check_channel(value)
        return None

    def reset(self) -> None:
        """Power-on state: idle, nothing recorded (NMT reset node)."""
        self.drive.remove_substep_hook(self._hook)
        self._state = IDLE
        self._rows: list[tuple[Value | None, ...]] = []
        self._kinds: tuple[str, ...] = ()
        self._trigger_index = NO_TRIGGER
        self._data: bytes | None = None
        self._pre = 0
        self._post: list[tuple[Value | None, ...]] = []
        self._ring: list[tuple[Value | None, ...]] = []
        self._seen = 0
        self._pos = 0
        self._getters: tuple[Getter, ...] = ()
        self._countdown = 1
        self._depth = 0
        self._post_len = 0
        self._trigger = TRIGGER_IMMEDIATE
        self._level = 0
        self._arm_at = 1
        self._prev: Value | None = None
        #: Plant step (:attr:`SimulatedDrive.plant_steps`) of the first sample since the start,
        #: and the sample numbers of the data's first sample and of the trigger sample.
        self.first_step: int | None = None
        self.divider = 1
        self._data_first_sample = 0
        self._trigger_sample: int | None = None
        #: +10: the data index the next read of +11 starts at.
        self.stream_position = 0

    # ------------------------------------------------------------------ the objects

    @property
    def status(self) -> int:
        return self._state

    @property
    def count(self) -> int:
        """Samples per channel in the data (while running: held so far)."""
        if self._state == WAITING:
            return min(self._seen, self._pre)
        if self._state == RECORDING:
            return len(self._rows) + len(self._post)
        return len(self._rows)

    @property
    def trigger_index(self) -> int:
        return self._trigger_index

    def data(self) -> bytes | None:
        """The recording as uploaded: None (0800 0024h) while running or when empty."""
        if self._state in (WAITING, RECORDING) or not self._rows:
            return None
        if self._data is None:
            self._data = _encode(self._rows, self._kinds)
        return self._data

    def stream_data(self) -> bytes:
        """+11: the header, then the samples from the stream position to the fill level (none
        while waiting for the trigger); the position moves past what is sent."""
        first = self.stream_position
        state = self._state
        rows = self._rows
        if state == WAITING:
            new: list[tuple[Value | None, ...]] = []
        elif state == RECORDING:
            # The data so far is rows (pre-trigger) then post; slice both, copy nothing else.
            new = rows[first:] + self._post[max(0, first - len(rows)) :]
        else:
            new = rows[first:]
        self.stream_position = first + len(new)
        header = STREAM_HEADER.pack(first, state, len(self._kinds), 0)
        return header + _encode(new, self._kinds) if new else header

    @property
    def data_first_step(self) -> int | None:
        """Plant step at which the data's first sample was taken (None: no data)."""
        if self.first_step is None:
            return None
        return self.first_step + self._data_first_sample * self.divider

    @property
    def trigger_step(self) -> int | None:
        """Plant step of the trigger sample (None: not triggered)."""
        if self.first_step is None or self._trigger_sample is None:
            return None
        return self.first_step + self._trigger_sample * self.divider

    # ------------------------------------------------------------------ start and stop

    def _config(self, offset: int, sub: int = 0) -> int:
        v = self.drive.read(self._first + offset, sub)
        return int(v) if isinstance(v, int | float) else 0

    def _check_channel(self, entry: int) -> Refusal | None:
        if entry == 0:
            return None
        index, sub, bits = entry >> 16, entry >> 8 & 0xFF, entry & 0xFF
        drive = self.drive
        if not drive.has_object(index, sub):
            return (ABORT_VALUE, f"0x{entry:08X}: {index:04X}h:{sub:02X} is no object")
        spec = drive.spec(index, sub)
        if not RecorderSpec.recordable(spec):
            return (
                ABORT_VALUE,
                f"0x{entry:08X}: {spec.name} ({spec.data_type.name}) cannot be recorded: "
                "integers of up to 32 bits and REAL32 only",
            )
        if bits != spec.bits:
            return (ABORT_VALUE, f"0x{entry:08X}: {spec.name} has {spec.bits} bits")
        return None

    def _start(self) -> Refusal | None:
        spec = self.spec
        drive = self.drive
        entries = [self._config(RecorderSpec.CHANNELS, n) for n in range(1, spec.max_channels + 1)]
        used = [e for e in entries if e]
        if not used:
            return (ABORT_APPLICATION, "no channel: write an object to record first")
        for e in used:
            refusal = self._check_channel(e)
            if refusal is not None:
                return (ABORT_APPLICATION, refusal[1])
        trigger = self._config(RecorderSpec.TRIGGER)
        if trigger not in (TRIGGER_IMMEDIATE, TRIGGER_RISING, TRIGGER_FALLING):
            return (ABORT_APPLICATION, f"trigger {trigger}: 0 immediate, 1 rising, 2 falling")
        depth = self._config(RecorderSpec.DEPTH)
        if not 1 <= depth <= spec.max_depth:
            return (ABORT_APPLICATION, f"depth {depth}: 1..{spec.max_depth} samples")
        pre = self._config(RecorderSpec.PRE_TRIGGER) if trigger else 0
        if pre >= depth:
            return (ABORT_APPLICATION, f"pre-trigger {pre} must be below the depth {depth}")
        getters = [drive.sampler(e >> 16, e >> 8 & 0xFF) for e in used]
        if trigger and not entries[0]:
            return (ABORT_APPLICATION, "a level trigger needs channel 1 (sub 1) set")
        if trigger and not isinstance(getters[0](), int | float):
            return (ABORT_APPLICATION, "channel 1 has no value to compare with the level")
        self.reset()
        self._getters = tuple(getters)
        self._kinds = tuple(
            "f" if drive.spec(e >> 16, e >> 8 & 0xFF).data_type is DataType.REAL32 else "i"
            for e in used
        )
        self.divider = max(1, self._config(RecorderSpec.DIVIDER))
        self._countdown = 1
        self._depth = depth
        self._pre = pre
        self._trigger = trigger
        self._level = self._config(RecorderSpec.LEVEL)
        self._arm_at = max(pre, 1)
        self._ring = [()] * pre
        # The first sample is taken after the next plant step.
        self.first_step = drive.plant_steps + 1
        self._post_len = depth
        if trigger == TRIGGER_IMMEDIATE:
            self._trigger_sample = 0
            self._trigger_index = 0
            self._state = RECORDING
        else:
            self._state = WAITING
        drive.on_substep(self._hook)
        return None

    def stop(self) -> None:
        """Stop a running recording and keep what it holds."""
        state = self._state
        if state == WAITING:
            # The ring holds the last min(seen, pre) samples; full, its oldest is at _pos.
            ring, pos = self._ring, self._pos
            self._rows = ring[pos:] + ring[:pos] if self._seen >= self._pre else ring[:pos]
            self._data_first_sample = self._seen - len(self._rows)
            self._finish(IDLE)
        elif state == RECORDING:
            self._rows += self._post
            self._finish(IDLE)

    def _finish(self, state: int) -> None:
        self._state = state
        self._post = []
        self._ring = []
        self._data = None
        self.drive.remove_substep_hook(self._hook)

    # ------------------------------------------------------------------ the hot path

    def _on_substep(self) -> None:
        """After every plant sub-step while running (keep it short: 4 kHz)."""
        self._countdown -= 1
        if self._countdown:
            return
        self._countdown = self.divider
        state = self._state
        row = tuple(map(call, self._getters))
        if state == RECORDING:
            post = self._post
            post.append(row)
            if len(post) >= self._post_len:
                self._rows += post
                self._finish(DONE)
            return
        if state != WAITING:
            return  # Removed within this control cycle; the cycle still holds the hook.
        v = row[0]
        prev = self._prev
        self._prev = v
        n = self._seen
        self._seen = n + 1
        if n >= self._arm_at:
            level = self._level
            crossed = (
                prev < level <= v  # type: ignore[operator]
                if self._trigger == TRIGGER_RISING
                else prev > level >= v  # type: ignore[operator]
            )
            if crossed:
                pre = self._pre
                ring, pos = self._ring, self._pos
                self._rows = ring[pos:] + ring[:pos] if pre else []
                self._data_first_sample = n - pre
                self._trigger_sample = n
                self._trigger_index = pre
                self._state = RECORDING
                self._post = [row]
                self._post_len = self._depth - pre
                if self._post_len <= 1:
                    self._rows += self._post
                    self._finish(DONE)
                return
        if self._pre:
            self._ring[self._pos] = row
            self._pos = (self._pos + 1) % self._pre


def _encode(rows: list[tuple[Value | None, ...]], kinds: tuple[str, ...]) -> bytes:
    """Channel-interleaved INTEGER32 little-endian words (REAL32 as its IEEE bits).

    numpy: the drive's lock is held while the SDO server fetches the data, and a full
    recording (8 x 8192 words) takes several times longer in a Python loop.
    """
    out = np.empty((len(rows), len(kinds)), dtype="<u4")
    for j, (kind, col) in enumerate(zip(kinds, zip(*rows, strict=True), strict=True)):
        dtype = np.float32 if kind == "f" else np.int64
        try:
            a = np.array(col, dtype=dtype)
        except (TypeError, ValueError):  # An object without a value (None) records 0.
            a = np.array([v or 0 for v in col], dtype=dtype)
        out[:, j] = a.view(np.uint32) if kind == "f" else np.bitwise_and(a, 0xFFFFFFFF)
    return out.tobytes()


def recorder_objects(profile: DeviceProfile) -> list[str]:
    """Problems with a profile's recorder objects (empty: consistent with docs/scope.md)."""
    spec = profile.recorder
    if spec is None:
        return []
    problems: list[str] = []
    entries = profile.entries
    expect: dict[int, DataType] = {
        RecorderSpec.DIVIDER: DataType.UNSIGNED16,
        RecorderSpec.DEPTH: DataType.UNSIGNED16,
        RecorderSpec.TRIGGER: DataType.UNSIGNED8,
        RecorderSpec.LEVEL: DataType.INTEGER32,
        RecorderSpec.PRE_TRIGGER: DataType.UNSIGNED16,
        RecorderSpec.CONTROL: DataType.UNSIGNED8,
        RecorderSpec.DATA: DataType.DOMAIN,
        RecorderSpec.COUNT: DataType.UNSIGNED32,
        RecorderSpec.TRIGGER_INDEX: DataType.UNSIGNED32,
    }
    for offset in range(RecorderSpec.TRIGGER_INDEX + 1):
        index = spec.object_index(offset)
        entry = entries.get(index)
        if entry is None:
            problems.append(f"recorder: {index:04X}h is missing")
            continue
        if spec.sim_only and not entry.sim_only:
            problems.append(f"recorder: {index:04X}h is not marked sim_only")
        if offset == RecorderSpec.CHANNELS:
            subs = {s.subindex: s for s in entry.specs()}
            for n in range(1, spec.max_channels + 1):
                s = subs.get(n)
                if s is None or s.data_type is not DataType.UNSIGNED32 or not s.access.writable:
                    problems.append(f"recorder: {index:04X}h:{n:02X} must be a writable UNSIGNED32")
        elif entry.data_type is not expect[offset]:
            problems.append(f"recorder: {index:04X}h must be {expect[offset].name}")
    # The streaming objects are optional, but both or neither (docs/scope.md).
    stream = {
        RecorderSpec.STREAM_POSITION: (DataType.UNSIGNED32, True),
        RecorderSpec.STREAM_DATA: (DataType.DOMAIN, False),
    }
    present = [offset for offset in stream if spec.object_index(offset) in entries]
    if len(present) == 1:
        problems.append(
            f"recorder: {spec.object_index(present[0]):04X}h without "
            f"{spec.object_index(({*stream} - {*present}).pop()):04X}h: streaming needs both"
        )
    for offset in present:
        index = spec.object_index(offset)
        entry = entries[index]
        data_type, writable = stream[offset]
        if (
            entry.data_type is not data_type
            or entry.access is None
            or entry.access.writable != writable
        ):
            access = "writable" if writable else "read-only"
            problems.append(f"recorder: {index:04X}h must be a {access} {data_type.name}")
        if spec.sim_only and not entry.sim_only:
            problems.append(f"recorder: {index:04X}h is not marked sim_only")
    return problems
