"""The fleet page's query with 10 000 drives x 20 backups each, on SQLite and PostgreSQL,
against a plain sqlite3 / psycopg SELECT of the same rows in the same run (issue 49).

The store is generated: ``--drives`` drives (half of them with a plant tag, a third with an
approved backup, some drifted), ``--backups`` backups each, spread over the past year, whose
content comes from 40 distinct files (identical content is stored once, as the store does).
The fleet table is filled by the fleet's own first sync (timed: ``initial_sync_s``).

Per query kind, ``--n`` runs of each side, interleaved so that both see the same load:

- ``servodesk``: ``FleetStore.fleet(...)`` as GET /fleet runs it (its incremental sync of the
  backups made since the last look, the count and the page, rows turned into dicts);
- ``plain``: the same count and page SELECT, written out, on a plain sqlite3 / psycopg
  connection, every row fetched.

Kinds: ``page`` (the first 100), ``search`` (``q=press``), ``drifted`` (drift filter),
``deep`` (the last page, offset 9 900). Reported: p50 and p99 in ms, and p99 ratio servodesk /
plain. For
scale, ``aggregate_ms`` is the median of the query the fleet table saves: the newest backup
of every drive by GROUP BY over all backups.

PostgreSQL runs on ``--pg-url`` (a server's postgres database), else on a throw-away server
started here with Debian's initdb/pg_ctl (bench_store.py's), or is skipped (and says so).

    python bench/bench_fleet.py [--json] [--drives 10000] [--backups 20] [--n 300]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import hashlib
import json
import random
import sqlite3
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import sqlalchemy as sa

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_store import _fresh_pg, throwaway_postgres
from servodesk.services import db
from servodesk.services.fleet import FleetStore

PROFILES = ("cia402-generic", "hiwin-e", "smartris", "ctmm04x", "lecsn-t")
MACHINES = ("Press", "Saw", "Feed", "Weld", "Lift", "Mill", "Wrap", "Sort", "Cut", "Pack")
DAY = 86400.0

#: kind -> FleetStore.fleet keyword arguments.
KINDS: dict[str, dict[str, Any]] = {
    "page": {},
    "search": {"q": "press"},
    "drifted": {"drift": "drifted"},
    "deep": {"offset": -100},  # The last page: --drives - 100.
}


def generate(engine: sa.Engine, drives: int, per_drive: int, seed: int = 49) -> None:
    """The store's rows: content, backups, gateways; tags, approvals, drift states."""
    rng = random.Random(seed)
    contents = [rng.randbytes(10_000).hex().encode() for _ in range(40)]
    shas = [hashlib.sha256(c).hexdigest() for c in contents]
    now = time.time()
    with db.write(engine) as conn:
        conn.execute(
            sa.insert(db.backup_content),
            [{"sha256": s, "size": len(c), "data": c} for s, c in zip(shas, contents, strict=True)],
        )
        conn.execute(
            sa.insert(db.gateways),
            [
                {
                    "name": f"line-{g}",
                    "url": f"https://line{g}:8000",
                    "started": now,
                    "last_seen": now,
                }
                for g in range(20)
            ],
        )
        batch: list[dict[str, Any]] = []
        for d in range(drives):
            profile = PROFILES[d % len(PROFILES)]
            key = f"0000029A-{d % 7:08X}-{100000 + d}"
            identity = json.dumps({"vendor_id": 0x29A, "product_code": d % 7, "serial": 100000 + d})
            for b in range(per_drive):
                created = now - 365 * DAY + (b * 18 + rng.random() * 17) * DAY
                stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(created))
                batch.append(
                    {
                        "id": f"{stamp}-{d:05d}{b:02d}",
                        "time": time.strftime("%Y-%m-%dT%H:%M:%S.000Z", time.gmtime(created)),
                        "created": created,
                        "profile_id": profile,
                        "drive_key": key,
                        "identity": identity,
                        "firmware": f"{1 + b // 7}.{d % 10}",
                        "bus": "{}",
                        "entries": 300,
                        "file": f"{stamp}-{d:05d}{b:02d}-{profile}.json",
                        "sha256": shas[rng.randrange(len(shas))],
                        "source": "drive",
                        "unreadable": "[]",
                    }
                )
            if len(batch) >= 5000:
                conn.execute(sa.insert(db.backups), batch)
                batch = []
        if batch:
            conn.execute(sa.insert(db.backups), batch)


