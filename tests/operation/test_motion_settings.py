"""A motion gives back the settings it wrote: nothing changes behind the user's back.

Issue "Motion safety" item 6: after jog/move/homing, 6081h, 6083h, 6084h and 6098h showed as
changed since the last save (CTMM04x 6081h 5000 -> 819), and the next "Save to EEPROM" stored
them with the user's own edit. Each test here failed on the code before 2026-12-07: the
values stayed and the session listed them as written since the last save.
"""

from __future__ import annotations

from typing import Any

from tests.operation.support import headers, operation_app, take_and_enable, wait_motion, wait_until

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"
A = headers("A")
SETTINGS = (0x6081, 0x6083, 0x6084)


def _dirty(client: Any) -> set[str]:
    return set(client.get(BASE).json().get("dirty", []))


def test_a_jog_and_a_move_give_back_the_profile_settings(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        before = {i: drive.read(i) for i in SETTINGS}
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            ws.send_json({"type": "subscribe", "session": SID})
            beats = take_and_enable(client, SID, "A", ws)
            # The user's own edit stays what it is: written since the last save.
            r = client.put(f"{BASE}/objects/0x6085", json={"value": 4_000_000}, headers=A)
            assert r.status_code == 200, r.text
            r = client.post(
                f"{BASE}/motion/jog", json={"velocity": 70_000, "acceleration": 700_000}, headers=A
            )
            assert r.status_code == 200, r.text
            assert wait_until(lambda: abs(drive.velocity) > 60_000, 2.0)
            assert drive.read(0x6083) == 700_000  # The jog's own ramp while it runs.
            assert client.post(f"{BASE}/motion/halt", json={}, headers=A).status_code == 200
            assert wait_until(lambda: all(drive.read(i) == before[i] for i in SETTINGS), 3.0), {
                i: drive.read(i) for i in SETTINGS
            }
            r = client.post(
                f"{BASE}/motion/move",
                json={
                    "mode": "relative",
                    "target": 20_000,
                    "velocity": 90_000,
                    "acceleration": 900_000,
                    "deceleration": 800_000,
                },
                headers=A,
            )
            assert r.status_code == 200, r.text
            assert wait_motion(client, SID)["state"] == "reached"
            assert wait_until(lambda: all(drive.read(i) == before[i] for i in SETTINGS), 3.0), {
                i: drive.read(i) for i in SETTINGS
            }
            dirty = _dirty(client)
            assert "0x6085:00" in dirty, dirty
            assert not {f"0x{i:04X}:00" for i in SETTINGS} & dirty, dirty
            beats.stop()
