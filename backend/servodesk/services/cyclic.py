"""A session's cyclic process data: TPDOs consumed, RPDOs produced, SYNC at a set period.

One :class:`CyclicExchange` per session. Its thread sends, every period, the RPDO frames (when
outputs are on) and then SYNC (CiA 301 §7.2.5: the drive samples its synchronous TPDOs and
applies its synchronous RPDOs at SYNC). TPDO frames are decoded on the bus thread the moment
they arrive, into the latest value of each mapped object and its receive time; the event loop
publishes the latest values to WebSocket watchers at 20 Hz, never a backlog.

Outputs are off by default: on a machine the PLC owns the RPDOs, and a second producer would
fight it. When a user turns them on, the output image starts from the drive's present values
(read by SDO), so switching on changes nothing on the axis; servodesk's own SDO writes to a
mapped RX object (the Operation page's controlword, targets) update the image too, so the next
RPDO carries them instead of overwriting them with a stale value.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

from servodesk.domain import pdo as pdomod
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import CONTROLWORD
from servodesk.domain.datatypes import DataType, Value, codec
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import ConflictError
from servodesk.links.base import QUICK_STOP_WORD
from servodesk.links.cyclic import CyclicTransport

if TYPE_CHECKING:
    from servodesk.services.session import Session

log = logging.getLogger(__name__)

#: Longest SYNC period accepted [s] and shortest (1 ms: the issue's target cycle).
MIN_PERIOD = 0.001
MAX_PERIOD = 1.0
#: A TPDO silent this long [s] (the exchange running at least as long) is explained.
IDLE_AFTER_S = 1.0
#: The event timer the "send it periodically" fix proposes [ms] (CiA 301 1800h:05, 1 ms).
FIX_EVENT_TIMER_MS = 100
#: WebSocket publishing rate of the latest values [Hz].
PUBLISH_HZ = 20.0
#: The controlword (CiA 402-2 §6.2.1), quick-stopped in the output image on a link loss.
LINK_LOST = "link lost"

_STRUCT = {
    DataType.INTEGER8: "b",
    DataType.UNSIGNED8: "B",
    DataType.INTEGER16: "h",
    DataType.UNSIGNED16: "H",
    DataType.INTEGER32: "i",
    DataType.UNSIGNED32: "I",
    DataType.INTEGER64: "q",
    DataType.UNSIGNED64: "Q",
    DataType.REAL32: "f",
    DataType.REAL64: "d",
}

Decoder = Callable[[bytes], tuple[Value, ...]]
#: Called on the bus thread for every TPDO decoded with (receive time, the TPDO's mapped
#: addresses, their values in that order); the addresses are the same list object with every
#: frame of a TPDO. It runs inside the cycle (on EtherCAT the line's one cycle thread, once per
#: slave and cycle), so a listener only takes the frame and does its work elsewhere: the
#: scope's costs 1-2 µs a frame (docs/scope.md "EtherCAT and PROFINET cyclic channels").
SampleListener = Callable[[float, list[ObjectAddress], tuple[Value, ...]], None]


def compile_decoder(profile: DeviceProfile, pdo: pdomod.Pdo) -> tuple[list[ObjectAddress], Decoder]:
    """A fast decoder for one PDO: one ``struct`` call when every entry is byte aligned.

    Falls back to the general bit-level :func:`servodesk.domain.pdo.unpack` otherwise.
    """
    slots = [s for s in pdomod.layout(profile, pdo) if s.address is not None]
    addresses = [s.address for s in slots if s.address is not None]
    order = ">" if profile.pdo.byte_order == "big" else "<"
    fmt = [order]
    pos = 0
    aligned = True
    for s in pdomod.layout(profile, pdo):
        ch = _STRUCT.get(s.data_type) if s.data_type is not None else None
        if s.offset_bits % 8 or s.bits % 8:
            aligned = False
            break
        gap = s.offset_bits // 8 - pos
        if gap:
            fmt.append(f"{gap}x")
        if s.address is None:
            fmt.append(f"{s.bits // 8}x")
        elif ch is None or struct.calcsize(ch) * 8 != s.bits:
            aligned = False
            break
        else:
            fmt.append(ch)
        pos = (s.offset_bits + s.bits) // 8
    if aligned:
        st = struct.Struct("".join(fmt))
        size = st.size

        def fast(data: bytes) -> tuple[Value, ...]:
            return st.unpack_from(data) if len(data) >= size else _short(len(data), size)

        return addresses, fast

    def general(data: bytes) -> tuple[Value, ...]:
        values = pdomod.unpack(profile, pdo, data)
        return tuple(values[a] for a in addresses)

    return addresses, general


def _short(got: int, want: int) -> tuple[Value, ...]:
    raise ValueError(f"frame of {got} bytes is shorter than the mapping ({want} bytes)")


@dataclass(eq=False)
class Channel:
    """One PDO on the bus as seen by the master."""

    pdo: pdomod.Pdo
    name: str
    cob_id: int
    addresses: list[ObjectAddress]
    decode: Decoder | None = None
    count: int = 0
    errors: int = 0
    last_time: float = 0.0
    values: tuple[Value, ...] = ()
    #: RX: the frame the thread sends (rebuilt when an output changes).
    frame: bytes = b""
    image: dict[ObjectAddress, Value] = field(default_factory=dict)
    #: Rate bookkeeping for the status (count and time at the previous rate sample).
    rate_count: int = 0
    rate_time: float = 0.0
    rate_hz: float = 0.0


def bus_cob_id(profile: DeviceProfile, pdo: pdomod.Pdo, node_id: int) -> int:
    """The identifier a PDO travels on (docs/pdo.md): its COB-ID, or 180h/200h + node."""
    if pdo.comm is not None:
        return pdo.comm.cob_id
    base = 0x200 if pdo.direction == pdomod.Direction.RX else 0x180
    return base + node_id


class CyclicExchange:
    """TPDO consumer, RPDO producer and SYNC producer of one session."""

    def __init__(
        self,
        session: Session,
        transport: CyclicTransport,
        config: pdomod.PdoConfig,
        *,
        period: float,
        outputs: bool,
        image: dict[ObjectAddress, Value] | None = None,
    ) -> None:
        self.session = session
        self.profile = session.profile
        self.transport = transport
        self.config = config
        self.period = period
        self.outputs = outputs
        #: How the drive synchronises to the exchange: "freerun" or "dc" (EtherCAT SYNC0).
        self.sync = "freerun"
        self.started_at = 0.0
        self._producer: SyncProducer | None = None
        self._sync0 = 0
        self._syncs_at_stop = 0
        #: The NMT state before cyclic data started (restored by a user's stop).
        self.nmt_before = "unknown"
        #: Replaced, never changed in place (add_listener, remove_listener): the bus thread
        #: iterates it while the event loop adds or removes the scope's listener.
        self.listeners: list[SampleListener] = []
        self._lock = threading.Lock()
        self._publisher: asyncio.Task[None] | None = None
        node = session.link.params.node_id
        self.tx: list[Channel] = []
        self.rx: list[Channel] = []
        for p in config.active(pdomod.Direction.TX):
            addresses, decode = compile_decoder(self.profile, p)
            self.tx.append(Channel(p, p.name, bus_cob_id(self.profile, p, node), addresses, decode))
        for p in config.active(pdomod.Direction.RX):
            slots = [s.address for s in pdomod.layout(self.profile, p) if s.address is not None]
            ch = Channel(p, p.name, bus_cob_id(self.profile, p, node), slots)
            ch.image = {a: (image or {}).get(a, 0) for a in slots}
            ch.frame = pdomod.pack(self.profile, p, ch.image)
            self.rx.append(ch)
        self._callbacks: list[tuple[int, Callable[[bytes, float], None]]] = []
        self.rtr = self.rtr_requests()

    # Lifecycle ----------------------------------------------------------------------------

    @property
    def running(self) -> bool:
        return self._producer is not None and self._producer.running

    @property
    def syncs(self) -> int:
        """SYNCs sent on the bus since this exchange started."""
        p = self._producer
        return p.syncs - self._sync0 if p is not None else self._syncs_at_stop

    def start(self) -> None:
        for ch in self.tx:
            cb = self._receiver(ch)
            self.transport.subscribe(ch.cob_id, cb)
            self._callbacks.append((ch.cob_id, cb))
        self.started_at = time.monotonic()
        producer = SyncProducer.attach(self)
        self._sync0 = producer.syncs
        self._producer = producer
        with contextlib.suppress(RuntimeError):
            self._publisher = asyncio.get_running_loop().create_task(
                self._publish_loop(), name=f"pdo publish {self.session.id}"
            )

    def stop(self) -> None:
        producer, self._producer = self._producer, None
        if producer is not None:
            self._syncs_at_stop = producer.syncs - self._sync0
            producer.detach(self)
        for ident, cb in self._callbacks:
            with contextlib.suppress(Exception):
                self.transport.unsubscribe(ident, cb)
        self._callbacks.clear()
        if self._publisher is not None:
            self._publisher.cancel()
            self._publisher = None

    def rtr_requests(self) -> list[tuple[int, int]]:
        """RTR-only TPDOs (CiA 301 types 252/253) come only when asked for: (COB-ID, bytes)."""
        return [
            (ch.cob_id, ch.pdo.bytes)
            for ch in self.tx
            if ch.pdo.comm is not None
            and ch.pdo.comm.transmission_type in (252, 253)
            and ch.pdo.comm.rtr_allowed
        ]

    def add_listener(self, listener: SampleListener) -> None:
        with self._lock:
            self.listeners = [*self.listeners, listener]

    def remove_listener(self, listener: SampleListener) -> None:
        with self._lock:
            self.listeners = [x for x in self.listeners if x is not listener]

    # Bus thread ---------------------------------------------------------------------------

    def _receiver(self, ch: Channel) -> Callable[[bytes, float], None]:
        decode = ch.decode
        assert decode is not None
        addresses = ch.addresses

        def on_frame(data: bytes, timestamp: float) -> None:
            try:
                values = decode(data)
            except (ValueError, struct.error):
                ch.errors += 1
                return
            ch.values = values
            ch.last_time = time.monotonic()
            ch.count += 1
            for listener in self.listeners:
                listener(timestamp, addresses, values)

        return on_frame

    # Outputs ------------------------------------------------------------------------------

    def rx_addresses(self) -> set[ObjectAddress]:
        return {a for ch in self.rx for a in ch.image}

    def set_outputs(self, values: dict[ObjectAddress, Value]) -> None:
        """Put values into the output image (already checked by the caller)."""
        with self._lock:
            for ch in self.rx:
                hit = False
                for a, v in values.items():
                    if a in ch.image:
                        ch.image[a] = v
                        hit = True
                if hit:
                    ch.frame = pdomod.pack(self.profile, ch.pdo, ch.image)

    def hold_on_link_loss(self) -> None:
        """The link is lost (called by the SYNC thread once per loss): the controlword in
        the output image becomes a quick stop (CiA 402-2 §6.2.1, 0002h), so that when the
        link returns and the line is back in OP the drive is not commanded again with what
        it was told before: motion never resumes by itself. A drive whose watchdog fired
        meanwhile is in Fault and shows it; the user resets and enables it again."""
        if self.outputs and self.carries(CONTROLWORD):
            self.set_outputs({CONTROLWORD: QUICK_STOP_WORD})
            log.warning("%s: link lost, quick stop in the output image", self.session.id)

    def carries(self, address: ObjectAddress) -> bool:
        return any(address in ch.image for ch in self.rx)

    async def write_through(self, address: ObjectAddress, data: bytes) -> None:
        """Write an RX-mapped object through the output image (see Session.write_object)."""
        spec = self.profile.spec(address)
        if spec is None:
            raise ValueError(f"{address} is not in the profile")
        self.set_outputs({address: codec(spec.data_type).decode(data)})
        # Sent with the next cycle and applied at its SYNC; two cycles leave room for a
        # cycle that was already being sent when the image changed.
        target = self.syncs + 2
        deadline = time.monotonic() + max(0.5, 10 * self.period)
        while self.syncs < target and self.running and time.monotonic() < deadline:  # noqa: ASYNC110 - the counter is advanced by the SYNC thread, not by a task
            await asyncio.sleep(min(self.period, 0.005))

    # Values and status --------------------------------------------------------------------

    def latest(self) -> dict[ObjectAddress, tuple[Value, float, str]]:
        """The newest value of every received object: (value, receive time, PDO name)."""
        out: dict[ObjectAddress, tuple[Value, float, str]] = {}
        for ch in self.tx:
            if ch.values:
                for a, v in zip(ch.addresses, ch.values, strict=True):
                    out[a] = (v, ch.last_time, ch.name)
        for ch in self.rx:
            for a, v in ch.image.items():
                out.setdefault(a, (v, 0.0, ch.name))
        return out

    def _rates(self) -> None:
        now = time.monotonic()
        for ch in self.tx:
            dt = now - ch.rate_time
            if ch.rate_time and dt >= 0.2:
                ch.rate_hz = (ch.count - ch.rate_count) / dt
            if not ch.rate_time or dt >= 0.2:
                ch.rate_count, ch.rate_time = ch.count, now

    def link_health(self) -> dict[str, Any] | None:
        """The transport's view of the bus (EtherCAT: working counter errors, missing frames,
        link lost), or None where it has none."""
        return self.transport.health()

    def values_view(self, health: dict[str, Any] | None = None) -> dict[str, Any]:
        """The latest values; ``stale`` on the received ones while the transport says its
        inputs are not the drive's present values (EtherCAT: N cycles without a valid
        working counter, the link lost): the UI greys them rather than show a statusword
        it cannot see as if it were the drive's."""
        stale = bool(health and health.get("stale"))
        rx = self.rx_addresses()
        out: dict[str, Any] = {}
        for a, (v, t, name) in self.latest().items():
            spec = self.profile.spec(a)
            eng: float | None = None
            if spec is not None and spec.unit and isinstance(v, int | float) and spec.scale:
                eng = float(v) * spec.scale
            out[str(a)] = {
                "value": v,
                "engineering": eng,
                "unit": spec.unit if spec else None,
                "raw_unit": spec.raw_unit if spec else None,
                "pdo": name,
                "age_s": round(time.monotonic() - t, 4) if t else None,
                "stale": stale and a not in rx,
            }
        return out

    def idle(self, ch: Channel, now: float) -> dict[str, Any] | None:
        """Why a TPDO has sent nothing for a while and what makes it send (issue 48), or None.

        CiA 301 §7.5.2.36: a TPDO of transmission type 254/255 is event-driven; without an
        event timer (sub 5 = 0) the drive sends it only on its event (a mapped value changes),
        so an idle axis sends nothing after the first frame. The fixes are the two documented
        ways to make it periodic: a synchronous type (1: every SYNC) or an event timer.
        """
        comm = ch.pdo.comm
        if comm is None or not self.running or now - self.started_at < IDLE_AFTER_S:
            return None
        if ch.last_time and now - ch.last_time < IDLE_AFTER_S:
            return None
        if comm.transmission_type not in (254, 255) or comm.event_timer:
            return None
        index = f"{ch.pdo.comm_index:04X}h" if ch.pdo.comm_index is not None else "its comm."
        return {
            "why": (
                f"{ch.name} is event-driven (transmission type {comm.transmission_type}) with "
                f"no event timer ({index}:05 = 0): the drive sends it only when a mapped value "
                "changes (CiA 301 §7.5.2.36). The axis is idle, so nothing changes and nothing "
                "arrives."
            ),
            "fixes": [
                {
                    "label": "send it with every SYNC (transmission type 1)",
                    "transmission_type": 1,
                    "event_timer": None,
                },
                {
                    "label": f"send it every {FIX_EVENT_TIMER_MS} ms (event timer)",
                    "transmission_type": None,
                    "event_timer": FIX_EVENT_TIMER_MS,
                },
            ],
        }

    def status(self) -> dict[str, Any]:
        self._rates()
        now = time.monotonic()
        elapsed = max(1e-9, now - self.started_at) if self.started_at else 0.0
        frames = sum(ch.count for ch in self.tx)

        def chan(ch: Channel, rx: bool) -> dict[str, Any]:
            return {
                "name": ch.name,
                "cob_id": ch.cob_id,
                "cob_id_hex": f"0x{ch.cob_id:03X}",
                "count": self.syncs if rx and self.outputs else ch.count,
                "rate_hz": round(ch.rate_hz, 1) if not rx else None,
                "errors": ch.errors,
                "idle": None if rx else self.idle(ch, now),
            }

        health = self.link_health()
        return {
            "running": self.running,
            "link": health,
            "stale": bool(health and health.get("stale")),
            "sync_period_ms": round(self.period * 1000, 3),
            "sync": self.sync,
            "outputs": self.outputs,
            "syncs": self.syncs,
            "rx_pdos": [chan(c, True) for c in self.rx],
            "tx_pdos": [chan(c, False) for c in self.tx],
            "frames_per_s": round(frames / elapsed, 1) if elapsed else 0.0,
            "decode_errors": sum(c.errors for c in self.tx),
            "values": self.values_view(health),
        }

    async def _publish_loop(self) -> None:
        hub = self.session.hub
        sid = self.session.id
        while True:
            await asyncio.sleep(1.0 / PUBLISH_HZ)
            if not hub.watchers(sid):
                continue
            self._rates()
            health = self.link_health()
            hub.publish(
                {
                    "type": "pdo",
                    "session": sid,
                    "link": health,
                    "values": self.values_view(health),
                    "rates": {c.name: round(c.rate_hz, 1) for c in self.tx},
                    "time": time.time(),
                },
                session=sid,
            )


