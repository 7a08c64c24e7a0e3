"""A gateway that loses its central PostgreSQL store keeps working on a local queue and syncs
when the store returns, and says so (issue 49; services/outbox.py, docs/deployment.md "When
the central store is unreachable").

The loss is real: the gateway reaches the throw-away PostgreSQL of tests/store/conftest.py
through a TCP relay that the test cuts (every connection closed, new ones refused) and
restores, as a broken network between a line PC and the central database would.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import itertools
import os
import socket
import sqlite3
import threading
import time
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import httpx
import psycopg
import pytest
import sqlalchemy as sa

from servodesk.api.app import create_app
from servodesk.api.state import AppState, state_of
from servodesk.services import db
from servodesk.services.audit import AuditLog, utc_now
from servodesk.services.outbox import OUTBOX_FILE, Outbox
from servodesk.settings import Settings
from tests.control_helpers import take_control
from tests.store.conftest import PgServer

_n = itertools.count()
SID = "cia402-generic-1"
RETRY_S = 0.3


class Relay:
    """A TCP relay 127.0.0.1:port -> the PostgreSQL server; :meth:`cut` closes every
    connection and refuses new ones (ECONNREFUSED), :meth:`restore` listens again."""

    def __init__(self, target_port: int) -> None:
        self.target = target_port
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = int(s.getsockname()[1])
        self._socks: list[socket.socket] = []
        self._lock = threading.Lock()
        self._listener: socket.socket | None = None
        self.restore()

    def restore(self) -> None:
        lst = socket.socket()
        lst.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        lst.bind(("127.0.0.1", self.port))
        lst.listen(64)
        self._listener = lst
        threading.Thread(target=self._accept, args=(lst,), daemon=True).start()

    def cut(self) -> None:
        lst, self._listener = self._listener, None
        if lst is not None:
            with contextlib.suppress(OSError):
                lst.shutdown(socket.SHUT_RDWR)
            lst.close()
        with self._lock:
            socks, self._socks = self._socks, []
        for s in socks:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()

    def _accept(self, lst: socket.socket) -> None:
        while True:
            try:
                client, _ = lst.accept()
            except OSError:
                return
            try:
                upstream = socket.create_connection(("127.0.0.1", self.target))
            except OSError:
                client.close()
                continue
            with self._lock:
                self._socks += [client, upstream]
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    @staticmethod
    def _pump(a: socket.socket, b: socket.socket) -> None:
        try:
            while data := a.recv(65536):
                b.sendall(data)
        except OSError:
            pass
        finally:
            for s in (a, b):
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)


@pytest.fixture
def relayed(pg_server: PgServer) -> Iterator[tuple[str, str, Relay]]:
    """(the URL through the relay, the direct URL, the relay) of a fresh database."""
    direct = pg_server.new_database()
    relay = Relay(pg_server.port)
    name = direct.rsplit("/", 1)[1]
    try:
        yield f"postgresql://servodesk@127.0.0.1:{relay.port}/{name}", direct, relay
    finally:
        relay.cut()


@contextlib.asynccontextmanager
async def serving(data_dir: Path, url: str) -> AsyncIterator[tuple[Any, httpx.AsyncClient]]:
    app = create_app(
        Settings(
            sim=True,
            sim_slmp="",
            sim_profinet="",
            sim_channel=f"outbox-{os.getpid()}-{next(_n)}",
            sim_profiles="cia402-generic",
            data_dir=data_dir,
            store_url=url,
            viewer_port=0,
            store_retry_s=RETRY_S,
        )
    )
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(
            transport=transport, base_url="http://test/api/v1", timeout=60
        ) as c:
            yield app, c


async def _status(c: httpx.AsyncClient) -> dict[str, Any]:
    r = await c.get("/status")
    assert r.status_code == 200, r.text
    store: dict[str, Any] = r.json()["store"]
    return store


async def _drained(c: httpx.AsyncClient, within: float = 30.0) -> dict[str, Any]:
    deadline = time.monotonic() + within
    while True:
        store = await _status(c)
        if store["reachable"] and not any(store["queued"].values()):
            return store
        assert time.monotonic() < deadline, f"the queue did not drain: {store}"
        await asyncio.sleep(RETRY_S)


async def _backup(c: httpx.AsyncClient, label: str) -> dict[str, Any]:
    r = await c.post(f"/sessions/{SID}/backups", json={"label": label})
    assert r.status_code == 201, r.text
    out: dict[str, Any] = r.json()
    return out


def _central(direct: str, statement: str) -> list[tuple[Any, ...]]:
    with psycopg.connect(direct.replace("postgresql://", "postgresql://", 1)) as conn:
        return list(conn.execute(statement).fetchall())


def _tuning_row(rid: str) -> dict[str, Any]:
    now = time.time()
    return {
        "id": rid, "drive_key": "0x1-0x2-0x3", "session": SID, "kind": "own", "mode": "basic",
        "status": "done", "started": now - 5, "ended": now, "by": "local", "client": "t",
        "applied": False, "result": {"pm_deg": 47.0},
    }  # fmt: skip


@pytest.mark.asyncio
async def test_offline_work_is_queued_shown_and_synced_when_the_store_returns(
    relayed: tuple[str, str, Relay], tmp_path: Path
) -> None:
    url, direct, relay = relayed
    async with serving(tmp_path, url) as (app, c):
        state: AppState = state_of(app)
        online = await _backup(c, "online")
        assert online["queued"] is False
        assert (await _status(c))["reachable"] is True

        relay.cut()
        offline = await _backup(c, "offline")
        assert offline["queued"] is True
        # The backup opens by its id while the store is away (from the queue).
        r = await c.get(f"/backups/{offline['id']}")
        assert r.status_code == 200, r.text
        # Audited actions: taking and releasing control.
        token = await take_control(c, SID, "offline-client")
        assert token
        # A restore of a backup the queue does not hold needs the central store: refused with
        # 503 before anything is written to the drive.
        r = await c.post(
            f"/sessions/{SID}/restore",
            json={"backup": online["id"]},
            headers={"X-Servodesk-Client": "offline-client"},
        )
        assert r.status_code == 503, r.text
        assert "cannot be reached" in r.json()["message"]
        r = await c.post(
            f"/sessions/{SID}/control",
            json={"action": "release"},
            headers={"X-Servodesk-Client": "offline-client"},
        )
        assert r.status_code == 200, r.text
        await asyncio.to_thread(state.tuning_results.add, _tuning_row("t-offline-1"))
        assert await asyncio.to_thread(state.audit.flush, 30.0)

        store = await _status(c)
        assert store["engine"] == "postgresql" and store["reachable"] is False
        assert store["since"] is not None and store["last_error"]
        assert store["queued"]["backups"] == 1 and store["queued"]["tuning_results"] == 1
        assert store["queued"]["audit_log"] >= 3  # backup.created, control.taken/released

        # What needs the central store says so: 503 naming it, never a 500.
        for path in (
            "/fleet",
            "/fleet/drift",
            "/backups",
            f"/sessions/{SID}/tuning/results",
            f"/sessions/{SID}/scope/captures",
        ):
            r = await c.get(path)
            assert r.status_code == 503, (path, r.text)
            assert f"127.0.0.1:{relay.port}" in r.json()["message"], (path, r.text)
            assert "local queue" in r.json()["hint"]

        # An audit read needs the central log: 503, not a 500.
        r = await c.get("/audit/verify")
        assert r.status_code == 503, r.text

        restored = utc_now()
        relay.restore()
        store = await _drained(c)
        assert store["last_sync"] is not None and store["synced"] >= 5
        verdict = await asyncio.to_thread(state.audit.verify)
        assert verdict.ok, verdict

    # In PostgreSQL: both backups with their bytes, the tuning result, the audit records.
    file = tmp_path / "backups" / offline["file"]
    (content,) = _central(
        direct,
        f"SELECT c.data FROM backups b JOIN backup_content c ON c.sha256 = b.sha256 "
        f"WHERE b.id = '{offline['id']}'",
    )
    assert bytes(content[0]) == file.read_bytes()
    assert hashlib.sha256(file.read_bytes()).hexdigest() == offline["sha256"]
    sources = [s for (s,) in _central(direct, "SELECT source FROM backups ORDER BY created")]
    assert sources == ["drive", "drive"]
    assert _central(direct, "SELECT id FROM tuning_results") == [("t-offline-1",)]
    events = [e for (e,) in _central(direct, "SELECT event FROM audit_log ORDER BY seq")]
    assert "control.taken" in events and "control.released" in events
    assert events.index("control.taken") < events.index("control.released")
    assert "config.store_synced" in events
    # The queued records keep their own times (made offline, before the store returned);
    # the sync's own record is after it.
    times = dict(_central(direct, "SELECT event, time FROM audit_log ORDER BY seq"))
    assert times["control.released"] < restored < times["config.store_synced"]


@pytest.mark.asyncio
async def test_a_queue_left_by_a_crash_is_synced_by_the_next_start(
    relayed: tuple[str, str, Relay], tmp_path: Path
) -> None:
    url, direct, relay = relayed
    async with serving(tmp_path, url) as (app, c):
        relay.cut()
        offline = await _backup(c, "before the crash")
        assert offline["queued"] is True
        assert await asyncio.to_thread(state_of(app).audit.flush, 30.0)
    # The app is gone; its queue is on disk.
    with sqlite3.connect(tmp_path / OUTBOX_FILE) as conn:
        assert conn.execute("SELECT id FROM backups").fetchall() == [(offline["id"],)]
        assert conn.execute("SELECT count(*) FROM outbox_audit").fetchone()[0] >= 1

    relay.restore()
    async with serving(tmp_path, url) as (app, c):
        await _drained(c)
        assert (await asyncio.to_thread(state_of(app).audit.verify)).ok
    assert _central(direct, f"SELECT id FROM backups WHERE id = '{offline['id']}'") == [
        (offline["id"],)
    ]


@pytest.mark.asyncio
async def test_the_sync_stops_before_the_store_closes(
    relayed: tuple[str, str, Relay], tmp_path: Path
) -> None:
    url, _direct, _relay = relayed
    calls: list[str] = []
    async with serving(tmp_path, url) as (app, _c):
        state: AppState = state_of(app)
        assert state.store_sync is not None
        sync_stop, store_close = state.store_sync.stop, state.backups.store.close

        async def stop() -> None:
            calls.append("store sync")
            await sync_stop()

        def close() -> None:
            calls.append("store")
            store_close()

        state.store_sync.stop = stop  # type: ignore[method-assign]
        state.backups.store.close = close  # type: ignore[method-assign]
    assert calls == ["store sync", "store"]


def test_a_sync_cut_off_half_way_never_duplicates(
    relayed: tuple[str, str, Relay], tmp_path: Path
) -> None:
    url, direct, relay = relayed
    central = db.open_engine(url)
    outbox = Outbox(tmp_path, central)
    log = AuditLog(url)
    log.outbox = outbox
    try:
        log.record("config.test", message="online")
        assert log.flush(10)
        relay.cut()
        for i in range(3):
            log.record("config.test", message=f"offline {i}")
        assert log.flush(30)
        outbox.add(
            db.tuning_results, _tuning_row("t-1") | {"gateway": "g", "applied": 0, "result": "{}"}
        )
        assert outbox.counts() == {"backups": 0, "tuning_results": 1, "audit_log": 3}
        relay.restore()

        # Rows: copied, then (as a crash before the local delete would leave them) queued
        # again and copied again: one row in the central store.
        assert outbox.sync_rows() == 1
        outbox.add(
            db.tuning_results, _tuning_row("t-1") | {"gateway": "g", "applied": 0, "result": "{}"}
        )
        assert outbox.sync_rows() == 1
        assert _central(direct, "SELECT count(*) FROM tuning_results")[0][0] == 1

        # Audit records: the central commit happens, the local delete does not (crash).
        drop = outbox.drop_audit

        def crash(last_id: int) -> None:
            raise OSError("power lost")

        outbox.drop_audit = crash  # type: ignore[method-assign]
        with pytest.raises(OSError):
            log.sync_queued()
        outbox.drop_audit = drop  # type: ignore[method-assign]
        assert outbox.counts()["audit_log"] == 3
        assert log.sync_queued() == 0  # Found on the chain: only deleted here.
        assert outbox.counts()["audit_log"] == 0
        messages = [m for (m,) in _central(direct, "SELECT message FROM audit_log ORDER BY seq")]
        assert messages == ["online", "offline 0", "offline 1", "offline 2"]
        assert log.verify().ok
    finally:
        log.close()
        outbox.close()
        central.dispose()


# Classification of connection-level errors --------------------------------------------------


def _raised(engine: sa.Engine, statement: str) -> BaseException:
    try:
        with engine.begin() as conn:
            conn.execute(sa.text(statement))
    except sa.exc.SQLAlchemyError as exc:
        return exc
    raise AssertionError(f"{statement} did not fail")


def test_only_a_lost_connection_counts_as_unreachable(pg_url: str, tmp_path: Path) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        closed = s.getsockname()[1]
    nowhere = sa.create_engine(f"postgresql+psycopg://servodesk@127.0.0.1:{closed}/x")
    assert db.is_unreachable(_raised(nowhere, "SELECT 1"))
    engine = db.open_engine(pg_url)
    try:
        assert not db.is_unreachable(_raised(engine, "SELEC 1"))  # ProgrammingError
        assert not db.is_unreachable(_raised(engine, "SELECT 1/0"))  # DataError
        with engine.begin() as conn:
            conn.execute(sa.text("CREATE TABLE k (id int primary key)"))
            conn.execute(sa.text("INSERT INTO k VALUES (1)"))
        assert not db.is_unreachable(_raised(engine, "INSERT INTO k VALUES (1)"))  # Integrity
        # The session killed under the gateway (an administrator, a failover): the connection
        # is invalidated.
        with engine.connect() as conn:
            pid = conn.execute(sa.text("SELECT pg_backend_pid()")).scalar()
            with psycopg.connect(pg_url, autocommit=True) as admin:
                admin.execute(f"SELECT pg_terminate_backend({pid})")
            with pytest.raises(sa.exc.SQLAlchemyError) as killed:
                conn.execute(sa.text("SELECT 1"))
        assert db.is_unreachable(killed.value)
        err = db.store_error(killed.value, engine)
        assert isinstance(err, db.StoreUnavailable) and "cannot be reached" in err.message
    finally:
        engine.dispose()
    lite = sa.create_engine(f"sqlite:///{tmp_path / 'x.db'}")
    assert not db.is_unreachable(_raised(lite, "SELECT * FROM missing"))  # SQLite: never
    assert not db.is_unreachable(ValueError("x"))


def test_an_account_check_while_the_store_is_away_is_a_503(
    relayed: tuple[str, str, Relay], tmp_path: Path
) -> None:
    from servodesk.api.errors import status_for
    from servodesk.services.users import UserStore, UsersUnavailable

    url, _direct, relay = relayed
    users = UserStore(tmp_path, url)
    try:
        users.add("ada", "engineer", "correct horse battery")
        token = users.create_token("ada", "t")[1]
        assert users.has_accounts() is True  # As the auth middleware asks on every request.
        relay.cut()
        assert users.has_accounts() is True  # The last answer: a login is still asked for.
        with pytest.raises(UsersUnavailable) as away:
            users.verify_token(token.encode())
        assert status_for(away.value) == 503
        relay.restore()
        assert users.verify_token(token.encode()) is not None
    finally:
        users.close()
