"""The dead-man: motion stops when its client's heartbeats stop or its WebSocket closes.

Latencies are measured on the bus: a plain python-can Bus on the virtual channel sees the
controlword download the backend sends, and the simulated drive tells when the axis stands.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

import httpx

from servodesk.api.app import create_app
from servodesk.api.control_deps import operation
from servodesk.settings import Settings
from tests.operation.support import (
    BusSpy,
    headers,
    is_stop,
    operation_app,
    take_and_enable,
    wait_until,
)

SID = "cia402-generic-1"
NODE = 1
DEADMAN_MS = 250  # The default SERVODESK_DEADMAN_MS.
#: Standstill: |velocity| within the drive's velocity threshold 606Fh (sim default, inc/s).
STANDSTILL = 1000


def _jog(client: Any) -> None:
    r = client.post(
        f"/api/v1/sessions/{SID}/motion/jog",
        json={"velocity": 200_000, "acceleration": 2_000_000},
        headers=headers("A"),
    )
    assert r.status_code == 200, r.text
    assert r.json()["active"] and r.json()["kind"] == "jog"


def test_missing_heartbeats_halt_then_quick_stop_within_the_deadline(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    spy = BusSpy(channel)
    try:
        with operation_app(channel, tmp_path, deadman_ms=DEADMAN_MS) as (client, sim):
            drive = sim.drives[0]
            with client.websocket_connect("/api/v1/ws?client=A") as ws:
                ws.send_json({"type": "subscribe", "session": SID})
                beats = take_and_enable(client, SID, "A", ws)
                t_start = time.time()
                _jog(client)
                # Heartbeats for longer than the dead-man time keep the jog running.
                time.sleep(0.6)
                assert abs(drive.velocity) > 150_000
                assert not [d for d in spy.controlwords(NODE, t_start) if is_stop(d.value)]
                last = beats.stop()
                stopped_at = wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 2.0)
                assert stopped_at is not None, "the axis did not stop"
                assert wait_until(
                    lambda: any(d.value & 0x86 == 0x02 for d in spy.controlwords(NODE, last)), 1.0
                ), [hex(d.value) for d in spy.controlwords(NODE, t_start)]
                stops = [d for d in spy.controlwords(NODE, last) if is_stop(d.value)]
                # Halt (bit 8, still enabled) first, then quick stop.
                assert stops[0].value & 0x010F == 0x010F
                assert any(d.value & 0x0086 == 0x0002 for d in stops[1:])
                latency_ms = (stops[0].time - last) * 1000.0
                standstill_ms = (stopped_at - last) * 1000.0
                assert DEADMAN_MS <= latency_ms <= DEADMAN_MS + 50, latency_ms
                assert standstill_ms <= DEADMAN_MS + 250, standstill_ms
                msg = _receive(ws, "deadman")
                assert msg["session"] == SID and "heartbeat" in msg["reason"]
                assert DEADMAN_MS <= msg["latency_ms"] <= DEADMAN_MS + 50
            st = client.get(f"/api/v1/sessions/{SID}/motion").json()
            assert st["active"] is False and st["state"] == "deadman"
            state = client.get(f"/api/v1/sessions/{SID}/state").json()["state"]
            assert state != "Operation enabled"  # Quick stop ends in Switch on disabled.
    finally:
        spy.close()


def test_closing_the_websocket_stops_the_jog(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    spy = BusSpy(channel)
    try:
        with operation_app(channel, tmp_path, deadman_ms=DEADMAN_MS) as (client, sim):
            drive = sim.drives[0]
            with client.websocket_connect("/api/v1/ws?client=A") as ws:
                beats = take_and_enable(client, SID, "A", ws)
                _jog(client)
                assert wait_until(lambda: abs(drive.velocity) > 150_000, 1.0)
                beats.stop()
                closing = time.time()
            closed = time.time()
            # The heartbeats stopped a moment ago: the socket closing, not the dead-man
            # deadline, must be what stops the axis.
            assert wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 1.0)
            st = client.get(f"/api/v1/sessions/{SID}/motion").json()
            assert st["state"] == "deadman" and "closed" in st["message"], (st, closed - closing)
            stops = [d for d in spy.controlwords(NODE, closing) if is_stop(d.value)]
            assert stops and (stops[0].time - closed) * 1000.0 < 100
    finally:
        spy.close()


async def test_backend_shutdown_stops_motion(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    # The lifespan is driven directly (a TestClient cannot shut down under an open
    # WebSocket); the client's socket is registered with the control service instead.
    spy = BusSpy(channel)
    try:
        settings = Settings(
            sim=True,
            sim_channel=channel,
            sim_profiles="cia402-generic",
            data_dir=tmp_path,
            viewer_port=0,
        )
        app = create_app(settings)
        async with app.router.lifespan_context(app):
            control = operation(app).control
            connection = control.connect("A")
            transport = httpx.ASGITransport(app=app)
            async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
                h = headers("A")
                r = await c.post(
                    f"/api/v1/sessions/{SID}/control", json={"action": "take"}, headers=h
                )
                assert r.status_code == 200
                control.bind(connection, SID, r.json()["token"])
                h = {**h, "X-Servodesk-Control": r.json()["token"]}
                r = await c.post(
                    f"/api/v1/sessions/{SID}/state", json={"command": "enable"}, headers=h
                )
                assert r.json()["state"] == "Operation enabled"
                r = await c.post(
                    f"/api/v1/sessions/{SID}/motion/jog",
                    json={"velocity": 200_000, "acceleration": 2_000_000},
                    headers=h,
                )
                assert r.status_code == 200, r.text
                t_jog = time.time()
                control.heartbeat(connection, SID)
                await asyncio.sleep(0.05)
        t_end = time.time()
        stops = [d for d in spy.controlwords(NODE, t_jog) if is_stop(d.value)]
        assert stops, "shutdown sent no halt/quick stop"
        assert stops[0].time <= t_end and stops[0].time - t_jog < 0.2
    finally:
        spy.close()


def _receive(ws: Any, kind: str, limit: int = 200) -> dict[str, Any]:
    for _ in range(limit):
        msg: dict[str, Any] = ws.receive_json()
        if msg.get("type") == kind:
            return msg
    raise AssertionError(f"no {kind} message")


def test_a_stall_of_the_backend_is_not_a_lost_client(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The backend's event loop held for 0.6 s (a garbage collection, a starved CPU): the
    client's heartbeats of that time wait unread in its socket, and the jog goes on. The
    dead-man then still stops the axis when the heartbeats really stop, and a client that goes
    silent during a stall is stopped once the stall and a short grace have passed."""
    with operation_app(channel, tmp_path, deadman_ms=DEADMAN_MS) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            _jog(client)
            assert wait_until(lambda: abs(drive.velocity) > 150_000, 1.0)
            client.portal.call(time.sleep, 0.6)  # Blocks the backend's event loop.
            time.sleep(0.3)
            st = client.get(f"/api/v1/sessions/{SID}/motion").json()
            assert st["active"] and abs(drive.velocity) > 150_000, st
            # The heartbeats stop for real: the dead-man still works.
            last = beats.stop()
            stopped_at = wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 2.0)
            assert stopped_at is not None
            assert (stopped_at - last) * 1000.0 <= DEADMAN_MS + 250
            st = client.get(f"/api/v1/sessions/{SID}/motion").json()
            assert st["state"] == "deadman" and "heartbeat" in st["message"], st
        # Silent during a stall: stopped after the stall and the grace, not never.
        assert client.post(
            f"/api/v1/sessions/{SID}/alarms/reset", json={}, headers=headers("A")
        ).status_code in (200, 409)
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            _jog(client)
            assert wait_until(lambda: abs(drive.velocity) > 150_000, 1.0)
            last = beats.stop()
            client.portal.call(time.sleep, 0.4)
            stopped_at = wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 2.0)
            assert stopped_at is not None
            # 0.4 s stall + 0.1 s grace + braking (the 250 ms dead-man ran out in the stall).
            assert (stopped_at - last) * 1000.0 <= 400 + 100 + 250 + 100
            st = client.get(f"/api/v1/sessions/{SID}/motion").json()
            assert st["state"] == "deadman" and "heartbeat" in st["message"], st
