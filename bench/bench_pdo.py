"""PDO remap time and cyclic data throughput (issue 6 "Measure").

1. Full remap of 4 TPDOs and 4 RPDOs of the simulated ``cia402-generic`` drive on a python-can
   virtual bus, alternating between two complete layouts: servodesk's apply (plan, writes,
   read-back verification, progress) against a plain canopen script sending the same plan's
   writes with ``sdo.download`` and no verification (the baseline), same process, alternating.
2. Cyclic data at a 1 ms SYNC: the simulated drive in its own process (``servodesk sim`` over
   ``udp_multicast``), the session in this one; frames received and decoded per second by the
   session, SYNCs sent, and this process's CPU (process time / wall time) while exchanging
   against the same session idle (no cyclic data) as the baseline.

    python bench/bench_pdo.py [--rounds 5] [--seconds 5] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import canopen

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from servodesk.domain import pdo as pdomod
from servodesk.domain.datatypes import codec, coerce_int
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.services import pdo as pdosvc
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.sim.bus import SimulatedBus

PROFILE = "cia402-generic"

# Two complete layouts (all 8 PDOs change between them): 64 bits each where possible.
LAYOUT_A = {
    "pdos": [
        {"direction": "rx", "number": 1, "entries": ["0x6040:00", "0x607A:00"]},
        {"direction": "rx", "number": 2, "entries": ["0x6040:00", "0x60FF:00"]},
        {"direction": "rx", "number": 3, "entries": ["0x6040:00", "0x6071:00"]},
        {"direction": "rx", "number": 4, "entries": ["0x6040:00", "0x6060:00"]},
        {"direction": "tx", "number": 1, "entries": ["0x6041:00", "0x6064:00"]},
        {"direction": "tx", "number": 2, "entries": ["0x6041:00", "0x606C:00"]},
        {"direction": "tx", "number": 3, "entries": ["0x6041:00", "0x6077:00"]},
        {"direction": "tx", "number": 4, "entries": ["0x6041:00", "0x6061:00"]},
    ]
}
LAYOUT_B = {
    "pdos": [
        {"direction": "rx", "number": 1, "entries": ["0x607A:00", "0x6040:00"]},
        {"direction": "rx", "number": 2, "entries": ["0x60FF:00", "0x6040:00"]},
        {"direction": "rx", "number": 3, "entries": ["0x6071:00", "0x6040:00"]},
        {"direction": "rx", "number": 4, "entries": ["0x6060:00", "0x6040:00"]},
        {"direction": "tx", "number": 1, "entries": ["0x6064:00", "0x6041:00"]},
        {"direction": "tx", "number": 2, "entries": ["0x606C:00", "0x6041:00"]},
        {"direction": "tx", "number": 3, "entries": ["0x6077:00", "0x6041:00"]},
        {"direction": "tx", "number": 4, "entries": ["0x6061:00", "0x6041:00"]},
    ]
}


def plain_apply(channel: str, node_id: int, steps: tuple[pdomod.PdoStep, ...]) -> float:
    """The same writes with a plain canopen client (no verification): seconds."""
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    try:
        node = canopen.RemoteNode(node_id, canopen.ObjectDictionary())
        network.add_node(node)
        names = {"preop": "PRE-OPERATIONAL", "start": "OPERATIONAL", "stop": "STOPPED"}
        t0 = time.perf_counter()
        for s in steps:
            if s.kind == "nmt":
                assert s.command is not None
                node.nmt.state = names[s.command]
                time.sleep(pdosvc.NMT_SETTLE_S)
            else:
                assert s.address is not None and s.data_type is not None
                data = codec(s.data_type).encode(coerce_int(s.value, s.data_type))
                node.sdo.download(s.address.index, s.address.subindex, data)
        return time.perf_counter() - t0
    finally:
        network.disconnect()


async def bench_remap(rounds: int) -> dict[str, Any]:
    channel = f"bench-pdo-{os.getpid()}"
    catalog = ProfileCatalog()
    bus = SimulatedBus.start([(PROFILE, 1)], channel=channel, catalog=catalog)
    manager = SessionManager(catalog, EventHub(), sdo_timeout=1.0, poll_hz=1.0)
    ours: list[float] = []
    plain: list[float] = []
    steps_n = 0
    try:
        session = await manager.open(
            LinkParams(interface="virtual", channel=channel, node_id=1), PROFILE, simulated=True
        )
        for i in range(rounds):
            for layout in (LAYOUT_A, LAYOUT_B):
                t0 = time.perf_counter()
                rep = await pdosvc.apply(session, layout, dry_run=False)
                ours.append(time.perf_counter() - t0)
                if not rep["ok"]:
                    raise RuntimeError(f"apply failed: {rep['error']}")
                steps_n = len(rep["steps"])
            # Baseline: the plan from B back to A and A to B, sent by plain canopen.
            for layout in (LAYOUT_A, LAYOUT_B):
                plan = await pdosvc.make_plan(session, layout)
                plain.append(await asyncio.to_thread(plain_apply, channel, 1, plan.steps))
            del i
    finally:
        await manager.close_all()
        bus.stop()
    med_o, med_p = statistics.median(ours), statistics.median(plain)
    return {
        "what": "full remap of 4 RPDOs + 4 TPDOs, cia402-generic twin, virtual bus",
        "steps": steps_n,
        "servodesk_apply_s": {
            "median": round(med_o, 4),
            "min": round(min(ours), 4),
            "max": round(max(ours), 4),
            "n": len(ours),
        },
        "plain_canopen_writes_s": {
            "median": round(med_p, 4),
            "min": round(min(plain), 4),
            "max": round(max(plain), 4),
            "n": len(plain),
        },
        "ratio_servodesk_over_plain": round(med_o / med_p, 2),
        "note": "servodesk also reads the configuration before and verifies it after",
    }


async def bench_cyclic(seconds: float, period_ms: float) -> dict[str, Any]:
    from tests.simproc import sim_subprocess

    channel = f"239.74.{os.getpid() % 250}.{(os.getpid() >> 8) % 250 + 1}"
    interface = "udp_multicast"
    with sim_subprocess(PROFILE, 1, interface, channel):
        catalog = ProfileCatalog()
        manager = SessionManager(catalog, EventHub(), sdo_timeout=1.0, poll_hz=1.0)
        try:
            session = await manager.open(
                LinkParams(interface=interface, channel=channel, node_id=1), PROFILE
            )
            await pdosvc.apply(session, LAYOUT_A, dry_run=False)
            # Every TPDO on every SYNC (type 1).
            await pdosvc.apply(
                session,
                {
                    "pdos": [
                        {"direction": "tx", "number": n, "transmission_type": 1}
                        for n in (1, 2, 3, 4)
                    ]
                },
                dry_run=False,
            )
            c0, w0 = time.process_time(), time.perf_counter()
            await asyncio.sleep(seconds)
            idle_cpu = (time.process_time() - c0) / (time.perf_counter() - w0)
            await pdosvc.start_cyclic(session, period_ms, outputs=False)
            await asyncio.sleep(0.5)
            ex = session.cyclic
            assert ex is not None
            f0 = sum(ch.count for ch in ex.tx)
            s0 = ex.syncs
            e0 = sum(ch.errors for ch in ex.tx)
            c0, w0 = time.process_time(), time.perf_counter()
            await asyncio.sleep(seconds)
            wall = time.perf_counter() - w0
            cpu = (time.process_time() - c0) / wall
            frames = sum(ch.count for ch in ex.tx) - f0
            syncs = ex.syncs - s0
            errors = sum(ch.errors for ch in ex.tx) - e0
            await pdosvc.stop_cyclic(session)
        finally:
            await manager.close_all()
    return {
        "what": f"cyclic data, {period_ms} ms SYNC, 4 TPDOs of 6 bytes on every SYNC, "
        "drive in its own process over udp_multicast",
        "seconds": round(wall, 2),
        "syncs_per_s": round(syncs / wall, 1),
        "tpdos_decoded_per_s": round(frames / wall, 1),
        "tpdos_expected_per_s": round(4 * syncs / wall, 1),
        "decode_errors": errors,
        "backend_cpu_core_fraction": round(cpu, 3),
        "baseline_idle_cpu_core_fraction": round(idle_cpu, 3),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--period-ms", type=float, default=1.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out = {
        "load": os.getloadavg(),
        "remap": asyncio.run(bench_remap(args.rounds)),
        "cyclic": asyncio.run(bench_cyclic(args.seconds, args.period_ms)),
    }
    if args.json:
        json.dump(out, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        r, c = out["remap"], out["cyclic"]
        print(
            f"remap: servodesk {r['servodesk_apply_s']['median'] * 1000:.0f} ms, plain canopen "
            f"{r['plain_canopen_writes_s']['median'] * 1000:.0f} ms ({r['steps']} steps)"
        )
        print(
            f"cyclic: {c['tpdos_decoded_per_s']:.0f} TPDOs/s decoded of "
            f"{c['tpdos_expected_per_s']:.0f}, {c['syncs_per_s']:.0f} SYNC/s, CPU "
            f"{c['backend_cpu_core_fraction'] * 100:.0f} % of a core "
            f"(idle {c['baseline_idle_cpu_core_fraction'] * 100:.0f} %)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
