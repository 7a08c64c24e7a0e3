"""The dead-man's watch: a thread of its own that stops the axis when the heartbeats stop.

Until 2026-12-07 the watch was a task on the event loop, and so was the stop it sent: while
one request parsed or serialised a large document (a 35 MB backup, a 10 MB scope CSV) the loop
was held for 2.5 to 9 s, and a jog whose client had gone silent stopped 3.5 s late (issue
"Motion safety", item 3). Now the watch runs on this thread and, where the link can put a
frame on the wire without the loop (:meth:`DriveLink.stop_frame`: CANopen, SLMP, EtherCAT),
it sends the quick stop from here (:func:`thread_stop`, which also puts it into servodesk's
cyclic outputs where they carry the controlword). The loop then does the orderly rest (halt
and quick stop through the link, the motion's end, the events) whenever it gets to it.

The watch cannot read heartbeats the loop has not read: a loop held longer than the dead-man
time stops the axis even when the client is alive (fail-safe, the same as a client that went
silent). Heavy work therefore leaves the loop (api/offload.py), so that this does not
happen in normal use.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from servodesk.domain.cia402 import CONTROLWORD
from servodesk.links.base import QUICK_STOP_WORD
from servodesk.realtime import raise_priority

if TYPE_CHECKING:
    from servodesk.services.session import Session

log = logging.getLogger(__name__)


def thread_stop(session: Session) -> Callable[[], None] | None:
    """What the dead-man's thread calls to stop ``session``'s drive without the event loop;
    None where there is no such path (the stop then goes through the loop).

    The link's own stop frame (an SDO download of the quick stop), and, while servodesk's
    cyclic outputs carry the controlword, the quick stop in the output image as well: the
    drive applies the next RPDO at SYNC (CiA 301 §7.2.2), which would otherwise command it
    again with the controlword the image held, over the SDO's quick stop. The exchange is
    looked up when the stop fires (cyclic data may start after the motion did); its output
    image takes the value under its own lock, and its SYNC thread sends it within a period.
    """
    frame = session.link.stop_frame()

    def into_outputs() -> bool:
        cyclic = session.cyclic
        if cyclic is None or not cyclic.outputs or not cyclic.carries(CONTROLWORD):
            return False
        cyclic.set_outputs({CONTROLWORD: QUICK_STOP_WORD})
        return True

    if frame is None and not (session.cyclic is not None and session.cyclic.outputs):
        return None

    def stop() -> None:
        into_outputs()
        if frame is not None:
            frame()

    return stop


#: How often the thread looks (s): the stop frame goes out at most this long after the
#: deadline, plus the thread's own scheduling delay.
PERIOD_S = 0.005


@dataclass(slots=True)
class _Armed:
    deadline_s: float
    #: Monotonic time of the last sign of the operator (heartbeat, or the motion's start).
    last: Callable[[], float]
    #: Puts the stop on the wire without the event loop; None: the link has no such path.
    stop: Callable[[], None] | None
    #: Called on this thread after the stop frame (or at once without one), with the last sign
    #: of life and the time the frame went out (both monotonic); it must not block.
    fired: Callable[[float, float | None], None]


class DeadmanWatch:
    """One thread for every armed motion of a backend."""

    def __init__(self, period_s: float = PERIOD_S) -> None:
        self.period_s = period_s
        self._armed: dict[object, _Armed] = {}
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None

    def arm(
        self,
        key: object,
        *,
        deadline_s: float,
        last: Callable[[], float],
        stop: Callable[[], None] | None,
        fired: Callable[[float, float | None], None],
    ) -> None:
        with self._lock:
            self._armed[key] = _Armed(deadline_s, last, stop, fired)
            if self._thread is None or not self._thread.is_alive():
                self._stopping.clear()
                self._thread = threading.Thread(
                    target=self._run, name="servodesk-deadman", daemon=True
                )
                self._thread.start()

    def disarm(self, key: object) -> None:
        with self._lock:
            self._armed.pop(key, None)

    def armed(self) -> int:
        with self._lock:
            return len(self._armed)

    def close(self) -> None:
        self._stopping.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(1.0)
        self._thread = None

    def _run(self) -> None:
        _raise_priority()
        while not self._stopping.wait(self.period_s):
            with self._lock:
                entries = list(self._armed.items())
            now = time.monotonic()
            for key, entry in entries:
                try:
                    last = entry.last()
                except Exception:  # A broken getter must not stop the watch of the others.
                    log.exception("dead-man: reading the last heartbeat failed")
                    last = 0.0
                if now - last < entry.deadline_s:
                    continue
                with self._lock:
                    if self._armed.get(key) is not entry:
                        continue  # Disarmed (the motion ended) meanwhile.
                    del self._armed[key]
                sent: float | None = None
                if entry.stop is not None:
                    try:
                        entry.stop()
                        sent = time.monotonic()
                    except Exception:
                        log.exception("dead-man: the stop frame could not be sent")
                try:
                    entry.fired(last, sent)
                except Exception:
                    log.exception("dead-man: the fired callback failed")


def _raise_priority() -> None:
    """The watcher thread at a real-time priority (servodesk/realtime.py), so that a busy
    machine does not keep it off the CPU past the dead-man time. It sleeps between looks."""
    raise_priority("dead-man")
