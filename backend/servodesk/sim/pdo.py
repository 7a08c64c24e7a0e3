"""The process data of a simulated drive: its PDOs on the bus (docs/pdo.md, "Families").

:class:`PdoEngine` is the device side of PDO communication for one
:class:`~servodesk.sim.engine.SimulatedDrive`. It reads the drive's configuration (communication
parameters 1400h+/1800h+, mapping parameters 1600h+/1A00h+, the EtherCAT assignment
1C12h/1C13h, the PROFIdrive telegram P922) and compiles every active PDO into a
:class:`struct.Struct` once per configuration change; per SYNC, received frame, RTR and control
cycle it only samples, packs, unpacks and compares. The bus front-end
(:mod:`servodesk.sim.canopen_device`) feeds it frames and NMT states and sends what it queues.

Per family (``profile.pdo.kind``):

- ``canopen`` (CiA 301 §7.2.2, §7.5.2.35-38): every PDO whose COB-ID has bit 31 clear and whose
  mapping holds at least one entry, on its own COB-ID, classic CAN, little-endian. TPDO types
  0 (at the SYNC after a mapped value changed), 1-240 (every n-th SYNC, from the SYNC whose
  counter equals the SYNC start value when both are used), 252 (sampled at SYNC, sent on RTR),
  253 (sampled and sent on RTR), 254/255 (on change, at most once per inhibit time, at least
  once per event timer); every TPDO answers an RTR unless COB-ID bit 30 is set. RPDO types 0-240
  apply the data at the next SYNC, 254/255 at once; an RPDO event timer is the reception
  deadline (EMCY 8250h). A frame shorter than the mapping is dropped with EMCY 8210h; a longer
  one is processed (CiA 301 §7.2.2.2) and, with the quirk ``rpdo_dlc_mismatch_emcy``, answered
  with that EMCY (smartris 001 §10-3: 8220h).
- ``ethercat`` (HIWIN 000 §2.8): the RxPDO assigned in 1C12h on 200h+node and the TxPDO assigned
  in 1C13h on 180h+node, one CAN FD frame each, the TxPDO at every SYNC (the EtherCAT cycle).
- ``fixed`` (CTMM04x 003 §4-1): 1600h on 200h+node, 1A00h on 180h+node, CAN FD, every SYNC.
- ``telegram`` (LECSN-T 004 §20.1.2): the setpoint telegram (1600h) on 200h+node and the
  actual-value telegram (1A00h) on 180h+node, CAN FD, every SYNC, big-endian; Reserved entries
  (index 0) are zero padding. A fixed telegram (1, 100: ``variable: false`` in the profile's
  ``pdo.telegrams``) uses the profile's layout instead of 1600h/1A00h; its words that are no
  object (STW1, ZSW1) are sent as zeros and ignored when received, and words narrower than
  their object (NSOLL_A) carry the object's raw value truncated to the word.

Received CAN FD process data (``ethercat``, ``fixed``, ``telegram``) is applied when it
arrives. PDOs are exchanged only in NMT OPERATIONAL (CiA 301 §7.3.2.2.1 table 35).

Choices where the manuals leave room:

- An event-driven TPDO is sent once on entering OPERATIONAL (its first "change").
- The event timer restarts with every transmission of the TPDO (smartris 001 §2-8: "the timer
  is reset" by an internal event). With the quirk ``tpdo_event_source`` (smartris: 6041h) only
  a change of that object is an event, and while the event timer is set only the timer sends
  (001 §2-8 note: "internal events are disabled").
- Type 252 follows CiA 301 and smartris' first description (001 §2-8 fig. 2-10: the SYNC
  samples, the RTR sends); the TPDO table in the same section says the opposite.
- A received value the drive refuses (out of range, a 402-state rule) is dropped silently: a
  PDO has no answer.
- The PDO EMCYs carry error register 11h (generic + communication, as smartris 001 §10-3 shows).

Over 700 lines: the PDO layouts of the four families (CANopen, EtherCAT assignment, PROFIdrive
telegram) compile to one :class:`Layout` that the engine samples per SYNC; the family rules are
the compile step's branches.
"""

