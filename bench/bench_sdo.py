"""SDO reads per second against a simulated drive: servodesk's link vs a plain canopen loop.

Both clients read the same objects from the same simulated drive on a python-can virtual bus,
in alternating rounds within one process (plain, servodesk, plain, ...), so the ratio compares
like with like. Prints a summary, or JSON with ``--json``.

    python bench/bench_sdo.py [--rounds 5] [--seconds 1.0] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import time

import canopen

from servodesk.domain.address import ObjectAddress
from servodesk.links.base import LinkParams
from servodesk.links.canopen_link import CanopenLink
from servodesk.sim.bus import SimulatedBus

ADDRESSES = [(0x1000, 0), (0x6041, 0), (0x6064, 0), (0x1018, 1), (0x6081, 0)]


def plain_canopen(channel: str, seconds: float) -> float:
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    try:
        node = network.add_node(1, canopen.ObjectDictionary())
        n, end = 0, time.perf_counter() + seconds
        t0 = time.perf_counter()
        while time.perf_counter() < end:
            index, sub = ADDRESSES[n % len(ADDRESSES)]
            node.sdo.upload(index, sub)
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        network.disconnect()


async def servodesk_link(channel: str, seconds: float) -> float:
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=1))
    await link.open()
    try:
        addrs = [ObjectAddress(i, s) for i, s in ADDRESSES]
        n, end = 0, time.perf_counter() + seconds
        t0 = time.perf_counter()
        while time.perf_counter() < end:
            await link.read(addrs[n % len(addrs)])
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        await link.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.seconds <= 0:
        print("bench_sdo: --rounds must be >= 1 and --seconds > 0", file=sys.stderr)
        return 2
    channel = f"bench-sdo-{os.getpid()}"
    sim = SimulatedBus.start(drives=[("cia402-generic", 1)], interface="virtual", channel=channel)
    try:
        plain: list[float] = []
        ours: list[float] = []
        plain.append(plain_canopen(channel, args.seconds))  # Warm-up round, also measured.
        for _ in range(args.rounds):
            ours.append(asyncio.run(servodesk_link(channel, args.seconds)))
            plain.append(plain_canopen(channel, args.seconds))
    finally:
        sim.stop()
    result = {
        "benchmark": "sdo_reads",
        "rounds": args.rounds,
        "seconds_per_round": args.seconds,
        "plain_canopen_reads_per_s_median": round(statistics.median(plain), 1),
        "servodesk_link_reads_per_s_median": round(statistics.median(ours), 1),
        "ratio": round(statistics.median(ours) / statistics.median(plain), 3),
        "plain_rounds": [round(x, 1) for x in plain],
        "servodesk_rounds": [round(x, 1) for x in ours],
        "target_ratio": 0.9,
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"plain canopen   {result['plain_canopen_reads_per_s_median']:>9} reads/s (median)")
        print(f"servodesk link  {result['servodesk_link_reads_per_s_median']:>9} reads/s (median)")
        print(f"ratio           {result['ratio']:>9} (target >= 0.9)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
