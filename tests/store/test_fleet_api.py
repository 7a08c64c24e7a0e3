"""The fleet API on a gateway serving simulated drives, on SQLite and PostgreSQL (issue 49,
second slice): who may read and change the fleet, plant tags, approvals, a drift check on
demand, the scheduled scan finding a parameter changed on the twin, and the webhook POSTed
to a real HTTP server started here."""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import threading
import time
from collections.abc import AsyncIterator, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import httpx
import pytest
import pytest_asyncio

from tests.backup.helpers import change_plain
from tests.store.gateway import Gateway, gateway

pytestmark = pytest.mark.asyncio(loop_scope="module")
_n = itertools.count()

GATEWAY = "line-7"
ROLES = ("administrator", "engineer", "service", "operator", "guest")
#: Generous: the scheduled scan reads every parameter of a drive on a loaded CI machine.
WAIT_S = 90.0


class Hook(BaseHTTPRequestHandler):
    received: list[dict[str, Any]]

    def do_POST(self) -> None:
        body = self.rfile.read(int(self.headers.get("Content-Length", "0")))
        self.server.received.append(  # type: ignore[attr-defined]
            {"type": self.headers.get("Content-Type"), "body": json.loads(body)}
        )
        self.send_response(204)
        self.end_headers()

    def log_message(self, *args: Any) -> None:
        pass


@pytest.fixture(scope="module")
def webhook() -> Iterator[ThreadingHTTPServer]:
    server = ThreadingHTTPServer(("127.0.0.1", 0), Hook)
    server.received = []  # type: ignore[attr-defined]
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()


@pytest_asyncio.fixture(loop_scope="module", scope="module", params=["sqlite", "postgresql"])
async def gw(
    request: pytest.FixtureRequest,
    tmp_path_factory: pytest.TempPathFactory,
    webhook: ThreadingHTTPServer,
) -> AsyncIterator[Gateway]:
    url = "" if request.param == "sqlite" else request.getfixturevalue("pg_server").new_database()
    async with gateway(
        tmp_path_factory.mktemp("gw"),
        url,
        ROLES,
        sim_channel=f"fleet-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic,hiwin-e",
        gateway_name=GATEWAY,
        gateway_url="https://line7.plant.example:8000",
        drift_interval_s=1.0,
        drift_webhook=f"http://127.0.0.1:{webhook.server_address[1]}/hook",
    ) as g:
        yield g


async def _drives(gw: Gateway, **params: Any) -> list[dict[str, Any]]:
    r = await gw.clients["guest"].get("/fleet", params=params)
    assert r.status_code == 200, r.text
    return list(r.json()["drives"])


async def _generic(gw: Gateway) -> dict[str, Any]:
    drives = await _drives(gw, q="cia402-generic")
    assert len(drives) == 1, drives
    return drives[0]


async def _approved(gw: Gateway) -> dict[str, Any]:
    """The generic drive tagged L2.Press.X with an approved backup: what the approval test
    leaves, made here when it has not run first (pytest-xdist may order the module's tests
    differently)."""
    generic = await _generic(gw)
    if generic["approved"] is None:
        eng, key, sid = gw.clients["engineer"], generic["drive_key"], generic["session"]
        if generic["plant_tag"] != "L2.Press.X":
            r = await eng.put("/fleet/tag", json={"drive": key, "tag": "L2.Press.X"})
            assert r.status_code == 200, r.text
        r = await eng.post(f"/sessions/{sid}/backups", json={"label": "commissioned"})
        assert r.status_code == 201, r.text
        approve = {"drive": key, "backup": r.json()["id"], "reason": "commissioned"}
        r = await eng.put("/fleet/approved", json=approve)
        assert r.status_code == 200, r.text
        generic = await _generic(gw)
    return generic


async def test_connected_drives_and_the_gateway_are_in_the_fleet(gw: Gateway) -> None:
    drives = await _drives(gw)
    assert {d["profile_id"] for d in drives} == {"cia402-generic", "hiwin-e"}
    generic = await _generic(gw)
    assert generic["gateway"] == GATEWAY
    assert generic["link"] == f"https://line7.plant.example:8000/#/overview/{generic['session']}"
    assert generic["drift"]["state"] == "unknown" and generic["approved"] is None
    r = await gw.clients["operator"].get("/fleet/gateways")
    assert r.status_code == 200
    (me,) = [g for g in r.json() if g["name"] == GATEWAY]
    assert me["alive"] and me["url"] == "https://line7.plant.example:8000" and me["buses"]