from __future__ import annotations

import logging
import math
import operator
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value
from servodesk.domain.profile import DeviceProfile, PdoWord
from servodesk.errors import ServodeskError

if TYPE_CHECKING:
    from servodesk.sim.engine import SimulatedDrive

log = logging.getLogger(__name__)

#: ``send(can_id, data, fd, extended)``: put one frame on the bus.
SendFn = Callable[[int, bytes, bool, bool], None]
#: ``emcy(code)``: send an EMCY with this error code.
EmcyFn = Callable[[int], None]
#: A received frame's data (python-can hands a bytearray).
_Data = bytes | bytearray

EMCY_PDO_LENGTH = 0x8210  # CiA 301 table 26: PDO not processed due to length error.
EMCY_RPDO_TIMEOUT = 0x8250  # CiA 301 table 26: RPDO timeout.

SYNC_COB_ID = 0x080
_FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
_EPS = 1e-9

#: PROFIdrive P922 "telegram selection" (004 §20.4.3.1) when the profile does not name it.
_P922 = "0x039A:00"


def pdo_kind(profile: DeviceProfile) -> str:
    """The family's PDO procedure: ``profile.pdo.kind``, or inferred when the profile does
    not set it (EtherCAT fieldbus, a fixed mapping, PROFINET telegrams)."""
    rules = profile.pdo
    if "kind" in rules.model_fields_set:
        return str(rules.kind)
    if rules.mapping_state == "fixed":
        return "fixed"
    if profile.fieldbus == "ethercat":
        return "ethercat"
    if profile.fieldbus == "profinet":
        return "telegram"
    return str(rules.kind)


def _big_endian(profile: DeviceProfile, kind: str) -> bool:
    rules = profile.pdo
    if "byte_order" in rules.model_fields_set:
        return rules.byte_order == "big"
    # 004 §20.1.2 "byte order big endian" (quirk byte_order in the LECSN profile).
    return kind == "telegram" or profile.quirk("byte_order") == "big_endian"


def fd_length(n: int) -> int:
    """The CAN FD frame length that holds ``n`` bytes (0-8, 12, 16, 20, 24, 32, 48, 64)."""
    for length in _FD_LENGTHS:
        if length >= n:
            return length
    raise ValueError(f"{n} bytes do not fit one CAN FD frame (64 bytes)")


# ---------------------------------------------------------------------------- layouts

_INT_FORMATS = {1: "B", 2: "H", 4: "I", 8: "Q"}


@dataclass(frozen=True, slots=True)
class _Field:
    """One mapped entry: ``key`` (index << 8 | subindex) or -1 for padding."""

    key: int
    nbytes: int
    signed: bool
    real: bool


