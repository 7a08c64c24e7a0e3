"""Dead-man latency: from the last heartbeat to the stop command on the bus, and to standstill.

A backend with a simulated drive on a python-can virtual bus; a client holds control, jogs
with heartbeats over the WebSocket, then stops sending them. A plain python-can Bus on the
same channel timestamps the first controlword download carrying halt (bit 8) or quick stop;
the simulated drive tells when the axis stands (|velocity| within 606Fh, 1000 inc/s). The
figures include the configured dead-man time (SERVODESK_DEADMAN_MS, 250 ms by default);
``over_deadline`` is what the backend adds to it. The cases, in the same process: the event
loop idle (the baseline); the loop held from the last heartbeat on for ``--hold-s``, as a
heavy request would hold it (the dead-man's thread must not wait for it: services/deadman.py);
and each heavy request of issue "Motion safety" item 3 really in flight from the last
heartbeat on: POST /scope/import of a 10 MB CSV, GET of a 30 MB backup (the upload limit
is 32 MiB), POST /compare of it with itself, and a restore preflight of it (api/offload.py
and api/backup_documents.py move their parsing off the loop; the server shares this process,
so they compete for its GIL as in `servodesk serve`).

    python bench/bench_deadman.py [--runs 20] [--deadman-ms 250] [--velocity 200000]
        [--hold-s 1] [--cases idle,loop_held,scope_import,backup_get,compare,preflight] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from typing import Any

import can
from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.benchmarks.documents import big_csv, padded_backup
from servodesk.settings import Settings

SID = "cia402-generic-1"
NODE = 1
STANDSTILL = 1000


class Spy:
    """First halt / quick-stop controlword download to the node, with its bus timestamp."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.stops: list[float] = []
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            m = self.bus.recv(0.05)
            if m is None or m.arbitration_id != 0x600 + NODE or len(m.data) < 6:
                continue
            if m.data[0] & 0xE0 != 0x20 or m.data[1:4] != b"\x40\x60\x00":
                continue
            word = int.from_bytes(m.data[4:6], "little")
            if word & 0x0100 or word & 0x0086 == 0x0002:
                self.stops.append(m.timestamp)

    def close(self) -> None:
        self._stop.set()
        self._t.join(1.0)
        self.bus.shutdown()


#: A request run from the last heartbeat on (None: the loop left alone).
Load = Callable[[], None] | None


def one_run(
    client: TestClient, ws: Any, drive: Any, spy: Spy, velocity: int, h: dict[str, str], load: Load
) -> dict[str, float]:
    r = client.post(f"/api/v1/sessions/{SID}/state", json={"command": "enable"}, headers=h)
    r.raise_for_status()
    r = client.post(
        f"/api/v1/sessions/{SID}/motion/jog",
        json={"velocity": velocity, "acceleration": 10 * abs(velocity)},
        headers=h,
    )
    r.raise_for_status()
    last = 0.0
    end = time.monotonic() + 0.3
    while time.monotonic() < end:
        last = time.time()
        ws.send_json({"type": "heartbeat", "session": SID})
        time.sleep(0.05)
    n = len(spy.stops)
    holder = None
    if load is not None:
        holder = threading.Thread(target=load)
        holder.start()
    t_end = time.monotonic() + 3.0
    standstill = None
    while time.monotonic() < t_end:
        if standstill is None and abs(drive.velocity) <= STANDSTILL and len(spy.stops) > n:
            standstill = time.time()
            break
        time.sleep(0.0005)
    if holder is not None:
        holder.join(120)
    if standstill is None or len(spy.stops) <= n:
        status = client.get(f"/api/v1/sessions/{SID}/motion").json()
        raise RuntimeError(
            f"the dead-man did not stop the axis: v={drive.velocity:.0f}, "
            f"stops {len(spy.stops)} (before {n}), motion {status}"
        )
    return {
        "to_bus_ms": (spy.stops[n] - last) * 1000.0,
        "to_standstill_ms": (standstill - last) * 1000.0,
    }


def big_backup(client: TestClient, h: dict[str, str], megabytes: float) -> str:
    """A backup of the drive made ``megabytes`` large and stored; its id.

    Padded with unreadable entries (what a drive with many aborting objects gives, LECSN-T:
    541), so its size is structure to parse, as in a large real backup, not one long string.
    """
    r = client.post(f"/api/v1/sessions/{SID}/backups", json={"label": "bench"}, headers=h)
    r.raise_for_status()
    doc = client.get(f"/api/v1/backups/{r.json()['id']}").json()
    body = padded_backup(doc, megabytes)
    r = client.post(
        "/api/v1/backups/upload?filename=big.json",
        content=body,
        headers={"Content-Type": "application/json"},
    )
    r.raise_for_status()
    return str(r.json()["id"])


