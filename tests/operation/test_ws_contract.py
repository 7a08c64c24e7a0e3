"""The WebSocket sends only the messages of its contract (api/ws_messages.py, issue 51 item 1).

The UI's types of these messages are generated from ``ServerMessage`` (frontend/src/api/
schema.ts), so a message outside it would reach a UI that is typed as if it could not exist.
A real session (a simulated HIWIN E behind the real socket: control, the dead-man's bind, a
backup and a restore, servo on, storing the parameters, homing, releasing control) must send
nothing the union does not describe, and a message that is not in it is not sent at all.
"""

from __future__ import annotations

import json
import logging
import threading
from typing import Any

import pytest
from pydantic import TypeAdapter
from starlette.testclient import WebSocketTestSession

from servodesk.api.ws_messages import RefusedMessage, ServerMessage, encode
from tests.operation.support import (
    TOKENS,
    Heartbeats,
    headers,
    operation_app,
    take,
    wait_motion,
    wait_until,
)

SID = "hiwin-e-1"
REV = 8_388_608  # hiwin-e simulation: 23-bit encoder, electronic gear 1:1.
A = headers("A")
SERVER: TypeAdapter[ServerMessage] = TypeAdapter(ServerMessage)


class Reader:
    """Every text frame the socket receives, read on a thread until the socket closes."""

    def __init__(self, ws: WebSocketTestSession) -> None:
        self.ws = ws
        self.frames: list[str] = []
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            try:
                self.frames.append(self.ws.receive_text())
            except Exception:  # The socket closed: the test reads what came.
                return

    def seen(self, kind: str, **fields: Any) -> bool:
        for text in list(self.frames):
            msg = json.loads(text)
            if msg["type"] == kind and all(msg.get(k) == v for k, v in fields.items()):
                return True
        return False

    def join(self) -> None:
        self._thread.join(5.0)


def _refusals(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "not sent" in r.getMessage()]


def test_a_real_session_sends_only_server_messages(
    channel: str, tmp_path: Any, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.ERROR, logger="servodesk.api.ws")
    with operation_app(channel, tmp_path, "hiwin-e") as (client, _sim):
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            reader = Reader(ws)
            ws.send_json({"type": "subscribe", "session": SID})
            ws.send_json({"type": "ping", "time": 12.5})
            ws.send_text("not json")
            ws.send_json({"type": "subscribe"})  # No session: an error, the socket stays.
            take(client, SID, "A")
            ws.send_json({"type": "bind", "session": SID, "token": TOKENS["A"]})
            assert wait_until(lambda: reader.seen("bind", session=SID, ok=True), 5.0, 0.01)
            # A backup and a restore of one changed parameter: progress, with the restore's item.
            backup = client.post(f"/api/v1/sessions/{SID}/backups", json={}, headers=A).json()
            r = client.put(
                f"/api/v1/sessions/{SID}/objects/0x6081", json={"value": 4321}, headers=A
            )
            assert r.status_code == 200, r.text
            r = client.post(
                f"/api/v1/sessions/{SID}/restore", json={"backup": backup["id"]}, headers=A
            )
            assert r.status_code == 200, r.text
            beats = Heartbeats(ws, SID)
            r = client.post(f"/api/v1/sessions/{SID}/state", json={"command": "enable"}, headers=A)
            assert r.status_code == 200, r.text
            r = client.post(f"/api/v1/sessions/{SID}/store", headers=A)
            assert r.status_code == 200, r.text
            r = client.post(
                f"/api/v1/sessions/{SID}/homing",
                json={"method": 17, "speed_switch": 3 * REV, "speed_zero": REV // 2},
                headers=A,
            )
            assert r.status_code == 200, r.text
            assert wait_motion(client, SID, 10.0)["state"] == "done"
            beats.stop()
            r = client.post(
                f"/api/v1/sessions/{SID}/control", json={"action": "release"}, headers=A
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: reader.seen("control", session=SID, owner=None), 5.0, 0.01)
        reader.join()

    kinds = []
    for text in reader.frames:
        SERVER.validate_json(text)  # What the UI's generated types describe.
        kinds.append(json.loads(text)["type"])
    assert not _refusals(caplog)  # (and tests/conftest.py fails any test that has one)
    expected = {"hello", "sessions", "state", "pong", "error", "control", "bind", "progress"}
    assert expected | {"motion", "homing"} <= set(kinds), kinds
    messages = [json.loads(t) for t in reader.frames]
    assert any(m["type"] == "progress" and m.get("item") for m in messages), "no restore item"
    errors = [m["message"] for m in messages if m["type"] == "error"]
    assert "not a JSON object" in errors
    assert any("session" in e for e in errors if e.startswith("'subscribe'")), errors


@pytest.mark.refuses_ws_messages
def test_a_message_outside_the_union_is_not_sent(
    channel: str, tmp_path: Any, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.ERROR, logger="servodesk.api.ws")
    with operation_app(channel, tmp_path, "hiwin-e") as (client, _sim):
        hub = client.app.state.servodesk.hub  # type: ignore[attr-defined]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            assert ws.receive_json()["type"] == "hello"
            assert ws.receive_json()["type"] == "sessions"
            for msg in (
                {"type": "surprise", "session": SID},  # A type the union does not have.
                {"type": "link", "session": SID, "event": "lost"},  # "message" missing.
                {"type": "nmt", "session": SID, "state": "x", "time": 1.0, "extra": 1},
                {"type": "pong", "time": 1.0},
            ):
                client.portal.call(hub.publish, msg)  # type: ignore[union-attr]
            # The next message on the socket is the valid one: the others were not sent.
            assert ws.receive_json() == {"type": "pong", "time": 1.0}
    refused = _refusals(caplog)
    assert len(refused) == 3, refused
    assert "'surprise'" in refused[0] and "'link'" in refused[1] and "extra" in refused[2]


def test_encode_refuses_and_keeps_what_the_publisher_gave() -> None:
    with pytest.raises(RefusedMessage, match="'state'"):
        encode({"type": "state", "session": SID})
    # Optional fields the publisher left out stay out (the schema: required = always sent).
    frame = encode({"type": "bind", "session": SID, "ok": True})
    assert json.loads(frame) == {"type": "bind", "session": SID, "ok": True}
    # The Python-side name of a JSON key that is a keyword goes out as the key.
    deadman = {"type": "deadman", "session": SID, "reason": "r", "latency_ms": 1.0}
    assert json.loads(encode({**deadman, "from": "event loop"}))["from"] == "event loop"
