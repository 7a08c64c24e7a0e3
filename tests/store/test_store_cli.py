"""A data directory of the earlier servodesk migrates in place, and ``servodesk store
export/import`` moves a store between SQLite and PostgreSQL without loss (issue 49).

``data/legacy`` was made by servodesk's store code as it was before issue 49 (the sqlite3
modules services/store.py, audit.py and users.py of 2026-12-07): three backups (two of them
the same bytes) with their files, a restore report, a parameter write, seven hash-chained
audit records, the account ``alice`` (password ``correct horse``) and an API token
(``token.txt``).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from servodesk.cli import main
from servodesk.services import db
from servodesk.services.audit import AuditLog
from servodesk.services.store import Store
from servodesk.services.tuning_store import TuningStore
from servodesk.services.users import UserStore

LEGACY = Path(__file__).parent / "data" / "legacy"


@pytest.fixture
def legacy(tmp_path: Path) -> Path:
    """A copy of the old data directory (the original stays untouched)."""
    return Path(shutil.copytree(LEGACY, tmp_path / "legacy"))


def _files(data_dir: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((data_dir / "backups").glob("*.json"))}


def _contents(store: Store) -> dict[str, bytes]:
    """Every backup's bytes as the store gives them (its local file, copied from the store
    when missing), checked against the recorded SHA-256."""
    out = {}
    for b in store.list_backups():
        row = store.backup_file_row(b["id"])
        data = store.backup_file(row["file"]).read_bytes()
        assert hashlib.sha256(data).hexdigest() == row["sha256"]
        out[b["id"]] = data
    return out


def test_an_old_data_directory_migrates_in_place(legacy: Path) -> None:
    files = _files(legacy)
    before = AuditLog(legacy / "servodesk.db")  # Opening migrates; the chain is unchanged.
    try:
        head = before.verify()
    finally:
        before.close()
    assert head.ok and head.records == 7
    store = Store(legacy)
    try:
        assert db.revision(store.engine) == "0006"
        assert len(store.list_backups()) == 3
        # The files' bytes are in the store now: identical content once.
        with store.engine.connect() as conn:
            rows = conn.execute(sa.select(db.backup_content.c.sha256)).all()
        assert len(rows) == 2
        assert sorted(_contents(store).values()) == sorted(files.values())
        assert store.get_restore("r1")["items"][0]["status"] == "written"
        assert store.list_audit("s1")[0]["new_value"] == 1000
    finally:
        store.close()
    users = UserStore(legacy)
    try:
        assert users.verify_password("alice", "correct horse") is not None
        assert users.verify_token((legacy / "token.txt").read_text().encode()) is not None
    finally:
        users.close()


def _lines(path: Path) -> list[str]:
    return sorted(path.read_text(encoding="utf-8").splitlines())


def test_round_trip_sqlite_postgresql_sqlite(
    legacy: Path, tmp_path: Path, pg_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    first, second, third = (tmp_path / f"export{i}.jsonl" for i in (1, 2, 3))
    tuning = _add_tuning(legacy)
    assert main(["store", "export", str(first), "--data-dir", str(legacy)]) == 0
    assert main(["store", "import", str(first), "--url", pg_url]) == 0
    out = capsys.readouterr().out
    assert "audit log verified: 7 records" in out
    assert main(["store", "export", str(second), "--url", pg_url]) == 0
    fresh = tmp_path / "fresh"
    assert main(["store", "import", str(second), "--data-dir", str(fresh)]) == 0
    assert main(["store", "export", str(third), "--data-dir", str(fresh)]) == 0
    # Every row of every table, byte for byte, through both engines (order aside: SQLite
    # lists the backups as they were made, PostgreSQL by id).
    assert _lines(first) == _lines(second) == _lines(third)
    header = json.loads(first.read_text().splitlines()[0])
    assert header["revision"] == "0006"

    old, new = Store(legacy), Store(fresh)
    try:
        assert _contents(new) == _contents(old)  # Byte-equal backups, files made on use.
        assert _files(fresh) == _files(legacy)
    finally:
        old.close()
        new.close()
    a, b = AuditLog(legacy / "servodesk.db"), AuditLog(fresh / "servodesk.db")
    try:
        va, vb = a.verify(), b.verify()
        assert va.ok and vb.ok and va.head == vb.head and vb.records == 7
    finally:
        a.close()
        b.close()
    # A tuning's result went along with its metadata (revision 0005).
    engine = db.open_engine(db.store_url(fresh))
    try:
        assert TuningStore(engine, "elsewhere").get(tuning["id"]) == tuning
    finally:
        engine.dispose()
    users = UserStore(fresh)
    try:
        assert users.verify_password("alice", "correct horse") is not None
        assert users.verify_token((legacy / "token.txt").read_text().encode()) is not None
    finally:
        users.close()
    # The imported PostgreSQL store keeps working: its parameter writes continue their ids.
    pg = Store(tmp_path / "gw", pg_url)
    try:
        rec = {"time": 9.0, "client": "c", "session": "s1", "drive_key": "k"}
        pg.add_audit({**rec, "address": "0x6060:00", "new_raw_hex": "01"})
        assert len(pg.list_audit("s1")) == 2
    finally:
        pg.close()


def _add_tuning(data_dir: Path) -> dict[str, Any]:
    """One tuning result in the store of ``data_dir`` (as services/tuning/jobs.py records
    it); what the store gives back for it."""
    engine = db.open_engine(db.store_url(data_dir))
    try:
        store = TuningStore(engine, "gw-a")
        result: dict[str, Any] = {
            "kind": "gains",
            "status": "done",
            "mode": "basic",
            "gains": [],
            "bode": None,
        }
        store.add(
            {
                "id": "tuning-20261207t120000z-abc123",
                "drive_key": "0000029C-03020002-1234",
                "session": "cia402-generic-1",
                "kind": "gains",
                "mode": "basic",
                "status": "done",
                "started": 1_796_000_000.25,
                "ended": 1_796_000_042.5,
                "by": "alice",
                "client": "A",
                "applied": True,
                "result": result,
            }
        )
        return store.get("tuning-20261207t120000z-abc123")
    finally:
        engine.dispose()


def _fails(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and err.startswith("servodesk: error: ")
    return err


def test_bad_input_exits_2_with_a_message(
    legacy: Path, tmp_path: Path, pg_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    export = tmp_path / "e.jsonl"
    err = _fails(["store", "export", str(export), "--url", "mysql://u@h/db"], capsys)
    assert "unknown store URL scheme 'mysql'" in err
    err = _fails(
        ["store", "export", str(export), "--url", "postgresql://u:secret@127.0.0.1:1/x"], capsys
    )
    assert "cannot open the store" in err and "secret" not in err
    assert not export.exists()

    assert main(["store", "export", str(export), "--data-dir", str(legacy)]) == 0
    capsys.readouterr()
    err = _fails(["store", "export", str(export), "--data-dir", str(legacy)], capsys)
    assert "exists" in err  # Never overwritten.

    err = _fails(["store", "import", str(tmp_path / "none.jsonl"), "--url", pg_url], capsys)
    assert "no file" in err
    notjson = tmp_path / "backup.json"
    notjson.write_text('{"format": "servodesk-backup"}\n')
    assert "no servodesk-store header" in _fails(["store", "import", str(notjson)], capsys)
    garbage = tmp_path / "garbage.bin"
    garbage.write_bytes(b"\x00\xff not json")
    assert "not a servodesk store export" in _fails(
        ["store", "import", str(garbage), "--url", pg_url], capsys
    )
    truncated = tmp_path / "truncated.jsonl"
    truncated.write_text("\n".join(export.read_text().splitlines()[:-3]) + "\n")
    assert "truncated" in _fails(["store", "import", str(truncated), "--url", pg_url], capsys)
    # Nothing of the refused import stayed: the same database takes the whole file.
    assert main(["store", "import", str(export), "--url", pg_url]) == 0
    capsys.readouterr()
    err = _fails(["store", "import", str(export), "--url", pg_url], capsys)
    assert "is not empty" in err
