"""Acceptance: every family's simulated drive, remapped and driven by a plain canopen master.

The drives run in real time (``SimulatedBus``, stepped by its runner thread) on a python-can
``virtual`` bus. The master is python-canopen alone: its ``RemoteNode`` SDO client, its own
PDO machinery (``PdoMap.save()`` is python-canopen's CiA 301 remapping procedure), its SYNC
producer, and ``Network.subscribe`` for the CAN FD frames of the EtherCAT, CC-Link IE TSN and
PROFINET twins. The object dictionary is the one servodesk builds from the profile (what a
master would load from the drive's EDS).
"""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import canopen
import pytest

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.od_build import build_object_dictionary

NODE = 7
_CATALOG = ProfileCatalog()


@dataclass
class Master:
    sim: SimulatedBus
    net: Any
    node: Any
    frames: dict[int, list[bytes]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def u(self, index: int, sub: int = 0, signed: bool = False) -> int:
        return int.from_bytes(self.node.sdo.upload(index, sub), "little", signed=signed)

    def w(self, index: int, sub: int, value: int, size: int) -> None:
        self.node.sdo.download(index, sub, value.to_bytes(size, "little", signed=value < 0))

    def listen(self, can_id: int) -> None:
        def on_frame(cid: int, data: bytearray, timestamp: float) -> None:
            with self.lock:
                self.frames.setdefault(cid, []).append(bytes(data))

        self.net.subscribe(can_id, on_frame)

    def take(self, can_id: int) -> list[bytes]:
        with self.lock:
            return self.frames.pop(can_id, [])

    def sync_and_wait(self, can_id: int, timeout: float = 1.0) -> bytes:
        """SYNC until a frame with ``can_id`` arrives; the last one."""
        self.take(can_id)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.net.sync.transmit()
            time.sleep(0.01)
            got = self.take(can_id)
            if got:
                return got[-1]
        raise AssertionError(f"no frame 0x{can_id:03X} after SYNC")


@contextmanager
def _master(profile_id: str, channel: str) -> Iterator[Master]:
    sim = SimulatedBus.start(drives=[(profile_id, NODE)], channel=channel, catalog=_CATALOG)
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    od = build_object_dictionary(_CATALOG.get(profile_id), NODE)
    node = canopen.RemoteNode(NODE, od)
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 1.0
    try:
        yield Master(sim, net, node)
    finally:
        net.disconnect()
        sim.stop()


def _wait(cond: Any, timeout: float = 2.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.01)


@pytest.mark.parametrize("profile_id", ["cia402-generic", "smartris"])
def test_canopen_families_remapped_with_python_canopen(profile_id: str, channel: str) -> None:
    with _master(profile_id, channel) as m:
        node = m.node
        node.tpdo.read()
        node.rpdo.read()
        # TPDO2: statusword, actual position, mode display, every SYNC.
        tp = node.tpdo[2]
        tp.clear()
        tp.add_variable(0x6041)
        tp.add_variable(0x6064)
        tp.add_variable(0x6061)
        tp.trans_type = 1
        tp.enabled = True
        tp.save()
        # RPDO3: controlword and target velocity, applied on arrival.
        rp = node.rpdo[3]
        rp.clear()
        rp.add_variable(0x6040)
        rp.add_variable(0x60FF)
        rp.trans_type = 255
        rp.enabled = True
        rp.save()
        # A plain script reads the mapping back.
        assert [m.u(0x1A01, s) for s in range(4)] == [3, 0x60410010, 0x60640020, 0x60610008]
        assert [m.u(0x1602, s) for s in range(3)] == [2, 0x60400010, 0x60FF0020]
        assert m.u(0x1801, 2) == 1 and not m.u(0x1801, 1) & 0x80000000
        m.w(0x6060, 0, 3, 1)

        # Pre-operational: a SYNC gets no TPDO.
        m.net.sync.transmit()
        assert not tp.wait_for_reception(0.2)
        node.nmt.state = "OPERATIONAL"
        time.sleep(0.05)
        m.net.sync.transmit()
        assert tp.wait_for_reception(1.0)
        sw, pos, mode = (v.raw for v in tp.map)
        assert (sw, pos, mode) == (m.u(0x6041), m.u(0x6064, signed=True), 3)
        assert bytes(tp.data) == struct.pack("<Hib", sw, pos, mode)

        # Enable and move through the RPDO (smartris: 40 ms between controlwords, 001 §5).
        rp.map[1].raw = 100_000
        for cw in (0x06, 0x07, 0x0F):
            rp.map[0].raw = cw
            rp.transmit()
            time.sleep(0.06)
        _wait(lambda: m.u(0x6041) & 0x6F == 0x27)
        _wait(lambda: m.u(0x606C, signed=True) > 50_000)
        m.net.sync.transmit()
        assert tp.wait_for_reception(1.0)
        assert tp.map[0].raw & 0x6F == 0x27
        rp.map[0].raw = 0x06
        rp.map[1].raw = 0
        rp.transmit()


def test_hiwin_assigned_txpdo_on_can_fd(channel: str) -> None:
    with _master("hiwin-e", channel) as m:
        # 000 §3.1.2, steps 2-6 (step 1: the twin boots in pre-operational).
        m.w(0x1C13, 0, 0, 1)
        m.w(0x1A02, 0, 0, 1)
        entries = [0x60410010, 0x60640020, 0x606C0020, 0x60610008, 0x603F0010]
        for i, e in enumerate(entries, 1):
            m.w(0x1A02, i, e, 4)
        m.w(0x1A02, 0, len(entries), 1)
        m.w(0x1C13, 1, 0x1A02, 2)
        m.w(0x1C13, 0, 1, 1)
        assert [m.u(0x1A02, s) for s in range(6)] == [5, *entries]
        assert (m.u(0x1C13, 0), m.u(0x1C13, 1)) == (1, 0x1A02)
        # More entries than the family allows are refused before anything changes.
        with pytest.raises(canopen.SdoAbortedError) as exc:
            m.w(0x1A02, 0, 9, 1)
        assert exc.value.code == 0x06090031  # 000 §3.1: 0 ~ 8 entries.
        m.listen(0x180 + NODE)
        m.node.nmt.state = "OPERATIONAL"
        time.sleep(0.05)
        frame = m.sync_and_wait(0x180 + NODE)
        assert len(frame) == 16  # 13 bytes on a CAN FD length.
        expected = struct.pack(
            "<HiibH",
            m.u(0x6041),
            m.u(0x6064, signed=True),
            m.u(0x606C, signed=True),
            m.u(0x6061, signed=True),
            m.u(0x603F),
        )
        assert frame == expected + bytes(3)


def test_ctmm_fixed_mapping_read_back_matches_the_frames(channel: str) -> None:
    with _master("ctmm04x", channel) as m:
        count = m.u(0x1A00, 0)
        entries = [m.u(0x1A00, s) for s in range(1, count + 1)]
        assert entries[:4] == [0x60410010, 0x60610008, 0x60620020, 0x60640020]
        with pytest.raises(canopen.SdoAbortedError):
            m.w(0x1A00, 1, 0x60640020, 4)  # 003 §4-1: pre-assigned, never written.
        m.listen(0x180 + NODE)
        m.node.nmt.state = "OPERATIONAL"
        time.sleep(0.05)
        frame = m.sync_and_wait(0x180 + NODE)
        size = sum(e & 0xFF for e in entries) // 8
        assert (size, len(frame)) == (29, 32)
        assert frame[:2] == struct.pack("<H", m.u(0x6041))
        assert frame[3:7] == struct.pack("<i", m.u(0x6062, signed=True))
        assert frame[size:] == bytes(3)


def test_lecsn_variable_telegram_big_endian(channel: str) -> None:
    with _master("lecsn-t", channel) as m:
        m.w(0x039A, 0, 103, 2)  # P922: telegram 103 (60 bytes per direction).
        entries = [0x60410010, 0x00000808, 0x60610008, 0x60640020] + [0x00001010] * 26
        m.w(0x1A00, 0, 0, 1)
        for i, e in enumerate(entries, 1):
            m.w(0x1A00, i, e, 4)
        m.w(0x1A00, 0, len(entries), 1)
        assert m.u(0x1A00, 0) == 30
        assert [m.u(0x1A00, s) for s in range(1, 5)] == entries[:4]
        m.listen(0x180 + NODE)
        m.node.nmt.state = "OPERATIONAL"
        time.sleep(0.05)
        frame = m.sync_and_wait(0x180 + NODE)
        assert len(frame) == 64  # 60 bytes on a CAN FD length.
        sw, mode, pos = m.u(0x6041), m.u(0x6061, signed=True), m.u(0x6064, signed=True)
        assert frame[:8] == struct.pack(">Hxbi", sw, mode, pos)  # 004 §20.1.2: big endian.
        assert frame[8:] == bytes(56)
