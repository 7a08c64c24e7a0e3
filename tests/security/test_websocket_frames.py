"""Defect 6: a binary frame on /api/v1/ws is answered with an error message and the socket
stays open (the protocol is JSON text frames, docs/api.md)."""

from __future__ import annotations

from fastapi import FastAPI
from fastapi.testclient import TestClient

WS = "ws://127.0.0.1:8000"  # TestClient.websocket_connect ignores base_url.


def test_a_binary_frame_gets_an_error_and_the_socket_stays(loopback_app: FastAPI) -> None:
    with (
        TestClient(loopback_app, base_url="http://127.0.0.1:8000") as c,
        c.websocket_connect(WS + "/api/v1/ws", subprotocols=["servodesk.v1"]) as ws,
    ):
        assert ws.receive_json()["type"] == "hello"
        assert ws.receive_json()["type"] == "sessions"
        ws.send_bytes(b'{"type":"ping"}')
        err = ws.receive_json()
        assert err["type"] == "error" and "text" in err["message"]
        ws.send_json({"type": "ping", "time": 1})
        assert ws.receive_json() == {"type": "pong", "time": 1}