class SyncProducer:
    """The one SYNC producer of a bus (CiA 301 §7.2.5: a network has one SYNC producer).

    Every session on the bus that runs cyclic data attaches its exchange; one thread sends,
    each period, the RPDOs of every exchange with outputs on, then SYNC, then the RTR requests.
    Two sessions on one bus therefore share the SYNC instead of doubling it; a second session
    asking for another period is refused, naming the period in use.
    """

    _by_bus: ClassVar[dict[object, SyncProducer]] = {}
    _registry_lock: ClassVar[threading.Lock] = threading.Lock()

    def __init__(self, transport: CyclicTransport, period: float) -> None:
        self.transport = transport
        self.period = period
        self.exchanges: list[CyclicExchange] = []
        self.syncs = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @classmethod
    def attach(cls, ex: CyclicExchange) -> SyncProducer:
        key = ex.transport.bus_key
        with cls._registry_lock:
            p = cls._by_bus.get(key)
            if p is not None and p.exchanges and abs(p.period - ex.period) > 1e-9:
                names = ", ".join(e.session.id for e in p.exchanges)
                raise ConflictError(
                    f"the bus already has a SYNC producer at {p.period * 1000:g} ms "
                    f"(cyclic data of {names})",
                    hint=f"use sync_period_ms {p.period * 1000:g}, or stop the other first",
                )
            if p is None or not p.running:
                p = cls(ex.transport, ex.period)
                cls._by_bus[key] = p
            p.exchanges = [*p.exchanges, ex]
            if not p.running:
                p._stop.clear()
                p._thread = threading.Thread(target=p._run, name="servodesk-sync", daemon=True)
                p._thread.start()
            return p

    def detach(self, ex: CyclicExchange) -> None:
        with self._registry_lock:
            self.exchanges = [e for e in self.exchanges if e is not ex]
            if self.exchanges:
                return
            self._stop.set()
            if self._by_bus.get(ex.transport.bus_key) is self:
                del self._by_bus[ex.transport.bus_key]
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(2.0)

    def _run(self) -> None:
        period = self.period
        transport = self.transport
        next_t = time.perf_counter()
        was_lost = False
        while not self._stop.is_set():
            exchanges = self.exchanges  # Replaced (never mutated) by attach/detach.
            try:
                for ex in exchanges:
                    if ex.outputs:
                        for ch in ex.rx:
                            transport.send(ch.cob_id, ch.frame)
                transport.send_sync()
                self.syncs += 1
                lost = transport.link_state() == LINK_LOST
                if lost and not was_lost:
                    for ex in exchanges:
                        ex.hold_on_link_loss()
                was_lost = lost
                for ex in exchanges:
                    for ident, length in ex.rtr:
                        transport.send_rtr(ident, length)
            except Exception:  # The adapter went away: stop instead of spinning on errors.
                log.exception("SYNC producer stopped")
                self._stop.set()
                break
            next_t += period
            delay = next_t - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -20 * period:
                # Far behind (a stalled machine): resume the rhythm rather than burst.
                next_t = time.perf_counter()
