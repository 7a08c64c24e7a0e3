"""The simulated drive's process data, seen from a plain python-canopen master.

The drive is stepped by the test (no runner thread), so event timers and inhibit times run
on simulated time and frame counts are exact. Frames are read from a spy bus on the same
virtual channel; an SDO upload after a SYNC or an RPDO is the barrier that proves the device
has processed it (one notifier thread handles the device's frames in order).
"""

from __future__ import annotations

import struct
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import can
import canopen
import pytest

from servodesk.domain import pdo as dpdo
from servodesk.domain.cia402 import State
from servodesk.domain.profile import DeviceProfile, Quirk
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.canopen_device import SimCanopenDevice
from servodesk.sim.engine import SimulatedDrive

NODE = 5
_CATALOG = ProfileCatalog()


@dataclass
class Twin:
    drive: SimulatedDrive
    device: SimCanopenDevice
    dnet: Any
    net: Any
    node: Any
    spy: can.BusABC
    seen: list[can.Message] = field(default_factory=list)

    def u(self, index: int, sub: int = 0, signed: bool = False) -> int:
        return int.from_bytes(self.node.sdo.upload(index, sub), "little", signed=signed)

    def w(self, index: int, sub: int, value: int, size: int) -> None:
        self.node.sdo.download(index, sub, value.to_bytes(size, "little", signed=value < 0))

    def abort(self, index: int, sub: int, value: int, size: int) -> int:
        with pytest.raises(canopen.SdoAbortedError) as exc:
            self.w(index, sub, value, size)
        return int(exc.value.code)

    def barrier(self) -> None:
        """Returns once the device has handled every frame sent before."""
        self.node.sdo.upload(0x6041, 0)

    def nmt(self, command: int) -> None:
        self.net.nmt.send_command(command)
        self.barrier()

    def sync(self, counter: int | None = None) -> None:
        self.net.send_message(0x80, b"" if counter is None else bytes([counter]))

    def send(self, can_id: int, data: bytes, fd: bool = False) -> None:
        msg = can.Message(arbitration_id=can_id, data=data, is_extended_id=False, is_fd=fd)
        with self.net.send_lock:
            self.net.bus.send(msg)

    def rtr(self, can_id: int) -> None:
        self.net.send_message(can_id, b"", remote=True)

    def frames(self, can_id: int) -> list[can.Message]:
        """The frames with this id the spy has seen (after a barrier); others are kept."""
        self.barrier()
        self.collect()
        out = [m for m in self.seen if m.arbitration_id == can_id and not m.is_remote_frame]
        self.seen = [m for m in self.seen if m.arbitration_id != can_id]
        return out

    def collect(self) -> list[can.Message]:
        while (m := self.spy.recv(0)) is not None:
            self.seen.append(m)
        return self.seen

    def data(self, can_id: int) -> list[bytes]:
        return [bytes(m.data) for m in self.frames(can_id)]

    def drain(self) -> None:
        self.barrier()
        self.collect()
        self.seen.clear()

    def step(self, seconds: float) -> None:
        self.drive.step(seconds)

    def emcys(self) -> list[int]:
        return [int.from_bytes(d[:2], "little") for d in self.data(0x80 + NODE)]

    def remap(self, comm: int, mapping: int, entries: list[int], **comm_subs: int) -> None:
        """CiA 301 §7.5.2.35/36: disable, count 0, entries, count, parameters, enable."""
        cob = self.u(comm, 1)
        self.w(comm, 1, cob | 0x80000000, 4)
        self.w(mapping, 0, 0, 1)
        for i, e in enumerate(entries, 1):
            self.w(mapping, i, e, 4)
        self.w(mapping, 0, len(entries), 1)
        sizes = {2: 1, 3: 2, 5: 2, 6: 1}
        for name, value in comm_subs.items():
            if name == "cob":
                continue
            sub = {"ttype": 2, "inhibit": 3, "event": 5, "start": 6}[name]
            self.w(comm, sub, value, sizes[sub])
        self.w(comm, 1, comm_subs.get("cob", cob) & 0x7FFFFFFF, 4)


