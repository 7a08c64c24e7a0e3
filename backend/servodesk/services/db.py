"""The store's database: one schema on SQLite or PostgreSQL (issue 49, docs/deployment.md).

``SERVODESK_STORE_URL`` names it: empty (the default) is the SQLite file
``<data_dir>/servodesk.db`` as before, with no setup; ``postgresql://user@host:port/db`` a
central PostgreSQL that several servodesk gateways share. The data layer is SQLAlchemy Core
(the tables below) and psycopg 3 for PostgreSQL; the schema is versioned by Alembic, with
the revisions inside the package (``servodesk/migrations``), and every open of a store
upgrades it to the newest revision first (:func:`open_engine`).

The guarantees of the SQLite store are kept on both engines:

- **one transaction per change** (:func:`write`): a crash leaves the old or the new state;
- on SQLite, **WAL with ``synchronous=FULL``** on every connection (a committed change
  survives a power loss) and ``BEGIN IMMEDIATE`` for writers, so that a read-then-write (the
  audit chain's append) takes the write lock before it reads: two processes never both read
  the same head;
- on PostgreSQL, a writer that must serialise with the other gateways takes a transaction-
  scoped advisory lock (:func:`serialise`); everything else relies on the primary keys and
  ``ON CONFLICT DO NOTHING``, so concurrent writers neither lose nor duplicate a record.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.engine.url import URL, make_url

from servodesk.errors import ServodeskError, Unavailable


class StoreError(ServodeskError):
    """The store or a backup file cannot be written or read."""


class StoreUnavailable(StoreError, Unavailable):
    """The central store (PostgreSQL) cannot be reached: a connection-level failure
    (:func:`is_unreachable`). HTTP 503: the next try may work."""


#: What a user is told the gateway does while the central store is away (services/outbox.py).
QUEUE_HINT = (
    "this gateway keeps its backups, tuning results and audit records in a local queue and "
    "syncs them when the store answers again; what needs the central store waits for it"
)


#: The file of the default store inside the data directory.
SQLITE_FILE = "servodesk.db"

# The tables. Column types are the SQLite store's (TEXT, REAL, INTEGER): an existing
# servodesk.db is this schema already, revision 0001 only adds what an older one lacks.
metadata = sa.MetaData()

backups = sa.Table(
    "backups",
    metadata,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("label", sa.Text, nullable=False, server_default=""),
    sa.Column("note", sa.Text, nullable=False, server_default=""),
    sa.Column("profile_id", sa.Text, nullable=False),
    sa.Column("profile_version", sa.Text, nullable=False, server_default=""),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("identity", sa.Text, nullable=False),
    sa.Column("firmware", sa.Text),
    sa.Column("bus", sa.Text, nullable=False),
    sa.Column("entries", sa.Integer, nullable=False),
    sa.Column("file", sa.Text, nullable=False),
    sa.Column("sha256", sa.Text, nullable=False),
    sa.Column("source", sa.Text, nullable=False, server_default="drive"),
    sa.Column("unreadable", sa.Text),
    sa.Index("backups_drive", "drive_key", "created"),
    sa.Index("backups_created", "created"),  # revision 0003: the fleet's sync
)

#: A backup's bytes, keyed by their SHA-256: identical content (the same drive backed up
#: twice unchanged, 10 000 drives of one default set) is stored once (revision 0002).
backup_content = sa.Table(
    "backup_content",
    metadata,
    sa.Column("sha256", sa.Text, primary_key=True),
    sa.Column("size", sa.Integer, nullable=False),
    sa.Column("data", sa.LargeBinary, nullable=False),
)

restores = sa.Table(
    "restores",
    metadata,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("backup", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("bus", sa.Text, nullable=False),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("dry_run", sa.Integer, nullable=False),
    sa.Column("finished", sa.Integer, nullable=False, server_default="0"),
    sa.Column("stored", sa.Integer, nullable=False, server_default="0"),
    sa.Column("interrupted", sa.Integer, nullable=False, server_default="0"),
    sa.Column("pre_backup", sa.Text),
    sa.Column("options", sa.Text, nullable=False),
    sa.Column("message", sa.Text),
)

restore_items = sa.Table(
    "restore_items",
    metadata,
    sa.Column("restore", sa.Text, primary_key=True),
    sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
    sa.Column("address", sa.Text, nullable=False),
    sa.Column("source", sa.Text, nullable=False),
    sa.Column("name", sa.Text, nullable=False),
    sa.Column("status", sa.Text, nullable=False),
    sa.Column("old_raw_hex", sa.Text),
    sa.Column("new_raw_hex", sa.Text),
    sa.Column("code", sa.Integer),
    sa.Column("meaning", sa.Text),
    sa.Column("message", sa.Text),
)

#: The parameter writes of a session (GET /sessions/{id}/audit), older than audit_log.
audit = sa.Table(
    "audit",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("time", sa.Float, nullable=False),
    sa.Column("client", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("address", sa.Text, nullable=False),
    sa.Column("name", sa.Text),
    sa.Column("old_raw_hex", sa.Text),
    sa.Column("new_raw_hex", sa.Text, nullable=False),
    sa.Column("old_value", sa.Text),
    sa.Column("new_value", sa.Text),
    sa.Index("audit_session", "session", "id"),
    sqlite_autoincrement=True,
)


def audit_record_columns() -> list[sa.Column[Any]]:
    """The columns of one audit record, as services/audit.py hashes them: the chained log's
    and the local queue's (services/outbox.py) hold the same record."""
    return [
        sa.Column("time", sa.Text, nullable=False),
        sa.Column("user", sa.Text, nullable=False),
        sa.Column("address", sa.Text, nullable=False),
        sa.Column("category", sa.Text, nullable=False),
        sa.Column("event", sa.Text, nullable=False),
        sa.Column("drive", sa.Text),
        sa.Column("result", sa.Text, nullable=False),
        sa.Column("message", sa.Text, nullable=False),
        sa.Column("details", sa.Text, nullable=False),
    ]


