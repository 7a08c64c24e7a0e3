"""The local queue of a gateway whose central store is away (issue 49, "Plant scale";
docs/deployment.md, "When the central store is unreachable").

A gateway on a central PostgreSQL store keeps working when the database cannot be reached
(a connection-level failure, :func:`servodesk.services.db.is_unreachable`): what it must
not lose goes to ``<data_dir>/outbox.db``, a SQLite file with the store's own schema
(opened by :func:`servodesk.services.db.open_engine`, so the migrations apply; WAL with
``synchronous=FULL``: a queued record survives a crash or a power loss), and
:meth:`Outbox.sync` copies it to the central store when it answers again.

What is queued:

- **backups** (their record and content), the automatic one before a restore included: the
  API answers 201 with ``queued: true``, and the backup opens by its id while offline;
- **tuning results** (services/tuning_store.py);
- **audit records** (services/audit.py): kept in ``outbox_audit`` in the order they were
  made, with their own times, and chained onto the central hash chain at the sync; their
  position on the chain is therefore the time of the sync, not of the event.

What is not: the ``audit`` table of parameter writes (its ids are the central store's; the
same writes are ``write.object`` records of the hash-chained log, which is queued), scope
captures, reports, fleet and drift writes and a restore's journal (a restore whose store is
lost stops as interrupted). Those answer 503 naming the unreachable store.

The sync copies rows with INSERT ... ON CONFLICT DO NOTHING (the row copy of ``servodesk
store import``), then deletes them here: a sync cut off between the two copies again and
never duplicates. A synced backup's ``created`` is the time of the sync (when the central
store got it: the fleet's sync reads backups by ``created``, services/fleet.py); its
``time`` stays the backup's own.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from servodesk.services import db

log = logging.getLogger(__name__)

#: The queue's file in the data directory.
OUTBOX_FILE = "outbox.db"

#: The tables whose rows are queued as they are, in the order a sync copies them (content
#: before the backups that name it).
QUEUED_TABLES: tuple[sa.Table, ...] = (db.backup_content, db.backups, db.tuning_results)

# Audit records waiting for the central chain. Not a table of the store's schema (it exists
# only in the outbox): made by create_all, which Alembic's revisions never touch.
_queue_metadata = sa.MetaData()
outbox_audit = sa.Table(
    "outbox_audit",
    _queue_metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    *db.audit_record_columns(),
    # Set on the last record of a sync just before the central commit: the hash that record
    # gets on the chain. A sync cut off after that commit finds the hash there and only
    # deletes; one cut off before finds nothing and appends again (never twice).
    sa.Column("synced_hash", sa.Text),
    sqlite_autoincrement=True,
)


@dataclass
class StoreHealth:
    """What the status bar says of the central store."""

    reachable: bool = True
    #: When the store was first found unreachable (epoch s; None while it answers).
    since: float | None = None
    last_error: str | None = None
    last_sync: float | None = None
    synced: int = 0  # Records synced since the process started.


class Outbox:
    """The local queue at ``<data_dir>/outbox.db`` of the central store ``central``."""

    def __init__(self, data_dir: Path, central: Engine) -> None:
        self.path = Path(data_dir) / OUTBOX_FILE
        self.central = central
        self.engine = db.open_engine(
            sa.URL.create("sqlite", database=str(self.path)).render_as_string()
        )
        _queue_metadata.create_all(self.engine)
        self.health = StoreHealth()
        self._lock = threading.Lock()  # health
        self._sync_lock = threading.Lock()  # one sync at a time

    def close(self) -> None:
        self.engine.dispose()

    # The central store's health -------------------------------------------------------------

    def lost(self, exc: BaseException) -> None:
        """The central store failed a write at connection level (``exc``)."""
        reason = str(getattr(exc, "message", "") or exc).splitlines()[0][:300]
        with self._lock:
            h = self.health
            if h.reachable:
                log.warning(
                    "store: %s unreachable (%s); queueing locally in %s",
                    db.describe(self.central),
                    reason,
                    self.path,
                )
                h.reachable, h.since = False, time.time()
            h.last_error = reason

    def answered(self) -> None:
        with self._lock:
            h = self.health
            if not h.reachable:
                log.warning("store: %s answers again", db.describe(self.central))
            h.reachable, h.since = True, None

    def note(self, *, synced: int = 0, error: str | None = None) -> None:
        """A sync's outcome: records synced (the error cleared), or why it failed."""
        with self._lock:
            h = self.health
            h.last_error = error
            if synced:
                h.last_sync = time.time()
                h.synced += synced

    def status(self) -> dict[str, Any]:
        """The status bar's store entry (services/status.py)."""
        with self._lock:
            h = self.health
            out: dict[str, Any] = {
                "reachable": h.reachable,
                "since": h.since,
                "last_sync": h.last_sync,
                "last_error": h.last_error,
                "synced": h.synced,
            }
        out["queued"] = self.counts()
        return out

    # Queueing ---------------------------------------------------------------------------------

    def add(
        self, table: sa.Table, row: dict[str, Any], content: dict[str, Any] | None = None
    ) -> None:
        """Queue one row of ``table`` (one of :data:`QUEUED_TABLES`), with a backup's content
        row, in one local transaction (committed and fsync'd when this returns)."""
        with db.transaction(self.engine) as conn:
            if content is not None:
                conn.execute(db.insert_ignore(conn, db.backup_content), content)
            conn.execute(sa.insert(table).values(row))

    def add_audit(self, records: list[dict[str, Any]]) -> None:
        """Queue audit records (the columns of ``outbox_audit`` less id and synced_hash) in
        the order given."""
        if records:
            with db.transaction(self.engine) as conn:
                conn.execute(sa.insert(outbox_audit), records)

    def has_audit(self) -> bool:
        rows = db.rows(self.engine, sa.select(outbox_audit.c.id).limit(1))
        return bool(rows)

    def counts(self) -> dict[str, int]:
        """Records queued, by kind (backups, tuning_results, audit_log)."""
        out: dict[str, int] = {}
        with db.read(self.engine) as conn:
            for name, table in (
                ("backups", db.backups),
                ("tuning_results", db.tuning_results),
                ("audit_log", outbox_audit),
            ):
                out[name] = int(
                    conn.execute(sa.select(sa.func.count()).select_from(table)).scalar() or 0
                )
        return out

    def rows(self, statement: sa.Executable) -> list[sa.RowMapping]:
        """``statement``'s rows in the queue (a backup opened while offline)."""
        return db.rows(self.engine, statement)

    # Sync ---------------------------------------------------------------------------------

    def sync_rows(self) -> int:
        """Copy the queued backups and tuning results to the central store, then delete them
        here; the number of records (content rows not counted). Raises what the central store
        raises (SQLAlchemyError)."""
        with self._sync_lock:
            taken: dict[str, list[dict[str, Any]]] = {}
            with db.read(self.engine) as conn:
                for table in QUEUED_TABLES:
                    order: list[Any] = list(table.primary_key.columns)
                    if table is db.backups:
                        order = [sa.literal_column("rowid")]  # The order they were made in.
                    taken[table.name] = [
                        dict(r) for r in conn.execute(sa.select(table).order_by(*order)).mappings()
                    ]
            if not any(taken.values()):
                return 0
            now = time.time()
            with db.write(self.central) as conn:
                for table in QUEUED_TABLES:
                    rows = taken[table.name]
                    if table is db.backups:
                        rows = [r | {"created": now} for r in rows]
                    if rows:
                        conn.execute(db.insert_ignore(conn, table), rows)
            # A crash here leaves rows the central store has: the next sync copies them
            # again, and ON CONFLICT DO NOTHING keeps one of each.
            with db.write(self.engine) as conn:
                for table in QUEUED_TABLES:
                    keys = [r[table.primary_key.columns[0].name] for r in taken[table.name]]
                    column = table.primary_key.columns[0]
                    for i in range(0, len(keys), 500):
                        conn.execute(sa.delete(table).where(column.in_(keys[i : i + 500])))
            return len(taken["backups"]) + len(taken["tuning_results"])

    def audit_queue(self) -> list[dict[str, Any]]:
        """The queued audit records, oldest first (with ``id`` and ``synced_hash``)."""
        return [dict(r) for r in self.rows(sa.select(outbox_audit).order_by(outbox_audit.c.id))]

    def mark_audit(self, last_id: int, digest: str) -> None:
        with db.transaction(self.engine) as conn:
            conn.execute(
                sa.update(outbox_audit)
                .where(outbox_audit.c.id == last_id)
                .values(synced_hash=digest)
            )

    def unmark_audit(self) -> None:
        with db.transaction(self.engine) as conn:
            conn.execute(
                sa.update(outbox_audit)
                .where(outbox_audit.c.synced_hash.is_not(None))
                .values(synced_hash=None)
            )

    def drop_audit(self, last_id: int) -> None:
        """Delete the queued audit records up to ``last_id`` (they are on the chain)."""
        with db.transaction(self.engine) as conn:
            conn.execute(sa.delete(outbox_audit).where(outbox_audit.c.id <= last_id))