@contextmanager
def _twin(profile: DeviceProfile, channel: str) -> Iterator[Twin]:
    drive = SimulatedDrive(profile, NODE)
    drive.step(drive.CONTROL_PERIOD)
    dnet = canopen.Network()
    dnet.NOTIFIER_CYCLE = 0.05
    dnet.connect(interface="virtual", channel=channel)
    device = SimCanopenDevice(drive)
    dnet.add_node(device)
    device.boot()
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    node = net.add_node(NODE)
    node.sdo.RESPONSE_TIMEOUT = 0.5
    spy = can.Bus(interface="virtual", channel=channel)
    twin = Twin(drive, device, dnet, net, node, spy)
    try:
        twin.drain()
        yield twin
    finally:
        spy.shutdown()
        net.disconnect()
        device.shutdown()
        dnet.disconnect()


@pytest.fixture
def generic(channel: str) -> Iterator[Twin]:
    with _twin(_CATALOG.get("cia402-generic"), channel) as t:
        yield t


@pytest.fixture
def smartris(channel: str) -> Iterator[Twin]:
    with _twin(_CATALOG.get("smartris"), channel) as t:
        yield t


@pytest.fixture
def hiwin(channel: str) -> Iterator[Twin]:
    with _twin(_CATALOG.get("hiwin-e"), channel) as t:
        yield t


@pytest.fixture
def ctmm(channel: str) -> Iterator[Twin]:
    with _twin(_CATALOG.get("ctmm04x"), channel) as t:
        yield t


@pytest.fixture
def lecsn(channel: str) -> Iterator[Twin]:
    with _twin(_CATALOG.get("lecsn-t"), channel) as t:
        yield t


def _values(drive: SimulatedDrive, addresses: list[tuple[int, int]]) -> list[Any]:
    return [drive.read(i, s) for i, s in addresses]


def _session_decode(twin: Twin, direction: str, data: bytes) -> dict[tuple[int, int], Any]:
    """What the session decodes from a frame (domain/pdo.py), with the config read by SDO."""
    profile = twin.drive.profile
    values = {}
    for a in dpdo.config_addresses(profile):
        try:
            values[a] = twin.drive.read(a.index, a.subindex)
        except Exception:
            continue
    config = dpdo.parse_config(profile, values)
    (pdo,) = config.active(direction)
    return {(a.index, a.subindex): v for a, v in dpdo.unpack(profile, pdo, data).items()}


def _move(twin: Twin, velocity: int = 200_000) -> None:
    """Enable in profile velocity by SDO and run for a while."""
    twin.w(0x6060, 0, 3, 1)
    twin.w(0x60FF, 0, velocity, 4)
    for cw in (0x06, 0x07, 0x0F):
        twin.w(0x6040, 0, cw, 2)
    assert twin.drive.state is State.OPERATION_ENABLED
    twin.step(0.3)


# ---------------------------------------------------------------------------- canopen kind


def test_remapped_tpdo_carries_exactly_the_mapped_objects_in_order(generic: Twin) -> None:
    t = generic
    _move(t)
    t.remap(0x1801, 0x1A01, [0x60640020, 0x60410010, 0x10010008, 0x60610008], ttype=1)
    assert [t.u(0x1A01, s) for s in range(5)] == [4, 0x60640020, 0x60410010, 0x10010008, 0x60610008]
    t.sync()
    assert t.data(0x285) == []  # PRE-OPERATIONAL: no PDOs.
    t.nmt(0x01)
    t.drain()
    t.sync()
    (frame,) = t.data(0x285)
    pos, sw, reg, mode = _values(t.drive, [(0x6064, 0), (0x6041, 0), (0x1001, 0), (0x6061, 0)])
    assert pos > 10_000 and mode == 3
    assert frame == struct.pack("<iHBb", pos, sw, reg, mode)
    # Another SYNC after motion: the new values.
    t.step(0.05)
    t.sync()
    (frame,) = t.data(0x285)
    assert struct.unpack("<i", frame[:4])[0] == t.drive.read(0x6064) > pos


def test_synchronous_types_every_nth_sync_and_sync_start_value(generic: Twin) -> None:
    t = generic
    t.remap(0x1800, 0x1A00, [0x60410010], ttype=1)
    t.remap(0x1801, 0x1A01, [0x60410010], ttype=3)
    t.remap(0x1802, 0x1A02, [0x60410010], ttype=2, start=3)
    t.nmt(0x01)
    t.drain()
    for _ in range(9):
        t.sync()
    t.barrier()
    msgs = [m.arbitration_id for m in _all(t)]
    assert msgs.count(0x185) == 9
    assert msgs.count(0x285) == 3
    # Without a SYNC counter the start value is not used: every 2nd SYNC.
    assert msgs.count(0x385) == 4
    # With a counter, the SYNC whose counter equals 3 is the first: 3, 5, 7.
    t.nmt(0x80)
    t.nmt(0x01)
    t.drain()
    got = []
    for counter in range(1, 9):
        t.sync(counter)
        if t.frames(0x385):
            got.append(counter)
    assert got == [3, 5, 7]


