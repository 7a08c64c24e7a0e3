"""Cyclic PROFINET IO against the simulated LECSN-T: the cycle servodesk's IO controller achieves
and what its frames lose, at the shortest send clock the twin takes (SendClockFactor 32 x
reduction ratio 1 = 1 ms; docs/profinet.md "Cyclic data").

One process: the twin (sim/profinet_device.py, its IO device on the slave end of a veth pair,
the drive stepped on the wall clock by SimRunner) and servodesk's ProfinetLink, whose IO
controller AR (links/profinet_io.py) sends the setpoint telegram on the master end. Over
``--seconds`` it reports:

- the output cycle achieved: median and p99 of the intervals between two output frames the
  controller's thread sent (µs), and the largest;
- input frames lost (gaps in the device's cycle counter) and received;
- data-status errors (input frames whose DataStatus or IOPS was not good) and watchdog
  expiries on both sides (the controller's "link lost", the device's data hold).

With ``--loss-runs N`` it then cuts the link N times (the device's end of the pair set down
for ``--cable-out-s``, then up: a cable pulled and put back) and reports, as median, p95 and
worst, the time from the cut to "link lost" and from the cable back to "ok" again (the IO AR
set up again by itself: Connect, PrmEnd, ApplicationReady, the first valid input;
links/profinet_io.py ``_recover``).

Needs root (a veth pair and raw sockets). Prints a summary, or JSON with ``--json``.

    python bench/bench_profinet_cyclic.py [--seconds 60] [--cycle-ms 1] [--loss-runs 20]
        [--cable-out-s 2] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import subprocess
import sys
import time
from typing import Any

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.links.profinet_link import ProfinetLink
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.profinet_device import ProfinetDevice
from servodesk.sim.runner import SimRunner
from servodesk.sim.veth import create_veth

P922 = 0x039A


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def _spread(values: list[float]) -> dict[str, float | None]:
    ms = [v * 1000 for v in values]
    if not ms:
        return {"median": None, "p95": None, "max": None}
    return {
        "median": round(statistics.median(ms), 1),
        "p95": round(_percentile(ms, 0.95), 1),
        "max": round(max(ms), 1),
    }


def _cable(ifname: str, *, up: bool) -> None:
    """The device's end of the pair down (the cable out) or up; the times count from the
    return of ``ip``, when the change is made for certain."""
    subprocess.run(["ip", "link", "set", ifname, "up" if up else "down"], check=True)


async def _until_state(io: Any, state: str, timeout: float) -> float | None:
    """Seconds until the controller's link state is ``state`` (polled every ms)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if io.health.state == state:
            return time.monotonic() - t0
        await asyncio.sleep(0.001)
    return None


async def link_losses(io: Any, ifname: str, runs: int, out_s: float) -> dict[str, Any]:
    """Cut the link ``runs`` times at the device's end (see the module docstring)."""
    to_lost: list[float] = []
    to_ok: list[float] = []
    failed = 0
    for _ in range(runs):
        _cable(ifname, up=False)
        lost = await _until_state(io, "link lost", 2.0)
        await asyncio.sleep(max(0.0, out_s - (lost or 0.0)))
        _cable(ifname, up=True)
        back = await _until_state(io, "ok", 10.0)
        if lost is None or back is None:
            failed += 1
        else:
            to_lost.append(lost)
            to_ok.append(back)
        await asyncio.sleep(0.3)  # settle before the next cut
    return {
        "runs": runs,
        "cable_out_s": out_s,
        "failed_runs": failed,
        "link_lost_ms": _spread(to_lost),
        "running_again_ms": _spread(to_ok),
        "recoveries": io.health.recoveries,
    }


async def measure(
    seconds: float, cycle_ms: float, loss_runs: int = 0, out_s: float = 2.0
) -> dict[str, Any]:
    pair = create_veth("sdbio")
    drive = SimulatedDrive(ProfileCatalog().get("lecsn-t"), 1)
    drive.write(P922, 0, 102)
    runner = SimRunner([drive])
    runner.start()
    dev = ProfinetDevice(drive).start()
    io_dev = dev.serve_io(pair.slave)
    link = ProfinetLink(
        LinkParams(interface="profinet", channel=dev.channel, node_id=1, extra={"nic": pair.master})
    )
    try:
        await link.open()
        link.prepare_io(102, 48, 48, cycle_ms / 1000.0, True)
        t0 = time.monotonic()
        await link.nmt("start")
        connect_ms = (time.monotonic() - t0) * 1000
        io = link.io
        assert io is not None
        await asyncio.sleep(0.2)  # settle
        h = io.health
        start = (h.cycles, h.received, h.lost, h.data_status_errors, h.losses)
        h.intervals.clear()
        samples: list[float] = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            await asyncio.sleep(0.5)
            samples += h.intervals[:]
            h.intervals.clear()
        cycles, received, lost, ds_errors, losses = (
            h.cycles - start[0],
            h.received - start[1],
            h.lost - start[2],
            h.data_status_errors - start[3],
            h.losses - start[4],
        )
        device_aborts = io_dev.aborts
        losses_seen = await link_losses(io, pair.slave, loss_runs, out_s) if loss_runs > 0 else None
        await link.close()
    finally:
        dev.stop()
        runner.stop()
        pair.delete()
    us = [s * 1e6 for s in samples]
    return {
        "seconds": seconds,
        "cycle_ms_asked": cycle_ms,
        "send_clock_factor": 32,
        "reduction_ratio": round(cycle_ms),
        "watchdog_ms": round(io.watchdog_factor * io.cycle * 1000, 3),
        "connect_ms": round(connect_ms, 1),
        "output_frames": cycles,
        "cycle_us_median": round(statistics.median(us), 1) if us else None,
        "cycle_us_p99": round(_percentile(us, 0.99), 1) if us else None,
        "cycle_us_max": round(max(us), 1) if us else None,
        "input_frames_received": received,
        "input_frames_lost": lost,
        "data_status_errors": ds_errors,
        "controller_watchdog_expiries": losses,
        "device_watchdog_expiries": device_aborts,
        "link_loss": losses_seen,
        "load_average_1min": round(os.getloadavg()[0], 2),
        "cores": os.cpu_count(),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--cycle-ms", type=float, default=1.0, help="1, 2, 4, 8 or 16")
    ap.add_argument("--loss-runs", type=int, default=0, help="cut the link this many times")
    ap.add_argument("--cable-out-s", type=float, default=2.0, help="each cut's length")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.seconds <= 0:
        print("--seconds must be positive", file=sys.stderr)
        return 2
    if args.loss_runs < 0 or args.cable_out_s <= 0:
        print("--loss-runs must be 0 or more and --cable-out-s positive", file=sys.stderr)
        return 2
    if os.geteuid() != 0:
        print("needs root: a veth pair and raw sockets", file=sys.stderr)
        return 2
    result = asyncio.run(measure(args.seconds, args.cycle_ms, args.loss_runs, args.cable_out_s))
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for k, v in result.items():
            print(f"{k:32} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
