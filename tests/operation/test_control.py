"""Control ownership: one client holds control, others watch; stopping is never refused."""

from __future__ import annotations

import time
from typing import Any

from tests.operation.support import (
    Heartbeats,
    headers,
    operation_app,
    take_and_enable,
    wait_until,
)

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"


def test_motion_and_writes_of_a_second_client_get_409_naming_the_owner(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        # Nobody holds control: anyone may write, nobody may move.
        r = client.put(f"{BASE}/objects/0x6081", json={"value": 150000})
        assert r.status_code == 200, r.text
        r = client.post(
            f"{BASE}/motion/jog",
            json={"velocity": 1000, "acceleration": 10000},
            headers=headers("B"),
        )
        assert r.status_code == 409 and "take control" in r.json()["hint"]

        take_and_enable(client, SID, "A")
        seen = client.get(f"{BASE}/control", headers=headers("B")).json()
        assert seen["owner"] == "A" and seen["you"] is False
        with (
            client.websocket_connect("/api/v1/ws?client=A") as ws_a,
            client.websocket_connect("/api/v1/ws?client=B") as ws_b,
        ):
            beats = Heartbeats(ws_a, SID)
            r = client.post(
                f"{BASE}/motion/jog",
                json={"velocity": 50000, "acceleration": 10**6},
                headers=headers("A"),
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 45_000, 1.0)
            for path, body in (
                ("motion/jog", {"velocity": -50000, "acceleration": 10**6}),
                ("motion/move", {"mode": "relative", "target": 1000}),
                ("motion/velocity", {"velocity": 1000}),
                ("motion/torque", {"torque": 100}),
            ):
                r = client.post(f"{BASE}/{path}", json=body, headers=headers("B"))
                assert r.status_code == 409, (path, r.text)
                assert "'A'" in r.json()["message"], r.json()
            for method, path, body in (
                ("put", "objects/0x6081", {"value": 1000}),
                ("post", "state", {"command": "disable"}),
                ("post", "store", None),
                ("post", "restore-defaults", {"confirm": True}),
            ):
                r = client.request(method, f"{BASE}/{path}", json=body, headers=headers("B"))
                assert r.status_code == 409, (path, r.text)
                assert "'A'" in r.json()["message"]
            # A write without any client id is another client too.
            assert client.put(f"{BASE}/objects/0x6081", json={"value": 1000}).status_code == 409
            # The jog still runs: nothing of B reached the drive.
            assert drive.read(0x60FF) == 50000 and drive.read(0x6081) == 150000
            assert drive.mode == 3 and drive.state.name == "OPERATION_ENABLED"
            # Halt is never refused, from anyone.
            r = client.post(f"{BASE}/motion/halt", json={}, headers=headers("B"))
            assert r.status_code == 200 and r.json()["state"] == "halted"
            assert wait_until(lambda: abs(drive.velocity) < 1000, 1.0)
            # Quick stop as a state command is never refused either.
            r = client.post(f"{BASE}/state", json={"command": "quick_stop"}, headers=headers("B"))
            assert r.status_code == 200, r.text
            beats.stop()
            del ws_b


def test_take_release_and_force_take_with_confirmation(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        assert client.post(f"{BASE}/control", json={"action": "take"}).status_code == 422
        take_and_enable(client, SID, "A")
        with client.websocket_connect("/api/v1/ws?client=A") as ws_a:
            ws_a.receive_json()  # hello
            beats = Heartbeats(ws_a, SID)
            r = client.post(
                f"{BASE}/motion/velocity", json={"velocity": 80000}, headers=headers("A")
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 70_000, 1.0)

            r = client.post(f"{BASE}/control", json={"action": "take"}, headers=headers("B"))
            assert r.status_code == 409 and "'A'" in r.json()["message"]
            r = client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("B"))
            assert r.status_code == 409
            r = client.post(f"{BASE}/control", json={"action": "force_take"}, headers=headers("B"))
            assert r.status_code == 409 and '"confirm": true' in r.json()["hint"]
            assert abs(drive.velocity) > 70_000
            r = client.post(
                f"{BASE}/control",
                json={"action": "force_take", "confirm": True},
                headers=headers("B"),
            )
            assert r.status_code == 200
            assert r.json()["owner"] == "B" and r.json()["you"] is True
            # A's motion stops when control is taken from it.
            assert wait_until(lambda: abs(drive.velocity) < 1000, 1.0)
            assert client.get(f"{BASE}/motion").json()["state"] == "halted"
            msg = _receive(ws_a, "control")
            assert msg["owner"] == "B"
            beats.stop()
        r = client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("B"))
        assert r.status_code == 200 and r.json()["owner"] is None


def test_motion_needs_the_clients_websocket(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, _sim):
        take_and_enable(client, SID, "A")
        r = client.post(
            f"{BASE}/motion/jog",
            json={"velocity": 1000, "acceleration": 10000},
            headers=headers("A"),
        )
        assert r.status_code == 409 and "WebSocket" in r.json()["message"]
        with client.websocket_connect("/api/v1/ws?client=A"):
            pass
        # The last socket closed: control is kept for a reload, then released.
        assert client.get(f"{BASE}/control").json()["owner"] == "A"


def _receive(ws: Any, kind: str, limit: int = 200) -> dict[str, Any]:
    end = time.monotonic() + 5
    for _ in range(limit):
        msg: dict[str, Any] = ws.receive_json()
        if msg.get("type") == kind or time.monotonic() > end:
            return msg
    raise AssertionError(f"no {kind} message")
