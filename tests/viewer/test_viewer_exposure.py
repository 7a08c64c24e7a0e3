"""The viewer's port has no token check: beyond loopback it starts only when the user opts in.

A backend bound beyond loopback requires its token on every API request; viser's websocket
server cannot check it, so without SERVODESK_VIEWER_PUBLIC=1 the viewer stays off and the log,
GET /viewer and (through it) the 3D view page say why.
"""

from __future__ import annotations

import logging
from pathlib import Path

import httpx
import pytest

from servodesk.api.app import create_app
from servodesk.api.routes.viewer import viewer
from servodesk.settings import Settings
from tests.security.server import make_accounts

from .conftest import free_port, port_is_bound

AUTH: dict[str, str] = {}


def _app(tmp_path: Path, port: int, public: bool) -> object:
    # Beyond loopback every request needs a login: an account and its API token.
    token = make_accounts(tmp_path, {"admin": "administrator"})["admin"]
    AUTH["Authorization"] = f"Bearer {token}"
    return create_app(
        Settings(
            host="0.0.0.0",
            data_dir=tmp_path,
            viewer_port=port,
            viewer_public=public,
        )
    )


async def test_beyond_loopback_the_viewer_is_not_started_and_says_why(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    port = free_port()
    app = _app(tmp_path, port, public=False)
    with caplog.at_level(logging.WARNING, logger="servodesk.services.viewer"):
        async with app.router.lifespan_context(app):  # type: ignore[attr-defined]
            assert not port_is_bound(port)
            assert viewer(app).server is None
            transport = httpx.ASGITransport(app=app)  # type: ignore[arg-type]
            async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
                assert (await c.get("/api/v1/viewer")).status_code == 401  # The API's token.
                body = (await c.get("/api/v1/viewer", headers=AUTH)).json()
    assert body["enabled"] is True and body["running"] is False
    assert body["url"] is None and body["port"] is None
    reason = body["error"]
    assert "0.0.0.0" in reason and "no token check" in reason
    assert "SERVODESK_VIEWER_PUBLIC=1" in reason
    assert any("SERVODESK_VIEWER_PUBLIC=1" in r.getMessage() for r in caplog.records)


async def test_opting_in_serves_it_and_warns(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    port = free_port()
    app = _app(tmp_path, port, public=True)
    with caplog.at_level(logging.WARNING, logger="servodesk.services.viewer"):
        async with app.router.lifespan_context(app):  # type: ignore[attr-defined]
            assert port_is_bound(port)
            info = viewer(app).info()
            assert info["running"] is True and info["error"] is None
    assert not port_is_bound(port)
    assert any("without a token check" in r.getMessage() for r in caplog.records)


def test_the_setting_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    assert Settings().viewer_public is False
    monkeypatch.setenv("SERVODESK_VIEWER_PUBLIC", "1")
    assert Settings().viewer_public is True