def _all(t: Twin) -> list[can.Message]:
    out = t.collect()
    t.seen = []
    return out


def test_acyclic_synchronous_tpdo_is_sent_at_the_sync_after_a_change(generic: Twin) -> None:
    t = generic
    t.remap(0x1800, 0x1A00, [0x60410010], ttype=0)
    t.nmt(0x01)
    t.drain()
    t.sync()
    assert len(t.frames(0x185)) == 1  # The first SYNC sends the initial values.
    t.sync()
    t.sync()
    assert t.frames(0x185) == []  # Nothing changed.
    t.w(0x6040, 0, 0x06, 2)  # Shutdown: the statusword changes.
    assert t.frames(0x185) == []  # ... but only the SYNC sends.
    t.sync()
    (frame,) = t.data(0x185)
    assert struct.unpack("<H", frame)[0] == t.drive.statusword & 0xFFFF


def test_event_driven_tpdo_honours_inhibit_time_and_event_timer(generic: Twin) -> None:
    t = generic
    _move(t)
    t.remap(0x1800, 0x1A00, [0x60640020], ttype=255, inhibit=0, event=0)
    t.remap(0x1801, 0x1A01, [0x60640020], ttype=254, inhibit=50, event=0)  # 5 ms.
    t.remap(0x1802, 0x1A02, [0x60410010], ttype=255, event=10)  # 10 ms, value unchanged.
    t.nmt(0x01)
    t.step(0.001)
    t.drain()
    t.step(0.1)
    t.barrier()
    ids = [m.arbitration_id for m in _all(t)]
    counts = {i: ids.count(i) for i in (0x185, 0x285, 0x385)}
    assert counts[0x185] == 100  # The position changes every cycle.
    assert counts[0x285] == 20  # At most one per 5 ms.
    assert counts[0x385] == 10  # Statusword unchanged: only the 10 ms timer.
    # The last frames carry the current values.
    t.step(0.001)
    (last,) = t.data(0x185)
    assert struct.unpack("<i", last)[0] == t.drive.read(0x6064)


def test_event_driven_tpdo_is_sent_once_on_entering_operational(generic: Twin) -> None:
    t = generic
    t.nmt(0x01)
    t.step(0.01)
    frames = t.data(0x185)  # Default TPDO1: statusword, type 255.
    assert frames == [struct.pack("<H", t.drive.statusword)]


def test_rtr_types_252_and_253_and_cob_id_bit_30(generic: Twin) -> None:
    t = generic
    _move(t)
    t.remap(0x1800, 0x1A00, [0x60640020], ttype=252)
    t.remap(0x1801, 0x1A01, [0x60640020], ttype=253)
    t.remap(0x1802, 0x1A02, [0x60640020], ttype=253, cob=0x40000385)  # No RTR.
    t.nmt(0x01)
    t.drain()
    t.sync()
    held = t.drive.read(0x6064)
    assert t.frames(0x185) == []  # 252: the SYNC samples, nothing is sent.
    t.step(0.05)
    t.rtr(0x185)
    t.rtr(0x285)
    t.rtr(0x385)
    assert t.data(0x185) == [struct.pack("<i", held)]  # The SYNC's sample.
    assert t.data(0x285) == [struct.pack("<i", t.drive.read(0x6064))]  # Sampled on RTR.
    assert t.frames(0x385) == []
    assert held != t.drive.read(0x6064)


