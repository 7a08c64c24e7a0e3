"""Control: one holder changes the drive, by a server-issued token; losing it makes the drive safe.

The rules are services/control.py's. Each test here failed on the code before 2026-12-07,
where a client id the client chose was the authority and nobody holding control let anyone
servo on (issue "Motion safety", items 1 and 2).
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from tests.operation.support import (
    TOKENS,
    Heartbeats,
    bind,
    headers,
    operation_app,
    take,
    take_and_enable,
    wait_until,
)

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"

#: Every route that can energise, move or change the drive, with a body the holder may send.
#: (method, path, body, what the holder gets when it holds control and its socket is bound)
CHANGING: list[tuple[str, str, Any]] = [
    ("put", "objects/0x6081", {"value": 120000}),
    ("put", "objects/0x6040", {"value": 0}),
    ("post", "state", {"command": "disable"}),
    ("post", "state", {"command": "enable"}),
    ("post", "state", {"command": "fault_reset"}),
    ("post", "store", None),
    ("post", "restore-defaults", {"confirm": True}),
    ("post", "alarms/reset", None),
    ("post", "alarms/clear-history", {"confirm": True}),
    ("post", "motion/jog", {"velocity": 1000, "acceleration": 100000}),
    ("post", "motion/move", {"mode": "relative", "target": 100}),
    ("post", "motion/velocity", {"velocity": 1000}),
    ("post", "motion/torque", {"torque": 10}),
    ("post", "motion/cyclic", {"mode": "csp", "amplitude": 10, "frequency": 1, "duration": 0.1}),
    ("post", "homing", {"method": 35}),
    ("post", "tuning/start", {"mode": "basic", "travel_window_rev": 0.5}),
    ("post", "tuning/undo", {"to": "before"}),
    ("post", "restore", {"backup": "nope"}),
    ("post", "pdo/apply", {"rpdos": [], "tpdos": [], "dry_run": True}),
    ("post", "pdo/cyclic", {"sync_period_ms": 10}),
    ("put", "pdo/cyclic/outputs", {"values": {}}),
    ("delete", "pdo/cyclic", None),
]
#: Never refused: anyone who sees the axis move may stop it.
STOPPING: list[tuple[str, str, Any]] = [
    ("post", "motion/halt", {}),
    ("post", "motion/stop", {}),
    ("post", "state", {"command": "quick_stop"}),
    ("post", "tuning/stop", None),
]


def _send(client: Any, method: str, path: str, body: Any, hdrs: Any) -> Any:
    return client.request(method, f"{BASE}/{path}", json=body, headers=hdrs)


def test_nobody_in_control_nothing_reaches_the_drive(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Item 1: with nobody holding control, servo on and every write are refused (409)."""
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        before = drive.read(0x6081)
        for method, path, body in CHANGING:
            r = _send(client, method, path, body, {"X-Servodesk-Client": "A"})
            assert r.status_code == 409, (path, body, r.status_code, r.text)
            assert "nobody holds control" in r.json()["message"], (path, r.json())
            assert "take control" in r.json()["hint"]
        assert drive.state.name == "SWITCH_ON_DISABLED"
        assert drive.read(0x6081) == before
        # Reads never need control.
        assert client.get(f"{BASE}/objects/0x6041").status_code == 200
        assert client.get(f"{BASE}/state").status_code == 200
        for method, path, body in STOPPING:
            r = _send(client, method, path, body, {"X-Servodesk-Client": "A"})
            assert r.status_code != 409, (path, r.text)
            assert r.status_code < 500


