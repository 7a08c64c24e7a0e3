"""The gain search worker of servodesk's own tuning ends with the server.

A server stopped while the worker existed left the worker process (and its resource tracker)
running for good: every full test run left one behind, started by the browser suite's
``servodesk serve``. The server now ends it at shutdown, and on Linux the worker also ends
when the server is killed outright.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from servodesk.services import tuning_own


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False


def _gone_within(pid: int, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not _alive(pid):
            return True
        time.sleep(0.05)
    return False


def test_shutdown_ends_the_worker() -> None:
    pool = tuning_own._design_pool()
    pid = pool.submit(os.getpid).result(timeout=60)
    assert _alive(pid)
    tuning_own.shutdown_design_pool()
    assert _gone_within(pid, 5), f"worker {pid} still runs"
    # The next tuning gets a new worker.
    assert tuning_own._design_pool().submit(os.getpid).result(timeout=60) != pid
    tuning_own.shutdown_design_pool()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_killed_server_takes_its_worker_with_it() -> None:
    code = (
        "import os, sys, time\n"
        "from servodesk.services import tuning_own\n"
        "print(tuning_own._design_pool().submit(os.getpid).result(timeout=60), flush=True)\n"
        "time.sleep(60)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        worker = int(proc.stdout.readline())
        assert _alive(worker)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert _gone_within(worker, 5), f"worker {worker} outlived its server"