async def test_tags_and_approvals_need_the_right_and_say_what_is_wrong(gw: Gateway) -> None:
    eng, guest = gw.clients["engineer"], gw.clients["guest"]
    generic = await _generic(gw)
    key, sid = generic["drive_key"], generic["session"]
    hiwin = (await _drives(gw, q="hiwin"))[0]["drive_key"]

    for role in ("guest", "operator"):
        r = await gw.clients[role].put("/fleet/tag", json={"drive": key, "tag": "L2.Press.X"})
        assert r.status_code == 403, r.text
        assert "write_parameters" in r.json()["message"]
    r = await eng.put("/fleet/tag", json={"drive": key, "tag": "L2 Press"})
    assert r.status_code == 400 and "not a plant tag" in r.json()["message"], r.text
    assert "letters, digits" in r.json()["hint"]
    r = await eng.put("/fleet/tag", json={"drive": "no-such-drive", "tag": "L2"})
    assert r.status_code == 404 and "no drive 'no-such-drive'" in r.json()["message"]
    r = await eng.put("/fleet/tag", json={"drive": key, "tag": "L2.Press.X"})
    assert r.status_code == 200 and r.json()["plant_tag"] == "L2.Press.X", r.text
    r = await eng.put("/fleet/tag", json={"drive": hiwin, "tag": "L2.Press.X"})
    assert r.status_code == 409 and key in r.json()["message"]

    r = await eng.post(f"/sessions/{sid}/backups", json={"label": "commissioned"})
    assert r.status_code == 201, r.text
    bid = r.json()["id"]
    approve = {"drive": "L2.Press.X", "backup": bid, "reason": "commissioned, QA signed"}
    for role in ("guest", "operator", "service"):
        r = await gw.clients[role].put("/fleet/approved", json=approve)
        assert r.status_code == 403, (role, r.text)
    r = await eng.put("/fleet/approved", json={k: v for k, v in approve.items() if k != "reason"})
    assert r.status_code == 422 and "reason" in r.json()["message"], r.text
    r = await eng.put("/fleet/approved", json={**approve, "reason": "  "})
    assert r.status_code == 422 and r.json()["field"] == "reason", r.text
    r = await eng.put("/fleet/approved", json={**approve, "backup": "nope"})
    assert r.status_code == 404 and "no backup 'nope'" in r.json()["message"]
    # No approval yet: a drift check has nothing to compare with.
    r = await eng.post(f"/sessions/{sid}/drift")
    assert r.status_code == 409 and "no approved backup" in r.json()["message"]

    r = await eng.put("/fleet/approved", json=approve)
    assert r.status_code == 200, r.text
    approved = r.json()["approved"]
    assert approved["backup"] == bid and approved["by"] == "engineer"
    assert approved["reason"] == "commissioned, QA signed" and approved["at"]
    # Who approved what, and why, is in the audit log.
    r = await gw.clients["administrator"].get("/audit", params={"event": "backup.approved"})
    (rec,) = r.json()
    assert rec["user"] == "engineer" and rec["message"] == "commissioned, QA signed"
    assert rec["details"] == {"drive_key": key, "backup": bid}

    r = await guest.post(f"/sessions/{sid}/drift")
    assert r.status_code == 403
    r = await gw.clients["service"].post(f"/sessions/{sid}/drift")
    assert r.status_code == 200, r.text
    # (The scheduled scan may have changed nothing yet: the drive is as approved.)
    assert r.json()["state"] == "in_step" and r.json()["count"] == 0
    assert r.json()["plant_tag"] == "L2.Press.X" and r.json()["webhook"] is None


