"""Login sessions on a real ``servodesk serve --sim`` that requires a login (IEC 62443-4-2
CR 1.11, 2.5, 2.6): login and logout, lock-out, idle time-out, API tokens, an administrator
ending a session (its WebSocket closes and the motion it was the dead-man of stops), and
control belonging to a user."""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from tests.security.server import PASSWORD, LiveServer, serve

SID = "cia402-generic-1"
S = f"/api/v1/sessions/{SID}"
IDLE_S = 3.0
LOCKOUT_S = 4.0


@pytest.fixture(scope="module")
def server() -> Iterator[LiveServer]:
    env = {
        "SERVODESK_SIM_PROFILES": "cia402-generic",
        "SERVODESK_SIM_CHANNEL": f"sessions-{os.getpid()}",
        "SERVODESK_SESSION_IDLE_S": str(IDLE_S),
        "SERVODESK_LOCKOUT_S": str(LOCKOUT_S),
    }
    accounts = {
        "admin": "administrator",
        "eve": "engineer",
        "sam": "service",
        "otto": "operator",
        "idler": "guest",
        "lock1": "guest",
        "lock2": "guest",
    }
    with serve("--sim", accounts=accounts, env=env) as srv:
        auth = {"Authorization": f"Bearer {srv.tokens['admin']}"}
        deadline = time.monotonic() + 30
        while not httpx.get(f"{srv.base}/api/v1/sessions", headers=auth).json():
            assert time.monotonic() < deadline, "the simulated drive did not come up"
            time.sleep(0.2)
        yield srv


def login(server: LiveServer, user: str, password: str = PASSWORD) -> httpx.Client:
    c = httpx.Client(base_url=server.base, timeout=30)
    r = c.post("/api/v1/auth/login", json={"user": user, "password": password})
    assert r.status_code == 200, r.text
    return c


def admin(server: LiveServer) -> httpx.Client:
    return httpx.Client(
        base_url=server.base,
        headers={"Authorization": f"Bearer {server.tokens['admin']}"},
        timeout=30,
    )


def test_login_me_and_logout(server: LiveServer) -> None:
    assert "logins required (7 accounts" in server.log()  # Said at start-up.
    c = login(server, "otto")
    me = c.get("/api/v1/auth/me").json()
    assert me["user"] == "otto" and me["role"] == "operator" and me["mode"] == "login"
    assert me["rights"] == ["acknowledge_alarms", "read", "take_control"]
    assert c.get("/api/v1/sessions").status_code == 200
    r = c.post("/api/v1/auth/logout", json={})
    assert r.status_code == 204 and "Max-Age=0" in r.headers["set-cookie"]
    # The session is gone on the server, not only the cookie in this client.
    assert c.get("/api/v1/sessions", cookies={"servodesk_session": "x"}).status_code == 401
    assert c.get("/api/v1/auth/me").status_code == 401


def test_an_old_cookie_after_logout_is_refused(server: LiveServer) -> None:
    c = login(server, "otto")
    secret = c.cookies["servodesk_session"]
    c.post("/api/v1/auth/logout", json={})
    r = httpx.get(f"{server.base}/api/v1/sessions", cookies={"servodesk_session": secret})
    assert r.status_code == 401


def test_five_failures_lock_the_account_until_a_time_even_for_the_right_password(
    server: LiveServer,
) -> None:
    url = f"{server.base}/api/v1/auth/login"
    for _ in range(5):
        r = httpx.post(url, json={"user": "lock1", "password": "wrong password"})
        assert r.status_code == 401
    r = httpx.post(url, json={"user": "lock1", "password": PASSWORD})
    assert r.status_code == 429, r.text
    body = r.json()
    assert "locked" in body["message"] and "until" in body["message"]
    assert time.time() < body["until"] <= time.time() + LOCKOUT_S + 1
    assert 1 <= int(r.headers["retry-after"]) <= LOCKOUT_S + 1
    # Another account is not locked by it (the address counter allows more).
    assert httpx.post(url, json={"user": "lock2", "password": PASSWORD}).status_code == 200
    time.sleep(body["until"] - time.time() + 0.2)
    assert httpx.post(url, json={"user": "lock1", "password": PASSWORD}).status_code == 200
    # The audit log has each step under the account's name (IEC 62443-4-2 CR 2.8), and never
    # the password.
    with admin(server) as a:
        rows = a.get("/api/v1/audit", params={"user": "lock1"}).json()
    events = [r["event"] for r in reversed(rows)]
    assert events.count("access.login_failed") == 5
    assert "access.locked_out" in events and "access.login_refused" in events
    assert events[-1] == "access.login"
    assert "wrong password" not in json.dumps([r["details"] for r in rows])


