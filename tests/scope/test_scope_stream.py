"""The scope's binary WebSocket: real clients on a real server, a fast one and a slow one.

The slow client never reads while the scope runs: a small receive buffer, a websockets queue
of one message and no compression, and the server's connections get a send buffer of a real
network's size rather than loopback's megabytes, so its socket backs up within seconds. The
fast client must still receive every sample the scope produced, count for count, with no
skipped frame and no gap in its sequence numbers; the slow client's queue drops whole frames,
counts them, flags the next frame, and never leaves a gap in its own sequence numbers either.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
import pytest_asyncio
import websockets

from servodesk.api.schemas_scope import ScopeStatusFrame
from servodesk.domain import scope_wire as wire
from servodesk.services.scope_channels import FRAME_PERIOD_S
from tests.scope.test_scope_service import (
    GENERIC,
    Rig,
    put_channels,
    run,
    serve,
    sim_settings,
    start_pdo,
)
from tests.scope.test_scope_service import fresh as fresh  # The fixture, on this rig.

pytestmark = pytest.mark.asyncio(loop_scope="module")

#: Send buffer of the server's connections: a real network holds far less than loopback's
#: megabytes, and a client that does not read must back up the server within the test.
SNDBUF = 32768


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rig(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Rig]:
    async with serve(sim_settings(tmp_path_factory.mktemp("data")), sndbuf=SNDBUF) as r:
        yield r


@dataclass
class Tally:
    """What one client received."""

    frames: int = 0
    seqs: list[int] = field(default_factory=list)
    skipped: int = 0
    flagged: int = 0
    samples: dict[int, int] = field(default_factory=dict)
    latencies: list[float] = field(default_factory=list)
    statuses: list[dict[str, Any]] = field(default_factory=list)

    def take(self, data: str | bytes) -> wire.Frame:
        now = time.time()
        assert isinstance(data, bytes), "the scope socket sends binary frames only"
        f = wire.decode_frame(data)
        self.frames += 1
        self.seqs.append(f.seq)
        self.skipped = f.skipped
        if f.skipped_before:
            self.flagged += 1
        if f.kind == wire.KIND_STATUS:
            assert f.status is not None
            # The body is what openapi.json says it is (the UI's type is generated from it).
            ScopeStatusFrame.model_validate(f.status)
            self.statuses.append(f.status)
        elif f.kind == wire.KIND_SAMPLES:
            for b in f.blocks:
                self.samples[b.id] = self.samples.get(b.id, 0) + b.n
                if b.n:
                    self.latencies.append(now - (f.t_ref + float(b.offsets()[-1])))
        return f


def slow_socket(port: int) -> socket.socket:
    """A connected TCP socket with a small receive buffer: it fills after a few frames."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    sock.setblocking(False)
    return sock


async def read_all(ws: Any, tally: Tally, quiet: float = 1.0) -> None:
    """Read until nothing arrives for ``quiet`` seconds."""
    with contextlib.suppress(TimeoutError):
        while True:
            tally.take(await asyncio.wait_for(ws.recv(), quiet))


async def test_a_slow_client_does_not_reduce_what_a_fast_client_receives(fresh: Rig) -> None:
    rig = fresh
    await start_pdo(rig, period_ms=1.0)
    await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00", "source": "pdo"},
            {"id": 1, "session": GENERIC, "address": "0x606C:00", "source": "pdo"},
            {"id": 2, "session": GENERIC, "address": "0x6041:00", "source": "sdo"},
            {"id": 3, "session": GENERIC, "address": "0x6077:00", "source": "recorder"},
        ],
    )
    proto = [wire.SUBPROTOCOL]
    fast_t, slow_t = Tally(), Tally()
    async with (
        websockets.connect(rig.ws_url, subprotocols=proto) as fast,  # type: ignore[arg-type]
        websockets.connect(
            rig.ws_url,
            subprotocols=proto,  # type: ignore[arg-type]
            sock=slow_socket(rig.port),
            max_queue=1,
            # Uncompressed: deflate shrinks these frames several times, and the buffers on
            # the way would then hold the whole test's data.
            compression=None,
        ) as slow,
    ):
        assert fast.subprotocol == wire.SUBPROTOCOL
        reader = asyncio.create_task(read_all(fast, fast_t, quiet=30.0))
        await asyncio.sleep(0.2)
        st = await run(rig, "start")
        assert st["clients"] == 2
        await asyncio.sleep(4.0)
        st = await run(rig, "stop")
        await asyncio.sleep(0.5)
        reader.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await reader
        await read_all(fast, fast_t, quiet=0.5)
        # Now the slow client reads what it still has.
        await read_all(slow, slow_t, quiet=1.0)
    produced = {c["id"]: c["samples"] for c in st["channels"]}
    assert all(n > 0 for n in produced.values()), produced
    # The fast client got every sample produced, nothing skipped, no gap in its sequence.
    assert fast_t.samples == produced
    assert fast_t.skipped == 0 and fast_t.flagged == 0
    assert fast_t.seqs == list(range(1, fast_t.frames + 1))
    assert produced[0] > 3000  # 1 ms SYNC for 4 s.
    lat = np.asarray(fast_t.latencies)
    assert np.percentile(lat, 50) < 0.5, np.percentile(lat, [50, 99])
    # The slow client's queue dropped whole frames, counted them and said so; its own
    # sequence numbers have no gap (skips are counted, not numbered).
    assert slow_t.skipped > 0, "the slow client never fell behind: the test proves nothing"
    assert slow_t.flagged >= 1
    assert slow_t.seqs == list(range(1, slow_t.frames + 1))
    assert sum(slow_t.samples.values()) < sum(produced.values())


