"""The store's writes on SQLite and PostgreSQL against a plain driver loop (issue 49).

Per engine, three kinds of change, each one transaction as servodesk makes them:

- ``backup``: a new 20 kB backup file (write_new_file) and ``Store.add_backup`` (content row
  and record); plain: the same file written the same way, then the two INSERTs in one
  transaction with sqlite3 / psycopg.
- ``item``: ``Store.set_item`` (a restore item's status, committed before the next write goes
  to the drive); plain: the UPDATE in its own transaction.
- ``audit``: ``AuditLog.record`` then ``flush`` (one record per transaction, the chain's lock
  and head read included); plain: lock (PostgreSQL advisory / SQLite BEGIN IMMEDIATE),
  SELECT of the head, sha256 and INSERT per transaction.

Ratios are servodesk's rate / the plain loop's, measured in the same run. PostgreSQL runs on
``--pg-url`` (an empty database), else on a throw-away server started here with Debian's
initdb/pg_ctl (as tests/store/conftest.py does), or is skipped (and says so).

    python bench/bench_store.py [--json] [--n 200] [--pg-url postgresql://...]
"""

from __future__ import annotations

import argparse
import contextlib
import glob
import hashlib
import json
import os
import pwd
import shutil
import socket
import sqlite3
import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from servodesk.services import db
from servodesk.services.audit import GENESIS, Actor, AuditLog, chain_hash
from servodesk.services.store import Store, write_new_file


def _info(bid: str, name: str, data: bytes) -> dict[str, Any]:
    return {
        "id": bid,
        "time": "2026-12-07T08:00:00Z",
        "label": "",
        "note": "",
        "profile_id": "cia402-generic",
        "profile_version": "1",
        "drive_key": "v-p-s",
        "identity": {},
        "firmware": None,
        "bus": {},
        "entries": 300,
        "file": name,
        "sha256": hashlib.sha256(data).hexdigest(),
        "unreadable": [],
    }


def _rate(n: int, body: Callable[[int], None]) -> float:
    t0 = time.perf_counter()
    for i in range(n):
        body(i)
    return n / (time.perf_counter() - t0)


def servodesk_rates(work: Path, url: str, n: int) -> dict[str, float]:
    store = Store(work / "sd", url)
    log = AuditLog(store.url)
    payload = os.urandom(10_000).hex().encode()

    def backup(i: int) -> None:
        data = b"%d" % i + payload
        name = f"sd-{i}.json"
        write_new_file(store.backup_file(name), data)
        store.add_backup(_info(f"sd-{i}", name, data))

    items = [
        {"address": f"0x2000:{i:02x}", "source": "b", "name": "n", "status": "pending"}
        for i in range(n)
    ]
    meta = {"id": "r", "backup": "b", "session": "s", "drive_key": "k", "bus": {}, "time": "t"}
    store.add_restore({**meta, "dry_run": False, "options": {}}, items)

    def item(i: int) -> None:
        store.set_item("r", i, status="written", old_raw_hex="00")

    def audit(i: int) -> None:
        log.record("write.parameter", who=Actor("bench"), drive="k", details={"i": i})
        log.flush(30)

    try:
        return {"backup": _rate(n, backup), "item": _rate(n, item), "audit": _rate(n, audit)}
    finally:
        log.close()
        store.close()


def plain_rates(work: Path, url: str, n: int) -> dict[str, float]:
    """The same rows with the bare driver, on a database servodesk made (same schema)."""
    Store(work / "plain", url).close()
    backups_dir = work / "plain" / "backups"
    postgres = url.startswith("postgresql")
    if postgres:
        import psycopg

        conn: Any = psycopg.connect(url)
        ph = "%s"
    else:
        conn = sqlite3.connect(work / "plain" / db.SQLITE_FILE, isolation_level=None)
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute("PRAGMA synchronous=FULL")
        ph = "?"

    @contextlib.contextmanager
    def tx() -> Iterator[Any]:
        if postgres:
            with conn.transaction():
                yield conn
        else:
            conn.execute("BEGIN IMMEDIATE")
            yield conn
            conn.execute("COMMIT")

    payload = os.urandom(10_000).hex().encode()
    cols = list(_info("x", "x", b"").keys())[:-1]

    def backup(i: int) -> None:
        data = b"%d" % i + payload
        name = f"pl-{i}.json"
        write_new_file(backups_dir / name, data)
        info = _info(f"pl-{i}", name, data)
        values = [json.dumps(info[c]) if c in ("identity", "bus") else info[c] for c in cols]
        with tx() as c:
            c.execute(
                f"INSERT INTO backup_content (sha256, size, data) VALUES ({ph},{ph},{ph})"
                " ON CONFLICT DO NOTHING",
                (info["sha256"], len(data), data),
            )
            c.execute(
                f"INSERT INTO backups ({', '.join(cols)}, created, source, unreadable) "
                f"VALUES ({', '.join([ph] * len(cols))}, {ph}, 'drive', '[]')",
                (*values, time.time()),
            )

    with tx() as c:
        for i in range(n):
            c.execute(
                "INSERT INTO restore_items (restore, seq, address, source, name, status) "
                f"VALUES ('r', {ph}, 'a', 'b', 'n', 'pending')",
                (i,),
            )

    def item(i: int) -> None:
        with tx() as c:
            c.execute(
                f"UPDATE restore_items SET status = {ph}, old_raw_hex = {ph} "
                f"WHERE restore = 'r' AND seq = {ph}",
                ("written", "00", i),
            )

    def audit(i: int) -> None:
        with tx() as c:
            if postgres:
                c.execute("SELECT pg_advisory_xact_lock(%s)", (db.LOCK_AUDIT_CHAIN,))
            last = c.execute("SELECT seq, hash FROM audit_log ORDER BY seq DESC LIMIT 1").fetchone()
            seq, prev = (last[0] + 1, last[1]) if last else (1, GENESIS)
            row = (seq, "2026-12-07T08:00:00.000000Z", "bench", "", "write", "write.parameter")
            row += ("k", "success", "", json.dumps({"i": i}))
            c.execute(
                'INSERT INTO audit_log (seq, time, "user", address, category, event, drive, '
                f"result, message, details, prev, hash) VALUES ({', '.join([ph] * 12)})",
                (*row, prev, chain_hash(prev, row)),
            )

    try:
        return {"backup": _rate(n, backup), "item": _rate(n, item), "audit": _rate(n, audit)}
    finally:
        conn.close()


