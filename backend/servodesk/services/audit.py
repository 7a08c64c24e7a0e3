"""The audit log: who did what to which drive, when, from where, and whether it worked.

IEC 62443-4-2 CR 2.8 (auditable events) asks a component to record access control, request
errors, control system events, backup and restore, configuration changes and the like, each
with a timestamp, source, category, type, event id and result. One record per event, in the
``audit_log`` table of the store (``<data_dir>/servodesk.db``, or the PostgreSQL of
``SERVODESK_STORE_URL`` that several gateways share: services/db.py).

**Append-only, with a hash chain** (CR 3.9, protection of audit information): record ``n``
stores ``hash = sha256(prev_hash + canonical(record))`` where ``prev_hash`` is record
``n - 1``'s hash (64 zeros for the first) and ``canonical`` is the compact JSON array of its
columns (:func:`canonical`). Triggers refuse UPDATE and DELETE (and TRUNCATE on PostgreSQL);
someone who edits the database past them changes a hash, and :meth:`AuditLog.verify`
(``servodesk audit verify``) names the first record that no longer fits: altered, missing
from the middle, or moved. Records cut off the end leave a shorter valid chain; compare the
head hash verify prints with one noted earlier to see that.

**Recording never blocks and never fails the caller.** :meth:`AuditLog.record` queues the
record and returns; one writer thread appends queued records in a transaction that reads the
last hash first, serialised with every other writer of the store, so the chain never forks:
on SQLite by ``BEGIN IMMEDIATE`` (a second process, the CLI, waits for SQLite's write lock),
on PostgreSQL by a transaction-scoped advisory lock that every gateway's writer takes before
it reads the head (:func:`servodesk.services.db.serialise`). The dead-man's stop therefore
never waits on the database (docs/security.md). On a central PostgreSQL store, a batch the
store cannot take because it is unreachable goes to the gateway's local queue
(:attr:`AuditLog.outbox`, services/outbox.py), and so does every batch after it until
:meth:`AuditLog.sync_queued` has chained the queue onto the central log, oldest first, with
the records' own times (their position on the chain is the time of the sync). Any other
record that cannot be written is logged and dropped. Readers (:meth:`query`, :meth:`verify`,
:meth:`export`) first wait for the queue to drain, so a request sees the records of
everything done before it (records in the local queue are not on the central log yet).

Who did it: the ``who`` argument, else the identity of the request being served (set by the
API's middleware through :func:`acting`), else :data:`SYSTEM` (the dead-man's thread, the
simulator).
"""

from __future__ import annotations

import contextlib
import contextvars
import csv
import hashlib
import io
import json
import logging
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol

import sqlalchemy as sa
from sqlalchemy.engine import RowMapping

from servodesk.services import db

if TYPE_CHECKING:
    from servodesk.services.outbox import Outbox

log = logging.getLogger(__name__)

Category = Literal[
    "access_control",
    "request_error",
    "control",
    "motion",
    "write",
    "backup",
    "restore",
    "configuration",
    "user_admin",
]

#: The category of an event is the first part of its id: ``control.taken`` is control.
PREFIXES: dict[str, Category] = {
    "access": "access_control",
    "request": "request_error",
    "control": "control",
    "motion": "motion",
    "write": "write",
    "backup": "backup",
    "restore": "restore",
    "config": "configuration",
    "user": "user_admin",
}
CATEGORIES: tuple[Category, ...] = tuple(PREFIXES.values())

#: The hash before the first record.
GENESIS = "0" * 64

#: Records queued and not yet written past which new ones are dropped (with a log line): a
#: database that cannot be written must not eat the server's memory.
MAX_PENDING = 100_000

_COLUMNS = (
    "seq",
    "time",
    "user",
    "address",
    "category",
    "event",
    "drive",
    "result",
    "message",
    "details",
)


class Who(Protocol):
    """Anyone with a name and an address (:class:`servodesk.api.identity.Caller`)."""

    @property
    def user(self) -> str: ...

    @property
    def address(self) -> str: ...


@dataclass(frozen=True)
class Actor:
    user: str
    address: str = ""


#: Events nobody asked for: the dead-man, a lapse of control, the simulator.
SYSTEM = Actor("system")

_acting: contextvars.ContextVar[Who | None] = contextvars.ContextVar(
    "servodesk_audit_actor", default=None
)


def acting(who: Who | None) -> contextvars.Token[Who | None]:
    """Make ``who`` the actor of events recorded in this context (a request and the tasks
    it starts); the API's middleware calls it with the request's identity."""
    return _acting.set(who)


def current_actor() -> Who:
    return _acting.get() or SYSTEM


