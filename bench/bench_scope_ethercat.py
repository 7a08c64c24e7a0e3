"""Scope channels from EtherCAT process data (issue 50): samples produced by the line's cycle
against samples delivered to a scope WebSocket client, on a line of simulated HIWIN E slaves.

A line of ``--slaves`` HIWIN E twins (their ESCs in a process of their own, SimulatedBus) on
one end of a veth pair; servodesk's app in this process with one session per slave, cyclic
data (inputs only, FreeRun) at each ``--periods`` entry, the 8 objects of the default TxPDO
1A00h of every slave as scope channels (source pdo), one binary WebSocket client
(/api/v1/scope/ws) reading every frame. Per period, two phases of ``--seconds``:

- ``baseline``: the cycle thread with no scope subscriber (the bare cycle loop).
- ``scope``: the same with the scope running and the client reading.

Each phase reports cycles per second, the interval between the inputs of slave 1 as they
reach the exchange (median, p99, max: the cycle's jitter), cycles lost (working counter short
or no frame back), the process's CPU per 1,000 cycle samples/s; the scope phase also the
samples the line produced (valid cycles x 8 channels x slaves), the samples the scope took
(its status) and the samples the client received, and the latency from a sample's time to
its arrival at the client (p50, p99). Periods below 1 ms are below what the API accepts
(services/cyclic.py MIN_PERIOD): the bench lowers the floor in its own process to measure
what the line achieves there. Needs root (veth, raw sockets).

    python bench/bench_scope_ethercat.py [--slaves 4] [--periods 1,0.5,0.25] [--seconds 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "backend"))

from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.domain import scope_wire as wire
from servodesk.services import pdo as pdosvc
from servodesk.services.scope import ScopeService
from servodesk.settings import Settings
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import create_veth

#: The default TxPDO 1A00h of the HIWIN E (profiles/hiwin-e, 000 §3.1.1): 8 objects.
OBJECTS = [
    "0x603F:00",
    "0x6041:00",
    "0x6061:00",
    "0x6064:00",
    "0x60B9:00",
    "0x60BA:00",
    "0x60F4:00",
    "0x60FD:00",
]


class Reader:
    """Reads the scope's binary frames on a thread of its own: every sample's time per
    channel, and the latency of each frame's newest sample (its time to the frame's arrival)."""

    def __init__(self, client: TestClient) -> None:
        self.client = client
        self.times: dict[int, list[np.ndarray]] = {}
        self.latency: list[float] = []
        self.skipped = 0
        self.frames = 0
        self.stop = threading.Event()
        self.ready = threading.Event()
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="bench-scope-ws", daemon=True)

    def _run(self) -> None:
        try:
            self._read()
        except BaseException as exc:  # Reported with the figures, not lost on a thread.
            self.error = exc

    def _read(self) -> None:
        with self.client.websocket_connect(
            "ws://127.0.0.1/api/v1/scope/ws", subprotocols=["servodesk.scope.v1"]
        ) as ws:
            self.ready.set()
            while not self.stop.is_set():
                data = ws.receive_bytes()
                now = time.time()
                frame = wire.decode_frame(data)
                self.skipped = frame.skipped
                if frame.kind != 1:
                    continue
                self.frames += 1
                newest = None
                for b in frame.blocks:
                    n = len(b.values)
                    if not n:
                        continue
                    offsets = (
                        np.asarray(b.times, dtype=np.float64)
                        if b.times is not None
                        else b.t0 + b.dt * np.arange(n, dtype=np.float64)
                    )
                    t = frame.t_ref + offsets
                    self.times.setdefault(b.id, []).append(t)
                    last = float(t[-1])
                    newest = last if newest is None else max(newest, last)
                if newest is not None:
                    self.latency.append(now - newest)

    def count(self, t0: float, t1: float) -> int:
        """Samples received with a time in (t0, t1]."""
        n = 0
        for parts in self.times.values():
            t = np.concatenate(parts)
            n += int(np.count_nonzero((t > t0) & (t <= t1)))
        return n


def _arrivals(transport: Any) -> tuple[list[float], Any]:
    """Inputs of slave 1 as the cycle thread hands them on (a receiver of the transport
    itself: the same cost in both phases)."""
    times: list[float] = []

    def on(data: bytes, t: float) -> None:
        times.append(time.perf_counter())

    transport.subscribe(0x181, on)
    return times, on


def _timed(transport: Any) -> tuple[list[float], Any]:
    """The time each cycle takes in the cycle thread (the LRW, the inputs handed on to the
    exchanges and their listeners): ``send_sync`` of the line's cycle thread, timed."""
    spent: list[float] = []
    inner = transport.send_sync

    def send_sync(counter: int | None = None) -> None:
        t0 = time.perf_counter()
        inner(counter)
        spent.append(time.perf_counter() - t0)

    transport.send_sync = send_sync
    return spent, inner


