"""The store on both engines (issue 49): every test here runs once on SQLite (the default,
the data directory's file) and once on a real PostgreSQL (tests/store/conftest.py).

What a user relies on: backups, their content and restore reports survive and are the same
from every gateway on the store; identical content is stored once; the audit chain verifies
and the database refuses to edit it; accounts and tokens work; two writers at once never
lose or duplicate a record and never fork the chain.
"""

from __future__ import annotations

import hashlib
import json
import threading
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from servodesk.errors import ConflictError, NotFoundError
from servodesk.services import db
from servodesk.services.audit import Actor, AuditLog
from servodesk.services.store import Store, write_new_file
from servodesk.services.users import UserStore


def _backup(store: Store, bid: str, data: bytes, drive: str = "d1") -> dict[str, Any]:
    """A backup as BackupService.save makes it: the file first, then the record."""
    name = f"{bid}-cia402-generic.json"
    write_new_file(store.backup_file(name), data)
    info = {
        "id": bid,
        "time": "2026-12-07T08:00:00Z",
        "label": "before tuning",
        "note": "",
        "profile_id": "cia402-generic",
        "profile_version": "1",
        "drive_key": drive,
        "identity": {"vendor_id": 1, "serial": 9},
        "firmware": "1.2",
        "bus": {"interface": "virtual", "channel": "x", "node_id": 3},
        "entries": 1,
        "file": name,
        "sha256": hashlib.sha256(data).hexdigest(),
        "unreadable": [],
    }
    store.add_backup(info)
    return info


def _restore(store: Store, bid: str) -> None:
    """A restore of ``bid`` as RestoreService records it: the report with its items, then
    each item's status in its own transaction, then the end."""
    rid = f"r-{bid}"
    meta = {"id": rid, "backup": bid, "session": "s", "drive_key": "d", "bus": {}, "time": "t"}
    items = [{"address": "0x6081:00", "source": "b", "name": "n", "status": "pending"}]
    store.add_restore({**meta, "dry_run": False, "options": {}}, items * 3)
    for seq in range(3):
        store.set_item(rid, seq, status="written", old_raw_hex="00")
    store.set_restore(rid, finished=True)


def _gateway(tmp_path: Path, engine_url: str, name: str) -> Store:
    """A gateway's store: its own data directory, the shared store (on SQLite: the first
    gateway's file, named by URL)."""
    url = engine_url or db.store_url(tmp_path / "g1")
    return Store(tmp_path / name, url)


def test_backups_restores_and_writes_round_trip(tmp_path: Path, engine_url: str) -> None:
    store = Store(tmp_path / "data", engine_url)
    try:
        _backup(store, "b1", b'{"a": 1}')
        _backup(store, "b2", b'{"a": 2}', drive="d2")
        assert [b["id"] for b in store.list_backups()] == ["b2", "b1"]
        assert [b["id"] for b in store.list_backups(drive_key="d1")] == ["b1"]
        got = store.get_backup("b1")
        assert got["identity"] == {"vendor_id": 1, "serial": 9} and got["complete"] is True
        assert store.update_backup("b1", "golden", None)["label"] == "golden"
        with pytest.raises(NotFoundError):
            store.get_backup("nope")

        store.add_restore(
            {
                "id": "r1",
                "backup": "b1",
                "session": "s1",
                "drive_key": "d1",
                "bus": {},
                "time": "t",
                "dry_run": False,
                "options": {"verify": True},
            },
            [
                {"address": f"0x6081:0{i}", "source": "b", "name": "n", "status": "pending"}
                for i in range(3)
            ],
        )
        store.set_item("r1", 1, status="written", old_raw_hex="00")
        store.set_restore("r1", finished=True, message="done")
        rep = store.get_restore("r1")
        assert rep["finished"] is True and rep["message"] == "done"
        assert [it["status"] for it in rep["items"]] == ["pending", "written", "pending"]

        for v in (1, 2):
            store.add_audit(
                {
                    "time": 1.0 + v,
                    "client": "c",
                    "session": "s1",
                    "drive_key": "d1",
                    "address": "0x6081:00",
                    "new_raw_hex": "01",
                    "new_value": v,
                }
            )
        assert [r["new_value"] for r in store.list_audit("s1")] == [2, 1]
    finally:
        store.close()


def test_a_second_gateway_opens_every_backup_and_content_is_stored_once(
    tmp_path: Path, engine_url: str
) -> None:
    one = _gateway(tmp_path, engine_url, "g1")
    two = _gateway(tmp_path, engine_url, "g2")
    try:
        data = json.dumps({"entries": list(range(500))}).encode()
        _backup(one, "b1", data)
        _backup(one, "b2", data)  # Unchanged drive backed up again.
        _backup(two, "b3", b"other")
        # Gateway two has no file of b1 in its data directory: it comes from the store.
        assert not (tmp_path / "g2" / "backups" / "b1-cia402-generic.json").exists()
        row = two.backup_file_row("b1")
        copied = two.backup_file(row["file"]).read_bytes()
        assert copied == data and hashlib.sha256(copied).hexdigest() == row["sha256"]
        assert two.content(row["sha256"]) == data
        with one.engine.connect() as conn:
            n = conn.execute(sa.select(sa.func.count()).select_from(db.backup_content)).scalar()
        assert n == 2  # b1 and b2 share one row.
        assert {b["id"] for b in one.list_backups()} == {"b1", "b2", "b3"}
    finally:
        one.close()
        two.close()