def test_no_process_data_outside_operational(generic: Twin) -> None:
    t = generic
    t.remap(0x1800, 0x1A00, [0x60410010], ttype=1)
    t.remap(0x1400, 0x1600, [0x60400010], ttype=255)
    t.drain()
    t.sync()
    t.send(0x205, b"\x06\x00")
    t.step(0.02)
    assert t.frames(0x185) == []  # PRE-OPERATIONAL.
    assert t.drive.state is State.SWITCH_ON_DISABLED
    # STOPPED answers no SDO: wait for the frames instead of a barrier.
    t.net.nmt.send_command(0x02)
    t.sync()
    t.send(0x205, b"\x06\x00")
    end = time.monotonic() + 2.0
    while t.device.nmt_state_byte != 0x04 and time.monotonic() < end:
        time.sleep(0.01)
    time.sleep(0.1)  # The SYNC and the RPDO follow the NMT command on the same thread.
    t.step(0.02)
    assert t.device.nmt_state_byte == 0x04
    assert [m for m in _all(t) if m.arbitration_id == 0x185] == []
    assert t.drive.state is State.SWITCH_ON_DISABLED
    t.nmt(0x01)
    t.drain()
    t.send(0x205, b"\x06\x00")
    t.sync()
    assert len(t.frames(0x185)) == 1
    assert t.drive.state is State.READY_TO_SWITCH_ON


def test_rpdo_writes_controlword_and_target_velocity(generic: Twin) -> None:
    t = generic
    t.remap(0x1400, 0x1600, [0x60400010, 0x60FF0020], ttype=255)
    t.w(0x6060, 0, 3, 1)
    t.nmt(0x01)
    for cw in (0x06, 0x07, 0x0F):
        t.send(0x205, struct.pack("<Hi", cw, 150_000))
    t.barrier()
    assert t.drive.state is State.OPERATION_ENABLED
    assert t.u(0x60FF, 0, signed=True) == 150_000
    t.step(0.5)
    assert abs(t.drive.velocity - 150_000) < 1_000
    assert t.drive.position > 30_000


def test_synchronous_rpdo_is_applied_at_the_next_sync(generic: Twin) -> None:
    t = generic
    t.remap(0x1400, 0x1600, [0x60400010], ttype=1)
    t.nmt(0x01)
    t.send(0x205, b"\x06\x00")
    t.barrier()
    assert t.drive.state is State.SWITCH_ON_DISABLED
    t.sync()
    t.barrier()
    assert t.drive.state is State.READY_TO_SWITCH_ON


def test_short_rpdo_is_dropped_with_emcy_8210(generic: Twin) -> None:
    t = generic
    t.remap(0x1400, 0x1600, [0x60400010, 0x60FF0020], ttype=255)
    t.nmt(0x01)
    t.drain()
    t.send(0x205, b"\x06\x00\x10")
    assert t.emcys() == [0x8210]
    assert t.drive.state is State.SWITCH_ON_DISABLED
    t.send(0x205, struct.pack("<Hi", 0x06, 0) + b"\x00\x00")  # Longer: processed.
    t.barrier()
    assert t.drive.state is State.READY_TO_SWITCH_ON
    assert t.emcys() == []


def test_rpdo_event_timer_is_a_reception_deadline(generic: Twin) -> None:
    t = generic
    t.remap(0x1400, 0x1600, [0x60400010], ttype=255, event=20)
    t.nmt(0x01)
    t.drain()
    t.step(0.1)
    assert t.emcys() == []  # Monitoring starts with the first RPDO.
    t.send(0x205, b"\x00\x00")
    t.barrier()
    t.step(0.015)
    assert t.emcys() == []
    t.step(0.015)
    frames = t.data(0x85)
    assert frames == [bytes([0x50, 0x82, 0x11, 0, 0, 0, 0, 0])]
    t.step(0.1)
    assert t.emcys() == []  # Once per timeout.


def test_reset_communication_reloads_the_pdo_configuration(generic: Twin) -> None:
    t = generic
    t.remap(0x1800, 0x1A00, [0x60640020, 0x60610008], ttype=1)
    t.nmt(0x82)  # Reset communication: the stored (default) mapping comes back.
    assert t.u(0x1A00, 0) == 1
    t.nmt(0x01)
    t.drain()
    t.step(0.002)
    assert t.data(0x185) == [struct.pack("<H", t.drive.statusword)]


