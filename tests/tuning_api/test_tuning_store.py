"""Tuning results in the store (issue 49, "Plant scale"; docs/tuning.md "Results in the store").

What a user relies on: a tuning that ended is still there after the server restarts (its
history, its whole result, the commissioning report's tuning section, the fleet page's "last
tuning"), and a store that fails never holds up or fails the tuning's stop.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import pytest

from tests.operation.support import headers, operation_app, take_and_enable, wait_until
from tests.tuning_api.support import PB_DEFAULTS, pb, start, wait_progress

SID = "lecsn-t-1"
#: The twin on CANopen (as in the other tuning tests' default), the same bus after the
#: restart: a drive is followed by its drive_key, and one without 1018h's serial is keyed by
#: where it sits (services/backup.py drive_key).
CAN: dict[str, Any] = {"sim_profinet": ""}
B = headers("B")


def _stopped_run(client: Any) -> dict[str, Any]:
    """Start the LECSN-T's one-touch tuning as A, stop it as B once it runs; the job."""
    with client.websocket_connect("/api/v1/ws?client=A") as ws:
        beats = take_and_enable(client, SID, "A", ws)
        assert start(client, SID, "A", travel=0.25).status_code == 202
        wait_progress(client, SID, 0.3)
        t0 = time.monotonic()
        r = client.post(f"/api/v1/sessions/{SID}/tuning/stop", headers=B)
        took = time.monotonic() - t0
        beats.stop()
    assert r.status_code == 200, r.text
    job: dict[str, Any] = r.json() | {"stop_took_s": took}
    return job


def _history(client: Any) -> list[dict[str, Any]]:
    r = client.get(f"/api/v1/sessions/{SID}/tuning/results")
    assert r.status_code == 200, r.text
    rows: list[dict[str, Any]] = r.json()
    return rows


def test_a_tuning_is_kept_in_the_store_across_a_restart(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    with operation_app(channel, tmp_path, "lecsn-t", **CAN) as (client, _sim):
        job = _stopped_run(client)
        assert job["state"] == "stopped", job
        # The write runs after the job has ended, in a thread: it lands shortly after.
        assert wait_until(lambda: len(_history(client)) == 1, 10.0)
        [row] = _history(client)
        assert row["status"] == "stopped" and row["mode"] == "basic"
        assert row["kind"] == "builtin" and row["applied"] is False
        assert row["by"] == "local" and row["client"] == "A"  # Loopback: single-user mode.
        assert row["session"] == SID and row["started"] <= row["ended"]
        assert "result" not in row  # The history is metadata only.
        memory = client.get(f"/api/v1/sessions/{SID}/tuning/result").json()
        drive_key = row["drive_key"]

    # The same data directory, a new server: nothing in memory, everything in the store.
    with operation_app(channel, tmp_path, "lecsn-t", **CAN) as (client, _sim):
        assert client.get(f"/api/v1/sessions/{SID}/tuning/result").status_code == 404
        assert _history(client) == [row]
        r = client.get(f"/api/v1/tuning/results/{row['id']}")
        assert r.status_code == 200, r.text
        stored = r.json()
        assert stored["result"] == memory
        assert stored["drive_key"] == drive_key and stored["gateway"]
        assert tuple(g["raw_after"] for g in stored["result"]["gains"]) == PB_DEFAULTS
        # The fleet page's "last tuning" column.
        drives = client.get("/api/v1/fleet", params={"q": "lecsn"}).json()["drives"]
        [mine] = [d for d in drives if d["drive_key"] == drive_key]
        last = mine["last_tuning"]
        assert last["id"] == row["id"] and last["status"] == "stopped" and last["mode"] == "basic"
        # The commissioning report takes the stored tuning and says where it comes from.
        r = client.post(f"/api/v1/sessions/{SID}/report")
        assert r.status_code == 201, r.text
        html = client.get(f"/api/v1/reports/{r.json()['id']}.html").text
        assert f"from the store: tuning {row['id']}" in html
        # Bad ids: a clear 4xx, never a 500.
        assert client.get("/api/v1/tuning/results/nope").status_code == 404
        r = client.get("/api/v1/tuning/results/..%2Fx")
        assert r.status_code in (400, 404, 422), r.text
        r = client.get("/api/v1/tuning/results/Bad%20Id")
        assert r.status_code == 422 and r.json()["field"] == "rid", r.text


def test_a_failing_store_does_not_hold_up_the_stop(
    channel: str, tmp_path: Any, caplog: pytest.LogCaptureFixture
) -> None:
    with operation_app(channel, tmp_path, "lecsn-t") as (client, sim):
        state = client.app.state.servodesk  # type: ignore[attr-defined]
        release = threading.Event()
        calls: list[dict[str, Any]] = []

        def broken(record: dict[str, Any]) -> None:
            # A store that hangs (a database gone away), then fails.
            calls.append(record)
            release.wait(30.0)
            raise OSError("the database went away")

        state.tuning.recorder = broken
        with caplog.at_level(logging.ERROR, logger="servodesk.services.tuning.jobs"):
            job = _stopped_run(client)
            # The stop answered with the tuning wound down while the store still hangs.
            assert job["state"] == "stopped", job
            assert not release.is_set() and job["stop_took_s"] < 10.0
            assert pb(sim.drives[0]) == PB_DEFAULTS
            assert wait_until(lambda: len(calls) == 1, 5.0)
            release.set()
            assert wait_until(lambda: "could not be kept in the store" in caplog.text, 5.0)
        # The server goes on: the in-memory result is there, the history simply empty.
        res = client.get(f"/api/v1/sessions/{SID}/tuning/result").json()
        assert res["status"] == "stopped"
        assert _history(client) == []
