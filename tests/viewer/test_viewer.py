"""The 3D twin: a real viser server beside the app, its stages following simulated drives."""

from __future__ import annotations

import asyncio
import math
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np
import pytest

from servodesk.api.routes.viewer import viewer
from servodesk.services import viewer as viewer_mod
from servodesk.services.viewer import Stage
from tests.viewer.conftest import Viewer, free_port, make_app, port_is_bound

pytestmark = pytest.mark.asyncio(loop_scope="module")

GENERIC = "cia402-generic-1"
HIWIN = "hiwin-e-2"


async def until(cond: Callable[[], bool], timeout: float = 3.0, what: str = "condition") -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.02)


def angle_of(wxyz: np.ndarray) -> float:
    """Rotation about +z of a quaternion (w, x, y, z), in radians."""
    w, x, y, z = (float(v) for v in wxyz)
    assert abs(x) < 1e-9 and abs(y) < 1e-9
    return 2.0 * math.atan2(z, w)


def same_angle(a: float, b: float) -> bool:
    return abs(math.remainder(a - b, 2.0 * math.pi)) < 1e-4


async def write(c: httpx.AsyncClient, sid: str, address: str, value: int) -> None:
    r = await c.put(f"/api/v1/sessions/{sid}/objects/{address}", json={"value": value})
    assert r.status_code == 200, r.text


async def stage_of(v: Viewer, sid: str) -> Stage:
    await until(lambda: v.service.stage(sid) is not None, what=f"the stage of {sid}")
    stage = v.service.stage(sid)
    assert stage is not None
    return stage


async def test_viewer_api_reports_the_running_server_and_serves_the_bundled_client(
    twin: Viewer,
) -> None:
    r = await twin.client.get("/api/v1/viewer")
    assert r.status_code == 200
    body = r.json()
    assert body["enabled"] and body["running"] and body["error"] is None
    assert body["port"] == twin.port and body["url"] == f"http://127.0.0.1:{twin.port}/"
    assert body["rate_hz"] >= 30 and body["clients"] == 0
    assert port_is_bound(twin.port)
    # The client page comes from the viser wheel itself: no network, no build.
    html = await asyncio.to_thread(
        lambda: urllib.request.urlopen(body["url"], timeout=5).read().decode()
    )
    assert "<html" in html.lower() and len(html) > 10_000


async def test_the_view_offers_no_public_share_link(twin: Viewer) -> None:
    # viser's share button tunnels the view through a public relay: the axes of a machine
    # must not leave its network from a click. What every client gets on connecting (the
    # server's persistent messages) configures the page without it.
    ws = twin.service.server._websock_server
    themes = [
        m
        for m in ws.get_message_buffer().message_from_id.values()
        if type(m).__name__ == "ThemeConfigurationMessage"
    ]
    assert themes and themes[-1].show_share_button is False


async def test_one_stage_per_session_side_by_side_with_labels(twin: Viewer) -> None:
    sessions = (await twin.client.get("/api/v1/sessions")).json()
    assert {s["id"] for s in sessions} == {GENERIC, HIWIN}
    stages = [await stage_of(twin, s["id"]) for s in sessions]
    xs = sorted(float(s.root.position[0]) for s in stages)
    assert xs[1] - xs[0] >= 1.0  # Side by side, not on top of each other.
    await until(lambda: all(s.label_text for s in stages), what="labels")
    for s, info in zip(stages, sessions, strict=True):
        assert s.choice.kind == "rotary"  # Both families are rotary servo motors.
        assert info["id"] in s.label.text
        # Long names are shortened to fit a stage's slot.
        name = info["profile_name"]
        n = viewer_mod.LABEL_NAME_CHARS
        assert (name if len(name) <= n else name[: n - 1] + "…") in s.label.text
        assert f"node {info['node_id']}" in s.label.text
    axes = {a["session"]: a for a in (await twin.client.get("/api/v1/viewer")).json()["axes"]}
    assert axes[GENERIC]["kind"] == "rotary" and axes[GENERIC]["source"] == "default"
    assert (
        axes[GENERIC]["scale"]
        == twin.service.manager.get(GENERIC).profile.simulation.counts_per_rev
    )


