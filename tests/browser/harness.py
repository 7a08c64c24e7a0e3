"""Shared pieces of the browser tests: finding Debian's Chromium and running the real backend.

Used by conftest.py (pytest fixtures) and shoot.py (screenshots for review). Playwright
never downloads a browser here: it drives the system Chromium through ``executable_path``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

CHROMIUM_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


class HarnessError(RuntimeError):
    """The browser test environment is not usable; the message says what to do."""


def chromium_executable() -> str:
    """Path of the Chromium to drive: $SERVODESK_CHROMIUM, else `chromium` on PATH."""
    path = os.environ.get("SERVODESK_CHROMIUM") or shutil.which("chromium")
    if not path or not Path(path).is_file():
        raise HarnessError(
            "Chromium not found (set SERVODESK_CHROMIUM or install Debian's package: "
            "apt-get install -y chromium; the Makefile does this). The browser tests never "
            "download a browser."
        )
    return path


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _get(url: str, timeout: float = 2.0) -> tuple[int, str]:
    with urllib.request.urlopen(url, timeout=timeout) as r:
        return r.status, r.read().decode("utf-8", "replace")


@contextlib.contextmanager
def running_server(
    timeout: float = 40.0, args: Sequence[str] = (), env: Mapping[str, str] | None = None
) -> Iterator[str]:
    """Start ``servodesk serve --sim`` (plus ``args``, with ``env`` added to the environment)
    on a free port, wait for /api/v1/health, yield its URL."""
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    log = tempfile.NamedTemporaryFile(  # noqa: SIM115 - kept open for the process's lifetime
        prefix="servodesk-serve-", suffix=".log", delete=False
    )
    cmd = [sys.executable, "-m", "servodesk", "serve", "--sim", "--port", str(port), *args]
    # A data directory of its own: never the user's ~/.servodesk (backups, audit log).
    data_dir = tempfile.mkdtemp(prefix="servodesk-browser-")
    # The 3D view page needs the viewer: give it a free port of its own.
    environ = {
        **os.environ,
        "SERVODESK_DATA_DIR": data_dir,
        "SERVODESK_VIEWER_PORT": str(free_port()),
        **(env or {}),
    }
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=log, stderr=subprocess.STDOUT, env=environ)

    def log_tail() -> str:
        log.flush()
        text = Path(log.name).read_text(encoding="utf-8", errors="replace")
        return text[-3000:]

    try:
        deadline = time.monotonic() + timeout
        while True:
            if proc.poll() is not None:
                raise HarnessError(
                    f"servodesk serve exited with code {proc.returncode} before it was ready:\n"
                    + log_tail()
                )
            try:
                status, _ = _get(f"{base}/api/v1/health")
                if status == 200:
                    break
            except (urllib.error.URLError, ConnectionError, TimeoutError, OSError):
                pass
            if time.monotonic() > deadline:
                raise HarnessError(
                    f"servodesk serve did not answer /api/v1/health in {timeout:.0f} s:\n"
                    + log_tail()
                )
            time.sleep(0.2)
        _, index = _get(f"{base}/")
        if 'id="root"' not in index:
            raise HarnessError(
                "the backend does not serve the built UI; build it first: "
                "cd frontend && npm ci && npm run build"
            )
        yield base
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)
        log.close()
        with contextlib.suppress(OSError):
            os.unlink(log.name)