def category_of(event: str) -> Category:
    """The category of an event id; a programming error (ValueError) for an unknown one."""
    prefix = event.split(".", 1)[0]
    try:
        return PREFIXES[prefix]
    except KeyError:
        raise ValueError(
            f"audit event {event!r}: its prefix must be one of {', '.join(PREFIXES)}"
        ) from None


def utc_now() -> str:
    """ISO 8601 in UTC with microseconds, e.g. ``2026-12-07T08:30:00.123456Z`` (sorts as
    text, so the time filters compare strings)."""
    return utc_text(datetime.now(UTC))


def utc_text(value: datetime) -> str:
    """A datetime in the stored format (a naive one is taken as UTC)."""
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    # isoformat, not strftime: the year is always four digits (strftime writes year 1 as "1").
    text = value.astimezone(UTC).replace(tzinfo=None).isoformat(timespec="microseconds")
    return text + "Z"


def canonical(row: tuple[Any, ...]) -> bytes:
    """The bytes a record's hash covers: its columns (seq .. details, details as the stored
    JSON text) as a compact JSON array, UTF-8."""
    return json.dumps(list(row), ensure_ascii=False, separators=(",", ":")).encode("utf-8")


def chain_hash(prev: str, row: tuple[Any, ...]) -> str:
    return hashlib.sha256(prev.encode("ascii") + canonical(row)).hexdigest()


@dataclass(frozen=True)
class Verdict:
    """What :meth:`AuditLog.verify` found."""

    ok: bool
    records: int  # Records checked (up to the first broken one).
    head: str  # Hash of the last good record (GENESIS for an empty log).
    broken: int | None = None  # seq of the first record that does not fit.
    problem: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "ok": self.ok,
            "records": self.records,
            "head": self.head,
            "broken": self.broken,
            "problem": self.problem,
        }


@dataclass(frozen=True)
class _Pending:
    time: str
    user: str
    address: str
    category: str
    event: str
    drive: str | None
    result: str
    message: str
    details: str


