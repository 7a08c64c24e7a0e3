"""The live scope (issue 7, docs/scope.md): channels, sources, triggers and the frame fan-out.

One :class:`ScopeService` belongs to the application. Its channels (up to 8) come from one or
several sessions and share one time base, the backend's ``time.time()``:

- ``pdo``: a listener on the session's cyclic exchange (services/cyclic.py) takes every
  decoded TPDO on the bus thread; a sample's time is the frame's bus timestamp.
- ``sdo``: one polling task per session reads its channels' objects in turn, as fast as the
  link answers (or at a requested rate); a sample's time is when the answer arrived.
- ``recorder``: the drive's own trace function (profile ``recorder`` block, sim/recorder.py)
  records at its control rate; its samples are placed at the recorder's period from the
  anchor sample, whose backend time is when servodesk saw the recording start.

Samples go into per-channel buffers (thread-safe: the PDO listener runs on the bus thread);
every 10 ms (``FRAME_PERIOD_S``) the producer task moves them into the rings, feeds the
trigger engine and encodes one binary frame (domain/scope_wire.py) that it offers to every
WebSocket client. Each client has its own queue of a quarter of a second of frames
(``CLIENT_QUEUE``); when it is full the oldest frame is dropped whole
and counted, so a slow client never slows the drive, the backend or the other clients (the
producer never awaits a socket). Nothing is invented: no interpolation, no NaN padding; the
times are the times the samples were taken or received.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
import math
import struct
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from servodesk.domain import cia402
from servodesk.domain import scope as core
from servodesk.domain import scope_export as export
from servodesk.domain import scope_wire as wire
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, codec
from servodesk.domain.profile import ObjectSpec, RecorderSpec
from servodesk.errors import (
    ConflictError,
    LinkError,
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.links.base import LinkEvent
from servodesk.links.cyclic import no_cyclic_reason

if TYPE_CHECKING:
    from servodesk.services.cyclic import CyclicExchange
    from servodesk.services.manager import SessionManager
    from servodesk.services.session import Session

log = logging.getLogger(__name__)

#: At most this many channels per scope (docs/scope.md "Model").
MAX_CHANNELS = 8
#: The producer's period: a frame carries what arrived since the previous one [s]. A sample
#: waits half of it on average (all of it at worst) before it is sent, which the live
#: latency aim (p99 < 50 ms from sample time to client) cannot spare much of; a frame's
#: fixed costs (one tick, one send per client) bound it from below (bench scope: 30 ms
#: gave p50 ~55-70 ms with 4 drives x 8 channels, 10 ms takes ~15 ms off).
FRAME_PERIOD_S = 0.01
#: Frames queued per WebSocket client before the oldest is dropped: a quarter of a second of
#: data, so a browser tab that pauses for a garbage collection or a layout does not lose any.
CLIENT_QUEUE = round(0.25 / FRAME_PERIOD_S)
#: A status frame at least this often [s] (achieved rates, sample counts).
STATUS_PERIOD_S = 1.0
#: Seconds of history the rings keep at the fastest rate a source offers (a 4 kHz recorder;
#: slower sources keep longer).
BUFFER_S = 10.0
RING_CAPACITY = int(BUFFER_S * 4000)
#: Window of sample times the achieved rate is measured over [s].
RATE_WINDOW_S = 2.0
#: A bus timestamp further than this from the backend clock is from another clock (a CAN
#: adapter's own counter): the reception time is used instead [s].
CLOCK_TOLERANCE_S = 0.5
#: Largest recording file the import opens [bytes].
MAX_IMPORT_BYTES = 64 << 20
#: A state or fault trigger polls the statusword this often [Hz] (its time resolution).
STATE_POLL_HZ = 100.0

STATUSWORD = ObjectAddress(0x6041)

SOURCES = ("auto", "pdo", "sdo", "recorder")
SOURCE_CODE = wire.SOURCE_CODES


# Channel configuration ---------------------------------------------------------------------


@dataclass(frozen=True)
class ChannelConfig:
    """One channel as the user asks for it (PUT /scope/channels)."""

    id: int
    session: str
    address: ObjectAddress
    source: str = "auto"
    #: Display scale and offset (shown = engineering x scale + offset; the page applies them).
    scale: float = 1.0
    offset: float = 0.0
    visible: bool = True
    label: str | None = None
    #: Requested rate [Hz]: SDO polls this often, a recorder samples at the nearest rate its
    #: divider gives; 0: as fast as the link answers, or the recorder's fastest.
    rate_hz: float = 0.0


class SampleBuffer:
    """Samples waiting for the next frame: appended from any thread, taken by the producer."""

    __slots__ = ("_lock", "_t", "_v")

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._t: list[float] = []
        self._v: list[float] = []

    def add(self, t: float, v: float) -> None:
        with self._lock:
            self._t.append(t)
            self._v.append(v)

    def add_many(self, t: Sequence[float], v: Sequence[float]) -> None:
        with self._lock:
            self._t.extend(t)
            self._v.extend(v)

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        with self._lock:
            t, v = self._t, self._v
            self._t, self._v = [], []
        return np.asarray(t, dtype=np.float64), np.asarray(v, dtype=np.float64)

    def clear(self) -> None:
        with self._lock:
            self._t, self._v = [], []


@dataclass(eq=False)
class ScopeChannel:
    """A configured channel and its live bookkeeping."""

    config: ChannelConfig
    spec: ObjectSpec
    source: str
    buffer: SampleBuffer = field(default_factory=SampleBuffer)
    ring: core.Ring = field(default_factory=lambda: core.Ring(RING_CAPACITY))
    #: Samples received since the scope started.
    samples: int = 0
    #: Samples older than one already kept (dropped; never expected).
    out_of_order: int = 0
    error: str | None = None
    #: Recent (first time, last time, count) of each batch, for the achieved rate, and the
    #: samples they hold.
    history: collections.deque[tuple[float, float, int]] = field(default_factory=collections.deque)
    history_n: int = 0
    rate_hz: float | None = None
    throughput_hz: float | None = None

    @property
    def id(self) -> int:
        return self.config.id

    @property
    def address(self) -> ObjectAddress:
        return self.config.address

    @property
    def session_id(self) -> str:
        return self.config.session

    def status(self) -> dict[str, Any]:
        c, s = self.config, self.spec
        return {
            "id": c.id,
            "session": c.session,
            "address": str(c.address),
            "name": s.name,
            "unit": s.unit,
            "raw_unit": s.raw_unit,
            "eng_scale": s.scale,
            "scale": c.scale,
            "offset": c.offset,
            "visible": c.visible,
            "label": c.label,
            "source": self.source,
            "requested_source": c.source,
            "requested_rate_hz": c.rate_hz or None,
            "rate_hz": round(self.rate_hz, 2) if self.rate_hz is not None else None,
            "throughput_hz": (
                round(self.throughput_hz, 2) if self.throughput_hz is not None else None
            ),
            "samples": self.samples,
            "error": self.error,
        }

    def note(self, t: np.ndarray) -> None:
        """Count new samples; measure the achieved rate on their times.

        ``throughput_hz`` is how many samples per second arrived over the last seconds of
        sample time. For PDO and SDO channels that is the achieved sample rate; a recorder's
        samples come in recordings at its own rate (``rate_hz``, set per recording) with
        gaps for the uploads, so its throughput is lower than its sample rate.
        """
        n = len(t)
        if not n:
            return
        self.samples += n
        last = float(t[-1])
        history = self.history
        history.append((float(t[0]), last, n))
        self.history_n += n
        while len(history) > 1 and history[0][1] < last - RATE_WINDOW_S:
            self.history_n -= history.popleft()[2]
        first = history[0][0]
        count = self.history_n
        if count > 1 and last > first:
            self.throughput_hz = (count - 1) / (last - first)
            if self.source != "recorder":
                self.rate_hz = self.throughput_hz


def parse_channel(data: dict[str, Any]) -> ChannelConfig:
    """A channel from its JSON (the route has checked the types)."""
    try:
        address = ObjectAddress.parse(str(data["address"]))
    except (ValueError, ValidationError) as exc:
        raise ValidationError(
            f"channel {data.get('id')}: {data.get('address')!r} is no object address",
            field="address",
            hint='write it as "0x6064:00"',
        ) from exc
    source = str(data.get("source") or "auto")
    if source not in SOURCES:
        raise ValidationError(
            f"channel {data.get('id')}: unknown source {source!r}",
            field="source",
            hint=f"use one of {', '.join(SOURCES)}",
        )
    return ChannelConfig(
        id=int(data["id"]),
        session=str(data["session"]),
        address=address,
        source=source,
        scale=float(data.get("scale") or 0.0) if data.get("scale") is not None else 1.0,
        offset=float(data.get("offset") or 0.0),
        visible=bool(data.get("visible", True)),
        label=data.get("label"),
        rate_hz=float(data.get("rate_hz") or 0.0),
    )


def _number(v: Value) -> float | None:
    if isinstance(v, bool | int | float):
        return float(v)
    return None


def tpdo_addresses(session: Session) -> set[ObjectAddress]:
    """Objects the session's running cyclic exchange receives in its active TPDOs."""
    ex = session.cyclic
    if ex is None or not ex.running:
        return set()
    return {a for ch in ex.tx for a in ch.addresses}


