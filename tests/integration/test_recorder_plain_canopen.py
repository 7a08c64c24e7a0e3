"""Acceptance: the simulated drives' recorder, driven by a plain canopen master.

The drives run in real time (``SimulatedBus``) on a python-can ``virtual`` bus; the master is
python-canopen's SDO client alone, as a user's script would be: it configures the recorder
objects, enables the drive and makes a profile position move with SDO writes, and uploads
the data object with a segmented SDO upload. The samples are compared with the simulation's
own values: a hook on every plant sub-step of the drive keeps what the plant was.
"""

from __future__ import annotations

import itertools
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
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.od_build import build_object_dictionary

NODE = 9
REV = 131072
POS, VEL = 0x60640020, 0x606C0020
_CATALOG = ProfileCatalog()


@dataclass
class PlantLog:
    """The plant's position and velocity after every sub-step, by step number."""

    drive: SimulatedDrive
    pos: dict[int, int] = field(default_factory=dict)
    vel: dict[int, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.drive.on_substep(self._on_step)

    def _on_step(self) -> None:  # Runs on the simulation thread, under the drive's lock.
        d = self.drive
        k = d.plant_steps
        self.pos[k] = d.position
        self.vel[k] = round(d.velocity)

    def close(self) -> None:
        self.drive.remove_substep_hook(self._on_step)

    def first_crossing(self, level: int) -> int:
        with self.drive.lock:
            steps = sorted(self.pos)
            pos = dict(self.pos)
        for a, b in itertools.pairwise(steps):
            if pos[a] < level <= pos[b]:
                return b
        raise AssertionError(f"the position never crossed {level}")


@dataclass
class Master:
    sim: SimulatedBus
    net: Any
    node: Any
    base: int

    def u(self, index: int, sub: int = 0, signed: bool = False) -> int:
        return int.from_bytes(self.node.sdo.upload(index, sub), "little", signed=signed)

    def w(self, index: int, sub: int, value: int, size: int) -> None:
        self.node.sdo.download(index, sub, value.to_bytes(size, "little", signed=value < 0))

    def rec(self, offset: int, value: int, size: int, sub: int = 0) -> None:
        self.w(self.base + offset, sub, value, size)

    def status(self) -> int:
        return self.u(self.base + 6)

    def upload(self, channels: int) -> list[tuple[int, ...]]:
        data = self.node.sdo.upload(self.base + 7, 0)
        n = len(data) // 4
        flat = struct.unpack(f"<{n}i", data)
        return [flat[i : i + channels] for i in range(0, n, channels)]


@contextmanager
def _master(profile_id: str, channel: str) -> Iterator[Master]:
    profile = _CATALOG.get(profile_id)
    assert profile.recorder is not None
    sim = SimulatedBus.start(drives=[(profile_id, NODE)], channel=channel, catalog=_CATALOG)
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    node = canopen.RemoteNode(NODE, build_object_dictionary(profile, NODE))
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 1.0
    try:
        yield Master(sim, net, node, profile.recorder.index)
    finally:
        net.disconnect()
        sim.stop()


def _wait(cond: Any, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.01)


def test_generic_twin_records_a_profile_move_with_a_level_trigger(channel: str) -> None:
    with _master("cia402-generic", channel) as m:
        drive = m.sim.drives[0]
        log = PlantLog(drive)
        try:
            start = m.u(0x6064, signed=True)
            level = start + REV // 4
            depth, pre = 2000, 400  # 0.5 s at 4 kHz, 20 % before the trigger.
            m.rec(0, POS, 4, sub=1)
            m.rec(0, VEL, 4, sub=2)
            m.rec(1, 1, 2)  # Every plant step.
            m.rec(2, depth, 2)
            m.rec(3, 1, 1)  # Level on channel 1, rising.
            m.rec(4, level, 4)
            m.rec(5, pre, 2)
            m.node.nmt.state = "OPERATIONAL"  # Written in any NMT state.
            time.sleep(0.05)
            assert [m.u(m.base, s) for s in range(3)] == [8, POS, VEL]
            m.rec(6, 1, 1)
            assert m.status() == 1
            # The configuration is refused while the recorder runs.
            with pytest.raises(canopen.SdoAbortedError) as info:
                m.rec(2, 100, 2)
            assert info.value.code == 0x08000022
            with pytest.raises(canopen.SdoAbortedError) as info:
                m.node.sdo.upload(m.base + 7, 0)
            assert info.value.code == 0x08000024  # No data while running.

            # Enable and move with SDO writes: profile position, one revolution.
            m.w(0x6060, 0, 1, 1)
            m.w(0x6081, 0, 400_000, 4)
            for cw in (0x06, 0x07, 0x0F):
                m.w(0x6040, 0, cw, 2)
            _wait(lambda: m.u(0x6041) & 0x6F == 0x27)
            _wait(lambda: m.u(m.base + 8) >= pre)  # Pre-trigger samples in the buffer.
            m.w(0x607A, 0, start + REV, 4)
            m.w(0x6040, 0, 0x1F, 2)
            m.w(0x6040, 0, 0x0F, 2)
            _wait(lambda: m.status() == 3)
            assert (m.u(m.base + 8), m.u(m.base + 9)) == (depth, pre)

            rows = m.upload(2)
        finally:
            log.close()
        assert len(rows) == depth
        # The trigger sample sits at the documented pre-trigger index: the first sample at or
        # above the level, the one before it below.
        t = log.first_crossing(level)
        assert rows[pre - 1][0] < level <= rows[pre][0]
        # One sample every plant sub-step: 1/4000 s of simulated time apart, each the plant's
        # position and velocity at that sub-step.
        assert drive.plant_period * 4000 == pytest.approx(1.0, abs=1e-12)
        expected = [(log.pos[t - pre + i], log.vel[t - pre + i]) for i in range(depth)]
        assert rows == expected
        assert max(r[1] for r in rows) > 100_000  # The move is in the window.
        # The recording stays readable (and the same) until the next start.
        assert m.upload(2) == rows
        m.rec(6, 0, 1)
        assert m.status() == 3 and m.u(m.base + 8) == depth


@pytest.mark.parametrize("profile_id", ["smartris", "hiwin-e", "ctmm04x", "lecsn-t"])
def test_every_family_twin_records_and_uploads(profile_id: str, channel: str) -> None:
    with _master(profile_id, channel) as m:
        drive = m.sim.drives[0]
        log = PlantLog(drive)
        try:
            m.rec(0, POS, 4, sub=1)
            m.rec(1, 4, 2)  # Every 4th plant step: 1 kHz.
            m.rec(2, 50, 2)
            m.rec(3, 0, 1)  # Immediate.
            m.rec(6, 1, 1)
            _wait(lambda: m.status() == 3)
            rows = m.upload(1)
        finally:
            log.close()
        rec = drive.recorder
        assert rec is not None and rec.data_first_step is not None
        first = rec.data_first_step
        assert (m.u(m.base + 8), m.u(m.base + 9)) == (50, 0)
        assert rows == [(log.pos[first + 4 * i],) for i in range(50)]


def test_two_recorders_upload_at_once(channel: str) -> None:
    # Two drives on one bus record and upload concurrently (one SDO channel each).
    sim = SimulatedBus.start(drives=[("cia402-generic", 3), ("smartris", 4)], channel=channel)
    net = canopen.Network()
    net.connect(interface="virtual", channel=channel)
    try:
        nodes = []
        for nid, pid in ((3, "cia402-generic"), (4, "smartris")):
            profile = _CATALOG.get(pid)
            assert profile.recorder is not None
            node = canopen.RemoteNode(nid, build_object_dictionary(profile, nid))
            net.add_node(node)
            node.sdo.RESPONSE_TIMEOUT = 1.0
            nodes.append((node, profile.recorder.index))
        for node, base in nodes:
            node.sdo.download(base, 1, POS.to_bytes(4, "little"))
            node.sdo.download(base + 2, 0, (500).to_bytes(2, "little"))
            node.sdo.download(base + 6, 0, b"\x01")
        for node, base in nodes:
            _wait(lambda n=node, b=base: n.sdo.upload(b + 6, 0) == b"\x03")
        out: dict[int, bytes] = {}

        def up(node: Any, base: int) -> None:
            out[node.id] = node.sdo.upload(base + 7, 0)

        threads = [threading.Thread(target=up, args=nb) for nb in nodes]
        for th in threads:
            th.start()
        for th in threads:
            th.join(10)
        assert {k: len(v) for k, v in out.items()} == {3: 2000, 4: 2000}
    finally:
        net.disconnect()
        sim.stop()
