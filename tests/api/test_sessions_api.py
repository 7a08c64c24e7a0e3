"""The REST API against a simulated drive: sessions, objects, state, errors."""

from __future__ import annotations

import asyncio

import httpx
import pytest

pytestmark = pytest.mark.asyncio(loop_scope="module")

SID = "cia402-generic-1"


async def test_health_reports_simulation_and_usable_links(client: httpx.AsyncClient) -> None:
    r = await client.get("/api/v1/health")
    assert r.status_code == 200
    body = r.json()
    assert body["status"] == "ok" and body["simulation"] is True
    assert body["links"]["canopen"] is None


async def test_sim_sessions_are_listed_with_identity(client: httpx.AsyncClient) -> None:
    r = await client.get("/api/v1/sessions")
    assert r.status_code == 200
    sessions = {s["id"]: s for s in r.json()}
    s = sessions[SID]
    assert s["simulated"] is True and s["profile_id"] == "cia402-generic"
    assert s["identity"]["vendor_id"] == 0x5344534B
    assert s["identity"]["device_name"] == "servodesk simulated CiA 402 drive"


async def test_read_gives_typed_hex_and_engineering_values(client: httpx.AsyncClient) -> None:
    r = await client.get(f"/api/v1/sessions/{SID}/objects/0x1000")
    assert r.status_code == 200
    assert r.json()["value"] == 0x00020192 and r.json()["raw_hex"] == "92010200"
    r = await client.get(f"/api/v1/sessions/{SID}/objects/1008h")  # Segmented upload.
    assert r.json()["value"] == "servodesk simulated CiA 402 drive"
    r = await client.get(f"/api/v1/sessions/{SID}/objects/0x6083:00")
    body = r.json()
    assert body["unit"] == "rpm/s" and body["raw_unit"] == "inc/s²"
    assert body["engineering"] == pytest.approx(body["value"] * 60 / 131072)


async def test_write_reads_back(client: httpx.AsyncClient) -> None:
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x6081", json={"value": 123456})
    assert r.status_code == 200, r.text
    assert r.json()["value"] == 123456
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x6081", json={"raw_hex": "40e20100"})
    assert r.json()["value"] == 123456 and r.json()["raw_hex"] == "40e20100"
    # Without the control token (the client holds control, conftest.py) the write is refused,
    # naming the holder, and nothing reaches the drive.
    req = client.build_request(
        "PUT", f"/api/v1/sessions/{SID}/objects/0x6081", json={"value": 654321}
    )
    del req.headers["X-Servodesk-Control"]
    r = await client.send(req)
    assert r.status_code == 409 and "'api-test' holds control" in r.json()["message"], r.text
    r = await client.get(f"/api/v1/sessions/{SID}/objects/0x6081")
    assert r.json()["value"] == 123456


async def test_write_to_read_only_is_4xx_with_abort_code_and_text(
    client: httpx.AsyncClient,
) -> None:
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x6041", json={"value": 1})
    assert r.status_code == 400
    body = r.json()
    assert body["code_hex"] == "0x06010002"
    assert body["meaning"] == "Attempt to write a read only object"
    # An object unknown to the profile goes to the drive, which aborts with its own code.
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x2FFF", json={"raw_hex": "01"})
    assert r.status_code == 404 and r.json()["code_hex"] == "0x06020000"
    assert r.json()["protocol"] == "sdo"


async def test_bad_requests_get_clear_4xx(client: httpx.AsyncClient) -> None:
    r = await client.get("/api/v1/sessions/nope/objects/0x1000")
    assert r.status_code == 404 and "no session 'nope'" in r.json()["message"]
    r = await client.get(f"/api/v1/sessions/{SID}/objects/zzz")
    assert r.status_code == 400 and "not an object address" in r.json()["message"]
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x6081", json={"value": -5})
    assert r.status_code == 400 and "below the minimum" in r.json()["message"]
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x6081", json={"colour": 1})
    assert r.status_code == 422 and r.json()["error"] == "ValidationError"
    r = await client.post("/api/v1/sessions/" + SID + "/state", json={"command": "fly"})
    assert r.status_code == 422
    r = await client.post("/api/v1/sessions", json={"interface": "nocan", "node_id": 1})
    assert r.status_code == 422 and r.json()["field"] == "interface"
    r = await client.post(
        "/api/v1/sessions", json={"interface": "socketcan", "channel": "nosuchcan9", "node_id": 1}
    )
    assert r.status_code == 404 and "cannot open CAN interface" in r.json()["message"]


async def test_opening_a_node_that_does_not_answer_is_404(client: httpx.AsyncClient) -> None:
    r = await client.post(
        "/api/v1/sessions",
        json={"interface": "virtual", "channel": "nobody-here", "node_id": 9},
    )
    assert r.status_code == 404
    assert "does not answer" in r.json()["message"]


async def test_twenty_concurrent_reads_all_return_correct_values(
    client: httpx.AsyncClient,
) -> None:
    expected = {
        "0x1000": 0x00020192,
        "0x1018:01": 0x5344534B,
        "0x1018:02": 0x402,
        "0x1018:03": 0x00010000,
        "0x6502": 0x2D,
    }
    addrs = [list(expected)[i % len(expected)] for i in range(20)]
    rs = await asyncio.gather(*(client.get(f"/api/v1/sessions/{SID}/objects/{a}") for a in addrs))
    assert [r.status_code for r in rs] == [200] * 20
    assert [r.json()["value"] for r in rs] == [expected[a] for a in addrs]


async def test_state_commands_walk_the_state_machine(client: httpx.AsyncClient) -> None:
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "enable"})
    assert r.status_code == 200, r.text
    assert r.json()["state"] == "Operation enabled"
    bits = {b["bit"]: b for b in r.json()["bits"]}
    assert bits[2]["set"] and bits[2]["name"] == "Operation enabled"
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "quick_stop"})
    assert r.json()["state"] in ("Quick stop active", "Switch on disabled")
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "disable"})
    assert r.json()["state"] == "Switch on disabled"


async def test_profiles_endpoint_lists_objects_with_units(client: httpx.AsyncClient) -> None:
    r = await client.get("/api/v1/profiles")
    assert any(p["id"] == "cia402-generic" for p in r.json())
    r = await client.get("/api/v1/profiles/cia402-generic")
    objs = {o["address"]: o for o in r.json()["object_list"]}
    assert objs["0x6064:00"]["unit"] == "deg" and objs["0x6064:00"]["raw_unit"] == "inc"
    r = await client.get("/api/v1/profiles/nope")
    assert r.status_code == 404 and "cia402-generic" in r.json()["hint"]