def _frozen(transport: Any) -> Any:
    """The line's lock held (no cycle starts) and the last cycle's hand-over finished: a
    moment at which the exchange's counters and the samples stamped so far agree."""
    lock = transport._shared.lock

    class Frozen:
        def __enter__(self) -> None:
            lock.acquire()
            time.sleep(0.005)  # A cycle hands its inputs on after releasing the lock.

        def __exit__(self, *exc: object) -> None:
            lock.release()

    return Frozen()


def _phase(
    client: TestClient, state: Any, sids: list[str], seconds: float, scope: bool, period: float
) -> dict[str, Any]:
    exchanges = [state.manager.get(s).cyclic for s in sids]
    transport = exchanges[0].transport
    times, cb = _arrivals(transport)
    producer = exchanges[0]._producer
    spent, inner = _timed(producer.transport)
    reader: Reader | None = None
    if scope:
        reader = Reader(client)
        reader.thread.start()
        reader.ready.wait(10)
    with _frozen(transport):
        if scope:
            r = client.post("/api/v1/scope/run", json={"action": "start"})
            assert r.status_code == 200, r.text
        counts0 = [ex.tx[0].count for ex in exchanges]
        missed0 = transport.missed
        t_start = time.time()
        times.clear()
        spent.clear()
        cpu0, w0 = time.process_time(), time.perf_counter()
    time.sleep(seconds)
    with _frozen(transport):
        cpu1, w1 = time.process_time(), time.perf_counter()
        counts1 = [ex.tx[0].count for ex in exchanges]
        missed1 = transport.missed
        t_end = time.time()
    transport.unsubscribe(0x181, cb)
    producer.transport.send_sync = inner
    cycle_us = np.array(spent) * 1e6 if spent else np.zeros(1)
    wall = w1 - w0
    if reader is not None:
        time.sleep(0.3)  # The samples up to t_end reach the client (frames every 10 ms).
        reader.stop.set()
        client.post("/api/v1/scope/run", json={"action": "stop"})  # A status frame ends it.
        reader.thread.join(5)
    d = np.diff(np.array(times)) * 1000 if len(times) > 1 else np.zeros(1)
    cycles = [c1 - c0 for c0, c1 in zip(counts0, counts1, strict=True)]
    produced = sum(cycles) * len(OBJECTS)
    out: dict[str, Any] = {
        "period_ms": period * 1000,
        "cycles_per_s": round(cycles[0] / wall, 1),
        "target_cycles_per_s": round(1 / period, 1),
        "interval_ms": {
            "median": round(float(np.median(d)), 4),
            "p99": round(float(np.percentile(d, 99)), 4),
            "max": round(float(np.max(d)), 4),
        },
        "cycle_us": {
            "median": round(float(np.median(cycle_us)), 1),
            "p99": round(float(np.percentile(cycle_us, 99)), 1),
        },
        "cycles_missed": missed1 - missed0,
        "cycle_samples_per_s": round(produced / wall, 1),
        "cpu_core": round((cpu1 - cpu0) / wall, 3),
        "cpu_ms_per_1000_samples_per_s": (
            round((cpu1 - cpu0) / wall * 1000 / (produced / wall / 1000), 3) if produced else None
        ),
    }
    if reader is not None:
        lat = np.array(reader.latency) * 1000 if reader.latency else np.zeros(1)
        received = reader.count(t_start, t_end)
        st = client.get("/api/v1/scope").json()
        out.update(
            {
                "produced": produced,
                "client_received": received,
                "lost": produced - received,
                "client_frames": reader.frames,
                "client_skipped_frames": reader.skipped,
                "reader_error": repr(reader.error) if reader.error else None,
                "latency_ms": {
                    "p50": round(float(np.percentile(lat, 50)), 2),
                    "p99": round(float(np.percentile(lat, 99)), 2),
                },
                "channel_errors": sorted({c["error"] for c in st["channels"] if c["error"]}),
            }
        )
    return out


