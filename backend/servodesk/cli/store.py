"""``servodesk store``: move a whole store between SQLite and PostgreSQL (issue 49).

``export FILE`` writes every table of the store (backups with their content, restores, both
audit tables, accounts and API tokens) to one file; ``import FILE`` reads it into an empty
store, in one transaction, and verifies the audit chain afterwards. Rows are copied as they
are (ids, times, hashes), so the audit chain of the copy verifies exactly as the original
did and every backup's bytes keep their SHA-256 (docs/deployment.md, "Moving a store").

The file is JSON lines: a header (format, version, the schema revision), one line per row
(``{"t": table, "r": {column: value}}``; binary columns in base64), and a closing line with
the number of rows per table, so that a truncated file is refused rather than half-read.
The store is the one the server would use (``SERVODESK_STORE_URL``, else the SQLite file in
``SERVODESK_DATA_DIR``) unless ``--url`` or ``--data-dir`` names another.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from servodesk.errors import ConflictError, NotFoundError, ValidationError
from servodesk.settings import Settings

FORMAT = "servodesk-store"
VERSION = 1
#: Rows inserted per statement on import.
BATCH = 500


def register(sub: Any) -> None:
    p = sub.add_parser("store", help="export or import the whole store (SQLite <-> PostgreSQL)")
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    export = actions.add_parser("export", help="write every table of the store to FILE")
    export.add_argument("file", metavar="FILE", help="a new file (never overwritten)")
    _where(export)
    export.set_defaults(func=run_export)
    imp = actions.add_parser("import", help="read FILE into an empty store")
    imp.add_argument("file", metavar="FILE", help="a file made by servodesk store export")
    _where(imp)
    imp.set_defaults(func=run_import)


def _where(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--url",
        default=None,
        metavar="URL",
        help="the store: postgresql://user@host:port/db (default: SERVODESK_STORE_URL, "
        "else the SQLite file of the data directory)",
    )
    p.add_argument(
        "--data-dir",
        default=None,
        metavar="DIR",
        help="the data directory (its SQLite store, unless --url; default: "
        "SERVODESK_DATA_DIR or ~/.servodesk)",
    )


def _target(args: argparse.Namespace) -> tuple[Path, str]:
    settings = Settings()
    data_dir = Path(args.data_dir) if args.data_dir else settings.data_dir
    if args.url is not None:
        return data_dir, args.url
    return data_dir, "" if args.data_dir else settings.store_url


# Export ---------------------------------------------------------------------------------


def run_export(args: argparse.Namespace) -> int:
    from servodesk.services.store import Store

    data_dir, url = _target(args)
    out = Path(args.file)
    # Opening the store copies a data directory's old backup files into it first, so the
    # export has every backup's content.
    store = Store(data_dir, url)
    try:
        try:
            f = open(out, "x", encoding="utf-8", newline="\n")  # noqa: SIM115
        except FileExistsError:
            raise ConflictError(
                f"{out} exists; an export never overwrites a file", hint="choose a new name"
            ) from None
        except OSError as exc:
            raise ValidationError(
                f"cannot write {out}: {exc.strerror or exc}",
                field="file",
                hint="choose a file in a directory you can write",
            ) from None
        try:
            with f:
                counts = _export(store.engine, f)
                f.flush()
                os.fsync(f.fileno())
        except BaseException:
            with contextlib.suppress(OSError):
                out.unlink()
            raise
    finally:
        store.close()
    total = ", ".join(f"{n} {t}" for t, n in counts.items())
    print(f"exported the store to {out}: {total}")
    return 0


def _export(engine: Any, f: IO[str]) -> dict[str, int]:
    import sqlalchemy as sa

    from servodesk.services import db

    counts: dict[str, int] = {}
    with engine.connect() as conn:
        if db.is_postgres(conn):
            # One snapshot for every table: a gateway writing meanwhile cannot make the
            # export see a backup without its content.
            conn = conn.execution_options(isolation_level="REPEATABLE READ")
        with conn.begin():
            revision = conn.execute(sa.text("SELECT version_num FROM alembic_version")).scalar()
            header = {"format": FORMAT, "version": VERSION, "revision": revision}
            f.write(json.dumps(header) + "\n")
            for table in db.TABLES:
                binary = {c.name for c in table.columns if isinstance(c.type, sa.LargeBinary)}
                order: list[Any] = list(table.primary_key.columns)
                if table is db.backups and not db.is_postgres(conn):
                    order = [sa.literal_column("rowid")]  # The order they were made in.
                n = 0
                result = conn.execution_options(yield_per=500).execute(
                    sa.select(table).order_by(*order)
                )
                for row in result.mappings():
                    rec = {k: _b64(v) if k in binary else v for k, v in row.items()}
                    f.write(json.dumps({"t": table.name, "r": rec}, ensure_ascii=False) + "\n")
                    n += 1
                counts[table.name] = n
    f.write(json.dumps({"end": True, "rows": counts}) + "\n")
    return counts


def _b64(value: Any) -> str:
    return base64.b64encode(bytes(value)).decode("ascii")


# Import ---------------------------------------------------------------------------------


def run_import(args: argparse.Namespace) -> int:
    from servodesk.services import db
    from servodesk.services.audit import AuditLog

    data_dir, url = _target(args)
    path = Path(args.file)
    try:
        f = open(path, "rb")  # noqa: SIM115
    except FileNotFoundError:
        raise NotFoundError(
            f"no file {path}", hint="give a file made by servodesk store export"
        ) from None
    except OSError as exc:
        raise ValidationError(f"cannot read {path}: {exc.strerror or exc}", field="file") from None
    with f:
        lines = _lines(f, path)
        header = next(lines, None)
        _check_header(header, path)
        target = db.store_url(data_dir, url)
        engine = db.open_engine(target)
        try:
            counts = _import(engine, lines, path)
        finally:
            engine.dispose()
    log = AuditLog(target)
    try:
        verdict = log.verify()
    finally:
        log.close()
    total = ", ".join(f"{n} {t}" for t, n in counts.items())
    print(f"imported {path} into {_shown(target)}: {total}")
    if not verdict.ok:
        print(f"audit log BROKEN at record {verdict.broken}: {verdict.problem}")
        print("  (it was broken in the exported store: the rows are copied as they are)")
        return 1
    print(f"audit log verified: {verdict.records} records, head {verdict.head}")
    return 0


def _shown(url: str) -> str:
    from sqlalchemy.engine.url import make_url

    return make_url(url).render_as_string(hide_password=True)


def _bad(path: Path, why: str) -> ValidationError:
    return ValidationError(
        f"{path} is not a servodesk store export: {why}",
        field="file",
        hint="give a file made by servodesk store export",
    )


def _lines(f: IO[bytes], path: Path) -> Iterator[dict[str, Any]]:
    for number, line in enumerate(f, 1):
        try:
            item = json.loads(line.decode("utf-8"))
        except ValueError:  # Also UnicodeDecodeError: not UTF-8 text.
            raise _bad(path, f"line {number} is not JSON") from None
        if not isinstance(item, dict):
            raise _bad(path, f"line {number} is not an object")
        yield item


def _check_header(header: dict[str, Any] | None, path: Path) -> None:
    if header is None:
        raise _bad(path, "it is empty")
    if header.get("format") != FORMAT:
        raise _bad(path, "its first line has no servodesk-store header")
    if header.get("version") != VERSION:
        raise _bad(
            path, f"format version {header.get('version')!r} (this servodesk reads {VERSION})"
        )
    known = {p.name.split("_", 1)[0] for p in _revisions()}
    if header.get("revision") not in known:
        raise ValidationError(
            f"{path} was exported from a store at schema revision {header.get('revision')!r}, "
            "which this servodesk does not know",
            field="file",
            hint="import it with the servodesk version that exported it, or a newer one",
        )


def _revisions() -> list[Path]:
    from servodesk import migrations

    return sorted((Path(migrations.__file__).parent / "versions").glob("[0-9]*.py"))


def _import(engine: Any, lines: Iterator[dict[str, Any]], path: Path) -> dict[str, int]:
    import sqlalchemy as sa

    from servodesk.services import db

    tables = {t.name: t for t in db.TABLES}
    counts = dict.fromkeys(tables, 0)
    pending: dict[str, list[dict[str, Any]]] = {name: [] for name in tables}
    ended: dict[str, Any] | None = None

    def flush(conn: Any, name: str) -> None:
        if pending[name]:
            conn.execute(sa.insert(tables[name]), pending[name])
            pending[name] = []

    try:
        with db.write(engine) as conn:
            # Two imports at once into one PostgreSQL would both see it empty.
            db.serialise(conn, db.LOCK_MIGRATE)
            for table in db.TABLES:
                if conn.execute(sa.select(sa.func.count()).select_from(table)).scalar():
                    raise ConflictError(
                        f"the target store {db.describe(engine)} is not empty "
                        f"(table {table.name} has rows)",
                        hint="import into a new database or an empty data directory",
                    )
            for item in lines:
                if item.get("end") is True:
                    ended = item
                    break
                name, row = item.get("t"), item.get("r")
                if not isinstance(name, str) or name not in tables or not isinstance(row, dict):
                    raise _bad(path, f"a row of an unknown table {name!r}")
                table = tables[name]
                unknown = set(row) - set(table.columns.keys())
                if unknown:
                    raise _bad(path, f"{name} has no column {sorted(unknown)[0]!r}")
                for column in table.columns:
                    if isinstance(column.type, sa.LargeBinary) and column.name in row:
                        row[column.name] = base64.b64decode(row[column.name], validate=True)
                pending[name].append(row)
                counts[name] += 1
                if len(pending[name]) >= BATCH:
                    flush(conn, name)
            if ended is None:
                raise _bad(path, "it ends before its closing line (truncated?)")
            # An export of an older revision lacks the tables added since (they stay empty).
            announced = ended.get("rows")
            if not isinstance(announced, dict) or announced != {
                k: v for k, v in counts.items() if v or k in announced
            }:
                raise _bad(path, f"it announces {ended.get('rows')} rows and holds {counts}")
            for table in db.TABLES:  # Content before the backups that name it, and so on.
                flush(conn, table.name)
            if db.is_postgres(conn):
                # The ids of ``audit`` came with the rows: the sequence continues after them.
                for serial in ("audit", "drift_results"):
                    conn.execute(
                        sa.text(
                            f"SELECT setval(pg_get_serial_sequence('{serial}', 'id'), "
                            f"COALESCE((SELECT max(id) FROM {serial}), 0) + 1, false)"
                        )
                    )
    except sa.exc.SQLAlchemyError as exc:
        raise db.store_error(exc) from exc
    except (ValueError, TypeError) as exc:  # base64, a value of the wrong type
        raise _bad(path, str(exc)) from exc
    return counts
