"""The design worker: one spawned process that runs the own tuning's searches and fits.

The gain search and the record fits are tens of milliseconds to seconds of Python arithmetic.
On the event loop (or in a thread, which would hold the GIL) they would hold the loop that
carries the operator's heartbeats, the dead-man and every other session's traffic, so
services/tuning/own hands them to this process (:func:`run`).

A tuning that is stopped (the operator's stop, a lost client, a fault) while its job runs
abandons the job: :func:`run` then ends the worker, unless another tuning's job is waiting
on it, and the next job starts a fresh one. ``ProcessPoolExecutor`` cannot cancel a job
that has started, and without this the next tuning on any axis queued behind the abandoned
search for up to 20 s (the heavy 100-200 Hz axes search twice).
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import multiprocessing
import signal
import sys
import threading
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, TypeVar

log = logging.getLogger(__name__)

_T = TypeVar("_T")

_POOL: ProcessPoolExecutor | None = None
#: The jobs submitted to the worker and not yet done: a worker whose only job was abandoned
#: is ended, one that still serves another tuning is not.
_PENDING: set[Future[Any]] = set()
#: prctl(2) option: the signal a process gets when the thread that started it ends.
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """In the worker (Linux): end with the server, however the server ends. A server killed
    outright (SIGKILL, or a stop that timed out waiting for a long search) left the worker
    and its resource tracker running for good."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):
        log.debug("tuning worker: prctl(PR_SET_PDEATHSIG) not available")


def pool() -> ProcessPoolExecutor:
    """The worker, started on first use (spawned, not forked: the server has bus threads a
    fork would copy in whatever state they are). Started from the event loop's thread, which
    lives as long as the server: the worker's parent-death signal fires when the *thread*
    that started it ends."""
    global _POOL
    if _POOL is None:
        _POOL = ProcessPoolExecutor(
            1, mp_context=multiprocessing.get_context("spawn"), initializer=_die_with_parent
        )
    return _POOL


async def run(job: Callable[[], _T]) -> _T:
    """``job`` in the worker; when the awaiting task is cancelled while the job runs, the
    job is abandoned and the worker ended where no other job waits on it (module
    docstring)."""
    executor = pool()
    future = executor.submit(job)
    # This worker's set: an _end meanwhile gives the next worker a new one.
    pending = _PENDING
    pending.add(future)
    future.add_done_callback(pending.discard)
    try:
        return await asyncio.wrap_future(future)
    except asyncio.CancelledError:
        # Cancelled before it started: the executor drops it. Done meanwhile: nothing to
        # stop. Running: only ending the process stops it.
        if not future.cancel() and not future.done() and not (pending - {future}):
            log.info("tuning worker: a stopped tuning's job abandoned, the worker ended")
            # On the event loop: the ended process is reaped in a thread, not waited for here.
            _end(executor, wait=False)
        raise


def _end(executor: ProcessPoolExecutor, *, wait: bool) -> None:
    global _POOL, _PENDING
    if _POOL is executor:
        _POOL, _PENDING = None, set()
    # ProcessPoolExecutor has no public way to end a busy worker (Python 3.11).
    workers = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for w in workers:
        w.terminate()

    def reap() -> None:
        for w in workers:
            w.join(2.0)

    if wait:
        reap()
    else:
        threading.Thread(target=reap, name="tuning-worker-reap", daemon=True).start()


def shutdown() -> None:
    """Stop the worker now (the server stops): a search in progress is abandoned (its tuning
    was stopped with the sessions) rather than waited for."""
    if _POOL is not None:
        _end(_POOL, wait=True)