def _sim_child(slave_nic: str, slaves: int, ready: Any, stop: Any) -> None:
    """The line's drives in a process of their own (as on a real line, the drives' work is
    not the server's): SimulatedBus steps them and runs their ESCs."""
    with SimulatedBus.start(
        drives=[("hiwin-e", i + 1) for i in range(slaves)],
        interface="ethercat",
        channel=slave_nic,
    ):
        ready.set()
        stop.wait()


def handover(frames: int = 100_000) -> dict[str, float]:
    """The scope's share of each frame, without the bus: the PDO source's listener as the
    cycle thread calls it (one TPDO of the 8 objects), and its flush as the scope's producer
    calls it; microseconds per frame."""
    from types import SimpleNamespace

    from servodesk.domain.address import ObjectAddress
    from servodesk.domain.profile_loader import ProfileCatalog
    from servodesk.services.scope_channels import ChannelConfig, ScopeChannel
    from servodesk.services.scope_sources import PdoSource

    profile = ProfileCatalog().get("hiwin-e")
    addresses = [ObjectAddress.parse(a) for a in OBJECTS]
    chans = []
    for i, a in enumerate(addresses):
        spec = profile.spec(a)
        assert spec is not None
        chans.append(ScopeChannel(ChannelConfig(i, "s", a, "pdo"), spec, "pdo"))
    src = PdoSource(SimpleNamespace(cyclic=None), chans)  # type: ignore[arg-type]
    listener = src._listener
    values = (0, 0x237, 8, 123456, 0, 0, 5, 0)
    t0 = time.perf_counter()
    for _ in range(frames):
        listener(time.monotonic(), addresses, values)
    t1 = time.perf_counter()
    src.flush()
    t2 = time.perf_counter()
    assert all(len(ch.buffer.take()[0]) == frames for ch in chans)
    return {
        "cycle_thread_us_per_frame": round((t1 - t0) / frames * 1e6, 3),
        "producer_us_per_frame": round((t2 - t1) / frames * 1e6, 3),
    }


def bench(slaves: int, periods: list[float], seconds: float) -> dict[str, Any]:
    # Below 1 ms the API refuses the period (services/cyclic.py MIN_PERIOD): lowered here only.
    vars(pdosvc)["MIN_PERIOD"] = min(periods)
    results: list[dict[str, Any]] = []
    ctx = multiprocessing.get_context("spawn")
    ready, stop = ctx.Event(), ctx.Event()
    with create_veth("sdbs") as pair, tempfile.TemporaryDirectory() as tmp:
        sim = ctx.Process(target=_sim_child, args=(pair.slave, slaves, ready, stop), daemon=True)
        sim.start()
        try:
            if not ready.wait(60):
                raise RuntimeError("the simulated line did not start")
            results = _run(pair.master, Path(tmp), slaves, periods, seconds)
        finally:
            stop.set()
            sim.join(10)
            if sim.is_alive():
                sim.kill()
    return {
        "benchmark": "scope_ethercat",
        "slaves": slaves,
        "channels": slaves * len(OBJECTS),
        "seconds_per_phase": seconds,
        "load_1min": round(os.getloadavg()[0], 2),
        "cores": os.cpu_count(),
        "scope_handover": handover(),
        "periods": results,
    }


