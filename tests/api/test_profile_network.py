"""GET /profiles/{id} and GET /sessions/{sid}/profile carry the profile's ``network:`` section
(the Network configuration page): its objects named as ``object_list`` names them."""

from __future__ import annotations

import httpx
import pytest

pytestmark = pytest.mark.asyncio(loop_scope="module")


async def test_the_lecsn_network_section_has_the_telegram_p922_and_the_leds(
    client: httpx.AsyncClient,
) -> None:
    r = await client.get("/api/v1/profiles/lecsn-t")
    assert r.status_code == 200
    body = r.json()
    net = body["network"]
    assert net is not None and "004 §20.1" in net["section"]
    objects = {o["address"]: o for o in body["object_list"]}
    # P922 Telegram selection is CoE index 039Ah (004 §20.1.5.1: PNU = index), the profile's
    # telegram object; the network section names it as object_list does.
    p922 = [o for o in net["objects"] if objects[o["address"]]["pnu"] == 922]
    assert [o["address"] for o in p922] == ["0x039A:00"]
    assert objects["0x039A:00"]["name"] == "Telegram selection"
    assert all(o["address"] in objects and o["section"].startswith("004") for o in net["objects"])
    leds = {(led["led"], led["state"]): led for led in net["leds"]}
    assert leds[("Network Status", "red double flash")]["meaning"] == "IP address not set"
    assert leds[("Card Status", "green on")]["section"] == "004 §20.2.3.2"
    assert any("SW2/SW3 = 01h to FEh" in rule["text"] for rule in net["addressing"])


@pytest.mark.parametrize(
    ("profile_id", "address", "led"),
    [
        ("ctmm04x", "0x603F:00", "DLINK (green)"),
        ("smartris", "0x2000:00", "Status 1 (green) / 2 (yellow)"),
    ],
)
async def test_ctmm04x_and_smartris_have_their_network_sections(
    client: httpx.AsyncClient, profile_id: str, address: str, led: str
) -> None:
    net = (await client.get(f"/api/v1/profiles/{profile_id}")).json()["network"]
    assert net is not None
    assert address in [o["address"] for o in net["objects"]]
    assert led in {x["led"] for x in net["leds"]}
    assert net["addressing"] and all(r["section"] for r in net["addressing"])


async def test_a_session_profile_carries_its_network_section(client: httpx.AsyncClient) -> None:
    r = await client.get("/api/v1/sessions/cia402-generic-1/profile")
    assert r.status_code == 200
    net = r.json()["network"]
    assert net is not None and net["leds"] == []
    assert "0x1017:00" in [o["address"] for o in net["objects"]]