# Fan-out -----------------------------------------------------------------------------------

#: Offsets in the frame header (docs/scope.md "Wire format"): flags u16 at 6, seq u32 at 8,
#: skipped u32 at 12. A frame is encoded once and stamped per client when it is sent.
_STAMP = struct.Struct("<HII")
_STAMP_AT = 6


class ScopeClient:
    """One WebSocket client: a bounded queue of encoded frames, dropped oldest-first."""

    def __init__(self, maxlen: int = CLIENT_QUEUE) -> None:
        self.frames: collections.deque[bytes] = collections.deque()
        self.maxlen = maxlen
        self.seq = 0
        #: Frames dropped for this client so far.
        self.skipped = 0
        self._told = 0
        self.wakeup = asyncio.Event()
        self.closed = False
        self.sent = 0

    def offer(self, frame: bytes) -> None:
        """Queue a frame; never blocks (called by the producer)."""
        if len(self.frames) >= self.maxlen:
            self.frames.popleft()
            self.skipped += 1
        self.frames.append(frame)
        self.wakeup.set()

    def next_frame(self) -> bytes | None:
        """The oldest queued frame, stamped with this client's seq, skipped count and flag."""
        if not self.frames:
            self.wakeup.clear()
            return None
        frame = bytearray(self.frames.popleft())
        flags = int.from_bytes(frame[6:8], "little")
        if self.skipped != self._told:
            flags |= 1  # Frames were skipped before this one.
            self._told = self.skipped
        self.seq += 1
        _STAMP.pack_into(frame, _STAMP_AT, flags, self.seq & 0xFFFFFFFF, self.skipped)
        self.sent += 1
        return bytes(frame)

    async def get(self) -> bytes | None:
        """The next frame to send; None once the scope closed this client."""
        while not self.closed:
            frame = self.next_frame()
            if frame is not None:
                return frame
            await self.wakeup.wait()
        return None