class AuditLog:
    """The append-only audit log in the store: ``where`` is the store's URL
    (``Store.url``), or the path of a SQLite file (``<data_dir>/servodesk.db``)."""

    def __init__(self, where: Path | str) -> None:
        if isinstance(where, Path) or "://" not in where:
            self.path: Path | None = Path(where)
            self.url = sa.URL.create("sqlite", database=str(where)).render_as_string()
        else:
            self.path, self.url = None, where
        self._engine = db.open_engine(self.url)
        self._cond = threading.Condition()  # The queue and its counters.
        self._queue: list[_Pending] = []
        self._queued = 0
        self._done = 0
        self._closed = False
        self._thread: threading.Thread | None = None
        #: The local queue while the central store is unreachable (PostgreSQL stores only;
        #: set by api/state.py). None: a record that cannot be written is dropped.
        self.outbox: Outbox | None = None
        # The writer's append and the sync of the queue: one at a time, so the queue's
        # records reach the chain before any later record.
        self._chain = threading.Lock()

    # Recording --------------------------------------------------------------------------

    def record(
        self,
        event: str,
        *,
        who: Who | None = None,
        drive: str | None = None,
        ok: bool = True,
        message: str = "",
        details: dict[str, Any] | None = None,
    ) -> None:
        """Queue one event; returns at once and never raises for a database problem.

        ``event`` is a stable id whose prefix is its category (:data:`PREFIXES`), e.g.
        ``control.taken``, ``access.login_failed``, ``user.created``; ``drive`` the session
        or drive key it concerns; ``ok``/``message`` the result; ``details`` anything else
        as JSON (never passwords, tokens or request bodies).
        """
        category = category_of(event)
        actor = who or current_actor()
        try:
            user, address = _clean(str(actor.user)), _clean(str(actor.address or ""))
        except Exception:  # A lazy identity that cannot be read must not fail the caller.
            log.exception("audit: the actor of %s cannot be read", event)
            user, address = SYSTEM.user, SYSTEM.address
        try:
            text = json.dumps(details or {}, sort_keys=True, default=str, ensure_ascii=False)
        except (TypeError, ValueError):  # Keys of mixed types, a cycle: keep what can be kept.
            text = json.dumps({"unserialisable": repr(details)}, ensure_ascii=False)
        text = _clean(text)
        message = _clean(message)
        drive = _clean(drive) if drive is not None else None
        with self._cond:
            # The time is taken under the queue's lock: within a process the records' times
            # never go backwards along the chain.
            pending = _Pending(
                utc_now(),
                user,
                address,
                category,
                event,
                drive,
                "success" if ok else "failure",
                message,
                text,
            )
            if self._closed:
                log.warning("audit log closed; event not recorded: %s", pending)
                return
            if len(self._queue) >= MAX_PENDING:
                log.error("audit queue full; event not recorded: %s", pending)
                return
            self._queue.append(pending)
            self._queued += 1
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._run, name="servodesk-audit", daemon=True
                )
                self._thread.start()
            self._cond.notify_all()

    def flush(self, timeout: float = 5.0) -> bool:
        """Wait until everything queued so far is written (or dropped); False on time-out."""
        deadline = time.monotonic() + timeout
        with self._cond:
            target = self._queued
            while self._done < target:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
        return True

    def close(self) -> None:
        self.flush()
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        self._engine.dispose()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closed:
                    self._cond.wait()
                if not self._queue:
                    return
                batch, self._queue = self._queue, []
            try:
                self._deliver(batch)
            except Exception:
                log.exception("audit log: %d records could not be written", len(batch))
                for p in batch:
                    log.error("audit record lost: %s", p)
            with self._cond:
                self._done += len(batch)
                self._cond.notify_all()

    def _deliver(self, batch: list[_Pending]) -> None:
        """The batch onto the central chain; into the local queue when the store is
        unreachable or the queue already holds older records (their order is kept)."""
        outbox = self.outbox
        with self._chain:
            if outbox is not None and outbox.has_audit():
                outbox.add_audit([_queued(p) for p in batch])
                return
            try:
                self._append(batch)
            except Exception as exc:
                if outbox is None or not db.is_unreachable(exc):
                    raise
                outbox.lost(exc)
                outbox.add_audit([_queued(p) for p in batch])
                log.warning("audit log: %d records queued locally", len(batch))

    def _append(self, batch: list[_Pending], before_commit: Any = None) -> str:
        """One transaction: take the chain's lock, read the last record, chain the batch
        onto it; the new head's hash. Another process's writer waits for the lock, then
        reads this batch's head. ``before_commit(head)`` runs just before the commit."""
        t = db.audit_log
        with db.write(self._engine) as conn:
            db.serialise(conn, db.LOCK_AUDIT_CHAIN)
            last = conn.execute(
                sa.select(t.c.seq, t.c.hash).order_by(t.c.seq.desc()).limit(1)
            ).first()
            seq, prev = (int(last.seq), str(last.hash)) if last else (0, GENESIS)
            rows: list[dict[str, Any]] = []
            for p in batch:
                seq += 1
                row = (
                    seq,
                    p.time,
                    p.user,
                    p.address,
                    p.category,
                    p.event,
                    p.drive,
                    p.result,
                    p.message,
                    p.details,
                )
                digest = chain_hash(prev, row)
                rows.append({**dict(zip(_COLUMNS, row, strict=True)), "prev": prev, "hash": digest})
                prev = digest
            conn.execute(sa.insert(t), rows)
            if before_commit is not None:
                before_commit(prev)
        return prev

    def sync_queued(self) -> int:
        """Chain the locally queued records onto the central log, oldest first; the number
        appended. Raises what the central store raises (it is still away).

        Exactly once: just before the central commit the queue notes the hash its last record
        gets there; a sync cut off after that commit finds the hash on the chain and only
        deletes the queue, one cut off before it appends again."""
        outbox = self.outbox
        if outbox is None:
            return 0
        with self._chain:
            queue = outbox.audit_queue()
            marked = [r for r in queue if r["synced_hash"] is not None]
            if marked:
                t = db.audit_log
                mark = marked[-1]
                with db.read(self._engine) as conn:
                    on_chain = conn.execute(
                        sa.select(t.c.seq).where(t.c.hash == mark["synced_hash"]).limit(1)
                    ).first()
                if on_chain is not None:
                    outbox.drop_audit(int(mark["id"]))
                    queue = [r for r in queue if r["id"] > mark["id"]]
                else:
                    outbox.unmark_audit()
            if not queue:
                return 0
            last_id = int(queue[-1]["id"])
            batch = [_Pending(**{k: r[k] for k in _Pending.__dataclass_fields__}) for r in queue]
            self._append(batch, before_commit=lambda head: outbox.mark_audit(last_id, head))
            outbox.drop_audit(last_id)
            return len(batch)

    # Reading ----------------------------------------------------------------------------

    def query(
        self,
        *,
        category: str | None = None,
        user: str | None = None,
        drive: str | None = None,
        event: str | None = None,
        since: datetime | None = None,
        until: datetime | None = None,
        limit: int = 200,
        before: int | None = None,
    ) -> list[dict[str, Any]]:
        """Records matching every given filter, newest first (``before``: seq below it)."""
        self.flush()
        t = db.audit_log
        query = sa.select(t)
        for column, value in (
            (t.c.category, category),
            (t.c.user, user),
            (t.c.drive, drive),
            (t.c.event, event),
        ):
            if value:
                query = query.where(column == value)
        if since is not None:
            query = query.where(t.c.time >= utc_text(since))
        if until is not None:
            query = query.where(t.c.time <= utc_text(until))
        if before is not None:
            query = query.where(t.c.seq < before)
        query = query.order_by(t.c.seq.desc()).limit(limit)
        return [_public(r) for r in db.rows(self._engine, query)]

    def _rows(self, since: datetime | None = None) -> Iterator[RowMapping]:
        """Every record in order, read in pages (no transaction is held between pages)."""
        t = db.audit_log
        after = 0
        while True:
            # A store that cannot be read is a StoreError (503 when it is unreachable).
            page = db.rows(
                self._engine, sa.select(t).where(t.c.seq > after).order_by(t.c.seq).limit(1000)
            )
            if not page:
                return
            for r in page:
                if since is None or r["time"] >= utc_text(since):
                    yield r
            after = page[-1]["seq"]

    def verify(self) -> Verdict:
        """Recompute the chain from the first record; the first one that does not fit."""
        self.flush()
        prev = GENESIS
        expected = 1
        count = 0
        for r in self._rows():
            seq = r["seq"]
            if seq != expected:
                what = (
                    f"record {expected} is missing (the next is {seq})"
                    if seq > expected
                    else f"record {seq} is out of order (expected {expected})"
                )
                return Verdict(False, count, prev, expected, what)
            if r["prev"] != prev:
                return Verdict(
                    False,
                    count,
                    prev,
                    seq,
                    f"record {seq} does not follow record {seq - 1} (its previous hash differs: "
                    "a record before it was removed, replaced or moved)",
                )
            row = tuple(r[c] for c in _COLUMNS)
            if chain_hash(prev, row) != r["hash"]:
                return Verdict(
                    False, count, prev, seq, f"record {seq} was altered (its hash does not match)"
                )
            prev = r["hash"]
            expected += 1
            count += 1
        return Verdict(True, count, prev)

    def export(self, fmt: Literal["jsonl", "csv"], since: datetime | None = None) -> Iterator[str]:
        """Every record (from ``since``) oldest first, with its hashes, as JSON lines or CSV."""
        self.flush()
        fields = [*_COLUMNS, "prev", "hash"]
        if fmt == "csv":
            buf = io.StringIO()
            writer = csv.writer(buf, lineterminator="\n")
            writer.writerow(fields)
            yield buf.getvalue()
        for r in self._rows(since):
            if fmt == "jsonl":
                yield json.dumps(_public(r), ensure_ascii=False) + "\n"
            else:
                buf = io.StringIO()
                csv.writer(buf, lineterminator="\n").writerow([_csv_cell(r[f]) for f in fields])
                yield buf.getvalue()