async def test_frames_carry_real_sample_times_and_status(fresh: Rig) -> None:
    rig = fresh
    await start_pdo(rig, period_ms=2.0)
    await put_channels(
        rig,
        [
            {"id": 0, "session": GENERIC, "address": "0x6064:00", "source": "pdo"},
            {"id": 5, "session": GENERIC, "address": "0x6077:00", "source": "recorder"},
        ],
    )
    tally = Tally()
    times: dict[int, list[np.ndarray]] = {0: [], 5: []}
    async with websockets.connect(rig.ws_url, subprotocols=[wire.SUBPROTOCOL]) as ws:  # type: ignore[list-item]
        first = tally.take(await asyncio.wait_for(ws.recv(), 5))
        # A new client is told the scope's state first.
        assert first.kind == wire.KIND_STATUS and first.status is not None
        assert first.status["type"] == "status" and first.status["state"] == "idle"
        await run(rig, "start")
        end = time.monotonic() + 1.5
        last = time.monotonic()
        gaps: list[float] = []
        while time.monotonic() < end:
            f = tally.take(await asyncio.wait_for(ws.recv(), 5))
            now = time.monotonic()
            if f.kind == wire.KIND_SAMPLES:
                gaps.append(now - last)
                last = now
                for b in f.blocks:
                    times[b.id].append(f.t_ref + b.offsets())
                    if b.source == wire.SOURCE_RECORDER and b.times is None:
                        # A recording's samples are equidistant: the period, no times.
                        assert b.dt == pytest.approx(1 / 4000, abs=1e-9)
                    elif b.source == wire.SOURCE_RECORDER:
                        # A streamed piece that spans the restart between two recordings
                        # (docs/scope.md): its times, the period apart but for that gap.
                        d = np.diff(b.times)
                        assert b.dt == 0.0 and np.sum(d > 1.5 / 4000) == 1, d
                        assert np.allclose(d[d <= 1.5 / 4000], 1 / 4000, atol=1e-6)
                    else:
                        assert b.source == wire.SOURCE_PDO and b.dt == 0.0
        await run(rig, "stop")
    # About one frame per producer period, never a burst of them.
    assert np.median(gaps) == pytest.approx(FRAME_PERIOD_S, abs=0.5 * FRAME_PERIOD_S)
    for cid, parts in times.items():
        t = np.concatenate(parts)
        assert len(t) > 10, cid
        assert np.all(np.diff(t) > 0), cid  # Real times, in order, across frames.
    assert any(s["running"] for s in tally.statuses)
    rates = {c["id"]: c for c in tally.statuses[-1]["channels"]}
    assert rates[0]["rate_hz"] == pytest.approx(500, rel=0.25)


async def test_a_client_speaking_another_protocol_is_told_to_reload(rig: Rig) -> None:
    async with websockets.connect(rig.ws_url, subprotocols=["servodesk.v1"]) as ws:  # type: ignore[list-item]
        with pytest.raises(websockets.ConnectionClosed) as exc:
            await asyncio.wait_for(ws.recv(), 5)
    assert exc.value.rcvd is not None and exc.value.rcvd.code == 4000
