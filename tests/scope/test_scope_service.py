"""The scope service against simulated drives: a known signal through every source.

A profile position move of the simulated generic drive is recorded through the PDO, SDO and
recorder sources and compared with the simulation's own values: a hook on the drive's control
cycle logs (wall time, position) of every cycle, the ground truth. PDO samples are the drive's
position at a cycle near their bus timestamps, at the cycle rate; SDO samples lie within the
positions the axis had around the time their answers arrived; recorder samples are the drive's
own recording, at its period. Level triggers with 20 % pre-trigger put the crossing where it
belongs in the captured window, from PDO data (the scope's trigger) and from the recorder (the
drive's trigger).

The rig (a real uvicorn server with the simulated drives, and its HTTP client) is shared by
test_scope_api.py and test_scope_stream.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import os
import socket
import time
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import pytest_asyncio
import uvicorn

from servodesk.api.app import create_app
from servodesk.api.routes.scope import scope_of
from servodesk.services.scope import ScopeService
from servodesk.services.scope_recorder import STREAM_SPAN_S
from servodesk.settings import Settings
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.engine_base import SimAbort
from tests.control_helpers import take_control

pytestmark = pytest.mark.asyncio(loop_scope="module")

GENERIC = "cia402-generic-1"
LECSN = "lecsn-t-1"  # On PROFINET: DO-ID 1.
HDR = {"X-Servodesk-Client": "scope-test"}
#: One motor revolution of the generic twin [counts] (its profile velocity: 200 000 counts/s).
REV = 131072
_n = itertools.count()


@dataclass
class Rig:
    client: httpx.AsyncClient
    app: Any
    port: int

    @property
    def scope(self) -> ScopeService:
        return scope_of(self.app)

    def drive(self, node: int = 1) -> SimulatedDrive:
        for d in self.app.state.servodesk.sim.drives:
            if d.node_id == node:
                drive: SimulatedDrive = d
                return drive
        raise KeyError(node)

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/api/v1/scope/ws"


class _Server(uvicorn.Server):
    """uvicorn without its signal handlers: in the test process they replaced SIGINT's for
    the rig's lifetime and, restored in another order than pytest-asyncio's loops set them,
    could leave a dead server's handler behind for later tests (test_cli_tune's Ctrl-C)."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


@contextlib.asynccontextmanager
async def serve(settings: Settings, *, sndbuf: int | None = None) -> AsyncIterator[Rig]:
    """The application on a real uvicorn server on 127.0.0.1 (a free port).

    ``sndbuf``: the send buffer of every accepted connection (Linux: inherited from the
    listening socket), so that a client that does not read backs up the server within
    seconds instead of after the megabytes loopback buffers otherwise take.
    """
    app = create_app(settings)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    if sndbuf is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, sndbuf)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = _Server(uvicorn.Config(app, log_level="warning", lifespan="on"))
    task = asyncio.create_task(server.serve(sockets=[sock]))
    while not server.started:
        if task.done():
            task.result()
        await asyncio.sleep(0.02)
    try:
        async with httpx.AsyncClient(
            base_url=f"http://127.0.0.1:{port}", headers=HDR, timeout=30
        ) as client:
            if settings.sim:
                # Applying PDOs and running cyclic data change the drive: the rig's client
                # holds control of the generic twin, its token on every request.
                await take_control(client, GENERIC, HDR["X-Servodesk-Client"])
            yield Rig(client, app, port)
    finally:
        server.should_exit = True
        await task
        sock.close()


def sim_settings(data_dir: Path) -> Settings:
    return Settings(
        sim=True,
        sim_channel=f"scope-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic,lecsn-t",
        data_dir=data_dir,
        viewer_port=0,
    )


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rig(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Rig]:
    async with serve(sim_settings(tmp_path_factory.mktemp("data"))) as r:
        yield r


