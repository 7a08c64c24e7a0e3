"""What the motion service keeps per drive: the axis, its motion, the CiA 402 bits and modes.

An :class:`Axis` is one session's drive as the motion service sees it: its cached limits, the
motion that runs (at most one), the lock every start holds, the stop counter a start checks
before its "go", and the settings the motions borrowed. A :class:`Motion` is one jog, move,
homing run, cyclic generator or tuning motion from its start to its end.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.cia402 import (
    Mode,
)
from servodesk.services.motion.limits import Limits
from servodesk.services.session import Borrowed, Session

# The modes of operation this service commands, as plain ints (6060h's values).
PP, PV = int(Mode.PROFILE_POSITION), int(Mode.PROFILE_VELOCITY)
TQ, HM = int(Mode.PROFILE_TORQUE), int(Mode.HOMING)
CSP, CSV = int(Mode.CYCLIC_SYNC_POSITION), int(Mode.CYCLIC_SYNC_VELOCITY)
CST = int(Mode.CYCLIC_SYNC_TORQUE)
CYCLIC_MODES = {"csp": CSP, "csv": CSV, "cst": CST}
#: Standstill when |velocity| is within 606Fh; this when the drive has no 606Fh (inc/s).
DEFAULT_STANDSTILL = 1000
#: A homing run whose statusword already shows an end state (a drive with an absolute encoder
#: keeps bit 12 set) is taken as ended only when it stays so this long without running.
HOMING_SETTLE_S = 0.3
#: Losing the holder: how long the axis gets to come to standstill before the power stage is
#: switched off anyway (a drive whose quick stop does not end; it then coasts).
SAFE_STOP_S = 5.0
#: States with the power stage on or about to be (CiA 402-2 §6.2, figure 9).
ENERGISED = {
    cia402.State.SWITCHED_ON,
    cia402.State.OPERATION_ENABLED,
    cia402.State.QUICK_STOP_ACTIVE,
}


@dataclass(eq=False)
class Motion:
    kind: str
    owner: str
    mode: int
    target: float | None
    #: time.monotonic() when the motion was asked for: the dead-man counts from here too.
    started: float
    active: bool = True
    state: str = "running"
    message: str = ""
    tasks: list[asyncio.Task[None]] = field(default_factory=list)
    #: Continuous motion near software limits: the limits and the deceleration the halt uses
    #: (position units per s², None: unknown), for the monitor's stop-before-the-limit check.
    guard: Limits | None = None
    halt_decel: float | None = None
    acceleration: float | None = None
    #: The commanded speed in position units per s (None: 60FFh is in other units).
    speed_cap: float | None = None
    #: 606Ch is in position units per s: the monitor reads it rather than differentiating
    #: the position (whose sample times jitter with the event loop).
    read_velocity: bool = False
    #: Called once with the motion when it ends, however it ends (the tuning service stops
    #: its job when the dead-man, a stop or a fault ends the tuning motion).
    on_end: list[Callable[[Motion], None]] = field(default_factory=list)


#: Ends of a motion the audit log records as failures: it did not end as asked.
FAILED = frozenset({"deadman", "error", "fault", "lost"})


def audit_facts(motion: Motion) -> dict[str, Any]:
    """What the audit log keeps of a motion."""
    return {
        "kind": motion.kind,
        "owner": motion.owner,
        "mode": motion.mode,
        "target": motion.target,
    }


@dataclass(eq=False)
class Axis:
    session: Session
    limits: Limits | None = None
    limits_gen: int = 0
    motion: Motion | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    #: Bumped by every stop: a start in progress sees it and does not send its "go".
    epoch: int = 0
    #: A start sent its "go" after a stop began: the stop sends its commands again.
    rehalt: bool = False
    last_target: float | None = None
    #: The settings the axis's motions wrote and give back when they end (session.BORROW).
    borrowed: Borrowed = field(default_factory=dict)

    @property
    def sid(self) -> str:
        return self.session.id
