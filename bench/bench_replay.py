"""Per-tick cost of the move simulation the own tuning ranks its candidates with and the
benchmark's oracle is chosen with: the fused tick loop (model/fused.py, what ``run_move`` takes
for a noiseless axis; compiled by numba) against the call-per-tick path through
``ServoLoop.update`` and ``Plant.step`` (``run_move_stepwise``, the baseline) and against the
same fused loop run as Python (``python_fused``, what ran before numba compiled it),
alternating in one process.

``recorded``: the replay of a try's move from the rest the recording found the axis in
(``run_recorded_move``, what the fit of the inertias to the winner's try runs some 80 times per
tuning, services/tuning/calibrate.py), fused against the per-cycle path through
``ServoLoop.run`` (``run_recorded_move_stepwise``, the baseline): milliseconds per replay.

Each plant runs the benchmark's reference move (0.5 rev, jerk-limited, watched 0.5 s) with the
``high`` design of its exact model, twice: with the model's numbers as Python floats, and as
numpy scalars, which is how an identified model and a designed gain set carry them (the
tuning's case). Reports the median microseconds per tick of each path, their ratios (fused
over baseline, and fused over the Python fused loop; below 1 is faster) and whether the three
gave the same positions to the count.

    python bench/bench_replay.py [--rounds 5] [--plants R10-200Hz,R30-100Hz,R3-rigid] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from dataclasses import fields, replace
from typing import Any

import numpy as np

from servodesk.benchmarks.tuning import default_plants, exact_model, plant_names
from servodesk.domain.tuning.design import design_gains
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.model import PlantModel
from servodesk.domain.tuning.search import reference_move
from servodesk.model import fused as fused_module
from servodesk.model.plant import PlantParams
from servodesk.model.plantfile import PlantSpec
from servodesk.model.replay import (
    ModelMoves,
    RecordedMove,
    run_move,
    run_move_stepwise,
    run_recorded_move,
    run_recorded_move_stepwise,
)

DEFAULT_PLANTS = "R10-200Hz,R30-100Hz,R1-800Hz,R3-rigid"


def _as_numpy(params: PlantParams, gains: ServoGains) -> tuple[PlantParams, ServoGains]:
    """The same numbers as numpy scalars where an identified model has them."""
    p = replace(
        params,
        motor_inertia=np.float64(params.motor_inertia),
        load_inertia=np.float64(params.load_inertia),
        coulomb=np.float64(params.coulomb),
    )
    g = replace(gains, **{f.name: np.float64(getattr(gains, f.name)) for f in fields(gains)})
    return p, g


def _designed(name: str) -> tuple[PlantSpec, PlantModel, float, ServoGains, ModelMoves]:
    """A plant of the default set, its exact model, loop rate, ``high`` design and the
    simulation of it (with its Coulomb friction)."""
    spec = dict(default_plants())[name]
    plant = exact_model(spec)
    rate = float(spec.loop_rate_hz)
    gains = design_gains(plant, rate, "high").gains
    moves = ModelMoves.of(
        plant,
        rate,
        counts_per_rev=spec.encoder_counts,
        torque_limit=spec.peak_torque,
        coulomb=spec.coulomb * spec.peak_torque,
    )
    assert moves is not None
    return spec, plant, rate, gains, moves


def one_plant(name: str, rounds: int, numpy_scalars: bool) -> dict[str, Any]:
    spec, plant, rate, gains, moves = _designed(name)
    params = moves.params
    if numpy_scalars:
        params, gains = _as_numpy(params, gains)
    move = reference_move(plant.total_inertia, spec.peak_torque, spec.encoder_counts, rate)
    ticks = len(move.p)
    base: list[float] = []
    fused: list[float] = []
    python: list[float] = []
    same = True
    run_move(params, gains, rate, spec.peak_torque, move)  # Loads (or compiles) the loop once.
    compiled = fused_module.COMPILED and fused_module._compiled is not None
    for _ in range(rounds):
        t0 = time.perf_counter()
        a = run_move_stepwise(params, gains, rate, spec.peak_torque, move)
        t1 = time.perf_counter()
        b = run_move(params, gains, rate, spec.peak_torque, move)
        t2 = time.perf_counter()
        fused_module.COMPILED = False
        try:
            c = run_move(params, gains, rate, spec.peak_torque, move)
        finally:
            fused_module.COMPILED = True
        t3 = time.perf_counter()
        base.append((t1 - t0) / ticks * 1e6)
        fused.append((t2 - t1) / ticks * 1e6)
        python.append((t3 - t2) / ticks * 1e6)
        same = (
            same
            and bool(np.array_equal(a, b, equal_nan=True))
            and bool(np.array_equal(a, c, equal_nan=True))
        )
    return {
        "plant": name,
        "numbers": "numpy scalars" if numpy_scalars else "floats",
        "ticks": ticks,
        "compiled": compiled,
        "baseline_us_per_tick": statistics.median(base),
        "python_fused_us_per_tick": statistics.median(python),
        "fused_us_per_tick": statistics.median(fused),
        "ratio": statistics.median(fused) / statistics.median(base),
        "ratio_to_python_fused": statistics.median(fused) / statistics.median(python),
        "same_positions": same,
    }


def one_recorded(name: str, rounds: int) -> dict[str, Any]:
    """A try's move replayed from rest (module docstring): a quarter revolution there at 0.7 x
    the peak torque over the axis's inertia, under the ``high`` design, the axis resting 3
    counts off the demand with its integral holding a small torque; 0.4 s recorded."""
    spec, plant, rate, gains, moves = _designed(name)
    cpr = spec.encoder_counts
    acc = 0.7 * spec.peak_torque / plant.total_inertia * cpr / (2.0 * np.pi)
    move = RecordedMove(
        gains=gains,
        distance=0.25 * cpr,
        velocity=min(0.8 * float(np.sqrt(acc * 0.25 * cpr)), 40.0 * cpr),
        acc=acc,
        offset=3.0,
        hold_torque=0.5 * spec.coulomb * spec.peak_torque,
        torque_limit=spec.peak_torque,
        position=np.zeros(int(0.4 * rate)),
    )
    run_recorded_move(moves.params, move, rate)  # Loads (or compiles) the loop once.
    base: list[float] = []
    fused: list[float] = []
    same = True
    for _ in range(rounds):
        t0 = time.perf_counter()
        a = run_recorded_move_stepwise(moves.params, move, rate)
        t1 = time.perf_counter()
        b = run_recorded_move(moves.params, move, rate)
        t2 = time.perf_counter()
        base.append((t1 - t0) * 1e3)
        fused.append((t2 - t1) * 1e3)
        same = same and bool(np.array_equal(a, b, equal_nan=True))
    return {
        "plant": name,
        "ticks": len(move.position),
        "baseline_ms_per_replay": statistics.median(base),
        "fused_ms_per_replay": statistics.median(fused),
        "ratio": statistics.median(fused) / statistics.median(base),
        "same_positions": same,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5, help="rounds of each path per plant")
    ap.add_argument("--plants", default=DEFAULT_PLANTS, help="comma-separated plant names")
    ap.add_argument("--json", action="store_true", help="print JSON")
    args = ap.parse_args(argv)
    try:
        names = plant_names(args.plants)
        if args.rounds < 1:
            raise ValueError("--rounds must be >= 1")
    except ValueError as exc:
        print(f"bench_replay: {exc}", file=sys.stderr)
        return 2
    rows = [one_plant(n, args.rounds, np_) for n in names for np_ in (False, True)]
    recorded = [one_recorded(n, args.rounds) for n in names]
    out = {
        "what": "reference move on an exact plant model, fused tick loop (model/fused.py, "
        "compiled) against ServoLoop.update + Plant.step per tick (baseline) and against the "
        "fused loop as Python (python_fused), same process",
        "rounds": args.rounds,
        "cpu_count": os.cpu_count(),
        "loadavg": os.getloadavg(),
        "plants": rows,
        "ratio_median_floats": statistics.median(
            r["ratio"] for r in rows if r["numbers"] == "floats"
        ),
        "ratio_median_numpy_scalars": statistics.median(
            r["ratio"] for r in rows if r["numbers"] == "numpy scalars"
        ),
        "ratio_to_python_fused_median": statistics.median(r["ratio_to_python_fused"] for r in rows),
        "recorded": recorded,
        "recorded_ratio_median": statistics.median(r["ratio"] for r in recorded),
        "same_positions": all(r["same_positions"] for r in [*rows, *recorded]),
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for r in rows:
            print(
                f"{r['plant']:12s} {r['numbers']:14s} {r['ticks']:6d} ticks  baseline "
                f"{r['baseline_us_per_tick']:.2f} us  python fused "
                f"{r['python_fused_us_per_tick']:.2f} us  fused {r['fused_us_per_tick']:.2f} us  "
                f"ratio {r['ratio']:.3f}" + ("" if r["same_positions"] else "  DIFFERENT")
            )
        print(
            f"median ratio to the baseline: floats {out['ratio_median_floats']:.3f}, "
            f"numpy scalars {out['ratio_median_numpy_scalars']:.3f}; to the Python fused loop "
            f"{out['ratio_to_python_fused_median']:.3f}"
        )
        for r in recorded:
            print(
                f"{r['plant']:12s} recorded move {r['ticks']:6d} ticks  baseline "
                f"{r['baseline_ms_per_replay']:.2f} ms  fused {r['fused_ms_per_replay']:.3f} ms  "
                f"ratio {r['ratio']:.3f}" + ("" if r["same_positions"] else "  DIFFERENT")
            )
    return 0 if out["same_positions"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
