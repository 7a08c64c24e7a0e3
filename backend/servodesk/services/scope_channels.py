"""The live scope's channels (docs/scope.md "Model"): their configuration, sample ring
buffers and status, and the scope's limits (channels, buffer, rates); shared by the
service (services/scope.py) and its sources (scope_sources.py, scope_recorder.py)."""

from __future__ import annotations

import collections
import logging
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from servodesk.domain import scope as core
from servodesk.domain import scope_wire as wire
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import Value
from servodesk.domain.profile import ObjectSpec
from servodesk.domain.scope import MAX_CHANNELS as MAX_CHANNELS  # The domain's: the one limit.
from servodesk.errors import (
    ValidationError,
)

if TYPE_CHECKING:
    pass

log = logging.getLogger(__name__)

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
#: slower sources keep longer). A ring holds float64 times and values: 40,000 samples are
#: 640 kB per channel, 20 MB with all 32 (docs/scope.md "Model").
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


def as_number(v: Value) -> float | None:
    if isinstance(v, bool | int | float):
        return float(v)
    return None
