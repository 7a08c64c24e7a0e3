"""Batch reads, dirty tracking, save to non-volatile memory, restore defaults, state checks."""

from __future__ import annotations

import asyncio
from pathlib import Path

import httpx
import pytest

pytestmark = pytest.mark.asyncio(loop_scope="module")

SID = "cia402-generic-1"
DATA = Path(__file__).parent.parent / "data" / "devdesc"


async def test_batch_read_keeps_order_and_reports_failures_in_place(
    client: httpx.AsyncClient,
) -> None:
    r = await client.post(
        f"/api/v1/sessions/{SID}/read", json={"addresses": ["0x1000", "0x2FFF", "0x1018:02"]}
    )
    assert r.status_code == 200
    res = r.json()["results"]
    assert res[0]["value"] == 0x00020192
    assert res[1]["address"] == "0x2FFF:00" and res[1]["error"]["code_hex"] == "0x06020000"
    assert res[2]["value"] == 0x402


async def test_writes_are_dirty_until_stored(client: httpx.AsyncClient) -> None:
    r = await client.put(f"/api/v1/sessions/{SID}/objects/0x6081", json={"value": 4321})
    assert r.status_code == 200
    info = (await client.get(f"/api/v1/sessions/{SID}")).json()
    assert "0x6081:00" in info["dirty"]
    r = await client.post(f"/api/v1/sessions/{SID}/store")
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["stored"] >= 1 and body["procedure"] == "0x1010:01 <- 0x65766173"
    assert (await client.get(f"/api/v1/sessions/{SID}")).json()["dirty"] == []


async def test_restore_defaults_needs_confirmation_then_resets(client: httpx.AsyncClient) -> None:
    await client.put(f"/api/v1/sessions/{SID}/objects/0x6081", json={"value": 777})
    await client.post(f"/api/v1/sessions/{SID}/store")
    r = await client.post(f"/api/v1/sessions/{SID}/restore-defaults", json={"confirm": False})
    assert r.status_code == 422 and r.json()["field"] == "confirm"
    r = await client.post(
        f"/api/v1/sessions/{SID}/restore-defaults", json={"confirm": True, "reset": True}
    )
    assert r.status_code == 200 and "reset" in r.json()["message"]
    # After the reset the drive boots with its defaults (6081h default 200000).
    for _ in range(50):
        r = await client.get(f"/api/v1/sessions/{SID}/objects/0x6081")
        if r.status_code == 200 and r.json()["value"] == 200000:
            break
    assert r.json()["value"] == 200000


async def test_a_state_command_that_does_not_apply_is_409_with_the_next_step(
    client: httpx.AsyncClient,
) -> None:
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "disable"})
    assert r.json()["state"] == "Switch on disabled"
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "switch_on"})
    assert r.status_code == 409
    assert r.json()["hint"] == "send shutdown first"
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "fault_reset"})
    assert r.status_code == 409 and "no fault" in r.json()["hint"]
    # Stopping is never refused.
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "quick_stop"})
    assert r.status_code == 200


async def test_unknown_object_is_404(client: httpx.AsyncClient) -> None:
    r = await client.get(f"/api/v1/sessions/{SID}/objects/0x2FFF")
    assert r.status_code == 404 and r.json()["code_hex"] == "0x06020000"


@pytest.mark.parametrize("fmt", ["eds", "dcf", "esi"])
async def test_every_format_exports(client: httpx.AsyncClient, fmt: str) -> None:
    r = await client.get(f"/api/v1/profiles/hiwin-e/export?format={fmt}")
    assert r.status_code == 200
    assert "attachment" in r.headers["content-disposition"]
    assert ("EtherCATInfo" in r.text) if fmt == "esi" else ("[DeviceInfo]" in r.text)


async def test_import_a_third_party_eds_as_a_profile(client: httpx.AsyncClient) -> None:
    text = (DATA / "acme_ad400.eds").read_text()
    r = await client.post(
        "/api/v1/profiles/import?filename=acme.eds&profile_id=acme-test",
        files={"file": ("acme.eds", text)},
    )
    assert r.status_code == 201, r.text
    assert r.json()["id"] == "acme-test" and r.json()["variables"] > 10
    assert (await client.get("/api/v1/profiles/acme-test")).status_code == 200
    r = await client.post(
        "/api/v1/profiles/import?filename=acme.eds&profile_id=acme-test",
        files={"file": ("acme.eds", text)},
    )
    assert r.status_code == 409
    r = await client.post(
        "/api/v1/profiles/import?filename=x.txt", files={"file": ("x.txt", "hello")}
    )
    assert r.status_code == 400 and ".eds" in r.json()["hint"]
    r = await client.post(
        "/api/v1/profiles/import?filename=bad.eds", files={"file": ("bad.eds", "[DeviceInfo\n")}
    )
    assert r.status_code == 400


CORPUS = Path(__file__).resolve().parents[2].parent / "shared" / "corpus"


@pytest.mark.skipif(not CORPUS.is_dir(), reason="the shared corpus is not beside the repository")
async def test_import_one_device_of_a_vendor_esi_with_its_warnings(
    client: httpx.AsyncClient,
) -> None:
    """An ESI with four devices: the chosen one, an EtherCAT profile, what was left out."""
    text = (CORPUS / "esi" / "Elmo_Gold_ECAT_00010420_V11.xml").read_text(encoding="latin-1")
    url = "/api/v1/profiles/import?filename=elmo.xml&profile_id=elmo-gold-drive"
    r = await client.post(url + "&device=3", files={"file": ("elmo.xml", text)})
    assert r.status_code == 201, r.text
    body = r.json()
    assert body["fieldbus"] == "ethercat" and "device 3 of 4" in body["description"]
    assert any("mapped in a TxPdo; taken as T" in w for w in body["warnings"]), body["warnings"]
    r = await client.post(
        url.replace("elmo-gold-drive", "elmo-x") + "&device=9", files={"file": ("elmo.xml", text)}
    )
    assert r.status_code == 400 and "no device 9: the file describes 4" in r.text, r.text


async def test_servo_on_never_starts_motion_from_a_leftover_target(
    client: httpx.AsyncClient,
) -> None:
    # Profile velocity with a target left from an earlier jog, then a stop.
    await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "disable"})
    await client.put(f"/api/v1/sessions/{SID}/objects/0x6060", json={"value": 3})
    await client.put(f"/api/v1/sessions/{SID}/objects/0x60FF", json={"value": 200000})
    r = await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "enable"})
    assert r.json()["state"] == "Operation enabled"
    target = await client.get(f"/api/v1/sessions/{SID}/objects/0x60FF")
    assert target.json()["value"] == 0
    await asyncio.sleep(0.3)
    r = await client.get(f"/api/v1/sessions/{SID}/state")
    assert r.json()["velocity"] == 0
    await client.post(f"/api/v1/sessions/{SID}/state", json={"command": "disable"})