class Layout:
    """A compiled mapping: which objects at which bytes, packed with one struct call.

    ``size`` is the mapped length in bytes, ``frame`` the length on the bus (CAN FD padding
    or a telegram's fixed size included).
    """

    __slots__ = (
        "_fields",
        "_masks",
        "_order",
        "_pack",
        "_slow",
        "_unpack",
        "frame",
        "keys",
        "size",
    )

    def __init__(self, fields: Sequence[_Field], big_endian: bool, frame: int) -> None:
        self._fields = tuple(fields)
        self.keys = tuple(f.key for f in fields if f.key >= 0)
        self.size = sum(f.nbytes for f in fields)
        self.frame = max(frame, self.size)
        order = ">" if big_endian else "<"
        self._slow = any(f.nbytes not in _INT_FORMATS for f in fields if f.key >= 0)
        tx, rx = [order], [order]
        masks: list[int] = []
        for f in fields:
            if f.key < 0:
                tx.append(f"{f.nbytes}x")
                rx.append(f"{f.nbytes}x")
                continue
            if f.real:
                code = "f" if f.nbytes == 4 else "d"
                tx.append(code)
                rx.append(code)
                masks.append(0)
                continue
            code = _INT_FORMATS.get(f.nbytes, "")
            tx.append(code)
            rx.append(code.lower() if f.signed else code)
            masks.append((1 << (8 * f.nbytes)) - 1)
        pad = self.frame - self.size
        if pad:
            tx.append(f"{pad}x")
        self._masks = tuple(masks)
        self._pack = struct.Struct("".join(tx)).pack if not self._slow else None
        self._unpack = struct.Struct("".join(rx)).unpack_from if not self._slow else None
        self._order: str = "big" if big_endian else "little"

    def pack(self, values: Sequence[Value | None]) -> bytes:
        """The frame for ``values`` (in ``keys`` order); None and text count as 0."""
        pack = self._pack
        if pack is not None:
            try:
                return pack(*[v & m if m else v for v, m in zip(values, self._masks, strict=True)])  # type: ignore[operator]
            except (TypeError, struct.error):
                pass
        return self._pack_slow(values)

    def _pack_slow(self, values: Sequence[Value | None]) -> bytes:
        out = bytearray()
        it = iter(values)
        for f in self._fields:
            if f.key < 0:
                out += bytes(f.nbytes)
                continue
            v = next(it)
            if f.real:
                fmt = (">" if self._order == "big" else "<") + ("f" if f.nbytes == 4 else "d")
                out += struct.pack(fmt, float(v) if isinstance(v, int | float) else 0.0)
                continue
            n = _as_int(v) & ((1 << (8 * f.nbytes)) - 1)
            out += n.to_bytes(f.nbytes, self._order)  # type: ignore[arg-type]
        out += bytes(self.frame - self.size)
        return bytes(out)

    def unpack(self, data: bytes | bytearray) -> list[tuple[int, Value]]:
        """``(key, value)`` of every mapped object in ``data`` (at least ``size`` bytes)."""
        unpack = self._unpack
        if unpack is not None:
            return list(zip(self.keys, unpack(data), strict=True))
        out: list[tuple[int, Value]] = []
        pos = 0
        for f in self._fields:
            chunk = data[pos : pos + f.nbytes]
            pos += f.nbytes
            if f.key < 0:
                continue
            if f.real:
                fmt = (">" if self._order == "big" else "<") + ("f" if f.nbytes == 4 else "d")
                out.append((f.key, struct.unpack(fmt, chunk)[0]))
            else:
                out.append((f.key, int.from_bytes(chunk, self._order, signed=f.signed)))  # type: ignore[arg-type]
        return out


def _group(tpdos: Sequence[_Tpdo]) -> tuple[int, ...]:
    """The keys one sample must read for ``tpdos``; sets each PDO's ``pick``/``event_pos``."""
    keys: list[int] = []
    pos: dict[int, int] = {}

    def at(k: int) -> int:
        if k not in pos:
            pos[k] = len(keys)
            keys.append(k)
        return pos[k]

    for t in tpdos:
        idx = [at(k) for k in t.layout.keys]
        t.event_pos = at(t.event_key) if t.event_key is not None else -1
        t.pick = _picker(idx)
    return tuple(keys)


def _picker(idx: Sequence[int]) -> Callable[[Sequence[Value | None]], tuple[Value | None, ...]]:
    """``values -> tuple(values[i] for i in idx)``, as fast as Python does it."""
    if not idx:
        return _none
    if len(idx) == 1:
        i = idx[0]

        def one(v: Sequence[Value | None]) -> tuple[Value | None, ...]:
            return (v[i],)

        return one
    getter: Callable[[Sequence[Value | None]], tuple[Value | None, ...]]
    getter = operator.itemgetter(*idx)
    return getter


def _none(v: Sequence[Value | None]) -> tuple[Value | None, ...]:
    return ()


def _as_int(v: Value | None) -> int:
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, int):
        return v
    if isinstance(v, float) and math.isfinite(v):
        return round(v)
    return 0


# ---------------------------------------------------------------------------- PDO state


@dataclass(slots=True, eq=False)
class _Tpdo:
    name: str
    can_id: int
    extended: bool
    fd: bool
    rtr: bool
    ttype: int
    inhibit: float  # s
    event: float  # s
    sync_start: int
    layout: Layout
    #: Quirk tpdo_event_source: only this object's change is an event (None: any mapped value).
    event_key: int | None
    #: This PDO's values (and its event object's) out of its group's shared sample.
    pick: Callable[[Sequence[Value | None]], tuple[Value | None, ...]] = tuple
    event_pos: int = -1
    # Runtime, reset on configuration and on entering OPERATIONAL.
    count: int = 0
    waiting: bool = False
    last: tuple[Value | None, ...] | None = None
    last_time: float = -math.inf
    due: float = math.inf
    held: bytes | None = None
    last_event: Value | None = None


