"""The motion service: the one entry point (services/motion/__init__.py says what it does).

Its parts are one class per seam, each in a module of its own; this class puts them together
and sets their state.
"""

from __future__ import annotations

import asyncio
from typing import Any

from servodesk.services.control import ControlService
from servodesk.services.deadman import DeadmanWatch
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.motion.axis import Axis
from servodesk.services.motion.commands import ProfileMotions
from servodesk.services.motion.cyclic import CyclicSetpoints
from servodesk.services.motion.tuning_motion import TuningMotions


class MotionService(ProfileMotions, CyclicSetpoints, TuningMotions):
    """Motion of the drive sessions: commands, stops, the dead-man, the safe state."""

    def __init__(
        self,
        manager: SessionManager,
        control: ControlService,
        hub: EventHub,
        *,
        deadman_s: float = 0.25,
        watchdog_period: float = 0.01,
        cyclic_period: float = 0.01,
    ) -> None:
        self.manager = manager
        self.control = control
        self.hub = hub
        self.deadman_s = deadman_s
        self.watchdog_period = watchdog_period
        self.cyclic_period = cyclic_period
        self._axes: dict[str, Axis] = {}
        self._background: set[asyncio.Task[Any]] = set()
        #: Making a drive safe after its holder was lost, per session (make_safe).
        self._safing: dict[str, asyncio.Task[str | None]] = {}
        #: The dead-man's watch, on a thread of its own (services/deadman.py).
        self._deadman = DeadmanWatch(period_s=min(watchdog_period, 0.005))
        control.on_lost(self._control_lost)
        control.on_bound(self._control_bound)