# Sources -----------------------------------------------------------------------------------


class PdoSource:
    """The cyclic exchange's TPDOs of one session, for that session's ``pdo`` channels."""

    def __init__(self, session: Session, channels: list[ScopeChannel]) -> None:
        self.session = session
        self.channels = channels
        self.exchange: CyclicExchange | None = None
        # Buffers by address (two channels may show one object, e.g. with other scales).
        self._index: dict[ObjectAddress, list[SampleBuffer]] = {}
        for ch in channels:
            self._index.setdefault(ch.address, []).append(ch.buffer)
        self._listener = self._make_listener()

    def _make_listener(self) -> Callable[[float, dict[ObjectAddress, Value]], None]:
        index = self._index
        tolerance = CLOCK_TOLERANCE_S
        # The exchange hands over the same address objects with every frame of a TPDO (kept
        # alive by it): looked up by identity after the first time, as hashing an address
        # costs more than everything else here. A new listener per exchange (attach).
        by_id: dict[int, list[SampleBuffer] | None] = {}

        def on_sample(timestamp: float, sample: dict[ObjectAddress, Value]) -> None:
            # The frame's bus timestamp is the sample's time when it is on the backend's
            # clock (python-can's virtual and UDP buses, socketcan); an adapter counting
            # from its own epoch gets the reception time instead.
            now = time.time()
            t = timestamp if abs(now - timestamp) < tolerance else now
            # Called for every TPDO (thousands per second): only its own few objects.
            for address, v in sample.items():
                key = id(address)
                if key in by_id:
                    bufs = by_id[key]
                else:
                    bufs = by_id[key] = index.get(address)
                if bufs is not None and not isinstance(v, str | bytes):
                    for buf in bufs:
                        buf.add(t, float(v))

        return on_sample

    def attach(self) -> bool:
        """Listen to the session's present exchange; False when cyclic data does not run."""
        ex = self.session.cyclic
        if ex is self.exchange and ex is not None and ex.running:
            return True
        self.detach()
        if ex is None or not ex.running:
            return False
        self._listener = self._make_listener()
        ex.listeners.append(self._listener)
        self.exchange = ex
        return True

    def detach(self) -> None:
        ex = self.exchange
        if ex is not None:
            with contextlib.suppress(ValueError):
                ex.listeners.remove(self._listener)
        self.exchange = None

    def check(self) -> None:
        """Follow a restart of cyclic data; mark the channels when it stopped."""
        ok = self.attach()
        mapped = tpdo_addresses(self.session) if ok else set()
        for ch in self.channels:
            if not ok:
                ch.error = "cyclic data stopped: start it on the PDO page (no samples meanwhile)"
            elif ch.address not in mapped:
                ch.error = f"{ch.address} is no longer in an active TPDO"
            elif ch.error is not None and ch.error.startswith(("cyclic", "0x")):
                ch.error = None