def test_an_idle_session_ends(server: LiveServer) -> None:
    c = login(server, "idler")
    for _ in range(3):  # Use keeps it alive past the idle time.
        time.sleep(IDLE_S / 2)
        assert c.get("/api/v1/auth/me").status_code == 200
    time.sleep(IDLE_S + 0.5)
    r = c.get("/api/v1/auth/me")
    assert r.status_code == 401
    with admin(server) as a:
        users = [s["user"] for s in a.get("/api/v1/auth/sessions").json()]
    assert "idler" not in users


def test_api_tokens_are_made_used_and_revoked(server: LiveServer) -> None:
    c = login(server, "sam")
    r = c.post("/api/v1/auth/tokens", json={"label": "nightly backup"})
    assert r.status_code == 201
    made = r.json()
    secret = made["secret"]
    listed = c.get("/api/v1/auth/tokens").json()
    mine = [t for t in listed if t["id"] == made["id"]]
    assert mine and mine[0]["label"] == "nightly backup" and "secret" not in mine[0]
    bearer = {"Authorization": f"Bearer {secret}"}
    me = httpx.get(f"{server.base}/api/v1/auth/me", headers=bearer).json()
    assert me["user"] == "sam" and me["session"] is None
    assert c.delete(f"/api/v1/auth/tokens/{made['id']}").status_code == 204
    assert httpx.get(f"{server.base}/api/v1/auth/me", headers=bearer).status_code == 401
    assert secret not in server.log()


def _ws(server: LiveServer, client: httpx.Client, tab: str) -> ClientConnection:
    cookie = f"servodesk_session={client.cookies['servodesk_session']}"
    ws = connect(
        f"ws://127.0.0.1:{server.port}/api/v1/ws?client={tab}",
        additional_headers={"Cookie": cookie},
    )
    assert json.loads(ws.recv(timeout=5))["type"] == "hello"
    return ws


def _wait_for(ws: ClientConnection, kind: str) -> dict[str, Any]:
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        msg: dict[str, Any] = json.loads(ws.recv(timeout=5))
        if msg.get("type") == kind:
            return msg
    raise AssertionError(f"no {kind} message")


