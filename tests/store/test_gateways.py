"""Two servodesk gateways (applications with their own data directories) on one PostgreSQL
store: an account made with ``servodesk users add`` on one machine logs in on the other, and
both gateways' audit records land in one chain (issue 49)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.cli import main
from servodesk.services.audit import AuditLog
from servodesk.settings import Settings

PASSWORD = "correct horse battery"


def _gateway(data_dir: Path, url: str) -> TestClient:
    settings = Settings(
        data_dir=data_dir,
        store_url=url,
        host="0.0.0.0",
        allowed_hosts="testserver",
        viewer_port=0,
    )
    return TestClient(create_app(settings))


def test_two_gateways_share_accounts_and_the_audit_chain(
    tmp_path: Path, pg_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path / "laptop"))
    monkeypatch.setenv("SERVODESK_STORE_URL", pg_url)
    monkeypatch.setattr("sys.stdin", io.StringIO(PASSWORD + "\n"))
    assert main(["users", "add", "ada", "--role", "engineer", "--password-stdin"]) == 0

    with _gateway(tmp_path / "line1", pg_url) as one, _gateway(tmp_path / "line2", pg_url) as two:
        for client in (one, two):
            r = client.post("/api/v1/auth/login", json={"user": "ada", "password": PASSWORD})
            assert r.status_code == 200, r.text
        bad = {"user": "ada", "password": "wrong password"}
        assert two.post("/api/v1/auth/login", json=bad).status_code == 401
    log = AuditLog(pg_url)
    try:
        events = [r["event"] for r in reversed(log.query(limit=100))]
        # (The refused login's 401 is recorded after it as request.refused.)
        assert events[:4] == ["user.created", "access.login", "access.login", "access.login_failed"]
        assert log.verify().ok
    finally:
        log.close()
    # Nothing of the store is in the gateways' data directories.
    assert not (tmp_path / "line1" / "servodesk.db").exists()