class SdoSource:
    """One polling task per session: its ``sdo`` channels read in turn."""

    def __init__(self, session: Session, channels: list[ScopeChannel]) -> None:
        self.session = session
        self.channels = channels
        self.task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self.task = asyncio.get_running_loop().create_task(
            self._run(), name=f"scope sdo {self.session.id}"
        )

    async def stop(self) -> None:
        if self.task is not None:
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task
            self.task = None

    async def _run(self) -> None:
        link = self.session.link
        decoders = [codec(ch.spec.data_type).decode for ch in self.channels]
        due = [0.0] * len(self.channels)
        periods = [
            1.0 / ch.config.rate_hz if ch.config.rate_hz > 0 else 0.0 for ch in self.channels
        ]
        # A link that reads several objects in one request (PROFINET: one PROFIdrive request
        # of up to 39 parameters) samples the due channels together, at one time stamp;
        # the others read them in turn, each stamped when its answer arrived.
        together = bool(getattr(link, "reads_many_at_once", False))

        def sampled(i: int, raw: bytes | ServodeskError, t: float) -> None:
            ch = self.channels[i]
            if isinstance(raw, ServodeskError):
                ch.error = raw.message
                due[i] = time.monotonic() + 1.0
                return
            v = _number(decoders[i](raw))
            if v is not None:
                ch.buffer.add(t, v)
                ch.error = None
            if periods[i]:
                # Keep the requested rhythm; after a stall start again from now.
                due[i] = max(due[i] + periods[i], time.monotonic() - periods[i])

        while True:
            now = time.monotonic()
            ready = [i for i in range(len(self.channels)) if due[i] <= now]
            waited = not ready
            try:
                if together and ready:
                    raws = await link.read_many([self.channels[i].address for i in ready])
                    t = time.time()
                    for i, got in zip(ready, raws, strict=True):
                        sampled(i, got, t)
                else:
                    for i in ready:
                        one: bytes | ServodeskError
                        try:
                            one = await link.read(self.channels[i].address)
                        except LinkError:
                            raise
                        except ServodeskError as exc:
                            one = exc
                        # The sample's time: when its answer arrived.
                        sampled(i, one, time.time())
            except LinkError as exc:
                for i in ready:
                    self.channels[i].error = exc.message
                await asyncio.sleep(0.2)  # The bus is gone or busy: do not spin.
                continue
            if waited:
                wait = min(due) - time.monotonic()
                await asyncio.sleep(max(wait, 0.0005))
            else:
                # Let the session's own poll and other requests have the link in between.
                await asyncio.sleep(0)


class StateWatch:
    """The CiA 402 state of the trigger channel's session, for state and fault triggers.

    Its own statusword poll (one SDO read per period, far less than the session's full
    state poll) gives each change the time its answer arrived; EMCY messages (CiA 301
    §7.2.7) count as faults at the time the link received them.
    """

    def __init__(self, session: Session, kind: str, events: collections.deque[float]) -> None:
        self.session = session
        self.kind = kind
        self.events = events
        self.task: asyncio.Task[None] | None = None
        self.state: str | None = None

    def start(self) -> None:
        self.task = asyncio.get_running_loop().create_task(
            self._run(), name=f"scope state {self.session.id}"
        )
        if self.kind == "fault":
            self.session.link.add_event_callback(self._on_event)

    async def stop(self) -> None:
        self.session.link.remove_event_callback(self._on_event)
        if self.task is not None:
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task
            self.task = None

    def _on_event(self, ev: LinkEvent) -> None:
        # Bus thread. An EMCY with error code 0000h is "error reset / no error", not a fault.
        if ev.kind == "emcy" and int(ev.data.get("code", 0)):
            self.events.append(ev.time)

    async def _run(self) -> None:
        link = self.session.link
        period = 1.0 / STATE_POLL_HZ
        while True:
            try:
                raw = await link.read(STATUSWORD)
            except ServodeskError:
                await asyncio.sleep(0.1)
                continue
            t = time.time()
            state = cia402.decode_state(int.from_bytes(raw[:2], "little")).value
            prev, self.state = self.state, state
            changed = prev is not None and state != prev
            if changed and (self.kind == "state" or state == cia402.State.FAULT.value):
                self.events.append(t)
            await asyncio.sleep(period)


# The service -------------------------------------------------------------------------------


