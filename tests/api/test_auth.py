"""A server bound beyond loopback requires its token on every request."""

from __future__ import annotations

from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.settings import Settings


def test_requests_without_the_token_get_401_and_with_it_pass() -> None:
    app = create_app(Settings(host="0.0.0.0", token="s3cret"))
    with TestClient(app) as c:
        r = c.get("/api/v1/health")
        assert r.status_code == 401
        assert "token" in r.json()["message"]
        assert c.get("/api/v1/health", headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert (
            c.get("/api/v1/health", headers={"Authorization": "Bearer s3cret"}).status_code == 200
        )
        # The first page load carries ?token=; the cookie it sets lets the UI's assets load.
        r = c.get("/api/v1/health?token=s3cret")
        assert r.status_code == 200 and "servodesk_token" in r.headers["set-cookie"]
        assert c.get("/api/v1/profiles").status_code == 200  # Cookie kept by the client.


def test_loopback_needs_no_token() -> None:
    with TestClient(create_app(Settings())) as c:
        assert c.get("/api/v1/health").status_code == 200


def test_serve_generates_and_prints_a_token_when_binding_beyond_loopback() -> None:
    # The CLI makes a token when none is set; the settings object must then require it.
    s = Settings(host="0.0.0.0")
    assert not s.is_loopback and s.token is None
    assert Settings(host="127.0.0.2").is_loopback