@pytest_asyncio.fixture(loop_scope="module")
async def fresh(rig: Rig) -> AsyncIterator[Rig]:
    """The rig with the scope stopped and emptied before and after the test."""

    async def reset() -> None:
        await rig.client.post("/api/v1/scope/run", json={"action": "stop"})
        await rig.client.put("/api/v1/scope/trigger", json={"mode": "roll"})
        await rig.client.put("/api/v1/scope/channels", json={"channels": []})
        await rig.client.delete(f"/api/v1/sessions/{GENERIC}/pdo/cyclic")

    await reset()
    try:
        yield rig
    finally:
        await reset()
        d = rig.drive()
        d.write(0x6040, 0, 0x06)  # Shut down: the next test starts from a still axis.


# Ground truth and motion ------------------------------------------------------------------


class Truth:
    """The simulation's own trajectory: (wall time, position, velocity) after every control
    cycle, or with ``substeps`` after every plant sub-step (what the drive's recorder samples,
    through the same :meth:`SimulatedDrive.sampler`)."""

    def __init__(self, drive: SimulatedDrive, *, substeps: bool = False) -> None:
        self.drive = drive
        self.substeps = substeps
        self.rows: list[tuple[float, float, float]] = []
        pos, vel = drive.sampler(0x6064, 0), drive.sampler(0x606C, 0)
        rows = self.rows

        def hook() -> None:
            rows.append((time.time(), pos(), vel()))  # type: ignore[arg-type]

        self._hook = hook

    def __enter__(self) -> Truth:
        if self.substeps:
            self.drive.on_substep(self._hook)
        else:
            self.drive.on_cycle(self._hook)
        return self

    def __exit__(self, *exc: object) -> None:
        d = self.drive
        if self.substeps:
            d.remove_substep_hook(self._hook)
        else:
            with d.lock:
                d._cycle_hooks.remove(self._hook)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rows = np.asarray(self.rows, dtype=np.float64)
        return rows[:, 0], rows[:, 1], rows[:, 2]


def enable_pp(d: SimulatedDrive) -> None:
    """Profile position mode, operation enabled (CiA 402-2 §6.2, §7)."""
    d.write(0x6060, 0, 1)
    for word in (0x06, 0x07, 0x0F):
        d.write(0x6040, 0, word)


async def move(d: SimulatedDrive, distance: int) -> tuple[int, int]:
    """A profile position move by ``distance`` counts; returns (start, target)."""
    start = int(d.read(0x6064, 0))
    target = start + distance
    d.write(0x607A, 0, target)
    d.write(0x6040, 0, 0x3F)  # New set-point, change immediately (bits 4 and 5).
    await asyncio.sleep(0.01)
    d.write(0x6040, 0, 0x2F)
    return start, target


