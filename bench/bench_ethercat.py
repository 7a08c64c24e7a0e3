"""CoE SDO reads per second over a simulated EtherCAT line: servodesk's EtherCAT link vs a
plain pysoem loop on the same master interface.

A HIWIN E twin is slave 1 of a simulated line (sim/ethercat_slave.py, its ESC in a process of
its own) on one end of a veth pair; both clients read the same objects on the other end, in
alternating rounds within one process (plain, servodesk, plain, ...):

- ``plain_pysoem``: ``slave.sdo_read(index, sub)`` of a pysoem master in a tight loop (SOEM's
  own CoE client, blocking): the floor.
- ``servodesk_ethercat``: ``await EthercatLink.read(ObjectAddress)`` on the event loop (a worker
  thread per request, the link's turn and lock, abort mapping).

Needs root (CAP_NET_ADMIN for the pair, CAP_NET_RAW for SOEM). Prints a summary, or JSON with
``--json``.

    python bench/bench_ethercat.py [--rounds 5] [--seconds 1.0] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import time

import pysoem

from servodesk.domain.address import ObjectAddress
from servodesk.errors import ServodeskError
from servodesk.links.base import LinkParams
from servodesk.links.ethercat_link import EthercatLink
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import create_veth

ADDRESSES = [(0x1000, 0), (0x6041, 0), (0x6064, 0), (0x1018, 1), (0x6081, 0)]


def plain_pysoem(nic: str, seconds: float) -> float:
    master = pysoem.Master()
    # The drives' CoE servers answer from a thread of this process (the ESCs run in their
    # own): the SOEM calls must release the GIL, as the link's do.
    master.always_release_gil = True
    master.open(nic)
    try:
        if master.config_init(release_gil=True) < 1:
            raise RuntimeError(f"no slave on {nic}")
        slave = master.slaves[0]
        n = 0
        t0 = time.perf_counter()
        end = t0 + seconds
        while time.perf_counter() < end:
            index, sub = ADDRESSES[n % len(ADDRESSES)]
            slave.sdo_read(index, sub)
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        master.close()


async def link_reads(nic: str, seconds: float) -> float:
    link = EthercatLink(LinkParams(interface="ethercat", channel=nic, node_id=1, timeout=1.0))
    await link.open()
    try:
        addrs = [ObjectAddress(i, s) for i, s in ADDRESSES]
        n = 0
        t0 = time.perf_counter()
        end = t0 + seconds
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
        print("bench_ethercat: --rounds must be >= 1 and --seconds > 0", file=sys.stderr)
        return 2
    load_before = os.getloadavg()
    plain: list[float] = []
    ours: list[float] = []
    try:
        with (
            create_veth("sdbench") as pair,
            SimulatedBus.start(drives=[("hiwin-e", 1)], interface="ethercat", channel=pair.slave),
        ):
            for _ in range(args.rounds):
                plain.append(plain_pysoem(pair.master, args.seconds))
                ours.append(asyncio.run(link_reads(pair.master, args.seconds)))
    except ServodeskError as exc:
        print(f"bench_ethercat: {exc.message}", file=sys.stderr)
        if exc.hint:
            print(f"  hint: {exc.hint}", file=sys.stderr)
        return 2
    result = {
        "benchmark": "ethercat_sdo_reads",
        "rounds": args.rounds,
        "seconds_per_round": args.seconds,
        "plain_pysoem_reads_per_s_median": round(statistics.median(plain), 1),
        "servodesk_ethercat_reads_per_s_median": round(statistics.median(ours), 1),
        "ratio": round(statistics.median(ours) / statistics.median(plain), 3),
        "round_trip_us_median": {
            "plain_pysoem": round(1e6 / statistics.median(plain), 1),
            "servodesk_ethercat": round(1e6 / statistics.median(ours), 1),
        },
        "plain_rounds": [round(x, 1) for x in plain],
        "servodesk_rounds": [round(x, 1) for x in ours],
        "load_average_1min": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "cpu_count": os.cpu_count(),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"plain pysoem        {result['plain_pysoem_reads_per_s_median']:>9} reads/s")
        print(f"servodesk EtherCAT  {result['servodesk_ethercat_reads_per_s_median']:>9} reads/s")
        print(f"ratio               {result['ratio']:>9}")
        print(f"round trip (us)     {result['round_trip_us_median']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
