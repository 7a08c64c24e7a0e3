"""The wall-clock runner, the multi-drive bus handle and the ``servodesk sim`` command."""

from __future__ import annotations

import argparse
import time

import canopen
import pytest

from servodesk.cli import sim as sim_cli
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.runner import SimRunner, run_unbound

from .support import new_drive


def test_runner_follows_the_wall_clock_and_stops() -> None:
    a, b = new_drive(), new_drive(node_id=6)
    runner = SimRunner([a, b]).start()
    t0 = a.time
    time.sleep(0.3)
    runner.stop()
    assert not runner.running
    elapsed = a.time - t0
    assert 0.2 < elapsed < 0.5
    assert abs(a.time - b.time) < 0.02
    frozen = a.time
    time.sleep(0.05)
    assert a.time == frozen


def test_runner_catches_up_in_chunks_and_drops_long_stalls() -> None:
    class Recorder:
        def __init__(self) -> None:
            self.steps: list[float] = []

        def step(self, dt: float) -> None:
            self.steps.append(dt)
            if len(self.steps) == 3:
                time.sleep(0.08)  # A stall: the runner must catch up in chunks.

    r = Recorder()
    runner = SimRunner([r], max_chunk=0.01, max_lag=0.5).start()
    time.sleep(0.3)
    runner.stop()
    assert max(r.steps) <= 0.01 + 1e-9
    assert sum(r.steps) == pytest.approx(0.3, abs=0.1)


def test_run_unbound_is_faster_than_real_time() -> None:
    d = new_drive()
    wall = run_unbound(d, 1.0)
    assert d.time == pytest.approx(1.001, abs=1e-6)
    assert wall < 0.5


def test_bus_with_two_drives_and_serials(channel: str) -> None:
    bus = SimulatedBus.start(
        drives=[("cia402-generic", 3), ("cia402-generic", 4)], channel=channel, serials=[11, 12]
    )
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="virtual", channel=channel)
    try:
        for node_id, serial in ((3, 11), (4, 12)):
            node = net.add_node(node_id)
            assert int.from_bytes(node.sdo.upload(0x1018, 4), "little") == serial
        assert [d.node_id for d in bus.drives] == [3, 4]
    finally:
        net.disconnect()
        bus.stop()
    bus.stop()  # Idempotent.


def _args(**kw: object) -> argparse.Namespace:
    base = {
        "profile": "cia402-generic",
        "node_id": 1,
        "interface": "virtual",
        "channel": "cli-test",
        "bitrate": None,
        "serial": None,
    }
    base.update(kw)
    return argparse.Namespace(**base)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"profile": "no-such-profile"}, "no profile"),
        ({"node_id": 0}, "outside 1..127"),
        ({"node_id": 128}, "outside 1..127"),
        ({"interface": "no-such-interface"}, "not available"),
    ],
)
def test_cli_bad_arguments_exit_2_with_a_message(
    capsys: pytest.CaptureFixture[str], kw: dict[str, object], message: str
) -> None:
    assert sim_cli.run(_args(**kw)) == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


def test_cli_registers_the_sim_command() -> None:
    parser = argparse.ArgumentParser()
    sim_cli.register(parser.add_subparsers())
    args = parser.parse_args(
        [
            "sim",
            "--profile",
            "x",
            "--node-id",
            "7",
            "--interface",
            "virtual",
            "--channel",
            "c",
            "--bitrate",
            "500000",
            "--serial",
            "0x10",
        ]
    )
    assert (args.profile, args.node_id, args.bitrate, args.serial) == ("x", 7, 500000, 16)
    assert args.func is sim_cli.run
