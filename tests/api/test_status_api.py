"""GET /status: the status bar's numbers per bus (issue 48, docs/api.md "Status"), against
the simulated drives: a CANopen twin on the virtual bus and the CTMM04x answering SLMP."""

from __future__ import annotations

import asyncio
import itertools
import os
from collections.abc import AsyncIterator
from typing import Any

import httpx
import pytest
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.control_helpers import bind_in_process, take_control

pytestmark = pytest.mark.asyncio(loop_scope="module")

_n = itertools.count()
SID = "cia402-generic-1"


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def client(tmp_path_factory) -> AsyncIterator[httpx.AsyncClient]:  # type: ignore[no-untyped-def]
    settings = Settings(
        sim=True,
        sim_channel=f"status-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic,ctmm04x",
        data_dir=tmp_path_factory.mktemp("data"),
        viewer_port=0,
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(
            transport=transport,
            base_url="http://test",
            headers={"X-Servodesk-Client": "status-test"},
            timeout=30,
        ) as c:
            token = await take_control(c, SID, "status-test")
            bind_in_process(app, SID, token, "status-test")
            yield c


async def _buses(client: httpx.AsyncClient) -> dict[str, Any]:
    r = await client.get("/api/v1/status")
    assert r.status_code == 200, r.text
    return {b["interface"]: b for b in r.json()["buses"]}


async def test_each_twin_bus_is_up_and_says_what_it_cannot_count(
    client: httpx.AsyncClient,
) -> None:
    # A second or two of the session's polls: the drive's answers are traffic.
    await asyncio.sleep(2.2)
    buses = await _buses(client)
    can_bus, slmp = buses["virtual"], buses["slmp"]
    assert can_bus["interface"] == "virtual" and can_bus["state"] == "up"
    assert [s["id"] for s in can_bus["sessions"]] == [SID]
    traffic = can_bus["traffic"]
    assert traffic["frames_per_s"] > 0
    # The virtual bus has no bitrate, no controller and no error frames: not reported, not 0.
    assert traffic["load_percent"] is None and "without a bitrate" in traffic["load_basis"]
    assert traffic["error_frames"] is None and traffic["bus_state"] is None
    assert can_bus["cycle"] is None and can_bus["ethercat"] is None
    assert can_bus["requests"] > 0
    # SLMP counts requests, not frames on a wire it shares with nobody servodesk can hear.
    assert slmp["link"] == "cclink-ie-tsn" and slmp["state"] == "up"
    assert slmp["traffic"] is None and slmp["requests"] > 0


async def test_a_running_cyclic_exchange_shows_its_configured_and_measured_cycle(
    client: httpx.AsyncClient,
) -> None:
    r = await client.post(f"/api/v1/sessions/{SID}/pdo/cyclic", json={"sync_period_ms": 5})
    assert r.status_code == 200, r.text
    try:
        await asyncio.sleep(1.0)
        cycle = (await _buses(client))["virtual"]["cycle"]
        assert cycle["session"] == SID and cycle["configured_ms"] == 5.0
        assert cycle["cycles"] > 0
        # A SYNC producer on a shared 2-core machine: the average is near the period.
        assert 4.0 <= cycle["measured_ms"] <= 10.0, cycle
    finally:
        r = await client.delete(f"/api/v1/sessions/{SID}/pdo/cyclic")
        assert r.status_code == 200, r.text
    assert (await _buses(client))["virtual"]["cycle"] is None
