"""PROFIdrive parameter reads per second against the simulated LECSN-T over PNIO-CM: servodesk's
PROFINET link vs a plain UDP client, one parameter at a time and batched.

All sides read the same objects in alternating rounds within one process:

- ``plain_pnio``: the same datagrams (domain/pnio.py, domain/profidrive.py) on a blocking UDP
  socket in a tight loop, one parameter request per object (a record write and a record
  read: two RPC round trips), no time-out handling, no turn, no error mapping: the floor.
- ``servodesk_profinet``: ``await ProfinetLink.read`` of one object at a time on the event loop
  ``servodesk serve`` runs on.
- ``servodesk_profinet_many``: ``await ProfinetLink.read_many`` of 39 objects (one parameter
  request of 39 parameters), as the Parameters page and the session's poll read: objects/s.

The ratios are servodesk's single reads over the plain client's, and the batched reads over
servodesk's single reads (medians). Prints a summary, or JSON with ``--json``.

    python bench/bench_profinet.py [--rounds 5] [--seconds 1.0] [--loop uvloop|asyncio] [--json]
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
import uuid
from typing import Any

try:
    import uvloop
except ImportError:  # Windows: servodesk serve runs on asyncio's own loop there.
    uvloop = None  # type: ignore[assignment]

from servodesk.domain import pnio
from servodesk.domain import profidrive as pd
from servodesk.domain.address import ObjectAddress
from servodesk.links.base import LinkParams
from servodesk.links.profinet_link import ProfinetLink
from servodesk.sim.bus import SimulatedBus

ADDRESSES = [(0x6041, 0), (0x6064, 0), (0x606C, 0), (0x6081, 0), (0x6083, 0)]
SIDES = {
    "plain_pnio": "one PROFIdrive read request per object as record write + record read on a "
    "blocking UDP socket in a tight loop (the floor)",
    "servodesk_profinet": "await ProfinetLink.read(ObjectAddress) on the event loop (turn, "
    "time-out, resend, AR check, error mapping)",
    "servodesk_profinet_many": "await ProfinetLink.read_many of 39 objects: one request of 39 "
    "parameters (objects per second)",
    "device": "one simulated LECSN-T (sim/profinet_device.py on 127.0.0.1 UDP) in this process, "
    "stepped on the wall clock",
}


def run_loop(coro: Any, loop: str) -> Any:
    if loop == "uvloop":
        return uvloop.run(coro)
    return asyncio.run(coro)


def plain_pnio(channel: str, seconds: float) -> float:
    host, port = pnio.parse_channel(channel)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.connect((host, port))
    sock.settimeout(1.0)
    activity, ar = uuid.uuid4(), uuid.uuid4()
    seq = 0

    def call(opnum: int, args: bytes) -> bytes:
        nonlocal seq
        seq += 1
        sock.send(
            pnio.build_rpc(
                pnio.RpcPacket(
                    pnio.PTYPE_REQUEST,
                    opnum,
                    pnio.object_uuid(0, 0),
                    pnio.DEVICE_INTERFACE,
                    activity,
                    seq,
                    pnio.request_body(args, pnio.MAX_DATAGRAM),
                )
            )
        )
        return sock.recv(65535)

    connect = pnio.ArRequest(ar, 1, bytes(6), pnio.object_uuid(0, 0), "bench")
    call(pnio.OP_CONNECT, pnio.ar_block_req(connect))
    where = pnio.RecordAddress(1, 1, pnio.INDEX_PARAMETER_ACCESS)
    read_args = pnio.record_request(pnio.BLOCK_READ_REQ, pnio.RecordHeader(1, ar, where, 240))
    writes = []
    for n, (i, s) in enumerate(ADDRESSES):
        req = pd.build_request(
            pd.Request(n + 1, pd.REQUEST_READ, 1, (pd.parameter_for(i, s, array=False),))
        )
        head = pnio.RecordHeader(1, ar, where, len(req))
        writes.append(pnio.record_request(pnio.BLOCK_WRITE_REQ, head) + req)
    try:
        n = 0
        t0 = time.perf_counter()
        end = t0 + seconds
        while time.perf_counter() < end:
            call(pnio.OP_WRITE, writes[n % len(writes)])
            call(pnio.OP_READ, read_args)
            n += 1
        return n / (time.perf_counter() - t0)
    finally:
        release = pnio.release_block(pnio.BLOCK_RELEASE_REQ, ar, 1, pnio.CONTROL_RELEASE)
        call(pnio.OP_RELEASE, release)
        sock.close()


async def link_reads(channel: str, seconds: float, many: bool) -> float:
    link = ProfinetLink(LinkParams(interface="profinet", channel=channel, node_id=1))
    await link.open()
    try:
        addrs = [ObjectAddress(i, s) for i, s in ADDRESSES]
        batch = [addrs[k % len(addrs)] for k in range(pd.MAX_PARAMETERS)]
        await link.read_many(addrs)  # Learn the shapes, as a session's first poll does.
        n = 0
        t0 = time.perf_counter()
        end = t0 + seconds
        while time.perf_counter() < end:
            if many:
                got = await link.read_many(batch)
                n += sum(isinstance(g, bytes) for g in got)
            else:
                await link.read(addrs[n % len(addrs)])
                n += 1
        return n / (time.perf_counter() - t0)
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
        print("bench_profinet: --rounds must be >= 1 and --seconds > 0", file=sys.stderr)
        return 2
    if args.loop == "uvloop" and uvloop is None:
        print("bench_profinet: uvloop is not installed", file=sys.stderr)
        return 2
    load_before = os.getloadavg()
    sim = SimulatedBus.start(drives=[("lecsn-t", 1)], interface="profinet", channel="127.0.0.1:0")
    where = sim.profinet[0].channel
    plain: list[float] = []
    ours: list[float] = []
    many: list[float] = []
    try:
        for _ in range(args.rounds):
            plain.append(plain_pnio(where, args.seconds))
            ours.append(run_loop(link_reads(where, args.seconds, False), args.loop))
            many.append(run_loop(link_reads(where, args.seconds, True), args.loop))
    finally:
        sim.stop()
    med = {k: statistics.median(v) for k, v in (("p", plain), ("o", ours), ("m", many))}
    result = {
        "benchmark": "profinet_reads",
        "sides": SIDES,
        "servodesk_event_loop": args.loop,
        "rounds": args.rounds,
        "seconds_per_round": args.seconds,
        "plain_pnio_reads_per_s_median": round(med["p"], 1),
        "servodesk_profinet_reads_per_s_median": round(med["o"], 1),
        "servodesk_profinet_many_objects_per_s_median": round(med["m"], 1),
        "ratio_link_to_plain": round(med["o"] / med["p"], 3),
        "ratio_many_to_single": round(med["m"] / med["o"], 2),
        "round_trip_us_median": {
            "plain_pnio": round(1e6 / med["p"], 1),
            "servodesk_profinet": round(1e6 / med["o"], 1),
            "servodesk_profinet_many_per_object": round(1e6 / med["m"], 1),
        },
        "plain_rounds": [round(x, 1) for x in plain],
        "servodesk_rounds": [round(x, 1) for x in ours],
        "servodesk_many_rounds": [round(x, 1) for x in many],
        "load_average_1min": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "cpu_count": os.cpu_count(),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"plain PNIO            {result['plain_pnio_reads_per_s_median']:>9} reads/s")
        print(f"servodesk PROFINET    {result['servodesk_profinet_reads_per_s_median']:>9} reads/s")
        print(
            f"servodesk read_many   {result['servodesk_profinet_many_objects_per_s_median']:>9}"
            " objects/s"
        )
        print(f"ratio link / plain    {result['ratio_link_to_plain']:>9}")
        print(f"ratio many / single   {result['ratio_many_to_single']:>9}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
