"""Scope channels from EtherCAT process data (issue 50, docs/scope.md "EtherCAT and PROFINET
cyclic channels"): every input image the line's cycle thread hands to the exchange reaches a
scope WebSocket client, one sample per channel and cycle, at the line's 1 ms cycle."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from servodesk.domain import scope_wire as wire
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import VethPair
from tests.operation.support import headers, operation_app, take

pytestmark = pytest.mark.timeout(90)
A = headers("A")
#: Four objects of each slave's default TxPDO 1A00h (HIWIN 000 §3.1.1): 2 slaves x 4 channels,
#: the scope's 8.
OBJECTS = ["0x6041:00", "0x6064:00", "0x60F4:00", "0x60FD:00"]


def test_the_scope_gets_every_cycle_of_two_slaves_at_1_ms(
    veth: VethPair, channel: str, tmp_path: Path
) -> None:
    with (
        SimulatedBus.start(
            drives=[("hiwin-e", 1), ("hiwin-e", 2)], interface="ethercat", channel=veth.slave
        ) as line,
        operation_app(channel, tmp_path) as (client, _sim),
    ):
        sids = []
        for node in (1, 2):
            r = client.post(
                "/api/v1/sessions",
                json={"interface": "ethercat", "channel": veth.master, "node_id": node},
            )
            assert r.status_code == 201, r.text
            sids.append(r.json()["id"])
        state = client.app.state.servodesk  # type: ignore[attr-defined]
        seen: dict[str, list[float]] = {}
        for sid in sids:
            take(client, sid, "A")
            r = client.post(
                f"/api/v1/sessions/{sid}/pdo/cyclic",
                json={"sync_period_ms": 1, "outputs": False},
                headers=A,
            )
            assert r.status_code == 200, r.text
            # Every input image the exchange decoded, stamped as the scope stamps its
            # samples (in the cycle thread): what the scope must deliver, cycle for cycle.
            times = seen[sid] = []
            state.manager.get(sid).cyclic.add_listener(
                lambda t, addresses, values, times=times: times.append(time.time())
            )
        chans = [
            {"id": 4 * d + k, "session": sid, "address": a, "source": "pdo"}
            for d, sid in enumerate(sids)
            for k, a in enumerate(OBJECTS)
        ]
        r = client.put("/api/v1/scope/channels", json={"channels": chans})
        assert r.status_code == 200, r.text
        got: dict[int, list[np.ndarray]] = {c["id"]: [] for c in chans}
        words: dict[int, list[np.ndarray]] = {c["id"]: [] for c in chans}
        skipped = 0
        with client.websocket_connect(
            "/api/v1/scope/ws", subprotocols=["servodesk.scope.v1"]
        ) as ws:
            assert client.post("/api/v1/scope/run", json={"action": "start"}).status_code == 200
            end = time.monotonic() + 2.0
            stopped = False
            while True:
                frame = wire.decode_frame(ws.receive_bytes())
                skipped = frame.skipped
                for b in frame.blocks:
                    n = len(b.values)
                    offsets = (
                        np.asarray(b.times) if b.times is not None else b.t0 + b.dt * np.arange(n)
                    )
                    got[b.id].append(frame.t_ref + offsets)
                    words[b.id].append(np.asarray(b.values))
                if not stopped and time.monotonic() > end:
                    st = client.post("/api/v1/scope/run", json={"action": "stop"}).json()
                    stopped = True
                if stopped and frame.kind == 3 and not (frame.status or {}).get("running"):
                    break  # The stop's status frame: every sample was sent before it.
        for sid in sids:
            r = client.delete(f"/api/v1/sessions/{sid}/pdo/cyclic", headers=A)
            assert r.status_code == 200, r.text
        assert [c["error"] for c in st["channels"]] == [None] * len(chans), st
        assert skipped == 0
        for d, sid in enumerate(sids):
            t = [np.concatenate(got[4 * d + k]) for k in range(len(OBJECTS))]
            # Each channel of a slave has one sample per cycle, the same cycles ...
            assert len({len(x) for x in t}) == 1, [len(x) for x in t]
            first, last = float(t[0][0]), float(t[0][-1])
            # ... every cycle the exchange decoded while the scope listened (none lost) ...
            arrived = sum(1 for x in seen[sid] if first - 5e-4 <= x <= last + 5e-4)
            assert len(t[0]) == arrived, (sid, len(t[0]), arrived)
            # ... at the line's 1 ms cycle (the cycle thread, not the scope, sets the pace).
            assert float(np.median(np.diff(t[0]))) == pytest.approx(0.001, rel=0.3)
            assert len(t[0]) >= 0.6 * (last - first) / 0.001
        # The values are each slave's own: its drive's statusword (idle, unchanged).
        for d, drive in enumerate(line.drives):
            assert set(np.concatenate(words[4 * d]).tolist()) == {float(drive.statusword)}