async def test_colour_follows_the_drive_state(twin: Viewer) -> None:
    c = twin.client
    stage = await stage_of(twin, GENERIC)
    await until(lambda: stage.colour == viewer_mod.DISABLED, what="grey (disabled)")
    assert tuple(stage.body.color) == viewer_mod.DISABLED
    r = await c.post(f"/api/v1/sessions/{GENERIC}/state", json={"command": "enable"})
    assert r.status_code == 200, r.text
    await until(lambda: tuple(stage.body.color) == viewer_mod.ENABLED, what="green (enabled)")
    sim = twin.app.state.servodesk.sim
    sim.drives[0].raise_fault(0x8611)
    await until(lambda: tuple(stage.body.color) == viewer_mod.FAULT, what="red (fault)")
    r = await c.post(f"/api/v1/sessions/{GENERIC}/state", json={"command": "fault_reset"})
    assert r.status_code == 200, r.text
    await until(lambda: tuple(stage.body.color) == viewer_mod.DISABLED, what="grey again")


async def test_rotor_and_ghost_follow_a_profile_position_move(twin: Viewer) -> None:
    c = twin.client
    session = twin.service.manager.get(GENERIC)
    cpr = session.profile.simulation.counts_per_rev
    stage = await stage_of(twin, GENERIC)
    before = angle_of(stage.moving.wxyz)
    r = await c.post(f"/api/v1/sessions/{GENERIC}/state", json={"command": "enable"})
    assert r.status_code == 200, r.text
    start = session.last_state.position if session.last_state else 0
    target = (start or 0) + cpr // 4 + 1234
    await write(c, GENERIC, "0x6060", 1)
    await write(c, GENERIC, "0x607A", target)
    await write(c, GENERIC, "0x6040", 0x0F)
    await write(c, GENERIC, "0x6040", 0x1F)  # New set-point (CiA 402-2 §6.5.1).
    # The ghost shows 607Ah as soon as it is read back.
    await until(
        lambda: (
            stage.ghost.visible
            and same_angle(angle_of(stage.ghost.wxyz), 2 * math.pi * target / cpr)
        ),
        what="the ghost at the target",
    )
    # The rotor arrives and its rotation is the actual position in counts.
    await until(
        lambda: stage.position is not None and abs(stage.position - target) < cpr / 100,
        timeout=5.0,
        what="the rotor at the target",
    )
    await write(c, GENERIC, "0x6040", 0x0F)
    await asyncio.sleep(0.2)
    assert session.last_state is not None and session.last_state.position is not None
    pos = session.last_state.position
    await until(lambda: stage.position == session.last_state.position, what="a frame")  # type: ignore[union-attr]
    assert same_angle(angle_of(stage.moving.wxyz), 2 * math.pi * stage.position / cpr)  # type: ignore[operator]
    assert not same_angle(angle_of(stage.moving.wxyz), before)
    assert abs(pos - target) < cpr / 100


