"""The store: backup records and their content, restore reports (item by item) and the
audit of parameter writes, on SQLite or PostgreSQL (services/db.py, docs/deployment.md).

The default is one SQLite database (``<data_dir>/servodesk.db``) in WAL mode with
``synchronous=FULL``; ``SERVODESK_STORE_URL=postgresql://...`` puts the same schema on a
central PostgreSQL that several gateways share. Every change is one transaction, so a crash
at any moment leaves either the old or the new state, and a committed restore item survives
a power loss. A restore commits its items a batch at a time (:meth:`Store.journal`, the group
commit of services/restore.py), in a thread.

A backup's bytes are in the store (``backup_content``, keyed by SHA-256: identical content
is stored once), so every machine on the store can open every backup. The data directory's
``backups/`` keeps a local copy of each file, written by :func:`write_new_file`: temporary
file in the same directory, fsync, then a hard link to the final name (which fails if the
name exists), so a file is never half-written under its name and never replaced. A file
another gateway made is copied there from the store when it is first opened here
(:meth:`Store.backup_file_row`); the files of a data directory made before the content was
in the store are copied into it when the store opens.

On a central PostgreSQL store that cannot be reached, a new backup's record and content wait
in the gateway's local queue (:attr:`Store.outbox`, services/outbox.py), and a backup is
looked for there too when the store lacks it or is away.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Connection, RowMapping

from servodesk.errors import ConflictError, NotFoundError, ServodeskError
from servodesk.files import inside, remove_stale_temp_files
from servodesk.services import db
from servodesk.services.db import StoreError, StoreUnavailable
from servodesk.services.outbox import Outbox

__all__ = ["Store", "StoreError", "write_new_file"]

log = logging.getLogger(__name__)


def write_new_file(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically; refuse (ConflictError) if ``path`` exists.

    Temporary file in the same directory, fsync, ``os.link`` to the final name (link never
    replaces an existing name), fsync of the directory. A crash or error at any step leaves
    no file under ``path`` and never touches an existing one.
    """
    path = Path(path)
    directory = path.parent
    directory.mkdir(parents=True, exist_ok=True)
    if path.exists():
        raise ConflictError(
            f"{path} exists; backups are never overwritten",
            hint="choose another file name",
        )
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise ConflictError(
                f"{path} exists; backups are never overwritten", hint="choose another file name"
            ) from None
        except OSError as exc:
            if exc.errno not in (1, 38, 95):  # EPERM / ENOSYS / EOPNOTSUPP: no hard links
                raise
            _copy_exclusive(tmp, path)
        _fsync_dir(directory)
    except OSError as exc:
        raise StoreError(
            f"cannot write {path}: {exc.strerror or exc}",
            hint="check free space and permissions of the directory",
        ) from exc
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _copy_exclusive(tmp: str, path: Path) -> None:
    """Fallback for file systems without hard links: O_EXCL create, copy, fsync."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        raise ConflictError(
            f"{path} exists; backups are never overwritten", hint="choose another file name"
        ) from None
    try:
        with os.fdopen(fd, "wb") as out, open(tmp, "rb") as src:
            out.write(src.read())
            out.flush()
            os.fsync(out.fileno())
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(path)
        raise


def _fsync_dir(directory: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


class Store:
    """Backups, restores and the audit of parameter writes, for the data directory
    ``data_dir`` (its local backup files) on the store at ``url`` (empty: the SQLite file
    in ``data_dir``)."""

    def __init__(self, data_dir: Path, url: str = "") -> None:
        self.data_dir = Path(data_dir)
        self.backups_dir = self.data_dir / "backups"
        try:
            self.backups_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            # A data directory that cannot be made (a file in its path, no permission) is the
            # user's setting to fix, not a traceback.
            raise StoreError(
                f"cannot use the data directory {self.data_dir}: {exc.strerror}",
                hint="set SERVODESK_DATA_DIR to a directory you can write",
            ) from exc
        # A crash in the middle of write_new_file can leave its temporary file behind.
        remove_stale_temp_files(self.backups_dir)
        #: The SQLite file of the default store (also where the audit log was before the URL).
        self.path = self.data_dir / db.SQLITE_FILE
        #: The store's URL: what AuditLog and UserStore open to share it.
        self.url = db.store_url(self.data_dir, url)
        self._engine = db.open_engine(self.url)
        self._postgres = db.is_postgres(self._engine)
        #: The local queue while a central (PostgreSQL) store is unreachable; None on a
        #: SQLite store, which is the local file itself (services/outbox.py).
        self.outbox: Outbox | None = None
        try:
            self._repair_columns()
            self._migrate_files()
        except sa.exc.SQLAlchemyError as exc:
            self._engine.dispose()
            raise db.store_error(exc, self._engine) from exc
        if self._postgres:
            self.outbox = Outbox(self.data_dir, self._engine)

    @property
    def engine(self) -> sa.Engine:
        return self._engine

    def _repair_columns(self) -> None:
        """``backups.unreadable`` (issue 48) is in revision 0001; a database that an older
        servodesk changed after it was upgraded (run against it again, or a copy taken back)
        can lack it while it says 0002. Added here, as that older servodesk did."""
        columns = {c["name"] for c in sa.inspect(self._engine).get_columns("backups")}
        if "unreadable" not in columns:
            with db.write(self._engine) as conn:
                conn.execute(sa.text("ALTER TABLE backups ADD COLUMN unreadable TEXT"))

    def _migrate_files(self) -> None:
        """Bring records of an older servodesk up to this schema, from their files.

        - Content: a backup whose bytes are not in the store yet (made before revision 0002)
          gets them from its file here, when the file is intact (its SHA-256 matches).
        - ``unreadable`` (issue 48) came later: a record without it takes the list from its
          own file, so an old incomplete backup is shown as incomplete too.

        A missing or damaged file is left alone: it is reported when the backup is used.
        """
        b, c = db.backups, db.backup_content
        query = (
            sa.select(b.c.id, b.c.file, b.c.sha256, b.c.unreadable, c.c.sha256.label("have"))
            .select_from(b.outerjoin(c, b.c.sha256 == c.c.sha256))
            .where(sa.or_(c.c.sha256.is_(None), b.c.unreadable.is_(None)))
        )
        with db.read(self._engine) as conn:
            rows = conn.execute(query).mappings().all()
        for row in rows:
            try:
                data = self.backup_file(str(row["file"])).read_bytes()
            except (OSError, ServodeskError):
                continue
            intact = hashlib.sha256(data).hexdigest() == row["sha256"]
            with db.write(self._engine) as conn:
                if row["have"] is None and intact:
                    conn.execute(db.insert_ignore(conn, c), _content_row(data))
                elif row["have"] is None:
                    log.warning("backup %s: its file differs from its SHA-256", row["id"])
                if row["unreadable"] is None:
                    items = _unreadable_of(data)
                    if items is not None:
                        conn.execute(
                            sa.update(b).where(b.c.id == row["id"]).values(unreadable=items)
                        )

    def close(self) -> None:
        self._engine.dispose()
        if self.outbox is not None:
            self.outbox.close()

    def backup_file(self, name: str) -> Path:
        """The path of backup file ``name``, confirmed inside the backups directory (a name
        from an old record or a bug must never reach another file)."""
        return inside(self.backups_dir, name)

    @contextlib.contextmanager
    def _tx(self) -> Iterator[Connection]:
        with db.transaction(self._engine) as conn:
            yield conn

    def _query(self, statement: sa.Executable) -> list[RowMapping]:
        return db.rows(self._engine, statement)

    # Backups -------------------------------------------------------------------------------

    def add_backup(self, info: dict[str, Any], source: str = "drive") -> bool:
        """The record of a backup whose file the caller has written (``info["file"]``), and
        the file's bytes, in one transaction; True when the central store was unreachable and
        both went to the local queue instead (:attr:`outbox`).

        A file that cannot be read here or no longer matches ``info["sha256"]`` leaves the
        record without content, as the record of a lost file was before: opening the
        backup then says that the file is missing or was changed (backup_files.read_checked).
        """
        data: bytes | None = None
        try:
            data = self.backup_file(info["file"]).read_bytes()
        except (OSError, ServodeskError) as exc:
            log.warning(
                "backup %s: its file cannot be read (%s); recorded without it", info["id"], exc
            )
        if data is not None and hashlib.sha256(data).hexdigest() != info["sha256"]:
            log.warning(
                "backup %s: its file differs from its SHA-256; recorded without it", info["id"]
            )
            data = None
        row = {
            "id": info["id"],
            "time": info["time"],
            "created": time.time(),
            "label": info["label"],
            "note": info["note"],
            "profile_id": info["profile_id"],
            "profile_version": info["profile_version"],
            "drive_key": info["drive_key"],
            "identity": json.dumps(info["identity"]),
            "firmware": info["firmware"],
            "bus": json.dumps(info["bus"]),
            "entries": info["entries"],
            "file": info["file"],
            "sha256": info["sha256"],
            "source": source,
            "unreadable": json.dumps(info.get("unreadable", [])),
        }
        content = _content_row(data) if data is not None else None
        try:
            with self._tx() as conn:
                if content is not None:
                    conn.execute(db.insert_ignore(conn, db.backup_content), content)
                conn.execute(sa.insert(db.backups).values(row))
        except StoreUnavailable as exc:
            if self.outbox is None:
                raise
            # The central store is away: the backup waits in the local queue
            # (services/outbox.py) and opens from there by its id until the sync.
            self.outbox.lost(exc)
            self.outbox.add(db.backups, row, content)
            log.warning("backup %s queued locally: %s", info["id"], exc.message)
            return True
        return False

    @staticmethod
    def _backup_row(r: RowMapping) -> dict[str, Any]:
        unreadable = json.loads(r["unreadable"]) if r["unreadable"] else []
        return {
            "id": r["id"],
            "time": r["time"],
            "label": r["label"],
            "note": r["note"],
            "profile_id": r["profile_id"],
            "profile_version": r["profile_version"],
            "drive_key": r["drive_key"],
            "identity": json.loads(r["identity"]),
            "firmware": r["firmware"],
            "bus": json.loads(r["bus"]),
            "entries": r["entries"],
            "file": r["file"],
            "sha256": r["sha256"],
            "source": r["source"],
            # Objects the drive refused when the backup was read: the backup lacks them.
            "unreadable": unreadable,
            "complete": not unreadable,
        }

    def _query_or_queued(self, statement: sa.Executable) -> list[RowMapping]:
        """A read of one backup's rows: from the central store, else (not there yet, or the
        store unreachable) from the local queue, where a backup made offline waits."""
        try:
            rows = self._query(statement)
        except StoreUnavailable:
            if self.outbox is None:
                raise
            queued = self.outbox.rows(statement)
            if queued:
                return queued
            raise
        if not rows and self.outbox is not None:
            return self.outbox.rows(statement)
        return rows

    def get_backup(self, bid: str) -> dict[str, Any]:
        rows = self._query_or_queued(sa.select(db.backups).where(db.backups.c.id == bid))
        if not rows:
            raise NotFoundError(f"no backup {bid!r}", hint="list the backups with GET /backups")
        return self._backup_row(rows[0])

    def backup_file_row(self, bid: str) -> dict[str, Any]:
        """Only what opening the backup's file needs (file, sha256, profile_id, label, note):
        nothing whose size the file decides is parsed here, on the caller's thread (the
        heavy part is parsed in the documents' worker: api/backup_documents.py).

        A file this data directory lacks (the backup was made by another gateway on the
        same store) is copied here from the store first, so that the path is there to read.
        """
        b = db.backups
        rows = self._query_or_queued(
            sa.select(b.c.file, b.c.sha256, b.c.profile_id, b.c.label, b.c.note).where(
                b.c.id == bid
            )
        )
        if not rows:
            raise NotFoundError(f"no backup {bid!r}", hint="list the backups with GET /backups")
        row = dict(rows[0])
        self._materialise(str(row["file"]), str(row["sha256"]))
        return row

    def _materialise(self, name: str, sha256: str) -> None:
        path = self.backup_file(name)
        if path.exists():
            return
        data = self.content(sha256)
        if data is None:
            return  # Neither here nor in the store: read_checked reports it missing.
        with contextlib.suppress(ConflictError):  # Another thread wrote it meanwhile.
            write_new_file(path, data)

    def content(self, sha256: str) -> bytes | None:
        """The backup content of this SHA-256, or None when the store lacks it."""
        c = db.backup_content
        rows = self._query_or_queued(sa.select(c.c.data).where(c.c.sha256 == sha256))
        return bytes(rows[0]["data"]) if rows else None

    def list_backups(
        self, drive_key: str | None = None, profile_id: str | None = None, limit: int = 1000
    ) -> list[dict[str, Any]]:
        b = db.backups
        query = sa.select(b)
        if drive_key:
            query = query.where(b.c.drive_key == drive_key)
        if profile_id:
            query = query.where(b.c.profile_id == profile_id)
        # The same second's backups in the order they were made: SQLite's rowid; PostgreSQL
        # has none, and a time-stamped id is the closest.
        tie = b.c.id.desc() if self._postgres else sa.literal_column("rowid").desc()
        query = query.order_by(b.c.created.desc(), tie).limit(limit)
        return [self._backup_row(r) for r in self._query(query)]

    def update_backup(self, bid: str, label: str | None, note: str | None) -> dict[str, Any]:
        self.get_backup(bid)
        values = {k: v for k, v in (("label", label), ("note", note)) if v is not None}
        if values:
            with self._tx() as conn:
                conn.execute(sa.update(db.backups).where(db.backups.c.id == bid).values(values))
        return self.get_backup(bid)

    # Restores ------------------------------------------------------------------------------

    def add_restore(self, meta: dict[str, Any], items: list[dict[str, Any]]) -> None:
        """A restore and all its items, in one transaction (before the first write)."""
        with self._tx() as conn:
            conn.execute(
                sa.insert(db.restores).values(
                    id=meta["id"],
                    backup=meta["backup"],
                    session=meta["session"],
                    drive_key=meta["drive_key"],
                    bus=json.dumps(meta["bus"]),
                    time=meta["time"],
                    created=time.time(),
                    dry_run=int(meta["dry_run"]),
                    finished=int(meta.get("finished", False)),
                    stored=0,
                    interrupted=0,
                    pre_backup=meta.get("pre_backup"),
                    options=json.dumps(meta["options"]),
                    message=meta.get("message"),
                )
            )
            if items:
                conn.execute(
                    sa.insert(db.restore_items),
                    [
                        {
                            "restore": meta["id"],
                            "seq": i,
                            "address": it["address"],
                            "source": it["source"],
                            "name": it["name"],
                            "status": it["status"],
                            "old_raw_hex": it.get("old_raw_hex"),
                            "new_raw_hex": it.get("new_raw_hex"),
                            "code": it.get("code"),
                            "meaning": it.get("meaning"),
                            "message": it.get("message"),
                        }
                        for i, it in enumerate(items)
                    ],
                )

    def set_item(self, rid: str, seq: int, **fields: Any) -> None:
        """Record one item's new status (committed before the next write goes out)."""
        values = {k: v for k, v in fields.items() if k in _ITEM_FIELDS}
        if not values:
            return
        ri = db.restore_items
        with self._tx() as conn:
            conn.execute(sa.update(ri).where(ri.c.restore == rid, ri.c.seq == seq).values(values))

    def journal(
        self,
        rid: str,
        items: dict[int, dict[str, Any]],
        audit: Sequence[dict[str, Any]] = (),
        restore: dict[str, Any] | None = None,
    ) -> None:
        """A restore's group commit (services/restore.py): items' new fields (by seq), the
        audit table's records of the writes and the restore's own fields, in ONE
        transaction. Blocking (a commit is an fsync): call it in a thread."""
        ri = db.restore_items
        # executemany needs one set of columns per statement: items grouped by theirs.
        by_columns: dict[tuple[str, ...], list[dict[str, Any]]] = {}
        for seq, fields in items.items():
            values = {k: v for k, v in fields.items() if k in _ITEM_FIELDS}
            if values:
                by_columns.setdefault(tuple(sorted(values)), []).append(
                    {**{f"v_{k}": v for k, v in values.items()}, "b_seq": seq}
                )
        restore_values = _restore_values(restore or {})
        with self._tx() as conn:
            for columns, params in by_columns.items():
                conn.execute(
                    sa.update(ri)
                    .where(ri.c.restore == rid, ri.c.seq == sa.bindparam("b_seq"))
                    .values({c: sa.bindparam(f"v_{c}") for c in columns}),
                    params,
                )
            if audit:
                conn.execute(sa.insert(db.audit), [_audit_row(rec) for rec in audit])
            if restore_values:
                conn.execute(
                    sa.update(db.restores).where(db.restores.c.id == rid).values(restore_values)
                )

    def set_restore(self, rid: str, **fields: Any) -> None:
        values = _restore_values(fields)
        if not values:
            return
        with self._tx() as conn:
            conn.execute(sa.update(db.restores).where(db.restores.c.id == rid).values(values))

    def get_restore(self, rid: str) -> dict[str, Any]:
        rows = self._query(sa.select(db.restores).where(db.restores.c.id == rid))
        if not rows:
            raise NotFoundError(f"no restore {rid!r}", hint="see the id in the restore report")
        r = rows[0]
        ri = db.restore_items
        items = self._query(sa.select(ri).where(ri.c.restore == rid).order_by(ri.c.seq))
        return {
            "id": r["id"],
            "backup": r["backup"],
            "session": r["session"],
            "drive_key": r["drive_key"],
            "bus": json.loads(r["bus"]),
            "time": r["time"],
            "dry_run": bool(r["dry_run"]),
            "finished": bool(r["finished"]),
            "stored": bool(r["stored"]),
            "interrupted": bool(r["interrupted"]),
            "pre_backup": r["pre_backup"],
            "options": json.loads(r["options"]),
            "message": r["message"],
            "items": [
                {
                    "seq": it["seq"],
                    "address": it["address"],
                    "source": it["source"],
                    "name": it["name"],
                    "status": it["status"],
                    "old_raw_hex": it["old_raw_hex"],
                    "new_raw_hex": it["new_raw_hex"],
                    "code": it["code"],
                    "meaning": it["meaning"],
                    "message": it["message"],
                }
                for it in items
            ],
        }

    # Audit ---------------------------------------------------------------------------------

    def add_audit(self, rec: dict[str, Any]) -> None:
        with self._tx() as conn:
            conn.execute(sa.insert(db.audit).values(_audit_row(rec)))

    def list_audit(self, session: str | None = None, limit: int = 100) -> list[dict[str, Any]]:
        a = db.audit
        query = sa.select(a)
        if session:
            query = query.where(a.c.session == session)
        query = query.order_by(a.c.id.desc()).limit(limit)
        return [
            {
                "time": r["time"],
                "client": r["client"],
                "session": r["session"],
                "drive_key": r["drive_key"],
                "address": r["address"],
                "name": r["name"],
                "old_raw_hex": r["old_raw_hex"],
                "new_raw_hex": r["new_raw_hex"],
                "old_value": json.loads(r["old_value"]) if r["old_value"] else None,
                "new_value": json.loads(r["new_value"]) if r["new_value"] else None,
            }
            for r in self._query(query)
        ]


