"""EtherCAT link loss during cyclic data: how long until servodesk says "link lost", and how
long after the link returns until the line is back in OP (issue 46, "Link loss").

A HIWIN E twin (its ESC in a process of its own, sim/ethercat_slave.py) is slave 1 of a line
on one end of a veth pair, mapped and in OP; a thread runs servodesk's process data cycle
(``EthercatCyclic.send_sync``, what the cyclic exchange's cycle thread runs) every
``--period-ms``. Each run pulls the cable (``ip link set <slave end> down``: the master's NIC
loses its carrier), waits for the line's health to say "link lost" (``lost_s``, from the
moment the command returned), keeps it down ``--down`` seconds (long enough for the drive's
SyncManager watchdog, 100 ms, to take it to SAFE-OP with error 001Bh), puts it up and waits
for the health to say "ok" with the slave in OP again (``back_s``, from the moment the
command returned). Needs root. Prints a summary, or JSON with ``--json``.

    python bench/bench_ethercat_link.py [--runs 20] [--down 2.0] [--period-ms 2] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import subprocess
import threading
import time
from typing import Any

from servodesk.links.base import LinkParams
from servodesk.links.ethercat_cyclic import EthercatCyclic
from servodesk.links.ethercat_health import LOST, OK, LineHealth
from servodesk.links.ethercat_link import EthercatLink
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import create_veth


def _cycles(transport: EthercatCyclic, period: float, stop: threading.Event) -> None:
    next_t = time.perf_counter()
    while not stop.is_set():
        transport.send(0x201, b"\x00" * 13)
        transport.send_sync()
        next_t += period
        delay = next_t - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        else:
            next_t = time.perf_counter()


def _until(ok: Any, timeout: float) -> float:
    t0 = time.monotonic()
    while not ok():
        if time.monotonic() - t0 > timeout:
            raise TimeoutError(f"not within {timeout} s")
        time.sleep(0.001)
    return time.monotonic() - t0


def _measure(
    nic: str, health: LineHealth, runs: int, down: float, lost: list[float], back: list[float]
) -> None:
    """The runs: the cable out and in, the times appended to ``lost`` and ``back``."""
    _until(lambda: health.state == OK and health.good_cycles > 50, 5)

    def in_op() -> bool:
        return health.state == OK and health.slave(0).al_state in ("op", None)

    for _ in range(runs):
        subprocess.run(["ip", "link", "set", nic, "down"], check=True)
        lost.append(_until(lambda: health.state == LOST, 5))
        time.sleep(down)
        subprocess.run(["ip", "link", "set", nic, "up"], check=True)
        back.append(_until(in_op, 10))
        time.sleep(0.2)


def _summary(values: list[float]) -> dict[str, float]:
    ordered = sorted(values)
    return {
        "median_s": statistics.median(ordered),
        "p95_s": ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))],
        "max_s": ordered[-1],
        "min_s": ordered[0],
    }


async def main(runs: int, down: float, period_ms: float) -> dict[str, Any]:
    lost: list[float] = []
    back: list[float] = []
    with create_veth("sdbl") as pair:
        sim = SimulatedBus.start(drives=[("hiwin-e", 1)], interface="ethercat", channel=pair.slave)
        try:
            link = EthercatLink(
                LinkParams(interface="ethercat", channel=pair.master, node_id=1, timeout=0.5)
            )
            await link.open()
            try:
                await link.nmt("start")  # config_map, SAFE-OP, OP
                transport = EthercatCyclic(link)
                health = link.line().health
                stop = threading.Event()
                thread = threading.Thread(
                    target=_cycles, args=(transport, period_ms / 1000, stop), daemon=True
                )
                thread.start()
                try:
                    _measure(pair.slave, health, runs, down, lost, back)
                finally:
                    stop.set()
                    thread.join(2)
                await link.nmt("preop")
            finally:
                await link.close()
        finally:
            sim.stop()
    return {
        "benchmark": "ethercat_link_loss",
        "runs": runs,
        "down_s": down,
        "period_ms": period_ms,
        "load_1min": os.getloadavg()[0],
        "time_to_link_lost": {**_summary(lost), "runs_s": lost},
        "time_back_to_op": {**_summary(back), "runs_s": back},
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--down", type=float, default=2.0)
    ap.add_argument("--period-ms", type=float, default=2.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    out = asyncio.run(main(a.runs, a.down, a.period_ms))
    if a.json:
        print(json.dumps(out, indent=2))
    else:
        lo, bk = out["time_to_link_lost"], out["time_back_to_op"]
        print(
            f"{a.runs} runs, link down {a.down:g} s, cycle {a.period_ms:g} ms: "
            f"'link lost' after {lo['median_s'] * 1000:.0f} ms median "
            f"({lo['max_s'] * 1000:.0f} ms max); back in OP {bk['median_s'] * 1000:.0f} ms "
            f"median ({bk['max_s'] * 1000:.0f} ms max) after the link returned"
        )