async def test_the_scheduled_scan_finds_a_changed_parameter_and_calls_the_webhook(
    gw: Gateway, webhook: ThreadingHTTPServer
) -> None:
    generic = await _approved(gw)
    state = gw.state
    session = state.manager.get(generic["session"])
    ps = await asyncio.to_thread(state.backups.load, generic["approved"]["backup"])
    webhook.received.clear()  # type: ignore[attr-defined]
    (changed,) = await change_plain(session, ps, 1)

    deadline = time.monotonic() + WAIT_S
    while True:
        drifted = await _drives(gw, drift="drifted")
        if drifted:
            break
        assert time.monotonic() < deadline, "the scheduled scan did not find the change"
        await asyncio.sleep(0.5)
    (drive,) = drifted
    key = generic["drive_key"]
    assert drive["drive_key"] == key and drive["drift"]["count"] == 1

    r = await gw.clients["guest"].get("/fleet/drift", params={"drive": "L2.Press.X"})
    assert r.status_code == 200
    result = r.json()[0]
    assert result["state"] == "drifted" and result["gateway"] == GATEWAY
    (diff,) = result["differences"]
    assert diff["address"] == str(changed) and diff["kind"] == "changed"
    assert diff["approved_raw_hex"] != diff["drive_raw_hex"]
    assert diff["name"] == session.profile.spec(changed).name

    while not webhook.received:  # type: ignore[attr-defined]
        assert time.monotonic() < deadline, "the webhook was not called"
        await asyncio.sleep(0.2)
    post = webhook.received[0]  # type: ignore[attr-defined]
    assert post["type"] == "application/json"
    body = post["body"]
    assert body["event"] == "servodesk.drift" and body["plant_tag"] == "L2.Press.X"
    assert body["gateway"] == GATEWAY and body["count"] == 1
    assert [p["address"] for p in body["parameters"]] == [str(changed)]
    # The outcome is recorded with the result; the next scans find the same drift and
    # record it without calling the webhook again.
    deadline = time.monotonic() + WAIT_S
    while True:
        r = await gw.clients["guest"].get("/fleet/drift", params={"drive": key, "limit": 1000})
        found = [x for x in r.json() if x["state"] == "drifted"]
        if len(found) >= 3 and found[-1]["webhook"] == "sent: HTTP 204":
            break
        assert time.monotonic() < deadline, found
        await asyncio.sleep(0.5)
    assert all(x["webhook"].startswith("not sent: as result") for x in found[:-1]), found
    assert len(webhook.received) == 1  # type: ignore[attr-defined]


async def test_an_approval_is_cleared_with_a_reason_and_audited(gw: Gateway) -> None:
    generic = await _approved(gw)
    key, bid = generic["drive_key"], generic["approved"]["backup"]
    eng = gw.clients["engineer"]
    clear = {"drive": "L2.Press.X", "reason": "drive rebuilt, new reference to follow"}

    async def delete(role: str, body: dict[str, Any]) -> httpx.Response:
        return await gw.clients[role].request("DELETE", "/fleet/approved", json=body)

    for role in ("guest", "operator", "service"):
        r = await delete(role, clear)
        assert r.status_code == 403 and "write_parameters" in r.json()["message"], (role, r.text)
    r = await delete("engineer", {"drive": key})
    assert r.status_code == 422 and "reason" in r.json()["message"], r.text
    r = await delete("engineer", {**clear, "reason": " "})
    assert r.status_code == 422 and r.json()["field"] == "reason", r.text
    r = await delete("engineer", {**clear, "drive": "no-such-drive"})
    assert r.status_code == 404, r.text
    assert (await _generic(gw))["approved"] is not None  # Nothing refused changed anything.

    r = await delete("engineer", clear)
    assert r.status_code == 200, r.text
    cleared = r.json()
    assert cleared["approved"] is None and cleared["drive_key"] == key
    assert cleared["drift"] == {"state": "unknown", "count": None, "time": None}
    assert (await _generic(gw))["approved"] is None
    # A drift check has nothing to compare with now; clearing twice says there is nothing.
    r = await eng.post(f"/sessions/{generic['session']}/drift")
    assert r.status_code == 409 and "no approved backup" in r.json()["message"]
    r = await delete("engineer", clear)
    assert r.status_code == 409 and "no approved backup to clear" in r.json()["message"]
    # Who cleared which approval, and why, is in the audit log.
    r = await gw.clients["administrator"].get("/audit", params={"event": "backup.approval_cleared"})
    (rec,) = r.json()
    assert rec["user"] == "engineer" and rec["message"] == clear["reason"]
    assert rec["details"] == {"drive_key": key, "backup": bid}
    await _approved(gw)  # The other tests' drive, approved again.


