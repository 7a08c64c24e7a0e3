"""The backend stops its services in one order (api/state.py, AppState.aclose): tuning jobs,
then motion halts the axes, then the scope and the 3D viewer, then the sessions, the store and
the workers, the simulated drives last. A real application with its simulated drive; each
service's stop is wrapped to record when it runs (and what the axis does at that moment).
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable
from typing import Any

import httpx
import pytest

from servodesk.api.app import create_app
from servodesk.api.state import AppState, state_of
from servodesk.domain.cia402 import State
from servodesk.settings import Settings
from tests.operation.support import headers

SID = "cia402-generic-1"


def _spy(calls: list[str], name: str, stop: Callable[[], Any], before: Callable[[], None]) -> Any:
    """``stop`` that first records ``name`` (and calls ``before``)."""

    def wrapper() -> Any:
        calls.append(name)
        before()
        return stop()

    return wrapper


def _watch(state: AppState, calls: list[str], seen: dict[str, Any]) -> None:
    sim = state.sim
    assert sim is not None
    drive = sim.drives[0]

    def look(name: str) -> Callable[[], None]:
        def at_stop() -> None:
            # What the axis does when this service starts to stop.
            seen[name] = (drive.state, state.motion.status(SID)["active"])

        return at_stop

    targets: list[tuple[str, Any, str]] = [
        ("tuning", state.tuning, "shutdown"),
        ("motion", state.motion, "shutdown"),
        ("control", state.control, "close"),
        ("scope", state.scope, "close"),
        ("viewer", state.viewer, "stop"),
        ("sessions", state.manager, "close_all"),
        ("store", state.backups.store, "close"),
        ("audit", state.audit, "close"),
        ("users", state.auth.users, "close"),
        ("sim", sim, "stop"),
    ]
    for name, service, method in targets:
        before = look(name) if name in ("tuning", "motion", "scope", "viewer") else lambda: None
        setattr(service, method, _spy(calls, name, getattr(service, method), before))


async def _jog(app: Any) -> None:
    """Take control, bind a dead-man connection in process, servo on and jog."""
    state = state_of(app)
    connection = state.control.connect("A")
    transport = httpx.ASGITransport(app=app)
    async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
        h = headers("A")
        r = await c.post(f"/api/v1/sessions/{SID}/control", json={"action": "take"}, headers=h)
        assert r.status_code == 200, r.text
        state.control.bind(connection, SID, r.json()["token"])
        h = {**h, "X-Servodesk-Control": r.json()["token"]}
        r = await c.post(f"/api/v1/sessions/{SID}/state", json={"command": "enable"}, headers=h)
        assert r.json()["state"] == "Operation enabled", r.text
        r = await c.post(
            f"/api/v1/sessions/{SID}/motion/jog",
            json={"velocity": 200_000, "acceleration": 2_000_000},
            headers=h,
        )
        assert r.status_code == 200, r.text
        state.control.heartbeat(connection, SID)
        await asyncio.sleep(0.05)


def _app(channel: str, tmp_path: Any) -> Any:
    return create_app(
        Settings(
            sim=True,
            sim_channel=channel,
            sim_profiles="cia402-generic",
            data_dir=tmp_path,
            viewer_port=0,
        )
    )


async def test_shutdown_halts_the_axis_before_the_scope_and_viewer_stop(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    app = _app(channel, tmp_path)
    state = state_of(app)
    calls: list[str] = []
    seen: dict[str, Any] = {}
    # The lifespan is driven directly: a TestClient cannot shut down under a running jog's
    # open WebSocket (tests/operation/test_deadman.py does the same).
    async with app.router.lifespan_context(app):
        _watch(state, calls, seen)
        await _jog(app)
        assert seen == {}
    assert calls == [
        "tuning",
        "motion",
        "control",
        "scope",
        "viewer",
        "sessions",
        "store",
        "audit",
        "users",
        "sim",
    ]
    # The jog still ran when the tuning and motion stops began ...
    assert seen["tuning"] == (State.OPERATION_ENABLED, True)
    assert seen["motion"] == (State.OPERATION_ENABLED, True)
    # ... and the axis was out of Operation enabled (quick stop), its motion ended, before the
    # scope and the viewer began to stop (their stops wait on threads and sockets).
    for name in ("scope", "viewer"):
        drive_state, active = seen[name]
        assert drive_state != State.OPERATION_ENABLED, (name, drive_state)
        assert active is False, name
    assert state.sim is None  # Stopped, and the state forgot it.


async def test_a_failing_stop_does_not_leave_the_rest_running(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    app = _app(channel, tmp_path)
    state = state_of(app)
    calls: list[str] = []
    seen: dict[str, Any] = {}

    async def broken() -> None:
        raise RuntimeError("the scope's stop failed")

    with pytest.raises(RuntimeError, match="scope's stop failed"):
        async with app.router.lifespan_context(app):
            _watch(state, calls, seen)
            state.scope.close = broken  # type: ignore[method-assign]
            await _jog(app)
    # The stops after the failing one still ran: the sessions closed, the drives stopped.
    assert calls[-5:] == ["sessions", "store", "audit", "users", "sim"]
    assert state.manager.all() == []
    assert state.sim is None


async def test_nothing_the_app_started_outlives_its_shutdown(channel, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Every task and thread the application started (session polls, the dead-man's watch,
    the bus's notifier, servodesk's heartbeat on the bus, the scope, the fleet's timer, the
    twins' threads) has ended once its shutdown returned: a task left pending would act on a
    closed session, a heartbeat thread would tell a drive the master still lives."""
    tasks_before = asyncio.all_tasks()
    threads_before = {t.ident for t in threading.enumerate()}
    app = _app(channel, tmp_path)
    async with app.router.lifespan_context(app):
        await _jog(app)
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            # The scope samples the drive too (its own thread and tasks).
            r = await c.put(
                "/api/v1/scope/channels",
                json={"channels": [{"id": 0, "session": SID, "address": "0x6064:00"}]},
                headers=headers("A"),
            )
            assert r.status_code == 200, r.text
            r = await c.post("/api/v1/scope/run", json={"action": "start"}, headers=headers("A"))
            assert r.status_code == 200, r.text
            await asyncio.sleep(0.2)
    pending = [t for t in asyncio.all_tasks() - tasks_before if not t.done()]
    pending = [t for t in pending if t is not asyncio.current_task()]
    assert pending == [], [t.get_name() + " " + repr(t.get_coro()) for t in pending]
    deadline = time.monotonic() + 3.0  # python-can's cyclic sender ends at its next period.
    while True:
        # The event loop's own worker threads (its default executor, AnyIO's pool for
        # Starlette's sync calls) belong to this test's loop and end with it, not the app.
        alive = [
            t
            for t in threading.enumerate()
            if t.ident not in threads_before
            and not t.name.startswith("asyncio_")
            and t.name != "AnyIO worker thread"
        ]
        if not alive or time.monotonic() > deadline:
            break
        await asyncio.sleep(0.05)
    assert alive == [], [t.name for t in alive]
