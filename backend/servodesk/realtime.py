"""Real-time priority for the few threads that must run on time.

The dead-man's watcher (services/deadman.py) and PROFINET's RT cycle (links/profinet_io.py,
and the twin's IO device, sim/profinet_io.py) each wait most of the time and then must run
within a few milliseconds: a busy machine (a build, a browser, other servers on a 2-core
laptop) kept them off the CPU long enough for a watchdog to expire (a CI run saw no input
frame for 516 ms). Linux SCHED_FIFO puts such a thread ahead of every normal one when it
wakes. It needs root or CAP_SYS_NICE (RLIMIT_RTPRIO); without them the thread keeps its normal
priority, which is what it had before. Only threads that sleep between their turns may ask:
one that never sleeps would starve its core.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading

log = logging.getLogger(__name__)

#: The SCHED_FIFO priority asked for: above every normal thread, far below the kernel's own
#: (1 is the lowest real-time priority, 99 the highest).
PRIORITY = 10


def raise_priority(what: str, priority: int = PRIORITY) -> bool:
    """Best effort: the calling thread at SCHED_FIFO ``priority``; True if it took."""
    setter = getattr(os, "sched_setscheduler", None)
    if setter is None or not hasattr(os, "SCHED_FIFO"):
        return False
    with contextlib.suppress(OSError):
        setter(threading.get_native_id(), os.SCHED_FIFO, os.sched_param(priority))
        log.debug("%s thread at SCHED_FIFO %d", what, priority)
        return True
    return False
