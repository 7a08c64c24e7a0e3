"""A plant's backup: every drive read at once (``BackupService.backup_many``, ``POST
/backups/plant``) against one after the other, in the same process and round.

The five families' twins are nodes 1-5 of one python-can virtual bus (as bench_backup.py). Per
round: each drive backed up alone in turn (the sum is ``sequential_s``), then all five at once
(``concurrent_s``); ``speedup`` = sequential / concurrent of the same round, medians over
``--repeat`` rounds. The bus is shared: CAN interleaves the nodes' SDO transfers (each node
answers on its own channel), so what they gain is the time each node spends answering and
servodesk spends between transfers, not more bits per second. The five twins answer from
threads of this same process (the GIL), which a real plant's drives do not share.

    python bench/bench_backup_plant.py [--json] [--repeat 5] [--families a,b,c]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.services.backup import BackupService
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.session import Session
from servodesk.services.store import Store
from servodesk.sim.bus import SimulatedBus

FAMILIES = ["cia402-generic", "hiwin-e", "smartris", "ctmm04x", "lecsn-t"]


async def run(data_dir: Path, repeat: int, families: list[str]) -> dict[str, Any]:
    channel = f"bench-plant-{os.getpid()}"
    drives = [(pid, i + 1) for i, pid in enumerate(families)]
    catalog = ProfileCatalog()
    bus = SimulatedBus.start(drives, channel=channel, catalog=catalog)
    manager = SessionManager(catalog, EventHub(), sdo_timeout=1.0, poll_hz=1.0)
    backups = BackupService(Store(data_dir), catalog)
    rounds: list[dict[str, Any]] = []
    try:
        sessions: list[Session] = []
        for pid, node in drives:
            params = LinkParams(interface="virtual", channel=channel, node_id=node, timeout=1.0)
            sessions.append(await manager.open(params, pid))
        entries = 0
        for _ in range(repeat):
            each: dict[str, float] = {}
            for s in sessions:
                t0 = time.perf_counter()
                info = await backups.backup(s)
                each[s.id] = time.perf_counter() - t0
                entries += info["entries"] if not rounds else 0
            t0 = time.perf_counter()
            results = await backups.backup_many(sessions)
            concurrent = time.perf_counter() - t0
            failed = [str(r) for r in results if not isinstance(r, dict)]
            if failed:
                raise RuntimeError(f"a backup of the plant failed: {failed}")
            sequential = sum(each.values())
            rounds.append(
                {
                    "sequential_s": sequential,
                    "concurrent_s": concurrent,
                    "speedup": sequential / concurrent,
                    "longest_alone_s": max(each.values()),
                    "each_s": each,
                }
            )
    finally:
        await manager.close_all()
        bus.stop()
        backups.store.close()

    def med(key: str) -> float:
        return round(statistics.median(float(r[key]) for r in rounds), 3)

    return {
        "drives": len(families),
        "families": families,
        "entries": entries,
        "rounds": repeat,
        "sequential_s": med("sequential_s"),
        "concurrent_s": med("concurrent_s"),
        "speedup": med("speedup"),
        # The floor of "at once": the longest drive's backup alone (LECSN-T's 2,432 entries).
        "longest_alone_s": med("longest_alone_s"),
        "each_s": {
            sid: round(statistics.median(r["each_s"][sid] for r in rounds), 3)
            for sid in rounds[0]["each_s"]
        },
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--repeat", type=int, default=5, help="rounds; medians are reported")
    ap.add_argument(
        "--families",
        default=",".join(FAMILIES),
        help="profile ids, one node each in this order (a profile may repeat)",
    )
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    families = [f.strip() for f in args.families.split(",") if f.strip()]
    known = ProfileCatalog().ids()
    unknown = [f for f in families if f not in known]
    if len(families) < 2 or unknown:
        ap.error(f"--families: give at least two of {', '.join(known)} (unknown: {unknown})")
    with tempfile.TemporaryDirectory() as d:
        res = asyncio.run(run(Path(d), args.repeat, families))
    meta = {"python": sys.version.split()[0], "cpus": os.cpu_count(), **res}
    if args.json:
        json.dump(meta, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0
    print(
        f"{res['drives']} drives, {res['entries']} entries: one after the other "
        f"{res['sequential_s']} s, at once {res['concurrent_s']} s ({res['speedup']}x); "
        f"the longest alone {res['longest_alone_s']} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
