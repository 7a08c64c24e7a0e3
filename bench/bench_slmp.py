"""SLMP object reads per second against a simulated CC-Link IE TSN station: servodesk's SLMP
link vs a plain UDP client, and vs servodesk's CANopen link on the same drive model.

All three read the same objects in alternating rounds within one process (plain SLMP,
servodesk SLMP, servodesk CANopen, plain SLMP, ...):

- ``plain_slmp``: the same 4E frames (domain/slmp.py) sent and received on a blocking UDP
  socket in a tight loop, no time-out handling, no turn, no error mapping: the floor.
- ``servodesk_slmp``: ``await SlmpLink.read`` on the event loop ``servodesk serve`` runs on.
- ``servodesk_canopen``: ``await CanopenLink.read`` of the same objects from a CTMM04x twin on
  a python-can virtual bus (what ``serve --sim`` used before the SLMP link).

The session polls its drive's state over whichever link it has (20 Hz, a handful of objects),
so the link's round trip bounds how fresh the pages are. The ratio is servodesk's SLMP reads
per second over the plain client's (medians). Prints a summary, or JSON with ``--json``.

    python bench/bench_slmp.py [--rounds 5] [--seconds 1.0] [--loop uvloop|asyncio] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import statistics
import sys
import time
from typing import Any

try:
    import uvloop
except ImportError:  # Windows: servodesk serve runs on asyncio's own loop there.
    uvloop = None  # type: ignore[assignment]

from servodesk.domain import slmp
from servodesk.domain.address import ObjectAddress
from servodesk.errors import LinkTimeoutError
from servodesk.links.base import DriveLink, LinkParams
from servodesk.links.canopen_link import CanopenLink
from servodesk.links.slmp_link import SlmpLink
from servodesk.sim.bus import SimulatedBus

ADDRESSES = [(0x1000, 0), (0x6041, 0), (0x6064, 0), (0x1018, 1), (0x6081, 0)]
SIDES = {
    "plain_slmp": "4E SDO Upload frames on a blocking UDP socket in a tight loop (the floor)",
    "servodesk_slmp": "await SlmpLink.read(ObjectAddress) on the event loop (turn, time-out, "
    "serial check, error mapping)",
    "servodesk_canopen": "await CanopenLink.read(ObjectAddress) of the same objects from a "
    "CTMM04x twin on a python-can virtual bus",
    "station": "one simulated CTMM04x axis (sim/slmp_station.py on 127.0.0.1 UDP) and one on a "
    "virtual CAN bus, in this process, stepped on the wall clock",
}


def run_loop(coro: Any, loop: str) -> Any:
    if loop == "uvloop":
        return uvloop.run(coro)
    return asyncio.run(coro)


def plain_slmp(channel: str, seconds: float) -> float:
    host, port = slmp.parse_channel(channel)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.connect((host, port))
    sock.settimeout(1.0)
    frames = [
        slmp.build_request(
            n, slmp.Route(), slmp.CMD_OBJECT, slmp.SUB_UPLOAD, slmp.upload_data(i, s)
        )
        for n, (i, s) in enumerate(ADDRESSES)
    ]
    try:
        n = 0
        t0 = time.perf_counter()
        end = t0 + seconds
        while time.perf_counter() < end:
            sock.send(frames[n % len(frames)])
            sock.recv(slmp.MAX_FRAME)
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        sock.close()


async def link_reads(link: DriveLink, seconds: float) -> tuple[float, int]:
    await link.open()
    try:
        addrs = [ObjectAddress(i, s) for i, s in ADDRESSES]
        n = timeouts = 0
        t0 = time.perf_counter()
        end = t0 + seconds
        while time.perf_counter() < end:
            try:
                await link.read(addrs[(n + timeouts) % len(addrs)])
            except LinkTimeoutError:
                timeouts += 1
                continue
            n += 1
        return n / (time.perf_counter() - t0), timeouts
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
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.seconds <= 0:
        print("bench_slmp: --rounds must be >= 1 and --seconds > 0", file=sys.stderr)
        return 2
    if args.loop == "uvloop" and uvloop is None:
        print("bench_slmp: uvloop is not installed", file=sys.stderr)
        return 2
    can_channel = f"bench-slmp-{os.getpid()}"
    load_before = os.getloadavg()
    station = SimulatedBus.start(drives=[("ctmm04x", 1)], interface="slmp", channel="127.0.0.1:0")
    can = SimulatedBus.start(drives=[("ctmm04x", 1)], interface="virtual", channel=can_channel)
    assert station.station is not None
    where = station.station.channel
    plain: list[float] = []
    ours: list[float] = []
    canopen: list[float] = []
    timeouts = {"servodesk_slmp": 0, "servodesk_canopen": 0}
    try:
        for _ in range(args.rounds):
            plain.append(plain_slmp(where, args.seconds))
            link = SlmpLink(LinkParams(interface="slmp", channel=where, node_id=1))
            rate, t = run_loop(link_reads(link, args.seconds), args.loop)
            ours.append(rate)
            timeouts["servodesk_slmp"] += t
            co = CanopenLink(LinkParams(interface="virtual", channel=can_channel, node_id=1))
            rate, t = run_loop(link_reads(co, args.seconds), args.loop)
            canopen.append(rate)
            timeouts["servodesk_canopen"] += t
    finally:
        station.stop()
        can.stop()
    result = {
        "benchmark": "slmp_reads",
        "sides": SIDES,
        "servodesk_event_loop": args.loop,
        "rounds": args.rounds,
        "seconds_per_round": args.seconds,
        "plain_slmp_reads_per_s_median": round(statistics.median(plain), 1),
        "servodesk_slmp_reads_per_s_median": round(statistics.median(ours), 1),
        "servodesk_canopen_reads_per_s_median": round(statistics.median(canopen), 1),
        "ratio_slmp_link_to_plain": round(statistics.median(ours) / statistics.median(plain), 3),
        "ratio_slmp_link_to_canopen_link": round(
            statistics.median(ours) / statistics.median(canopen), 3
        ),
        "round_trip_us_median": {
            "plain_slmp": round(1e6 / statistics.median(plain), 1),
            "servodesk_slmp": round(1e6 / statistics.median(ours), 1),
            "servodesk_canopen": round(1e6 / statistics.median(canopen), 1),
        },
        "plain_rounds": [round(x, 1) for x in plain],
        "servodesk_slmp_rounds": [round(x, 1) for x in ours],
        "servodesk_canopen_rounds": [round(x, 1) for x in canopen],
        "timeouts": timeouts,
        "load_average_1min": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "cpu_count": os.cpu_count(),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        rt = result["round_trip_us_median"]
        assert isinstance(rt, dict)
        print(f"plain SLMP        {result['plain_slmp_reads_per_s_median']:>9} reads/s (median)")
        print(f"servodesk SLMP    {result['servodesk_slmp_reads_per_s_median']:>9} reads/s")
        print(f"servodesk CANopen {result['servodesk_canopen_reads_per_s_median']:>9} reads/s")
        print(f"ratio to plain    {result['ratio_slmp_link_to_plain']:>9}")
        print(f"round trip (us)   {rt}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
