"""Acceptance: the LECSN-T twin's one-touch tuning, driven by a plain canopen master.

The twin runs in real time (``SimulatedBus``) on a python-can ``virtual`` bus; the master is
python-canopen's SDO client alone, with an empty object dictionary (raw uploads and downloads,
as a user's script would do from the manual's tables): it enables the drive in profile position
mode, starts one-touch tuning (P11600 = 2D50h, 004 §20.8.7), keeps the motor moving back and
forth with SDO writes while it reads the progress (P11601 = 2D51h), reads the result (P11604 =
2D54h) and the tuned load to motor inertia ratio (PB06 = 2086h), then undoes it (P11603 =
2D53h) and checks that the restored values survive an NMT reset node ("saved to EEP-ROM").
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import canopen
import pytest

from servodesk.sim.bus import SimulatedBus

NODE = 11
MODE, STATUS, STOP, CLEAR, ERROR = 0x2D50, 0x2D51, 0x2D52, 0x2D53, 0x2D54
PB06, PB09 = 0x2086, 0x2089
SPEED = 200_000  # 6081h, in the twin's raw unit (counts/s)
STROKE = 30_000  # counts


@dataclass
class Master:
    node: Any

    def u(self, index: int, sub: int = 0, signed: bool = False) -> int:
        return int.from_bytes(self.node.sdo.upload(index, sub), "little", signed=signed)

    def w(self, index: int, sub: int, value: int, size: int) -> None:
        self.node.sdo.download(index, sub, value.to_bytes(size, "little", signed=value < 0))

    def move(self, target: int) -> None:
        """A profile position move to ``target``; returns when the command has ended."""
        self.w(0x607A, 0, target, 4)
        self.w(0x6040, 0, 0x3F, 2)  # New set-point, change immediately, absolute.
        self.w(0x6040, 0, 0x0F, 2)
        time.sleep(STROKE / SPEED + 0.2)  # The move and a dwell at the end point.


@contextmanager
def _master(channel: str) -> Iterator[tuple[SimulatedBus, Master]]:
    sim = SimulatedBus.start(drives=[("lecsn-t", NODE)], channel=channel)
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    od = canopen.ObjectDictionary()  # type: ignore[no-untyped-call]
    node = canopen.RemoteNode(NODE, od)  # Empty: raw SDO uploads and downloads.
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 1.0
    try:
        yield sim, Master(node)
    finally:
        net.disconnect()
        sim.stop()


def _wait(cond: Callable[[], bool], timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError("timed out")
        time.sleep(0.01)


def test_one_touch_tuning_over_sdo_while_the_master_moves_the_axis(channel: str) -> None:
    with _master(channel) as (sim, m):
        # Factory state: nothing tuned (simulation values of PB06/PB09: 7.00 times, 823 rad/s).
        assert [m.u(i) for i in (MODE, STATUS, ERROR)] == [0, 0, 0]
        assert (m.u(PB06), m.u(PB09)) == (700, 823)

        # Servo off: tuning ends at once with C002h, 100 %, mode back to 0.
        m.w(MODE, 0, 1, 1)
        assert [m.u(i) for i in (MODE, STATUS, ERROR)] == [0, 100, 0xC002]

        # Enable in profile position mode; no ramp (0 ms time constants).
        m.w(0x6060, 0, 1, 1)
        m.w(0x6081, 0, SPEED, 4)
        m.w(0x6083, 0, 0, 4)
        m.w(0x6084, 0, 0, 4)
        for cw in (0x06, 0x07, 0x0F):
            m.w(0x6040, 0, cw, 2)
        _wait(lambda: m.u(0x6041) & 0x6F == 0x27)
        home = m.u(0x6064, signed=True)

        # Start and stop: 1EA5h cancels (C000h); any other value is refused.
        m.w(MODE, 0, 2, 1)
        assert m.u(MODE) == 2
        with pytest.raises(canopen.SdoAbortedError) as info:
            m.w(STOP, 0, 0x1234, 2)
        assert info.value.code == 0x06090030  # PROFIdrive error 02h on the real card.
        m.w(STOP, 0, 0x1EA5, 2)
        assert [m.u(i) for i in (MODE, STATUS, ERROR)] == [0, 100, 0xC000]

        # Basic mode while the master moves the axis back and forth.
        m.w(MODE, 0, 1, 1)
        assert [m.u(i) for i in (MODE, STATUS, ERROR)] == [1, 0, 0]
        progress: list[int] = []
        n = 0
        while m.u(MODE) != 0:
            assert n < 16, f"still tuning after {n} moves, progress {progress}"
            n += 1
            m.move(home + (STROKE if n % 2 else 0))
            progress.append(m.u(STATUS))
        assert (m.u(STATUS), m.u(ERROR)) == (100, 0x0000)
        assert progress == sorted(progress) and progress[0] > 0 and progress[-1] == 100
        assert len(set(progress)) >= 4  # Seen going up in steps.
        # The twin's load is 3 times the motor inertia (simulation.load_inertia_ratio).
        drive = sim.drives[0]
        true_ratio = drive.plant_params.load_inertia / drive.plant_params.motor_inertia
        ratio = m.u(PB06, signed=True) / 100
        assert ratio == pytest.approx(true_ratio, rel=0.10)
        tuned_speed_gain = m.u(PB09)
        assert tuned_speed_gain != 823

        # Undo to the values before tuning; saved to EEP-ROM, so a reset node keeps them.
        m.w(CLEAR, 0, 1, 2)
        assert (m.u(PB06), m.u(PB09)) == (700, 823)
        m.node.nmt.send_command(0x81)  # NMT reset node (a power cycle).
        time.sleep(0.3)
        _wait(lambda: m.u(0x6041) & 0x4F == 0x40)  # Switch on disabled again.
        assert (m.u(PB06), m.u(PB09)) == (700, 823)
        assert [m.u(i) for i in (MODE, STATUS, ERROR)] == [0, 0, 0]