async def wait_reached(d: SimulatedDrive, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    await asyncio.sleep(0.05)
    while not d.statusword & 0x400:  # Target reached (CiA 402-2 §6.2.2).
        assert time.monotonic() < end, "the move did not finish"
        await asyncio.sleep(0.01)


async def put_channels(rig: Rig, channels: list[dict[str, Any]]) -> dict[str, Any]:
    r = await rig.client.put("/api/v1/scope/channels", json={"channels": channels})
    assert r.status_code == 200, r.text
    body: dict[str, Any] = r.json()
    return body


async def run(rig: Rig, action: str) -> dict[str, Any]:
    r = await rig.client.post("/api/v1/scope/run", json={"action": action})
    assert r.status_code == 200, r.text
    body: dict[str, Any] = r.json()
    return body


async def status(rig: Rig) -> dict[str, Any]:
    body: dict[str, Any] = (await rig.client.get("/api/v1/scope")).json()
    return body


async def wait_done(rig: Rig, timeout: float = 10.0) -> dict[str, Any]:
    """The status once a single capture is done and the scope has stopped after it."""
    end = time.monotonic() + timeout
    while True:
        st = await status(rig)
        if (st["state"] == "done" and not st["running"]) or time.monotonic() > end:
            return st
        await asyncio.sleep(0.05)


async def start_pdo(rig: Rig, period_ms: float = 2.0) -> None:
    """TPDO1 = position and velocity on every SYNC, the only TPDO; cyclic data at
    ``period_ms``."""
    r = await rig.client.post(
        f"/api/v1/sessions/{GENERIC}/pdo/apply",
        json={
            "pdos": [
                {
                    "direction": "tx",
                    "number": 1,
                    "entries": ["0x6064:00", "0x606C:00"],
                    "transmission_type": 1,
                    "enabled": True,
                },
                # The others off: the default TPDO2 carries 6064h too (event-driven).
                *({"direction": "tx", "number": n, "enabled": False} for n in (2, 3, 4)),
            ]
        },
    )
    assert r.status_code == 200 and r.json()["ok"], r.text
    r = await rig.client.post(
        f"/api/v1/sessions/{GENERIC}/pdo/cyclic", json={"sync_period_ms": period_ms}
    )
    assert r.status_code == 200, r.text


def samples(rig: Rig, cid: int) -> tuple[np.ndarray, np.ndarray]:
    """Every sample the scope holds for channel ``cid`` (backend times, raw values)."""
    ch = next(c for c in rig.scope.channels if c.id == cid)
    return ch.ring.all()


def position_near(
    truth_t: np.ndarray, truth_p: np.ndarray, t: float, before: float, after: float
) -> np.ndarray:
    """The positions the axis had in [t - before, t + after] (wall time)."""
    i0 = int(np.searchsorted(truth_t, t - before, side="left"))
    i1 = int(np.searchsorted(truth_t, t + after, side="right"))
    return truth_p[max(0, i0 - 1) : i1 + 1]


# Tests ------------------------------------------------------------------------------------


async def test_pdo_source_records_the_move_at_the_cycle_rate(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    await start_pdo(rig, period_ms=2.0)
    st = await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00"},  # auto -> pdo (mapped)
            {"id": 1, "session": GENERIC, "address": "0x606C:00", "source": "pdo"},
        ],
    )
    assert [c["source"] for c in st["channels"]] == ["pdo", "pdo"]
    assert st["channels"][0]["unit"] and st["channels"][0]["raw_unit"] == "inc"
    await run(rig, "start")
    # Standstill: every PDO sample carries the value the drive reports by SDO.
    await asyncio.sleep(0.4)
    r = await rig.client.get(f"/api/v1/sessions/{GENERIC}/objects/0x6064:00")
    still = r.json()["value"]
    t, v = samples(rig, 0)
    assert len(t) > 50
    assert set(v.tolist()) == {float(still)}
    with Truth(d) as truth:
        t_move = time.time()
        start, target = await move(d, REV)
        await wait_reached(d)
        await asyncio.sleep(0.1)
    st = await run(rig, "stop")
    t, v = samples(rig, 0)
    # Monotonic bus times at the cycle rate (2 ms SYNC: 500 Hz), measured not requested.
    assert np.all(np.diff(t) > 0)
    assert np.median(np.diff(t)) == pytest.approx(0.002, rel=0.25)
    ch0 = st["channels"][0]
    assert ch0["rate_hz"] == pytest.approx(500, rel=0.25)
    assert ch0["samples"] == len(t)
    # During the move each sample is a position the simulation had near the sample's time.
    tt, tp, _ = truth.arrays()
    moving = (t > t_move) & (t < tt[-1])
    assert np.count_nonzero(moving) > 200
    assert v[moving].min() <= start + 100 and v[moving].max() >= target - 100
    for ts, vs in zip(t[moving], v[moving], strict=True):
        near = position_near(tt, tp, ts, 0.05, 0.05)
        assert vs in near, (ts, vs, near.min(), near.max())


