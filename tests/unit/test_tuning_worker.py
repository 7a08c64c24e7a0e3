"""The design worker of servodesk's own tuning (services/tuning/worker.py) ends with the
server, and with a stopped tuning's job.

A server stopped while the worker existed left the worker process (and its resource tracker)
running for good: every full test run left one behind, started by the browser suite's
``servodesk serve``. The server now ends it at shutdown, and on Linux the worker also ends
when the server is killed outright. A tuning stopped during its search left the search
running, and the next tuning on any axis waited behind it.
"""

from __future__ import annotations

import asyncio
import functools
import os
import signal
import subprocess
import sys
import time

import pytest

from servodesk.services.tuning import worker as tuning_worker

# Processes started, stopped and waited for on the wall clock (a job "has started" after 0.5 s).
pytestmark = pytest.mark.wallclock


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
    pool = tuning_worker.pool()
    pid = pool.submit(os.getpid).result(timeout=60)
    assert _alive(pid)
    tuning_worker.shutdown()
    assert _gone_within(pid, 5), f"worker {pid} still runs"
    # The next tuning gets a new worker.
    assert tuning_worker.pool().submit(os.getpid).result(timeout=60) != pid
    tuning_worker.shutdown()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_killed_server_takes_its_worker_with_it() -> None:
    code = (
        "import os, sys, time\n"
        "from servodesk.services.tuning import worker as tuning_worker\n"
        "print(tuning_worker.pool().submit(os.getpid).result(timeout=60), flush=True)\n"
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


def _pid_after(seconds: float) -> int:
    """A job standing for a long search: the worker's pid after ``seconds``."""
    time.sleep(seconds)
    return os.getpid()


def test_a_stopped_tunings_search_does_not_hold_up_the_next() -> None:
    """The job of a tuning that is stopped (its task cancelled) while the job runs ends with
    its worker; the next job gets a fresh worker at once instead of queueing behind it."""

    async def stopped_during_its_search() -> int:
        worker = await tuning_worker.run(os.getpid)
        task = asyncio.create_task(tuning_worker.run(functools.partial(_pid_after, 60.0)))
        await asyncio.sleep(0.5)  # the long job has started in the worker
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        return worker

    worker = asyncio.run(stopped_during_its_search())
    assert _gone_within(worker, 5), f"worker {worker} still runs the abandoned job"
    t0 = time.monotonic()
    fresh = asyncio.run(tuning_worker.run(os.getpid))
    assert fresh != worker
    # A spawn and the job, not the rest of the abandoned one's 60 s.
    assert time.monotonic() - t0 < 30.0
    tuning_worker.shutdown()


def test_a_job_another_tuning_waits_for_is_not_ended() -> None:
    """Two tunings share the worker: stopping one while its job runs must not break the job
    the other one is waiting for, which then runs to its end."""

    async def one_stopped_one_waiting() -> tuple[int, int]:
        worker = await tuning_worker.run(os.getpid)
        stopped = asyncio.create_task(tuning_worker.run(functools.partial(_pid_after, 1.0)))
        waiting = asyncio.create_task(tuning_worker.run(functools.partial(_pid_after, 0.0)))
        await asyncio.sleep(0.3)
        stopped.cancel()
        with pytest.raises(asyncio.CancelledError):
            await stopped
        return worker, await asyncio.wait_for(waiting, 30.0)

    worker, other = asyncio.run(one_stopped_one_waiting())
    assert other == worker  # the same worker ran the other tuning's job
    assert _alive(worker)
    tuning_worker.shutdown()
    assert _gone_within(worker, 5)