#: The hash-chained audit log (services/audit.py); append-only by triggers.
audit_log = sa.Table(
    "audit_log",
    metadata,
    sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
    *audit_record_columns(),
    sa.Column("prev", sa.Text, nullable=False),
    sa.Column("hash", sa.Text, nullable=False),
    sa.Index("audit_log_time", "time"),
)

users = sa.Table(
    "users",
    metadata,
    sa.Column("name", sa.Text, primary_key=True),
    sa.Column("role", sa.Text, nullable=False),
    sa.Column("hash", sa.Text, nullable=False),
    sa.Column("disabled", sa.Integer, nullable=False, server_default="0"),
    sa.Column("created", sa.Float, nullable=False),
)

api_tokens = sa.Table(
    "api_tokens",
    metadata,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("user", sa.Text, nullable=False),
    sa.Column("label", sa.Text, nullable=False, server_default=""),
    sa.Column("sha256", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("last_used", sa.Float),
    sa.Index("api_tokens_user", "user"),
)

#: The servodesk processes that share this store (revision 0003, services/fleet.py): each
#: registers on start and says it is alive every heartbeat.
gateways = sa.Table(
    "gateways",
    metadata,
    sa.Column("name", sa.Text, primary_key=True),
    sa.Column("url", sa.Text, nullable=False),
    sa.Column("buses", sa.Text, nullable=False, server_default="[]"),
    sa.Column("version", sa.Text, nullable=False, server_default=""),
    sa.Column("started", sa.Float, nullable=False),
    sa.Column("last_seen", sa.Float, nullable=False),
)

#: One row per drive the store knows (revision 0003): its identity and last backup (kept
#: from ``backups`` by services/fleet.py), the user's plant tag, the approved ("golden")
#: backup with who, when and why, and the last drift check's outcome. The fleet page reads
#: this table alone, so a page of 10 000 drives is one indexed query.
fleet_drives = sa.Table(
    "fleet_drives",
    metadata,
    sa.Column("drive_key", sa.Text, primary_key=True),
    sa.Column("plant_tag", sa.Text, unique=True),
    sa.Column("serial", sa.Text),
    sa.Column("profile_id", sa.Text, nullable=False, server_default=""),
    sa.Column("firmware", sa.Text),
    sa.Column("gateway", sa.Text),
    sa.Column("session", sa.Text),
    sa.Column("seen", sa.Float),
    sa.Column("last_backup", sa.Text),
    sa.Column("last_backup_time", sa.Text),
    sa.Column("last_backup_created", sa.Float),
    sa.Column("approved_backup", sa.Text),
    sa.Column("approved_by", sa.Text),
    sa.Column("approved_at", sa.Text),
    sa.Column("approved_reason", sa.Text),
    sa.Column("drift_state", sa.Text, nullable=False, server_default="unknown"),
    sa.Column("drift_count", sa.Integer),
    sa.Column("drift_time", sa.Text),
    sa.Column("alarms", sa.Integer),
    sa.Index("fleet_drives_drift", "drift_state"),
    sa.Index("fleet_drives_backup_created", "last_backup_created"),
)

#: Every drift check: a connected drive against its approved backup (revision 0003).
drift_results = sa.Table(
    "drift_results",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("gateway", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("backup", sa.Text, nullable=False),
    sa.Column("state", sa.Text, nullable=False),
    sa.Column("count", sa.Integer, nullable=False),
    sa.Column("differences", sa.Text, nullable=False),
    sa.Column("webhook", sa.Text),
    sa.Index("drift_results_drive", "drive_key", "id"),
    sqlite_autoincrement=True,
)

#: Every commissioning report made (revision 0004, services/report_store.py): its data's
#: canonical SHA-256 (printed in the report), the HTML exactly as it was served, and the PDF
#: once one was printed, so that ``servodesk report verify`` can check a copy later.
reports = sa.Table(
    "reports",
    metadata,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("plant_tag", sa.Text),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("by", sa.Text, nullable=False),
    sa.Column("sha256", sa.Text, nullable=False),
    sa.Column("html", sa.LargeBinary, nullable=False),
    sa.Column("html_sha256", sa.Text, nullable=False),
    sa.Column("pdf", sa.LargeBinary),
    sa.Column("pdf_sha256", sa.Text),
    sa.Index("reports_drive", "drive_key", "created"),
)

#: Every tuning job that ended, done, failed or stopped (revision 0005, services/
#: tuning_store.py): which drive, where, how, by which user and client, whether its gains
#: were left applied, and the TuningResult as JSON (docs/tuning.md), so that a restart or
#: another gateway keeps it.
tuning_results = sa.Table(
    "tuning_results",
    metadata,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("gateway", sa.Text, nullable=False),
    sa.Column("kind", sa.Text, nullable=False),
    sa.Column("mode", sa.Text, nullable=False),
    sa.Column("status", sa.Text, nullable=False),
    sa.Column("started", sa.Float, nullable=False),
    sa.Column("ended", sa.Float, nullable=False),
    sa.Column("by", sa.Text, nullable=False),
    sa.Column("client", sa.Text, nullable=False),
    sa.Column("applied", sa.Integer, nullable=False),
    sa.Column("result", sa.Text, nullable=False),
    sa.Index("tuning_results_drive", "drive_key", "ended"),
)

#: Scope captures the user kept (revision 0006, services/capture_store.py): the drive, where
#: and by whom, the user's title and note, the channels' summary (names, units, periods) for
#: the list, whether the drive's commissioning reports show it, and the recording (every
#: sample, raw, with each channel's raw-to-engineering scale) and trigger as JSON.
scope_captures = sa.Table(
    "scope_captures",
    metadata,
    sa.Column("id", sa.Text, primary_key=True),
    sa.Column("drive_key", sa.Text, nullable=False),
    sa.Column("session", sa.Text, nullable=False),
    sa.Column("gateway", sa.Text, nullable=False),
    sa.Column("title", sa.Text, nullable=False),
    sa.Column("note", sa.Text, nullable=False, server_default=""),
    sa.Column("time", sa.Text, nullable=False),
    sa.Column("created", sa.Float, nullable=False),
    sa.Column("by", sa.Text, nullable=False),
    sa.Column("client", sa.Text, nullable=False),
    sa.Column("window", sa.Text, nullable=False),
    sa.Column("samples", sa.Integer, nullable=False),
    sa.Column("channels", sa.Text, nullable=False),
    sa.Column("attached", sa.Integer, nullable=False, server_default="0"),
    sa.Column("sha256", sa.Text, nullable=False),
    sa.Column("data", sa.Text, nullable=False),
    sa.Index("scope_captures_drive", "drive_key", "created"),
)

#: Every table in the order an export writes and an import reads them.
TABLES: tuple[sa.Table, ...] = (
    backup_content,
    backups,
    restores,
    restore_items,
    audit,
    audit_log,
    users,
    api_tokens,
    gateways,
    fleet_drives,
    drift_results,
    reports,
    tuning_results,
    scope_captures,
)

#: The advisory lock keys of :func:`serialise` (PostgreSQL): any 64-bit numbers, fixed.
LOCK_MIGRATE = 0x5345_5256_0001
LOCK_AUDIT_CHAIN = 0x5345_5256_0002


def store_url(data_dir: Path, url: str = "") -> str:
    """The URL of the store: ``url`` when given (SERVODESK_STORE_URL), else the SQLite file
    in ``data_dir``."""
    if url:
        return url
    return URL.create("sqlite", database=str(Path(data_dir) / SQLITE_FILE)).render_as_string()


def check_url(url: str) -> URL:
    """``url`` parsed, with PostgreSQL always on psycopg 3; a clear StoreError otherwise."""
    hint = "use postgresql://user@host:port/database, or leave SERVODESK_STORE_URL empty"
    try:
        parsed = make_url(url)
    except (sa.exc.ArgumentError, ValueError):
        raise StoreError(f"{_redact(url)!r} is not a store URL", hint=hint) from None
    if parsed.get_backend_name() == "sqlite":
        if parsed.drivername not in ("sqlite", "sqlite+pysqlite"):
            raise StoreError(f"unsupported SQLite driver {parsed.drivername!r}", hint=hint)
        if not parsed.database or parsed.database == ":memory:":
            raise StoreError("a SQLite store needs a file (sqlite:////path/servodesk.db)")
        return parsed
    if parsed.get_backend_name() in ("postgresql", "postgres"):
        if parsed.drivername not in ("postgresql", "postgres", "postgresql+psycopg"):
            raise StoreError(
                f"unsupported PostgreSQL driver {parsed.drivername!r}",
                hint="servodesk talks to PostgreSQL through psycopg 3: postgresql://...",
            )
        return parsed.set(drivername="postgresql+psycopg")
    raise StoreError(
        f"unknown store URL scheme {parsed.drivername!r} in SERVODESK_STORE_URL", hint=hint
    )


def _redact(url: str) -> str:
    """A URL fit for a message: never its password."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except (sa.exc.ArgumentError, ValueError):
        return "<unparsable URL>"


def describe(engine: Engine) -> str:
    """The store's URL without its password (for messages and logs)."""
    return engine.url.render_as_string(hide_password=True)


def is_postgres(engine: Engine | Connection) -> bool:
    return engine.dialect.name == "postgresql"


def _sqlite_pragmas(dbapi_conn: Any, _record: Any) -> None:
    # pysqlite's own transaction handling is off (isolation_level None): the "begin" event
    # below says BEGIN itself, IMMEDIATE for a writer (SQLAlchemy's documented recipe).
    dbapi_conn.isolation_level = None
    cur = dbapi_conn.cursor()
    cur.execute("PRAGMA journal_mode=WAL")
    cur.execute("PRAGMA synchronous=FULL")
    cur.execute("PRAGMA busy_timeout=5000")
    cur.close()


def _sqlite_begin(conn: Connection) -> None:
    immediate = conn.get_execution_options().get("servodesk_write", False)
    conn.exec_driver_sql("BEGIN IMMEDIATE" if immediate else "BEGIN")


_migrated: set[str] = set()
_migrated_lock = threading.Lock()


def open_engine(url: str, *, migrate: bool = True) -> Engine:
    """An engine for ``url`` (:func:`check_url`), the schema upgraded to the newest revision
    (once per URL and process). A database that cannot be reached is a StoreError that
    names it, never a traceback."""
    parsed = check_url(url)
    if parsed.get_backend_name() == "sqlite":
        assert parsed.database is not None
        try:
            Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreError(
                f"cannot use the data directory {Path(parsed.database).parent}: {exc.strerror}",
                hint="set SERVODESK_DATA_DIR to a directory you can write",
            ) from exc
        engine = sa.create_engine(
            parsed, connect_args={"check_same_thread": False}, pool_pre_ping=False
        )
        event.listen(engine, "connect", _sqlite_pragmas)
        event.listen(engine, "begin", _sqlite_begin)
    else:
        engine = sa.create_engine(
            parsed,
            pool_pre_ping=True,  # A gateway outlives a database restart.
            pool_size=4,
            max_overflow=4,
            connect_args={"connect_timeout": 10},
        )
    key = describe(engine)
    try:
        with _migrated_lock:
            if migrate and key not in _migrated:
                upgrade(engine)
                _migrated.add(key)
            else:
                with engine.connect():
                    pass  # Reachable: refused now rather than at the first request.
    except sa.exc.SQLAlchemyError as exc:
        engine.dispose()
        raise StoreError(
            f"cannot open the store {key}: {_reason(exc)}",
            hint="check SERVODESK_STORE_URL (or SERVODESK_DATA_DIR), that the database runs "
            "and that this user may connect",
        ) from exc
    return engine


def _reason(exc: sa.exc.SQLAlchemyError) -> str:
    orig = getattr(exc, "orig", None)
    text = str(orig if orig is not None else exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def upgrade(engine: Engine) -> None:
    """Run the Alembic revisions up to head in one transaction, serialised between
    processes (PostgreSQL: advisory lock; SQLite: BEGIN IMMEDIATE)."""
    from alembic import command
    from alembic.config import Config
    from alembic.script import ScriptDirectory
    from alembic.util.exc import CommandError

    from servodesk import migrations

    cfg = Config()
    cfg.set_main_option("script_location", str(Path(migrations.__file__).parent))
    with write(engine) as conn:
        serialise(conn, LOCK_MIGRATE)
        cfg.attributes["connection"] = conn
        try:
            command.upgrade(cfg, "head")
        except CommandError as exc:
            # A store a newer servodesk upgraded (a revision this one does not ship): it is
            # not touched, and the message says what to do rather than Alembic's words.
            known = ScriptDirectory.from_config(cfg).get_current_head()
            raise StoreError(
                f"the store is at a schema revision this servodesk does not know ({exc}); "
                f"it knows revisions up to {known}",
                hint="a newer servodesk wrote it: use that version, or give this one "
                "another store (SERVODESK_STORE_URL or SERVODESK_DATA_DIR)",
            ) from exc


def revision(engine: Engine) -> str | None:
    """The schema revision the database is at (None: not a servodesk store yet)."""
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


@contextlib.contextmanager
def write(engine: Engine) -> Iterator[Connection]:
    """One writing transaction: committed when the block ends, rolled back on an error
    (SQLite: BEGIN IMMEDIATE, the write lock first)."""
    with engine.connect().execution_options(servodesk_write=True) as conn, conn.begin():
        yield conn


@contextlib.contextmanager
def read(engine: Engine) -> Iterator[Connection]:
    """One reading transaction (a consistent view)."""
    with engine.connect() as conn, conn.begin():
        yield conn


def rows(engine: Engine, statement: sa.Executable) -> list[sa.RowMapping]:
    """``statement``'s rows, read in one transaction; a database failure as a StoreError."""
    try:
        with read(engine) as conn:
            return list(conn.execute(statement).mappings().all())
    except sa.exc.SQLAlchemyError as exc:
        raise store_error(exc, engine) from exc


@contextlib.contextmanager
def transaction(engine: Engine) -> Iterator[Connection]:
    """One writing transaction (:func:`write`), a database failure as a StoreError."""
    try:
        with write(engine) as conn:
            yield conn
    except sa.exc.SQLAlchemyError as exc:
        raise store_error(exc, engine) from exc


def serialise(conn: Connection, key: int) -> None:
    """Hold the lock ``key`` until this transaction ends (PostgreSQL). On SQLite the
    transaction's write lock (BEGIN IMMEDIATE) serialises writers already."""
    if is_postgres(conn):
        conn.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": key})


def insert_ignore(conn: Connection, table: sa.Table) -> Any:
    """INSERT ... ON CONFLICT DO NOTHING on either engine (content stored once)."""
    if is_postgres(conn):
        from sqlalchemy.dialects.postgresql import insert as pg_insert

        return pg_insert(table).on_conflict_do_nothing()
    from sqlalchemy.dialects.sqlite import insert as sqlite_insert

    return sqlite_insert(table).on_conflict_do_nothing()


# SQLSTATE classes and codes that say the database is not there rather than that the request
# was wrong (PostgreSQL manual, Appendix A "PostgreSQL Error Codes"): class 08 connection
# exception; 57P01-57P03 admin/crash shutdown, cannot connect now; 53300 too many connections;
# 3D000 the database does not exist (dropped or renamed under the gateway).
_LOST_CODES = frozenset({"57P01", "57P02", "57P03", "53300", "3D000"})


def is_unreachable(exc: BaseException) -> bool:
    """Whether ``exc`` says the central PostgreSQL store cannot be reached (a connection-
    level failure), as opposed to a refused statement (integrity, programming error, a
    serialisation failure or deadlock: those are the request's, and retrying them from a
    queue would not help).

    A server that is down, unreachable, restarting or gone gives a psycopg
    OperationalError without SQLSTATE (the connection attempt failed), one of class 08, or
    an InterfaceError / an invalidated connection (the socket broke mid-statement); the
    pool's time-out counts too. SQLite errors never count: a SQLite store is the local file.
    """
    if isinstance(exc, StoreUnavailable):
        return True
    if isinstance(exc, sa.exc.TimeoutError):  # The pool's: every connection hangs.
        return True
    if not isinstance(exc, sa.exc.DBAPIError):
        return False
    try:
        import psycopg
    except ImportError:  # pragma: no cover - psycopg is a dependency
        return False
    orig = exc.orig
    if not isinstance(orig, psycopg.Error):
        return False  # SQLite (or another driver): not a remote store.
    if exc.connection_invalidated or isinstance(orig, psycopg.InterfaceError):
        return True
    if not isinstance(orig, psycopg.OperationalError):
        return False
    code = orig.sqlstate
    return code is None or code.startswith("08") or code in _LOST_CODES


def store_error(exc: sa.exc.SQLAlchemyError, engine: Engine | None = None) -> StoreError:
    """A database failure as the error the user sees: :class:`StoreUnavailable` (503,
    naming the store) when the central store cannot be reached."""
    if is_unreachable(exc):
        where = f" {describe(engine)}" if engine is not None else ""
        return StoreUnavailable(
            f"the central store{where} cannot be reached: {_reason(exc)}", hint=QUEUE_HINT
        )
    return StoreError(f"store error: {_reason(exc)}", hint="see the server log")
