"""Heavy requests leave the event loop: a jog's heartbeats are read while a big file is parsed.

Issue "Motion safety" item 3: a POST /scope/import of a 10 MB CSV (or a 35 MB backup) held the
event loop for seconds. The dead-man's thread (services/deadman.py) stops an axis whose
heartbeats the loop has not read, so such a request would now stop a live client's jog; the
parsing runs in a worker process instead (api/offload.py). A real server process, so that the
test's own work (building the upload, its heartbeats) does not share the server's GIL. On the
code before the offload the jog ended in "deadman" during the import; with the parse in a
thread (not a process) too: NumPy's text conversion holds the GIL for up to 1.9 s at a time.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any

import httpx
from websockets.sync.client import connect

from tests.live import live_server

SID = "cia402-generic-1"


def _big_csv(megabytes: float) -> bytes:
    rows = ["time_s,position [inc]"]
    n = int(megabytes * 1e6 / 18)
    rows += [f"{i * 0.0005:.6f},{(i * 7919) % 1000003}" for i in range(n)]
    return ("\n".join(rows) + "\n").encode()


def test_a_10_mb_import_does_not_hold_the_loop_or_stop_a_live_jog() -> None:
    data = _big_csv(10.0)
    assert len(data) > 9_500_000
    env = {"SERVODESK_SIM_PROFILES": "cia402-generic", "SERVODESK_DEADMAN_MS": "250"}
    with live_server(env=env) as base:
        api = f"{base}/api/v1"
        base_ws = base.replace("http://", "ws://")
        with (
            httpx.Client(timeout=60) as http,
            connect(f"{base_ws}/api/v1/ws?client=A", subprotocols=["servodesk.v1"]) as ws,  # type: ignore[list-item]
        ):
            r = http.post(
                f"{api}/sessions/{SID}/control",
                json={"action": "take"},
                headers={"X-Servodesk-Client": "A"},
            )
            token = r.json()["token"]
            h = {"X-Servodesk-Client": "A", "X-Servodesk-Control": token}
            ws.send(json.dumps({"type": "bind", "session": SID, "token": token}))
            while json.loads(ws.recv(5)).get("type") != "bind":
                pass
            stop = threading.Event()

            def beat() -> None:
                while not stop.wait(0.05):
                    ws.send(json.dumps({"type": "heartbeat", "session": SID}))

            beats = threading.Thread(target=beat, daemon=True)
            beats.start()
            try:
                r = http.post(f"{api}/sessions/{SID}/state", json={"command": "enable"}, headers=h)
                assert r.status_code == 200, r.text
                r = http.post(
                    f"{api}/sessions/{SID}/motion/jog",
                    json={"velocity": 20_000, "acceleration": 200_000},
                    headers=h,
                )
                assert r.status_code == 200, r.text
                result: dict[str, Any] = {}

                def upload() -> None:
                    t0 = time.monotonic()
                    with httpx.Client(timeout=120) as c:
                        resp = c.post(
                            f"{api}/scope/import?filename=big.csv",
                            files={"file": ("big.csv", data, "text/csv")},
                        )
                    result["status"] = resp.status_code
                    result["bytes"] = len(resp.content)  # Not decoded: it would hold our GIL.
                    result["seconds"] = time.monotonic() - t0

                t = threading.Thread(target=upload)
                t.start()
                worst = 0.0
                while t.is_alive():
                    t0 = time.monotonic()
                    assert http.get(f"{api}/health").status_code == 200
                    worst = max(worst, time.monotonic() - t0)
                    time.sleep(0.02)
                t.join()
                assert result["status"] == 200, result
                assert result["bytes"] > 9_000_000, result  # 555,555 samples of two columns
                motion = http.get(f"{api}/sessions/{SID}/motion").json()
                assert motion["active"] and motion["kind"] == "jog", (motion, result, worst)
                assert worst < 0.25, (worst, result)
                print(
                    f"worst /health {worst * 1000:.0f} ms during a {result['seconds']:.1f} s import"
                )
                http.post(f"{api}/sessions/{SID}/motion/halt", json={}, headers=h)
            finally:
                stop.set()
                beats.join(1.0)