#: The fields of a restore item that change as the restore goes.
_ITEM_FIELDS = frozenset({"status", "old_raw_hex", "code", "meaning", "message"})
#: The fields of a restore that change as it goes.
_RESTORE_FIELDS = frozenset(
    {"finished", "stored", "interrupted", "message", "session", "pre_backup"}
)


def _restore_values(fields: dict[str, Any]) -> dict[str, Any]:
    return {
        k: int(v) if isinstance(v, bool) else v for k, v in fields.items() if k in _RESTORE_FIELDS
    }


def _audit_row(rec: dict[str, Any]) -> dict[str, Any]:
    """The ``audit`` table's row of a write record (BackupService.write_record)."""
    return {
        "time": rec["time"],
        "client": rec["client"],
        "session": rec["session"],
        "drive_key": rec["drive_key"],
        "address": rec["address"],
        "name": rec.get("name"),
        "old_raw_hex": rec.get("old_raw_hex"),
        "new_raw_hex": rec["new_raw_hex"],
        "old_value": json.dumps(rec.get("old_value")),
        "new_value": json.dumps(rec.get("new_value")),
    }


def _content_row(data: bytes) -> dict[str, Any]:
    return {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data), "data": data}


def _unreadable_of(data: bytes) -> str | None:
    """The ``unreadable`` list of a backup file as stored JSON text (None: not a list)."""
    try:
        doc = json.loads(data)
    except ValueError:
        return None
    items = doc.get("unreadable", []) if isinstance(doc, dict) else None
    return json.dumps(items) if isinstance(items, list) else None