def annotate(engine: sa.Engine, drives: int, seed: int = 49) -> None:
    """Plant tags, gateways, approvals and drift states on the synced fleet table."""
    rng = random.Random(seed + 1)
    f = db.fleet_drives
    with db.read(engine) as conn:
        rows = conn.execute(sa.select(f.c.drive_key, f.c.last_backup).order_by(f.c.drive_key)).all()
    updates = []
    for i, (key, last) in enumerate(rows):
        approved = last if i % 3 == 0 else None
        state = rng.choice(("in_step", "in_step", "drifted")) if approved else "unknown"
        updates.append(
            {
                "k": key,
                "tag": f"L{i % 40}.{MACHINES[i % len(MACHINES)]}.{i}" if i % 2 == 0 else None,
                "gateway": f"line-{i % 20}",
                "session": f"cia402-generic-{i % 127 + 1}",
                "approved": approved,
                "state": state,
                "count": rng.randint(1, 9) if state == "drifted" else (0 if approved else None),
            }
        )
    stmt = (
        sa.update(f)
        .where(f.c.drive_key == sa.bindparam("k"))
        .values(
            plant_tag=sa.bindparam("tag"),
            gateway=sa.bindparam("gateway"),
            session=sa.bindparam("session"),
            approved_backup=sa.bindparam("approved"),
            approved_by="bench",
            approved_reason="generated",
            drift_state=sa.bindparam("state"),
            drift_count=sa.bindparam("count"),
        )
    )
    with db.write(engine) as conn:
        conn.execute(stmt, updates)
    assert len(rows) == drives, (len(rows), drives)


def plain_query(postgres: bool, kind: dict[str, Any]) -> tuple[str, str, list[Any]]:
    """The count and page SQL for the plain driver, with its parameters."""
    mark = "%s" if postgres else "?"
    where, params = [], []
    if kind.get("q"):
        pattern = f"%{kind['q'].lower()}%"
        cols = ("f.plant_tag", "f.drive_key", "f.serial", "f.profile_id")
        where.append("(" + " OR ".join(f"lower({c}) LIKE {mark}" for c in cols) + ")")
        params += [pattern] * len(cols)
    if kind.get("drift"):
        where.append(f"f.drift_state = {mark}")
        params.append(kind["drift"])
    clause = f" WHERE {' AND '.join(where)}" if where else ""
    count = f"SELECT count(*) FROM fleet_drives f{clause}"
    page = (
        "SELECT f.*, g.url AS gateway_url FROM fleet_drives f "
        f"LEFT OUTER JOIN gateways g ON f.gateway = g.name{clause} "
        "ORDER BY f.plant_tag IS NULL, f.plant_tag, f.drive_key "
        f"LIMIT 100 OFFSET {int(kind.get('offset', 0))}"
    )
    return count, page, params


def percentile(values: list[float], p: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(p / 100 * (len(ordered) - 1)))]