async def test_sdo_source_stays_within_the_motion_envelope(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    st = await put_channels(
        rig, [{"id": 3, "session": GENERIC, "address": "0x6064:00", "source": "sdo"}]
    )
    assert st["channels"][0]["source"] == "sdo"
    await run(rig, "start")
    with Truth(d) as truth:
        await asyncio.sleep(0.1)
        await move(d, -REV)
        await wait_reached(d)
        await asyncio.sleep(0.1)
        st = await run(rig, "stop")
    t, v = samples(rig, 3)
    assert len(t) > 100 and np.all(np.diff(t) > 0)
    tt, tp, _ = truth.arrays()
    inside = (t > tt[0] + 0.06) & (t < tt[-1])
    assert np.count_nonzero(inside) > 100
    # An answer arriving at t carries the position of a moment shortly before t.
    for ts, vs in zip(t[inside], v[inside], strict=True):
        near = position_near(tt, tp, ts, 0.05, 0.005)
        assert near.min() <= vs <= near.max(), (ts, vs, near.min(), near.max())
    # The achieved rate is what was measured: samples over their time span.
    ch = st["channels"][0]
    assert ch["rate_hz"] == pytest.approx((len(t) - 1) / (t[-1] - t[0]), rel=0.3)
    assert ch["requested_rate_hz"] is None


async def test_sdo_source_keeps_a_requested_rate(fresh: Rig) -> None:
    rig = fresh
    await put_channels(
        rig,
        [{"id": 0, "session": GENERIC, "address": "0x6041:00", "source": "sdo", "rate_hz": 50}],
    )
    await run(rig, "start")
    await asyncio.sleep(1.0)
    st = await run(rig, "stop")
    t, _ = samples(rig, 0)
    assert np.median(np.diff(t)) == pytest.approx(0.02, rel=0.2)
    assert st["channels"][0]["rate_hz"] == pytest.approx(50, rel=0.2)


def recording(d: SimulatedDrive, channels: int) -> tuple[np.ndarray, int]:
    """The drive's last recording (rows x channels, signed) and its trigger index."""
    rec = d.recorder
    assert rec is not None
    with d.lock:
        data = rec.data()
        trig = rec.trigger_index
    assert data is not None
    words = np.frombuffer(data, dtype="<i4").reshape(-1, channels)
    return words.astype(np.float64), trig


def segments(t: np.ndarray) -> list[slice]:
    """The recordings in a recorder channel: runs of samples one period apart."""
    cuts = np.flatnonzero(np.diff(t) > 1.5 / 4000) + 1
    bounds = [0, *cuts.tolist(), len(t)]
    return [slice(a, b) for a, b in itertools.pairwise(bounds)]


async def test_recorder_source_free_running_is_the_drives_own_samples(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    info = (await rig.client.get(f"/api/v1/sessions/{GENERIC}/recorder")).json()
    assert info["present"] and info["rate_hz"] == 4000 and "0x6064:00" in info["objects"]
    st = await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00"},  # auto -> recorder
            {"id": 1, "session": GENERIC, "address": "0x606C:00", "source": "recorder"},
        ],
    )
    assert [c["source"] for c in st["channels"]] == ["recorder", "recorder"]
    with Truth(d, substeps=True) as truth:
        await run(rig, "start")
        await asyncio.sleep(0.2)
        await move(d, REV)
        await wait_reached(d)
        st = await run(rig, "stop")
    t, v = samples(rig, 0)
    _, vel = samples(rig, 1)
    tt, tp, tv = truth.arrays()
    checked = 0
    for seg in segments(t):
        st_, sv, svel = t[seg], v[seg], vel[seg]
        if len(sv) < 20 or np.all(sv == sv[0]):
            continue  # At standstill a recording matches anywhere: nothing to locate.
        # Each recording is a run of consecutive plant steps of the simulation, value for
        # value (position and velocity), found near the recording's own times.
        window = np.flatnonzero(np.abs(tt - st_[0]) < 0.1)
        starts = [j for j in window if tp[j] == sv[0] and j + len(sv) <= len(tp)]
        match = [
            j
            for j in starts
            if np.array_equal(tp[j : j + len(sv)], sv) and np.array_equal(tv[j : j + len(sv)], svel)
        ]
        assert match, f"recording at {st_[0]:.3f} is not a run of the simulation's samples"
        # Placed at the recorder's period (4 kHz) from its anchor: no interpolation.
        assert np.allclose(np.diff(st_), 1 / 4000, atol=1e-6)
        checked += 1
    assert checked >= 1, "the move was recorded"
    assert st["channels"][0]["rate_hz"] == pytest.approx(4000, rel=0.01)
    # Each restart leaves a gap: fewer samples per second arrive than the recorder takes.
    assert st["channels"][0]["throughput_hz"] < 4000


