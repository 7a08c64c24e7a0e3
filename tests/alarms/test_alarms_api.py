"""Alarms and homing routes against a simulated generic drive (real CANopen, virtual bus)."""

from __future__ import annotations

import asyncio
import itertools
import os
from collections.abc import AsyncIterator

import httpx
import pytest
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.control_helpers import take_control

_n = itertools.count()
pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def api(tmp_path_factory) -> AsyncIterator[tuple[httpx.AsyncClient, str, object]]:  # type: ignore[no-untyped-def]
    settings = Settings(
        sim=True,
        sim_channel=f"alarms-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic",
        data_dir=tmp_path_factory.mktemp("data"),
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as c:
            sid = (await c.get("/api/v1/sessions")).json()[0]["id"]
            # Resetting alarms and clearing the history change the drive: the client holds
            # its control, the token on every request.
            await take_control(c, sid, "alarms-test")
            yield c, sid, app.state.servodesk.sim


async def test_homing_methods_lists_the_family_methods(api) -> None:  # type: ignore[no-untyped-def]
    c, sid, _sim = api
    r = await c.get(f"/api/v1/sessions/{sid}/homing/methods")
    assert r.status_code == 200
    methods = {m["method"]: m for m in r.json()}
    assert set(methods) == {35, 37}
    assert methods[37]["uses"] == [] and methods[37]["direction"] is None
    assert methods[37]["section"].startswith("CiA 402-2")
    r = await c.get(f"/api/v1/sessions/{sid}/homing")
    assert r.json()["state"] in ("idle", "attained")


async def test_fault_shows_with_text_and_clears_with_bit_7(api) -> None:  # type: ignore[no-untyped-def]
    c, sid, sim = api
    sim.drives[0].raise_fault(0x8611)
    await asyncio.sleep(0.2)  # The EMCY reaches the session.
    r = await c.get(f"/api/v1/sessions/{sid}/alarms")
    body = r.json()
    assert body["state"] == "Fault"
    assert body["current"]["code"] == 0x8611
    assert body["current"]["name"] == "Following error"
    assert body["current"]["remedy"]
    assert any(e["code"] == 0x8611 for e in body["emcy_log"])
    assert body["history"][0]["source"] == "1003h"
    assert body["history"][0]["code"] == 0x8611
    assert "bit 7" in body["reset_procedure"]
    assert body["can_clear_history"]
    r = await c.post(f"/api/v1/sessions/{sid}/alarms/reset", json={})
    assert r.status_code == 200, r.text
    assert r.json()["current"] is None
    assert r.json()["state"] == "Switch on disabled"
    r = await c.post(f"/api/v1/sessions/{sid}/alarms/clear-history", json={})
    assert r.status_code == 422 and r.json()["field"] == "confirm"
    r = await c.post(f"/api/v1/sessions/{sid}/alarms/clear-history", json={"confirm": True})
    assert r.status_code == 200
    assert r.json()["history"] == []
