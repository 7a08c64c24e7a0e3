"""``servodesk report verify FILE``: is this copy of a commissioning report the one servodesk
made (docs/report.md)?

The file (the report's HTML or its PDF) names its report id and the SHA-256 of the report's
data (the HTML in its title and footer, the PDF in its /Title). ``verify`` looks the id up in
the store and exits 0 when the file is byte for byte the HTML or PDF the store recorded for
that report ("matches report <id> of <drive> made <when> by <who>"); 1, with the reason,
when it is not (altered, unknown id, hash not the store's); 2 for bad arguments (no such
file, no store), like the other commands.
"""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path
from typing import Any

from servodesk.errors import NotFoundError, ValidationError
from servodesk.settings import Settings

#: The largest file verify reads (a report of a few thousand rows is a few MB).
MAX_BYTES = 256 * 1024 * 1024


def register(sub: Any) -> None:
    p = sub.add_parser("report", help="commissioning reports: verify a copy")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    verify = actions.add_parser(
        "verify", help="check a report's HTML or PDF against the store (exit 1: not the same)"
    )
    verify.add_argument("file", metavar="FILE", help="the report's .html or .pdf")
    verify.add_argument(
        "--data-dir",
        default=None,
        metavar="DIR",
        help="servodesk's data directory (default: SERVODESK_STORE_URL's store, else "
        "SERVODESK_DATA_DIR or ~/.servodesk)",
    )
    verify.set_defaults(func=run_verify)


def _read(path: Path) -> bytes:
    try:
        with path.open("rb") as f:
            data = f.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise NotFoundError(f"no file {path}", hint="give the report's .html or .pdf") from None
    except OSError as exc:
        raise ValidationError(
            f"cannot read {path}: {exc.strerror or exc}", field="file", hint="check the path"
        ) from None
    if len(data) > MAX_BYTES:
        raise ValidationError(
            f"{path} is larger than {MAX_BYTES // (1024 * 1024)} MB: not a report",
            field="file",
            hint="give the report's .html or .pdf",
        )
    return data


def _store_url(args: argparse.Namespace) -> str:
    from servodesk.services import db

    settings = Settings()
    if settings.store_url and not args.data_dir:  # A central store (SERVODESK_STORE_URL).
        return settings.store_url
    data_dir = Path(args.data_dir) if args.data_dir else settings.data_dir
    if not (data_dir / db.SQLITE_FILE).is_file():
        raise NotFoundError(
            f"no servodesk store in {data_dir} (no {db.SQLITE_FILE})",
            hint="give the data directory the server uses with --data-dir, or set "
            "SERVODESK_STORE_URL",
        )
    return db.store_url(data_dir)


def check(data: bytes, meta_of: Any) -> tuple[bool, str]:
    """Whether ``data`` (a report's HTML or PDF) is a report the store recorded, and why
    (``meta_of(id)``: the store's metadata of a report, NotFoundError when unknown)."""
    from servodesk.services.report import content_hash
    from servodesk.services.report_html import embedded_data
    from servodesk.services.report_pdf import find_in_html, find_in_pdf

    is_pdf = data.startswith(b"%PDF-")
    kind = "PDF" if is_pdf else "HTML"
    if is_pdf:
        found = find_in_pdf(data)
    else:
        text = data.decode("utf-8", "replace")
        found = find_in_html(text)
    if found is None:
        return False, f"not a servodesk report: no report id and hash in this {kind}"
    rid, printed = found
    if not is_pdf:
        # The data the page embeds must still have the hash it prints (no store needed).
        embedded = embedded_data(text)
        if embedded is None or content_hash(embedded) != printed:
            return False, (
                f"altered: the report data in this HTML no longer has the SHA-256 it prints "
                f"({printed[:16]}...) for report {rid}"
            )
    try:
        meta = meta_of(rid)
    except NotFoundError:
        return False, f"unknown: the store has no report {rid}"
    if meta["sha256"] != printed:
        return False, (
            f"altered: the file prints SHA-256 {printed[:16]}... for report {rid}, the store "
            f"recorded {meta['sha256'][:16]}..."
        )
    digest = hashlib.sha256(data).hexdigest()
    if digest not in (meta["html_sha256"], meta.get("pdf_sha256")):
        made = "its HTML" + (" or PDF" if meta.get("pdf_sha256") else "")
        return False, (
            f"altered: this {kind} is not byte for byte {made} as the store recorded it for "
            f"report {rid} (SHA-256 {digest[:16]}...)"
        )
    drive = meta["drive_key"] + (f" ({meta['plant_tag']})" if meta.get("plant_tag") else "")
    return True, f"matches report {rid} of {drive} made {meta['time']} by {meta['by']}"


def run_verify(args: argparse.Namespace) -> int:
    from servodesk.services import db
    from servodesk.services.report_store import ReportStore

    data = _read(Path(args.file))
    engine = db.open_engine(_store_url(args))
    try:
        ok, message = check(data, ReportStore(engine).get)
    finally:
        engine.dispose()
    print(message)
    return 0 if ok else 1
