"""Real-time factor of one simulated axis stepping unbound through profile-position moves.

``python bench/bench_sim.py [--seconds S] [--runs N] --json`` runs a representative sequence
(enable, long and short absolute and relative moves with the set-point handshake, waiting
for target reached) for S simulated seconds, N times, and reports the median real-time
factor (simulated seconds per wall-clock second; the aim is >= 20).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimulatedDrive

REV = 131072
# (target, relative) pairs the sequence cycles through.
MOVES = [(3 * REV, False), (-REV, True), (REV // 8, True), (0, False), (-2 * REV, False)]


def one_run(seconds: float, profile_id: str) -> dict[str, float]:
    drive = SimulatedDrive(ProfileCatalog().get(profile_id), 1)
    drive.step(0.001)
    for word in (0x06, 0x07, 0x0F):
        drive.write(0x6040, 0, word)
    moves = 0
    chunk = 0.01
    t0 = time.perf_counter()
    while drive.time < seconds:
        target, relative = MOVES[moves % len(MOVES)]
        drive.write(0x607A, 0, target)
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
    ap.add_argument("--json", action="store_true", help="print JSON")
    args = ap.parse_args(argv)
    if args.seconds <= 0 or args.runs < 1:
        print("bench_sim: --seconds must be > 0 and --runs >= 1", file=sys.stderr)
        return 2
    runs = [one_run(args.seconds, args.profile) for _ in range(args.runs)]
    rtfs = [r["rtf"] for r in runs]
    result = {
        "benchmark": "sim_profile_position_unbound",
        "profile": args.profile,
        "control_rate_hz": 1000,
        "plant_substeps": 4,
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
            f"({result['rtf_min']}..{result['rtf_max']}) over {args.runs} runs"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
