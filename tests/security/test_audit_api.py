"""The audit log as a user meets it (docs/security.md, "Audit log"): what servodesk records
when drives are controlled, moved and written, the refused requests, the filters of
GET /api/v1/audit, verification and export; and a data directory of an older servodesk."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.services.store import Store
from servodesk.settings import Settings
from tests.operation.support import (
    headers,
    operation_app,
    take,
    take_and_enable,
    wait_motion,
    wait_until,
)

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"


def _events(client: TestClient, **filters: Any) -> list[dict[str, Any]]:
    r = client.get("/api/v1/audit", params={"limit": 1000, **filters})
    assert r.status_code == 200, r.text
    out: list[dict[str, Any]] = r.json()
    return out


def _names(records: list[dict[str, Any]]) -> list[str]:
    return [r["event"] for r in records]


def test_control_writes_motion_and_refusals_are_recorded(channel: str, tmp_path: Path) -> None:
    with operation_app(channel, tmp_path, deadman_ms=250) as (client, sim):
        drive = sim.drives[0]
        take(client, SID, "A")
        r = client.put(f"{BASE}/objects/0x6081:00", json={"value": 1234}, headers=headers("A"))
        assert r.status_code == 200, r.text
        r = client.post(f"{BASE}/store", headers=headers("A"))
        assert r.status_code == 200, r.text
        # Refused: a write by someone who does not hold control (409), a request with a
        # token in its query (the token must not reach the log).
        r = client.put(f"{BASE}/objects/0x6081:00", json={"value": 1}, headers=headers("B"))
        assert r.status_code == 409
        assert client.get("/api/v1/sessions/nope?token=Zm9vYmFy-secret").status_code == 404
        take(client, SID, "B", force=True)

        with client.websocket_connect("/api/v1/ws?client=B") as ws:
            ws.send_json({"type": "subscribe", "session": SID})
            take(client, SID, "B")
            beats = take_and_enable(client, SID, "B", ws)
            r = client.post(
                f"{BASE}/motion/jog",
                json={"velocity": 100_000, "acceleration": 2_000_000},
                headers=headers("B"),
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 50_000, 3.0)
            beats.stop()  # The operator goes silent: the dead-man stops the jog.
            m = wait_motion(client, SID, 5.0)
            assert m["state"] == "deadman", m
        r = client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("B"))

        records = _events(client)
        names = _names(records)
        for expected in (
            "control.taken",
            "write.object",
            "write.store_eeprom",
            "request.refused",
            "control.forced",
            "write.state_command",
            "motion.started",
            "motion.stopped",
        ):
            assert expected in names, (expected, names)
        # Newest first, one chain.
        seqs = [r["seq"] for r in records]
        assert seqs == sorted(seqs, reverse=True)
        assert client.get("/api/v1/audit/verify").json()["ok"] is True

        write = next(
            r
            for r in records
            if r["event"] == "write.object" and r["details"]["address"] == "0x6081:00"
        )
        assert write["drive"] == SID and write["category"] == "write"
        assert write["user"] == "local" and write["address"] == "testclient"
        assert write["details"]["new_value"] == 1234 and write["details"]["client"] == "A"

        forced = next(r for r in records if r["event"] == "control.forced")
        assert forced["details"] == {"client": "B", "previous": "A"}

        refused = [r for r in records if r["event"] == "request.refused"]
        statuses = {r["details"]["status"]: r for r in refused}
        assert statuses[409]["details"]["path"] == f"{BASE}/objects/0x6081:00"
        assert statuses[404]["details"]["path"] == "/api/v1/sessions/nope"
        assert all("secret" not in str(r) for r in records)
        assert all(r["result"] == "failure" for r in refused)

        # The dead-man's stop: a failure, by the system, with its reason.
        stop = next(
            r
            for r in records
            if r["event"] == "motion.stopped" and r["details"]["state"] == "deadman"
        )
        assert stop["result"] == "failure" and stop["user"] == "system"
        assert "heartbeat" in stop["message"] and stop["details"]["kind"] == "jog"
        started = next(r for r in records if r["event"] == "motion.started")
        assert started["user"] == "local" and started["details"]["owner"] == "B"


def test_filters_window_and_export(channel: str, tmp_path: Path) -> None:
    with operation_app(channel, tmp_path) as (client, _):
        take(client, SID, "A")
        client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("A"))
        client.get("/api/v1/sessions/nope")
        everything = _events(client)
        assert {r["category"] for r in _events(client, category="control")} == {"control"}
        assert _names(_events(client, category="control")) == ["control.released", "control.taken"]
        assert _events(client, drive="nope") == []
        assert {r["drive"] for r in _events(client, drive=SID)} == {SID}
        assert _events(client, user="someone-else") == []
        assert len(_events(client, user="local")) == len(everything)
        assert len(_events(client, limit=1)) == 1
        newest = everything[0]
        assert _events(client, since="2999-01-01T00:00:00Z") == []
        assert _events(client, until="2000-01-01T00:00:00") == []
        assert newest in _events(client, since=newest["time"])
        assert [r["seq"] for r in _events(client, before=newest["seq"])] == [
            r["seq"] for r in everything[1:]
        ]
        # An empty window lists nothing; bad filters are a 4xx, never a 500.
        assert _events(client, since="2026-12-02", until="2026-12-01") == []
        r = client.get("/api/v1/audit", params={"category": "nonsense"})
        assert r.status_code == 422
        r = client.get("/api/v1/audit", params={"since": "yesterday"})
        assert r.status_code == 422

        r = client.get("/api/v1/audit/export", params={"format": "csv"})
        assert r.status_code == 200
        assert r.headers["content-type"].startswith("text/csv")
        assert "attachment" in r.headers["content-disposition"]
        lines = r.text.splitlines()
        assert lines[0].startswith("seq,time,user,address,category,event")
        # Every record up to the export (the export's own request is not refused).
        assert len(lines) - 1 >= len(everything)
        r = client.get("/api/v1/audit/export", params={"format": "jsonl"})
        assert r.status_code == 200 and r.text.count("\n") >= len(everything)


def test_a_cross_origin_request_refused_before_any_route_is_recorded(tmp_path: Path) -> None:
    app = create_app(Settings(data_dir=tmp_path, allowed_hosts=""))
    with TestClient(app, base_url="http://127.0.0.1:8000") as client:
        r = client.post(
            "/api/v1/sessions/x/alarms/reset", headers={"Origin": "http://evil.example"}
        )
        assert r.status_code == 403
        rec = _events(client, category="request_error")[0]
        assert rec["details"] == {
            "status": 403,
            "method": "POST",
            "path": "/api/v1/sessions/x/alarms/reset",
        }


def test_a_data_directory_of_an_older_servodesk_keeps_its_write_history(tmp_path: Path) -> None:
    """The parameter-write table of before issue 45 stays as it was (GET /audit/writes) and
    the new log starts beside it in the same database."""
    store = Store(tmp_path)
    store.add_audit(
        {
            "time": time.time(),
            "client": "ui-old",
            "session": "s-old",
            "drive_key": "canopen:vcan0:3",
            "address": "0x6081:00",
            "new_raw_hex": "10000000",
            "new_value": 16,
        }
    )
    store.close()
    with TestClient(create_app(Settings(data_dir=tmp_path))) as client:
        old = client.get("/api/v1/audit/writes").json()
        assert [(w["client"], w["new_value"]) for w in old] == [("ui-old", 16)]
        client.get("/api/v1/sessions/nope")
        assert _names(_events(client)) == ["request.refused"]
        assert client.get("/api/v1/audit/verify").json() == {
            "ok": True,
            "records": 1,
            "head": _events(client)[0]["hash"],
            "broken": None,
            "problem": None,
        }


def test_filters_at_the_edges_of_time_never_fail(tmp_path: Path) -> None:
    """Found by schemathesis: times UTC cannot hold are the ends of time; a page cursor
    past SQLite's integers is a 422."""
    with TestClient(create_app(Settings(data_dir=tmp_path))) as client:
        client.get("/api/v1/sessions/nope")  # One record.
        assert _events(client, since="9999-12-31T23:00:00-05:00") == []
        assert len(_events(client, since="0001-01-01T00:30:00+01:00")) == 1
        assert _events(client, until="0001-01-01T00:30:00+01:00") == []
        assert len(_events(client, until="9999-12-31T23:00:00-05:00")) == 1
        r = client.get("/api/v1/audit", params={"before": str(10**30)})
        assert r.status_code == 422
        r = client.get("/api/v1/audit/export", params={"since": "9999-12-31T23:00:00-05:00"})
        assert r.status_code == 200 and r.text == ""
