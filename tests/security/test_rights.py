"""The rights matrix (docs/security.md, Roles) on a real ``servodesk serve --sim`` bound
beyond loopback: each role against one representative route of each right. A role lacking
the right gets 403 naming it; a role that has it passes the check and meets the route (2xx,
or 409 because nobody holds control, or 422 for the body: never 401/403/5xx)."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from servodesk.domain.roles import RIGHTS, Right, Role
from tests.security.server import LiveServer, serve

SID = "cia402-generic-1"
S = f"/api/v1/sessions/{SID}"
CLIENT = {"X-Servodesk-Client": "rights-test"}

#: right -> (method, path, JSON body): a representative route needing that right.
ROUTES: dict[Right, tuple[str, str, Any]] = {
    Right.READ: ("GET", "/api/v1/sessions", None),
    Right.TAKE_CONTROL: ("POST", f"{S}/control", {"action": "release"}),
    Right.ACKNOWLEDGE_ALARMS: ("POST", f"{S}/alarms/reset", {}),
    Right.CLEAR_ALARMS: ("POST", f"{S}/alarms/clear-history", {"confirm": True}),
    Right.CONNECT: ("DELETE", "/api/v1/sessions/no-such-session", None),
    Right.JOG_HOME: ("POST", f"{S}/motion/jog", {"velocity": 1000, "acceleration": 10000}),
    Right.BACKUP: ("POST", f"{S}/backups", {"label": "rights"}),
    Right.RESTORE: ("POST", f"{S}/restore", {"backup": "none"}),
    Right.WRITE_PARAMETERS: ("PUT", f"{S}/objects/0x6060:00", {"value": 1}),
    Right.CONTROL_DRIVE: ("POST", f"{S}/motion/velocity", {"velocity": 1000}),
    Right.TUNE: ("POST", f"{S}/tuning/start", {}),
    Right.PDO: ("DELETE", f"{S}/pdo/cyclic", None),
    Right.SAVE_EEPROM: ("POST", f"{S}/store", {}),
    Right.MANAGE_USERS: ("GET", "/api/v1/auth/users", None),
    Right.READ_AUDIT: ("GET", "/api/v1/audit", None),
}


@pytest.fixture(scope="module")
def sim_server() -> Iterator[LiveServer]:
    env = {
        "SERVODESK_SIM_PROFILES": "cia402-generic",
        "SERVODESK_SIM_CHANNEL": f"rights-{os.getpid()}",
    }
    # Beyond loopback, as on a plant network (plain HTTP: the test talks to it on 127.0.0.1;
    # TLS is tests/security/test_tls.py's).
    beyond = ("--host", "0.0.0.0", "--insecure-http")
    accounts = {r.value: r.value for r in Role}
    with serve("--sim", *beyond, accounts=accounts, env=env) as server:
        auth = {"Authorization": f"Bearer {server.tokens['administrator']}"}
        deadline = time.monotonic() + 30
        while not httpx.get(f"{server.base}/api/v1/sessions", headers=auth).json():
            assert time.monotonic() < deadline, "the simulated drive did not come up"
            time.sleep(0.2)
        yield server


def test_every_right_has_a_representative_route() -> None:
    assert set(ROUTES) == set(Right) - {Right.FORCE_CONTROL}  # test_sessions.py: force-take


@pytest.mark.parametrize("role", list(Role), ids=lambda r: r.value)
def test_each_role_gets_403_exactly_where_it_lacks_the_right(
    sim_server: LiveServer, role: Role
) -> None:
    auth = {"Authorization": f"Bearer {sim_server.tokens[role.value]}", **CLIENT}
    wrong: list[str] = []
    with httpx.Client(base_url=sim_server.base, headers=auth, timeout=30) as c:
        for right, (method, path, body) in ROUTES.items():
            r = c.request(method, path, json=body)
            has = right in RIGHTS[role]
            if has:
                ok = r.status_code in (200, 201, 202, 204, 404, 409, 422)
            else:
                ok = (
                    r.status_code == 403
                    and r.json()["right"] == right.value
                    and r.json()["role"] == role.value
                    and right.value in r.json()["message"]
                )
            if not ok:
                wrong.append(f"{right.value}: {method} {path} -> {r.status_code} {r.text[:200]}")
    assert not wrong, "\n".join(wrong)
    assert "Traceback" not in sim_server.log()


def test_every_route_of_the_api_is_in_the_rights_table() -> None:
    """A route added without a line in api/rights.py would need manage_users (fail closed):
    this says which line is missing."""
    import tempfile
    from pathlib import Path

    from servodesk.api.app import create_app
    from servodesk.api.rights import PUBLIC, ROUTE_RIGHTS
    from servodesk.settings import Settings

    app = create_app(Settings(data_dir=Path(tempfile.mkdtemp()), viewer_port=0))
    ids = {op["operationId"] for ops in app.openapi()["paths"].values() for op in ops.values()}
    assert not ids - set(ROUTE_RIGHTS) - PUBLIC
    assert {"websocket", "scope_socket"} <= set(ROUTE_RIGHTS)
