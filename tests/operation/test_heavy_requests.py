"""Heavy requests leave the event loop: a jog's heartbeats are read while a big file is parsed.

Issue "Motion safety" item 3: a POST /scope/import of a 10 MB CSV, or a GET, compare or restore
preflight of a 35 MB backup, held the event loop for seconds. The dead-man's thread
(services/deadman.py) stops an axis whose heartbeats the loop has not read, so such a request
would now stop a live client's jog; the parsing runs in a worker process instead
(api/offload.py). A real server process, so that the test's own work (building the upload,
its heartbeats) does not share the server's GIL. On the code before the offload the jog ended
in "deadman" during the import; with the parse in a thread (not a process) too: NumPy's text
conversion holds the GIL for up to 1.9 s at a time, as ``json.loads`` of a 30 MB backup does
for 0.3-0.9 s (api/backup_documents.py).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from typing import Any

import httpx
from websockets.sync.client import connect

from servodesk.benchmarks.documents import big_csv, padded_backup
from tests.live import live_server

SID = "cia402-generic-1"


def _big_backup(http: httpx.Client, api: str, h: dict[str, str], megabytes: float) -> str:
    """A backup of the twin padded to ``megabytes`` with unreadable entries (a drive with many
    refused objects: LECSN-T 541) and stored; its id. Structure to parse, not one string."""
    r = http.post(f"{api}/sessions/{SID}/backups", json={"label": "big"}, headers=h)
    assert r.status_code == 201, r.text
    doc = http.get(f"{api}/backups/{r.json()['id']}").json()
    body = padded_backup(doc, megabytes)
    r = http.post(
        f"{api}/backups/upload?filename=big.json",
        content=body,
        headers={"Content-Type": "application/json"},
        timeout=120,
    )
    assert r.status_code == 201, r.text
    return str(r.json()["id"])


def test_a_10_mb_import_does_not_hold_the_loop_or_stop_a_live_jog() -> None:
    data = big_csv(10.0)
    assert len(data) > 9_500_000

    def upload(c: httpx.Client, api: str, _h: dict[str, str]) -> httpx.Response:
        return c.post(
            f"{api}/scope/import?filename=big.csv", files={"file": ("big.csv", data, "text/csv")}
        )

    _beside_a_live_jog(upload, min_bytes=9_000_000)  # 555,555 samples of two columns


def test_a_30_mb_backup_read_compared_and_preflighted_beside_a_live_jog() -> None:
    """GET, compare and preflight of a 30 MB backup (the upload limit is 32 MiB) leave the
    loop free and the jog running: parsed and rendered in the documents' worker process."""
    bid: dict[str, str] = {}

    def prepare(http: httpx.Client, api: str, h: dict[str, str]) -> None:
        bid["id"] = _big_backup(http, api, h, 30.0)

    def read_compare_preflight(c: httpx.Client, api: str, _h: dict[str, str]) -> httpx.Response:
        src = {"kind": "backup", "id": bid["id"]}
        r = c.get(f"{api}/backups/{bid['id']}")
        assert r.status_code == 200 and len(r.content) > 25_000_000, r.status_code
        r = c.post(f"{api}/compare", json={"a": src, "b": src})
        assert r.status_code == 200 and len(r.content) > 50_000_000, r.status_code
        return c.post(f"{api}/sessions/{SID}/restore/preflight", json={"backup": bid["id"]})

    _beside_a_live_jog(read_compare_preflight, min_bytes=25_000_000, prepare=prepare)


Heavy = Callable[[httpx.Client, str, dict[str, str]], httpx.Response]


def _beside_a_live_jog(
    heavy: Heavy,
    *,
    min_bytes: int,
    prepare: Callable[[httpx.Client, str, dict[str, str]], None] | None = None,
) -> None:
    """Run ``heavy`` while a held client jogs with heartbeats; /health answers quickly
    throughout and the jog is still running at the end."""
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
                if prepare is not None:  # Before the jog: building the file is not measured.
                    prepare(http, api, h)
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
                        resp = heavy(c, api, h)
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
                assert result["bytes"] > min_bytes, result
                motion = http.get(f"{api}/sessions/{SID}/motion").json()
                assert motion["active"] and motion["kind"] == "jog", (motion, result, worst)
                assert worst < 0.25, (worst, result)
                print(f"worst /health {worst * 1000:.0f} ms during {result['seconds']:.1f} s of it")
                http.post(f"{api}/sessions/{SID}/motion/halt", json={}, headers=h)
            finally:
                stop.set()
                beats.join(1.0)
