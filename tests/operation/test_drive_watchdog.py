"""The drive's own watchdog: a dead PC stops the axis without servodesk.

Issue "Motion safety": "arm the drive's own watchdog so a dead PC stops the axis without
servodesk: CiA 301 heartbeat consumer (1016h) ... on CANopen drives that support it". While a
holder's dead-man socket is bound, servodesk produces a heartbeat (node 127, 05h every
100 ms) and writes the drive's 1016h:01 to consume it; the drive reacts per 6007h when it
lapses (the twin: sim/heartbeat_consumer.py). Each test failed on the code before 2026-12-07:
nothing was armed, and a PC that died mid-jog left the drive running on its last target.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import can
import canopen

from servodesk.links import canopen_link
from tests.operation.support import (
    bind,
    headers,
    operation_app,
    take,
    take_and_enable,
    wait_until,
)

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"
ARMED = (127 << 16) | 1000


def test_binding_arms_the_drives_heartbeat_consumer_and_releasing_puts_it_back(
    channel, tmp_path
) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        assert drive.read(0x1016, 1) == 0
        # An independent heartbeat consumer: python-canopen's NMT master on the same bus.
        network = canopen.Network()
        network.connect(interface="virtual", channel=channel)
        try:
            master = network.add_node(canopen.RemoteNode(127, canopen.ObjectDictionary()))
            with client.websocket_connect("/api/v1/ws?client=A") as ws:
                take(client, SID, "A")
                assert drive.read(0x1016, 1) == 0  # A holder without a dead-man: nothing armed.
                bind(ws, SID, "A")
                assert wait_until(lambda: drive.read(0x1016, 1) == ARMED, 2.0)
                master.nmt.wait_for_heartbeat(timeout=1.0)
                assert master.nmt.state == "OPERATIONAL"
                seen = client.get(f"{BASE}/control", headers=headers("A")).json()
                assert "1016h:01" in seen["protection"]["drive_watchdog"]
                assert "If this PC dies" in seen["protection"]["summary"]
                # A store saves the drive's own entry, not servodesk's arming.
                r = client.post(f"{BASE}/store", headers=headers("A"))
                assert r.status_code == 200, r.text
                assert drive._nv.get(0x101601) in (None, 0)
                assert drive.read(0x1016, 1) == ARMED
                r = client.post(f"{BASE}/control", json={"action": "release"}, headers=headers("A"))
                assert r.status_code == 200, r.text
                assert wait_until(lambda: drive.read(0x1016, 1) == 0, 2.0)
                time.sleep(0.3)
                # servodesk stopped producing: canopen sees no new heartbeat.
                stamp = master.nmt.timestamp
                time.sleep(0.3)
                assert master.nmt.timestamp == stamp
        finally:
            network.disconnect()


def test_a_dead_pc_is_stopped_by_the_drive_itself(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The heartbeat stops as it would when the PC dies (servodesk's dead-man keeps beating
    here, so only the drive can stop the axis): the drive quick-stops on its own."""
    with operation_app(channel, tmp_path, deadman_ms=5000) as (client, sim):
        drive = sim.drives[0]
        emcy: list[int] = []
        spy = can.Bus(interface="virtual", channel=channel)
        stop = threading.Event()

        def listen() -> None:
            while not stop.is_set():
                m = spy.recv(0.05)
                if m is not None and m.arbitration_id == 0x81 and len(m.data) >= 2:
                    emcy.append(int.from_bytes(m.data[:2], "little"))

        t = threading.Thread(target=listen, daemon=True)
        t.start()
        try:
            with client.websocket_connect("/api/v1/ws?client=A") as ws:
                beats = take_and_enable(client, SID, "A", ws)
                assert wait_until(lambda: drive.read(0x1016, 1) == ARMED, 2.0)
                # CiA 301: the consumer watches from the first heartbeat after its entry was
                # written; a heartbeat that dies before that is no event.
                time.sleep(0.5)
                r = client.post(
                    f"{BASE}/motion/jog",
                    json={"velocity": 60_000, "acceleration": 600_000},
                    headers=headers("A"),
                )
                assert r.status_code == 200, r.text
                assert wait_until(lambda: abs(drive.velocity) > 50_000, 2.0)
                _kill_heartbeat(channel)
                died = time.time()
                stopped = wait_until(lambda: abs(drive.velocity) < 1000, 3.0)
                assert stopped is not None, "the drive did not stop by itself"
                # 1000 ms consumer time, then the quick-stop ramp.
                assert 0.9 < stopped - died < 2.5, stopped - died
                assert wait_until(lambda: 0x8130 in emcy, 1.0), emcy
                assert drive.state.name != "OPERATION_ENABLED"
                beats.stop()
        finally:
            stop.set()
            t.join(1.0)
            spy.shutdown()


def _kill_heartbeat(channel: str) -> None:
    """Stop servodesk's heartbeat on ``channel`` and nothing else, as a dead PC would."""
    shared: Any = canopen_link.pool._nets[("virtual", channel)]
    shared.heartbeat.stop()