def loads(client: TestClient, h: dict[str, str], hold: float, cases: list[str]) -> dict[str, Load]:
    """Each case's load, built once (the files) and run in each of its runs."""
    out: dict[str, Load] = {}

    def ok(r: Any) -> None:
        if r.status_code >= 400:
            raise RuntimeError(
                f"{r.request.method} {r.request.url.path}: {r.status_code} {r.text[:200]}"
            )

    if "idle" in cases:
        out["idle"] = None
    if "loop_held" in cases:
        out["loop_held"] = lambda: client.portal.call(time.sleep, hold)
    if "scope_import" in cases:
        csv = big_csv(10.0)
        out["scope_import"] = lambda: ok(
            client.post(
                "/api/v1/scope/import?filename=big.csv",
                files={"file": ("big.csv", csv, "text/csv")},
            )
        )
    if {"backup_get", "compare", "preflight"} & set(cases):
        bid = big_backup(client, h, 30.0)  # The upload limit is 32 MiB.
        src = {"kind": "backup", "id": bid}
        out["backup_get"] = lambda: ok(client.get(f"/api/v1/backups/{bid}"))
        out["compare"] = lambda: ok(client.post("/api/v1/compare", json={"a": src, "b": src}))
        out["preflight"] = lambda: ok(
            client.post(f"/api/v1/sessions/{SID}/restore/preflight", json={"backup": bid})
        )
    return {c: out[c] for c in cases}


def summary(values: list[float]) -> dict[str, float]:
    return {
        "median": round(statistics.median(values), 2),
        "worst": round(max(values), 2),
        "best": round(min(values), 2),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--deadman-ms", type=int, default=250)
    ap.add_argument("--velocity", type=int, default=200_000, help="jog velocity, inc/s")
    ap.add_argument(
        "--hold-s", type=float, default=1.0, help="how long the loop is held in the second case"
    )
    ap.add_argument(
        "--cases",
        default="idle,loop_held,scope_import,backup_get,compare,preflight",
        help="comma-separated; the first is the baseline the others are compared with",
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    known = {"idle", "loop_held", "scope_import", "backup_get", "compare", "preflight"}
    if not cases or set(cases) - known:
        ap.error(f"--cases: each of {sorted(known)}")
    channel = f"bench-deadman-{os.getpid()}"
    spy = Spy(channel)
    runs: dict[str, list[dict[str, float]]] = {c: [] for c in cases}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            settings = Settings(
                sim=True,
                sim_channel=channel,
                sim_profiles="cia402-generic",
                data_dir=tmp,
                deadman_ms=args.deadman_ms,
                viewer_port=0,  # No 3D viewer: it would only compete for the CPU.
                allowed_hosts="testserver",  # Starlette's TestClient's Host (api/hosts.py).
            )
            app = create_app(settings)
            with TestClient(app) as client:
                drive = app.state.servodesk.sim.drives[0]
                r = client.post(
                    f"/api/v1/sessions/{SID}/control",
                    json={"action": "take"},
                    headers={"X-Servodesk-Client": "bench"},
                )
                r.raise_for_status()
                token = r.json()["token"]
                h = {"X-Servodesk-Client": "bench", "X-Servodesk-Control": token}
                with client.websocket_connect("/api/v1/ws?client=bench") as ws:
                    ws.send_json({"type": "bind", "session": SID, "token": token})
                    while ws.receive_json().get("type") != "bind":
                        pass
                    for case, load in loads(client, h, args.hold_s, cases).items():
                        for i in range(args.runs):
                            # Alternate directions: the axis stays clear of the simulated
                            # limit switches.
                            v = args.velocity if i % 2 == 0 else -args.velocity
                            runs[case].append(one_run(client, ws, drive, spy, v, h, load))
                            time.sleep(0.05)
    finally:
        spy.close()
    result: dict[str, Any] = {
        "runs": args.runs,
        "deadman_ms": args.deadman_ms,
        "velocity": args.velocity,
        "hold_s": args.hold_s,
    }
    for case, rs in runs.items():
        bus = [r["to_bus_ms"] for r in rs]
        still = [r["to_standstill_ms"] for r in rs]
        result[case] = {
            "heartbeat_to_stop_on_bus_ms": summary(bus),
            "heartbeat_to_standstill_ms": summary(still),
            "over_deadline_ms": summary([b - args.deadman_ms for b in bus]),
        }
    # Each case against the first (the idle loop), run in the same process.
    base = result[cases[0]]["heartbeat_to_stop_on_bus_ms"]["median"]
    result["median_ratio_to_" + cases[0]] = {
        c: round(result[c]["heartbeat_to_stop_on_bus_ms"]["median"] / base, 3) for c in cases
    }
    result["worst_stop_on_bus_ms"] = max(
        result[c]["heartbeat_to_stop_on_bus_ms"]["worst"] for c in cases
    )
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"dead-man {args.deadman_ms} ms, {args.runs} runs a case, jog {args.velocity} inc/s")
        for case in runs:
            b = result[case]["heartbeat_to_stop_on_bus_ms"]
            s_ = result[case]["heartbeat_to_standstill_ms"]
            print(
                f"  {case}: last heartbeat -> stop on the bus: median {b['median']} ms, "
                f"worst {b['worst']}; -> standstill: median {s_['median']} ms, worst {s_['worst']}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
