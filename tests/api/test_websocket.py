"""The WebSocket pushes sessions, state changes and refuses other protocol versions."""

from __future__ import annotations

import os

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.control_helpers import take_control_sync
from tests.operation.support import bind, headers, take


@pytest.fixture
def app_client(tmp_path):  # type: ignore[no-untyped-def]
    s = Settings(
        sim=True, sim_channel=f"ws-{os.getpid()}", sim_profiles="cia402-generic", data_dir=tmp_path
    )
    with TestClient(create_app(s)) as c:
        yield c


def test_hello_sessions_then_live_state_after_a_command(app_client: TestClient) -> None:
    with app_client.websocket_connect("/api/v1/ws", subprotocols=["servodesk.v1"]) as ws:
        hello = ws.receive_json()
        assert hello["type"] == "hello" and hello["protocol"] == 1
        sessions = ws.receive_json()
        assert sessions["type"] == "sessions"
        assert [s["id"] for s in sessions["sessions"]] == ["cia402-generic-1"]
        ws.send_json({"type": "subscribe", "session": "cia402-generic-1"})
        # Servo on needs control and this socket bound as its dead-man.
        take(app_client, "cia402-generic-1", "ws-test")
        bind(ws, "cia402-generic-1", "ws-test")
        r = app_client.post(
            "/api/v1/sessions/cia402-generic-1/state",
            json={"command": "enable"},
            headers=headers("ws-test"),
        )
        assert r.status_code == 200, r.text
        seen = []
        for _ in range(50):
            msg = ws.receive_json()
            if msg["type"] == "state":
                seen.append(msg["state"])
                if msg["state"] == "Operation enabled":
                    break
        assert "Operation enabled" in seen
        assert isinstance(msg["position"], int) and msg["statusword_hex"].startswith("0x")


def test_other_protocol_versions_are_refused_with_a_reason(app_client: TestClient) -> None:
    with app_client.websocket_connect("/api/v1/ws", subprotocols=["servodesk.v0"]) as ws:
        with pytest.raises(WebSocketDisconnect) as info:
            ws.receive_json()
        assert info.value.code == 4000


def test_heartbeat_loss_is_reported(app_client: TestClient) -> None:
    with app_client.websocket_connect("/api/v1/ws", subprotocols=["servodesk.v1"]) as ws:
        ws.receive_json()
        ws.receive_json()
        ws.send_json({"type": "subscribe", "session": "cia402-generic-1"})
        take_control_sync(app_client, "cia402-generic-1", "ws-test")
        r = app_client.put("/api/v1/sessions/cia402-generic-1/objects/0x1017", json={"value": 20})
        assert r.status_code == 200
        # The drive's heartbeat falls silent behind the session's back (as a hung drive's would).
        sim = app_client.app.state.servodesk.sim  # type: ignore[attr-defined]
        sim.drives[0].write(0x1017, 0, 0)
        sim.devices[0].nmt.stop_heartbeat()
        events = []
        for _ in range(100):
            msg = ws.receive_json()
            if msg["type"] == "link":
                events.append(msg["event"])
                if "heartbeat_lost" in events:
                    break
        assert "heartbeat_lost" in events
