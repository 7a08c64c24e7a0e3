"""Stepping simulated drives in time: on the wall clock, or as fast as possible.

:class:`SimRunner` steps any number of drives from ONE background thread with a 1 ms period.
When the thread falls behind (a busy machine, a debugger), it catches up in chunks of at most
``max_chunk`` seconds, and drops lateness beyond ``max_lag`` so a long stall does not turn
into a burst of simulated time. :func:`run_unbound` steps one drive without waiting, for
benchmarks and tests.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterable
from typing import Protocol

log = logging.getLogger(__name__)


class Steppable(Protocol):
    def step(self, dt: float) -> None: ...


class SimRunner:
    """Steps drives on the wall clock in one daemon thread."""

    def __init__(
        self,
        drives: Iterable[Steppable] = (),
        *,
        period: float = 1e-3,
        max_chunk: float = 0.01,
        max_lag: float = 0.5,
    ) -> None:
        self._drives: list[Steppable] = list(drives)
        self.period = period
        self.max_chunk = max_chunk
        self.max_lag = max_lag
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        #: Simulated seconds dropped because the thread was too late (diagnostics).
        self.dropped = 0.0

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def add(self, drive: Steppable) -> None:
        with self._lock:
            self._drives.append(drive)

    def remove(self, drive: Steppable) -> None:
        with self._lock:
            self._drives.remove(drive)

    def start(self) -> SimRunner:
        if self.running:
            return self
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="servodesk-sim", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the thread and wait for it (idempotent)."""
        self._stop.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout)
        self._thread = None

    def _run(self) -> None:
        last = time.monotonic()
        next_wake = last + self.period
        while not self._stop.is_set():
            now = time.monotonic()
            due = now - last
            if due > self.max_lag:
                self.dropped += due - self.max_lag
                log.debug("simulation %.3f s late; dropping the excess", due)
                due = self.max_lag
            last = now
            with self._lock:
                drives = list(self._drives)
            while due > 1e-9:
                chunk = due if due < self.max_chunk else self.max_chunk
                for d in drives:
                    try:
                        d.step(chunk)
                    except Exception:  # A broken drive must not stop the others.
                        log.exception("simulated drive step failed")
                due -= chunk
            next_wake += self.period
            delay = next_wake - time.monotonic()
            if delay < -self.max_lag:
                next_wake = time.monotonic() + self.period
                delay = self.period
            if delay > 0:
                self._stop.wait(delay)


def run_unbound(drive: Steppable, seconds: float, chunk: float = 0.01) -> float:
    """Step ``drive`` through ``seconds`` of simulated time as fast as possible.

    Returns the wall-clock seconds it took.
    """
    t0 = time.perf_counter()
    remaining = seconds
    while remaining > 1e-12:
        dt = chunk if remaining > chunk else remaining
        drive.step(dt)
        remaining -= dt
    return time.perf_counter() - t0
