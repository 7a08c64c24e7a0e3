"""The audit log's hash chain (services/audit.py): every kind of tampering with the SQLite
file is found, by ``servodesk audit verify`` (exit 1, the first broken record) and by the
service; concurrent writers never fork the chain; export carries every record."""

from __future__ import annotations

import csv
import io
import json
import sqlite3
import threading
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.services.audit import GENESIS, Actor, AuditLog, as_actor


def _log(data: Path, n: int = 5) -> None:
    """``n`` records in ``data/servodesk.db``, written and closed."""
    data.mkdir(parents=True, exist_ok=True)
    log = AuditLog(data / "servodesk.db")
    for i in range(n):
        log.record(
            "control.taken",
            who=Actor("alice", "192.0.2.7"),
            drive=f"s{i}",
            details={"i": i},
        )
    log.close()


def _tamper(data: Path, *sql: str) -> None:
    """Edit the file directly, as someone with the file (not servodesk) would: past the
    append-only triggers."""
    db = sqlite3.connect(data / "servodesk.db")
    db.execute("DROP TRIGGER audit_log_no_update")
    db.execute("DROP TRIGGER audit_log_no_delete")
    for s in sql:
        db.execute(s)
    db.commit()
    db.close()


def _verify(data: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["audit", "verify", "--data-dir", str(data)])
    return code, capsys.readouterr().out


