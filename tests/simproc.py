"""``servodesk sim`` as its own process, for tests that talk to it across processes."""

from __future__ import annotations

import contextlib
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator


@contextlib.contextmanager
def sim_subprocess(
    profile: str, node_id: int, interface: str, channel: str
) -> Iterator[subprocess.Popen[str]]:
    """Start ``python -m servodesk sim``; wait for its "serving" line; stop it afterwards.

    stderr goes to a file: a pipe nobody drains could block the sim if it logged a lot.
    """
    args = [
        "sim",
        "--profile",
        profile,
        "--node-id",
        str(node_id),
        "--interface",
        interface,
        "--channel",
        channel,
    ]
    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(
            [sys.executable, "-m", "servodesk", *args],
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
        )
        try:
            line = _first_line(proc)
            if "serving" not in line:
                err.seek(0)
                raise AssertionError(
                    f"the sim did not start (exit {proc.poll()}): {line}{err.read()}"
                )
            assert f"node {node_id}" in line and channel in line, line
            yield proc
        finally:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(5)
            if proc.stdout is not None:
                proc.stdout.close()


def _first_line(proc: subprocess.Popen[str], timeout: float = 30) -> str:
    assert proc.stdout is not None
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if sel.select(timeout=0.2):
            line = proc.stdout.readline()
            if line:
                return line
        if proc.poll() is not None:
            return ""
    return ""