async def test_recorder_streams_while_it_records(fresh: Rig) -> None:
    """Issue 50: the first samples arrive while the drive still records, and the recording
    comes whole, every sample once, in order: a run of the simulation's own samples."""
    rig = fresh
    d = rig.drive()
    rec = d.recorder
    assert rec is not None and rec.streams
    enable_pp(d)
    await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00", "source": "recorder"},
            {"id": 1, "session": GENERIC, "address": "0x606C:00", "source": "recorder"},
        ],
    )
    depth = round(STREAM_SPAN_S * 4000)
    with Truth(d, substeps=True) as truth:
        await run(rig, "start")
        t_start = time.monotonic()
        while not len(samples(rig, 0)[0]):
            assert time.monotonic() - t_start < 2.0, "no recorder samples within 2 s"
            await asyncio.sleep(0.002)
        # (No await since the samples arrived: this is the state they arrived in.)
        with d.lock:
            status_then, count_then = rec.status, rec.count
        source = rig.scope._recorders[0]
        assert source.records == 0, "no recording had ended yet"
        assert status_then == 2 and count_then < depth, "the first recording still runs"
        assert len(samples(rig, 0)[0]) < depth
        assert (await status(rig))["recorders"][0]["streaming"] is True
        await move(d, REV)
        await wait_reached(d)
        # Into the second recording, so that the first is complete.
        await asyncio.sleep(max(0.0, STREAM_SPAN_S + 0.3 - (time.monotonic() - t_start)))
        await run(rig, "stop")
    t, v = samples(rig, 0)
    _, vel = samples(rig, 1)
    tt, tp, tv = truth.arrays()
    seg = segments(t)[0]
    st_, sv, svel = t[seg], v[seg], vel[seg]
    # The first recording, complete: depth samples one period apart (no gap, no duplicate) ...
    assert len(sv) == depth
    assert np.allclose(np.diff(st_), 1 / 4000, atol=1e-6)
    # ... value for value a run of consecutive plant steps (the move starts inside it).
    assert not np.all(sv == sv[-1])
    window = np.flatnonzero(np.abs(tt - st_[0]) < 0.1)
    match = [
        j
        for j in window
        if j + depth <= len(tp)
        and np.array_equal(tp[j : j + depth], sv)
        and np.array_equal(tv[j : j + depth], svel)
    ]
    assert match, "the streamed recording is not a run of the simulation's samples"


