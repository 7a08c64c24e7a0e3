"""Compute time of the own tuning's design search, with and without the plant-response cache.

The design search (``search.tune_on_model``: the design, the margins of every variation on the
identification and stuck-load sets, the tick-by-tick ranking of the feasible ones) is what an
operator waits for between the test moves and the verification move. It runs here on the
exact models of some of the benchmark's plants, with the ranking simulation the service uses
(``sim/replay.ModelMoves``), in alternating rounds within one process: the baseline with
``model.RESPONSE_CACHE_SIZE = 0`` (every margin check solves the plant's frequency response
again), then with the cache, and so on. Each round clears the cache first, so a round pays
for its own solves. The ratio is the median of the cached rounds over the median of the
baseline rounds, per plant. Prints a summary, or JSON with ``--json``.

    python bench/bench_tuning_design.py [--rounds 3] [--plants R3-400Hz,R10-200Hz,R3-rigid] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from typing import Any

from servodesk.benchmarks.tuning import default_plants, exact_model, plant_names
from servodesk.domain.tuning import model as loop_model
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.search import tune_on_model
from servodesk.model.replay import ModelMoves

DEFAULT_PLANTS = "R3-400Hz,R10-200Hz,R30-800Hz,R3-rigid"


def one_run(name: str, cached: bool) -> tuple[float, int, ServoGains]:
    """Seconds of one design search on the plant's exact model, its feasible count and the
    gains it chose."""
    spec = dict(default_plants())[name]
    plant = exact_model(spec)
    rate = float(spec.loop_rate_hz)
    coulomb = spec.coulomb * spec.peak_torque
    loop_model.RESPONSE_CACHE_SIZE = 64 if cached else 0
    loop_model._responses.clear()
    rerank = ModelMoves.of(
        plant,
        rate,
        counts_per_rev=spec.encoder_counts,
        torque_limit=spec.peak_torque,
        coulomb=coulomb,
    )
    t0 = time.perf_counter()
    result = tune_on_model(
        plant,
        rate,
        "high",
        counts_per_rev=spec.encoder_counts,
        torque_limit=spec.peak_torque,
        coulomb=coulomb,
        rerank=rerank,
    )
    return time.perf_counter() - t0, result.feasible, result.gains


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="rounds of each kind per plant")
    ap.add_argument("--plants", default=DEFAULT_PLANTS, help="comma-separated plant names")
    ap.add_argument("--json", action="store_true", help="print JSON")
    args = ap.parse_args(argv)
    try:
        names = plant_names(args.plants)
        if args.rounds < 1:
            raise ValueError("--rounds must be >= 1")
    except ValueError as exc:
        print(f"bench_tuning_design: {exc}", file=sys.stderr)
        return 2
    size = loop_model.RESPONSE_CACHE_SIZE
    rows: list[dict[str, Any]] = []
    try:
        for name in names:
            base: list[float] = []
            fast: list[float] = []
            feasible = 0
            same = True
            for _ in range(args.rounds):
                s, feasible, g0 = one_run(name, cached=False)
                base.append(s)
                s, _, g1 = one_run(name, cached=True)
                fast.append(s)
                same = same and g0 == g1
            rows.append(
                {
                    "plant": name,
                    "feasible": feasible,
                    "same_gains": same,
                    "baseline_s": base,
                    "cached_s": fast,
                    "baseline_median_s": statistics.median(base),
                    "cached_median_s": statistics.median(fast),
                    "ratio": statistics.median(fast) / statistics.median(base),
                }
            )
    finally:
        loop_model.RESPONSE_CACHE_SIZE = size
    out = {
        "what": "own tuning's design search (search.tune_on_model with sim/replay.ModelMoves) "
        "on exact plant models; baseline without the plant-response cache, same process",
        "rounds": args.rounds,
        "cpu_count": os.cpu_count(),
        "loadavg": os.getloadavg(),
        "plants": rows,
        "ratio_median": statistics.median(r["ratio"] for r in rows),
        "same_gains": all(r["same_gains"] for r in rows),
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for r in rows:
            print(
                f"{r['plant']:12s} {r['feasible']:4d} feasible  baseline "
                f"{r['baseline_median_s']:.2f} s  cached {r['cached_median_s']:.2f} s  "
                f"ratio {r['ratio']:.2f}" + ("" if r["same_gains"] else "  CHOSE OTHER GAINS")
            )
        print(f"median ratio {out['ratio_median']:.2f}")
    return 0 if out["same_gains"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
