"""Commissioning reports in the store, on SQLite and PostgreSQL (issue 49; docs/report.md):
revision 0004 makes the table, a report is found again by its id and by its file's hash, its
first PDF is the one kept, and an unknown id is a clear NotFoundError."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.errors import NotFoundError
from servodesk.services import db
from servodesk.services.report_store import ReportStore
from servodesk.services.store import Store


def _meta(rid: str) -> dict[str, str | None]:
    return {
        "id": rid,
        "drive_key": "5344534B-00000402-1",
        "plant_tag": "L2.Press.X",
        "session": "cia402-generic-1",
        "time": "2026-12-07T14:00:00.000Z",
        "by": "engineer",
        "sha256": "ab" * 32,
    }


def test_reports_are_recorded_and_found_again(engine_url: str, tmp_path: Path) -> None:
    store = Store(tmp_path, engine_url)
    try:
        assert db.revision(store.engine) == "0006"
        reports = ReportStore(store.engine)
        html = b"<!DOCTYPE html><title>report</title>"
        meta = reports.add(_meta("report-1"), html)
        assert meta["html_sha256"] == hashlib.sha256(html).hexdigest()
        assert reports.get("report-1") == meta
        assert reports.html("report-1") == html and reports.pdf("report-1") is None
        # The first PDF kept is the one every later print returns.
        assert reports.set_pdf("report-1", b"%PDF-1 first") == b"%PDF-1 first"
        assert reports.set_pdf("report-1", b"%PDF-1 second") == b"%PDF-1 first"
        pdf_hash = hashlib.sha256(b"%PDF-1 first").hexdigest()
        assert reports.get("report-1")["pdf_sha256"] == pdf_hash
        found = reports.by_file_hash(pdf_hash)
        assert found is not None and found["id"] == "report-1"
        assert reports.by_file_hash("00" * 32) is None
        with pytest.raises(NotFoundError, match="no report 'report-2'"):
            reports.get("report-2")
    finally:
        store.close()


def test_reports_move_with_the_store(engine_url: str, tmp_path: Path) -> None:
    """``servodesk store export/import`` carries the reports, bytes and hashes, to either
    engine: a report made on one store still verifies against the other."""
    source = Store(tmp_path / "a")
    try:
        reports = ReportStore(source.engine)
        reports.add(_meta("report-1"), b"<html>\xc3\xa4</html>")
        reports.set_pdf("report-1", b"%PDF-1 print")
        made = reports.get("report-1")
    finally:
        source.close()
    dump = tmp_path / "store.jsonl"
    assert main(["store", "export", str(dump), "--data-dir", str(tmp_path / "a")]) == 0
    target = ["--url", engine_url] if engine_url else ["--data-dir", str(tmp_path / "b")]
    assert main(["store", "import", str(dump), *target]) == 0
    store = Store(tmp_path / "b", engine_url)
    try:
        moved = ReportStore(store.engine)
        assert moved.get("report-1") == made
        assert moved.html("report-1") == b"<html>\xc3\xa4</html>"
        assert moved.pdf("report-1") == b"%PDF-1 print"
    finally:
        store.close()
