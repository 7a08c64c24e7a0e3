"""Shared pieces of the browser tests: finding Debian's Chromium, running the real backend,
and taking control of a drive as the UI does.

Used by conftest.py (pytest fixtures), the tests and shoot.py (screenshots for review).
Playwright never downloads a browser here: it drives the system Chromium through
``executable_path``.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
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
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from playwright.sync_api import Page

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


#: The logs of the servers running now: a failed browser test shows their tails
#: (conftest.py), since what the server did is half of what went wrong.
SERVER_LOGS: list[Path] = []


def server_log_tail(chars: int = 6000) -> str:
    """The last ``chars`` characters of each running server's log, headed by its path."""
    parts = []
    for path in SERVER_LOGS:
        with contextlib.suppress(OSError):
            parts.append(f"--- {path.name} ---\n" + path.read_text("utf-8", "replace")[-chars:])
    return "\n".join(parts)


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
    SERVER_LOGS.append(Path(log.name))

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
            except urllib.error.HTTPError as exc:
                if exc.code == 401:  # Up, and requires a login (accounts exist).
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
        with contextlib.suppress(ValueError):
            SERVER_LOGS.remove(Path(log.name))
        with contextlib.suppress(OSError):
            os.unlink(log.name)


# ---------------------------------------------------------------------------------------------
# Control (docs/api.md "Control and motion as built"): every request that changes a drive
# needs the control token, servo on and motion also a WebSocket bound to it. The UI keeps its
# tab's token in sessionStorage (frontend/src/lib/controlToken.ts); these helpers take control
# the way a person does (the header's control indicator) and read the tab's token for the
# API calls a test makes on the page's behalf.
# ---------------------------------------------------------------------------------------------

#: sessionStorage keys of the UI: the tab's client label and its control token.
CLIENT_KEY = "servodesk.client"
CONTROL_KEY = "servodesk.control"
#: Control of a tab that closed stays 5 s with it (the server's grace for a reload), and a
#: test that follows may find it so: waits for it to lapse allow this much.
CONTROL_LAPSE_MS = 10_000


def take_control(page: Page, sid: str | None = None, timeout: float = CONTROL_LAPSE_MS) -> None:
    """Take control of ``sid`` (default: the session the page shows) with the header's Take
    control, on a page of that session, and wait until this tab holds it and its WebSocket
    is bound as the dead-man."""
    from playwright.sync_api import expect

    indicator = page.get_by_test_id("control-indicator")
    if sid is not None:
        expect(indicator).to_have_attribute("data-session", sid)
    expect(indicator).to_have_attribute("data-known", "true")
    if indicator.get_attribute("data-you") != "true":
        take = page.get_by_test_id("control-take")
        # Shown once nobody holds control: a closed tab of an earlier test may hold it for 5 s.
        expect(take).to_be_visible(timeout=timeout)
        take.click()
    expect(indicator).to_have_attribute("data-you", "true")
    expect(indicator).to_have_attribute("data-bound", "true")


def shown_int(page: Page, testid: str) -> int:
    """The whole number an element shows (a position or velocity in drive units)."""
    text = page.get_by_test_id(testid).inner_text().strip()
    assert re.fullmatch(r"-?\d+", text), f"{testid} shows {text!r}"
    return int(text)


def tab_control(page: Page) -> dict[str, Any] | None:
    """What the page's tab holds: ``{"token", "sessions"}`` from its sessionStorage, or None."""
    text = page.evaluate(f"() => sessionStorage.getItem({CONTROL_KEY!r})")
    if not text:
        return None
    held = json.loads(text)
    return held if isinstance(held, dict) and held.get("token") else None


def control_headers(page: Page) -> dict[str, str]:
    """The headers the page's own requests carry: its client label and, when it holds
    control, its token (for the API calls a test makes on the page's behalf)."""
    client = page.evaluate(f"() => sessionStorage.getItem({CLIENT_KEY!r})")
    headers = {"Content-Type": "application/json"}
    if client:
        headers["X-Servodesk-Client"] = client
    held = tab_control(page)
    if held:
        headers["X-Servodesk-Control"] = held["token"]
    return headers


def release_control(page: Page) -> None:
    """Leave the drives the page holds as the next test expects them: motion halted, servo
    off, control released. Quiet: a test that failed half way may have left anything."""
    if page.is_closed():
        return
    try:
        held = tab_control(page)
        if not held:
            return
        headers = control_headers(page)
        for sid in held.get("sessions", []):
            base = f"/api/v1/sessions/{sid}"
            page.request.post(f"{base}/motion/halt", data="{}", headers=headers)
            page.request.post(f"{base}/state", data='{"command":"disable"}', headers=headers)
            page.request.post(f"{base}/control", data='{"action":"release"}', headers=headers)
        page.evaluate(f"() => sessionStorage.removeItem({CONTROL_KEY!r})")
    except Exception:  # Cleanup must not hide the test's own failure.
        pass


def api_take_control(
    page: Page, sid: str, client: str, timeout: float = CONTROL_LAPSE_MS / 1000
) -> str:
    """Take control of ``sid`` over the API as a script labelled ``client``; its token.
    Waits while a closed tab's control lingers (409 "holds control")."""
    deadline = time.monotonic() + timeout
    while True:
        r = page.request.post(
            f"/api/v1/sessions/{sid}/control",
            data='{"action":"take"}',
            headers={"X-Servodesk-Client": client, "Content-Type": "application/json"},
        )
        if r.ok:
            token = r.json()["token"]
            assert isinstance(token, str) and token
            return token
        if r.status != 409 or time.monotonic() > deadline:
            raise AssertionError(f"take control of {sid} as {client}: {r.status} {r.text()}")
        time.sleep(0.25)


def start_mover(page: Page, sid: str, token: str, client: str) -> None:
    """Open a second WebSocket in the page that binds itself to the control ``token`` holds
    (the dead-man of motion a test starts over the API) and sends heartbeats every 50 ms."""
    page.evaluate(
        """([sid, token, client]) => new Promise((resolve, reject) => {
            const url = new URL('/api/v1/ws', location.href);
            url.protocol = location.protocol === 'https:' ? 'wss:' : 'ws:';
            url.searchParams.set('client', client);
            const ws = new WebSocket(url.toString(), 'servodesk.v1');
            ws.onopen = () => ws.send(JSON.stringify({type: 'bind', session: sid, token}));
            ws.onmessage = (ev) => {
                const m = JSON.parse(ev.data);
                if (m.type !== 'bind' || m.session !== sid) return;
                if (!m.ok) { ws.close(); reject(new Error('bind refused: ' + m.message)); return; }
                const msg = JSON.stringify({type: 'heartbeat', session: sid});
                const beat = () => ws.readyState === 1 && ws.send(msg);
                beat();
                window.__servodeskMover = {ws, timer: setInterval(beat, 50)};
                resolve(true);
            };
            ws.onerror = () => reject(new Error('the mover socket did not open'));
        })""",
        [sid, token, client],
    )


def stop_mover(page: Page) -> None:
    if page.is_closed():
        return
    page.evaluate(
        """() => {
            const m = window.__servodeskMover;
            if (!m) return;
            clearInterval(m.timer);
            m.ws.close();
            window.__servodeskMover = null;
        }"""
    )
