"""``servodesk bench``: the benchmarks that ship with the package.

    servodesk bench scope [--json] [--seconds 10] [--drives 4] [--clients 5] [--channels 8]

``scope`` measures the live scope end to end (issue 7 "Measure"): simulated drives in their
own process, the server on uvicorn, WebSocket clients in this process; see
servodesk/benchmarks/scope.py for what each figure means.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser("bench", help="run a benchmark (scope, tuning)")
    cmds = p.add_subparsers(dest="bench_command", metavar="BENCHMARK")
    s = cmds.add_parser(
        "scope",
        help="live scope: sources, WebSocket fan-out, latency and CPU",
        description="Simulated drives, the server and WebSocket clients on this machine: "
        "samples produced and delivered per second, drops, latency, CPU.",
    )
    add_scope_arguments(s)
    s.set_defaults(func=_run_scope)
    t = cmds.add_parser(
        "tuning",
        help="servodesk's tuning on simulated plants against an oracle",
        description="Tune a generic twin on each plant (plant files, or the default set of "
        "issue 8), then a 0.5-revolution move on the true plant; the same for the oracle's "
        "gains (exact plant knowledge). One JSON object per plant.",
    )
    t.add_argument("--plant", action="append", metavar="FILE", help="a plant file (repeatable)")
    t.add_argument("--only", help="comma-separated parts of plant names to run")
    t.add_argument("--mode", choices=["low", "basic", "high"], default="high")
    t.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    t.add_argument(
        "--cache",
        default=str(Path.home() / ".cache" / "servodesk" / "oracle"),
        help="where oracle results are cached per plant hash ('' for none)",
    )
    t.add_argument(
        "--seeds",
        type=_seed_list,
        default=[1],
        metavar="LIST",
        help="comma-separated torque-noise seeds of the tuned twin (default 1); each plant is "
        "tuned once per seed, and the JSON adds a summary per seed",
    )
    t.add_argument("--json", action="store_true", help="print the results as JSON")
    t.set_defaults(func=_run_tuning)
    p.set_defaults(func=lambda args: _usage(p))


def add_scope_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seconds", type=float, default=10.0, help="measured seconds per source")
    p.add_argument("--drives", type=int, default=4, help="simulated drives, one bus each")
    p.add_argument("--clients", type=int, default=5, help="WebSocket clients")
    p.add_argument("--channels", type=int, default=8, help="channels per drive (1..8)")
    p.add_argument(
        "--sources",
        default="pdo,recorder",
        help="comma-separated sources to measure in turn: pdo, recorder, sdo",
    )
    p.add_argument(
        "--bus",
        choices=["udp_multicast", "virtual"],
        default="udp_multicast",
        help="udp_multicast: drives in their own process; virtual: in the server process",
    )
    p.add_argument(
        "--no-compression", action="store_true", help="clients do not offer permessage-deflate"
    )
    p.add_argument(
        "--recorder-rate",
        type=_recorder_rate,
        default=0.0,
        metavar="HZ",
        help="the recorder's sample rate (a divider of its 4000 Hz; 0: 4000 Hz): the rate "
        "at which a bus carries the stream (docs/scope.md)",
    )
    p.add_argument("--json", action="store_true", help="print the results as JSON")


def _recorder_rate(text: str) -> float:
    """``1000``: a sample rate in Hz, 0 (the recorder's fastest) up to 4000."""
    try:
        hz = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of Hz, e.g. 1000") from None
    if not 0 <= hz <= 4000:
        raise argparse.ArgumentTypeError(f"{text!r}: give 0 (4000 Hz) to 4000 Hz")
    return hz


def _seed_list(text: str) -> list[int]:
    """``1,2,3``: distinct non-negative integers, at most 16 of them."""
    try:
        seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a comma-separated list of integers, e.g. 1,2,3,4"
        ) from None
    if not seeds or min(seeds) < 0 or len(set(seeds)) != len(seeds) or len(seeds) > 16:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give 1 to 16 distinct seeds >= 0, e.g. 1,2,3,4"
        )
    return seeds


def _usage(p: argparse.ArgumentParser) -> int:
    p.print_help(sys.stderr)
    return 2


def _run_tuning(args: argparse.Namespace) -> int:
    from servodesk.benchmarks.tuning import run
    from servodesk.errors import ServodeskError

    try:
        return run(args)
    except ServodeskError as exc:  # A bad plant file: say what is wrong, exit 2.
        print(f"servodesk bench tuning: {exc.message}", file=sys.stderr)
        return 2


def _run_scope(args: argparse.Namespace) -> int:
    # Imported here: `servodesk --help` does not load numpy, uvicorn and the simulation.
    from servodesk.benchmarks.scope import run

    return run(args)