async def test_recorder_without_stream_objects_uploads_whole_recordings(fresh: Rig) -> None:
    """A drive that refuses the stream objects (0602 0000h) gets the whole-recording upload."""
    rig = fresh
    d = rig.drive()
    stream_data = (0x2F0B << 8) | 0  # The live getter of 2F0Bh (the twin's object store).
    own = d._live[stream_data]

    def refuse() -> None:
        raise SimAbort(0x06020000)

    d._live[stream_data] = refuse
    try:
        await put_channels(
            rig, [{"id": 0, "session": GENERIC, "address": "0x6077:00", "source": "recorder"}]
        )
        await run(rig, "start")
        # Two recordings uploaded whole (0.1 s each; a loaded machine takes longer).
        deadline = time.monotonic() + 5.0
        rs = (await status(rig))["recorders"][0]
        while rs["records"] < 2 and time.monotonic() < deadline:
            await asyncio.sleep(0.1)
            rs = (await status(rig))["recorders"][0]
        await run(rig, "stop")
    finally:
        d._live[stream_data] = own
    assert rs["streaming"] is False and rs["records"] >= 2
    t, _ = samples(rig, 0)
    gaps = np.diff(t)
    # Recordings of 0.1 s, each uploaded once done: the uploads leave gaps.
    assert gaps.max() > 10 / 4000 and np.median(gaps) == pytest.approx(1 / 4000, abs=1e-6)


def check_window(
    rig: Rig, cap: dict[str, Any], cid: int, level: float, pre: float, window: float
) -> None:
    """The crossing sample is at the trigger time, ``pre`` of the window before it, and the
    capture holds exactly the samples the scope had in that window (a gap in the data, from
    a stalled bus on a loaded machine, stays a gap)."""
    ch = next(c for c in cap["channels"] if c["id"] == cid)
    t = np.asarray(ch["t"])  # Seconds from t_ref = the trigger time.
    v = np.asarray(ch["v"])
    assert cap["t_ref"] == cap["trigger_time"]
    assert cap["window"] == pytest.approx([-pre * window, (1 - pre) * window], abs=1e-6)
    k = int(np.flatnonzero(t == 0.0)[0])
    assert v[k] >= level > v[k - 1], "the trigger sample crosses the level, its previous not"
    rt, rv = samples(rig, cid)
    t_ref = cap["t_ref"]
    if rig.scope.trigger_time == t_ref and rig.scope.capture_window is not None:
        # The latest capture: its exact bounds (the JSON's window is float32). A sample that
        # lands on the window's end within float rounding is in or out by the backend's
        # arithmetic, t0 <= t <= t1, which a tolerance here would second-guess (seen once:
        # the ring one sample longer than the capture at the end).
        t0, t1 = rig.scope.capture_window
    else:
        t0, t1 = t_ref - pre * window - 1e-6, t_ref + (1 - pre) * window + 1e-6
    inside = (rt >= t0) & (rt <= t1)

    def around(at: float) -> list[tuple[float, float]]:
        near = np.abs(rt - at) < 0.005
        return [(float(x - t_ref), float(y)) for x, y in zip(rt[near], rv[near], strict=True)]

    assert np.array_equal(rv[inside], v), (
        f"capture {len(v)} samples, {t[0] if len(t) else None}..{t[-1] if len(t) else None} s "
        f"from t_ref; ring {int(inside.sum())} inside [{t0 - t_ref}, {t1 - t_ref}]; ring around "
        f"the start {around(t0)}, around the end {around(t1)}; capture window {cap['window']}"
    )
    assert np.allclose(rt[inside] - t_ref, t, atol=1e-6)
    assert len(t) > 0.5 * window / float(np.median(np.diff(rt))), "most of the window"


