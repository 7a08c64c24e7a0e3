"""The embedded store: backup records, restore reports (item by item) and the audit log.

One SQLite database (``<data_dir>/servodesk.db``) in WAL mode with ``synchronous=FULL``:
every change is one transaction, so a crash at any moment leaves either the old or the new
state, and a committed restore item survives a power loss. Backup files live beside it in
``<data_dir>/backups/`` and are written by :func:`write_new_file`: temporary file in the
same directory, fsync, then a hard link to the final name (which fails if the name exists),
so a file is never half-written under its name and never replaced.

The connection is shared by the event loop and worker threads behind one lock; every call
is short (milliseconds).
"""

from __future__ import annotations

import contextlib
import json
import os
import sqlite3
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from servodesk.errors import ConflictError, NotFoundError, ServodeskError
from servodesk.files import inside, remove_stale_temp_files

SCHEMA = """
CREATE TABLE IF NOT EXISTS backups (
    id TEXT PRIMARY KEY,
    time TEXT NOT NULL,
    created REAL NOT NULL,
    label TEXT NOT NULL DEFAULT '',
    note TEXT NOT NULL DEFAULT '',
    profile_id TEXT NOT NULL,
    profile_version TEXT NOT NULL DEFAULT '',
    drive_key TEXT NOT NULL,
    identity TEXT NOT NULL,
    firmware TEXT,
    bus TEXT NOT NULL,
    entries INTEGER NOT NULL,
    file TEXT NOT NULL,
    sha256 TEXT NOT NULL,
    source TEXT NOT NULL DEFAULT 'drive',
    unreadable TEXT
);
CREATE INDEX IF NOT EXISTS backups_drive ON backups (drive_key, created);
CREATE TABLE IF NOT EXISTS restores (
    id TEXT PRIMARY KEY,
    backup TEXT NOT NULL,
    session TEXT NOT NULL,
    drive_key TEXT NOT NULL,
    bus TEXT NOT NULL,
    time TEXT NOT NULL,
    created REAL NOT NULL,
    dry_run INTEGER NOT NULL,
    finished INTEGER NOT NULL DEFAULT 0,
    stored INTEGER NOT NULL DEFAULT 0,
    interrupted INTEGER NOT NULL DEFAULT 0,
    pre_backup TEXT,
    options TEXT NOT NULL,
    message TEXT
);
CREATE TABLE IF NOT EXISTS restore_items (
    restore TEXT NOT NULL,
    seq INTEGER NOT NULL,
    address TEXT NOT NULL,
    source TEXT NOT NULL,
    name TEXT NOT NULL,
    status TEXT NOT NULL,
    old_raw_hex TEXT,
    new_raw_hex TEXT,
    code INTEGER,
    meaning TEXT,
    message TEXT,
    PRIMARY KEY (restore, seq)
);
CREATE TABLE IF NOT EXISTS audit (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    client TEXT NOT NULL,
    session TEXT NOT NULL,
    drive_key TEXT NOT NULL,
    address TEXT NOT NULL,
    name TEXT,
    old_raw_hex TEXT,
    new_raw_hex TEXT NOT NULL,
    old_value TEXT,
    new_value TEXT
);
CREATE INDEX IF NOT EXISTS audit_session ON audit (session, id);
"""


