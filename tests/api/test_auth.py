"""Which mode a server is in (docs/security.md, Users): single-user on loopback without
accounts, a login everywhere else."""

from __future__ import annotations

from pathlib import Path

from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.security.server import PASSWORD, make_accounts


def _settings(tmp_path: Path, **kw: object) -> Settings:
    return Settings(data_dir=tmp_path, allowed_hosts="testserver", viewer_port=0, **kw)  # type: ignore[arg-type]


def test_beyond_loopback_everything_needs_a_login_even_without_accounts(tmp_path: Path) -> None:
    # No account: nobody can log in (serve refuses to start this way; the app fails closed).
    with TestClient(create_app(_settings(tmp_path, host="0.0.0.0"))) as c:
        r = c.get("/api/v1/health")
        assert r.status_code == 401 and "log in" in r.json()["message"]
        assert r.headers["www-authenticate"] == "Bearer"
        assert c.get("/api/v1/auth/me").status_code == 401


def test_beyond_loopback_a_login_or_an_api_token_passes(tmp_path: Path) -> None:
    token = make_accounts(tmp_path, {"ada": "engineer"})["ada"]
    with TestClient(create_app(_settings(tmp_path, host="0.0.0.0"))) as c:
        assert c.get("/api/v1/health").status_code == 401
        bearer = {"Authorization": f"Bearer {token}"}
        assert c.get("/api/v1/health", headers=bearer).status_code == 200
        wrong = {"Authorization": f"Bearer {token[:-1]}x"}
        assert c.get("/api/v1/health", headers=wrong).status_code == 401
        r = c.post("/api/v1/auth/login", json={"user": "ada", "password": PASSWORD})
        assert r.status_code == 200, r.text
        cookie = r.headers["set-cookie"]
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and "Path=/" in cookie
        assert "Secure" not in cookie  # Plain HTTP here; under TLS it is Secure.
        me = c.get("/api/v1/auth/me").json()  # The client keeps the cookie.
        assert me["user"] == "ada" and me["role"] == "engineer" and me["mode"] == "login"
        assert "write_parameters" in me["rights"] and "manage_users" not in me["rights"]


def test_the_cookie_is_secure_when_the_request_came_over_tls(tmp_path: Path) -> None:
    make_accounts(tmp_path, {"ada": "engineer"})
    app = create_app(_settings(tmp_path, host="0.0.0.0"))
    with TestClient(app, base_url="https://testserver") as c:
        r = c.post("/api/v1/auth/login", json={"user": "ada", "password": PASSWORD})
        assert r.status_code == 200 and "Secure" in r.headers["set-cookie"]


def test_loopback_without_accounts_is_the_single_user_mode(tmp_path: Path) -> None:
    with TestClient(create_app(_settings(tmp_path))) as c:
        assert c.get("/api/v1/health").status_code == 200
        me = c.get("/api/v1/auth/me").json()
        assert me == {
            **me,
            "user": "local",
            "role": "administrator",
            "mode": "single-user",
            "session": None,
        }
        assert "manage_users" in me["rights"]


def test_loopback_with_accounts_needs_a_login_unless_single_user(tmp_path: Path) -> None:
    make_accounts(tmp_path, {"ada": "engineer"})
    with TestClient(create_app(_settings(tmp_path))) as c:
        assert c.get("/api/v1/health").status_code == 401
    with TestClient(create_app(_settings(tmp_path, single_user=True))) as c:
        assert c.get("/api/v1/health").status_code == 200
        assert c.get("/api/v1/auth/me").json()["mode"] == "single-user"
    # --single-user does nothing beyond loopback.
    with TestClient(create_app(_settings(tmp_path, host="0.0.0.0", single_user=True))) as c:
        assert c.get("/api/v1/health").status_code == 401


def test_an_encoded_api_path_is_no_way_around_the_login(tmp_path: Path) -> None:
    make_accounts(tmp_path, {"ada": "engineer"})
    with TestClient(create_app(_settings(tmp_path, host="0.0.0.0"))) as c:
        for path in (
            "/%61pi/v1/sessions",
            "/api/v1/%73essions",
            "/api/v1/auth/login/../../sessions",
        ):
            assert c.get(path).status_code in (401, 404), path


def test_the_ui_files_and_the_login_load_without_a_login(tmp_path: Path) -> None:
    make_accounts(tmp_path, {"ada": "engineer"})
    with TestClient(create_app(_settings(tmp_path, host="0.0.0.0"))) as c:
        # The UI's files (here the API docs page: the built UI may be rebuilt meanwhile) and the
        # schema need no login; the UI shows its login form from them.
        assert c.get("/docs").status_code == 200
        assert c.get("/openapi.json").status_code == 200
        r = c.post("/api/v1/auth/login", json={"user": "ada", "password": "wrong password"})
        assert r.status_code == 401 and "wrong user name or password" in r.json()["message"]
