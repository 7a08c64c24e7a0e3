"""Real-time factor of one simulated axis stepping unbound through profile-position moves.

``python bench/bench_sim.py [--seconds S] [--runs N] [--loop-rate HZ] [--controller servo|cycle]
--json`` runs a representative sequence (enable, long and short absolute and relative moves with
the set-point handshake, waiting for target reached) for S simulated seconds, N times, and
reports the median real-time factor (simulated seconds per wall-clock second; the aim is >= 20).

``--loop-rate`` sets the servo loop and plant rate (default: the profile's
``simulation.loop_rate_hz``, 4000 for the generic twin; plant files use 16000). ``--controller
cycle`` drops the profile's ``tuning:`` block, so the twin runs the cycle-rate cascade the
drives had before the servo loop of docs/tuning.md (the "before" figure). ``--plant FILE``
simulates a plant file's axis (docs/tuning.md) at its loop rate unless ``--loop-rate`` is given.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.model.plant import PlantParams
from servodesk.model.plantfile import load_plant_file
from servodesk.sim.engine import SimulatedDrive

REV = 131072
# (target, relative) pairs the sequence cycles through, in revolutions.
MOVES = [(3.0, False), (-1.0, True), (0.125, True), (0.0, False), (-2.0, False)]


def one_run(
    seconds: float,
    profile_id: str,
    loop_rate: int | None = None,
    controller: str = "servo",
    plant: PlantParams | None = None,
) -> dict[str, float]:
    profile = ProfileCatalog().get(profile_id)
    if controller == "cycle":
        profile = profile.model_copy(update={"tuning": None})
    drive = SimulatedDrive(profile, 1, plant_params=plant, loop_rate_hz=loop_rate)
    drive.step(0.001)
    for word in (0x06, 0x07, 0x0F):
        drive.write(0x6040, 0, word)
    moves = 0
    chunk = 0.01
    t0 = time.perf_counter()
    while drive.time < seconds:
        target, relative = MOVES[moves % len(MOVES)]
        drive.write(0x607A, 0, round(target * drive.plant_params.counts_per_rev))
        word = 0x0F | (0x40 if relative else 0)
        drive.write(0x6040, 0, word | 0x10)
        drive.step(0.001)
        drive.write(0x6040, 0, word)
        deadline = drive.time + 5.0
        while not drive.statusword & 0x400 and drive.time < min(deadline, seconds):
            drive.step(chunk)
        moves += 1
    wall = time.perf_counter() - t0
    return {"simulated_s": drive.time, "wall_s": wall, "rtf": drive.time / wall, "moves": moves}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per run")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--profile", default="cia402-generic")
    ap.add_argument(
        "--loop-rate", type=int, default=None, help="servo loop / plant rate in Hz (n x 1000)"
    )
    ap.add_argument("--plant", default=None, metavar="FILE", help="a TOML plant file")
    ap.add_argument(
        "--controller",
        choices=("servo", "cycle"),
        default="servo",
        help="servo: the profile's servo loop (docs/tuning.md); cycle: the 1 kHz cascade",
    )
    ap.add_argument("--json", action="store_true", help="print JSON")
    args = ap.parse_args(argv)
    if args.seconds <= 0 or args.runs < 1:
        print("bench_sim: --seconds must be > 0 and --runs >= 1", file=sys.stderr)
        return 2
    if args.loop_rate is not None and (args.loop_rate < 1000 or args.loop_rate % 1000):
        print("bench_sim: --loop-rate must be a multiple of 1000 Hz", file=sys.stderr)
        return 2
    plant: PlantParams | None = None
    loop_rate = args.loop_rate
    if args.plant:
        spec = load_plant_file(args.plant)
        plant = spec.plant_params(seed=1)
        loop_rate = loop_rate or spec.loop_rate_hz
    runs = [
        one_run(args.seconds, args.profile, loop_rate, args.controller, plant)
        for _ in range(args.runs)
    ]
    drive = SimulatedDrive(
        ProfileCatalog().get(args.profile), 1, plant_params=plant, loop_rate_hz=loop_rate
    )
    rtfs = [r["rtf"] for r in runs]
    result = {
        "benchmark": "sim_profile_position_unbound",
        "profile": args.profile,
        "plant": args.plant,
        "control_rate_hz": 1000,
        "loop_rate_hz": drive.loop_rate_hz,
        "plant_substeps": drive.loop_rate_hz // 1000,
        "controller": args.controller
        if args.controller == "cycle" or drive.servo is not None
        else "cycle",
        "simulated_s_per_run": args.seconds,
        "runs": args.runs,
        "moves_per_run": runs[0]["moves"],
        "rtf_median": round(statistics.median(rtfs), 1),
        "rtf_min": round(min(rtfs), 1),
        "rtf_max": round(max(rtfs), 1),
        "target": 20.0,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"real-time factor {result['rtf_median']}x median "
            f"({result['rtf_min']}..{result['rtf_max']}) over {args.runs} runs "
            f"({result['controller']} controller, loop {result['loop_rate_hz']} Hz)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