def test_the_audit_chain_verifies_and_the_database_refuses_edits(
    tmp_path: Path, engine_url: str
) -> None:
    url = db.store_url(tmp_path, engine_url)
    log = AuditLog(url)
    try:
        for i in range(5):
            log.record("control.taken", who=Actor("alice", "192.0.2.7"), drive=f"s{i}")
        log.record("access.login_failed", who=Actor("eve", "198.51.100.1"), ok=False)
        v = log.verify()
        assert v.ok and v.records == 6
        assert [r["user"] for r in log.query(category="access_control")] == ["eve"]
        assert len(list(log.export("jsonl"))) == 6
        engine = db.open_engine(url)
        try:
            for statement in (
                "UPDATE audit_log SET \"user\" = 'mallory' WHERE seq = 3",
                "DELETE FROM audit_log WHERE seq = 2",
            ):
                with (
                    pytest.raises(sa.exc.DatabaseError, match="append-only"),
                    engine.begin() as conn,
                ):
                    conn.execute(sa.text(statement))
        finally:
            engine.dispose()
        assert log.verify().ok
    finally:
        log.close()


def test_an_edit_past_the_trigger_is_found(tmp_path: Path, engine_url: str) -> None:
    url = db.store_url(tmp_path, engine_url)
    log = AuditLog(url)
    for i in range(4):
        log.record("control.taken", who=Actor("alice"), drive=f"s{i}")
    log.close()
    engine = db.open_engine(url)
    with engine.begin() as conn:  # Someone with the database's owner rights.
        if db.is_postgres(conn):
            conn.execute(sa.text("ALTER TABLE audit_log DISABLE TRIGGER audit_log_no_change"))
        else:
            conn.execute(sa.text("DROP TRIGGER audit_log_no_update"))
        conn.execute(sa.text("UPDATE audit_log SET \"user\" = 'mallory' WHERE seq = 3"))
    engine.dispose()
    log = AuditLog(url)
    try:
        v = log.verify()
        assert not v.ok and v.broken == 3 and v.records == 2
    finally:
        log.close()


def test_accounts_and_tokens(tmp_path: Path, engine_url: str) -> None:
    users = UserStore(tmp_path, engine_url)
    try:
        users.add("alice", "administrator", "correct horse")
        with pytest.raises(ConflictError):
            users.add("alice", "operator", "another password")
        assert users.verify_password("alice", "correct horse") is not None
        assert users.verify_password("alice", "wrong password") is None
        token, secret = users.create_token("alice", "ci")
        found = users.verify_token(secret.encode())
        assert found is not None and found[1].id == token.id
        with pytest.raises(ConflictError, match="last enabled administrator"):
            users.remove("alice")
        users.add("bob", "administrator", "battery staple")
        users.remove("alice")  # Its tokens go with it, in the same transaction.
        assert users.tokens("alice") == [] and users.verify_token(secret.encode()) is None
        users.close()  # Reopened on use, as an application's second lifespan does.
        assert [u.name for u in users.all()] == ["bob"]
    finally:
        users.close()


def test_two_writers_at_once_lose_and_duplicate_nothing(tmp_path: Path, engine_url: str) -> None:
    """Two gateways (each its own store objects and connections) append audit records and
    back up at the same time: every record is there once, and the chain is one chain."""
    per_writer, backups_each = 150, 15
    errors: list[BaseException] = []
    start = threading.Barrier(2)

    def gateway(name: str) -> None:
        try:
            store = _gateway(tmp_path, engine_url, name)
            log = AuditLog(store.url)
            start.wait(timeout=60)
            for i in range(per_writer):
                log.record("backup.created", who=Actor(name), details={"i": i})
                if i % (per_writer // backups_each) == 0:
                    bid = f"{name}-{i}"
                    _backup(store, bid, bid.encode(), drive=name)
                    _restore(store, bid)
                    log.flush(timeout=60)  # Several transactions, interleaved with the other.
            assert log.flush(timeout=120)
            log.close()
            store.close()
        except BaseException as exc:
            errors.append(exc)

    Store(tmp_path / "g1", engine_url).close()  # The schema first (as a first start would).
    threads = [threading.Thread(target=gateway, args=(n,)) for n in ("g1", "g2")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert not errors, errors
    url = db.store_url(tmp_path / "g1", engine_url)
    log = AuditLog(url)
    store = Store(tmp_path / "g3", url)
    try:
        v = log.verify()
        assert v.ok, v
        assert v.records == 2 * per_writer
        seen = {(r["user"], r["details"]["i"]) for r in log.query(limit=10_000)}
        assert len(seen) == 2 * per_writer  # None lost; with verify's count, none twice.
        ids = [b["id"] for b in store.list_backups()]
        assert len(ids) == len(set(ids)) == 2 * backups_each
        for bid in ids:
            rep = store.get_restore(f"r-{bid}")
            assert rep["finished"] and [it["status"] for it in rep["items"]] == ["written"] * 3
    finally:
        log.close()
        store.close()