async def test_stored_tunings_are_listed_read_and_in_the_fleet(gw: Gateway) -> None:
    generic = await _generic(gw)
    key, sid = generic["drive_key"], generic["session"]
    body = {
        "kind": "gains", "status": "stopped", "error": None, "drive_code": None,
        "mode": "basic", "job": f"{sid}-t1", "identified": None, "bode": None,
        "margins": None, "gains": [], "step": None, "axis_time_s": None,
        "excursion_rev": None, "travel": None, "peak_torque_pct": None,
        "peak_torque_polled_s": None, "applied": False, "stored": False, "notes": ["n"],
    }  # fmt: skip
    for n, (status, ended) in enumerate((("stopped", 1000.0), ("done", 2000.0))):
        record = {
            "id": f"tuning-t{n}", "drive_key": key, "session": sid, "kind": "gains",
            "mode": "basic", "status": status, "started": ended - 60, "ended": ended,
            "by": "engineer", "client": "tab-1", "applied": status == "done",
            "result": {**body, "status": status, "applied": status == "done"},
        }  # fmt: skip
        await asyncio.to_thread(gw.state.tuning_results.add, record)
    # Whoever may read tuning information reads them: the guest too.
    guest = gw.clients["guest"]
    r = await guest.get(f"/sessions/{sid}/tuning/results")
    assert r.status_code == 200, r.text
    rows = r.json()
    assert [x["id"] for x in rows] == ["tuning-t1", "tuning-t0"]  # Newest first.
    assert rows[0]["gateway"] == GATEWAY and rows[0]["applied"] is True
    assert "result" not in rows[0]
    r = await guest.get("/tuning/results/tuning-t0")
    assert r.status_code == 200, r.text
    assert r.json()["result"] == {**body, "status": "stopped"}
    assert r.json()["started"] == 940.0 and r.json()["by"] == "engineer"
    r = await guest.get("/tuning/results/tuning-none")
    assert r.status_code == 404 and "no tuning result" in r.json()["message"]
    r = await guest.get("/tuning/results/Not%20An%20Id")
    assert r.status_code == 422 and "rid" in r.json()["field"], r.text
    r = await guest.get(f"/sessions/{sid}/tuning/results", params={"limit": 0})
    assert r.status_code == 422
    # The fleet page's "last tuning" column: the newest one.
    last = (await _generic(gw))["last_tuning"]
    assert last == {"id": "tuning-t1", "time": "1970-01-01T00:33:20.000Z", "status": "done",
                    "mode": "basic"}  # fmt: skip
    hiwin = (await _drives(gw, q="hiwin"))[0]
    assert hiwin["last_tuning"] is None


async def test_bad_fleet_queries_are_4xx(gw: Gateway) -> None:
    await _approved(gw)  # The drive tagged L2.Press.X, found by a search below.
    guest = gw.clients["guest"]
    r = await guest.get("/fleet", params={"drift": "sideways"})
    assert r.status_code == 422 and "drift" in r.json()["message"]
    r = await guest.get("/fleet", params={"limit": 0})
    assert r.status_code == 422
    r = await guest.get("/fleet/drift", params={"drive": "nope"})
    assert r.status_code == 404
    # A NUL never reaches the database (PostgreSQL refuses it in text): a clear 422.
    r = await guest.get("/fleet", params={"q": "L2\x00"})
    assert r.status_code == 422 and r.json()["field"] == "q", r.text
    body = {"drive": "L2.Press.X", "backup": "b", "reason": "why\x00"}
    r = await gw.clients["engineer"].put("/fleet/approved", json=body)
    assert r.status_code == 422 and r.json()["field"] == "reason", r.text
    r = await guest.get("/fleet", params={"q": "L2.PRESS"})
    assert [d["plant_tag"] for d in r.json()["drives"]] == ["L2.Press.X"]
