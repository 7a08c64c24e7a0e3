"""Software position limits (607Dh) and continuous motion; limits the drive does not have.

Jog and profile velocity have no target position to check before they start: the motion
monitor halts the axis (with the halt deceleration) before it reaches a software limit in its
direction of travel, and a jog or velocity command toward a limit the axis is already at or
beyond is refused before anything is sent. A limit object the drive refuses is reported as
unknown with the reason; only a dead link makes GET /limits fail.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from tests.operation.support import (
    BusSpy,
    headers,
    operation_app,
    take_and_enable,
    wait_motion,
    wait_until,
)

SID = "cia402-generic-1"
BASE = f"/api/v1/sessions/{SID}"
A = headers("A")
LO, HI = -100_000, 100_000


def _set_limits(client: Any, lo: int, hi: int) -> None:
    for addr, value in (("0x607D:01", lo), ("0x607D:02", hi)):
        r = client.put(f"{BASE}/objects/{addr}", json={"value": value}, headers=A)
        assert r.status_code == 200, r.text


class Extremes:
    """Samples the simulated axis every millisecond: the furthest it went each way."""

    def __init__(self, drive: Any) -> None:
        self.drive = drive
        self.lowest = self.highest = drive.position
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            p = self.drive.position
            self.lowest, self.highest = min(self.lowest, p), max(self.highest, p)
            time.sleep(0.001)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(1.0)


def test_jog_and_velocity_halt_before_the_software_limits(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        with client.websocket_connect("/api/v1/ws?client=A") as ws:
            beats = take_and_enable(client, SID, "A", ws)
            _set_limits(client, LO, HI)
            seen = Extremes(drive)
            try:
                # Jog toward max: 300000 inc/s would cross the limit 0.33 s after the start.
                r = client.post(
                    f"{BASE}/motion/jog",
                    json={"velocity": 300_000, "acceleration": 3_000_000},
                    headers=A,
                )
                assert r.status_code == 200, r.text
                done = wait_motion(client, SID, 3.0)
                assert done["state"] == "halted", done
                assert "limit max 100000" in done["message"], done
                assert wait_until(lambda: abs(drive.velocity) <= 1000, 1.0)
                assert seen.highest < HI, seen.highest
                assert seen.highest > HI - 40_000, seen.highest  # It did not stop far short.
                # Still enabled: a halt, not a quick stop.
                state = client.get(f"{BASE}/state").json()["state"]
                assert state == "Operation enabled"

                # Profile velocity toward min, from wherever the jog stopped.
                r = client.post(
                    f"{BASE}/motion/velocity",
                    json={
                        "velocity": -250_000,
                        "acceleration": 2_500_000,
                        "deceleration": 2_500_000,
                    },
                    headers=A,
                )
                assert r.status_code == 200, r.text
                done = wait_motion(client, SID, 3.0)
                assert done["state"] == "halted" and "limit min -100000" in done["message"], done
                assert wait_until(lambda: abs(drive.velocity) <= 1000, 1.0)
                assert LO < seen.lowest < LO + 40_000, seen.lowest
            finally:
                seen.stop()
                beats.stop()


def test_continuous_motion_toward_a_limit_already_reached_is_refused(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    spy = BusSpy(channel)
    try:
        with operation_app(channel, tmp_path) as (client, sim):
            drive = sim.drives[0]
            with client.websocket_connect("/api/v1/ws?client=A") as ws:
                beats = take_and_enable(client, SID, "A", ws)
                pos = drive.position
                # The axis stands exactly at max and beyond min.
                _set_limits(client, pos - 50_000, pos)
                for path, body in (
                    ("motion/jog", {"velocity": 10_000, "acceleration": 100_000}),
                    ("motion/velocity", {"velocity": 1}),
                ):
                    t0 = time.time()
                    r = client.post(f"{BASE}/{path}", json=body, headers=A)
                    t1 = time.time()
                    assert r.status_code == 400, (path, r.text)
                    msg = r.json()["message"]
                    assert f"limit max {pos}" in msg and "0x607D:02" in msg, msg
                    assert r.json()["field"] == "velocity"
                    time.sleep(0.02)
                    assert spy.writes(1, t0, t1 + 0.02) == [], path
                # Away from the limit it runs (and is halted before min).
                r = client.post(
                    f"{BASE}/motion/jog",
                    json={"velocity": -100_000, "acceleration": 1_000_000},
                    headers=A,
                )
                assert r.status_code == 200, r.text
                done = wait_motion(client, SID, 3.0)
                assert done["state"] == "halted" and "limit min" in done["message"], done
                assert drive.position > pos - 50_000
                beats.stop()
    finally:
        spy.close()


def test_limits_the_drive_refuses_are_unknown_with_the_reason(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        drive = sim.drives[0]
        # A firmware without 607Fh and 6072h: its SDO server answers abort 0602 0000h.
        with drive._lock:
            del drive._specs[0x607F00]
            del drive._specs[0x607200]
        r = client.get(f"{BASE}/limits")
        assert r.status_code == 200, r.text
        lim = r.json()
        # No max torque from the drive; the profile's range of 6071h stands in, with why.
        assert "0x6071" in lim["sources"]["max_torque"]
        assert "refused 0x6072:00" in lim["sources"]["max_torque"]
        assert "refused 0x607F:00 (abort 0x" in lim["sources"]["max_velocity"]
        # The other limits are still read from the drive.
        assert lim["sources"]["position_max"] == "0x607D:02"


def test_limits_of_a_drive_that_does_not_answer_are_an_error(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path) as (client, sim):
        sim.stop()
        r = client.get(f"{BASE}/limits")
        assert r.status_code in (502, 504), r.text


def test_limits_carry_the_ramps_unit_kind_and_the_familys_default(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    # The Operation page starts a ramp that is neither a rate nor a time (CTMM04x: PMC842SR
    # rate registers, larger = gentler) at the family's own default of 6083h; the server says
    # which kind each family's ramp is (domain/ramps.py), so the page does not parse units.
    with operation_app(channel, tmp_path, "ctmm04x,lecsn-t,cia402-generic") as (client, _sim):
        kinds = {}
        for s in client.get("/api/v1/sessions").json():
            acc = client.get(f"/api/v1/sessions/{s['id']}/limits").json()["units"]["acceleration"]
            kinds[s["profile_id"]] = acc["ramp"]
            if s["profile_id"] == "ctmm04x":
                assert acc == {
                    "raw_unit": "PMC842SR RATE DATA",
                    "unit": None,
                    "scale": 1.0,
                    "default": 100,
                    "ramp": "register",
                }
        assert kinds == {"ctmm04x": "register", "lecsn-t": "time", "cia402-generic": "rate"}
