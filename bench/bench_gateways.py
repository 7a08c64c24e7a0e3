"""Several gateways on one store: backups per second from N ``servodesk serve --sim`` processes
at once, each backing up its five twins, and the drift check's time per drive (issue 49).

Each gateway is a real ``servodesk serve --sim`` process (its five twins: cia402-generic,
HIWIN E and smartris on its own virtual CAN bus, CTMM04x on SLMP, LECSN-T on PROFINET, each
on ephemeral ports), all on one PostgreSQL store (a throw-away server, bench_store.py's), as
docs/deployment.md sets gateways up. Per round every gateway backs up all its drives at once
(``POST /sessions/{sid}/backups``), the gateways at the same time. Then each drive's first
backup is approved and its drift checked on demand (``POST /sessions/{sid}/drift``: every
parameter read again and compared with the approved backup), timed per drive.

Against, in the same run on the same server: a plain psycopg loop that inserts the same number
of backup rows (content and record, bench_store.py's ``plain_rates``) and one that selects
the approved backups' content. Their ratio says how much of a gateway's time is the store's:
the rest is the drives' buses. SQLite runs the same with one gateway (a SQLite store is
one machine's).

    python bench/bench_gateways.py [--json] [--gateways 4] [--rounds 3]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import httpx

from servodesk.services import db

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_store import _fresh_pg, plain_rates, throwaway_postgres

REPO = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def gateway(name: str, store_url: str, work: Path) -> Iterator[str]:
    """A ``servodesk serve --sim`` process named ``name`` on ``store_url``; yields its URL."""
    port = _free_port()
    data = work / name
    data.mkdir(parents=True)
    env = {
        **os.environ,
        "PYTHONPATH": str(REPO / "backend"),
        "SERVODESK_DATA_DIR": str(data),
        "SERVODESK_STORE_URL": store_url,
        "SERVODESK_GATEWAY_NAME": name,
        "SERVODESK_GATEWAY_URL": f"http://127.0.0.1:{port}",
        "SERVODESK_SIM_CHANNEL": f"bench-{name}-{os.getpid()}",
        "SERVODESK_VIEWER_PORT": "0",
    }
    log = (work / f"{name}.log").open("w")
    cmd = [sys.executable, "-m", "servodesk", "serve", "--sim", "--port", str(port)]
    proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"gateway {name} exited: {(work / f'{name}.log').read_text()}")
            try:
                if httpx.get(f"{base}/api/v1/health", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"gateway {name} did not start in 90 s")
            time.sleep(0.3)
        yield base
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


def _pct(values: list[float], p: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(p / 100 * (len(s) - 1)))]


async def _sessions(c: httpx.AsyncClient) -> list[str]:
    for _ in range(60):
        r = await c.get("/api/v1/sessions")
        sids = [s["id"] for s in r.json()]
        if len(sids) >= 5:
            return sids
        await asyncio.sleep(0.5)
    raise RuntimeError(f"{c.base_url}: {len(sids)} sessions, not 5")


async def measure(bases: list[str], rounds: int) -> dict[str, Any]:
    clients = [
        httpx.AsyncClient(base_url=b, timeout=120, headers={"X-Servodesk-Client": "bench"})
        for b in bases
    ]
    try:
        sids = await asyncio.gather(*(_sessions(c) for c in clients))
        latencies: list[float] = []
        made: dict[tuple[int, str], str] = {}

        async def one(g: int, sid: str, label: str) -> None:
            t0 = time.perf_counter()
            r = await clients[g].post(f"/api/v1/sessions/{sid}/backups", json={"label": label})
            latencies.append(time.perf_counter() - t0)
            if r.status_code != 201:
                raise RuntimeError(f"backup of {sid} on {bases[g]}: {r.status_code} {r.text}")
            made.setdefault((g, sid), r.json()["id"])

        walls = []
        for n in range(rounds):
            t0 = time.perf_counter()
            await asyncio.gather(
                *(one(g, sid, f"round {n}") for g in range(len(clients)) for sid in sids[g])
            )
            walls.append(time.perf_counter() - t0)
        count = sum(len(s) for s in sids)

        # The drift check per drive: approve its first backup, then check it on demand.
        drift_s: list[float] = []
        for (g, sid), bid in made.items():
            c = clients[g]
            fleet = (await c.get("/api/v1/fleet", params={"q": sid.rsplit("-", 1)[0]})).json()
            # A drive is one row across gateways (vendor-product-serial): the HIWIN twins
            # all have serial 1 and are one drive that the last gateway to back it up holds.
            key = next(
                (
                    d["drive_key"]
                    for d in fleet["drives"]
                    if d["session"] == sid and d["gateway"] == f"gw{g}"
                ),
                None,
            )
            if key is None:
                continue
            body = {"drive": key, "backup": bid, "reason": "bench"}
            r = await c.put("/api/v1/fleet/approved", json=body)
            if r.status_code != 200:
                raise RuntimeError(f"approve {key}: {r.status_code} {r.text}")
            t0 = time.perf_counter()
            r = await c.post(f"/api/v1/sessions/{sid}/drift")
            drift_s.append(time.perf_counter() - t0)
            if r.status_code != 200 or r.json()["state"] != "in_step":
                raise RuntimeError(f"drift of {sid}: {r.status_code} {r.text}")
        return {
            "gateways": len(bases),
            "drives": count,
            "rounds": rounds,
            "backups_per_s": round(count / statistics.median(walls), 2),
            "backup_latency_p50_s": round(_pct(latencies, 50), 3),
            "backup_latency_p99_s": round(_pct(latencies, 99), 3),
            "drift_checked_drives": len(drift_s),
            "drift_check_p50_s": round(_pct(drift_s, 50), 3),
            "drift_check_p99_s": round(_pct(drift_s, 99), 3),
        }
    finally:
        for c in clients:
            await c.aclose()


def run_engine(label: str, urls: list[str], plain_url: str, rounds: int) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="servodesk-bench-gw-") as tmp, ExitStack() as stack:
        work = Path(tmp)
        bases = [stack.enter_context(gateway(f"gw{i}", u, work)) for i, u in enumerate(urls)]
        ours = asyncio.run(measure(bases, rounds))
        plain_url = plain_url or db.store_url(work / "plain")
        plain = plain_rates(work, plain_url, max(20, ours["drives"] * rounds))
    ours["engine"] = label
    ours["plain_backup_rows_per_s"] = round(plain["backup"], 1)
    ours["backups_over_plain"] = round(ours["backups_per_s"] / plain["backup"], 4)
    return ours


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--gateways", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    out: dict[str, Any] = {"python": sys.version.split()[0], "cpus": os.cpu_count()}
    with throwaway_postgres() as server:
        if server is None:
            out["postgresql"] = "skipped: no initdb (apt-get install postgresql)"
        else:
            store = _fresh_pg(server, "fleet")
            urls = [store] * args.gateways
            out["postgresql"] = run_engine(
                "postgresql", urls, _fresh_pg(server, "plain"), args.rounds
            )
    out["sqlite"] = run_engine("sqlite", [""], "", args.rounds)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for k in ("postgresql", "sqlite"):
            print(k, out[k])


if __name__ == "__main__":
    main()