def test_control_belongs_to_a_user_and_ending_the_session_stops_the_motion(
    server: LiveServer,
) -> None:
    eve = login(server, "eve")
    ws = _ws(server, eve, "eve-tab")
    h = {"X-Servodesk-Client": "eve-tab"}
    r = eve.post(f"{S}/control", json={"action": "take"}, headers=h)
    assert r.status_code == 200 and r.json()["user"] == "eve", r.text
    token = r.json()["token"]
    h["X-Servodesk-Control"] = token
    ws.send(json.dumps({"type": "bind", "session": SID, "token": token}))
    assert _wait_for(ws, "bind")["ok"] is True
    stop = threading.Event()

    def beat() -> None:  # The dead-man's heartbeats, as the UI sends them.
        while not stop.is_set():
            try:
                ws.send(json.dumps({"type": "heartbeat", "session": SID}))
            except ConnectionClosed:
                return
            time.sleep(0.05)

    beats = threading.Thread(target=beat, daemon=True)
    beats.start()
    try:
        r = eve.post(f"{S}/state", json={"command": "enable"}, headers=h)
        assert r.status_code == 200, r.text
        r = eve.post(
            f"{S}/motion/jog", json={"velocity": 100_000, "acceleration": 1_000_000}, headers=h
        )
        assert r.status_code == 200, r.text

        # Another user (service, who may take control) is refused while eve holds it: 409
        # naming eve; a service user may not force-take it from her either (403).
        sam = login(server, "sam")
        other = {"X-Servodesk-Client": "sam-tab"}
        r = sam.post(f"{S}/control", json={"action": "take"}, headers=other)
        assert r.status_code == 409 and "'eve'" in r.json()["message"], r.text
        r = sam.post(f"{S}/control", json={"action": "force_take", "confirm": True}, headers=other)
        assert r.status_code == 403 and r.json()["right"] == "force_control", r.text
        # eve's token is worth nothing in sam's hands.
        r = sam.post(
            f"{S}/motion/jog",
            json={"velocity": 1, "acceleration": 1000},
            headers={**other, "X-Servodesk-Control": token},
        )
        assert r.status_code == 409, r.text
        seen = sam.get(f"{S}/control").json()
        assert seen["user"] == "eve" and seen["token"] is None
        time.sleep(0.3)
        assert eve.get(f"{S}/motion").json()["state"] == "running"

        # The administrator ends eve's login session: her socket closes at once (4401), the
        # dead-man stops the jog and the drive is disabled.
        with admin(server) as a:
            sessions = [s for s in a.get("/api/v1/auth/sessions").json() if s["user"] == "eve"]
            assert len(sessions) == 1 and sessions[0]["websockets"] == 1
            t0 = time.monotonic()
            assert a.delete(f"/api/v1/auth/sessions/{sessions[0]['id']}").status_code == 204
        with pytest.raises(ConnectionClosed) as closed:
            while True:
                ws.recv(timeout=5)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 4401
        assert time.monotonic() - t0 < 1.0
        deadline = time.monotonic() + 3
        with admin(server) as a:
            while a.get(f"{S}/motion").json()["state"] == "running":
                assert time.monotonic() < deadline, "the motion did not stop"
                time.sleep(0.05)
            assert a.get(f"{S}/state").json()["state"] != "Operation enabled"
        assert eve.get("/api/v1/auth/me").status_code == 401
    finally:
        stop.set()
        ws.close()
        beats.join(2)


def test_an_administrator_may_force_take_from_another_user(server: LiveServer) -> None:
    sam = login(server, "sam")
    deadline = time.monotonic() + 10  # A holder whose socket closed lapses after its grace.
    while sam.get(f"{S}/control").json()["user"] is not None:
        assert time.monotonic() < deadline, "control did not lapse"
        time.sleep(0.2)
    r = sam.post(
        f"{S}/control",
        json={"action": "force_take", "confirm": True},
        headers={"X-Servodesk-Client": "sam-tab"},
    )
    assert r.status_code == 200 and r.json()["user"] == "sam", r.text
    with admin(server) as a:
        who = {"X-Servodesk-Client": "admin-tab"}
        r = a.post(f"{S}/control", json={"action": "take"}, headers=who)
        assert r.status_code == 409 and "'sam'" in r.json()["message"]
        r = a.post(f"{S}/control", json={"action": "force_take", "confirm": True}, headers=who)
        assert r.status_code == 200 and r.json()["user"] == "admin", r.text
        r = a.post(
            f"{S}/control",
            json={"action": "release"},
            headers={**who, "X-Servodesk-Control": r.json()["token"]},
        )
        assert r.status_code == 200


def test_disabling_an_account_ends_its_sessions(server: LiveServer) -> None:
    otto = login(server, "otto")
    ws = _ws(server, otto, "otto-tab")
    with admin(server) as a:
        r = a.patch("/api/v1/auth/users/otto", json={"disabled": True})
        assert r.status_code == 200 and r.json()["disabled"] is True
        with pytest.raises(ConnectionClosed):
            while True:
                ws.recv(timeout=5)
        assert otto.get("/api/v1/auth/me").status_code == 401
        r = httpx.post(
            f"{server.base}/api/v1/auth/login", json={"user": "otto", "password": PASSWORD}
        )
        assert r.status_code == 401
        assert a.patch("/api/v1/auth/users/otto", json={"disabled": False}).status_code == 200
    login(server, "otto")