async def test_rotary_limits_are_drawn_as_arc_marks(twin: Viewer) -> None:
    cpr = twin.service.manager.get(GENERIC).profile.simulation.counts_per_rev
    await write(twin.client, GENERIC, "0x607D:01", -cpr // 4)
    await write(twin.client, GENERIC, "0x607D:02", cpr // 2)
    await until(
        lambda: (
            (s := twin.service.stage(GENERIC)) is not None and s.limits == (-cpr // 4, cpr // 2)
        ),
        what="the limits",
    )
    stage = twin.service.stage(GENERIC)
    assert stage is not None
    names = {n.name for n in stage.nodes}
    assert any(n.endswith("/limit_marks") for n in names)
    marks = next(n for n in stage.nodes if n.name.endswith("/limit_marks"))
    ends = [(float(p[1][0]), float(p[1][1])) for p in marks.points]
    assert same_angle(math.atan2(ends[0][1], ends[0][0]), -math.pi / 2)
    assert same_angle(math.atan2(ends[1][1], ends[1][0]), math.pi)
    # 0/0 switches them off (CiA 402-2 §6.5.4): the marks go.
    await write(twin.client, GENERIC, "0x607D:01", 0)
    await write(twin.client, GENERIC, "0x607D:02", 0)
    await until(
        lambda: (s := twin.service.stage(GENERIC)) is not None and s.limits is None,
        what="the limits gone",
    )
    stage = twin.service.stage(GENERIC)
    assert stage is not None
    assert not any(n.name.endswith("/limit_marks") for n in stage.nodes)


async def test_linear_stage_with_scale_limits_and_carriage(twin: Viewer) -> None:
    c = twin.client
    r = await c.put(f"/api/v1/viewer/axes/{GENERIC}", json={"kind": "linear", "scale": 1000})
    assert r.status_code == 200, r.text
    assert r.json() == {
        "session": GENERIC,
        "kind": "linear",
        "scale": 1000.0,
        "scale_unit": "counts/mm",
        "source": "user",
        "limits": r.json()["limits"],
    }
    await write(c, GENERIC, "0x607D:01", -50_000)  # -50 mm
    await write(c, GENERIC, "0x607D:02", 150_000)  # +150 mm
    await until(
        lambda: (
            (s := twin.service.stage(GENERIC)) is not None
            and s.choice.kind == "linear"
            and s.limits == (-50_000, 150_000)
        ),
        what="a linear stage with limits",
    )
    stage = twin.service.stage(GENERIC)
    assert stage is not None
    posts = {n.name.rsplit("/", 1)[1]: n for n in stage.nodes if "/limit_" in n.name}
    assert set(posts) == {"limit_min", "limit_max"}
    lo, hi = float(posts["limit_min"].position[0]), float(posts["limit_max"].position[0])
    assert lo < hi
    # 200 mm between the posts; the scale maps counts to mm.
    assert hi - lo == pytest.approx(200.0 / stage.mm_per_unit)
    session = twin.service.manager.get(GENERIC)
    await until(lambda: stage.position is not None, what="a position")
    assert stage.position is not None
    x = float(stage.moving.position[0])
    # The carriage sits at the actual position in mm on the rail's window.
    assert x == pytest.approx((stage.position / 1000.0 - stage.centre_mm) / stage.mm_per_unit)
    assert tuple(stage.moving.wxyz) == (1.0, 0.0, 0.0, 0.0)
    # Back to rotary: the profile's counts per revolution when no scale is given.
    r = await c.put(f"/api/v1/viewer/axes/{GENERIC}", json={"kind": "rotary"})
    assert r.status_code == 200 and r.json()["scale"] == session.profile.simulation.counts_per_rev


async def test_axis_choice_is_validated(twin: Viewer) -> None:
    c = twin.client
    r = await c.put("/api/v1/viewer/axes/nope-9", json={"kind": "rotary"})
    assert r.status_code == 404
    r = await c.put(f"/api/v1/viewer/axes/{GENERIC}", json={"kind": "spiral"})
    assert r.status_code == 422
    r = await c.put(f"/api/v1/viewer/axes/{GENERIC}", json={"kind": "linear", "scale": -1})
    assert r.status_code == 422
    r = await c.put(f"/api/v1/viewer/axes/{GENERIC}", json={"kind": "linear"})
    assert r.status_code == 400 and r.json()["field"] == "scale"


async def test_server_starts_and_stops_with_the_app_and_stages_track_sessions(
    tmp_path: Path,
) -> None:
    port = free_port()
    app = make_app(tmp_path, "cia402-generic", port)
    assert not port_is_bound(port)
    async with app.router.lifespan_context(app):
        assert port_is_bound(port)
        service = viewer(app)
        manager = service.manager
        await until(lambda: service.stage(GENERIC) is not None, what="the stage")
        session = manager.get(GENERIC)
        params = session.link.params
        await manager.close(GENERIC)
        await until(lambda: service.stage(GENERIC) is None, what="the stage removed")
        await manager.open(params, "cia402-generic", simulated=True)
        await until(lambda: service.stage(GENERIC) is not None, what="the stage back")
        assert service.server is not None
    assert service.server is None
    # The port is free once the app has shut down: another server can bind it at once.
    assert not port_is_bound(port)
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", port))


async def test_disabled_when_viewer_port_is_zero(tmp_path: Path) -> None:
    app = make_app(tmp_path, "cia402-generic", 0)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as c:
            body = (await c.get("/api/v1/viewer")).json()
            assert body["enabled"] is False and body["running"] is False
            assert body["url"] is None and body["port"] is None and body["clients"] == 0
            assert viewer(app).server is None
            # The choice is kept for when the viewer runs.
            r = await c.put(
                f"/api/v1/viewer/axes/{GENERIC}", json={"kind": "rotary", "scale": 4096}
            )
            assert r.status_code == 200 and r.json()["scale"] == 4096
