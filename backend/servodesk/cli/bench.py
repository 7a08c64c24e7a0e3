"""``servodesk bench``: the benchmarks that ship with the package.

    servodesk bench scope [--json] [--seconds 10] [--drives 4] [--clients 5] [--channels 8]

``scope`` measures the live scope end to end (issue 7 "Measure"): simulated drives in their
own process, the server on uvicorn, WebSocket clients in this process; see
servodesk/benchmarks/scope.py for what each figure means.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser("bench", help="run a benchmark (scope)")
    cmds = p.add_subparsers(dest="bench_command", metavar="BENCHMARK")
    s = cmds.add_parser(
        "scope",
        help="live scope: sources, WebSocket fan-out, latency and CPU",
        description="Simulated drives, the server and WebSocket clients on this machine: "
        "samples produced and delivered per second, drops, latency, CPU.",
    )
    add_scope_arguments(s)
    s.set_defaults(func=_run_scope)
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
    p.add_argument("--json", action="store_true", help="print the results as JSON")


def _usage(p: argparse.ArgumentParser) -> int:
    p.print_help(sys.stderr)
    return 2


def _run_scope(args: argparse.Namespace) -> int:
    # Imported here: `servodesk --help` does not load numpy, uvicorn and the simulation.
    from servodesk.benchmarks.scope import run

    return run(args)