@dataclass(slots=True, eq=False)
class _Rpdo:
    name: str
    can_id: int
    synchronous: bool
    timeout: float  # s, 0: no deadline monitoring
    layout: Layout
    #: Quirk rpdo_dlc_mismatch_emcy: a longer frame is answered with that EMCY too.
    exact: bool
    pending: bytes | None = None
    last_rx: float | None = None
    timed_out: bool = False


class PdoEngine:
    """The PDOs of one simulated drive (see the module docstring for the behaviour)."""

    def __init__(self, drive: SimulatedDrive, send: SendFn, emcy: EmcyFn) -> None:
        self._drive = drive
        self._send = send
        self._emcy = emcy
        profile = drive.profile
        self.kind = pdo_kind(profile)
        self._big = _big_endian(profile, self.kind)
        self._fd = self.kind != "canopen"
        q = profile.quirk("tpdo_event_source")
        self._event_key: int | None = None
        if q:
            a = ObjectAddress.parse(str(q))
            self._event_key = a.index << 8 | a.subindex
        q = profile.quirk("rpdo_dlc_mismatch_emcy")
        self._too_long_emcy = int(q, 0) if isinstance(q, str) else (q if isinstance(q, int) else 0)
        self._operational = False
        self.sync_id = SYNC_COB_ID
        tel = ObjectAddress.parse(profile.pdo.telegram_object or _P922)
        self._telegram = (tel.index, tel.subindex)
        #: Besides 1400h-1BFFh, the objects whose writes change the configuration.
        self._config_indexes = frozenset((0x1005, 0x1C12, 0x1C13, tel.index))
        self._tpdos: list[_Tpdo] = []
        self._sync_tpdos: list[_Tpdo] = []
        self._event_tpdos: list[_Tpdo] = []
        self._rpdos: list[_Rpdo] = []
        self._sync_rpdos: list[_Rpdo] = []
        self._sync_keys: tuple[int, ...] = ()
        self._cycle_keys: tuple[int, ...] = ()
        self._timed_rpdos: list[_Rpdo] = []
        #: Frame handlers by CAN id; replaced as a whole on reconfiguration (read lock-free).
        self._handlers: dict[int, Callable[[_Data, bool], None]] = {}
        self._cyclic = False
        self._out: list[tuple[int, bytes, bool, bool]] = []
        self._emcys: list[int] = []
        #: Counters for diagnostics and tests: frames sent / received, per CAN id.
        self.sent: dict[int, int] = {}
        self.received: dict[int, int] = {}
        self.configure()
        drive.on_cycle(self._on_cycle)
        drive.on_step(self.flush)

    # ------------------------------------------------------------------ configuration

    @property
    def operational(self) -> bool:
        return self._operational

    @property
    def tpdo_names(self) -> list[str]:
        """Names and CAN ids of the active TPDOs, for logs and tests."""
        return [f"{t.name}@{t.can_id:03X}" for t in self._tpdos]

    @property
    def rpdo_names(self) -> list[str]:
        return [f"{r.name}@{r.can_id:03X}" for r in self._rpdos]

    def frame_bytes(self, direction: str) -> int:
        """Bytes on the bus of the active RxPDOs ("rx") or TxPDOs ("tx"): a telegram's
        fixed size (PROFINET's IO data lengths, sim/profinet_io.py)."""
        items: Sequence[_Tpdo | _Rpdo] = self._rpdos if direction == "rx" else self._tpdos
        return sum(x.layout.frame for x in items)

    def configure(self) -> None:
        """Rebuild the active PDOs from the drive's objects (after a write or a reset)."""
        with self._drive.lock:
            try:
                tpdos, rpdos = self._build()
            except (ServodeskError, ValueError) as exc:
                # A configuration the drive accepted but that cannot be compiled (e.g. a
                # telegram longer than one CAN FD frame): no process data rather than a crash.
                log.warning("node %d: process data disabled: %s", self._drive.node_id, exc)
                tpdos, rpdos = [], []
            self._tpdos = tpdos
            self._rpdos = rpdos
            self._sync_tpdos = [t for t in tpdos if t.ttype <= 240 or t.ttype == 252]
            self._event_tpdos = [t for t in tpdos if t.ttype >= 254]
            # One sample per SYNC / control cycle serves every PDO of the group.
            self._sync_keys = _group(self._sync_tpdos)
            self._cycle_keys = _group(self._event_tpdos)
            self._sync_rpdos = [r for r in rpdos if r.synchronous]
            self._timed_rpdos = [r for r in rpdos if r.timeout > 0]
            handlers: dict[int, Callable[[_Data, bool], None]] = {}
            handlers[self.sync_id] = self._on_sync_frame
            for r in rpdos:
                handlers[r.can_id] = self._rpdo_handler(r)
            for t in tpdos:
                if t.rtr and t.can_id not in handlers:
                    handlers[t.can_id] = self._rtr_handler(t)
            self._handlers = handlers
            self._reset_runtime()
        log.debug(
            "node %d PDOs (%s): tx %s rx %s",
            self._drive.node_id,
            self.kind,
            self.tpdo_names,
            self.rpdo_names,
        )

    def on_object_written(self, index: int) -> None:
        """The drive accepted a write of ``index``: reconfigure when it is a PDO object."""
        if 0x1400 <= index <= 0x1BFF or index in self._config_indexes:
            self.configure()

    def set_operational(self, operational: bool) -> None:
        """NMT state change: PDOs are exchanged in OPERATIONAL only (CiA 301 §7.3.2.2.1)."""
        with self._drive.lock:
            if operational == self._operational:
                return
            self._operational = operational
            self._reset_runtime()

    def _reset_runtime(self) -> None:
        now = self._drive.time
        for t in self._tpdos:
            t.count = 0
            t.waiting = t.sync_start > 0 and 1 <= t.ttype <= 240
            t.last = None
            t.last_time = -math.inf
            t.due = now + t.event if t.event else math.inf
            t.held = None
            t.last_event = None
        for r in self._rpdos:
            r.pending = None
            r.last_rx = None
            r.timed_out = False
        self._cyclic = self._operational and bool(self._event_tpdos or self._timed_rpdos)

    def _build(self) -> tuple[list[_Tpdo], list[_Rpdo]]:
        d = self._drive
        node = d.node_id
        cob = self._get(0x1005, 0, SYNC_COB_ID) if d.has_object(0x1005) else SYNC_COB_ID
        self.sync_id = cob & 0x7FF
        if self.kind == "canopen":
            return self._build_canopen()
        rx_map: int | None = 0x1600
        tx_map: int | None = 0x1A00
        rx_words: Sequence[PdoWord] | None = None
        tx_words: Sequence[PdoWord] | None = None
        frame_min = 0
        if self.kind == "ethercat":
            rx_map = self._assigned(0x1C12)
            tx_map = self._assigned(0x1C13)
        elif self.kind == "telegram":
            number = self._get(*self._telegram, 0)
            tel = d.profile.pdo.telegram(number) if number else None
            if tel is not None:
                frame_min = tel.bytes
                if not tel.variable or not d.has_object(0x1600):
                    rx_words, tx_words = tel.rx, tel.tx
        tpdos: list[_Tpdo] = []
        rpdos: list[_Rpdo] = []
        rx = self._layout_words(rx_words, frame_min) if rx_words is not None else None
        if rx is None and rx_map is not None:
            rx = self._layout_mapping(rx_map, frame_min)
        if rx is not None and rx.keys:
            rpdos.append(
                _Rpdo(
                    name=self._name("rx", rx_map),
                    can_id=0x200 + node,
                    synchronous=False,
                    timeout=0.0,
                    layout=rx,
                    exact=False,
                )
            )
        tx = self._layout_words(tx_words, frame_min) if tx_words is not None else None
        if tx is None and tx_map is not None:
            tx = self._layout_mapping(tx_map, frame_min)
        if tx is not None and tx.size:
            # Sent at every SYNC (the EtherCAT cycle / the PROFINET send clock).
            tpdos.append(
                _Tpdo(
                    name=self._name("tx", tx_map),
                    can_id=0x180 + node,
                    extended=False,
                    fd=True,
                    rtr=False,
                    ttype=1,
                    inhibit=0.0,
                    event=0.0,
                    sync_start=0,
                    layout=tx,
                    event_key=None,
                )
            )
        return tpdos, rpdos

    def _name(self, direction: str, mapping: int | None) -> str:
        if self.kind == "telegram":
            return "setpoint telegram" if direction == "rx" else "actual-value telegram"
        prefix = "RxPDO" if direction == "rx" else "TxPDO"
        return f"{prefix} {mapping or 0:04X}h"

    def _build_canopen(self) -> tuple[list[_Tpdo], list[_Rpdo]]:
        d = self._drive
        tpdos: list[_Tpdo] = []
        rpdos: list[_Rpdo] = []
        for n in range(512):
            comm = 0x1400 + n
            if not d.has_object(comm, 1) or not d.has_object(0x1600 + n):
                continue
            cob = self._get(comm, 1, 0x80000000)
            if cob & 0x80000000:
                continue
            layout = self._layout_mapping(0x1600 + n, 0)
            if layout is None or not layout.keys:
                continue
            ttype = self._get(comm, 2, 255)
            if 241 <= ttype <= 253:
                continue  # Reserved for RPDOs (CiA 301 §7.5.2.35 table 72).
            timer = self._get(comm, 5, 0) if d.has_object(comm, 5) else 0
            rpdos.append(
                _Rpdo(
                    name=f"RPDO{n + 1}",
                    can_id=cob & (0x1FFFFFFF if cob & 0x20000000 else 0x7FF),
                    synchronous=ttype <= 240,
                    timeout=timer / 1000.0,
                    layout=layout,
                    exact=self._too_long_emcy != 0,
                )
            )
        for n in range(512):
            comm = 0x1800 + n
            if not d.has_object(comm, 1) or not d.has_object(0x1A00 + n):
                continue
            cob = self._get(comm, 1, 0x80000000)
            if cob & 0x80000000:
                continue
            layout = self._layout_mapping(0x1A00 + n, 0)
            if layout is None or not layout.size:
                continue
            ttype = self._get(comm, 2, 255)
            if 241 <= ttype <= 251:
                continue  # Reserved (CiA 301 §7.5.2.37 table 73).
            event = ttype >= 254
            inhibit = self._get(comm, 3, 0) if event and d.has_object(comm, 3) else 0
            timer = self._get(comm, 5, 0) if event and d.has_object(comm, 5) else 0
            start = self._get(comm, 6, 0) if d.has_object(comm, 6) else 0
            tpdos.append(
                _Tpdo(
                    name=f"TPDO{n + 1}",
                    can_id=cob & (0x1FFFFFFF if cob & 0x20000000 else 0x7FF),
                    extended=bool(cob & 0x20000000),
                    fd=False,
                    rtr=not cob & 0x40000000,
                    ttype=ttype,
                    inhibit=inhibit * 1e-4,  # 100 µs units.
                    event=timer / 1000.0,
                    sync_start=start,
                    layout=layout,
                    event_key=self._event_key,
                )
            )
        return tpdos, rpdos

    def _get(self, index: int, subindex: int, default: int) -> int:
        try:
            v = self._drive.read(index, subindex)
        except Exception:  # Absent or unreadable: the caller's default.
            return default
        return v if isinstance(v, int) else default

    def _assigned(self, index: int) -> int | None:
        """The mapping object assigned to a sync manager (1C12h/1C13h), None when none is."""
        if not self._drive.has_object(index) or self._get(index, 0, 0) < 1:
            return None
        mapping = self._get(index, 1, 0)
        return mapping if self._drive.has_object(mapping) else None

    def _layout_mapping(self, index: int, frame_min: int) -> Layout | None:
        d = self._drive
        count = self._get(index, 0, 0)
        fields: list[_Field] = []
        for s in range(1, count + 1):
            raw = self._get(index, s, 0)
            f = self._field(raw >> 16, raw >> 8 & 0xFF, raw & 0xFF)
            if f is None:
                log.debug("node %d: 0x%04X:%02X = 0x%08X not usable", d.node_id, index, s, raw)
                return None
            fields.append(f)
        return self._make_layout(fields, frame_min)

    def _layout_words(self, words: Sequence[PdoWord], frame_min: int) -> Layout | None:
        fields: list[_Field] = []
        for w in words:
            text = (w.address or "").strip().lower()
            if not text or text.startswith("reserved"):
                bits = w.bits
                if bits is None and text.startswith("reserved:"):
                    bits = int(text.partition(":")[2])
                fields.append(_Field(-1, (bits or 0) // 8, False, False))
                continue
            a = ObjectAddress.parse(text)
            dt = w.data_type
            f = self._field(a.index, a.subindex, w.bits or (dt.bits if dt else None), dt)
            if f is None:
                return None
            fields.append(f)
        return self._make_layout(fields, frame_min)

    def _field(
        self, index: int, subindex: int, bits: int | None, dt: DataType | None = None
    ) -> _Field | None:
        """One entry; ``bits``/``dt`` other than the object's only for telegram words."""
        if index == 0 or (self.kind == "canopen" and 0x0002 <= index <= 0x0007):
            # Padding: a Reserved entry (004 §20.1.2) or a CiA 301 dummy entry.
            n = bits or 0
            return _Field(-1, n // 8, False, False) if n % 8 == 0 else None
        try:
            spec = self._drive.spec(index, subindex)
        except Exception:  # SimAbort: no such object.
            return None
        typ = dt or spec.data_type
        n = bits if bits is not None else typ.bits
        if not n or n % 8 or (dt is None and typ.bits != n):
            return None
        return _Field(index << 8 | subindex, n // 8, typ.is_signed, typ.is_real)

    def _make_layout(self, fields: Sequence[_Field], frame_min: int) -> Layout:
        size = sum(f.nbytes for f in fields)
        if self._fd:
            frame = fd_length(max(size, frame_min))
        else:
            if size > 8:
                raise ValueError(f"a PDO of {size} bytes does not fit a classic CAN frame")
            frame = size
        return Layout(fields, self._big, frame)

    # ------------------------------------------------------------------ bus events

    def on_frame(self, can_id: int, data: _Data, remote: bool) -> None:
        """A frame from the bus (any id; unknown ids cost one dict lookup)."""
        handler = self._handlers.get(can_id)
        if handler is None or not self._operational:
            return
        handler(data, remote)
        self.flush()

    def _on_sync_frame(self, data: _Data, remote: bool) -> None:
        if remote:
            return
        self.on_sync(data[0] if data else None)

    def on_sync(self, counter: int | None = None) -> None:
        """SYNC (CiA 301 §7.2.5): apply synchronous RPDOs, then sample and send TPDOs."""
        d = self._drive
        with d.lock:
            if not self._operational:
                return
            now = d.time
            for r in self._sync_rpdos:
                data = r.pending
                if data is not None:
                    r.pending = None
                    d.write_process(r.layout.unpack(data))
            if not self._sync_tpdos:
                return
            vals = d.sample(self._sync_keys)
            for t in self._sync_tpdos:
                tt = t.ttype
                tv = t.pick(vals)
                if tt == 252:
                    t.held = t.layout.pack(tv)
                    continue
                if tt == 0:
                    # Acyclic synchronous: sent at the SYNC after an event (a changed value, or
                    # with the quirk tpdo_event_source a change of that object).
                    if t.last is not None:
                        if t.event_pos >= 0:
                            if vals[t.event_pos] == t.last_event:
                                continue
                        elif tv == t.last:
                            continue
                    self._emit(t, tv, now, vals)
                    continue
                if t.waiting:
                    # CiA 301 §7.5.2.37 sub 6: the SYNC whose counter equals the start value
                    # counts as the first one; without a counter the start value is unused.
                    if counter is not None and counter != t.sync_start:
                        continue
                    t.waiting = False
                    if counter is not None:
                        t.count = 0
                        self._emit(t, tv, now, vals)
                        continue
                t.count += 1
                if t.count >= tt:
                    t.count = 0
                    self._emit(t, tv, now, vals)

    def _rpdo_handler(self, r: _Rpdo) -> Callable[[_Data, bool], None]:
        def handle(data: _Data, remote: bool) -> None:
            if remote:
                return
            self._on_rpdo(r, data)

        return handle

    def _rtr_handler(self, t: _Tpdo) -> Callable[[_Data, bool], None]:
        def handle(data: _Data, remote: bool) -> None:
            if remote:
                self._on_rtr(t)

        return handle

    def _on_rpdo(self, r: _Rpdo, data: _Data) -> None:
        d = self._drive
        size = r.layout.size
        n = len(data)
        self.received[r.can_id] = self.received.get(r.can_id, 0) + 1
        with d.lock:
            if n < size:
                self._emcys.append(EMCY_PDO_LENGTH)
                return
            if n > size and r.exact:
                self._emcys.append(self._too_long_emcy)
            r.last_rx = d.time
            r.timed_out = False
            if r.synchronous:
                r.pending = bytes(data[:size])
                return
        d.write_process(r.layout.unpack(data))

    def _on_rtr(self, t: _Tpdo) -> None:
        d = self._drive
        with d.lock:
            if t.ttype == 252 and t.held is not None:
                self._out.append((t.can_id, t.held, t.fd, t.extended))
                return
            keys = t.layout.keys if t.event_key is None else (*t.layout.keys, t.event_key)
            vals = d.sample(keys)
            tv = tuple(vals[: len(t.layout.keys)])
            self._emit(t, tv, d.time, None, vals[-1] if t.event_key is not None else None)

    # ------------------------------------------------------------------ control cycle

    def _on_cycle(self) -> None:
        """Once per control cycle, under the drive's lock: event-driven TPDOs, RPDO deadlines."""
        if not self._cyclic:
            return
        d = self._drive
        now = d.time
        if self._event_tpdos:
            vals = d.sample(self._cycle_keys)
            for t in self._event_tpdos:
                tv = t.pick(vals)
                # Not the event timer (CiA 301 §7.5.2.37 sub 5) and not the first time:
                if now + _EPS < t.due and t.last is not None:
                    if t.event_pos >= 0:
                        # Quirk tpdo_event_source: only that object's change is an internal
                        # event, and none while the event timer sends periodically
                        # (smartris 001 §2-8 note).
                        if t.event or vals[t.event_pos] == t.last_event:
                            continue
                    elif tv == t.last:
                        continue
                if now + _EPS < t.last_time + t.inhibit:
                    continue  # Inhibit time (CiA 301 §7.5.2.37 sub 3): retried next cycle.
                self._emit(t, tv, now, vals)
        for r in self._timed_rpdos:
            if r.last_rx is not None and not r.timed_out and now > r.last_rx + r.timeout + _EPS:
                # CiA 301 §7.5.2.35 sub 5: the deadline after the last reception passed.
                r.timed_out = True
                self._emcys.append(EMCY_RPDO_TIMEOUT)

    def _emit(
        self,
        t: _Tpdo,
        tv: tuple[Value | None, ...],
        now: float,
        group: Sequence[Value | None] | None,
        event_value: Value | None = None,
    ) -> None:
        self._out.append((t.can_id, t.layout.pack(tv), t.fd, t.extended))
        t.last = tv
        t.last_time = now
        if t.event:
            t.due = now + t.event
        if t.event_key is not None:
            t.last_event = group[t.event_pos] if group is not None else event_value

    def flush(self) -> None:
        """Send what the engine queued (called outside the drive's lock)."""
        if not self._out and not self._emcys:
            return
        with self._drive.lock:
            out, self._out = self._out, []
            emcys, self._emcys = self._emcys, []
        sent = self.sent
        for can_id, data, fd, extended in out:
            self._send(can_id, data, fd, extended)
            sent[can_id] = sent.get(can_id, 0) + 1
        for code in emcys:
            self._emcy(code)
