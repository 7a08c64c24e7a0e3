"""EtherCAT process data cycles over a simulated line: servodesk's cyclic transport vs a plain
pysoem loop on the same master, and the period servodesk's cycle thread holds at 1 ms.

A HIWIN E twin (its ESC in a process of its own, sim/ethercat_slave.py) is slave 1 of a line
on one end of a veth pair, mapped and in OP (13 output and 23 input bytes, one LRW a cycle).
In alternating rounds within one process:

- ``plain_pysoem``: ``send_processdata`` + ``receive_processdata`` in a tight loop: the floor.
- ``servodesk``: ``EthercatCyclic.send_sync`` in a tight loop (the master's lock, the outputs
  copied in, the inputs handed to a subscriber), what each cycle of the cycle thread runs.

Then ``paced_1ms``: the cyclic exchange's own cycle thread (services/cyclic.py SyncProducer)
at a 1 ms period for ``--seconds``: cycles per second, median and 99th percentile interval
between the inputs' arrivals. Then the same slave in DC mode (SYNC0 at 1 ms, docs/ethercat.md
"Synchronisation": each exchange also carries the drift control datagram, FRMW of the system
time): ``servodesk_dc`` in alternating rounds with FreeRun ones of the same process, its
ratio to them, and ``paced_1ms_dc``. Needs root. Prints a summary, or JSON with ``--json``.

    python bench/bench_ethercat_pd.py [--rounds 5] [--seconds 1.0] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import time
from typing import Any

import numpy as np

from servodesk.links.base import LinkParams
from servodesk.links.ethercat_cyclic import EthercatCyclic
from servodesk.links.ethercat_link import EthercatLink
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import create_veth


def plain(link: EthercatLink, seconds: float) -> float:
    shared, _ = link._master()
    master = shared.master
    n = 0
    t0 = time.perf_counter()
    end = t0 + seconds
    while time.perf_counter() < end:
        master.send_processdata()
        master.receive_processdata(2000)
        n += 1
    return n / (time.perf_counter() - t0)


def ours(transport: EthercatCyclic, seconds: float) -> float:
    n = 0
    t0 = time.perf_counter()
    end = t0 + seconds
    while time.perf_counter() < end:
        transport.send(0x201, b"\x00" * 13)
        transport.send_sync()
        n += 1
    return n / (time.perf_counter() - t0)


def paced(transport: EthercatCyclic, seconds: float, period: float = 0.001) -> dict[str, float]:
    """The cycle loop of services/cyclic.py SyncProducer, on its own, at ``period``."""
    arrivals: list[float] = []
    missed = transport.missed
    transport.subscribe(0x181, lambda data, t: arrivals.append(t))
    next_t = time.perf_counter()
    end = next_t + seconds
    while time.perf_counter() < end:
        transport.send_sync()
        next_t += period
        delay = next_t - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    d = np.diff(np.array(arrivals))
    return {
        "cycles_per_s": len(arrivals) / seconds,
        "interval_median_ms": float(np.median(d) * 1000),
        "interval_p99_ms": float(np.percentile(d, 99) * 1000),
        "missed_wkc": float(transport.missed - missed),
    }


async def main(rounds: int, seconds: float) -> dict[str, Any]:
    with create_veth("sdbp") as pair:
        sim = SimulatedBus.start(drives=[("hiwin-e", 1)], interface="ethercat", channel=pair.slave)
        try:
            link = EthercatLink(
                LinkParams(interface="ethercat", channel=pair.master, node_id=1, timeout=0.5)
            )
            await link.open()
            try:
                await link.nmt("start")  # config_map, SAFE-OP, OP
                transport = EthercatCyclic(link)
                transport.subscribe(0x181, lambda data, t: None)
                p_runs, s_runs = [], []
                for _ in range(rounds):
                    p_runs.append(plain(link, seconds))
                    s_runs.append(ours(transport, seconds))
                pacing = paced(transport, seconds)
                # DC SYNC0 at 1 ms, against FreeRun rounds taken alternately (the slave goes
                # back to PRE-OP for each change of synchronisation).
                f_runs, d_runs = [], []
                for _ in range(rounds):
                    for mode, runs in (("freerun", f_runs), ("dc", d_runs)):
                        link.configure_sync(mode, 0.001)
                        await link.nmt("start")
                        runs.append(ours(transport, seconds))
                link.configure_sync("dc", 0.001)
                await link.nmt("start")
                pacing_dc = paced(transport, seconds)
                await link.nmt("preop")
            finally:
                await link.close()
        finally:
            sim.stop()
    p, s = statistics.median(p_runs), statistics.median(s_runs)
    f, d = statistics.median(f_runs), statistics.median(d_runs)
    return {
        "benchmark": "ethercat_process_data",
        "rounds": rounds,
        "seconds_per_round": seconds,
        "load_1min": os.getloadavg()[0],
        "plain_pysoem": {"cycles_per_s": p, "us_per_cycle": 1e6 / p, "runs": p_runs},
        "servodesk": {"cycles_per_s": s, "us_per_cycle": 1e6 / s, "runs": s_runs},
        "ratio_servodesk_to_plain": s / p,
        "paced_1ms": pacing,
        "servodesk_freerun": {"cycles_per_s": f, "us_per_cycle": 1e6 / f, "runs": f_runs},
        "servodesk_dc": {"cycles_per_s": d, "us_per_cycle": 1e6 / d, "runs": d_runs},
        "ratio_dc_to_freerun": d / f,
        "paced_1ms_dc": pacing_dc,
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    out = asyncio.run(main(a.rounds, a.seconds))
    if a.json:
        print(json.dumps(out, indent=2))
    else:
        print(
            f"plain pysoem {out['plain_pysoem']['cycles_per_s']:.0f} cycles/s, servodesk "
            f"{out['servodesk']['cycles_per_s']:.0f} cycles/s "
            f"(ratio {out['ratio_servodesk_to_plain']:.2f}); paced at 1 ms: {out['paced_1ms']}"
        )
        print(
            f"DC SYNC0 {out['servodesk_dc']['cycles_per_s']:.0f} cycles/s, FreeRun "
            f"{out['servodesk_freerun']['cycles_per_s']:.0f} (ratio "
            f"{out['ratio_dc_to_freerun']:.2f}); paced at 1 ms in DC: {out['paced_1ms_dc']}"
        )
