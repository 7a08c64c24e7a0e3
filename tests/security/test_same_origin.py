"""Defect 2: cross-site requests and DNS rebinding. The server answers only requests for its
own host names, takes state-changing requests and WebSockets only from its own origin (or
from no browser at all), and only JSON bodies (multipart where a file is uploaded)."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.security.conftest import backup_bytes
from tests.security.server import LiveServer

BASE = "http://127.0.0.1:8000"
WS = "ws://127.0.0.1:8000"  # TestClient.websocket_connect ignores base_url.
JSON = {"Content-Type": "application/json"}
EVIL = "http://evil.example"


def _upload(c: TestClient, headers: dict[str, str], data: bytes | None = None) -> httpx.Response:
    return c.post(
        "/api/v1/backups/upload",
        params={"filename": "drive.json"},
        content=backup_bytes() if data is None else data,
        headers=headers,
    )


def _refused(r: httpx.Response, status: int, error: str) -> None:
    assert r.status_code == status, r.text
    body = r.json()
    assert body["error"] == error and body["message"] and body["hint"], body


def test_a_cross_site_upload_is_refused(loopback_app: FastAPI) -> None:
    with TestClient(loopback_app, base_url=BASE) as c:
        _refused(_upload(c, {**JSON, "Origin": EVIL}), 403, "OriginNotAllowed")
        # The same with the attacker's host name (DNS rebinding) and a form's content type.
        r = _upload(c, {"Origin": EVIL, "Host": "evil.example:8000", "Content-Type": "text/plain"})
        assert r.status_code in (400, 403, 415)
        assert c.get("/api/v1/backups").json() == []


def test_requests_for_another_host_name_are_refused(loopback_app: FastAPI) -> None:
    with TestClient(loopback_app, base_url=BASE) as c:
        # DNS rebinding: evil.example now resolves to 127.0.0.1; the browser sends its name.
        _refused(
            c.get("/api/v1/backups", headers={"Host": "evil.example:8000"}), 400, "HostNotAllowed"
        )
        _refused(_upload(c, {**JSON, "Host": "evil.example:8000"}), 400, "HostNotAllowed")
        _refused(
            c.get("/api/v1/health", headers={"Host": "127.attacker.example"}), 400, "HostNotAllowed"
        )
        for host in ("127.0.0.1:8000", "localhost:8000", "[::1]:8000", "LOCALHOST", "127.0.0.1"):
            assert c.get("/api/v1/health", headers={"Host": host}).status_code == 200, host


def test_state_changing_requests_take_json_only(loopback_app: FastAPI) -> None:
    with TestClient(loopback_app, base_url=BASE) as c:
        for ct in ("text/plain", "application/x-www-form-urlencoded", "text/plain; charset=utf-8"):
            _refused(_upload(c, {"Content-Type": ct}), 415, "UnsupportedMediaType")
        # A body with no content type at all (fetch() with a Blob) is refused as well.
        _refused(_upload(c, {}), 415, "UnsupportedMediaType")
        # Routes that take no body: the alarm reset a cross-site form could post.
        r = c.post(
            "/api/v1/sessions/x-1/alarms/reset",
            content=b"{}",
            headers={"Content-Type": "text/plain"},
        )
        _refused(r, 415, "UnsupportedMediaType")
        # multipart/form-data only where a file is uploaded.
        r = c.post("/api/v1/compare", files={"file": ("a.json", b"{}", "application/json")})
        _refused(r, 415, "UnsupportedMediaType")
        assert c.get("/api/v1/backups").json() == []


def test_own_origin_scripts_and_uploads_pass(loopback_app: FastAPI) -> None:
    with TestClient(loopback_app, base_url=BASE) as c:
        assert _upload(c, {**JSON, "Origin": BASE}).status_code == 201
        assert _upload(c, {**JSON, "Origin": "http://localhost:8000"}).status_code == 201
        assert _upload(c, JSON).status_code == 201  # No Origin: a script or the CLI.
        # The UI uploads a file as multipart/form-data (a DCF as well as JSON).
        r = c.post(
            "/api/v1/backups/upload",
            params={"filename": "drive.json"},
            files={"file": ("drive.json", backup_bytes(), "application/json")},
            headers={"Origin": BASE},
        )
        assert r.status_code == 201, r.text
        # A bodiless state change with no content type (DELETE) passes the content check.
        assert c.delete("/api/v1/sessions/nope-1", headers={"Origin": BASE}).status_code == 404


@pytest.mark.parametrize(
    "origin",
    [
        EVIL,
        "http://127.0.0.1:9999",
        "http://127.0.0.1",
        "null",
        "http://127.0.0.1:8000.evil.example",
    ],
)
def test_other_origins_are_refused(loopback_app: FastAPI, origin: str) -> None:
    with TestClient(loopback_app, base_url=BASE) as c:
        _refused(_upload(c, {**JSON, "Origin": origin}), 403, "OriginNotAllowed")


def test_configured_host_names_are_allowed(tmp_path: Path) -> None:
    app = create_app(Settings(data_dir=tmp_path, allowed_hosts="servodesk.lan, bench-pc:9000"))
    with TestClient(app, base_url=BASE) as c:
        h = {**JSON, "Host": "servodesk.lan:8000", "Origin": "http://servodesk.lan:8000"}
        assert _upload(c, h).status_code == 201
        # A name with a port allows that origin port (a proxy or a mapped container port).
        h = {**JSON, "Host": "bench-pc:9000", "Origin": "http://bench-pc:9000"}
        assert _upload(c, h).status_code == 201
        _refused(_upload(c, {**JSON, "Origin": "http://bench-pc:8001"}), 403, "OriginNotAllowed")


def test_a_cross_site_websocket_is_closed_before_anything_is_sent(loopback_app: FastAPI) -> None:
    with TestClient(loopback_app, base_url=BASE) as c:
        for headers, code in (({"Origin": EVIL}, 4403), ({"Host": "evil.example:8000"}, 4400)):
            with c.websocket_connect(WS + "/api/v1/ws", headers=headers) as ws:
                with pytest.raises(WebSocketDisconnect) as info:
                    ws.receive_json()
                assert info.value.code == code
                assert info.value.reason
        # The scope's binary socket as well.
        with c.websocket_connect(WS + "/api/v1/scope/ws", headers={"Origin": EVIL}) as ws:
            with pytest.raises(WebSocketDisconnect) as info:
                ws.receive_bytes()
            assert info.value.code == 4403
        # The page's own origin, and no origin (a script): the hello comes.
        for headers in ({"Origin": BASE}, {}):
            with c.websocket_connect(WS + "/api/v1/ws", headers=headers) as ws:
                assert ws.receive_json()["type"] == "hello"


def test_a_real_server_on_loopback_checks_host_and_origin(token_server: LiveServer) -> None:
    auth = {"Authorization": f"Bearer {token_server.token}"}
    own = token_server.base
    url = f"{own}/api/v1/backups/upload?filename=drive.json"
    data = backup_bytes()
    r = httpx.post(url, content=data, headers={**auth, **JSON, "Origin": EVIL})
    assert r.status_code == 403
    r = httpx.post(url, content=data, headers={**auth, **JSON, "Host": "evil.example"})
    assert r.status_code == 400
    r = httpx.post(url, content=data, headers={**auth, **JSON, "Origin": own})
    assert r.status_code == 201, r.text
