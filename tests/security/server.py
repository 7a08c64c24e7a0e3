"""A real ``servodesk serve`` (uvicorn) on loopback, with its log, for the tests that need the
server's own HTTP parsing and access log: raw sockets, WebSocket handshakes, log capture."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import httpx

from tests.live import free_port

#: The password of every account :func:`serve` makes.
PASSWORD = "correct horse battery"


@dataclass
class LiveServer:
    base: str
    port: int
    #: The administrator's API token (``accounts``), sent as Authorization: Bearer.
    token: str | None
    log_path: Path
    data_dir: Path
    #: Account name -> its API token (one account per role asked for).
    tokens: dict[str, str] = field(default_factory=dict)

    def log(self) -> str:
        return self.log_path.read_text(encoding="utf-8", errors="replace")


def make_accounts(data_dir: Path, roles: dict[str, str]) -> dict[str, str]:
    """Accounts ``name -> role`` (password :data:`PASSWORD`) in ``data_dir``'s store, as
    ``servodesk users add`` makes them; their API tokens."""
    from servodesk.services.users import UserStore

    users = UserStore(data_dir)
    try:
        out = {}
        for name, role in roles.items():
            if users.get(name) is None:
                users.add(name, role, PASSWORD)
            out[name] = users.create_token(name, "tests")[1]
        return out
    finally:
        users.close()


@contextlib.contextmanager
def serve(
    *args: str, accounts: dict[str, str] | None = None, env: dict[str, str] | None = None
) -> Iterator[LiveServer]:
    """``servodesk serve`` (no simulated drives: it starts in seconds) on a free port; with
    ``accounts`` (name -> role) made first, so that it requires a login (docs/security.md)."""
    port = free_port()
    work = Path(tempfile.mkdtemp(prefix="servodesk-security-"))
    log_path = work / "server.log"
    tokens = make_accounts(work / "data", accounts) if accounts else {}
    token = next(iter(tokens.values()), None)
    full_env = {
        **os.environ,
        "SERVODESK_DATA_DIR": str(work / "data"),
        "SERVODESK_VIEWER_PORT": "0",
        "SERVODESK_LOG_LEVEL": "info",  # The access log is what some tests read.
        **(env or {}),
    }
    cmd = [sys.executable, "-m", "servodesk", "serve", "--port", str(port), *args]
    base = f"http://127.0.0.1:{port}"
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, env=full_env, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 40
        while True:
            if proc.poll() is not None:
                raise RuntimeError(
                    f"servodesk serve exited with {proc.returncode}:\n{log_path.read_text()}"
                )
            with contextlib.suppress(httpx.HTTPError):
                if (
                    httpx.get(f"{base}/api/v1/health", headers=headers, timeout=1).status_code
                    == 200
                ):
                    break
            if time.monotonic() > deadline:
                raise RuntimeError(f"servodesk serve did not come up:\n{log_path.read_text()}")
            time.sleep(0.2)
        yield LiveServer(base, port, token, log_path, work / "data", tokens)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        shutil.rmtree(work, ignore_errors=True)


def raw_request(port: int, request: bytes, timeout: float = 5.0) -> bytes:
    """Send ``request`` as it is on a new connection; the whole answer (until the server
    closes, or ``timeout``)."""
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(request)
        chunks: list[bytes] = []
        with contextlib.suppress(TimeoutError, ConnectionResetError):
            while True:
                data = s.recv(65536)
                if not data:
                    break
                chunks.append(data)
                if b"\r\n\r\n" in b"".join(chunks) and _complete(b"".join(chunks)):
                    break
    return b"".join(chunks)


def _complete(answer: bytes) -> bool:
    head, _, body = answer.partition(b"\r\n\r\n")
    for line in head.split(b"\r\n")[1:]:
        name, _, value = line.partition(b":")
        if name.strip().lower() == b"content-length":
            return len(body) >= int(value.strip())
    return False


def status_of(answer: bytes) -> int:
    """The status code of a raw HTTP answer (0: none)."""
    parts = answer.split(b" ", 2)
    return int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else 0