def test_sync_and_tpdo_sent_by_the_session_codec_decode_alike(generic: Twin) -> None:
    t = generic
    _move(t, -50_000)
    t.remap(0x1800, 0x1A00, [0x60410010, 0x606C0020, 0x60610008], ttype=1)
    for n in (0x1801, 0x1802, 0x1803):
        t.w(n, 1, t.u(n, 1) | 0x80000000, 4)
    t.nmt(0x01)
    t.drain()
    t.sync()
    (frame,) = t.data(0x185)
    decoded = _session_decode(t, "tx", frame)
    assert decoded == {
        (0x6041, 0): t.drive.read(0x6041),
        (0x606C, 0): t.drive.read(0x606C),
        (0x6061, 0): 3,
    }


# ---------------------------------------------------------------------------- smartris


def test_smartris_event_tpdo_follows_the_statusword_only(smartris: Twin) -> None:
    t = smartris
    t.nmt(0x01)
    t.step(0.01)
    (first,) = t.data(0x185)  # TPDO1 (255): statusword, mode display, digital inputs.
    assert first[:2] == struct.pack("<H", t.drive.statusword)
    t.drive.set_inputs(0x30000)  # 60FDh changes, the statusword does not: no event.
    t.step(0.05)
    assert t.frames(0x185) == []
    t.w(0x6040, 0, 0x06, 2)
    t.step(0.01)
    (frame,) = t.data(0x185)
    assert frame == _expected(t.drive, [(0x6041, 0), (0x6061, 0), (0x60FD, 0)])
    assert t.drive.read(0x60FD) & 0x30000 == 0x30000


def test_smartris_event_timer_disables_internal_events(smartris: Twin) -> None:
    t = smartris
    t.remap(0x1800, 0x1A00, [0x60410010], ttype=255, event=20)
    t.nmt(0x01)
    t.step(0.001)
    t.drain()
    t.step(0.1)
    assert len(t.frames(0x185)) == 5
    t.w(0x6040, 0, 0x06, 2)  # A statusword change while the timer runs: no extra frame.
    t.step(0.01)
    assert t.frames(0x185) == []
    t.step(0.01)
    (frame,) = t.data(0x185)
    assert frame == struct.pack("<H", t.drive.statusword)


def test_smartris_rtr_only_tpdos_and_longer_rpdo(smartris: Twin) -> None:
    t = smartris
    t.nmt(0x01)
    t.step(0.01)
    t.drain()
    t.rtr(0x285)  # TPDO2 (253): statusword, position actual.
    assert t.data(0x285) == [struct.pack("<Hi", t.drive.statusword, t.drive.position)]
    # 001 §10-3: RPDO1 (7 bytes) sent with DLC 8 is answered with EMCY 8220h; 001 §2-8: the
    # drive processes the mapped bytes at its start.
    t.send(0x205, struct.pack("<HbI", 0x06, 3, 0) + b"\x00")
    assert t.emcys() == [0x8220]
    assert t.drive.state is State.READY_TO_SWITCH_ON


def test_smartris_refuses_unknown_and_unmappable_objects(smartris: Twin) -> None:
    t = smartris
    t.w(0x1A01, 0, 0, 1)
    assert t.abort(0x1A01, 1, 0x5FFF0010, 4) == 0x06020000  # 001 §2-8 note 1.
    assert t.abort(0x1A01, 1, 0x60400010, 4) == 0x06040041
    t.w(0x1A01, 1, 0x60640020, 4)
    t.w(0x1A01, 2, 0x606C0020, 4)
    t.w(0x1A01, 3, 0x60410010, 4)
    assert t.abort(0x1A01, 0, 3, 1) == 0x06040042  # 80 bits > 64.


# ---------------------------------------------------------------------------- hiwin-e


