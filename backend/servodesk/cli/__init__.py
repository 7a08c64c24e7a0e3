"""The ``servodesk`` command line: one module per command, each with ``register`` and ``run``.

Errors a user can cause (bad arguments, unknown profile, unreachable bus) print one message
with a hint on stderr and exit with code 2; never a traceback. A reader that stops early
(``servodesk openapi | head``) ends the command quietly with 141, as a POSIX tool's.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import select
import sys
from collections.abc import Sequence

from servodesk import __version__
from servodesk.errors import NotFoundError, ServodeskError, SettingsError

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
        # A reader gone while the last output sat in the buffer shows here, not at exit.
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        if not _stdout_closed():
            raise  # A socket's broken pipe is a real failure, not a reader that had enough.
        # Python's recipe (library/signal.html, "Note on SIGPIPE"): stdout to devnull, so
        # that the interpreter's final flush does not fail again. Not SIG_DFL for SIGPIPE: it
        # would kill `serve` on any socket's broken pipe. 141 (128 + SIGPIPE) is what the
        # shell reports for a C tool killed this way (`seq 1e9 | head`): with `set -o
        # pipefail` a script sees the output was cut short, as with any other tool; 0 would
        # claim it was all delivered.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return 141
    except NotFoundError as exc:
        _fail(exc)
        return 2
    except ServodeskError as exc:
        _fail(exc)
        return 2
    except KeyboardInterrupt:
        return 130


def _stdout_closed() -> bool:
    """stdout is a pipe whose reader has gone: poll reports an error on it (Linux pipe_poll)."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        return False  # Not a file (captured by a test, replaced by a caller).
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    return any(events & select.POLLERR for _, events in poller.poll(0))


def _fail(exc: ServodeskError) -> None:
    # Bad SERVODESK_* settings: one line each, all of them at once (settings.py).
    lines = exc.problems if isinstance(exc, SettingsError) else [exc.message]
    for line in lines:
        print(f"servodesk: error: {line}", file=sys.stderr)
    if exc.hint:
        print(f"  hint: {exc.hint}", file=sys.stderr)
