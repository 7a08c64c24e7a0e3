"""The live scope (issue 7, docs/scope.md): channels, sources, triggers and the frame fan-out.

One :class:`ScopeService` belongs to the application. Its channels (up to 32, 4 drives x 8)
come from one or several sessions and share one time base, the backend's ``time.time()``:

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

The channels and their buffers are services/scope_channels.py, the PDO, SDO and state
sources services/scope_sources.py, the drive-side recorder services/scope_recorder.py. About
700 lines remain: :class:`ScopeService`'s configuration, run state, trigger, producer and
fan-out share its channels and buffers under one lock, as one acquisition.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
import struct
import time
from collections.abc import Callable
from dataclasses import asdict
from typing import TYPE_CHECKING, Any

import numpy as np

from servodesk.domain import scope as core
from servodesk.domain import scope_export as export
from servodesk.domain import scope_wire as wire
from servodesk.domain.datatypes import DataType
from servodesk.errors import (
    ConflictError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links.cyclic import no_cyclic_reason

if TYPE_CHECKING:
    from servodesk.services.manager import SessionManager
    from servodesk.services.session import Session

from servodesk.services.scope_channels import (
    BUFFER_S,
    CLIENT_QUEUE,
    FRAME_PERIOD_S,
    MAX_CHANNELS,
    MAX_IMPORT_BYTES,
    RING_CAPACITY,
    SOURCE_CODE,
    STATUS_PERIOD_S,
    ChannelConfig,
    ScopeChannel,
)
from servodesk.services.scope_recorder import RecorderSource, recorder_of
from servodesk.services.scope_sources import PdoSource, SdoSource, StateWatch, tpdo_addresses

log = logging.getLogger(__name__)

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
            p.flush()
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
            p.flush()
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
                # The recorder's own period where known: a short streamed piece's mean of
                # epoch differences is off by up to 0.24 us / n.
                period = 1.0 / ch.rate_hz if ch.rate_hz else float(d.mean())
                if abs(period - float(d.mean())) > 1e-6:
                    period = float(d.mean())
                return wire.Block(ch.id, source, v, period, float(t[0] - t_ref))
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