async def test_level_trigger_with_20_percent_pre_trigger_from_pdo_data(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    await start_pdo(rig, period_ms=2.0)
    await put_channels(rig, [{"id": 0, "session": GENERIC, "address": "0x6064:00"}])
    start = int(d.read(0x6064, 0))
    level = start + REV / 2
    r = await rig.client.put(
        "/api/v1/scope/trigger",
        json={
            "mode": "single",
            "kind": "level",
            "channel": 0,
            "level": level,
            "slope": "rising",
            "pre": 0.2,
            "window_s": 0.5,
        },
    )
    assert r.status_code == 200, r.text
    st = await run(rig, "arm")
    assert st["state"] == "armed"
    await asyncio.sleep(0.2)
    await move(d, REV)
    await wait_reached(d)
    st = await wait_done(rig)
    assert st["state"] == "done" and not st["running"], st["state"]
    cap = (await rig.client.get("/api/v1/scope/capture")).json()
    check_window(rig, cap, 0, level, 0.2, 0.5)


async def test_level_trigger_by_the_drives_recorder(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00", "source": "recorder"},
            {"id": 1, "session": GENERIC, "address": "0x6077:00", "source": "recorder"},
        ],
    )
    start = int(d.read(0x6064, 0))
    level = start - REV / 2
    r = await rig.client.put(
        "/api/v1/scope/trigger",
        json={
            "mode": "single",
            "kind": "level",
            "channel": 0,
            "level": level,
            "slope": "falling",
            "pre": 0.2,
            "window_s": 0.5,
        },
    )
    assert r.status_code == 200, r.text
    await run(rig, "arm")
    await asyncio.sleep(0.3)
    # The drive waits for the crossing itself: status 1 (waiting for the trigger).
    assert d.read(0x2F06, 0) == 1
    await move(d, -REV)
    await wait_reached(d)
    st = await wait_done(rig)
    assert st["state"] == "done", st
    cap = (await rig.client.get("/api/v1/scope/capture")).json()
    ch = next(c for c in cap["channels"] if c["id"] == 0)
    t, v = np.asarray(ch["t"]), np.asarray(ch["v"])
    # The window is the drive's recording: 0.5 s at 4 kHz, the crossing at 20 %.
    data, trig = recording(d, 2)
    assert trig == 400 and len(data) == 2001
    assert np.array_equal(v, data[:, 0]) and np.array_equal(
        np.asarray(next(c for c in cap["channels"] if c["id"] == 1)["v"]), data[:, 1]
    )
    assert t[trig] == 0.0 and v[trig] <= level < v[trig - 1]
    assert np.allclose(np.diff(t), 1 / 4000, atol=1e-6)
    assert t[0] == pytest.approx(-0.1, abs=1e-6) and t[-1] == pytest.approx(0.4, abs=1e-6)
    assert cap["window"] == pytest.approx([-0.1, 0.4], abs=1e-6)


async def test_state_trigger_captures_the_enable(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    d.write(0x6040, 0, 0x06)
    await put_channels(
        rig, [{"id": 0, "session": GENERIC, "address": "0x6041:00", "source": "sdo"}]
    )
    r = await rig.client.put(
        "/api/v1/scope/trigger",
        json={"mode": "single", "kind": "state", "channel": 0, "pre": 0.5, "window_s": 0.4},
    )
    assert r.status_code == 200, r.text
    await run(rig, "arm")
    await asyncio.sleep(0.3)
    t_cmd = time.time()
    for word in (0x07, 0x0F):
        d.write(0x6040, 0, word)
    st = await wait_done(rig)
    assert st["state"] == "done", st
    cap = (await rig.client.get("/api/v1/scope/capture")).json()
    # The trigger is the poll that saw the new state: soon after the command.
    assert 0 <= cap["trigger_time"] - t_cmd < 0.2
    v = np.asarray(cap["channels"][0]["v"])
    t = np.asarray(cap["channels"][0]["t"])
    # Before the trigger the statusword says "ready to switch on", after it "enabled".
    assert (int(v[t < -0.05][0]) & 0x6F) == 0x21
    assert (int(v[t > 0.05][-1]) & 0x6F) == 0x27


async def test_recorded_samples_are_never_invented(fresh: Rig) -> None:
    rig = fresh
    await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00", "source": "sdo"},
            {"id": 1, "session": GENERIC, "address": "0x6077:00", "source": "recorder"},
        ],
    )
    await run(rig, "start")
    await asyncio.sleep(0.6)
    await run(rig, "stop")
    for cid in (0, 1):
        t, v = samples(rig, cid)
        assert len(t) and not np.isnan(v).any() and not np.isnan(t).any()
    # Streamed: one period apart within a recording, a gap at each restart, nothing filled
    # in and nothing twice.
    t, _ = samples(rig, 1)
    gaps = np.diff(t)
    assert gaps.min() > 0.9 / 4000 and np.median(gaps) == pytest.approx(1 / 4000, abs=1e-6)