class ScopeService:
    """The application's scope: channels, acquisition, trigger, capture and fan-out."""

    def __init__(self, manager: SessionManager, *, max_channels: int = MAX_CHANNELS) -> None:
        self.manager = manager
        self.max_channels = max_channels
        self.channels: list[ScopeChannel] = []
        self.trigger = core.Trigger(mode="roll")
        self.engine: core.TriggerEngine | None = None
        self.running = False
        self.clients: set[ScopeClient] = set()
        self.capture_window: tuple[float, float] | None = None
        self.trigger_time: float | None = None
        self._capture: export.Recording | None = None
        #: A single capture completed (the scope stops after it).
        self._done = False
        self._finisher: asyncio.Task[None] | None = None
        self._pdo: list[PdoSource] = []
        self._sdo: list[SdoSource] = []
        self._recorders: list[Any] = []
        self._producer: asyncio.Task[None] | None = None
        self._events: collections.deque[float] = collections.deque(maxlen=64)
        self._watches: list[StateWatch] = []
        self._last_status = 0.0
        self._status_dirty = True
        self._t_started = 0.0
        self._lock = asyncio.Lock()
        #: Frames produced (samples and capture), for the bench and the status.
        self.frames = 0
        self.captures = 0

    # Status -----------------------------------------------------------------------------

    @property
    def state(self) -> str:
        if self._done:
            return "done"
        if not self.running:
            return "idle"
        if self.trigger.mode == "roll" or self.engine is None:
            return "rolling"
        s: str = self.engine.state
        return "armed" if s == "idle" else s

    def status(self) -> dict[str, Any]:
        return {
            "running": self.running,
            "state": self.state,
            "trigger": asdict(self.trigger),
            "channels": [ch.status() for ch in self.channels],
            "clients": len(self.clients),
            "buffer_s": BUFFER_S,
            "frame_period_ms": FRAME_PERIOD_S * 1000,
            "recorders": [r.status() for r in self._recorders],
        }

    # Configuration ----------------------------------------------------------------------

    async def set_channels(self, configs: list[ChannelConfig]) -> dict[str, Any]:
        """Check and take a new channel list (the scope restarts when it ran)."""
        if len(configs) > self.max_channels:
            raise ValidationError(
                f"{len(configs)} channels: a scope has at most {self.max_channels}",
                field="channels",
                hint="remove channels, or open a second view on another page",
            )
        ids = [c.id for c in configs]
        if len(set(ids)) != len(ids):
            raise ValidationError("two channels have the same id", field="channels")
        for c in configs:
            if not 0 <= c.id < self.max_channels:
                raise ValidationError(
                    f"channel id {c.id} is outside 0..{self.max_channels - 1}", field="channels"
                )
        slots: dict[str, int] = {}
        channels = [await self._resolve(c, slots) for c in configs]
        async with self._lock:
            was = self.running
            if was:
                await self._stop_acquisition()
            self.channels = sorted(channels, key=lambda ch: ch.id)
            self._capture = None
            self.capture_window = None
            self._done = False
            self._status_dirty = True
            if was:
                await self._start_acquisition()
        return self.status()

    async def _resolve(self, c: ChannelConfig, slots: dict[str, int]) -> ScopeChannel:
        """The channel with its object checked and its source chosen (docs/scope.md).

        ``slots`` counts the recorder channels taken per session so far.
        """
        session = self.manager.get(c.session)  # NotFoundError names it.
        spec = session.profile.spec(c.address)
        where = f"channel {c.id}: {c.address} on {c.session}"
        if spec is None:
            raise NotFoundError(
                f"{where} is not in the profile {session.profile.id}",
                hint="pick an object from the object dictionary page",
            )
        if not spec.access.readable:
            raise ValidationError(
                f"{where} ({spec.name}) is write-only: it cannot be sampled",
                field="address",
            )
        if not (spec.data_type.is_numeric or spec.data_type is DataType.BOOLEAN):
            raise ValidationError(
                f"{where} ({spec.name}) is a {spec.data_type.name}, not a number",
                field="address",
                hint="the scope shows numeric objects",
            )
        mapped = c.address in tpdo_addresses(session)
        recorder = recorder_of(session)
        recordable = recorder is not None and recorder.recordable(spec)
        free = recorder is not None and slots.get(c.session, 0) < recorder.max_channels
        source = c.source
        if source == "auto":
            source = "pdo" if mapped else "recorder" if recordable and free else "sdo"
        elif source == "pdo" and not mapped:
            no_cyclic = no_cyclic_reason(session.link)
            raise ValidationError(
                f"{where} is not in an active TPDO while cyclic data runs",
                field="source",
                hint=f"{no_cyclic}: use source sdo or auto"
                if no_cyclic
                else "map it on the PDO page and start cyclic data, or use source sdo or auto",
            )
        elif source == "recorder" and not recordable:
            raise ValidationError(
                f"{where}: "
                + (
                    "the drive has no recorder"
                    if recorder is None
                    else f"the drive's recorder cannot record {spec.name}"
                ),
                field="source",
                hint="use source sdo, or pdo when it is mapped",
            )
        elif source == "recorder" and not free:
            assert recorder is not None
            raise ValidationError(
                f"{where}: the drive's recorder has {recorder.max_channels} channels, all taken",
                field="source",
                hint="use source sdo or auto for this one",
            )
        if source == "recorder":
            slots[c.session] = slots.get(c.session, 0) + 1
        if source != "pdo":
            # One read now: an object the drive refuses (abort) is named here, not later as
            # a silent channel without samples.
            try:
                await session.link.read(c.address)
            except ObjectAccessError as exc:
                exc.message = f"{where}: {exc.message}"
                raise
        return ScopeChannel(config=c, spec=spec, source=source)

    async def set_trigger(self, trigger: core.Trigger) -> dict[str, Any]:
        known = {ch.id for ch in self.channels}
        if trigger.mode != "roll" and known and trigger.channel not in known:
            raise ValidationError(
                f"trigger channel {trigger.channel} is not configured",
                field="channel",
                hint=f"use one of {', '.join(str(ch.id) for ch in self.channels)}",
            )
        async with self._lock:
            was = self.running
            if was and (self._recorders or self._watches or trigger.kind in ("state", "fault")):
                # The drive's recorder takes the trigger in its configuration, and state or
                # fault triggers hook the session: start over with the new trigger.
                await self._stop_acquisition()
            self.trigger = trigger
            self._done = False
            self._setup_engine()
            if was and not self.running:
                await self._start_acquisition()
            self._status_dirty = True
        return self.status()

    def _setup_engine(self) -> None:
        if self.trigger.mode == "roll":
            self.engine = None
            return
        self.engine = core.TriggerEngine(self.trigger)
        if self.running:
            self.engine.arm()

    async def run(self, action: str) -> dict[str, Any]:
        async with self._lock:
            if action == "stop":
                if self.running:
                    await self._stop_acquisition()
            elif action in ("start", "arm"):
                # Refusals that depend on the scope's present set-up are conflicts (409).
                if not self.channels:
                    raise ConflictError(
                        "the scope has no channels", hint="add channels first (PUT /scope/channels)"
                    )
                if action == "arm" and self.trigger.mode == "roll":
                    raise ConflictError(
                        "roll mode has no trigger to arm",
                        hint="set the trigger mode to single or normal first",
                    )
                self._done = False
                self._setup_engine()
                if not self.running:
                    await self._start_acquisition()
                elif self.engine is not None:
                    self.engine.arm()
                if action == "arm":
                    self._capture = None
                    self.capture_window = None
            else:
                raise ValidationError(
                    f"unknown action {action!r}", field="action", hint="use start, stop or arm"
                )
            self._status_dirty = True
        return self.status()

    # Acquisition ------------------------------------------------------------------------

    async def _start_acquisition(self) -> None:
        by_session: dict[str, dict[str, list[ScopeChannel]]] = {}
        for ch in self.channels:
            ch.buffer.clear()
            ch.ring = core.Ring(RING_CAPACITY)
            ch.samples = 0
            ch.history.clear()
            ch.history_n = 0
            ch.throughput_hz = None
            ch.rate_hz = None
            ch.error = None
            by_session.setdefault(ch.session_id, {}).setdefault(ch.source, []).append(ch)
        self._t_started = time.time()
        for sid, groups in by_session.items():
            try:
                session = self.manager.get(sid)
            except NotFoundError as exc:
                for chans in groups.values():
                    for ch in chans:
                        ch.error = exc.message
                continue
            if "pdo" in groups:
                pdo = PdoSource(session, groups["pdo"])
                pdo.check()
                self._pdo.append(pdo)
            if "sdo" in groups:
                sdo = SdoSource(session, groups["sdo"])
                sdo.start()
                self._sdo.append(sdo)
            if "recorder" in groups:
                rec = recorder_of(session)
                if rec is not None:
                    src = RecorderSource(session, rec, groups["recorder"], self)
                    src.start()
                    self._recorders.append(src)
        self._hook_events()
        if self.engine is not None:
            self.engine.arm()
        self.running = True
        self._producer = asyncio.get_running_loop().create_task(
            self._produce(), name="scope producer"
        )

    async def _stop_acquisition(self) -> None:
        self.running = False
        if self._producer is not None:
            self._producer.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._producer
            self._producer = None
        for p in self._pdo:
            p.detach()
        for s in self._sdo:
            await s.stop()
        for r in self._recorders:
            await r.stop()
        self._pdo, self._sdo, self._recorders = [], [], []
        await self._unhook_events()
        # What arrived until now still counts: sent, and in the export.
        self._send(self._drain())
        if self.engine is not None:
            self.engine.stop()
        self._broadcast_status()

    async def close(self) -> None:
        async with self._lock:
            if self.running:
                await self._stop_acquisition()
        for c in list(self.clients):
            c.closed = True
            c.wakeup.set()

    # State and fault events -------------------------------------------------------------

    def _trigger_session(self) -> Session | None:
        ch = next((c for c in self.channels if c.id == self.trigger.channel), None)
        if ch is None:
            return None
        try:
            return self.manager.get(ch.session_id)
        except NotFoundError:
            return None

    def _hook_events(self) -> None:
        if self.trigger.mode == "roll" or self.trigger.kind not in ("state", "fault"):
            return
        session = self._trigger_session()
        if session is None:
            return
        watch = StateWatch(session, self.trigger.kind, self._events)
        watch.start()
        self._watches.append(watch)

    async def _unhook_events(self) -> None:
        for watch in self._watches:
            await watch.stop()
        self._watches = []
        self._events.clear()

    # Producer ---------------------------------------------------------------------------

    async def _produce(self) -> None:
        next_t = time.monotonic()
        while True:
            next_t += FRAME_PERIOD_S
            delay = next_t - time.monotonic()
            if delay < -10 * FRAME_PERIOD_S:
                next_t = time.monotonic()  # Far behind (a stalled machine): no burst.
            await asyncio.sleep(max(delay, 0.0))
            try:
                self._tick()
            except Exception:  # A bug here must not end the stream silently.
                log.exception("scope producer tick failed")

    def _drain(self) -> list[tuple[ScopeChannel, np.ndarray, np.ndarray]]:
        """Move buffered samples into the rings and the trigger; what each channel got."""
        fresh = []
        for ch in self.channels:
            t, v = ch.buffer.take()
            if not len(t):
                continue
            # (Array methods, not np.any/np.diff: this runs per channel on every frame.)
            if len(t) > 1 and (t[1:] < t[:-1]).any():
                # Two TPDOs carrying one object may interleave: keep the ring in time order.
                order = np.argsort(t, kind="stable")
                t, v = t[order], v[order]
            last = ch.ring.last_time
            if last is not None and t[0] < last:
                # Never expected (one source per channel delivers in order); kept out rather
                # than shown at a time it was not taken.
                keep = t >= last
                ch.out_of_order += int(len(t) - np.count_nonzero(keep))
                t, v = t[keep], v[keep]
                if not len(t):
                    continue
            ch.ring.extend(t, v)
            ch.note(t)
            fresh.append((ch, t, v))
            self._feed_trigger(ch, t, v)
        return fresh

    def _feed_trigger(self, ch: ScopeChannel, t: np.ndarray, v: np.ndarray) -> None:
        engine = self.engine
        # Fed always (not only while armed): the engine keeps the previous sample, so a
        # crossing right at the first sample after arming is seen too.
        if engine is not None and ch.id == self.trigger.channel and engine.feed(t, v) is not None:
            self._status_dirty = True

    def _tick(self) -> None:
        for p in self._pdo:
            p.check()
        fresh = self._drain()
        engine = self.engine
        if engine is not None:
            while self._events:
                if engine.event(self._events.popleft()) is not None:
                    self._status_dirty = True
            while (window := engine.complete(self._data_now())) is not None:
                last = engine.last_window
                self._take_capture(window, last[1] if last is not None else window[0])
                self._status_dirty = True
            if self.trigger.mode == "single" and engine.state == "done" and not self._done:
                # Single: one window, then the scope stops (docs/scope.md "Model").
                self._done = True
                self._finisher = asyncio.get_running_loop().create_task(self._finish_single())
        self._send(fresh)
        now = time.monotonic()
        if self._status_dirty or now - self._last_status >= STATUS_PERIOD_S:
            self._broadcast_status()

    async def _finish_single(self) -> None:
        async with self._lock:
            if self.running and self._done:
                await self._stop_acquisition()

    def _data_now(self) -> float:
        """The time up to which every running channel has delivered its samples.

        A window is complete when its end is covered by the slowest channel (a recorder's
        samples come after its upload), or at the latest 2 s after the wall clock passed it.
        """
        wall = time.time()
        latest = [ch.ring.last_time for ch in self.channels]
        known = [t for t in latest if t is not None]
        if not known or len(known) < len(latest):
            return wall - 2.0
        return max(min(known), wall - 2.0)

    def _take_capture(self, window: tuple[float, float], trigger_time: float) -> None:
        t0, t1 = window
        self.capture_window = window
        self.trigger_time = trigger_time
        chans = []
        blocks = []
        for ch in self.channels:
            t, v = ch.ring.window(t0, t1)
            chans.append(self._channel_data(ch, t - trigger_time, v))
            blocks.append(self._block(ch, t, v, trigger_time))
        self._capture = export.Recording(trigger_time, trigger_time, chans)
        self.captures += 1
        self._offer(wire.encode_frame(wire.KIND_CAPTURE, 0, 0, trigger_time, blocks))

    @staticmethod
    def _channel_data(ch: ScopeChannel, t: np.ndarray, v: np.ndarray) -> export.ChannelData:
        s = ch.spec
        return export.ChannelData(
            id=ch.id,
            name=ch.config.label or s.name,
            unit=s.unit or "",
            raw_unit=s.raw_unit or "",
            scale=s.scale,
            address=str(ch.address),
            session=ch.session_id,
            source=ch.source,
            t=t,
            v=v,
        )

    @staticmethod
    def _block(ch: ScopeChannel, t: np.ndarray, v: np.ndarray, t_ref: float) -> wire.Block:
        source = SOURCE_CODE[ch.source]
        if ch.source == "recorder" and len(t) > 1:
            # A recording's samples are equidistant (placed at its period): send the period
            # instead of the times when this piece has no gap between two recordings.
            # (Epoch times in float64 resolve about 0.24 us: equal within 1 us.)
            d = np.diff(t)
            if float(d.max() - d.min()) < 1e-6:
                return wire.Block(ch.id, source, v, float(d.mean()), float(t[0] - t_ref))
        return wire.Block.from_times(ch.id, source, t_ref, t, v)

    def _send(self, fresh: list[tuple[ScopeChannel, np.ndarray, np.ndarray]]) -> None:
        """One samples frame with everything that arrived since the previous one."""
        if not fresh:
            return
        t_ref = min(float(t[0]) for _, t, _ in fresh)
        blocks = [self._block(ch, t, v, t_ref) for ch, t, v in fresh]
        self._offer(wire.encode_frame(wire.KIND_SAMPLES, 0, 0, t_ref, blocks))

    def _offer(self, frame: bytes) -> None:
        self.frames += 1
        for c in self.clients:
            c.offer(frame)

    def _broadcast_status(self) -> None:
        self._status_dirty = False
        self._last_status = time.monotonic()
        if self.clients:
            self._offer(self.status_frame())

    def status_frame(self) -> bytes:
        return wire.encode_status(0, 0, time.time(), {"type": "status", **self.status()})

    # Clients ----------------------------------------------------------------------------

    def connect(self) -> ScopeClient:
        client = ScopeClient()
        self.clients.add(client)
        client.offer(self.status_frame())
        self._status_dirty = True
        return client

    def disconnect(self, client: ScopeClient) -> None:
        self.clients.discard(client)
        self._status_dirty = True

    # Recordings -------------------------------------------------------------------------

    def capture(self) -> dict[str, Any]:
        """The last captured window (docs/scope.md: GET /scope/capture), with the window's
        bounds (``window``: seconds from ``t_ref``): samples are only where there were some."""
        out = self._recording_json(self._capture_recording())
        if self.capture_window is not None:
            t_ref = out["t_ref"]
            out["window"] = [self.capture_window[0] - t_ref, self.capture_window[1] - t_ref]
        return out

    def kept(self, window: str) -> tuple[Callable[[], dict[str, Any]], dict[str, Any] | None]:
        """What a kept capture stores (services/capture_store.py), taken now: a function that
        makes the JSON of the captured window (``window="capture"``, as :meth:`capture`) or
        of the buffer, with each channel's display settings, and the trigger as set (None for
        the buffer). The function may run in a worker thread (a full buffer's JSON held the
        loop, as the export's did)."""
        rec = self._capture_recording() if window == "capture" else self.buffer_recording()
        configs = {ch.id: ch.config for ch in self.channels}
        bounds = self.capture_window if window == "capture" else None
        trigger = asdict(self.trigger) if window == "capture" else None

        def make() -> dict[str, Any]:
            out = rec.to_json()
            for c in out["channels"]:
                c["eng_scale"] = c["scale"]
                cfg = configs.get(c["id"])
                if cfg is not None:
                    c["label"] = cfg.label
                    c["display_scale"] = cfg.scale
                    c["offset"] = cfg.offset
            if bounds is not None:
                out["window"] = [bounds[0] - out["t_ref"], bounds[1] - out["t_ref"]]
            return out

        return make, trigger

    def _capture_recording(self) -> export.Recording:
        if self._capture is None:
            raise NotFoundError(
                "no captured window yet",
                hint="set a single or normal trigger, arm it and wait for the event",
            )
        return self._capture

    def buffer_recording(self) -> export.Recording:
        """Everything the rings hold (the export's ``window=buffer``), times from the oldest."""
        data = [(ch, *ch.ring.all()) for ch in self.channels]
        firsts = [float(t[0]) for _, t, _ in data if len(t)]
        if not firsts:
            raise NotFoundError(
                "the scope holds no samples", hint="start the scope and let it record first"
            )
        t_ref = min(firsts)
        return export.Recording(
            t_ref, None, [self._channel_data(ch, t - t_ref, v) for ch, t, v in data]
        )

    def _recording_json(self, rec: export.Recording) -> dict[str, Any]:
        out = rec.to_json()
        # The page's display settings travel beside the profile's data of each channel.
        configs = {ch.id: ch.config for ch in self.channels}
        for c in out["channels"]:
            cfg = configs.get(c["id"])
            c["eng_scale"] = c["scale"]
            if cfg is not None:
                c["label"] = cfg.label
                c["display_scale"] = cfg.scale
                c["offset"] = cfg.offset
        return out

    def export(self, fmt: str, window: str) -> tuple[bytes, str, str]:
        """(file bytes, media type, file name) of the capture or the buffer."""
        rec = self._capture_recording() if window == "capture" else self.buffer_recording()
        data, media = export.export_recording(rec, fmt)
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(rec.t_ref))
        ext = "mf4" if fmt == "mdf4" else "csv"
        return data, media, f"scope-{window}-{stamp}.{ext}"

    async def export_off_loop(self, fmt: str, window: str) -> tuple[bytes, str, str]:
        """:meth:`export` with the recording taken on the loop (the buffers change there) and
        the file formatted in a worker thread (api/offload.py)."""
        rec = self._capture_recording() if window == "capture" else self.buffer_recording()
        data, media = await asyncio.to_thread(export.export_recording, rec, fmt)
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(rec.t_ref))
        ext = "mf4" if fmt == "mdf4" else "csv"
        return data, media, f"scope-{window}-{stamp}.{ext}"

    def import_recording(self, data: bytes, filename: str) -> dict[str, Any]:
        """A recording file (CSV or MDF4) as the JSON the page opens."""
        return import_recording(data, filename)