class StoreSync:
    """The task that empties the queue into the central store (owned by api/state.py).

    Every ``retry_s`` seconds (SERVODESK_STORE_RETRY_S) while something is queued or the
    store was found away: copy the queued rows (:meth:`Outbox.sync_rows`), then chain the
    queued audit records (``sync_audit``: AuditLog.sync_queued); a store still away is
    noted and tried again at the next period. A sync that moved records is logged and
    audited (``config.store_synced``).
    """

    def __init__(
        self,
        outbox: Outbox,
        sync_audit: Callable[[], int],
        record: Callable[..., None],
        retry_s: float = 5.0,
    ) -> None:
        self.outbox = outbox
        self.sync_audit = sync_audit
        self.record = record
        self.retry_s = retry_s
        self._task: asyncio.Task[None] | None = None

    def queued(self) -> dict[str, int]:
        return self.outbox.counts()

    def sync_once(self) -> int:
        """One try (blocking: call it in a thread); the records synced, or -1 when the
        store is still away."""
        try:
            with self.outbox.central.connect():
                pass  # Reachable at all? (a cheap refusal while it is away)
            count = self.outbox.sync_rows()
            count += self.sync_audit()
        except (sa.exc.SQLAlchemyError, db.StoreError) as exc:
            if not db.is_unreachable(exc):
                # A refused row (a schema newer than this gateway's?): the queue stays, the
                # reason is shown in the status and logged; the next period tries again.
                log.exception("store: the local queue cannot be synced")
                self.outbox.note(error=str(exc).splitlines()[0][:300])
                return -1
            self.outbox.lost(exc)
            return -1
        self.outbox.answered()
        self.outbox.note(synced=count)
        if count:
            log.warning("store: %d records synced", count)
            self.record(
                "config.store_synced",
                message=f"store: {count} records synced",
                details={"records": count, "store": db.describe(self.outbox.central)},
            )
        return count

    def due(self) -> bool:
        """Whether a try is worth it: something is queued, or the store was found away."""
        return not self.outbox.health.reachable or any(self.queued().values())

    async def run(self) -> None:
        while True:
            try:
                if await asyncio.to_thread(self.due):
                    await asyncio.to_thread(self.sync_once)
            except Exception:  # The local file itself: logged, tried again.
                log.exception("store: sync of the local queue failed")
            await asyncio.sleep(self.retry_s)

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self.run(), name="store-sync")

    async def stop(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
