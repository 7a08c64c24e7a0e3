"""A real ``servodesk serve --sim`` process for tests that need a live server."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator

import httpx


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.contextmanager
def live_server(*extra: str, env: dict[str, str] | None = None) -> Iterator[str]:
    """Start ``servodesk serve --sim`` on a free port; yield its base URL; stop it."""
    port = free_port()
    data_dir = tempfile.mkdtemp(prefix="servodesk-live-")  # Never the user's ~/.servodesk.
    full_env = {
        **os.environ,
        "SERVODESK_SIM_CHANNEL": f"live-{os.getpid()}-{port}",
        "SERVODESK_DATA_DIR": data_dir,
        **(env or {}),
    }
    proc = subprocess.Popen(
        [sys.executable, "-m", "servodesk", "serve", "--sim", "--port", str(port), *extra],
        env=full_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 30
        while True:
            if proc.poll() is not None:
                out = proc.stdout.read() if proc.stdout else ""
                raise RuntimeError(f"servodesk serve exited with {proc.returncode}:\n{out}")
            try:
                r = httpx.get(f"{base}/api/v1/sessions", timeout=1)
                if r.status_code == 200 and r.json():
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError("servodesk serve did not come up within 30 s")
            time.sleep(0.2)
        yield base
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        shutil.rmtree(data_dir, ignore_errors=True)
