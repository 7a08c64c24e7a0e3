"""SDO reads per second against a simulated drive: servodesk's link vs a plain canopen loop.

Both clients read the same objects from the same simulated drive on a python-can virtual bus,
in alternating rounds within one process (plain, servodesk, plain, ...), so the ratio compares
like with like. The ratio is the median of the servodesk rounds over the median of the plain
rounds. On a shared machine single rounds swing widely, so the JSON also gives each servodesk
round against the plain rounds either side of it, the process CPU time per read (all threads:
client, bus threads and the simulated drive) and the load average. Prints a summary, or JSON
with ``--json``.

The servodesk side runs on the event loop ``servodesk serve`` runs on: uvicorn takes uvloop
when it is installed (it is a dependency on Linux and macOS), so that is the default here;
``--loop asyncio`` measures the standard library's loop.

    python bench/bench_sdo.py [--rounds 5] [--seconds 1.0] [--loop uvloop|asyncio] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import time
from typing import Any

import canopen

try:
    import uvloop
except ImportError:  # Windows: servodesk serve runs on asyncio's own loop there.
    uvloop = None  # type: ignore[assignment]

from servodesk.domain.address import ObjectAddress
from servodesk.errors import LinkTimeoutError
from servodesk.links.base import LinkParams
from servodesk.links.canopen_link import CanopenLink
from servodesk.sim.bus import SimulatedBus

ADDRESSES = [(0x1000, 0), (0x6041, 0), (0x6064, 0), (0x1018, 1), (0x6081, 0)]


def run_loop(coro: Any, loop: str) -> Any:
    """Run ``coro`` on a fresh event loop of the chosen kind."""
    if loop == "uvloop":
        return uvloop.run(coro)
    return asyncio.run(coro)


SIDES = {
    "plain_canopen": "canopen RemoteNode.sdo.upload(index, subindex) in a tight loop in the "
    "calling thread (canopen's own SDO client: the answer is handed over from canopen's bus "
    "thread through a blocking queue)",
    "servodesk_link": "await CanopenLink.read(ObjectAddress) in a tight loop on an asyncio event "
    "loop (servodesk's public link API: per-node turn, time-out, abort mapping; the answer is "
    "handed over from canopen's bus thread to the loop)",
    "drive": "one simulated CiA 402 drive (servodesk sim, a canopen LocalNode, node 1) on a "
    "python-can virtual bus in the same process, stepped on the wall clock",
    "objects": "expedited uploads of " + ", ".join(f"{i:04X}h:{s}" for i, s in ADDRESSES),
}


class Round:
    """Reads per second, process CPU time per read and time-outs of one timed round.

    A read that times out (a machine so loaded that the drive's thread did not run for the
    client's whole time-out, twice) is counted on either side and not as a read.
    """

    def __init__(self) -> None:
        self.n = 0
        self.timeouts = 0
        self._t0 = time.perf_counter()
        self._c0 = time.process_time()

    def done(self) -> tuple[float, float, int]:
        wall, cpu = time.perf_counter() - self._t0, time.process_time() - self._c0
        return self.n / wall, cpu / max(self.n, 1) * 1e6, self.timeouts


def plain_canopen(channel: str, seconds: float) -> tuple[float, float, int]:
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    try:
        node = network.add_node(1, canopen.ObjectDictionary())
        end = time.perf_counter() + seconds
        r = Round()
        while time.perf_counter() < end:
            index, sub = ADDRESSES[(r.n + r.timeouts) % len(ADDRESSES)]
            try:
                node.sdo.upload(index, sub)
            except canopen.SdoCommunicationError:
                r.timeouts += 1
                continue
            r.n += 1
        return r.done()
    finally:
        network.disconnect()


async def servodesk_link(channel: str, seconds: float) -> tuple[float, float, int]:
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=1))
    await link.open()
    try:
        addrs = [ObjectAddress(i, s) for i, s in ADDRESSES]
        end = time.perf_counter() + seconds
        r = Round()
        while time.perf_counter() < end:
            try:
                await link.read(addrs[(r.n + r.timeouts) % len(addrs)])
            except LinkTimeoutError:
                r.timeouts += 1
                continue
            r.n += 1
        return r.done()
    finally:
        await link.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument(
        "--loop",
        choices=["uvloop", "asyncio"],
        default="uvloop" if uvloop is not None else "asyncio",
        help="event loop of the servodesk side (default: what servodesk serve uses)",
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.seconds <= 0:
        print("bench_sdo: --rounds must be >= 1 and --seconds > 0", file=sys.stderr)
        return 2
    if args.loop == "uvloop" and uvloop is None:
        print("bench_sdo: uvloop is not installed", file=sys.stderr)
        return 2
    channel = f"bench-sdo-{os.getpid()}"
    load_before = os.getloadavg()
    sim = SimulatedBus.start(drives=[("cia402-generic", 1)], interface="virtual", channel=channel)
    try:
        plain_runs: list[tuple[float, float, int]] = []
        our_runs: list[tuple[float, float, int]] = []
        plain_runs.append(plain_canopen(channel, args.seconds))  # Warm-up round, also measured.
        for _ in range(args.rounds):
            our_runs.append(run_loop(servodesk_link(channel, args.seconds), args.loop))
            plain_runs.append(plain_canopen(channel, args.seconds))
    finally:
        sim.stop()
    plain = [rate for rate, _, _ in plain_runs]
    ours = [rate for rate, _, _ in our_runs]
    # Each servodesk round against the mean of the plain rounds just before and after it.
    per_round = [ours[i] / ((plain[i] + plain[i + 1]) / 2) for i in range(len(ours))]
    result = {
        "benchmark": "sdo_reads",
        "sides": SIDES,
        "servodesk_event_loop": args.loop,
        "rounds": args.rounds,
        "seconds_per_round": args.seconds,
        "plain_canopen_reads_per_s_median": round(statistics.median(plain), 1),
        "servodesk_link_reads_per_s_median": round(statistics.median(ours), 1),
        "ratio": round(statistics.median(ours) / statistics.median(plain), 3),
        "plain_rounds": [round(x, 1) for x in plain],
        "servodesk_rounds": [round(x, 1) for x in ours],
        "ratio_per_round": [round(x, 3) for x in per_round],
        "plain_canopen_process_cpu_us_per_read_median": round(
            statistics.median(cpu for _, cpu, _ in plain_runs), 1
        ),
        "servodesk_link_process_cpu_us_per_read_median": round(
            statistics.median(cpu for _, cpu, _ in our_runs), 1
        ),
        "timeouts": {
            "plain_canopen": sum(t for _, _, t in plain_runs),
            "servodesk_link": sum(t for _, _, t in our_runs),
        },
        "load_average_1min": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "cpu_count": os.cpu_count(),
        "target_ratio": 0.9,
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"plain canopen   {result['plain_canopen_reads_per_s_median']:>9} reads/s (median)")
        print(f"servodesk link  {result['servodesk_link_reads_per_s_median']:>9} reads/s (median)")
        print(f"ratio           {result['ratio']:>9} (target >= 0.9)")
        print(f"per round       {result['ratio_per_round']}")
        print(f"load average    {result['load_average_1min']} (before, after)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