async def test_fault_trigger_captures_the_fault(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    await put_channels(
        rig, [{"id": 0, "session": GENERIC, "address": "0x603F:00", "source": "sdo"}]
    )
    r = await rig.client.put(
        "/api/v1/scope/trigger",
        json={"mode": "single", "kind": "fault", "channel": 0, "pre": 0.25, "window_s": 0.4},
    )
    assert r.status_code == 200, r.text
    await run(rig, "arm")
    await asyncio.sleep(0.3)
    t_fault = time.time()
    d.raise_fault(0x8611)  # Following error: EMCY and the Fault state (CiA 402-2 §6.2).
    try:
        st = await wait_done(rig)
        assert st["state"] == "done", st
        cap = (await rig.client.get("/api/v1/scope/capture")).json()
        # The EMCY (or the first statusword poll in Fault) is the trigger: right after it.
        assert 0 <= cap["trigger_time"] - t_fault < 0.1
        t = np.asarray(cap["channels"][0]["t"])
        v = np.asarray(cap["channels"][0]["v"])
        assert set(v[t < -0.02].tolist()) == {0.0}  # No error code before the fault...
        assert set(v[t > 0.05].tolist()) == {float(0x8611)}  # ...the fault's after it.
    finally:
        d.write(0x6040, 0, 0x00)
        d.write(0x6040, 0, 0x80)  # Fault reset (CiA 402-2 §6.2.1: bit 7 rising edge).


async def test_normal_mode_rearms_after_each_capture(fresh: Rig) -> None:
    rig = fresh
    d = rig.drive()
    enable_pp(d)
    await start_pdo(rig, period_ms=2.0)
    await put_channels(rig, [{"id": 0, "session": GENERIC, "address": "0x6064:00"}])
    start = int(d.read(0x6064, 0))
    level = start + REV / 2
    r = await rig.client.put(
        "/api/v1/scope/trigger",
        json={"mode": "normal", "channel": 0, "level": level, "pre": 0.5, "window_s": 0.2},
    )
    assert r.status_code == 200, r.text
    await run(rig, "arm")
    before = rig.scope.captures
    windows = []
    for _ in range(2):
        await move(d, REV)  # Up through the level: a capture.
        await wait_reached(d)
        await asyncio.sleep(0.3)
        windows.append((await rig.client.get("/api/v1/scope/capture")).json())
        check_window(rig, windows[-1], 0, level, 0.5, 0.2)  # While it is the latest.
        await move(d, -REV)  # Down through it: no capture on a rising slope.
        await wait_reached(d)
    st = await run(rig, "stop")
    assert rig.scope.captures - before == 2
    assert windows[0]["trigger_time"] < windows[1]["trigger_time"]
    assert st["state"] == "idle"


async def test_channels_polled_over_profinet_are_sampled_together(fresh: Rig) -> None:
    # The LECSN-T over PROFINET: its link reads several objects in one PROFIdrive request,
    # so the scope samples the due channels together, at one time stamp each round.
    rig = fresh
    await put_channels(
        rig,
        [
            {"id": 0, "session": LECSN, "address": "0x6041:00", "source": "sdo"},
            {"id": 1, "session": LECSN, "address": "0x6064:00", "source": "sdo"},
        ],
    )
    await run(rig, "start")
    await asyncio.sleep(0.5)
    await run(rig, "stop")
    t0, v0 = samples(rig, 0)
    t1, _ = samples(rig, 1)
    assert len(t0) > 100, len(t0)  # hundreds of samples per second over loopback UDP
    assert np.array_equal(t0, t1)  # one request, one time stamp
    assert not np.isnan(v0).any()
