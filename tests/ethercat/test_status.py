"""GET /status on an EtherCAT line (issue 48, docs/api.md "Status"): the HIWIN twin behind a
veth pair; while cyclic data runs the bus shows its cycle and the line's counters, a pulled
cable makes it "down" with the missing frames counted, and it is "up" again once the line is
back (links/ethercat_health.py)."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.operation.support import headers, operation_app, take

pytestmark = pytest.mark.timeout(120)
A = headers("A")
SID = "hiwin-e-1"


@pytest.fixture
def app(channel: str, tmp_path: Path) -> Iterator[tuple[TestClient, Any]]:
    with operation_app(channel, tmp_path, "hiwin-e", sim_ethercat=True) as pair:
        yield pair


def _line(client: TestClient, ok: Any, timeout: float = 5.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    bus: dict[str, Any] = {}
    while time.monotonic() < deadline:
        (bus,) = client.get("/api/v1/status").json()["buses"]
        if ok(bus):
            return bus
        time.sleep(0.02)
    raise AssertionError(f"not within {timeout} s: {bus}")


def test_the_line_shows_its_cycle_and_a_pulled_cable_as_down(app: tuple[TestClient, Any]) -> None:
    client, sim = app
    (bus,) = client.get("/api/v1/status").json()["buses"]
    assert (bus["link"], bus["interface"], bus["state"]) == ("ethercat", "ethercat", "up")
    # No counts of frames on an EtherCAT link, and no cycle before cyclic data.
    assert bus["traffic"] is None and bus["cycle"] is None and bus["ethercat"] is None
    take(client, SID, "A")
    url = f"/api/v1/sessions/{SID}/pdo/cyclic"
    r = client.post(url, json={"sync_period_ms": 2, "outputs": False}, headers=A)
    assert r.status_code == 200, r.text
    try:
        bus = _line(client, lambda b: b["cycle"] is not None and b["cycle"]["cycles"] > 50)
        assert bus["cycle"]["configured_ms"] == 2.0 and bus["state"] == "up"
        assert 1.5 <= bus["cycle"]["measured_ms"] <= 4.0, bus["cycle"]
        assert bus["ethercat"]["missing_frames"] == 0
        subprocess.run(["ip", "link", "set", sim.veth.slave, "down"], check=True)
        try:
            bus = _line(client, lambda b: b["state"] == "down")
            assert bus["reason"] and bus["ethercat"]["missing_frames"] > 0
        finally:
            subprocess.run(["ip", "link", "set", sim.veth.slave, "up"], check=True)
        bus = _line(client, lambda b: b["state"] == "up", timeout=10.0)
        assert bus["ethercat"]["losses"] >= 1 and bus["reason"] is None
    finally:
        r = client.delete(url, headers=A)
        assert r.status_code == 200, r.text