@contextlib.contextmanager
def throwaway_postgres() -> Iterator[str | None]:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    if not found:
        yield None
        return
    bindir = Path(found[-1]).parent
    base = Path(tempfile.mkdtemp(prefix="servodesk-bench-pg-"))
    prefix: list[str] = []
    if os.geteuid() == 0:
        pw = pwd.getpwnam("postgres")
        os.chown(base, pw.pw_uid, pw.pw_gid)
        prefix = ["runuser", "-u", "postgres", "--"]
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    data = str(base / "data")
    run: dict[str, Any] = {"check": True, "capture_output": True, "timeout": 180}
    subprocess.run(
        [*prefix, str(bindir / "initdb"), "-D", data, "-U", "bench", "--auth=trust"], **run
    )
    opts = f"-p {port} -c listen_addresses=127.0.0.1 -c unix_socket_directories={base}"
    subprocess.run(
        [
            *prefix,
            str(bindir / "pg_ctl"),
            "-D",
            data,
            "-o",
            opts,
            "-w",
            "-l",
            f"{base}/log",
            "start",
        ],
        **run,
    )
    try:
        yield f"postgresql://bench@127.0.0.1:{port}/postgres"
    finally:
        subprocess.run(
            [*prefix, str(bindir / "pg_ctl"), "-D", data, "-m", "fast", "-w", "stop"],
            check=False,
            capture_output=True,
        )
        shutil.rmtree(base, ignore_errors=True)


def _fresh_pg(server: str, name: str) -> str:
    import psycopg

    with psycopg.connect(server, autocommit=True) as c:
        c.execute(f'DROP DATABASE IF EXISTS "{name}"')
        c.execute(f'CREATE DATABASE "{name}"')
    return server.rsplit("/", 1)[0] + "/" + name


def run_engine(server: str | None, label: str, n: int, rounds: int) -> dict[str, Any]:
    ours: dict[str, list[float]] = {"backup": [], "item": [], "audit": []}
    plain: dict[str, list[float]] = {"backup": [], "item": [], "audit": []}
    for r in range(rounds):
        with tempfile.TemporaryDirectory(prefix="servodesk-bench-store-") as tmp:
            work = Path(tmp)
            url_a = _fresh_pg(server, f"sd{r}") if server else ""
            url_b = _fresh_pg(server, f"pl{r}") if server else ""
            for k, v in servodesk_rates(work, url_a, n).items():
                ours[k].append(v)
            for k, v in plain_rates(work, url_b or db.store_url(work / "plain"), n).items():
                plain[k].append(v)
    out: dict[str, Any] = {"engine": label, "n": n, "rounds": rounds}
    for k in ours:
        a, b = statistics.median(ours[k]), statistics.median(plain[k])
        out[k] = {
            "servodesk_per_s": round(a, 1),
            "plain_per_s": round(b, 1),
            "ratio": round(a / b, 2),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--pg-url", default=None, help="a PostgreSQL server (its postgres database)")
    args = ap.parse_args()
    results = [run_engine(None, "sqlite", args.n, args.rounds)]
    with contextlib.ExitStack() as stack:
        server = args.pg_url or stack.enter_context(throwaway_postgres())
        if server:
            results.append(run_engine(server, "postgresql", args.n, args.rounds))
        else:
            results.append({"engine": "postgresql", "skipped": "no initdb and no --pg-url"})
    if args.json:
        print(json.dumps({"bench": "store", "results": results}, indent=1))
        return
    for r in results:
        if "skipped" in r:
            print(f"{r['engine']}: skipped ({r['skipped']})")
            continue
        for k in ("backup", "item", "audit"):
            v = r[k]
            print(
                f"{r['engine']:10s} {k:7s} servodesk {v['servodesk_per_s']:8.1f}/s  "
                f"plain {v['plain_per_s']:8.1f}/s  ratio {v['ratio']:.2f}"
            )


if __name__ == "__main__":
    main()