def test_an_intact_log_verifies(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _log(tmp_path)
    code, out = _verify(tmp_path, capsys)
    assert code == 0, out
    assert "5 records" in out


def test_an_altered_record_is_found(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _log(tmp_path)
    _tamper(tmp_path, "UPDATE audit_log SET user = 'mallory' WHERE seq = 3")
    code, out = _verify(tmp_path, capsys)
    assert code == 1
    assert "record 3" in out and "altered" in out


def test_a_record_deleted_in_the_middle_is_found(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _log(tmp_path)
    _tamper(tmp_path, "DELETE FROM audit_log WHERE seq = 2")
    code, out = _verify(tmp_path, capsys)
    assert code == 1
    assert "record 2 is missing" in out


def test_a_deleted_record_renumbered_away_is_found(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Closing the gap (seq 3.. moved down by one) does not hide a deletion: record 2 now
    claims a previous hash that is not record 1's."""
    _log(tmp_path)
    _tamper(
        tmp_path,
        "DELETE FROM audit_log WHERE seq = 2",
        "UPDATE audit_log SET seq = seq - 1 WHERE seq > 2",
    )
    code, out = _verify(tmp_path, capsys)
    assert code == 1
    assert "record 2" in out


def test_reordered_records_are_found(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two records swapped (their seq exchanged): the first of them no longer fits."""
    _log(tmp_path)
    _tamper(
        tmp_path,
        "UPDATE audit_log SET seq = -1 WHERE seq = 2",
        "UPDATE audit_log SET seq = 2 WHERE seq = 4",
        "UPDATE audit_log SET seq = 4 WHERE seq = -1",
    )
    code, out = _verify(tmp_path, capsys)
    assert code == 1
    assert "record 2" in out


def test_a_rehashed_record_still_breaks_the_next(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Someone who alters a record and recomputes its hash breaks the link of the next."""
    _log(tmp_path)
    db = sqlite3.connect(tmp_path / "servodesk.db")
    row = db.execute(
        "SELECT seq, time, user, address, category, event, drive, result, message, details, "
        "prev FROM audit_log WHERE seq = 3"
    ).fetchone()
    db.close()
    from servodesk.services.audit import chain_hash

    forged = (*row[:2], "mallory", *row[3:10])
    _tamper(
        tmp_path,
        f"UPDATE audit_log SET user = 'mallory', hash = '{chain_hash(row[10], forged)}' "
        "WHERE seq = 3",
    )
    code, out = _verify(tmp_path, capsys)
    assert code == 1
    assert "record 4 does not follow record 3" in out


def test_the_log_refuses_update_and_delete(tmp_path: Path) -> None:
    _log(tmp_path)
    db = sqlite3.connect(tmp_path / "servodesk.db")
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):
        db.execute("UPDATE audit_log SET user = 'x' WHERE seq = 1")
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):
        db.execute("DELETE FROM audit_log")
    db.close()


def test_concurrent_writers_do_not_fork_the_chain(tmp_path: Path) -> None:
    """Threads of one process and a second process's connection (the CLI beside the
    server) append at once: one chain, every record in it."""
    path = tmp_path / "servodesk.db"
    one, two = AuditLog(path), AuditLog(path)

    def write(log: AuditLog, who: str) -> None:
        for i in range(150):
            log.record("motion.stopped", who=Actor(who), details={"i": i})

    threads = [
        threading.Thread(target=write, args=(log, f"{name}{k}"))
        for k in range(3)
        for log, name in ((one, "a"), (two, "b"))
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    two.close()
    verdict = one.verify()
    assert verdict.ok, verdict
    assert verdict.records == 900
    rows = one.query(limit=10_000)
    assert sorted(r["seq"] for r in rows) == list(range(1, 901))
    assert len({r["prev"] for r in rows}) == 900  # No two records chained to the same one.
    one.close()


def test_the_actor_of_the_context_is_recorded(tmp_path: Path) -> None:
    log = AuditLog(tmp_path / "servodesk.db")
    with as_actor(Actor("bob", "198.51.100.4")):
        log.record("write.alarm_reset", drive="s1")
    log.record("motion.stopped", drive="s1", ok=False, message="dead-man")
    newest, older = log.query(limit=2)
    assert (older["user"], older["address"], older["category"]) == ("bob", "198.51.100.4", "write")
    assert (newest["user"], newest["result"], newest["message"]) == (
        "system",
        "failure",
        "dead-man",
    )
    log.close()


def test_an_unknown_event_prefix_is_a_programming_error(tmp_path: Path) -> None:
    log = AuditLog(tmp_path / "servodesk.db")
    with pytest.raises(ValueError, match="prefix"):
        log.record("frobnicate.done")
    log.close()


def test_text_that_is_not_utf8_does_not_lose_the_record(tmp_path: Path) -> None:
    """A path decoded with surrogateescape (a request for /%ff) still makes a record."""
    log = AuditLog(tmp_path / "servodesk.db")
    log.record("request.refused", ok=False, message="404 GET /\udcff", details={"p": "\udcff"})
    assert log.query(limit=1)[0]["message"] == "404 GET /?"
    assert log.verify().ok
    log.close()


def test_export_jsonl_and_csv_carry_every_record(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _log(tmp_path, 3)
    assert main(["audit", "export", "--data-dir", str(tmp_path)]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [x["seq"] for x in lines] == [1, 2, 3]
    assert lines[0]["prev"] == GENESIS and lines[1]["prev"] == lines[0]["hash"]
    assert lines[2]["details"] == {"i": 2} and lines[2]["user"] == "alice"
    out = tmp_path / "audit.csv"
    assert (
        main(["audit", "export", "--format", "csv", "-o", str(out), "--data-dir", str(tmp_path)])
        == 0
    )
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [r["event"] for r in rows] == ["control.taken"] * 3
    assert rows[2]["hash"] == lines[2]["hash"]
    # --since later than every record: nothing but the CSV header.
    assert main(["audit", "export", "--since", "2999-01-01", "--data-dir", str(tmp_path)]) == 0
    assert capsys.readouterr().out == ""


def test_cli_bad_input_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["audit", "verify", "--data-dir", str(tmp_path / "none")]) == 2
    assert "no servodesk store" in capsys.readouterr().err
    _log(tmp_path, 1)
    assert main(["audit", "export", "--since", "yesterday", "--data-dir", str(tmp_path)]) == 2
    assert "ISO 8601" in capsys.readouterr().err
