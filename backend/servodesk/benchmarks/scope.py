"""The live scope's benchmark (issue 7 "Measure"): ``servodesk bench scope [--json]``.

Three processes, as in a deployment: the simulated drives (each on its own bus: one SYNC
producer per network, CiA 301 §7.2.5), the servodesk server (uvicorn on 127.0.0.1, the real
application), and this process with the WebSocket clients (the ``websockets`` package,
offering permessage-deflate as a browser does; the server declines it, cli/serve.py
``ws_options``, and the JSON says what was negotiated). For each source (PDO at 1 ms SYNC, the
drive-side recorder at 4 kHz) the scope gets ``--channels`` objects of each of ``--drives``
drives, ``--clients`` clients read the stream, and the bench reports:

- samples produced per second (the limit) and what every client received per second;
- samples dropped for clients that keep up (must be 0): the produced count minus what each
  client received, after the scope stopped and the last frame arrived, and skipped frames;
- latency from each sample's time (the backend clock) to the client's receipt, p50/p99;
- CPU of the server process (its process time over wall time; 1.0 = one core busy), of the
  drives' process and of this one (the clients), and the load average.

Production is never faked: the samples counted are the scope's own count of what the drives
delivered. Where a source falls short of the issue's 4 kHz x 8 channels per drive, the JSON
says what it achieved and why (a 1 ms SYNC is the cyclic exchange's fastest period; the
recorder's data comes by SDO block upload, whose measured throughput bounds its share of
recording time). The recorder is measured three times in one run: ``recorder_segmented``
with the links' block upload switched off and whole recordings uploaded once done,
``recorder_whole`` the same by block upload, then ``recorder``, streamed while it records
(docs/scope.md "Streaming while recording"); ``recorder_block_vs_segmented`` and
``recorder_stream_vs_whole`` give the ratios, and every phase the CAN bus load its frames
would put on a 1 Mbit/s bus (``can_bus``, docs/scope.md "Block upload"). ``--recorder-rate``
asks the recorder for a lower sample rate (a divider of its 4 kHz), to find the rate a bus
carries.

Children: ``python -m servodesk.benchmarks.scope --child sim|server ...`` (internal).

Over 700 lines: one benchmark run (three processes, their start and teardown, the clients, the
tallies and the JSON report) read top to bottom; it is a script that ships with ``servodesk
bench``, not a library.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import selectors
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from servodesk.domain.address import ObjectAddress

PROFILE = "cia402-generic"
#: The drive objects a channel can take, in the order channels are assigned (the generic
#: twin: every object is both TPDO-mappable and recordable).
OBJECTS = [
    "0x6064:00",
    "0x606C:00",
    "0x60F4:00",
    "0x60FD:00",
    "0x6077:00",
    "0x6041:00",
    "0x603F:00",
    "0x6061:00",
]
#: TPDO layout carrying all of them on every SYNC (CiA 301: at most 64 bits per classic PDO).
TPDOS = [OBJECTS[0:2], OBJECTS[2:4], OBJECTS[4:8]]
#: The issue's target per drive: 8 channels at 4 kHz.
TARGET_HZ = 4000.0
SYNC_PERIOD_MS = 1.0
CLK_TCK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


# Processes ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class BusSpec:
    """Where one simulated drive is: a udp_multicast group and port of its own, its node."""

    channel: str
    port: int
    node: int

    def text(self) -> str:
        return f"{self.channel}/{self.port}/{self.node}"

    @classmethod
    def parse(cls, text: str) -> BusSpec:
        channel, port, node = text.split("/")
        return cls(channel, int(port), int(node))


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (all its threads), from /proc."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    # Fields after the command: state is [0], utime [11], stime [12] (proc(5)).
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        port: int = s.getsockname()[1]
        return port


def sim_child(buses: list[BusSpec], interface: str) -> int:
    """The simulated drives, each on its own bus, stepped by one runner thread."""
    import canopen

    from servodesk.domain.profile_loader import ProfileCatalog
    from servodesk.sim.canopen_device import SimCanopenDevice
    from servodesk.sim.engine import SimulatedDrive
    from servodesk.sim.runner import SimRunner

    catalog = ProfileCatalog()
    networks: list[Any] = []
    devices: list[SimCanopenDevice] = []
    drives: list[SimulatedDrive] = []
    for b in buses:
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.05
        kwargs: dict[str, Any] = {"interface": interface, "channel": b.channel}
        if interface == "udp_multicast":
            kwargs["port"] = b.port
        network.connect(**kwargs)
        drive = SimulatedDrive(catalog.get(PROFILE), b.node)
        dev = SimCanopenDevice(drive)
        network.add_node(dev)
        networks.append(network)
        devices.append(dev)
        drives.append(drive)
    runner = SimRunner(drives)
    for d in drives:
        d.step(d.CONTROL_PERIOD)  # Leave "Not ready to switch on" before boot-up.
    for dev in devices:
        dev.boot()
    runner.start()
    flag = {"stop": False}

    def on_signal(signum: int, frame: object) -> None:
        flag["stop"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    print("ready", flush=True)
    while not flag["stop"]:
        time.sleep(0.2)
    runner.stop()
    for dev in devices:
        with contextlib.suppress(Exception):
            dev.shutdown()
    for n in networks:
        with contextlib.suppress(Exception):
            n.disconnect()
    return 0


def server_child(buses: list[BusSpec], interface: str, max_channels: int, data_dir: str) -> int:
    """The servodesk application on uvicorn (127.0.0.1, a free port), sessions opened.

    On the event loop ``servodesk serve`` runs (cli/serve.py: uvloop where installed), so
    the bench measures the loop users get, not asyncio's own.
    """
    try:
        import uvloop
    except ImportError:
        return asyncio.run(_serve(buses, interface, max_channels, data_dir))
    with asyncio.Runner(loop_factory=uvloop.new_event_loop) as runner:
        return runner.run(_serve(buses, interface, max_channels, data_dir))


async def _serve(buses: list[BusSpec], interface: str, max_channels: int, data_dir: str) -> int:
    import uvicorn

    from servodesk.api.app import create_app
    from servodesk.links.base import LinkParams
    from servodesk.services.scope import ScopeService
    from servodesk.settings import Settings

    sim = None
    if interface == "virtual":
        # Drives in this process (the option --bus virtual): one bus each.
        from servodesk.sim.bus import SimulatedBus

        sim = [
            SimulatedBus.start([(PROFILE, b.node)], interface="virtual", channel=b.channel)
            for b in buses
        ]
    app = create_app(Settings(data_dir=Path(data_dir), viewer_port=0))
    state = app.state.servodesk
    manager = state.manager
    # The bench's scope takes every drive's channels (the application's scope: 8).
    state.scope = ScopeService(manager, max_channels=max_channels)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.bind(("127.0.0.1", 0))
    from servodesk.cli.serve import ws_options

    # The WebSocket settings ``servodesk serve`` uses (no permessage-deflate, as there).
    config = uvicorn.Config(app, log_level="warning", lifespan="on", **ws_options())
    server = uvicorn.Server(config)
    task = asyncio.create_task(server.serve(sockets=[sock]))
    while not server.started:
        if task.done():
            task.result()
        await asyncio.sleep(0.02)
    sids = []
    for b in buses:
        extra = {"port": b.port} if interface == "udp_multicast" else {}
        params = LinkParams(interface=interface, channel=b.channel, node_id=b.node, extra=extra)
        session = await manager.open(params, PROFILE, simulated=True)
        sids.append(session.id)
    print(json.dumps({"port": sock.getsockname()[1], "sessions": sids}), flush=True)
    links = [manager.get(sid).link for sid in sids]
    threading.Thread(
        target=_commands,
        args=(links, asyncio.get_running_loop()),
        name="bench-commands",
        daemon=True,
    ).start()
    await task
    if sim is not None:
        for s in sim:
            s.stop()
    return 0


#: The axes' motion for the bench (CiA 402-2: 6060h = 3 profile velocity, the controlword's
#: shutdown / switch on / enable operation, 60FFh the target velocity), written through each
#: session's link by the harness: a bench has no person in control to ask (docs/safety.md),
#: and the signals must move, not be constants.
_MOVE = (
    (ObjectAddress(0x6060), (3).to_bytes(1, "little", signed=True)),
    (ObjectAddress(0x6040), (0x0006).to_bytes(2, "little")),
    (ObjectAddress(0x6040), (0x0007).to_bytes(2, "little")),
    (ObjectAddress(0x6040), (0x000F).to_bytes(2, "little")),
)
_STOP = ((ObjectAddress(0x6040), (0x0006).to_bytes(2, "little")),)


async def _write_all(links: list[Any], writes: Any, velocity: int = 0) -> None:
    for i, link in enumerate(links):
        for address, data in writes:
            await link.write(address, data)
        if velocity:
            v = velocity * (i + 1)
            await link.write(ObjectAddress(0x60FF), v.to_bytes(4, "little", signed=True))


def _commands(links: list[Any], loop: asyncio.AbstractEventLoop) -> None:
    """The server child's control lines on stdin, one JSON reply each:

    - ``move`` / ``stop``: the axes turn at 20,000 inc/s x their number (profile velocity),
      or are switched off again (written through the links, not the API: see ``_MOVE``);
    - ``upload segmented`` / ``upload block``: the CANopen links' SDO upload for large reads
      (``CanopenLink.block_upload``), so one run measures both paths;
    - ``stream on`` / ``stream off``: the recorder source streams while the drive records, or
      uploads each recording once done (``RecorderSource.streaming_enabled``);
    - ``frames``: the SDO frames each session's link sent and received so far.
    """
    for line in sys.stdin:
        cmd = line.split()
        reply: dict[str, Any] = {"ok": True}
        if cmd in (["move"], ["stop"]):
            coro = _write_all(links, _MOVE, 20000) if cmd == ["move"] else _write_all(links, _STOP)
            try:
                asyncio.run_coroutine_threadsafe(coro, loop).result(timeout=20)
            except Exception as exc:  # the bench reports it and goes on
                reply = {"ok": False, "error": f"{cmd[0]}: {exc}"}
        elif cmd[:1] == ["upload"] and len(cmd) == 2:
            for link in links:
                if hasattr(link, "block_upload"):
                    link.block_upload = cmd[1] == "block"
        elif cmd[:1] == ["stream"] and len(cmd) == 2:
            from servodesk.services.scope_recorder import RecorderSource

            RecorderSource.streaming_enabled = cmd[1] == "on"
        elif cmd == ["frames"]:
            reply["frames"] = [
                int(getattr(link, "sdo_frames_tx", 0)) + int(getattr(link, "sdo_frames_rx", 0))
                for link in links
            ]
            reply["block_resent"] = [int(getattr(link, "block_resent", 0)) for link in links]
            reply["block_timeouts"] = [int(getattr(link, "block_timeouts", 0)) for link in links]
        else:
            reply = {"ok": False, "error": f"unknown command {line.strip()!r}"}
        print(json.dumps(reply), flush=True)


def _ask(proc: subprocess.Popen[str], command: str) -> dict[str, Any]:
    """Send a control line to the server child and return its reply."""
    assert proc.stdin is not None
    proc.stdin.write(command + "\n")
    proc.stdin.flush()
    line = _first_line(proc, 30.0)
    if not line:
        raise RuntimeError(f"the server did not answer {command!r}")
    reply: dict[str, Any] = json.loads(line)
    if not reply.get("ok"):
        raise RuntimeError(str(reply.get("error")))
    return reply


def _first_line(proc: subprocess.Popen[str], timeout: float = 60.0) -> str:
    assert proc.stdout is not None
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if sel.select(timeout=0.2):
            return proc.stdout.readline()
        if proc.poll() is not None:
            break
    return ""


@contextlib.contextmanager
def child(args: list[str]) -> Any:
    """A child process of this module; yields (process, its first stdout line)."""
    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "servodesk.benchmarks.scope", "--child", *args],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
        )
        try:
            line = _first_line(proc)
            if not line:
                err.seek(0)
                raise RuntimeError(f"the {args[0]} process did not start: {err.read()[-2000:]}")
            yield proc, line
        finally:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(15)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(5)
            if proc.stdout is not None:
                proc.stdout.close()
            if proc.stdin is not None:
                with contextlib.suppress(OSError):
                    proc.stdin.close()


# Clients -----------------------------------------------------------------------------------


@dataclass
class Client:
    """One WebSocket client reading as fast as it can, tallying what it gets.

    The receive loop only stamps each message with its receipt time and keeps it; decoding
    waits until the phase is over. Five clients share this process's event loop: decoding
    one client's frame while the next client's frame waits would add this process's own
    CPU time to the next frame's latency (and a decode backlog would keep growing it).
    """

    messages: list[tuple[float, bytes]] = field(default_factory=list)
    last_rx: float = 0.0
    #: The WebSocket extensions the server accepted ("none" for none).
    extensions: str = ""
    ready: asyncio.Event = field(default_factory=asyncio.Event)
    error: str | None = None
    # Filled by tally() from the messages.
    frames: int = 0
    samples: int = 0
    skipped: int = 0
    flagged: int = 0
    seq_gaps: int = 0

    def tally(self, w0: float, w1: float) -> tuple[int, int, int, np.ndarray]:
        """Decode everything received; count it, and return (samples, frames, bytes,
        latencies [s]) of the frames that arrived within ``[w0, w1)`` (receipt times)."""
        from servodesk.domain import scope_wire as wire

        in_samples = in_frames = in_bytes = 0
        latencies: list[np.ndarray] = []
        last_seq = 0
        for now, msg in self.messages:
            f = wire.decode_frame(msg)
            inside = w0 <= now < w1
            self.frames += 1
            if f.seq != last_seq + 1:
                self.seq_gaps += 1
            last_seq = f.seq
            self.skipped = f.skipped
            if f.skipped_before:
                self.flagged += 1
            if inside:
                in_frames += 1
                in_bytes += len(msg)
            if f.kind != wire.KIND_SAMPLES:
                continue
            for b in f.blocks:
                self.samples += b.n
                if inside and b.n:
                    in_samples += b.n
                    latencies.append(now - (f.t_ref + b.offsets()))
        lat = np.concatenate(latencies) if latencies else np.zeros(0)
        return in_samples, in_frames, in_bytes, lat


async def read_stream(url: str, c: Client, compression: bool) -> None:
    import websockets

    from servodesk.domain import scope_wire as wire

    try:
        async with websockets.connect(
            url,
            subprotocols=[wire.SUBPROTOCOL],  # type: ignore[list-item]
            compression="deflate" if compression else None,
            max_size=None,
        ) as ws:
            headers = ws.response.headers if ws.response is not None else {}
            c.extensions = headers.get("Sec-WebSocket-Extensions", "") or "none"
            c.ready.set()
            keep = c.messages.append
            async for msg in ws:
                # Receipt: the message as the application gets it (after the websockets
                # layer's decompression, as a browser's onmessage), before any decoding.
                keep((time.time(), msg))  # type: ignore[arg-type]
                c.last_rx = time.monotonic()
    except Exception as exc:  # Reported in the JSON, not a traceback.
        c.error = f"{type(exc).__name__}: {exc}"
        c.ready.set()


# The control plane over HTTP ---------------------------------------------------------------


@dataclass(frozen=True)
class Reply:
    """One HTTP answer of the server: status, body text, and what was asked (for messages)."""

    method: str
    path: str
    status_code: int
    text: str

    def json(self) -> Any:
        return json.loads(self.text)


class Http:
    """The bench's REST calls, on the standard library (urllib in a worker thread).

    The command ships in the wheel (``servodesk bench scope``), so it may use only the
    wheel's dependencies; httpx is a development one (pyproject ``dependency-groups``). The
    calls configure and read the scope outside the measured stream, so a thread per call is
    no cost to the figures. An HTTP error status is returned, not raised, as the callers
    check it themselves.
    """

    def __init__(self, base: str, timeout: float = 60.0) -> None:
        self.base = base
        self.timeout = timeout
        #: The bench is one client (docs/ui.md "One token per tab"); the control token of each
        #: session it took is sent with the writes to that session.
        self.client = f"servodesk-bench-{os.getpid()}"
        self.tokens: dict[str, str] = {}

    async def __aenter__(self) -> Http:
        return self

    async def __aexit__(self, *exc: object) -> None:
        return None  # No connection is kept between calls.

    def _call(self, method: str, path: str, body: Any) -> Reply:
        data = None if body is None else json.dumps(body).encode("utf-8")
        req = urllib.request.Request(self.base + path, data=data, method=method)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        req.add_header("X-Servodesk-Client", self.client)
        for sid, token in self.tokens.items():
            if path.startswith(f"/api/v1/sessions/{sid}/"):
                req.add_header("X-Servodesk-Control", token)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as r:
                return Reply(method, path, r.status, r.read().decode("utf-8", "replace"))
        except urllib.error.HTTPError as e:
            return Reply(method, path, e.code, e.read().decode("utf-8", "replace"))

    async def get(self, path: str) -> Reply:
        return await asyncio.to_thread(self._call, "GET", path, None)

    async def post(self, path: str, json: Any = None) -> Reply:
        return await asyncio.to_thread(self._call, "POST", path, {} if json is None else json)

    async def put(self, path: str, json: Any = None) -> Reply:
        return await asyncio.to_thread(self._call, "PUT", path, {} if json is None else json)

    async def delete(self, path: str) -> Reply:
        return await asyncio.to_thread(self._call, "DELETE", path, None)


# The bench ---------------------------------------------------------------------------------


async def _phase(
    http: Http,
    url: str,
    sids: list[str],
    source: str,
    *,
    seconds: float,
    channels: int,
    clients: int,
    compression: bool,
    pids: dict[str, int],
    control: Callable[[str], dict[str, Any]] | None = None,
    recorder_rate: float = 0.0,
) -> dict[str, Any]:
    """One source: configure, stream to the clients, measure, stop, drain, count.

    ``recorder_segmented`` is the recorder with the links' block upload switched off
    (``control``: the server child's command line), the baseline of ``recorder``.
    """
    scope_source = "recorder" if source.startswith("recorder") else source

    async def ok(r: Reply) -> Any:
        if r.status_code >= 300:
            raise RuntimeError(f"{r.method} {r.path}: {r.status_code} {r.text}")
        return r.json()

    for sid in sids:
        if source == "pdo":
            layout = {
                "pdos": [
                    *(
                        {
                            "direction": "tx",
                            "number": i + 1,
                            "entries": entries,
                            "transmission_type": 1,
                            "enabled": True,
                        }
                        for i, entries in enumerate(TPDOS)
                    ),
                    {"direction": "tx", "number": 4, "enabled": False},
                ]
            }
            rep = await ok(await http.post(f"/api/v1/sessions/{sid}/pdo/apply", json=layout))
            if not rep["ok"]:
                raise RuntimeError(f"{sid}: the PDO mapping failed: {rep['error']}")
            await ok(
                await http.post(
                    f"/api/v1/sessions/{sid}/pdo/cyclic", json={"sync_period_ms": SYNC_PERIOD_MS}
                )
            )
        else:
            await http.delete(f"/api/v1/sessions/{sid}/pdo/cyclic")
    rate = recorder_rate if scope_source == "recorder" else 0.0
    chans = [
        {
            "id": d * channels + k,
            "session": sid,
            "address": OBJECTS[k],
            "source": scope_source,
            "rate_hz": rate,
        }
        for d, sid in enumerate(sids)
        for k in range(channels)
    ]
    await ok(await http.put("/api/v1/scope/channels", json={"channels": chans}))
    tallies = [Client() for _ in range(clients)]
    tasks = [asyncio.create_task(read_stream(url, c, compression)) for c in tallies]
    for c in tallies:
        await c.ready.wait()
    await ok(await http.post("/api/v1/scope/run", json={"action": "start"}))
    await asyncio.sleep(1.5)  # Sources settle (first recordings, first frames).

    def produced(st: dict[str, Any]) -> int:
        return sum(int(ch["samples"]) for ch in st["channels"])

    st0 = await ok(await http.get("/api/v1/scope"))
    frames0 = await asyncio.to_thread(control, "frames") if control is not None else None
    cpu0 = {k: cpu_seconds(p) for k, p in pids.items()}
    t0 = time.time()
    w0 = time.perf_counter()
    await asyncio.sleep(seconds)
    wall = time.perf_counter() - w0
    t1 = time.time()
    cpu1 = {k: cpu_seconds(p) for k, p in pids.items()}
    frames1 = await asyncio.to_thread(control, "frames") if control is not None else None
    st1 = await ok(await http.get("/api/v1/scope"))
    cyclic = []
    if source == "pdo":
        for sid in sids:
            cs = await ok(await http.get(f"/api/v1/sessions/{sid}/pdo/cyclic"))
            cyclic.append(
                {
                    "session": sid,
                    "tpdo_frames_per_s": cs["frames_per_s"],
                    "syncs": cs.get("syncs"),
                }
            )
    final = await ok(await http.post("/api/v1/scope/run", json={"action": "stop"}))
    # Drain: every frame sent before the stop reaches the clients that keep up.
    end = time.monotonic() + 15.0
    while time.monotonic() < end:
        await asyncio.sleep(0.25)
        if all(time.monotonic() - c.last_rx > 1.0 for c in tallies):
            break
    for t in tasks:
        t.cancel()
    for t in tasks:
        with contextlib.suppress(asyncio.CancelledError):
            await t
    total = produced(final)
    prod_rate = (produced(st1) - produced(st0)) / wall
    per_channel = [float(ch["throughput_hz"] or 0.0) for ch in st1["channels"]]
    out_clients: list[dict[str, Any]] = []
    delivered: list[float] = []
    lats: list[np.ndarray] = []
    for c in tallies:
        n_samples, n_frames, n_bytes, lat_c = c.tally(t0, t1)
        lats.append(lat_c)
        delivered.append(round(n_samples / wall, 1))
        out_clients.append(
            {
                "delivered_samples_per_s": delivered[-1],
                "frames_per_s": round(n_frames / wall, 1),
                "kbytes_per_s": round(n_bytes / wall / 1000, 1),
                "received_total": c.samples,
                "dropped_samples": total - c.samples,
                "skipped_frames": c.skipped,
                "seq_gaps": c.seq_gaps,
                "error": c.error,
            }
        )
    lat = np.concatenate(lats) if lats else np.zeros(0)
    hz = 1000.0 / SYNC_PERIOD_MS if source == "pdo" else (rate or TARGET_HZ)
    n_expected = len(sids) * channels * hz
    result: dict[str, Any] = {
        "source": source,
        "ws_extensions_negotiated": sorted({c.extensions for c in tallies}),
        "channels": len(chans),
        "target_samples_per_s": len(sids) * channels * TARGET_HZ,
        "source_max_samples_per_s": n_expected,
        "produced_samples_per_s": round(prod_rate, 1),
        "produced_per_channel_hz": {
            "min": round(min(per_channel), 1),
            "median": round(statistics.median(per_channel), 1),
            "max": round(max(per_channel), 1),
        },
        "produced_total": total,
        "delivered_per_client_samples_per_s": {
            "min": min(delivered),
            "max": max(delivered),
        },
        "delivered_over_produced": round(min(delivered) / prod_rate, 4) if prod_rate else None,
        "dropped_samples_fast_clients": sum(max(0, total - c.samples) for c in tallies),
        "skipped_frames_fast_clients": sum(c.skipped for c in tallies),
        "latency_ms": {
            "p50": round(float(np.percentile(lat, 50)) * 1000, 2) if lat.size else None,
            "p99": round(float(np.percentile(lat, 99)) * 1000, 2) if lat.size else None,
            "max": round(float(lat.max()) * 1000, 2) if lat.size else None,
            "samples": int(lat.size),
        },
        "cpu_core_fraction": {
            k: round((cpu1[k] - cpu0[k]) / wall, 3) for k in pids if cpu0[k] == cpu0[k]
        },
        "clients": out_clients,
        "seconds": round(wall, 2),
    }
    if cyclic:
        result["cyclic"] = cyclic
    if scope_source == "recorder":
        result["recorders"] = st1.get("recorders", [])
    if frames0 is not None and frames1 is not None:
        result["can_bus"] = _bus_load(frames0, frames1, wall, cyclic)
    result["why"] = _why(result, channels)
    return result


#: A CAN 2.0A data frame with 8 data bytes: 111 bits (108 from SOF to EOF, 3 of
#: intermission) and at most 24 stuff bits (one per 4 bits of the 98 stuffed ones), so at most
#: 135 bits; at 1 Mbit/s, at least 7407 such frames per second fit (the issue's 7,000-8,000).
CAN_FRAME_BITS = 135
CAN_BITRATE = 1_000_000


def _bus_load(
    f0: dict[str, Any], f1: dict[str, Any], wall: float, cyclic: list[dict[str, Any]]
) -> dict[str, Any]:
    """The share of a 1 Mbit/s CAN bus the scope's frames take, per drive's bus.

    Counted, not estimated: the SDO frames each session's link sent and received in the
    window (the recorder's upload, its status polls, the session's state poll); with PDO, also
    the TPDOs the cyclic exchange received and one SYNC per period. Every frame counts as a
    full 8-byte frame at worst-case stuffing (CAN_FRAME_BITS), an upper bound.
    """
    sdo = [(b - a) / wall for a, b in zip(f0["frames"], f1["frames"], strict=True)]
    per_bus = list(sdo)
    for i, c in enumerate(cyclic):
        per_bus[i] += float(c.get("tpdo_frames_per_s") or 0.0) + 1000.0 / SYNC_PERIOD_MS
    ceiling = CAN_BITRATE / CAN_FRAME_BITS
    return {
        "bitrate": CAN_BITRATE,
        "bits_per_frame": CAN_FRAME_BITS,
        "ceiling_frames_per_s": round(ceiling),
        "sdo_frames_per_s_per_drive": [round(x) for x in sdo],
        "frames_per_s_per_drive": [round(x) for x in per_bus],
        "bus_fraction_per_drive_bus": {
            "min": round(min(per_bus) / ceiling, 3),
            "median": round(statistics.median(per_bus) / ceiling, 3),
            "max": round(max(per_bus) / ceiling, 3),
        },
        "bus_fraction_if_all_drives_shared_one_bus": round(sum(per_bus) / ceiling, 3),
        "block_segments_resent": [
            b - a for a, b in zip(f0["block_resent"], f1["block_resent"], strict=True)
        ],
        "block_sub_blocks_timed_out": [
            b - a for a, b in zip(f0["block_timeouts"], f1["block_timeouts"], strict=True)
        ],
    }


def _ratios(block: dict[str, Any], segmented: dict[str, Any]) -> dict[str, Any]:
    """Block upload over the segmented baseline, measured in the same run."""

    def ratio(a: float | None, b: float | None) -> float | None:
        return round(a / b, 3) if a is not None and b else None

    return {
        "produced_samples_per_s": ratio(
            block["produced_samples_per_s"], segmented["produced_samples_per_s"]
        ),
        "latency_p50": ratio(block["latency_ms"]["p50"], segmented["latency_ms"]["p50"]),
        "latency_p99": ratio(block["latency_ms"]["p99"], segmented["latency_ms"]["p99"]),
    }


def _why(r: dict[str, Any], channels: int) -> str:
    """What limited production, in words, from the figures."""
    drives = r["channels"] // max(channels, 1)
    per_drive = r["produced_samples_per_s"] / max(drives, 1)
    target = channels * TARGET_HZ
    if r["source"] == "pdo":
        return (
            f"PDO at a {SYNC_PERIOD_MS:g} ms SYNC (the cyclic exchange's shortest period, "
            f"services/cyclic.py MIN_PERIOD) carries {1000 / SYNC_PERIOD_MS:g} samples/s per "
            f"channel: at most {channels * 1000 / SYNC_PERIOD_MS:g} per drive against the "
            f"target {target:g}; achieved {per_drive:.0f} per drive"
            + (
                f" ({per_drive / (channels * 1000 / SYNC_PERIOD_MS) * 100:.0f} % of the SYNC "
                "rate: SYNCs and TPDOs lost to CPU load show up here)"
            )
        )
    recs = r.get("recorders") or []
    share = [x["recording_share"] for x in recs if x.get("recording_share") is not None]
    upload = [x["upload_bytes_per_s"] for x in recs if x.get("upload_bytes_per_s")]
    hz = r["source_max_samples_per_s"] / max(r["channels"], 1)
    need = channels * hz * 4
    block = r["source"] != "recorder_segmented"
    streamed = any(x.get("streaming") for x in recs)
    text = (
        f"the recorder samples at {hz:g} Hz inside the drive, and its data comes by "
        f"{'block' if block else 'segmented'} SDO upload, "
        f"{'streamed while it records' if streamed else 'each recording once done'}: "
        f"{channels} channels x {hz:g} Hz x 4 bytes = {need / 1000:.0f} kB/s per drive"
    )
    if upload:
        per = "889 bytes per acknowledged sub-block" if block else "7 bytes per round trip"
        text += f" against {statistics.median(upload) / 1000:.1f} kB/s uploaded ({per})"
    if share:
        text += f", so it records {statistics.median(share) * 100:.0f} % of the time"
    lag = [x["stream_lag_s"] for x in recs if x.get("stream_lag_s") is not None]
    if streamed and lag:
        text += f"; the newest sample was {statistics.median(lag) * 1000:.0f} ms old when read"
    skips = sum(int(x.get("stream_skips") or 0) for x in recs)
    if streamed and skips:
        text += (
            f"; the streams skipped ahead {skips} times (gaps): the upload carries less "
            "than the recorder takes at this rate"
        )
    return text + f"; achieved {per_drive:.0f} samples/s per drive (target {target:g})"


async def bench(
    *,
    seconds: float,
    drives: int,
    clients: int,
    channels: int,
    sources: list[str],
    interface: str,
    compression: bool,
    recorder_rate: float = 0.0,
) -> dict[str, Any]:
    if not 1 <= channels <= len(OBJECTS):
        raise ValueError(f"--channels must be 1..{len(OBJECTS)}")
    tag = os.getpid()
    buses = [
        BusSpec(
            f"239.74.{(tag >> 8) % 250 + 1}.{(tag + i) % 250 + 1}"
            if interface == "udp_multicast"
            else f"bench-scope-{tag}-{i}",
            _free_udp_port() if interface == "udp_multicast" else 0,
            i + 1,
        )
        for i in range(drives)
    ]
    bus_arg = ",".join(b.text() for b in buses)
    data_dir = tempfile.mkdtemp(prefix="servodesk-bench-scope-")
    out: dict[str, Any] = {
        "what": f"live scope: {drives} simulated {PROFILE} drives x {channels} channels, "
        f"{clients} WebSocket clients over a uvicorn server on 127.0.0.1",
        "bus": (
            "udp_multicast, one group and port per drive; the drives in their own process"
            if interface == "udp_multicast"
            else "python-can virtual, one channel per drive; the drives in the server process"
        ),
        "compression_offered": "permessage-deflate" if compression else "none",
        "recorder_rate_hz": recorder_rate or TARGET_HZ,
        "cpus": os.cpu_count(),
        "load_before": [round(x, 2) for x in os.getloadavg()],
        "phases": {},
    }
    with contextlib.ExitStack() as stack:
        pids: dict[str, int] = {"bench_clients": os.getpid()}
        if interface == "udp_multicast":
            sim_proc, _ = stack.enter_context(child(["sim", "--buses", bus_arg]))
            pids["drives"] = sim_proc.pid
        server_proc, line = stack.enter_context(
            child(
                [
                    "server",
                    "--buses",
                    bus_arg,
                    "--interface",
                    interface,
                    "--max-channels",
                    str(drives * channels),
                    "--data-dir",
                    data_dir,
                ]
            )
        )
        pids["server"] = server_proc.pid
        info = json.loads(line)
        base = f"http://127.0.0.1:{info['port']}"
        url = f"ws://127.0.0.1:{info['port']}/api/v1/scope/ws"
        sids: list[str] = info["sessions"]
        async with Http(base, timeout=60) as http:
            # Control of each drive (the PDO mapping is a write: docs/ui.md), then the axes
            # move (profile velocity, CiA 402-2 §6.6): signals, not constants.
            for sid in sids:
                r = await http.post(f"/api/v1/sessions/{sid}/control", json={"action": "take"})
                if r.status_code != 200:
                    raise RuntimeError(f"{sid}: control refused: {r.status_code} {r.text}")
                http.tokens[sid] = r.json()["token"]

            def control(command: str) -> dict[str, Any]:
                return _ask(server_proc, command)

            control("move")

            # The recorder is measured three times in the same run: whole recordings by
            # segmented upload (as before issue 50), by block upload, then streamed.
            whole = ["recorder_segmented", "recorder_whole"]
            phases = [
                p
                for source in sources
                for p in ([*whole, source] if source == "recorder" else [source])
            ]
            for source in phases:
                if source.startswith("recorder"):
                    control(
                        "upload segmented" if source == "recorder_segmented" else "upload block"
                    )
                    control("stream off" if source in whole else "stream on")
                out["phases"][source] = await _phase(
                    http,
                    url,
                    sids,
                    source,
                    seconds=seconds,
                    channels=channels,
                    clients=clients,
                    compression=compression,
                    pids=pids,
                    control=control,
                    recorder_rate=recorder_rate,
                )
            got = out["phases"]
            if {"recorder_whole", "recorder_segmented"} <= got.keys():
                out["recorder_block_vs_segmented"] = _ratios(
                    got["recorder_whole"], got["recorder_segmented"]
                )
            if {"recorder", "recorder_whole"} <= got.keys():
                out["recorder_stream_vs_whole"] = _ratios(got["recorder"], got["recorder_whole"])
            control("stop")
            for sid in sids:
                await http.post(f"/api/v1/sessions/{sid}/control", json={"action": "release"})
    out["load_after"] = [round(x, 2) for x in os.getloadavg()]
    return out


def summary(out: dict[str, Any]) -> str:
    lines = [out["what"], f"bus: {out['bus']}; load {out['load_before']} -> {out['load_after']}"]
    for name, p in out["phases"].items():
        lines.append(
            f"{name}: produced {p['produced_samples_per_s']:.0f} samples/s (source max "
            f"{p['source_max_samples_per_s']:.0f}, target {p['target_samples_per_s']:.0f}); "
            f"per client {p['delivered_per_client_samples_per_s']['min']:.0f}-"
            f"{p['delivered_per_client_samples_per_s']['max']:.0f}/s; dropped "
            f"{p['dropped_samples_fast_clients']}; latency p50 {p['latency_ms']['p50']} ms, "
            f"p99 {p['latency_ms']['p99']} ms; CPU {p['cpu_core_fraction']}"
        )
        lines.append(f"  why: {p['why']}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    sources = [s.strip() for s in args.sources.split(",") if s.strip()]
    out = asyncio.run(
        bench(
            seconds=args.seconds,
            drives=args.drives,
            clients=args.clients,
            channels=args.channels,
            sources=sources,
            interface=args.bus,
            compression=not args.no_compression,
            recorder_rate=args.recorder_rate,
        )
    )
    if args.json:
        json.dump(out, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        print(summary(out))
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--child"]:
        cp = argparse.ArgumentParser(prog="servodesk.benchmarks.scope --child")
        cp.add_argument("kind", choices=["sim", "server"])
        cp.add_argument("--buses", required=True)
        cp.add_argument("--interface", default="udp_multicast")
        cp.add_argument("--max-channels", type=int, default=8)
        cp.add_argument("--data-dir", default=".")
        a = cp.parse_args(argv[1:])
        buses = [BusSpec.parse(x) for x in a.buses.split(",")]
        if a.kind == "sim":
            return sim_child(buses, a.interface)
        return server_child(buses, a.interface, a.max_channels, a.data_dir)
    from servodesk.cli.bench import add_scope_arguments

    p = argparse.ArgumentParser(
        prog="bench_scope", description="Live scope benchmark (issue 7 'Measure')."
    )
    add_scope_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
