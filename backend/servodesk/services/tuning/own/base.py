"""The own tuning's shared state and the small steps every phase uses (services/tuning/own).

:class:`TuningBase` holds what one run learns and keeps (the request, the gains as last
written, the travel guard, the notes), reads and writes the gains, tells whether the drive is
still in Operation enabled, and hands CPU work to the design worker (:meth:`TuningBase._compute`).
The phases build on it, each module one class (the package's docstring).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import STATUSWORD, State, decode_state
from servodesk.domain.datatypes import Value
from servodesk.domain.profile import TuningSpec
from servodesk.domain.tuning.design import ResponseLevel
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.search import SearchResult
from servodesk.domain.tuning.travel import TravelBound
from servodesk.errors import ServodeskError, ValidationError
from servodesk.model.plant import PlantParams
from servodesk.services.tuning import worker as tuning_worker
from servodesk.services.tuning.io import TuningIO, read_float
from servodesk.services.tuning.travel import PlannedMove, TravelGuard

log = logging.getLogger(__name__)

#: What a job handed to the design worker returns (:meth:`TuningBase._compute`).
_T = TypeVar("_T")

Progress = Callable[[float, str], None]

#: Test signal generator sub-indexes (docs/tuning.md).
SIG_KIND, SIG_AMPLITUDE, SIG_F0, SIG_F1, SIG_DURATION, SIG_CONTROL, SIG_TORQUE, SIG_VALUE = range(
    1, 9
)
SIG_PRBS = 2
#: The verification move's distance at most: this share of the window's width, and
#: VERIFY_REV. It runs from a rest position half its distance below the start
#: (``Drive.home``), so that it and the tries, as long as half the window, are centred on the
#: start and keep half their distance in reserve at either end (services/tuning/travel.py
#: NEW_GAINS_SHARE); the identification moves start there too (identify.py IDENT_REV).
VERIFY_WINDOW_SHARE = 0.5
#: Verification move: at most this many rev (and VERIFY_WINDOW_SHARE of the window's width).
VERIFY_REV = 0.25
VERIFY_SETTLE_S = 0.25


@dataclass(frozen=True, slots=True)
class OwnTuningRequest:
    """What the user asked for (POST .../tuning/start, ``servodesk tune``)."""

    mode: ResponseLevel
    #: The travel window's total width [rev], centred on where the axis stands: the axis stays
    #: within +- half of it (domain/tuning/travel.py).
    travel_window_rev: float
    #: Torque limit during tuning [% of the rated torque].
    torque_limit_pct: float
    #: The peak torque the machine's own moves accelerate with [% of the rated torque]: the
    #: gains are ranked on the reference move (search.py: 0.5 rev, jerk-limited, at 70 % of
    #: it). None: the tuning's torque limit.
    move_torque_pct: float | None = None
    #: Half the window in position units as the user confirmed it (the service's
    #: :func:`~servodesk.domain.tuning.travel.half_window` with 6064h's units per revolution);
    #: None: from ``travel_window_rev`` and the encoder's counts per revolution (608Fh).
    half_window_counts: int | None = None


class TuningFailed(ServodeskError):
    """The tuning stopped before it had a result it could stand behind."""


@dataclass(slots=True)
class Drive:
    """What the procedure learns about the drive before it moves it."""

    rate_hz: float
    counts_per_rev: float
    rated_torque: float
    limit_torque: float
    current_loop_hz: float | None
    #: Where the axis stood: the centre of the travel bound, where it is brought back to.
    start_counts: int
    #: The travel bound the user confirmed (start +- half the window).
    bound: TravelBound
    #: The fastest profile velocity the drive allows (607Fh) [counts/s].
    max_velocity: float
    #: The peak torque of the machine's moves the gains are ranked for [N m]; the tuning's own
    #: moves stay within ``limit_torque``.
    move_torque: float
    #: Where the identification moves, the verification move and the tries start from and come
    #: back to: half the verification distance below the start, so that those moves are
    #: centred on it (set by the frequency response's way back; the start until then).
    home: int = 0

    @property
    def width(self) -> float:
        """The travel window's width [counts]."""
        return 2.0 * self.bound.half

    @property
    def verify_distance(self) -> float:
        """The verification move's distance before any shortening [counts]."""
        return min(VERIFY_REV * self.counts_per_rev, VERIFY_WINDOW_SHARE * self.width)


