"""The dead-man: motion stops when its client's heartbeats stop or its WebSocket closes.

Latencies are measured on the bus: a plain python-can Bus on the virtual channel sees the
controlword download the backend sends, and the simulated drive tells when the axis stands.
"""

from __future__ import annotations

import asyncio
import threading
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


def test_missing_heartbeats_quick_stop_within_the_deadline(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
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
                # Quick stop first, from the dead-man's thread (services/deadman.py); the
                # loop's halt then finds the drive out of Operation enabled and is not sent.
                assert stops[0].value & 0x0086 == 0x0002
                latency_ms = (stops[0].time - last) * 1000.0
                standstill_ms = (stopped_at - last) * 1000.0
                assert DEADMAN_MS <= latency_ms <= DEADMAN_MS + 50, latency_ms
                assert standstill_ms <= DEADMAN_MS + 250, standstill_ms
                msg = _receive(ws, "deadman")
                assert msg["session"] == SID and "heartbeat" in msg["reason"]
                assert DEADMAN_MS <= msg["latency_ms"] <= DEADMAN_MS + 50
                assert msg["from"] == "dead-man thread"
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


def test_a_held_event_loop_does_not_delay_the_stop(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Issue "Motion safety" item 3: while a request held the event loop (a 35 MB backup
    parsed, a 10 MB CSV imported) a silent client's jog stopped after 3.5 s instead of
    0.25 s. The dead-man's thread now puts the quick stop on the bus while the loop is still
    held. The loop is held here for 2 s; on the old code the first stop frame came after it."""
    spy = BusSpy(channel)
    try:
        with operation_app(channel, tmp_path, deadman_ms=DEADMAN_MS) as (client, sim):
            drive = sim.drives[0]
            with client.websocket_connect("/api/v1/ws?client=A") as ws:
                ws.send_json({"type": "subscribe", "session": SID})
                beats = take_and_enable(client, SID, "A", ws)
                _jog(client)
                assert wait_until(lambda: abs(drive.velocity) > 150_000, 1.0)
                holder = threading.Thread(target=client.portal.call, args=(time.sleep, 2.0))
                last = beats.stop()
                holder.start()  # The backend's event loop is held from now for 2 s.
                stop_seen = wait_until(
                    lambda: any(is_stop(d.value) for d in spy.controlwords(NODE, last)), 1.5
                )
                held = holder.is_alive()
                holder.join(5.0)
                assert stop_seen is not None, "no stop frame while the loop was held"
                assert held, "the loop was not held any more: the test proves nothing"
                first = next(d for d in spy.controlwords(NODE, last) if is_stop(d.value))
                assert first.value == 0x0002  # Quick stop, from the dead-man's thread.
                assert (first.time - last) * 1000.0 <= DEADMAN_MS + 50, first.time - last
                assert wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 2.0)
                msg = _receive(ws, "deadman")
                assert msg["from"] == "dead-man thread" and msg["stop_frame_ms"] <= DEADMAN_MS + 50
    finally:
        spy.close()


def test_a_loop_held_longer_than_the_dead_man_stops_even_a_live_client(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Fail-safe: the dead-man's thread cannot read heartbeats the held loop has not read, so
    a loop held past the dead-man time stops the axis although the client still beats (a
    shorter hold does not). Heavy work leaves the loop for this reason."""
    with operation_app(channel, tmp_path, deadman_ms=DEADMAN_MS) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            _jog(client)
            assert wait_until(lambda: abs(drive.velocity) > 150_000, 1.0)
            client.portal.call(time.sleep, 0.1)  # Shorter than the dead-man: the jog goes on.
            time.sleep(0.2)
            assert client.get(f"/api/v1/sessions/{SID}/motion").json()["active"]
            client.portal.call(time.sleep, 0.6)
            assert wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 2.0)
            st = client.get(f"/api/v1/sessions/{SID}/motion").json()
            assert st["state"] == "deadman" and "heartbeat" in st["message"], st
            beats.stop()


def test_the_thread_stop_also_holds_against_cyclic_outputs(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """With servodesk's cyclic outputs on, RPDO1 carries the controlword (CiA 402 default
    mapping), and every SYNC the drive applies it (CiA 301 §7.2.2). With 605Ah = 6 the drive
    stays in Quick stop active after its ramp (CiA 402-2 §6.3.4), from where "enable
    operation" takes it back to Operation enabled (transition 16): the dead-man thread's SDO
    quick stop alone was undone by the next RPDO, which still held "enable operation", and
    the jog's velocity came back. The thread now puts the quick stop into the output image
    too. The loop is held the whole time, so only the thread can have done it."""
    with operation_app(channel, tmp_path, deadman_ms=DEADMAN_MS) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            r = client.post(
                f"/api/v1/sessions/{SID}/pdo/cyclic",
                json={"sync_period_ms": 5, "outputs": True},
                headers=headers("A"),
            )
            assert r.status_code == 200, r.text
            assert "0x6040:00" in {
                a for a, v in r.json()["values"].items() if v["pdo"].startswith("RPDO")
            }
            r = client.put(
                f"/api/v1/sessions/{SID}/objects/0x605A",
                json={"value": 6},
                headers=headers("A"),
            )
            assert r.status_code == 200, r.text
            _jog(client)
            assert wait_until(lambda: abs(drive.velocity) > 150_000, 1.0)
            holder = threading.Thread(target=client.portal.call, args=(time.sleep, 1.5))
            last = beats.stop()
            holder.start()  # The event loop is held from now on.
            # Quick stop active (statusword xxxx xxxx x00x 0111b) or already disabled after it.
            left = wait_until(lambda: drive.statusword & 0x6F in (0x07, 0x40), 1.0)
            # Many SYNCs later, the loop still held: no RPDO has taken it back.
            again = wait_until(lambda: drive.statusword & 0x6F == 0x27, 0.3)
            held = holder.is_alive()
            holder.join(5.0)
            assert left is not None, f"still {drive.statusword:#06x} after the deadline"
            assert again is None, "the next RPDO took the drive back to Operation enabled"
            assert held, "the loop was not held any more: the test proves nothing"
            assert (left - last) * 1000.0 <= DEADMAN_MS + 100
            assert wait_until(lambda: abs(drive.velocity) <= STANDSTILL, 2.0)
            client.delete(f"/api/v1/sessions/{SID}/pdo/cyclic", headers=headers("A"))