def _run(
    nic: str, data_dir: Path, slaves: int, periods: list[float], seconds: float
) -> list[dict[str, Any]]:
    results = []
    app = create_app(Settings(data_dir=data_dir, viewer_port=0))
    with TestClient(
        app, base_url="http://127.0.0.1", headers={"X-Servodesk-Client": "bench"}
    ) as client:
        state = app.state.servodesk
        state.scope = ScopeService(state.manager, max_channels=slaves * len(OBJECTS))
        sids, tokens = [], {}
        for i in range(slaves):
            r = client.post(
                "/api/v1/sessions", json={"interface": "ethercat", "channel": nic, "node_id": i + 1}
            )
            assert r.status_code == 201, r.text
            sid = r.json()["id"]
            r = client.post(f"/api/v1/sessions/{sid}/control", json={"action": "take"})
            assert r.status_code == 200, r.text
            sids.append(sid)
            tokens[sid] = r.json()["token"]
        chans = [
            {"id": d * len(OBJECTS) + k, "session": sid, "address": a, "source": "pdo"}
            for d, sid in enumerate(sids)
            for k, a in enumerate(OBJECTS)
        ]
        for period in periods:
            for sid in sids:
                r = client.post(
                    f"/api/v1/sessions/{sid}/pdo/cyclic",
                    json={"sync_period_ms": period * 1000, "outputs": False},
                    headers={"X-Servodesk-Control": tokens[sid]},
                )
                if r.status_code != 200:
                    # The route's schema floor is 1 ms: below it, through the service.
                    client.portal.call(  # type: ignore[union-attr]
                        pdosvc.start_cyclic, state.manager.get(sid), period * 1000, False
                    )
            r = client.put("/api/v1/scope/channels", json={"channels": chans})
            assert r.status_code == 200, r.text
            time.sleep(0.5)
            base = _phase(client, state, sids, seconds, False, period)
            scope = _phase(client, state, sids, seconds, True, period)
            results.append({"baseline": base, "scope": scope})
            for sid in sids:
                client.delete(
                    f"/api/v1/sessions/{sid}/pdo/cyclic",
                    headers={"X-Servodesk-Control": tokens[sid]},
                )
    return results


def summary(out: dict[str, Any]) -> str:
    h = out["scope_handover"]
    lines = [
        f"{out['slaves']} slaves x 8 channels, load {out['load_1min']}; the scope's share of "
        f"a frame: {h['cycle_thread_us_per_frame']} us in the cycle thread, "
        f"{h['producer_us_per_frame']} us in its producer"
    ]
    for p in out["periods"]:
        b, s = p["baseline"], p["scope"]
        lines.append(
            f"{s['period_ms']:g} ms: baseline {b['cycles_per_s']} cycles/s "
            f"(interval p99 {b['interval_ms']['p99']} ms); scope {s['cycles_per_s']} cycles/s, "
            f"produced {s['produced']} received {s['client_received']} "
            f"lost {s['lost']}, latency p50 {s['latency_ms']['p50']} / p99 "
            f"{s['latency_ms']['p99']} ms, CPU {b['cpu_core']} -> {s['cpu_core']} core"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--slaves", type=int, default=4)
    ap.add_argument("--periods", default="1,0.5,0.25", help="cycle periods in ms")
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    res = bench(a.slaves, [float(x) / 1000 for x in a.periods.split(",")], a.seconds)
    print(json.dumps(res, indent=2) if a.json else summary(res))
