"""The global stop (POST /motion/stop-all, issue 48): every axis the caller controls, at once.

What the header's STOP ALL relies on: both jogging axes get their quick stop, a drive that does
not answer (NMT stopped: it ignores SDOs, CiA 301 §7.3.2.2.1) neither delays the other's stop
nor the answer beyond its wait, and axes of another account are left alone. The stop needs no
control token: a request without one stops the axes all the same.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from typing import Any

from servodesk.api.control_deps import operation
from servodesk.api.routes.stop_all import ANSWER_WAIT_S
from servodesk.sim.canopen_device import NMT_PRE_OPERATIONAL, NMT_STOPPED
from tests.operation.support import (
    BusSpy,
    Heartbeats,
    bind,
    headers,
    is_stop,
    operation_app,
    take,
    wait_motion,
)

A = headers("A")
JOG = {"velocity": 200_000, "acceleration": 2_000_000}
#: The silent drive's SDOs time out after this long (Settings.sdo_timeout): far longer than the
#: other drive's stop may take, so a stop sent one drive after the other is seen.
SDO_TIMEOUT_S = 1.5


def _jogging(client: Any, sids: list[str], stack: ExitStack) -> list[Heartbeats]:
    """Take control of ``sids`` as A (one token), bind a socket per drive, servo on, jog."""
    beats: list[Heartbeats] = []
    for sid in sids:
        take(client, sid, "A")
    for sid in sids:
        ws = stack.enter_context(client.websocket_connect("/api/v1/ws?client=A"))
        bind(ws, sid, "A")
        beats.append(Heartbeats(ws, sid))
        r = client.post(f"/api/v1/sessions/{sid}/state", json={"command": "enable"}, headers=A)
        assert r.status_code == 200 and r.json()["state"] == "Operation enabled", r.text
        r = client.post(f"/api/v1/sessions/{sid}/motion/jog", json=JOG, headers=A)
        assert r.status_code == 200 and r.json()["active"], r.text
    return beats


def test_stop_all_stops_every_held_axis_without_waiting_for_a_silent_one(
    channel: str, tmp_path: Any
) -> None:
    spy = BusSpy(channel)
    try:
        with (
            operation_app(
                channel, tmp_path, "cia402-generic,hiwin-e", sdo_timeout=SDO_TIMEOUT_S
            ) as (client, sim),
            ExitStack() as stack,
        ):
            listed = client.get("/api/v1/sessions").json()
            sids = [s["id"] for s in listed]
            nodes = {s["id"]: s["node_id"] for s in listed}
            assert len(sids) == 2, sids
            beats = _jogging(client, sids, stack)
            # The first drive in the server's order goes silent: a stop sent drive after drive
            # would wait its SDO time-out before the second drive's.
            silent, other = sids
            dev = next(d for d in sim.devices if d.id == nodes[silent])
            dev.set_nmt_state(NMT_STOPPED)
            try:
                t0 = time.time()
                # No control token: a stop is never refused for the lack of one.
                r = client.post("/api/v1/motion/stop-all", headers={"X-Servodesk-Client": "A"})
                answered = time.time() - t0
                assert r.status_code == 200, r.text
                body = r.json()
                by_sid = {i["session"]: i for i in body["sessions"]}
                assert set(by_sid) == {silent, other}, body
                assert by_sid[other]["result"] == "stopped", body
                assert by_sid[other]["motion"]["state"] == "stopped", body
                assert not by_sid[other]["motion"]["active"], body
                assert by_sid[silent]["result"] in ("failed", "pending"), body
                assert by_sid[silent]["message"], body
                assert (body["stopped"], body["failed"] + body["pending"]) == (1, 1), body
                assert answered < ANSWER_WAIT_S + 1.0, answered
                # The answering drive's quick stop was on the bus well before the silent
                # drive's SDO time-out.
                stops = [d for d in spy.controlwords(nodes[other], after=t0) if is_stop(d.value)]
                assert stops, "no quick stop reached the answering drive"
                assert stops[0].time - t0 < SDO_TIMEOUT_S / 2, stops[0].time - t0
            finally:
                dev.set_nmt_state(NMT_PRE_OPERATIONAL)
            assert not wait_motion(client, other)["active"]
            for b in beats:
                b.stop()
    finally:
        spy.close()


def test_stop_all_leaves_axes_of_other_accounts_and_free_axes_alone(
    channel: str, tmp_path: Any
) -> None:
    with (
        operation_app(channel, tmp_path, "cia402-generic,hiwin-e") as (client, _sim),
        ExitStack() as stack,
    ):
        sids = [s["id"] for s in client.get("/api/v1/sessions").json()]
        mine, theirs = sids
        beats = _jogging(client, [mine], stack)
        # Another account holds the second drive (as its login would: services/control.py).
        operation(client.app).control.take(theirs, "bob-tab", user="bob")
        r = client.post("/api/v1/motion/stop-all", headers={"X-Servodesk-Client": "A"})
        assert r.status_code == 200, r.text
        body = r.json()
        assert [i["session"] for i in body["sessions"]] == [mine], body
        assert body["user"] == "local" and body["stopped"] == 1, body
        assert client.get(f"/api/v1/sessions/{mine}/motion").json()["state"] == "stopped"
        # Nothing held: an empty answer, not an error.
        for b in beats:
            b.stop()
        r = client.post(f"/api/v1/sessions/{mine}/control", json={"action": "release"}, headers=A)
        assert r.status_code == 200, r.text
        r = client.post("/api/v1/motion/stop-all")
        assert r.status_code == 200 and r.json()["sessions"] == [], r.text