def import_recording(data: bytes, filename: str) -> dict[str, Any]:
    """A recording file (CSV or MDF4) as the JSON the page opens."""
    if len(data) > MAX_IMPORT_BYTES:
        raise ValidationError(
            f"{filename}: {len(data)} bytes is above the {MAX_IMPORT_BYTES >> 20} MiB the "
            "scope opens",
            hint="export a shorter window",
        )
    if not data:
        raise ValidationError(f"{filename}: the file is empty", hint="send the file's bytes")
    return export.import_recording(data, filename).to_json()


def import_recording_json(data: bytes, filename: str) -> bytes:
    """:func:`import_recording` as JSON bytes: what the documents' worker process returns
    (api/offload.py), so that neither the parse nor the serialisation holds the loop."""
    doc = import_recording(data, filename)
    # As Starlette's JSONResponse renders it (to_json gives None for NaN).
    return json.dumps(doc, ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode()


# Drive-side recorder ----------------------------------------------------------------------

#: Recorder status values (docs/scope.md: 0 idle, 1 waiting for the trigger, 2 recording, 3 done).
REC_IDLE, REC_WAITING, REC_RECORDING, REC_DONE = 0, 1, 2, 3
#: Sample time one free-running recording covers [s]: the upload of the next one waits for
#: it, so longer recordings mean fewer gaps but more latency.
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
