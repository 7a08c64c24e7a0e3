"""The simulated drive's heartbeat consumer (CiA 301 §7.2.8.3.2.2, object 1016h).

1016h:01 = producer node id (bits 16-23) and consumer time in ms (bits 0-15); 0 for either
switches the entry off. Monitoring starts with the first heartbeat received from that
producer ("the heartbeat consumer ... is activated by the first heartbeat received") and, once
a consumer time passes without one, the drive raises a heartbeat event: EMCY 8130h (CiA 301
table 21, "life guard error or heartbeat error") and the reaction its abort connection option
code 6007h asks for (CiA 402-2, object 6007h: 0 no action, 1 fault, 2 disable voltage,
3 quick stop). A real drive reacts this way when the PC that commissions it dies; the twin
must too, or servodesk's arming of it proves nothing.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

log = logging.getLogger(__name__)

#: CiA 301 table 21: life guard error or heartbeat error.
HEARTBEAT_EVENT = 0x8130


class HeartbeatConsumer:
    """Watches one producer (the CiA 301 entry 1016h:01) on a thread of its own."""

    def __init__(self, on_event: Callable[[int], None], period_s: float = 0.005) -> None:
        #: Called on the watch thread with the producer's node id when its heartbeat lapses.
        self._on_event = on_event
        self._period = period_s
        self._producer = 0
        self._timeout = 0.0
        self._last: float | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def producer(self) -> int:
        return self._producer

    def configure(self, entry: int) -> None:
        """A write of 1016h:01: producer ``entry >> 16 & 0x7F``, time ``entry & 0xFFFF`` ms."""
        producer, ms = (entry >> 16) & 0x7F, entry & 0xFFFF
        with self._lock:
            self._producer = producer if ms else 0
            self._timeout = ms / 1000.0
            self._last = None  # Not monitored until the first heartbeat (CiA 301).
        if self._producer and (self._thread is None or not self._thread.is_alive()):
            self._stop.clear()
            self._thread = threading.Thread(
                target=self._run, name="sim-heartbeat-consumer", daemon=True
            )
            self._thread.start()

    def on_frame(self, can_id: int) -> None:
        """Any frame of the bus; a heartbeat of the producer (COB-ID 700h + id) re-arms."""
        if self._producer and can_id == 0x700 + self._producer:
            with self._lock:
                self._last = time.monotonic()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
        self._thread = None

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            with self._lock:
                last, timeout, producer = self._last, self._timeout, self._producer
                lapsed = bool(producer) and last is not None and time.monotonic() - last > timeout
                if lapsed:
                    self._last = None  # One event per loss; the next heartbeat re-arms.
            if lapsed:
                try:
                    self._on_event(producer)
                except Exception:
                    log.exception("heartbeat event of producer %d not handled", producer)