class StoreError(ServodeskError):
    """The store or a backup file cannot be written or read."""


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
    """Backups, restores and the audit log in ``data_dir``."""

    def __init__(self, data_dir: Path) -> None:
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
        self.path = self.data_dir / "servodesk.db"
        self._lock = threading.RLock()
        try:
            self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
            self._db.row_factory = sqlite3.Row
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.execute("PRAGMA busy_timeout=5000")
            self._db.executescript(SCHEMA)
            self._migrate()
        except sqlite3.Error as exc:
            raise StoreError(
                f"cannot open the store {self.path}: {exc}",
                hint="check SERVODESK_DATA_DIR and its permissions",
            ) from exc

    def _migrate(self) -> None:
        """Bring a store of an older servodesk up to this schema.

        The ``unreadable`` column (issue 48) came later: a record without it takes the list
        from its own file, so an old incomplete backup is shown as incomplete too.
        """
        columns = {r["name"] for r in self._db.execute("PRAGMA table_info(backups)")}
        if "unreadable" not in columns:
            self._db.execute("ALTER TABLE backups ADD COLUMN unreadable TEXT")
        for row in self._db.execute(
            "SELECT id, file FROM backups WHERE unreadable IS NULL"
        ).fetchall():
            try:
                doc = json.loads(self.backup_file(str(row["file"])).read_bytes())
                items = doc.get("unreadable", []) if isinstance(doc, dict) else None
            except (OSError, ValueError, ServodeskError):
                continue  # A missing or damaged file is reported when it is used.
            if isinstance(items, list):
                self._db.execute(
                    "UPDATE backups SET unreadable = ? WHERE id = ?",
                    (json.dumps(items), row["id"]),
                )

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def backup_file(self, name: str) -> Path:
        """The path of backup file ``name``, confirmed inside the backups directory (a name
        from an old record or a bug must never reach another file)."""
        return inside(self.backups_dir, name)

    @contextlib.contextmanager
    def _tx(self) -> Iterator[sqlite3.Connection]:
        with self._lock:
            try:
                self._db.execute("BEGIN IMMEDIATE")
                try:
                    yield self._db
                except BaseException:
                    self._db.execute("ROLLBACK")
                    raise
                self._db.execute("COMMIT")
            except sqlite3.Error as exc:
                raise StoreError(f"store error: {exc}", hint="see the server log") from exc

    def _query(self, sql: str, args: tuple[Any, ...] = ()) -> list[sqlite3.Row]:
        with self._lock:
            try:
                return list(self._db.execute(sql, args).fetchall())
            except sqlite3.Error as exc:
                raise StoreError(f"store error: {exc}", hint="see the server log") from exc

    # Backups -------------------------------------------------------------------------------

    def add_backup(self, info: dict[str, Any], source: str = "drive") -> None:
        with self._tx() as db:
            db.execute(
                "INSERT INTO backups (id, time, created, label, note, profile_id, "
                "profile_version, drive_key, identity, firmware, bus, entries, file, sha256, "
                "source, unreadable) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (
                    info["id"],
                    info["time"],
                    time.time(),
                    info["label"],
                    info["note"],
                    info["profile_id"],
                    info["profile_version"],
                    info["drive_key"],
                    json.dumps(info["identity"]),
                    info["firmware"],
                    json.dumps(info["bus"]),
                    info["entries"],
                    info["file"],
                    info["sha256"],
                    source,
                    json.dumps(info.get("unreadable", [])),
                ),
            )

    @staticmethod
    def _backup_row(r: sqlite3.Row) -> dict[str, Any]:
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

    def get_backup(self, bid: str) -> dict[str, Any]:
        rows = self._query("SELECT * FROM backups WHERE id = ?", (bid,))
        if not rows:
            raise NotFoundError(f"no backup {bid!r}", hint="list the backups with GET /backups")
        return self._backup_row(rows[0])

    def backup_file_row(self, bid: str) -> dict[str, Any]:
        """Only what opening the backup's file needs (file, sha256, profile_id, label, note):
        nothing whose size the file decides is parsed here, on the caller's thread (the
        heavy part is parsed in the documents' worker: api/backup_documents.py)."""
        rows = self._query(
            "SELECT file, sha256, profile_id, label, note FROM backups WHERE id = ?", (bid,)
        )
        if not rows:
            raise NotFoundError(f"no backup {bid!r}", hint="list the backups with GET /backups")
        return dict(rows[0])

    def list_backups(
        self, drive_key: str | None = None, profile_id: str | None = None, limit: int = 1000
    ) -> list[dict[str, Any]]:
        sql = "SELECT * FROM backups WHERE 1=1"
        args: list[Any] = []
        if drive_key:
            sql += " AND drive_key = ?"
            args.append(drive_key)
        if profile_id:
            sql += " AND profile_id = ?"
            args.append(profile_id)
        sql += " ORDER BY created DESC, rowid DESC LIMIT ?"
        args.append(limit)
        return [self._backup_row(r) for r in self._query(sql, tuple(args))]

    def update_backup(self, bid: str, label: str | None, note: str | None) -> dict[str, Any]:
        self.get_backup(bid)
        with self._tx() as db:
            if label is not None:
                db.execute("UPDATE backups SET label = ? WHERE id = ?", (label, bid))
            if note is not None:
                db.execute("UPDATE backups SET note = ? WHERE id = ?", (note, bid))
        return self.get_backup(bid)

    # Restores ------------------------------------------------------------------------------

    def add_restore(self, meta: dict[str, Any], items: list[dict[str, Any]]) -> None:
        """A restore and all its items, in one transaction (before the first write)."""
        with self._tx() as db:
            db.execute(
                "INSERT INTO restores (id, backup, session, drive_key, bus, time, created, "
                "dry_run, finished, stored, interrupted, pre_backup, options, message) "
                "VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (
                    meta["id"],
                    meta["backup"],
                    meta["session"],
                    meta["drive_key"],
                    json.dumps(meta["bus"]),
                    meta["time"],
                    time.time(),
                    int(meta["dry_run"]),
                    int(meta.get("finished", False)),
                    0,
                    0,
                    meta.get("pre_backup"),
                    json.dumps(meta["options"]),
                    meta.get("message"),
                ),
            )
            db.executemany(
                "INSERT INTO restore_items (restore, seq, address, source, name, status, "
                "old_raw_hex, new_raw_hex, code, meaning, message) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
                [
                    (
                        meta["id"],
                        i,
                        it["address"],
                        it["source"],
                        it["name"],
                        it["status"],
                        it.get("old_raw_hex"),
                        it.get("new_raw_hex"),
                        it.get("code"),
                        it.get("meaning"),
                        it.get("message"),
                    )
                    for i, it in enumerate(items)
                ],
            )

    def set_item(self, rid: str, seq: int, **fields: Any) -> None:
        """Record one item's new status (committed before the next write goes out)."""
        allowed = {"status", "old_raw_hex", "code", "meaning", "message"}
        cols = [k for k in fields if k in allowed]
        if not cols:
            return
        sets = ", ".join(f"{c} = ?" for c in cols)
        with self._tx() as db:
            db.execute(
                f"UPDATE restore_items SET {sets} WHERE restore = ? AND seq = ?",
                (*[fields[c] for c in cols], rid, seq),
            )

    def set_restore(self, rid: str, **fields: Any) -> None:
        allowed = {"finished", "stored", "interrupted", "message", "session", "pre_backup"}
        cols = [k for k in fields if k in allowed]
        if not cols:
            return
        sets = ", ".join(f"{c} = ?" for c in cols)
        vals = [int(v) if isinstance(v, bool) else v for v in (fields[c] for c in cols)]
        with self._tx() as db:
            db.execute(f"UPDATE restores SET {sets} WHERE id = ?", (*vals, rid))

    def get_restore(self, rid: str) -> dict[str, Any]:
        rows = self._query("SELECT * FROM restores WHERE id = ?", (rid,))
        if not rows:
            raise NotFoundError(f"no restore {rid!r}", hint="see the id in the restore report")
        r = rows[0]
        items = self._query("SELECT * FROM restore_items WHERE restore = ? ORDER BY seq", (rid,))
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
        with self._tx() as db:
            db.execute(
                "INSERT INTO audit (time, client, session, drive_key, address, name, "
                "old_raw_hex, new_raw_hex, old_value, new_value) VALUES (?,?,?,?,?,?,?,?,?,?)",
                (
                    rec["time"],
                    rec["client"],
                    rec["session"],
                    rec["drive_key"],
                    rec["address"],
                    rec.get("name"),
                    rec.get("old_raw_hex"),
                    rec["new_raw_hex"],
                    json.dumps(rec.get("old_value")),
                    json.dumps(rec.get("new_value")),
                ),
            )

    def list_audit(self, session: str | None = None, limit: int = 100) -> list[dict[str, Any]]:
        sql = "SELECT * FROM audit"
        args: list[Any] = []
        if session:
            sql += " WHERE session = ?"
            args.append(session)
        sql += " ORDER BY id DESC LIMIT ?"
        args.append(limit)
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
            for r in self._query(sql, tuple(args))
        ]
