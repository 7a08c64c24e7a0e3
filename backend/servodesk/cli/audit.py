"""``servodesk audit``: verify the audit log's hash chain, export it (docs/security.md).

``verify`` exits 0 when every record still fits the chain and 1 naming the first that does
not (altered, missing, moved): a script or a monitoring job can run it. ``export`` writes
every record (from ``--since``) as JSON lines or CSV, with the hashes, oldest first.
"""

from __future__ import annotations

import argparse
import sys
from datetime import datetime
from pathlib import Path
from typing import Any

from servodesk.errors import NotFoundError, ValidationError
from servodesk.services.audit import AuditLog
from servodesk.settings import Settings


def register(sub: Any) -> None:
    p = sub.add_parser("audit", help="verify or export the audit log")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    verify = actions.add_parser("verify", help="recompute the hash chain (exit 1: broken)")
    _data_dir(verify)
    verify.set_defaults(func=run_verify)
    export = actions.add_parser("export", help="every record as JSON lines or CSV")
    _data_dir(export)
    export.add_argument("--format", choices=["jsonl", "csv"], default="jsonl")
    export.add_argument(
        "--since", default=None, metavar="TIME", help="ISO 8601, e.g. 2026-12-01 (UTC)"
    )
    export.add_argument("--output", "-o", default=None, metavar="FILE", help="default: stdout")
    export.set_defaults(func=run_export)


def _data_dir(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--data-dir",
        default=None,
        metavar="DIR",
        help="servodesk's data directory (default: SERVODESK_DATA_DIR or ~/.servodesk)",
    )


def _open(args: argparse.Namespace) -> AuditLog:
    settings = Settings()
    if settings.store_url and not args.data_dir:  # A central store (SERVODESK_STORE_URL).
        return AuditLog(settings.store_url)
    data_dir = Path(args.data_dir) if args.data_dir else settings.data_dir
    db = data_dir / "servodesk.db"
    if not db.is_file():
        raise NotFoundError(
            f"no servodesk store in {data_dir} (no servodesk.db)",
            hint="give the data directory the server uses with --data-dir",
        )
    return AuditLog(db)


def run_verify(args: argparse.Namespace) -> int:
    log = _open(args)
    try:
        v = log.verify()
    finally:
        log.close()
    if v.ok:
        print(f"audit log verified: {v.records} records, head {v.head}")
        return 0
    print(f"audit log BROKEN at record {v.broken}: {v.problem}")
    print(f"  the {v.records} records before it fit the chain (last good hash {v.head})")
    return 1


def run_export(args: argparse.Namespace) -> int:
    since = None
    if args.since:
        try:
            since = datetime.fromisoformat(args.since)
        except ValueError:
            raise ValidationError(
                f"--since {args.since!r} is not an ISO 8601 time",
                field="since",
                hint="e.g. 2026-12-01 or 2026-12-01T08:00:00Z",
            ) from None
    log = _open(args)
    try:
        if args.output:
            with open(args.output, "w", encoding="utf-8", newline="") as f:
                for chunk in log.export(args.format, since):
                    f.write(chunk)
        else:
            for chunk in log.export(args.format, since):
                sys.stdout.write(chunk)
    except OSError as exc:
        raise ValidationError(
            f"cannot write {args.output}: {exc.strerror or exc}",
            field="output",
            hint="choose a file in a directory you can write",
        ) from None
    finally:
        log.close()
    return 0
