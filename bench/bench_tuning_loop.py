"""How long servodesk's own tuning holds the event loop that carries the operator's heartbeats.

One tuning per plant and noise seed of the benchmark's default set (benchmarks/tuning.py), at
``high`` (the whole procedure: identification, frequency response, record fits, the gain
search, the tries on the axis and the fit of the inertias to the winner's try), twice in this
process: as the service runs it (``offload``: every search and fit in the design worker) and,
as the baseline, with all of it on the event loop. The twin steps in a thread while the tuning
awaits it, as a real drive moves while the service awaits its bus, so every hold measured is the
tuning's own arithmetic: the longest synchronous stretch of the tuning task between two awaits,
and the time spent in stretches longer than the dead-man's tick (30 ms). The dead-man allows
250 ms by default (SERVODESK_DEADMAN_MS).

    python bench/bench_tuning_loop.py [--plants R10-200Hz,R3-400Hz] [--seeds 2] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
import time
from collections.abc import Generator
from typing import Any

from servodesk.benchmarks.tuning import SimIO, build_drive, default_plants, plant_names
from servodesk.services.tuning import worker as tuning_worker
from servodesk.services.tuning.own import OwnTuning, OwnTuningRequest

#: A stretch longer than this counts as holding the loop (the dead-man's watchdog naps a few
#: milliseconds; a heartbeat every 100 ms).
HOLD_S = 0.03


class SteppedInAThread(SimIO):
    """The twin stepped in a thread while the tuning waits."""

    async def sleep(self, seconds: float) -> None:
        await asyncio.to_thread(self.drive.step, seconds)


class Timed:
    """Awaits a coroutine and times each of its synchronous stretches between awaits."""

    def __init__(self, coro: Any) -> None:
        self.coro = coro
        self.stretches: list[float] = []

    def __await__(self) -> Generator[Any, Any, Any]:
        gen = self.coro.__await__()
        value: Any = None
        error: BaseException | None = None
        while True:
            t0 = time.perf_counter()
            try:
                out = gen.throw(error) if error is not None else gen.send(value)
            except StopIteration as stop:
                self.stretches.append(time.perf_counter() - t0)
                return stop.value
            self.stretches.append(time.perf_counter() - t0)
            error = None
            try:
                value = yield out
            except BaseException as exc:  # handed on to the coroutine, as a task would
                error, value = exc, None


def one(name: str, seed: int, offload: bool) -> dict[str, Any]:
    spec = dict(default_plants())[name]
    drive = build_drive(spec, seed)
    move_pct = 100.0 * spec.peak_torque / spec.rated_torque
    req = OwnTuningRequest("high", 0.5, 175.0, move_pct)  # type: ignore[arg-type]
    timed = Timed(OwnTuning(SteppedInAThread(drive), req, offload=offload).run())

    async def run() -> Any:
        return await timed

    t0 = time.perf_counter()
    result = asyncio.run(run())
    held = [s for s in timed.stretches if s > HOLD_S]
    return {
        "plant": name,
        "seed": seed,
        "offload": offload,
        "wall_s": round(time.perf_counter() - t0, 2),
        "longest_hold_ms": round(1e3 * max(timed.stretches), 1),
        "held_over_30ms_s": round(sum(held), 3),
        "holds_over_30ms": len(held),
        "refit": (result["identified"].get("refit") or {}).get("outcome"),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", default="R10-200Hz,R3-400Hz,R30-100Hz")
    ap.add_argument("--seeds", default="2")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    try:
        names = plant_names(args.plants)
        seeds = [int(s) for s in args.seeds.split(",") if s]
    except ValueError as exc:
        print(f"bench_tuning_loop: {exc}", file=sys.stderr)
        return 2
    rows = []
    try:
        for name in names:
            for seed in seeds:
                for offload in (True, False):
                    rows.append(one(name, seed, offload))
    finally:
        tuning_worker.shutdown()
    ours = [r for r in rows if r["offload"]]
    base = [r for r in rows if not r["offload"]]
    out = {
        "benchmark": "tuning_loop",
        "hold_threshold_ms": 1e3 * HOLD_S,
        "longest_hold_ms": {
            "offload_median": statistics.median(r["longest_hold_ms"] for r in ours),
            "offload_worst": max(r["longest_hold_ms"] for r in ours),
            "on_loop_median": statistics.median(r["longest_hold_ms"] for r in base),
            "on_loop_worst": max(r["longest_hold_ms"] for r in base),
        },
        "ratio_longest_hold_median": statistics.median(
            a["longest_hold_ms"] / b["longest_hold_ms"] for a, b in zip(ours, base, strict=True)
        ),
        "rows": rows,
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for r in rows:
            print(
                f"{r['plant']:>12} s{r['seed']} {'offload' if r['offload'] else 'on loop':>8}: "
                f"longest hold {r['longest_hold_ms']:7.1f} ms, {r['holds_over_30ms']} holds "
                f"over 30 ms ({r['held_over_30ms_s']:.2f} s), refit {r['refit']}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
