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
    # The server's output goes to a file: a pipe nobody drains fills up (64 kB of access
    # log) and blocks the server's event loop in a log write.
    log_file = tempfile.TemporaryFile("w+")  # noqa: SIM115 - closed in the finally below
    proc = subprocess.Popen(
        [sys.executable, "-m", "servodesk", "serve", "--sim", "--port", str(port), *extra],
        env=full_env,
        stdout=log_file,
        stderr=subprocess.STDOUT,
        text=True,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 30
        while True:
            if proc.poll() is not None:
                log_file.seek(0)
                out = log_file.read()
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
        log_file.close()
        shutil.rmtree(data_dir, ignore_errors=True)
