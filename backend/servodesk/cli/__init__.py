"""The ``servodesk`` command line: one module per command, each with ``register`` and ``run``.

Errors a user can cause (bad arguments, unknown profile, unreachable bus) print one message
with a hint on stderr and exit with code 2; never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
from collections.abc import Sequence

from servodesk import __version__
from servodesk.errors import NotFoundError, ServodeskError

#: Command modules in the order ``--help`` lists them.
COMMANDS = [
    "serve",
    "sim",
    "profiles",
    "openapi",
    "scan",
    "backup",
    "pdo",
    "tune",
    "dcp",
    "bench",
    "users",
    "audit",
    "store",
    "report",
]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        self.print_usage(sys.stderr)
        print(f"servodesk: error: {message}", file=sys.stderr)
        sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="servodesk",
        description="Commissioning tool for CiA 402 servo drives (CANopen, EtherCAT, "
        "CC-Link IE TSN, PROFINET).",
    )
    parser.add_argument("--version", action="version", version=f"servodesk {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        if importlib.util.find_spec(f"servodesk.cli.{name}") is None:
            continue  # A command whose module is not part of this build.
        module = importlib.import_module(f"servodesk.cli.{name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        code: int = args.func(args)
        return code
    except NotFoundError as exc:
        _fail(exc)
        return 2
    except ServodeskError as exc:
        _fail(exc)
        return 2
    except KeyboardInterrupt:
        return 130


def _fail(exc: ServodeskError) -> None:
    print(f"servodesk: error: {exc.message}", file=sys.stderr)
    if exc.hint:
        print(f"  hint: {exc.hint}", file=sys.stderr)