class TuningBase:
    """One tuning run's state over a :class:`TuningIO` (a session's drive, or a simulated one)."""

    def __init__(
        self,
        io: TuningIO,
        request: OwnTuningRequest,
        progress: Progress | None = None,
        *,
        current_loop_hz: float | None = None,
        offload: bool = True,
    ) -> None:
        spec = io.profile.tuning
        if spec is None or spec.kind != "gains":
            raise ValidationError(
                f"{io.profile.name} has no gain map for servodesk's tuning",
                hint="see the Tuning page for what this family offers",
            )
        if request.mode not in ("low", "basic", "high"):
            raise ValidationError(
                f"mode {request.mode!r} is not one of low, basic, high", field="mode"
            )
        if not 0.05 <= request.travel_window_rev <= 100.0:
            raise ValidationError(
                f"travel window {request.travel_window_rev} rev is outside 0.05..100 rev",
                field="travel_window_rev",
            )
        if not 10.0 <= request.torque_limit_pct <= 500.0:
            raise ValidationError(
                f"torque limit {request.torque_limit_pct} % is outside 10..500 % of rated",
                field="torque_limit_pct",
            )
        self.io = io
        self.spec: TuningSpec = spec
        self.request = request
        self._progress = progress
        self._current_loop_hz = current_loop_hz
        self._offload = offload
        self.axis_time_s = 0.0
        self._frf_record: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None
        #: The last identification moves of a compliant axis: rate [Hz], torque at the
        #: shaft [N m], angle and position demand [rad] (_identify).
        self._moves_record: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None
        self.excursion = (0.0, 0.0)
        self.peak_torque = 0.0
        #: The travel bound and what is known of how far the moves reach (_learn).
        self._guard: TravelGuard | None = None
        #: The gains the drive runs (as last written), where the demand rests [counts] and the
        #: quick-stop deceleration 6085h as last written (None: not raised by servodesk).
        self._gains_now = ServoGains()
        self._demand = 0.0
        self._qs_dec: float | None = None
        self._qs_writable = False
        #: The simulated axis the model foretells the moves' overshoot on (None: no model yet).
        self._travel_params: PlantParams | None = None
        #: Every move sent, in order (_move; _run_moves observes them from its recording).
        self._moves: list[PlannedMove] = []
        #: The first move's velocity and acceleration, whose run-on the factory gains showed:
        #: the way back to the start after a refusal (_measure_frf).
        self._slow: tuple[float, float] | None = None
        #: A speed the axis stands still within [counts/s] (606Fh, _learn).
        self._rest_speed = 0.0
        #: What the procedure adds to the design's notes in the result.
        self._notes: list[str] = []
        #: What the tries' recordings fitted and what came of it (:meth:`_redesign`), for the
        #: result's ``identified.refit``; None where no try was fitted.
        self._refit: dict[str, Any] | None = None

    def progress(self, fraction: float, step: str) -> None:
        log.info("tuning %.0f %%: %s", fraction * 100.0, step)
        if self._progress is not None:
            self._progress(fraction, step)

    def _gain_address(self, name: str) -> ObjectAddress | None:
        g = self.spec.gains.get(name)
        return None if g is None else g.address

    async def read_gains(self) -> ServoGains:
        values: dict[str, float] = {}
        for name, g in self.spec.gains.items():
            values[name] = await read_float(self.io, g.address) * g.scale
        return ServoGains.from_dict(values)

    async def write_gains(self, gains: ServoGains) -> None:
        """Every mapped gain; the loop state stays (the drive takes them from the next tick)."""
        d = gains.as_dict()
        for n in (1, 2):
            if d[f"notch{n}_hz"] == 0.0:
                # A notch that is off: its width and depth do nothing, keep them in range.
                d[f"notch{n}_width"] = max(d[f"notch{n}_width"], 1.0)
        for name, g in self.spec.gains.items():
            spec = self.io.profile.spec(g.address)
            raw: Value = d[name] / g.scale
            if spec is not None and spec.data_type.is_integer:
                raw = round(float(raw))
            await self.io.write(g.address, raw)
        self._gains_now = gains

    async def _has(self, address: ObjectAddress) -> bool:
        return self.io.profile.spec(address) is not None

    async def _statusword(self) -> int:
        return int(await read_float(self.io, STATUSWORD))

    async def _check_healthy(self) -> None:
        sw = await self._statusword()
        state = decode_state(sw)
        if state is not State.OPERATION_ENABLED:
            raise TuningFailed(
                f"the drive left Operation enabled during tuning ({state.value})",
                hint="read the Alarms page, clear the cause, then tune again",
            )

    def _signal(self, sub: int) -> ObjectAddress:
        index = self.spec.signal_index
        if index is None:
            raise TuningFailed(
                f"{self.io.profile.name} has no test signal generator",
                hint="servodesk's tuning needs the drive to inject a test signal",
            )
        return ObjectAddress(index, sub)

    @property
    def guard(self) -> TravelGuard:
        assert self._guard is not None, "the travel bound is set by _learn"
        return self._guard

    async def _search(self, job: Callable[[], SearchResult]) -> SearchResult:
        """The gain search ``job`` (:meth:`_compute`)."""
        return await self._compute(job)

    async def _compute(self, job: Callable[[], _T]) -> _T:
        """``job`` in the design's worker process unless the tuning runs on simulated time: the
        searches and fits are tens of milliseconds to seconds of Python arithmetic that, here
        or in a thread (which would hold the GIL), would hold the event loop that carries the
        operator's heartbeats and every other session's traffic."""
        if self._offload:
            return await tuning_worker.run(job)
        return job()


async def quietly(aw: Any) -> None:
    """Best effort (restoring after a failure): a second error must not hide the first."""
    try:
        await aw
    except Exception as exc:
        log.warning("tuning: restoring failed: %s", exc)
