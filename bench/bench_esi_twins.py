"""Twins made from the vendor corpus's CiA 402 ESIs, checked over the wire (issue 46).

For each CiA 402 ESI of ../shared/corpus (Ingenia EVE-XCR-E, Elmo Gold (device 3), Inovance
IS620N, Synapticon single and multi, ETG ModulesSlots CiA402): ``servodesk sim --esi FILE`` on
one end of a veth pair and, on the other, whether the file imports, the profile ``servodesk
scan`` names and whether the identity is the ESI's, the objects a backup read of those it
tried, whether ``servodesk pdo show`` answers, whether the drive reached Operation enabled in
CSP through cyclic data and followed a ramped target (servodesk/benchmarks/esi_twins.py does
each step). Needs root. Prints a table, or JSON with ``--json``.

    python bench/bench_esi_twins.py [--corpus ../shared/corpus] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from servodesk.benchmarks.esi_twins import table
from servodesk.sim.veth import create_veth

COLUMNS = ("file", "import_ok", "scan_id", "backup", "pdo_show", "oe_csp", "follows", "s")


def main(corpus: Path) -> dict[str, Any]:
    t0 = time.monotonic()
    with create_veth("sdbe") as pair, tempfile.TemporaryDirectory() as tmp:
        rows = table(corpus, pair.master, pair.slave, Path(tmp))
    for r in rows:
        r["backup"] = f"{r.get('backup_read')}/{r.get('backup_readable')}"
    return {
        "benchmark": "esi_twins",
        "corpus": str(corpus),
        "load_1min": os.getloadavg()[0],
        "seconds": round(time.monotonic() - t0, 1),
        "all_ok": all(not r["errors"] for r in rows),
        "files": rows,
    }


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default = Path(__file__).resolve().parents[2] / "shared" / "corpus"
    ap.add_argument("--corpus", type=Path, default=default)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    out = main(a.corpus)
    if a.json:
        print(json.dumps(out, indent=2))
    else:
        print("  ".join(f"{c:>14}" for c in COLUMNS))
        for r in out["files"]:
            print("  ".join(f"{str(r.get(c))[:14]:>14}" for c in COLUMNS))
            for e in r["errors"]:
                print(f"    {e}")
        print(f"{out['seconds']} s, load {out['load_1min']:.2f}")