def test_control_matrix_holder_other_and_spoofed_id(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Every changing route x {someone else's control, the holder's id spoofed, the holder}."""
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            take(client, SID, "A")
            bind(ws, SID, "A")
            beats = Heartbeats(ws, SID)
            before = drive.read(0x6081)
            spoofed = {"X-Servodesk-Client": "A"}  # The label, without the token.
            wrong = {"X-Servodesk-Client": "A", "X-Servodesk-Control": "x" * 22}
            for who, hdrs in (("B", headers("B")), ("spoofed", spoofed), ("wrong", wrong)):
                for method, path, body in CHANGING:
                    r = _send(client, method, path, body, hdrs)
                    assert r.status_code == 409, (who, path, r.status_code, r.text)
                    assert "'A' holds control" in r.json()["message"], (who, path, r.json())
            assert drive.read(0x6081) == before
            assert drive.state.name == "SWITCH_ON_DISABLED"
            # The holder is never refused for control (other 4xx: its body or the drive).
            for method, path, body in CHANGING:
                if path.startswith(("motion/", "homing", "tuning/start")):
                    continue  # Run below, with the drive enabled.
                r = _send(client, method, path, body, headers("A"))
                assert r.status_code != 409 or "holds control" not in r.text, (path, r.text)
                assert r.status_code < 500, (path, r.text)
            r = _send(client, "post", "state", {"command": "enable"}, headers("A"))
            assert r.status_code == 200 and r.json()["state"] == "Operation enabled", r.text
            r = _send(client, "post", "motion/jog", CHANGING[9][2], headers("A"))
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 500, 2.0)
            r = _send(client, "post", "motion/halt", {}, headers("B"))
            assert r.status_code == 200, r.text
            beats.stop()


def test_a_socket_with_the_holders_id_is_no_dead_man(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Item 2: a second WebSocket opened with the holder's client id kept a jog running for
    over 9 s after the holder died. Its heartbeats do not count now: the jog stops."""
    with operation_app(channel, tmp_path, deadman_ms=250) as (client, sim):
        drive = sim.drives[0]
        with (
            client.websocket_connect("/api/v1/ws?client=A") as ws_a,
            client.websocket_connect("/api/v1/ws?client=A") as ws_spy,
        ):
            beats = take_and_enable(client, SID, "A", ws_a)
            spy_beats = Heartbeats(ws_spy, SID)
            # Binding without the token is refused.
            ws_spy.send_json({"type": "bind", "session": SID, "token": "guess"})
            r = client.post(
                f"{BASE}/motion/jog",
                json={"velocity": 50000, "acceleration": 10**6},
                headers=headers("A"),
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 45_000, 2.0)
            last = beats.stop()  # The holder dies; the spy keeps beating as "A".
            stopped = wait_until(lambda: abs(drive.velocity) < 1000, 3.0)
            assert stopped is not None, "the spoofing socket's heartbeats kept the jog running"
            assert stopped - last < 1.5
            spy_beats.stop()


def test_losing_the_holders_socket_disables_the_drive(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Item 1: when the controlling tab closed, the drive stayed enabled. Now it is brought to
    Switch on disabled; a reload within the grace time keeps control, not the servo."""
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            take_and_enable(client, SID, "A", ws).stop()
            assert drive.state.name == "OPERATION_ENABLED"
        assert wait_until(lambda: drive.state.name == "SWITCH_ON_DISABLED", 3.0), drive.state
        info = client.get(f"{BASE}/control", headers=headers("A")).json()
        assert info["owner"] == "A" and info["orphaned"] is True and info["you"] is True
        # The reloaded tab binds its new socket with the same token: control is kept.
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            bind(ws, SID, "A")
            info = client.get(f"{BASE}/control", headers=headers("A")).json()
            assert info["owner"] == "A" and info["orphaned"] is False and info["bound"] is True
            assert drive.state.name == "SWITCH_ON_DISABLED"
            events: list[dict[str, Any]] = []
        # Nobody comes back: control lapses after the grace time.
        assert wait_until(
            lambda: client.get(f"{BASE}/control").json()["owner"] is None, 8.0, step=0.1
        )
        del events


def test_force_take_stops_the_motion_and_disables_the_drive(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        assert client.post(f"{BASE}/control", json={"action": "take"}).status_code == 422
        with client.websocket_connect("/api/v1/ws?client=A") as ws_a:
            beats = take_and_enable(client, SID, "A", ws_a)
            r = client.post(
                f"{BASE}/motion/velocity", json={"velocity": 80000}, headers=headers("A")
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 70_000, 2.0)

            r = client.post(f"{BASE}/control", json={"action": "take"}, headers=headers("B"))
            assert r.status_code == 409 and "'A'" in r.json()["message"]
            assert r.json().get("token") is None
            r = client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("B"))
            assert r.status_code == 409
            r = client.post(f"{BASE}/control", json={"action": "force_take"}, headers=headers("B"))
            assert r.status_code == 409 and '"confirm": true' in r.json()["hint"]
            assert abs(drive.velocity) > 70_000
            take(client, SID, "B", force=True)
            info = client.get(f"{BASE}/control", headers=headers("B")).json()
            assert info["owner"] == "B" and info["you"] is True
            # A's motion stops and its drive is disabled when control is taken from it.
            assert wait_until(lambda: abs(drive.velocity) < 1000, 2.0)
            assert wait_until(lambda: drive.state.name == "SWITCH_ON_DISABLED", 8.0)
            msg = _receive(ws_a, "safe_state")
            assert msg["client"] == "A" and "taken over" in msg["reason"]
            assert msg["state"] == "Switch on disabled"
            beats.stop()
            # A's token is worth nothing now.
            r = client.put(f"{BASE}/objects/0x6081", json={"value": 1}, headers=headers("A"))
            assert r.status_code == 409 and "'B' holds control" in r.json()["message"]
        r = client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("B"))
        assert r.status_code == 200 and r.json()["owner"] is None


def test_a_script_holds_control_but_cannot_energise_without_a_dead_man(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        token = take(client, SID, "script")
        # Taking again with the token is idempotent; the token is only told to its holder.
        assert take(client, SID, "script") == token
        seen = client.get(f"{BASE}/control").json()
        assert seen["token"] is None
        # The page says what stops the axis: here the dead-man's own thread on CANopen.
        assert seen["protection"]["stop_path"] == "dead-man thread"
        assert seen["protection"]["deadman_ms"] == 1000
        r = client.put(f"{BASE}/objects/0x6081", json={"value": 90000}, headers=headers("script"))
        assert r.status_code == 200, r.text
        assert drive.read(0x6081) == 90000
        for method, path, body in (
            ("post", "state", {"command": "enable"}),
            ("post", "state", {"command": "switch_on"}),
            ("put", "objects/0x6040", {"value": 0x0F}),
            ("post", "motion/jog", {"velocity": 1000, "acceleration": 100000}),
            # Process data servodesk produces carries the controlword too.
            ("put", "pdo/cyclic/outputs", {"values": {"0x6040:00": 0x0F}}),
            ("post", "pdo/cyclic", {"sync_period_ms": 10, "outputs": True}),
        ):
            r = _send(client, method, path, body, headers("script"))
            assert r.status_code == 409, (path, r.text)
            assert "dead-man" in r.json()["message"], r.json()
        assert drive.state.name == "SWITCH_ON_DISABLED"


@pytest.fixture(autouse=True)
def _fresh_tokens() -> Any:
    TOKENS.clear()
    yield
    TOKENS.clear()


def _receive(ws: Any, kind: str, timeout: float = 8.0) -> dict[str, Any]:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg: dict[str, Any] = ws.receive_json()
        if msg.get("type") == kind:
            return msg
    raise AssertionError(f"no {kind} message")
