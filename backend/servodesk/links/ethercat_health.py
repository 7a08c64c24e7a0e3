"""What the process data cycles of one EtherCAT line say about the line: working counter
errors and missing frames per slave, inputs gone stale, the link lost and back.

Every cycle is one LRW of the line's image (links/ethercat_cyclic.py); SOEM's
``receive_processdata`` answers the working counter it came back with, or -1 (EC_NOFRAME)
when no frame came back at all. ETG.1000.4 §5.4.3: every slave whose FMMUs the LRW reaches
adds 1 for its inputs and 2 for its outputs, so a counter short of SOEM's ``expected_wkc``
means some slave did not take part; a missing frame (or a counter of 0) means nothing
answered: the cable to the first slave, or the master's own NIC. The NIC's carrier
(``/sys/class/net/<nic>/carrier``, where the kernel exposes it) tells the second case at once.

This module holds the bookkeeping only; the cycle thread feeds it and acts on it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Cycles without valid inputs after which the inputs are marked stale.
STALE_CYCLES = 3
#: Consecutive cycles with no frame back (or working counter 0) after which the link is
#: "lost" (a carrier that reads 0 says so at once).
LOST_CYCLES = 10
#: How often the carrier file is read while cycles run [s] (a file read per cycle at 1 kHz
#: is not free; 20 ms is well under the watchdog of a drive, 100 ms).
CARRIER_EVERY_S = 0.02
#: While the link is back but the slaves are not yet in their state: how often the cycle
#: thread reads their AL states and asks again [s]. pysoem holds the GIL in those calls.
RECOVER_EVERY_S = 0.05

OK = "ok"
DEGRADED = "degraded"
LOST = "link lost"
RECOVERING = "recovering"


def read_carrier(nic: str) -> bool | None:
    """The NIC's carrier (1: a link partner is there), or None where it cannot be read (not
    a Linux interface, or the interface is down: the kernel then answers EINVAL)."""
    try:
        text = (Path("/sys/class/net") / nic / "carrier").read_text().strip()
    except OSError:
        return None
    return text == "1" if text in ("0", "1") else None


@dataclass
class SlaveHealth:
    """One slave's part of the line's cycles."""

    position: int
    #: Cycles whose working counter fell short while this slave was found not taking part
    #: (its AL state below the line's, or its error indication set).
    wkc_errors: int = 0
    #: Cycles whose frame did not come back (every slave misses those).
    missing_frames: int = 0
    #: The AL state and status code as last read (while recovering or diagnosing).
    al_state: str | None = None
    al_status_code: int = 0

    def view(self) -> dict[str, Any]:
        return {
            "position": self.position,
            "node_id": self.position + 1,
            "wkc_errors": self.wkc_errors,
            "missing_frames": self.missing_frames,
            "al_state": self.al_state,
            "al_status_code": self.al_status_code,
        }


@dataclass
class LineHealth:
    """The line's cycles: counters and the link's state (:data:`OK`, :data:`DEGRADED`,
    :data:`LOST`, :data:`RECOVERING`)."""

    nic: str
    slaves: dict[int, SlaveHealth] = field(default_factory=dict)
    state: str = OK
    cycles: int = 0
    good_cycles: int = 0
    wkc_errors: int = 0
    missing_frames: int = 0
    #: Consecutive cycles without valid inputs, and consecutive cycles with nothing back.
    bad_run: int = 0
    silent_run: int = 0
    last_wkc: int | None = None
    expected_wkc: int = 0
    carrier: bool | None = None
    carrier_at: float = 0.0
    #: Monotonic times: the last cycle with valid inputs, the link lost, back in its state.
    last_good: float = 0.0
    lost_at: float | None = None
    back_at: float | None = None
    losses: int = 0
    #: Why the link is lost or degraded, in words.
    reason: str | None = None
    #: Next time the recovery reads and asks the slaves' states.
    recover_next: float = 0.0

    def slave(self, position: int) -> SlaveHealth:
        found = self.slaves.get(position)
        if found is None:
            found = self.slaves[position] = SlaveHealth(position)
        return found

    @property
    def stale(self) -> bool:
        """The inputs are not the slaves' present values (:data:`STALE_CYCLES` cycles or
        more without valid ones, or the link not back in its state yet)."""
        return self.bad_run >= STALE_CYCLES or self.state in (LOST, RECOVERING)

    def reset(self, slaves: int) -> None:
        """A new exchange on a line of ``slaves``: counters from zero. Every slave's entry
        exists from here on, so that the status (event loop) never iterates the dict while
        the cycle thread adds to it."""
        self.slaves = {p: SlaveHealth(p) for p in range(slaves)}
        self.state = OK
        self.cycles = self.good_cycles = self.wkc_errors = self.missing_frames = 0
        self.bad_run = self.silent_run = 0
        self.last_wkc = None
        self.lost_at = self.back_at = None
        self.losses = 0
        self.reason = None
        self.last_good = time.monotonic()

    def view(self) -> dict[str, Any]:
        now = time.monotonic()
        return {
            "state": self.state,
            "reason": self.reason,
            "stale": self.stale,
            "cycles": self.cycles,
            "wkc_errors": self.wkc_errors,
            "missing_frames": self.missing_frames,
            "last_wkc": self.last_wkc,
            "expected_wkc": self.expected_wkc,
            "carrier": self.carrier,
            "losses": self.losses,
            "since_good_s": round(now - self.last_good, 3) if self.last_good else None,
            "slaves": [self.slaves[p].view() for p in sorted(self.slaves)],
        }