def test_hiwin_assigned_pdos_travel_as_can_fd_frames(hiwin: Twin) -> None:
    t = hiwin
    # 000 §3.1.2: assignment off, count 0, entries, count, assigned index, assignment on.
    t.w(0x1C13, 0, 0, 1)
    t.w(0x1A01, 0, 0, 1)
    for i, e in enumerate((0x60410010, 0x60640020, 0x32100020, 0x60610008), 1):
        t.w(0x1A01, i, e, 4)
    t.w(0x1A01, 0, 4, 1)
    t.w(0x1C13, 1, 0x1A01, 2)
    t.w(0x1C13, 0, 1, 1)
    t.w(0x3210, 0, struct.unpack("<I", struct.pack("<f", 1.5))[0], 4)
    assert [t.u(0x1A01, s) for s in range(5)] == [4, 0x60410010, 0x60640020, 0x32100020, 0x60610008]
    t.nmt(0x01)
    t.drain()
    t.sync()
    (msg,) = t.frames(0x185)
    assert msg.is_fd and len(msg.data) == 12  # 11 bytes padded to a CAN FD length.
    sw, pos, real, mode = _values(t.drive, [(0x6041, 0), (0x6064, 0), (0x3210, 0), (0x6061, 0)])
    assert bytes(msg.data) == struct.pack("<Hifb", sw, pos, real, mode) + b"\x00"
    assert real == 1.5
    assert _session_decode(t, "tx", bytes(msg.data)) == {
        (0x6041, 0): sw,
        (0x6064, 0): pos,
        (0x3210, 0): 1.5,
        (0x6061, 0): mode,
    }
    # The assigned RxPDO (1600h: controlword, mode, target position, touch probe, outputs).
    rx = struct.pack("<HbiHI", 0x06, 8, 1234, 0, 0)
    t.send(0x200 + NODE, rx + bytes(16 - len(rx)), fd=True)
    t.barrier()
    assert t.drive.state is State.READY_TO_SWITCH_ON
    assert t.u(0x607A, 0) == 1234 and t.u(0x6060, 0) == 8


def test_hiwin_mapping_rules(hiwin: Twin) -> None:
    t = hiwin
    t.w(0x1C12, 0, 0, 1)
    t.w(0x1600, 0, 0, 1)
    t.w(0x1600, 1, 0x60400010, 4)
    t.w(0x1600, 2, 0x60400010, 4)
    assert t.abort(0x1600, 0, 2, 1) == 0x06040043  # 000 §3.1: no object twice.
    assert t.abort(0x1600, 0, 9, 1) == 0x06090031  # 000 §3.1: 0 ~ 8 entries.
    t.w(0x1600, 0, 1, 1)
    t.w(0x1C12, 0, 1, 1)
    t.nmt(0x01)
    code = t.abort(0x1600, 0, 0, 1)
    assert code == (0x06010002 if t.drive.profile.quirk("pdo_state_abort") else 0x08000022)
    assert t.u(0x1600, 0) == 1


def test_hiwin_assignment_checks_the_mapping_length(channel: str) -> None:
    # 000 §3.1.2 note 1: 1C12h:00 <- 1 answers 0604 0042h when the assigned mapping is too
    # long. The family's entries are at most 32 bits, so 8 of them fit the 40 bytes; a
    # 16-byte variant of the family shows the check.
    base = _CATALOG.get("hiwin-e")
    small = base.model_copy(update={"pdo": base.pdo.model_copy(update={"max_bytes": 16})})
    small = small.model_copy(
        update={"quirks": (*base.quirks, Quirk(id="pdo_state_abort", value=0x06010002))}
    )
    with _twin(small, channel) as t:
        t.w(0x1C12, 0, 0, 1)
        t.w(0x1601, 0, 0, 1)
        for i, e in enumerate((0x607A0020, 0x60FF0020, 0x60810020, 0x60830020, 0x60840020), 1):
            t.w(0x1601, i, e, 4)
        t.w(0x1601, 0, 5, 1)  # 20 bytes: the mapping object itself is fine.
        t.w(0x1C12, 1, 0x1601, 2)
        assert t.abort(0x1C12, 0, 1, 1) == 0x06040042
        assert t.u(0x1C12, 0) == 0
        t.w(0x1601, 0, 4, 1)
        t.w(0x1C12, 0, 1, 1)
        t.nmt(0x01)
        # HIWIN 000 §2.8.1 note 1 (quirk pdo_state_abort): 0601 0002h outside PreOp.
        assert t.abort(0x1601, 0, 0, 1) == 0x06010002
        assert t.abort(0x1C12, 0, 0, 1) == 0x06010002


# ---------------------------------------------------------------------------- ctmm04x