def run_engine(url: str, label: str, drives: int, per_drive: int, n: int) -> dict[str, Any]:
    engine = db.open_engine(url)
    postgres = db.is_postgres(engine)
    t0 = time.perf_counter()
    generate(engine, drives, per_drive)
    generate_s = time.perf_counter() - t0
    fleet = FleetStore(engine)
    t0 = time.perf_counter()
    fleet.sync()
    initial_sync_s = time.perf_counter() - t0
    annotate(engine, drives)
    if postgres:
        with db.write(engine) as conn:
            conn.execute(sa.text("ANALYZE"))

    if postgres:
        import psycopg

        plain_conn: Any = psycopg.connect(
            engine.url.set(drivername="postgresql").render_as_string(hide_password=False)
        )
    else:
        plain_conn = sqlite3.connect(str(engine.url.database), isolation_level=None)

    def plain(kind: dict[str, Any]) -> Callable[[], None]:
        count, page, params = plain_query(postgres, kind)

        def run() -> None:
            cur = plain_conn.cursor()
            cur.execute("BEGIN")
            cur.execute(count, params)
            total = cur.fetchone()[0]
            cur.execute(page, params)
            rows = cur.fetchall()
            cur.execute("COMMIT")
            assert total >= len(rows)

        return run

    out: dict[str, Any] = {
        "engine": label,
        "drives": drives,
        "backups": drives * per_drive,
        "n": n,
        "generate_s": round(generate_s, 1),
        "initial_sync_s": round(initial_sync_s, 2),
    }
    try:
        for name, kind in KINDS.items():
            if kind.get("offset", 0) < 0:
                kind = {**kind, "offset": drives + kind["offset"]}
            ours_t: list[float] = []
            plain_t: list[float] = []
            ours_run = functools.partial(fleet.fleet, limit=100, **kind)
            plain_run = plain(kind)
            expected = fleet.fleet(limit=100, **kind)
            assert expected["drives"], f"{name}: no rows"
            for _ in range(5):  # Warm both (caches, prepared plans).
                ours_run()
                plain_run()
            for _ in range(n):
                t = time.perf_counter()
                ours_run()
                ours_t.append((time.perf_counter() - t) * 1000)
                t = time.perf_counter()
                plain_run()
                plain_t.append((time.perf_counter() - t) * 1000)
            p99_ours, p99_plain = percentile(ours_t, 99), percentile(plain_t, 99)
            out[name] = {
                "total": expected["total"],
                "servodesk_p50_ms": round(statistics.median(ours_t), 2),
                "servodesk_p99_ms": round(p99_ours, 2),
                "plain_p50_ms": round(statistics.median(plain_t), 2),
                "plain_p99_ms": round(p99_plain, 2),
                "p99_ratio": round(p99_ours / p99_plain, 2),
            }
        b = db.backups
        aggregate = sa.select(b.c.drive_key, sa.func.max(b.c.created)).group_by(b.c.drive_key)
        times = []
        for _ in range(5):
            t = time.perf_counter()
            with db.read(engine) as conn:
                conn.execute(aggregate).all()
            times.append((time.perf_counter() - t) * 1000)
        out["aggregate_ms"] = round(statistics.median(times), 1)
    finally:
        plain_conn.close()
        engine.dispose()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--drives", type=int, default=10_000)
    ap.add_argument("--backups", type=int, default=20, help="backups per drive")
    ap.add_argument("--n", type=int, default=300, help="runs of each query kind and side")
    ap.add_argument("--pg-url", default=None, help="a PostgreSQL server (its postgres database)")
    args = ap.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix="servodesk-bench-fleet-") as tmp:
        results.append(
            run_engine(db.store_url(Path(tmp)), "sqlite", args.drives, args.backups, args.n)
        )
    with contextlib.ExitStack() as stack:
        server = args.pg_url or stack.enter_context(throwaway_postgres())
        if server:
            url = _fresh_pg(server, "fleet")
            results.append(run_engine(url, "postgresql", args.drives, args.backups, args.n))
        else:
            results.append({"engine": "postgresql", "skipped": "no initdb and no --pg-url"})
    if args.json:
        print(json.dumps({"bench": "fleet", "results": results}, indent=1))
        return
    for r in results:
        if "skipped" in r:
            print(f"{r['engine']}: skipped ({r['skipped']})")
            continue
        print(
            f"{r['engine']}: {r['drives']} drives, {r['backups']} backups; first sync "
            f"{r['initial_sync_s']} s; GROUP BY over the backups {r['aggregate_ms']} ms"
        )
        for k in KINDS:
            v = r[k]
            print(
                f"  {k:8s} ({v['total']:5d}) servodesk p50 {v['servodesk_p50_ms']:7.2f} "
                f"p99 {v['servodesk_p99_ms']:7.2f} ms  plain p50 {v['plain_p50_ms']:7.2f} "
                f"p99 {v['plain_p99_ms']:7.2f} ms  p99 ratio {v['p99_ratio']:.2f}"
            )


if __name__ == "__main__":
    main()