def _queued(p: _Pending) -> dict[str, Any]:
    return {k: getattr(p, k) for k in _Pending.__dataclass_fields__}


def _clean(text: str) -> str:
    """``text`` as valid UTF-8: a lone surrogate (a path or header decoded with
    surrogateescape) becomes "?" instead of failing the writer's whole batch."""
    return text.encode("utf-8", "replace").decode("utf-8")


def _csv_cell(value: Any) -> Any:
    """A cell a spreadsheet shows as text: formula-like text gets a leading quote (CSV
    injection, OWASP). The hash covers the stored value, not this rendering."""
    if isinstance(value, str) and value[:1] in ("=", "+", "-", "@", "\t", "\r"):
        return "'" + value
    return "" if value is None else value


def _public(r: RowMapping) -> dict[str, Any]:
    out = {c: r[c] for c in _COLUMNS}
    out["details"] = json.loads(r["details"]) if r["details"] else {}
    out["prev"] = r["prev"]
    out["hash"] = r["hash"]
    return out


class Discard:
    """The audit log of a service built without one (the CLI's tune command, tests)."""

    def record(
        self,
        event: str,
        *,
        who: Who | None = None,
        drive: str | None = None,
        ok: bool = True,
        message: str = "",
        details: dict[str, Any] | None = None,
    ) -> None:
        category_of(event)  # Still a programming error to use an unknown id.

    def flush(self, timeout: float = 5.0) -> bool:
        return True  # Nothing is ever queued.


class Recorder(Protocol):
    """What a service needs of the audit log: :meth:`AuditLog.record`."""

    def record(
        self,
        event: str,
        *,
        who: Who | None = None,
        drive: str | None = None,
        ok: bool = True,
        message: str = "",
        details: dict[str, Any] | None = None,
    ) -> None: ...

    def flush(self, timeout: float = 5.0) -> bool:
        """Block until what was recorded so far is written (a restore's intent must be in the
        chain before its writes go out: services/restore.py). Call it off the event loop."""
        ...


DISCARD = Discard()


@contextlib.contextmanager
def as_actor(who: Who | None) -> Iterator[None]:
    """``with as_actor(identity):`` events recorded inside are ``identity``'s."""
    token = acting(who)
    try:
        yield
    finally:
        _acting.reset(token)