def test_ctmm_fixed_pdos_every_sync(ctmm: Twin) -> None:
    t = ctmm
    assert t.abort(0x1A00, 1, 0x60640020, 4) == 0x06010002  # 003 §4-1: fixed mapping.
    t.nmt(0x01)
    t.drain()
    t.sync()
    t.sync()
    msgs = t.frames(0x185)
    assert len(msgs) == 2 and all(m.is_fd and len(m.data) == 32 for m in msgs)
    addrs = [(0x6041, 0), (0x6061, 0), (0x6062, 0), (0x6064, 0), (0x606C, 0), (0x60FD, 0)]
    addrs += [(0x200A, 0), (0x2011, 0), (0x2012, 0), (0x2013, 0)]
    expected = _expected(t.drive, addrs)
    assert len(expected) == 29
    assert bytes(msgs[-1].data) == expected + bytes(3)
    rx = struct.pack("<HbiiI", 0x06, 1, 500, 0, 0)  # 15 bytes -> 16.
    t.send(0x205, rx + b"\x00", fd=True)
    t.barrier()
    assert t.drive.state is State.READY_TO_SWITCH_ON
    assert t.u(0x607A, 0) == 500


_CODES = {
    "INTEGER8": "b",
    "UNSIGNED8": "B",
    "INTEGER16": "h",
    "UNSIGNED16": "H",
    "INTEGER32": "i",
    "UNSIGNED32": "I",
    "REAL32": "f",
}


def _expected(drive: SimulatedDrive, addrs: list[tuple[int, int]], order: str = "<") -> bytes:
    """The objects' current values packed by their own data types, in order."""
    fmt = order + "".join(_CODES[drive.spec(i, s).data_type.name] for i, s in addrs)
    vals: list[Any] = []
    for i, s in addrs:
        try:
            vals.append(drive.read(i, s))
        except Exception:  # No value: the frame carries 0.
            vals.append(0)
    return struct.pack(fmt, *vals)


# ---------------------------------------------------------------------------- lecsn-t


def test_lecsn_telegram_102_is_big_endian(lecsn: Twin) -> None:
    t = lecsn
    t.w(0x039A, 0, 102, 2)  # P922: telegram 102 (the master's GSDML choice).
    # A custom actual-value telegram: mode display, Reserved 8, statusword, position,
    # velocity, padded to 48 bytes with Reserved 16-bit entries.
    entries = [0x60610008, 0x00000808, 0x60410010, 0x60640020, 0x606C0020]
    entries += [0x00001010] * 18
    t.w(0x1A00, 0, 0, 1)
    for i, e in enumerate(entries, 1):
        t.w(0x1A00, i, e, 4)
    t.w(0x1A00, 0, len(entries), 1)
    _move(t, 100_000)
    t.nmt(0x01)
    t.drain()
    t.sync()
    (msg,) = t.frames(0x185)
    assert msg.is_fd and len(msg.data) == 48
    mode, sw, pos, vel = _values(t.drive, [(0x6061, 0), (0x6041, 0), (0x6064, 0), (0x606C, 0)])
    assert bytes(msg.data) == struct.pack(">bxHii", mode, sw, pos, vel) + bytes(36)
    assert pos > 0 and vel > 0
    assert _session_decode(t, "tx", bytes(msg.data)) == {
        (0x6061, 0): mode,
        (0x6041, 0): sw,
        (0x6064, 0): pos,
        (0x606C, 0): vel,
    }
    # The default setpoint telegram 102: mode, Reserved 8, controlword, ... big-endian.
    rx = bytearray(48)
    struct.pack_into(">bxH", rx, 0, 3, 0x000F)
    struct.pack_into(">i", rx, 20, 77_000)  # 60FFh after 6040h, 2D01-3h, 6071h, 6087h, 607Ah.
    t.send(0x205, bytes(rx), fd=True)
    t.barrier()
    assert t.drive.state is State.OPERATION_ENABLED
    assert t.u(0x60FF, 0, signed=True) == 77_000


def test_rpdo_new_set_point_uses_the_target_of_the_same_pdo(generic: Twin) -> None:
    t = generic
    t.remap(0x1400, 0x1600, [0x60400010, 0x607A0020], ttype=255)
    t.w(0x6060, 0, 1, 1)  # Profile position.
    for cw in (0x06, 0x07, 0x0F):
        t.w(0x6040, 0, cw, 2)
    t.nmt(0x01)
    start = t.drive.position
    # CiA 402-2 §6.5 new set-point (bit 4) with the target in the same RPDO.
    t.send(0x205, struct.pack("<Hi", 0x1F, start + 40_000))
    t.barrier()
    assert t.drive.statusword & 0x1000  # Set-point acknowledged.
    t.send(0x205, struct.pack("<Hi", 0x0F, start + 40_000))
    t.step(1.0)
    assert abs(t.drive.position - (start + 40_000)) < 200
