"""3D viewer: scene update rate a client sees, and the backend's CPU, with 4 axes moving.

Starts ``servodesk serve --sim`` (five simulated drives on a virtual bus, the viewer on a free
port) and moves four axes in profile velocity over the REST API (enable, 6060h = 3, 60FFh).
Then, for ``--seconds`` each:

1. no viewer client: the backend's CPU (process time / wall time) while the axes move;
2. one viewer client: a websocket client speaking viser's protocol (it sends one camera
   message, as a browser does, so the backend counts it and polls the drives at >= 30 Hz)
   counts the scene updates it receives per second: websocket frames, and position updates
   (SetOrientationMessage) of each moving axis; and the backend's CPU again.

    python bench/bench_viewer.py [--seconds 5] [--json]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from typing import Any

import msgspec.msgpack
import viser
import zstandard
from viser import _messages
from websockets.sync.client import connect

#: Sessions moved (the fifth simulated drive stands).
MOVED = ["cia402-generic-1", "hiwin-e-2", "ctmm04x-1", "lecsn-t-1"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def api(base: str, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
    req = urllib.request.Request(
        f"{base}/api/v1{path}",
        data=json.dumps(body).encode() if body is not None else None,
        method=method,
        headers={"Content-Type": "application/json"},
    )
    with urllib.request.urlopen(req, timeout=10) as r:
        return json.loads(r.read() or b"null")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (Linux /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure_cpu(pid: int, seconds: float) -> float:
    c0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    return (cpu_seconds(pid) - c0) / (time.monotonic() - t0)


class ViserClient:
    """A minimal viser websocket client: counts frames and scene messages as they arrive."""

    def __init__(self, url: str) -> None:
        self.ws = connect(
            url.replace("http://", "ws://"),
            subprotocols=[f"viser-v{viser.__version__}"],  # type: ignore[list-item]
            max_size=None,
        )
        camera = _messages.ViewerCameraMessage(
            wxyz=(1.0, 0.0, 0.0, 0.0),
            position=(0.0, -5.0, 4.0),
            fov=1.0,
            near=0.01,
            far=100.0,
            image_height=720,
            image_width=1280,
            look_at=(0.0, 0.0, 0.0),
            up_direction=(0.0, 0.0, 1.0),
        )
        self.ws.send(msgspec.msgpack.encode(camera.as_serializable_dict()))
        self.frames: list[float] = []
        self.updates: collections.Counter[str] = collections.Counter()
        self.counting = False
        self._zstd = zstandard.ZstdDecompressor()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        try:
            for raw in self.ws:
                assert isinstance(raw, bytes)
                if not self.counting:
                    continue
                self.frames.append(time.monotonic())
                n = int.from_bytes(raw[:8], "little")
                c = int.from_bytes(raw[8:16], "little")
                inner = msgspec.msgpack.decode(self._zstd.decompress(raw[16 : 16 + c], n))
                for m in inner["messages"]:
                    if m["type"] == "SetOrientationMessage":
                        self.updates[m["name"]] += 1
        except Exception:  # The connection closes at the end.
            return

    def close(self) -> None:
        self.ws.close()
        self._t.join(2.0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    port, vport = free_port(), free_port()
    env = {
        **os.environ,
        "SERVODESK_DATA_DIR": tempfile.mkdtemp(prefix="servodesk-bench-viewer-"),
        "SERVODESK_VIEWER_PORT": str(vport),
        "SERVODESK_SIM_CHANNEL": f"bench-viewer-{os.getpid()}",
    }
    proc = subprocess.Popen(
        [sys.executable, "-m", "servodesk", "serve", "--sim", "--port", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    result: dict[str, Any] = {"axes_moving": len(MOVED), "seconds": args.seconds}
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                if len(api(base, "GET", "/sessions")) >= 5:
                    break
            except OSError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                print("servodesk serve did not come up", file=sys.stderr)
                return 1
            time.sleep(0.3)
        info = api(base, "GET", "/viewer")
        scale = {a["session"]: a["scale"] for a in info["axes"]}
        for sid in MOVED:
            # 1/10 revolution per second: stays inside the simulated limit switches.
            api(base, "POST", f"/sessions/{sid}/state", {"command": "enable"})
            api(base, "PUT", f"/sessions/{sid}/objects/0x6060", {"value": 3})
            api(base, "PUT", f"/sessions/{sid}/objects/0x60FF", {"value": int(scale[sid] / 10)})
        time.sleep(1.0)
        result["backend_cpu_no_client"] = round(measure_cpu(proc.pid, args.seconds), 3)
        client = ViserClient(info["url"])
        time.sleep(1.5)  # The client is registered and the sessions poll faster.
        result["viewer_clients"] = api(base, "GET", "/viewer")["clients"]
        client.counting = True
        t0 = time.monotonic()
        result["backend_cpu_with_client"] = round(measure_cpu(proc.pid, args.seconds), 3)
        client.counting = False
        elapsed = time.monotonic() - t0
        states = {sid: api(base, "GET", f"/sessions/{sid}/state")["state"] for sid in MOVED}
        client.close()
        per_axis = {sid: round(client.updates[f"/axes/{sid}/rotor"] / elapsed, 1) for sid in MOVED}
        result["ws_frames_per_s"] = round(len(client.frames) / elapsed, 1)
        result["axis_updates_per_s"] = per_axis
        result["axis_updates_per_s_min"] = min(per_axis.values())
        result["states"] = states
        result["viewer_rate_hz"] = info["rate_hz"]
        result["cpu_count"] = os.cpu_count()
        for sid in MOVED:
            api(base, "PUT", f"/sessions/{sid}/objects/0x60FF", {"value": 0})
            api(base, "POST", f"/sessions/{sid}/state", {"command": "disable"})
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for k, v in result.items():
            print(f"{k}: {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
