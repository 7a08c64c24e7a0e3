"""servodesk's own one-touch tuning: identify, measure, design, verify (docs/tuning.md).

Over 700 lines: :class:`OwnTuning` is one run whose phases (safety, identification, design,
tries on the axis, verification, result) share its state; a split into a module a phase was
made and measured in issue 51 and held the event loop past the dead-man's period on the real
server (tests/browser/test_tuning.py), so it waits for its own change.

For a drive whose profile maps its servo gains (``tuning.kind: gains``). The steps, each a few
hundred milliseconds of axis motion inside the travel window the user confirmed:

1. Frequency response: a PRBS torque from the drive's test signal generator while the axis
   travels at a constant speed; the recorder captures the test signal, the torque command and
   the velocity at the loop rate; the plant's response is their instrumental estimate
   (domain/tuning/identify.py). Resonances come from its peaks over the rigid-body line.
2. Inertia and friction: back-and-forth profile-position moves, sized from the first estimate so
   that the inertial torque is about a third of the tuning torque limit and the acceleration
   phases last several periods of the lowest anti-resonance (anchors-tuning.md §3.7: faster
   moves identify the motor, not the machine); least squares on torque against acceleration.
   A resonance without an anti-resonance in the band has it below: the moves are sized for
   the band's lowest frequency, and their inertia places it (identify.py).
3. Before: the drive's gains as they are, a verification move sized for the inertia found,
   recorded by the drive-side recorder (the "before" step response).
4. Design: the identified two-mass model, notches where a resonance limits the loop, the
   highest velocity gain meeting PM >= 45 deg, GM >= 8 dB, Ms <= 6 dB (domain/tuning/design.py)
   scaled to the response level; then the candidates near it ranked by what they do to a move
   on the identified model (settling to +-10 counts, then +-100 counts, then following error),
   the same objective as the benchmark's oracle (domain/tuning/search.py).
5. Apply and verify: the new gains are written, the verification move runs again (the "after"
   step response); a result that does not settle or is worse than before is undone.

Safety (issue 8 §7): during tuning the torque limit 6072h is the user's and the following error
window 6065h is widened (the low default gains of an untuned axis lag far behind a brisk
identification move). The travel window W the user confirms is a total width centred on where
the axis stands: every move is planned so that its set-points, the loop's overshoot past them and
a stop's run-out stay within start +- W/2 (services/tuning/travel.py), and the drive's own
software position limits 607Dh are set there before the first move (CiA 402-2 §6.5.4), with the
quick-stop deceleration 6085h raised to each move's own so that a dead-man stop brakes no
gentler than the move. All of them, the mode and every gain are put back when the tuning ends,
fails or is cancelled (stop, dead-man), once the axis has stopped; the new gains stay only after
a successful verification, and nothing is stored to non-volatile memory unless the user asks
(POST .../tuning/store).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, replace
from typing import Any, NamedTuple, TypeVar

import numpy as np
from scipy.signal import lfilter  # type: ignore[import-untyped]

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CONTROLWORD,
    CW_ENABLE,
    CW_HALT,
    CW_IMMEDIATE,
    CW_NEW_SETPOINT,
    ENCODER_INCREMENTS,
    ENCODER_REVOLUTIONS,
    FOLLOWING_ERROR,
    FOLLOWING_ERROR_WINDOW,
    HALT_OPTION,
    MAX_PROFILE_VELOCITY,
    MAX_TORQUE,
    MODE,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    QUICK_STOP_DEC,
    QUICK_STOP_OPTION,
    RATED_TORQUE,
    SOFT_LIMIT_MAX,
    SOFT_LIMIT_MIN,
    STATUSWORD,
    SW_TARGET_REACHED,
    TARGET_POSITION,
    VELOCITY,
    VELOCITY_THRESHOLD,
    Mode,
    State,
    decode_state,
)
from servodesk.domain.datatypes import Value
from servodesk.domain.profile import TuningSpec
from servodesk.domain.tuning.design import ResponseLevel
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.identify import (
    Frf,
    InertiaEstimate,
    RecordFit,
    Resonance,
    demand_spans,
    find_resonances,
    frequency_response,
    identify_rigid,
    inertia_from_frf,
    inertia_from_moves,
    model_damping,
    moves_gravity,
    plant_from_identification,
    resonance_from_record,
    travel_load_torque,
    with_hidden_anti_resonance,
)
from servodesk.domain.tuning.metrics import move_metrics, smoothed_settling
from servodesk.domain.tuning.model import LoopModel, PlantModel
from servodesk.domain.tuning.promise import RESONANCE_TOL, RESONANCE_TOL_PEAK
from servodesk.domain.tuning.search import (
    ALTERNATIVE_SETTLING_FACTOR,
    LOW_ANTI_RESONANCE_HZ,
    REF_HOLD_PERIODS,
    RIGID_VARIATIONS,
    VARIATIONS,
    SearchResult,
    tune_on_model,
)
from servodesk.domain.tuning.travel import TravelBound, half_window
from servodesk.errors import DriveStateError, ServodeskError, ValidationError
from servodesk.model.plant import PlantParams
from servodesk.model.replay import ModelMoves, OwnMove, RecordedMove, WorstOf
from servodesk.services.session import Session
from servodesk.services.tuning import worker as tuning_worker
from servodesk.services.tuning.calibrate import fit_inertias, fit_split, recorded_move
from servodesk.services.tuning.io import DriveRecorder, Recording, SessionIO, TuningIO, read_float
from servodesk.services.tuning.travel import (
    UNSEEN_SHARE,
    PlannedMove,
    TravelExceeded,
    TravelGuard,
    model_overshoots,
)

log = logging.getLogger(__name__)

PP = int(Mode.PROFILE_POSITION)
#: What a job handed to the design worker returns (:meth:`OwnTuning._compute`).
_T = TypeVar("_T")

Progress = Callable[[float, str], None]


#: Test signal generator sub-indexes (docs/tuning.md).
SIG_KIND, SIG_AMPLITUDE, SIG_F0, SIG_F1, SIG_DURATION, SIG_CONTROL, SIG_TORQUE, SIG_VALUE = range(
    1, 9
)
SIG_PRBS = 2

#: Chirp: from this frequency, for this long, at this share of the tuning torque limit.
CHIRP_F0_HZ = 10.0
CHIRP_S = 1.0
CHIRP_SHARE = 0.12
#: The lowest frequency the response is read at, twice the chirp's start: where the search for
#: resonances and dips and the rigid-body band begin.
BAND_LOW_HZ = 2.0 * CHIRP_F0_HZ
#: The frequency response is measured travelling this far (anchors-tuning.md §3.5: at most +-0.25
#: rev per frequency response) ...
FRF_TRAVEL_REV = 0.45
#: ... centred on the start, each end at most this share of the half-window from it: its way up, the
#: first move, keeps the rest in reserve for run-on nothing yet foretells (measured:
#: docs/tuning.md).
FRF_HALF_SHARE = 0.9
#: The way up to the travel's start accelerates and brakes over this long, and the axis rests there
#: this long before the travel, so that a soft load has stopped swinging (measured: docs/tuning.md).
#: Resting is not axis time.
FRF_PRE_RAMP_S = 0.25
FRF_REST_S = 1.0
#: The recording of the frequency response's travel goes on this long after its profile ends, with
#: the position, so that what the travel ran on past its end is measured, not guessed.
FRF_TAIL_S = 0.15
#: The identification moves' and the verification move's distance at most: these shares of the
#: window's width (and IDENT_REV, VERIFY_REV). Both run from a rest position half the verification
#: distance below the start (``_Drive.home``): the verification move and the tries, as long as
#: half the window, are centred on the start and keep half their distance in reserve at either
#: end (services/tuning/travel.py NEW_GAINS_SHARE).
IDENT_REV = 0.2
IDENT_WINDOW_SHARE = 0.4
VERIFY_WINDOW_SHARE = 0.5
#: A move that does not fit is shortened by this factor until it does (at most
#: SHRINK_STEPS times).
SHRINK = 0.85
SHRINK_STEPS = 12
#: The identification moves must keep this share of their distance (_identify).
MIN_IDENT_SHARE = 0.5
#: After a stop or a failure the axis must stand (606Ch within the velocity threshold 606Fh)
#: for this long, polled this often, before the settings are put back; at most REST_WAIT_S.
REST_STILL_S = 0.03
REST_POLL_S = 0.01
REST_WAIT_S = 2.0
#: Identification moves: inertial torque as a share of the tuning torque limit.
MOVE_TORQUE_SHARE = 0.35
#: An anti-resonance the record fit finds below the band is taken when its motor inertia is
#: within this fraction of the frequency response's (OwnTuning._anti_below_band) ...
BELOW_BAND_MOTOR_TOL = 0.25
#: ... and its anti-resonance lies below this multiple of the band's lower edge: the peak
#: finder needs bins on both sides of a dip (8 Hz apart), so one within a bin of the edge
#: does not show either (a load 8 x the motor on a 60 Hz shaft: 20.0 Hz).
BELOW_BAND_EDGE = 1.25
#: Acceleration phases last at least this many periods of the lowest anti-resonance.
MOVE_AR_PERIODS = 3.0
#: Friction fit window of a compliant axis: short, so that the torque step at each reversal is not
#: smeared into the viscous term; the shaft's oscillation averages out (measured: docs/tuning.md).
FRICTION_WINDOW_S = 0.004
#: The identification moves of a compliant axis start this long after the last one's profile
#: ended, so that the load moves with the motor when the moves' double integral begins
#: (:meth:`OwnTuning._moves_inertia`; measured: docs/tuning.md). Rest is not axis time.
COMPLIANT_MOVES_REST_S = 0.1
#: The moves' double integral is taken for a compliant axis's inertia where friction is less
#: than this share of it on every move ...
MOVES_INERTIAL_SHARE_MIN = 0.6
#: ... and its moves agree within this (relative standard deviation; measured: docs/tuning.md).
MOVES_SPREAD_MAX = 0.015
#: The moves' inertia fitted with a viscous friction (``MovesInertia.with_viscous``) is taken
#: where it parts from the plain one by more than this: viscous friction makes the plain value
#: come out high by its share (measured: docs/tuning.md).
MOVES_VISCOUS_PART = 0.03
#: An axis without a resonance in its frequency response must fit the rigid-body equation
#: within this share of the torque's spread unexplained (measured: docs/tuning.md).
RIGID_RESIDUAL_MAX = 0.3
#: Verification move: at most this many rev (and VERIFY_WINDOW_SHARE of the window's width).
VERIFY_REV = 0.25
VERIFY_SETTLE_S = 0.25
#: A try of a runner-up on a slow axis is watched up to this long after its profile
#: (:func:`watch_for`; measured: docs/tuning.md).
TRY_WATCH_MAX_S = 1.0
#: A runner-up tried on the axis replaces the pick so far only where it settles clearly sooner: in
#: less than this share of the pick's time; a smaller lead is within what the two moves of one try
#: disagree by (measured: docs/tuning.md). Not where the response did not show the anti-resonance.
TRY_CLEAR_SHARE = 0.7
#: A try's move has settled only where the 5 ms mean of its error then stays inside +-10 counts for
#: at least this long before the watch ends (``_try_key``); one that did not counts as the watch: a
#: last crossing just before the watch ends is torque noise (measured: docs/tuning.md).
TRY_SETTLED_HOLD_S = 0.1
#: Axis time a tuning may spend moving (issue 8: at most 5 s); runners-up are tried only while
#: one more try, the verification move after it and the way back to the start fit, with 0.1 s to
#: spare for what the count of a profile's time misses (measured: docs/tuning.md).
AXIS_BUDGET_S = 4.9
#: The search again with the inertias the tries' recordings fit (services/tuning/calibrate.py)
#: only where one of them moved by at least this share and the fit's output error is at most
#: this share of the model's: a model already within the noise is not searched again.
CALIBRATE_MIN_CHANGE = 0.005
CALIBRATE_ERROR_SHARE = 0.5
#: Below this anti-resonance the tuning takes the record fit's whole-axis inertia,
#: J_M (f_r / f_ar)^2 (``RecordFit.total_inertia``): the response's rigid-body band then holds
#: three or fewer of its 7.8 Hz bins (measured: docs/tuning.md).
RECORD_INERTIA_BELOW_HZ = 65.0
#: From there up to this anti-resonance, where the test moves' double integral is not taken, the
#: inertia is the geometric mean of the response's rigid-body band and the record fit's
#: J_M (f_r / f_ar)^2 when they agree within :data:`RECORD_BLEND_AGREE`: their errors are
#: independent (measured: docs/tuning.md).
RECORD_BLEND_BELOW_HZ = 150.0
#: How far apart the two estimates may be for :data:`RECORD_BLEND_BELOW_HZ` (a fit further
#: off fitted something else).
RECORD_BLEND_AGREE = 0.1
#: Torque share of the move runners-up are compared with (search.py's reference move: 0.7).
RANK_TORQUE_SHARE = 0.7
#: Runs of the oracle's structure search (oracle.py; search.tune_on_model ``structure_runs``)
#: on the model of a compliant axis whose anti-resonance the response shows, ranked with the
#: variations (measured: docs/tuning.md).
STRUCTURE_RUNS = 100
#: A rigid axis whose inertia the drive's position demand instrumented (identify_rigid) is ranked on
#: the identified axis and on it this much lighter and heavier (``WorstOf``): the instrumented fit's
#: error on the benchmark's rigid axes, with a margin (measured: docs/tuning.md) ...
RIGID_INERTIA_TOLERANCE = 0.0065
#: ... and on it this much lighter too: a machine's load changes a little, and an inertia
#: feed-forward above the axis's inertia overshoots and sticks (measured: docs/tuning.md).
RIGID_LIGHTER = 0.015
#: A compliant axis's first candidates are re-ranked by their worst move over the model and
#: the model with its Coulomb friction this much lower and higher (search.confirmed): what the
#: moves measure is a few percent off (measured: docs/tuning.md).
FRICTION_CONFIRM = 0.02
#: The least inertia change (a share of it) the same confirmation takes where the moves'
#: double integral gave the inertia (measured: docs/tuning.md).
INERTIA_CONFIRM_MIN = 0.002
#: A mode the record fit placed may be this much less damped than the fit says (the margins
#: hold there too, search.identification_set): the fit cannot say itself how far off its
#: damping is (measured: docs/tuning.md).
LIGHT_DAMPING_FACTOR = 0.25


@dataclass(frozen=True, slots=True)
class OwnTuningRequest:
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
class _Drive:
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


class Redesign(NamedTuple):
    """The gain search again on the model with the inertias the tries' recordings fit."""

    design: SearchResult
    model: PlantModel


class OwnTuning:
    """One tuning run over a :class:`TuningIO` (a session's drive, or a simulated one)."""

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

    # ------------------------------------------------------------------ small helpers

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

    # ------------------------------------------------------------------ the run

    async def run(self) -> dict[str, Any]:
        """Tune; returns the TuningResult JSON (docs/tuning.md). On any failure or
        cancellation the previous gains and settings are back before the error propagates."""
        sw = await self._statusword()
        if decode_state(sw) is not State.OPERATION_ENABLED:
            raise DriveStateError(
                f"tuning needs Operation enabled; the drive is in {decode_state(sw).value}",
                hint="servo on first (Operation page)",
            )
        drive = await self._learn()
        before = await self.read_gains()
        saved = await self._save_settings()
        try:
            await self._set_safety(drive)
            self.progress(0.05, "frequency response (PRBS torque while travelling)")
            frf = await self._measure_frf(drive)
            j_rough = self._inertia_from_frf(frf, drive, (BAND_LOW_HZ, 4.0 * BAND_LOW_HZ))
            first = self._resonances(frf, j_rough, drive)
            j_frf, frf_band_ok = self._inertia_corrected(frf, drive, first, j_rough)
            # From here the model foretells how far the factory gains overshoot a move
            # (services/tuning/travel.py), besides what the frequency response's moves showed.
            self._set_travel_model(
                plant_from_identification(j_frf, first, current_loop_hz=drive.current_loop_hz),
                drive,
            )
            self.progress(0.3, "inertia and friction (test moves)")
            # An anti-resonance below the band leaves the moves little inertial torque to fit:
            # the record fit's whole-axis inertia stands in when theirs comes out negative.
            early = (await self._anti_below_band(first, j_frf))[1]
            fallback = early.total_inertia if early is not None else None
            # A rigid axis's moves are also recorded with the drive's position demand, which
            # instruments their fit, and its ranking then trusts the model (below).
            instrumented = await self._instrumented(first)
            est, cruise_rad_s = await self._identify(
                drive, j_frf, first, fallback, instrumented=instrumented
            )
            # A compliant axis: the inertia of the frequency response's rigid-body band, with
            # the two-mass shape divided out, is the better estimate (the test moves' fit must
            # smooth over the shaft oscillation); a rigid axis: the moves' fit (friction and
            # gravity apart).
            compliant = any(r.anti_freq_hz for r in first)
            inertia = j_frf if compliant and frf_band_ok else est.inertia
            # Better still, where friction leaves the moves enough inertial torque: their
            # double integral (the benchmark's 400-800 Hz axes over seeds 1-4: |error| median
            # 0.25 %, worst 1.2 %, where the response's band was 0.94 % and 3.9 %,
            # docs/tuning.md).
            from_moves = self._moves_inertia(inertia) if compliant else None
            j_moves, moves_spread = from_moves if from_moves is not None else (None, None)
            if j_moves is not None:
                log.debug("inertia from the moves: %.4g (the response's: %.4g)", j_moves, inertia)
                inertia = j_moves
            est = replace(est, inertia=inertia)
            found = with_hidden_anti_resonance(first, j_frf, inertia, BAND_LOW_HZ)
            hidden = found != first
            if hidden:
                # The frequency response saw the motor alone: the mode's anti-resonance lies
                # below its band, and the moves' inertia places it (identify.py).
                log.debug("anti-resonance below the band measured: %s", found)
            else:
                found = self._resonances(frf, inertia, drive)
            found, below_fit = await self._anti_below_band(found, j_frf)
            below_band = below_fit is not None
            resonances, j_record = await self._sharpen(found)
            # The record fit moved a peak: the two estimates disagreed by more than 3 %.
            refitted = [r.freq_hz for r in resonances] != [r.freq_hz for r in found]
            low = _lowest_anti(resonances)
            if (
                j_record is not None
                and j_moves is None
                and low is not None
                and low < RECORD_INERTIA_BELOW_HZ
                # A fit that lands far from both other estimates fitted something else; one
                # that found the anti-resonance below the band agreed with the response's
                # motor inertia instead (_anti_below_band), and there the moves saw part of
                # the load only.
                and (below_band or 0.5 < j_record / inertia < 2.0)
            ):
                # Below a low anti-resonance neither the moves (which must smooth over the
                # swinging load) nor the response's few rigid-body bins place the inertia well
                # (R30-100Hz +14 %, R30-200Hz +10 %, R3-100Hz -27 %); the record fit's
                # J_M (f_r / f_ar)^2 does, within 5 % on the benchmark's six such plants over
                # four noise seeds (docs/tuning.md).
                log.debug("inertia from the record fit: %.4g (was %.4g)", j_record, inertia)
                inertia = j_record
                est = replace(est, inertia=inertia)
            elif (
                j_record is not None
                and j_moves is None
                and frf_band_ok
                and low is not None
                and low < RECORD_BLEND_BELOW_HZ
                and abs(j_record / inertia - 1.0) < RECORD_BLEND_AGREE
            ):
                # Two estimates with independent errors: the response's few rigid-body bins
                # below 0.7 f_ar, two-mass shape divided out, and the fit of the whole record
                # (how far each was off: RECORD_BLEND_BELOW_HZ).
                blended = math.sqrt(j_record * inertia)
                log.debug(
                    "inertia: %.4g, between the response's band %.4g and the record fit %.4g",
                    blended,
                    inertia,
                    j_record,
                )
                self._notes.append(
                    f"inertia {blended:.4g} kg m^2: the mean of the frequency response's "
                    f"rigid-body band ({inertia:.4g}) and the fit of its whole record "
                    f"({j_record:.4g})"
                )
                inertia = blended
                est = replace(est, inertia=inertia)
            # The verification move is sized for the inertia the moves confirmed: the frequency
            # response alone can see the motor without its load (below a low anti-resonance),
            # and a move sized for that runs into the torque limit.
            self.progress(0.55, "verification move with the present gains")
            model = plant_from_identification(
                inertia,
                resonances,
                viscous=max(est.viscous, 0.0),
                current_loop_hz=drive.current_loop_hz,
            )
            self._set_travel_model(model, drive, coulomb=max(est.coulomb, 0.0), gravity=est.gravity)

            def verify_size(d: float) -> tuple[float, float]:
                return self._verify_profile(drive, inertia, d)[1:]

            # Where the frequency response did not show the anti-resonance, the new gains'
            # first moves are given a larger reserve (travel.UNSEEN_SHARE).
            if hidden or below_band or self._travel_params is None:
                self.guard.fresh_share = UNSEEN_SHARE
            # Shortened where the present gains' overshoot would not fit, nor the reserve of
            # gains that have not moved the axis yet (the new gains': their model's is checked
            # before their own verification move, below).
            profile = await self._fit_profile(
                drive,
                verify_size,
                drive.verify_distance,
                VERIFY_SETTLE_S,
                "the verification move",
                also_fresh=True,
            )
            step_before = await self._verify_move(drive, profile)
            if self.guard.fresh_share < UNSEEN_SHARE and not self._model_foretold(2):
                # The model did not foretell the present gains' run-on: the new gains, designed
                # on it, get the larger reserve too, and the move they are compared on is run
                # again as short as that needs (soft-8x-60hz: 0.034 rev where the model said
                # 0.004; the design's gains then ran on 0.066).
                self.guard.fresh_share = UNSEEN_SHARE
                shorter = await self._fit_profile(
                    drive,
                    verify_size,
                    profile[0],
                    VERIFY_SETTLE_S,
                    "the verification move",
                    also_fresh=True,
                )
                if shorter[0] < profile[0]:
                    profile = shorter
                    step_before = await self._verify_move(drive, profile)
            self.progress(0.65, "designing gains and filters")
            # The ranking's model has Coulomb friction only (its viscous term is dropped,
            # below), and a sticking axis that stops 10 counts early or late settles at another
            # time: the friction it takes matters to the percent.
            f_ar = model.anti_resonance_hz
            low_anti = f_ar is not None and f_ar < LOW_ANTI_RESONANCE_HZ
            # The moves' own friction: c + b v at their cruise speed. They measured it at that
            # one speed, and from one speed the fit cannot tell c from b: it lent up to half
            # of the Coulomb friction to b (R1-100Hz: c 47 % low, where b is 0; taking c + b v
            # rather than c: bench median 1.84 -> 1.76 x the oracle, docs/tuning.md). Below a
            # low anti-resonance c alone: the moves are gentle there and their b is the
            # shaft's, not friction (a load 10 x the motor behind 18 Hz: c + b v was far above
            # the friction, and the ranking's gains overshot 11 % where the factory gains
            # overshot 6 %); their c was 8-30 % low there.
            moves_friction = max(
                est.coulomb + (0.0 if low_anti else est.viscous * cruise_rad_s), 0.0
            )
            # A compliant axis's moves, recorded with the drive's demand, give the gravity
            # apart from the friction (identify.moves_gravity: within 0.02 % of the peak
            # torque, where their least squares were up to 0.054 % off, 2.4 mN m, the same way
            # on every seed), and the frequency response's slow constant-speed travel less
            # that gravity is the friction: within 1.6 % on every compliant axis of the
            # benchmark over two seeds, where c + b v was -3 to +11 % off (docs/tuning.md).
            # Without the moves' gravity the travel's friction is taken below a low
            # anti-resonance only (within 1.2 % there): a 400 Hz axis's least-squares gravity
            # left it 2-3.7 % high.
            gravity = self._moves_gravity(inertia)
            if gravity is not None:
                est = replace(est, gravity=gravity)
            travel = self._travel_friction(inertia, est.gravity)
            friction = moves_friction
            if travel is not None and (gravity is not None or low_anti):
                friction = travel
                self._notes.append(
                    f"Coulomb friction from the slow travel of the frequency response "
                    f"({travel:.4g} N m; the test moves gave {moves_friction:.4g} N m)"
                )

            # An anti-resonance below the band measured was placed by the moves' inertia or
            # the record fit, its damping too: the structure search's pick, as sharp as that
            # model allows, overshot on the axis (a load 10 x the motor on a 60 Hz shaft,
            # damping 0.01: 11 % where the factory gains overshot 6 %, and refused).
            unseen = hidden or below_band

            # Ranked without the viscous term: the moves' fit lends it friction and shaft
            # effects the machine may not have (R10-100Hz: 0.0029 N m s/rad where there is
            # none), and damping the axis lacks makes sluggish gains look settled. Real
            # viscous friction only helps whatever gains win (bench median ratio 1.93 ->
            # 1.60, docs/tuning.md).
            def model_moves(
                model: PlantModel, scale: float = 1.0, friction_scale: float = 1.0
            ) -> ModelMoves | None:
                return ModelMoves.of(
                    replace(
                        model,
                        viscous=0.0,
                        motor_inertia=model.motor_inertia * scale,
                        load_inertia=model.load_inertia * scale,
                    ),
                    drive.rate_hz,
                    counts_per_rev=drive.counts_per_rev,
                    torque_limit=drive.move_torque,
                    coulomb=friction * friction_scale,
                    gravity=est.gravity,
                )

            def design_job(
                model: PlantModel, incumbent: ServoGains | None = None
            ) -> tuple[Callable[[], SearchResult], bool]:
                """The gain search on ``model`` (the identified axis, or the same with the
                inertias the tries' records fitted: :meth:`_try_alternatives`), and whether it
                ranks a rigid axis with the instrumented inertia (no tries then)."""

                def moves(scale: float, friction_scale: float = 1.0) -> ModelMoves | None:
                    return model_moves(model, scale, friction_scale)

                nominal = moves(1.0)
                rerank: ModelMoves | WorstOf | None = nominal
                variations = VARIATIONS
                rigid_model = nominal is not None and instrumented
                if rigid_model:
                    # Its variations reach feed-forwards near the inertia: a rigid axis then
                    # stops closer to the target when its profile ends (R10-rigid: 61 counts
                    # of lag at 0.85 J, 30 at 1.0 J), which the oracle's gains rest on; that
                    # pays only with the inertia known to well under 2 %.
                    tol = RIGID_INERTIA_TOLERANCE
                    members = (
                        moves(1.0 - tol),
                        nominal,
                        moves(1.0 + tol),
                        moves(1.0 - RIGID_LIGHTER),
                    )
                    rerank = WorstOf(tuple(m for m in members if m is not None))
                    self._notes.append(
                        f"ranked by the worst move on the identified axis, on it "
                        f"{100.0 * tol:.2g} % lighter and heavier, and "
                        f"{100.0 * RIGID_LIGHTER:.2g} % lighter (a lighter load must not "
                        f"overshoot and stick)"
                    )
                    variations = replace(VARIATIONS, ff=RIGID_VARIATIONS.ff)
                    if self.request.move_torque_pct is not None:
                        # The whole rigid grid only for the machine's own move: gains ranked at
                        # the hardest move stayed as fast on gentler ones (100-351 % of rated,
                        # 0.25 and 0.5 rev, six rigid axes), while those ranked at the tuning's
                        # limit settled many times slower on harder moves (R3-rigid 0.9 -> 19-27
                        # ms), and the rigid grid's more so (R1-rigid 57 ms even on its own
                        # move, docs/tuning.md).
                        variations = RIGID_VARIATIONS
                # A compliant axis's first candidates must also settle with the friction a
                # little off what the moves measured (1.4-6.9 % high on the benchmark's 400 Hz
                # axes): the model's fastest were often fast only at that friction
                # (search.confirmed).
                confirm: WorstOf | None = None
                if resonances and not rigid_model:
                    off: list[ModelMoves | OwnMove | None] = [
                        moves(1.0, 1.0 + f) for f in (-FRICTION_CONFIRM, FRICTION_CONFIRM)
                    ]
                    if moves_spread is not None:
                        # Where the moves' double integral gave the inertia, also with the
                        # inertia off by as much as their moves disagree (at least
                        # INERTIA_CONFIRM_MIN), each on the machine's move as that inertia makes
                        # it: stress-noise4x seed 2's model, 1.2 % light, put first gains that
                        # settled 10 x slower than the oracle's on the axis (docs/tuning.md).
                        spread = max(moves_spread, INERTIA_CONFIRM_MIN)
                        log.debug("confirmed with the inertia +-%.2g %%", 100.0 * spread)
                        for f in (-spread, spread):
                            m = moves(1.0 + f)
                            off.append(OwnMove(m, model.total_inertia * (1.0 + f)) if m else None)
                    if all(m is not None for m in off):
                        confirm = WorstOf(tuple(m for m in off if m is not None))
                job = functools.partial(
                    tune_on_model,
                    model,
                    drive.rate_hz,
                    self.request.mode,
                    counts_per_rev=drive.counts_per_rev,
                    torque_limit=drive.move_torque,
                    coulomb=friction,
                    gravity=est.gravity,
                    rerank=rerank,
                    variations=variations,
                    # The oracle's structures too, where a resonance gives them something to
                    # shape (a rigid axis's structures changed nothing, docs/tuning.md), unless
                    # the frequency response did not show its anti-resonance (``unseen``).
                    structure_runs=STRUCTURE_RUNS if resonances and not unseen else 0,
                    # High response trusts a resonance where the response's own peak put it
                    # (promise.RESONANCE_TOL_PEAK); one the record fit placed, it does not.
                    resonance_tol=(
                        RESONANCE_TOL_PEAK
                        if self.request.mode == "high" and not (unseen or refitted)
                        else RESONANCE_TOL
                    ),
                    # Where the response did not show the anti-resonance the model's moves are
                    # the least like the axis's, and the tries on the axis may pick any runner-up:
                    # a load 10 x the motor behind a 60 Hz shaft overshot 11 % with the model's
                    # winner (the factory gains: 6 %), and a runner-up the model put slower
                    # than 1.5 x the winner settled it.
                    try_factor=math.inf if unseen else ALTERNATIVE_SETTLING_FACTOR,
                    confirm=confirm,
                    # Not where the response did not show the anti-resonance: there the model's
                    # moves are the least like the axis's.
                    ff_sweep=not unseen,
                    incumbent=incumbent,
                    # A mode the record fit placed is a low, sharp one whose damping the record
                    # barely resolves (identify.resonance_from_record): the margins also hold
                    # with it LIGHT_DAMPING_FACTOR as damped.
                    light_damping=(
                        model.damping * LIGHT_DAMPING_FACTOR
                        if resonances and (unseen or refitted)
                        else None
                    ),
                )
                return job, rigid_model

            job, rigid_model = design_job(model)
            design = await self._search(job)
            self.progress(0.8, "applying the new gains and verifying")
            # The new gains' overshoot on the identified model, with the friction and gravity
            # the ranking took, before they move the axis.
            self._set_travel_model(model, drive, coulomb=friction, gravity=est.gravity)
            if not await self._fits_there_and_back(drive, profile, design.gains, VERIFY_SETTLE_S):
                raise TravelExceeded(
                    "the new gains may overshoot the verification move past the travel window "
                    "(on the identified model, or half the move where they have not moved the "
                    "axis yet); the previous gains are back",
                    hint="give a wider travel window, or tune with a lower response level",
                )
            await self.write_gains(design.gains)
            step_after = await self._verify_move(drive, profile)
            await self._check_healthy()
            if not rigid_model:
                # On a rigid axis with the instrumented inertia the model is the axis to
                # within its friction's few percent (its settling on the benchmark's seven
                # rigid axes matched the true plant's to 0.1 ms with the exact inertia): the
                # tries' brisk move and torque noise judged worse than it and took the old
                # design's gains back (R3-rigid 1.40 -> 1.46 x the oracle, R1-rigid 1.38 ->
                # 2.3 on two of four seeds, docs/tuning.md).

                identified = model

                async def redesign(
                    records: list[RecordedMove], first: ServoGains
                ) -> Redesign | None:
                    return await self._redesign(
                        identified,
                        model_moves(identified),
                        records,
                        drive,
                        design_job,
                        first,
                        split_only=moves_spread is not None,
                    )

                _, step_after, design, model = await self._try_alternatives(
                    drive,
                    profile,
                    design,
                    step_after,
                    model,
                    trust_model=not unseen,
                    # Not where the response did not show the anti-resonance (the model's shape
                    # is its least certain part there, which the inertias cannot mend). Where the
                    # moves' double integral gave the inertia (within 0.25 % at the median on the
                    # benchmark's 400-800 Hz axes, closer than the fit, whose inertias also take
                    # up what the friction and damping are off by: R3-800Hz seed 1's motor came
                    # out 4.1 % heavier and its gains settled 2 x slower), only the split between
                    # motor and load is fitted, the total held (_redesign's split_only). Only at
                    # ``high``: the other levels rank nothing and try nothing on the axis.
                    redesign=None if unseen or self.request.mode != "high" else redesign,
                )
            refuse_if_worse(step_before, step_after)
            # Back where the axis stood, with the new gains at the verification's speed.
            await self._return_to_start(drive, profile[1], profile[2])
        except BaseException as exc:
            # The axis stops first: putting 607Dh, 6085h or the gains back while it still
            # moved would change how it stops.
            await _quietly(self._come_to_rest())
            await _quietly(self.write_gains(before))
            if isinstance(exc, TuningFailed | TravelExceeded) and self._slow is not None:
                # The tuning's own verdict, the axis enabled: back to the start with the
                # previous gains, as gently as their first move, whose run-on they showed.
                await _quietly(self._return_to_start(drive, *self._slow))
            await _quietly(self._restore_settings(saved))
            raise
        await self._restore_settings(saved)
        self.progress(1.0, "done")
        return self._result(
            drive,
            before,
            design,
            est,
            (travel, friction),
            cruise_rad_s,
            resonances,
            model,
            frf,
            step_before,
            step_after,
        )

    async def _learn(self) -> _Drive:
        io = self.io
        prof = io.profile
        rate_addr = self.spec.loop_rate_address
        rate = (
            await read_float(io, rate_addr)
            if rate_addr is not None
            else (prof.recorder.rate_hz if prof.recorder else 0.0)
        )
        if not rate > 0.0:
            raise TuningFailed("the drive reports no servo loop rate")
        if await self._has(ENCODER_INCREMENTS):
            inc = await read_float(io, ENCODER_INCREMENTS)
            revs = (
                await read_float(io, ENCODER_REVOLUTIONS)
                if await self._has(ENCODER_REVOLUTIONS)
                else 1.0
            )
            cpr = inc / max(revs, 1.0)
        else:
            cpr = float(prof.simulation.counts_per_rev)
        if await self._has(RATED_TORQUE):
            rated = await read_float(io, RATED_TORQUE) * 1e-3  # 6076h is in mN m.
        else:
            rated = prof.simulation.rated_torque
        limit = rated * self.request.torque_limit_pct / 100.0
        if await self._has(MAX_TORQUE):
            drive_max = await read_float(io, MAX_TORQUE) * 1e-3 * rated
            if drive_max > 0.0:
                limit = min(limit, drive_max)
        current = self._current_loop_hz
        addr = self.spec.current_loop_address
        if current is None and addr is not None:
            current = await read_float(io, addr)
        p0 = int(await read_float(io, POSITION))
        half = self.request.half_window_counts
        if half is None:
            half = half_window(self.request.travel_window_rev, cpr)
        bound = TravelBound(p0, half)
        if await self._has(SOFT_LIMIT_MIN) and await self._has(SOFT_LIMIT_MAX):
            lo = await read_float(io, SOFT_LIMIT_MIN)
            hi = await read_float(io, SOFT_LIMIT_MAX)
            # Both 0 switches the limits off (CiA 402-2 §6.5.4).
            if lo < hi and (bound.low < lo or bound.high > hi):
                raise ValidationError(
                    f"the travel window {self.request.travel_window_rev:g} rev (±{half} around "
                    f"{p0}: {bound.low}..{bound.high}) does not fit the software limits "
                    f"{lo:.0f}..{hi:.0f} (607Dh)",
                    field="travel_window_rev",
                    hint="move the axis away from the limit or give a smaller window",
                )
        vmax = math.inf
        if await self._has(MAX_PROFILE_VELOCITY):
            vmax = await read_float(io, MAX_PROFILE_VELOCITY) or math.inf
        move = limit
        if self.request.move_torque_pct is not None:
            move = rated * self.request.move_torque_pct / 100.0
        self._guard = TravelGuard(bound)
        self._demand = float(p0)
        self._rest_speed = 0.01 * cpr
        if await self._has(VELOCITY_THRESHOLD):
            self._rest_speed = await read_float(io, VELOCITY_THRESHOLD) or self._rest_speed
        self._gains_now = await self.read_gains()
        return _Drive(rate, cpr, rated, limit, current, p0, bound, vmax, move, home=p0)

    async def _save_settings(self) -> list[tuple[ObjectAddress, Value]]:
        saved: list[tuple[ObjectAddress, Value]] = []
        for a in (
            MODE,
            FOLLOWING_ERROR_WINDOW,
            MAX_TORQUE,
            SOFT_LIMIT_MIN,
            SOFT_LIMIT_MAX,
            PROFILE_VELOCITY,
            PROFILE_ACC,
            PROFILE_DEC,
            QUICK_STOP_DEC,
        ):
            spec = self.io.profile.spec(a)
            if spec is not None and spec.access.readable and spec.access.writable:
                saved.append((a, await self.io.read(a)))
        return saved

    async def _restore_settings(self, saved: list[tuple[ObjectAddress, Value]]) -> None:
        for a, v in saved:
            await self.io.write(a, v)

    async def _write_if(self, address: ObjectAddress, value: Value) -> None:
        spec = self.io.profile.spec(address)
        if spec is not None and spec.access.writable:
            await self.io.write(address, value)

    def _writable(self, address: ObjectAddress) -> bool:
        spec = self.io.profile.spec(address)
        return spec is not None and spec.access.writable

    async def _set_safety(self, drive: _Drive) -> None:
        """Before the first move: the user's torque limit, the drive's software position
        limits 607Dh at the travel bound, a following error window as wide as the travel
        window, and what a stop brakes with (module docstring)."""
        await self._write_if(
            MAX_TORQUE, max(1, round(drive.limit_torque / drive.rated_torque * 1e3))
        )
        b = drive.bound
        if self._writable(SOFT_LIMIT_MIN) and self._writable(SOFT_LIMIT_MAX):
            # CiA 402-2 §6.5.4: the drive limits every target to 607Dh:01..02 (min = max = 0
            # switches them off; a bound of at least one count either side never is 0..0).
            # The backstop behind servodesk's own planning: a target outside never reaches
            # the axis, whatever computed it.
            await self.io.write(SOFT_LIMIT_MIN, b.low)
            await self.io.write(SOFT_LIMIT_MAX, b.high)
            self._notes.append(
                f"the drive's software position limits 607Dh were {b.low} .. {b.high} (the "
                f"travel bound) from before the first move, and are back as they were"
            )
        else:
            self._notes.append(
                f"{self.io.profile.name} has no writable software position limits (607Dh): only "
                f"servodesk's own bound ({b.low} .. {b.high}) applied, not the drive's"
            )
        await self._write_if(FOLLOWING_ERROR_WINDOW, round(drive.width))
        await self.io.write(MODE, PP)
        self._qs_writable = self._writable(QUICK_STOP_DEC)
        self._qs_dec = None
        guard = self._guard
        assert guard is not None
        guard.stop_deceleration = await self._stop_deceleration()

    async def _stop_deceleration(self) -> float | None:
        """The gentlest ramp a dead-man stop may brake with where servodesk cannot raise it
        [counts/s²] (TravelGuard.stop_deceleration). The dead-man halts (controlword bit 8,
        605Dh) and then quick-stops (605Ah) the axis (services/motion/); CiA 402-2 §6.3.4:
        options 1 (and 5) brake on the profile deceleration 6084h, which each move sets to its
        own, 2 (and 6) on the quick-stop deceleration 6085h, which :meth:`_move` raises to the
        move's own where it is writable, 3, 4, 7, 8 at the current or voltage limit. Option 0
        lets the axis coast: the result's notes say that its run-out is not bounded."""
        options: dict[ObjectAddress, int] = {}
        for a in (QUICK_STOP_OPTION, HALT_OPTION):
            if await self._has(a):
                with contextlib.suppress(ServodeskError):
                    options[a] = int(await read_float(self.io, a))
        if options.get(QUICK_STOP_OPTION) == 0:
            self._notes.append(
                "the quick stop option (605Ah = 0) lets the axis coast: a dead-man stop's "
                "run-out is the machine's friction and is not bounded by the travel window"
            )
        # Without 605Ah a drive's quick stop is taken to brake on 6085h (CiA 402-2's default).
        qs = options.get(QUICK_STOP_OPTION, 2)
        on_qs_ramp = qs in (2, 6) or options.get(HALT_OPTION) == 2
        if not on_qs_ramp or self._qs_writable or not await self._has(QUICK_STOP_DEC):
            return None
        dec = await read_float(self.io, QUICK_STOP_DEC)
        self._notes.append(
            f"the quick-stop deceleration 6085h ({dec:.0f} counts/s²) is not writable: each "
            f"move's reserve includes the run-out of a stop on it"
        )
        return dec

    # ------------------------------------------------------------------ the travel bound

    def _set_travel_model(
        self, model: PlantModel, drive: _Drive, *, coulomb: float = 0.0, gravity: float = 0.0
    ) -> None:
        """The identified axis the moves' overshoot is foretold on (travel.py
        :func:`model_overshoots`), under the tuning's own torque limit; none where the
        simulation lacks the model's modes (a second resonance): then the measured run-on and
        the new gains' share of the distance alone."""
        moves = ModelMoves.of(
            model,
            drive.rate_hz,
            counts_per_rev=drive.counts_per_rev,
            torque_limit=drive.limit_torque,
            coulomb=coulomb,
            gravity=gravity,
        )
        self._travel_params = moves.params if moves is not None else None
        self.guard.predicted.clear()  # An older model's predictions.

    async def _predict(self, drive: _Drive, moves: list[PlannedMove], watch_s: float) -> None:
        """The model's overshoot for ``moves`` it has not foretold yet (in the design worker:
        the first run of the compiled tick loop takes seconds)."""
        params = self._travel_params
        todo = self.guard.needs_model(moves)
        if params is None or not todo:
            return
        job = functools.partial(
            model_overshoots,
            params,
            drive.rate_hz,
            drive.limit_torque,
            [(m.gains, m.distance, m.velocity, m.acc) for m in todo],
            watch_s,
        )
        self.guard.learn_model(todo, await self._compute(job))

    def _there_and_back(
        self, drive: _Drive, profile: tuple[float, float, float], gains: ServoGains
    ) -> list[PlannedMove]:
        """A move from :attr:`_Drive.home` up by the profile's distance and back, as written."""
        distance, velocity, acc = profile
        v, a = _as_written(drive, velocity, acc)
        home = float(drive.home)
        far = float(round(drive.home + distance))  # As _plan rounds the target.
        return [PlannedMove(home, far, v, a, gains), PlannedMove(far, home, v, a, gains)]

    async def _fits_there_and_back(
        self,
        drive: _Drive,
        profile: tuple[float, float, float],
        gains: ServoGains,
        watch_s: float,
    ) -> bool:
        moves = self._there_and_back(drive, profile, gains)
        if gains is not _FRESH:  # Nothing to simulate: the reserve is its share of the move.
            await self._predict(drive, moves, watch_s)
        return all(self.guard.fits(m) for m in moves)

    async def _fit_profile(
        self,
        drive: _Drive,
        size: Callable[[float], tuple[float, float]],
        distance: float,
        watch_s: float,
        what: str,
        gains: ServoGains | None = None,
        *,
        also_fresh: bool = False,
    ) -> tuple[float, float, float]:
        """(distance, velocity, acceleration): ``distance``, or shorter by :data:`SHRINK`
        steps until a move there and back from home with ``gains`` (the present ones), its
        velocity and acceleration ``size(distance)``, fits the bound with its reserve;
        ``also_fresh``: and with gains that have not moved the axis yet (the verification
        move, which the new gains run too). ``what`` names the moves in the note a shortening
        leaves."""
        wanted = distance
        velocity, acc = size(distance)
        sets = [gains or self._gains_now, *([_FRESH] if also_fresh else [])]
        for _ in range(SHRINK_STEPS):
            velocity, acc = size(distance)
            fits = [
                await self._fits_there_and_back(drive, (distance, velocity, acc), g, watch_s)
                for g in sets
            ]
            if all(fits):
                break
            distance *= SHRINK
        if distance < wanted:
            self._notes.append(
                f"{what} shortened from {wanted / drive.counts_per_rev:.3g} to "
                f"{distance / drive.counts_per_rev:.3g} rev: their overshoot must stay inside "
                f"the travel window"
            )
        return distance, velocity, acc

    def _model_foretold(self, last: int) -> bool:
        """Whether the model foretold the run-on of the ``last`` moves observed (the present
        gains' verification move there and back) within the reserve it gave them."""
        g = self.guard
        return all(g.foretold(move, past) for move, past in g.log[-last:])

    def _return_s(self, drive: _Drive, profile: tuple[float, float, float]) -> float:
        """The axis time of the way back to the start at the profile's speed [s]."""
        return _move_time(abs(drive.start_counts - drive.home), profile[1], profile[2])

    async def _return_to_start(self, drive: _Drive, velocity: float, acc: float) -> None:
        """From the rest position back to where the axis stood when the tuning began (in
        Operation enabled only; a move like any other, checked against the bound)."""
        if round(self._demand) == drive.start_counts:
            return
        if decode_state(await self._statusword()) is not State.OPERATION_ENABLED:
            return
        await self._run_moves(drive, [drive.start_counts], velocity, acc, 0.05, settle=True)

    async def _come_to_rest(self) -> None:
        """Halt the axis (controlword bit 8 with 605Dh's ramp: at the move's own deceleration;
        only in Operation enabled, where 0x010F cannot enable a drive, as services/motion/
        sends it) and wait until it stands, at most :data:`REST_WAIT_S`: after a stop, a
        dead-man (whose quick stop has the drive out of Operation enabled already) or a
        failure, before anything is put back."""
        if decode_state(await self._statusword()) is State.OPERATION_ENABLED:
            await self.io.write(CONTROLWORD, CW_ENABLE | CW_HALT)
        if not await self._has(VELOCITY):
            return
        still = 0.0
        began = self.io.now()
        while still < REST_STILL_S and self.io.now() - began < REST_WAIT_S:
            speed = abs(await read_float(self.io, VELOCITY))
            still = still + REST_POLL_S if speed <= self._rest_speed else 0.0
            await self.io.sleep(REST_POLL_S)

    # ------------------------------------------------------------------ motion

    def _plan(self, target: float, velocity: float, acc: float, drive: _Drive) -> PlannedMove:
        """The move to ``target`` from where the demand rests, as :meth:`_move` writes it."""
        v, a = _as_written(drive, velocity, acc)
        return PlannedMove(self._demand, round(target), float(v), float(a), self._gains_now)

    @property
    def guard(self) -> TravelGuard:
        assert self._guard is not None, "the travel bound is set by _learn"
        return self._guard

    async def _move(self, drive: _Drive, target: float, velocity: float, acc: float) -> PlannedMove:
        """An absolute profile-position move (CiA 402-2 §6.5: new set-point on the rising edge
        of bit 4, change immediately), checked against the travel bound first: its set-points,
        the overshoot past its target its gains may show and a stop's run-out
        (:class:`~servodesk.services.tuning.travel.TravelGuard`). The moves are planned to fit;
        one that does not after a move of its gains ran on further than foretold (the way
        back of a verification move or a try, whose way there showed it) is slowed, its
        velocity and acceleration by :data:`SHRINK` steps, until it fits: the run-on grows
        with the speed. Returns the move as sent."""
        planned = plan = self._plan(target, velocity, acc, drive)
        for _ in range(SHRINK_STEPS):
            if self.guard.fits(plan):
                break
            v, a = _as_written(drive, plan.velocity * SHRINK, plan.acc * SHRINK)
            plan = replace(plan, velocity=float(v), acc=float(a))
        plan = self.guard.require(plan)  # Refused where even the slowest would not fit.
        if plan.velocity < planned.velocity:
            self._notes.append(
                f"a move to {plan.target:.0f} slowed to {plan.velocity / planned.velocity:.2g} "
                f"x its speed: its gains had run on further than foretold"
            )
        if self._qs_writable and (self._qs_dec is None or plan.acc > self._qs_dec):
            # A dead-man stop then brakes no gentler than the move would have (605Ah option
            # 2: the quick-stop ramp; stop_overrun): 6085h at least the move's deceleration.
            await self.io.write(QUICK_STOP_DEC, round(plan.acc))
            self._qs_dec = plan.acc
        await self.io.write(PROFILE_VELOCITY, round(plan.velocity))
        await self.io.write(PROFILE_ACC, round(plan.acc))
        await self.io.write(PROFILE_DEC, round(plan.acc))
        await self.io.write(TARGET_POSITION, round(plan.target))
        await self.io.write(CONTROLWORD, CW_ENABLE | CW_IMMEDIATE)
        await self.io.write(CONTROLWORD, CW_ENABLE | CW_IMMEDIATE | CW_NEW_SETPOINT)
        await self.io.write(CONTROLWORD, CW_ENABLE | CW_IMMEDIATE)
        self._demand = plan.target
        self._moves.append(plan)
        return plan

    async def _wait_reached(self, timeout_s: float) -> bool:
        """Until the drive reports target reached (statusword bit 10), at most ``timeout_s``
        (an untuned axis may creep into its window for long: the metrics then say so)."""
        start = self.io.now()
        while not await self._statusword() & SW_TARGET_REACHED:
            if self.io.now() - start > timeout_s:
                return False
            await self.io.sleep(0.002)
        return True

    async def _run_moves(
        self,
        drive: _Drive,
        targets: list[float],
        velocity: float,
        acc: float,
        rest_s: float,
        *,
        settle: bool = False,
        extra: list[ObjectAddress] | None = None,
        origin: float | None = None,
    ) -> tuple[Recording, list[tuple[float, float]]]:
        """Moves one after the other, recorded (position, torque command) at the loop rate
        (or a divider that makes the recording fit). Returns the recording and each move's
        (start, end of its commanded profile) in recording time. ``settle``: each move waits
        for target reached (verification); otherwise the next starts ``rest_s`` after the
        profile's end, wherever the axis is (identification needs motion, not arrival).
        ``origin``: where the first move starts (default: where the demand rests); the
        moves' durations, and so the recording's length and the axis time, follow from it.
        Each move's recorded positions, until the next move starts, tell the travel guard how
        far its gains ran on past its target (TravelGuard.observe)."""
        first = self._demand if origin is None else origin
        distance = max(abs(b - a) for a, b in zip([first, *targets], targets, strict=False))
        duration = _move_time(distance, velocity, acc)
        # Room for the axis to arrive late (an untuned loop lags its profile).
        total = len(targets) * (duration + rest_s) + 0.02
        rec = DriveRecorder(self.io, drive.rate_hz)
        assert rec.spec is not None
        divider = max(1, math.ceil(total * drive.rate_hz / rec.spec.max_depth))
        torque = self._signal(SIG_TORQUE)
        await rec.configure([POSITION, torque, *(extra or [])], total, divider)
        await rec.start()
        t0 = self.io.now()
        spans: list[tuple[float, float]] = []
        sent = len(self._moves)
        for target in targets:
            start = self.io.now() - t0
            plan = await self._move(drive, target, velocity, acc)
            took = duration
            if plan.velocity < _as_written(drive, velocity, acc)[0]:
                # Slowed (_move): as long as it takes now.
                took = _move_time(abs(plan.distance), plan.velocity, plan.acc)
            spans.append((start, start + took))
            await self.io.sleep(took)
            if settle:
                await self._wait_reached(1.0)
            await self.io.sleep(rest_s)
            await self._check_healthy()
            self.axis_time_s += took
        recording = await rec.finish()
        self._account(drive, recording[POSITION], recording[torque])
        t = recording.t
        ends = [s for s, _e in spans[1:]] + [math.inf]
        for plan, (begin, _end), until in zip(self._moves[sent:], spans, ends, strict=True):
            self.guard.observe(plan, recording[POSITION][(t >= begin) & (t < until)])
        return recording, spans

    def _account(self, drive: _Drive, position: np.ndarray, torque: np.ndarray) -> None:
        if len(position):
            lo = (float(position.min()) - drive.start_counts) / drive.counts_per_rev
            hi = (float(position.max()) - drive.start_counts) / drive.counts_per_rev
            self.excursion = (min(self.excursion[0], lo), max(self.excursion[1], hi))
        if len(torque):
            self.peak_torque = max(self.peak_torque, float(np.max(np.abs(torque))))

    def _signal(self, sub: int) -> ObjectAddress:
        index = self.spec.signal_index
        if index is None:
            raise TuningFailed(
                f"{self.io.profile.name} has no test signal generator",
                hint="servodesk's tuning needs the drive to inject a test signal",
            )
        return ObjectAddress(index, sub)

    # ------------------------------------------------------------------ measurements

    async def _measure_frf(self, drive: _Drive) -> Frf:
        """The plant's frequency response: a PRBS torque from the drive's signal generator
        while the axis travels at a constant speed (a profile-position move across the
        window), so that Coulomb friction is a constant torque rather than stick-slip, which
        would make a small-signal response look stiffer than the machine (anchors-tuning.md
        §3.7: "use a velocity offset").

        The travel is centred on the start, downward (+-0.225 rev at 0.39 rev/s in the
        default 0.5 rev window; until the first session of 2026-12-07 it went 0.45 rev up from
        the start, in a window confirmed as +-0.25 rev). The way up to its start is the
        tuning's first move (:data:`FRF_HALF_SHARE`, :data:`FRF_PRE_RAMP_S`); what it runs on
        past its end (the factory gains' run-on, services/tuning/travel.py) sizes the travel,
        and the travel's own what follows. The way back ends at :attr:`_Drive.home`, where the
        identification moves start."""
        r_addr = self._signal(SIG_VALUE)
        t_addr = self._signal(SIG_TORQUE)
        guard = self.guard
        bound = drive.bound
        start = float(drive.start_counts)
        distance = float(
            math.floor(
                min(FRF_TRAVEL_REV * drive.counts_per_rev, 2.0 * FRF_HALF_SHARE * bound.half)
            )
        )
        velocity = min(distance / (CHIRP_S + 0.15), 0.95 * drive.max_velocity)
        acc = velocity / 0.02  # At speed within 20 ms, long before the recording starts.
        # Downward: where the axis comes back to afterwards, the rest below the start
        # (:attr:`_Drive.home`), is then a short way on. Upward, with the way back across the
        # window, the benchmark's settling was worse on every variant measured (seeds 1-4:
        # geometric mean 1.13 against 1.08 x the oracle, 95 against 99 rows within 2 x;
        # docs/tuning.md).
        high = start + round(distance / 2.0)
        low = high - round(distance)
        # The first move, up to where the travel starts: at the travel's speed with gentle
        # ramps, which leave a heavy load behind a soft shaft hardly swinging when the travel
        # starts (FRF_PRE_RAMP_S, FRF_REST_S; at twice the speed the benchmark's 400-800 Hz axes
        # came out worse); its reserve is what the half-window leaves past its end.
        self._slow = (velocity, velocity / FRF_PRE_RAMP_S)
        guard.fresh_reserve = bound.high - high
        try:
            await self._run_moves(drive, [high], *self._slow, FRF_REST_S, settle=True)
        finally:
            guard.fresh_reserve = None
        # The travel down: what the first move ran on past its end, at the same speed, with
        # the integral wound up against the friction over a cruise as long, sizes it (shortened
        # at its far end where it must be).
        for _ in range(SHRINK_STEPS):
            if guard.fits(self._plan(low, velocity, acc, drive)):
                break
            distance *= SHRINK
            velocity = min(distance / (CHIRP_S + 0.15), 0.95 * drive.max_velocity)
            acc = velocity / 0.02
            low = high - round(distance)
        seconds = CHIRP_S + 0.02
        rec = DriveRecorder(self.io, drive.rate_hz)
        assert rec.spec is not None
        # The position too where the recorder has a channel for it, through the travel's end.
        with_position = rec.spec.max_channels >= 4
        channels = [r_addr, t_addr, VELOCITY, *([POSITION] if with_position else [])]
        travel_s = _move_time(distance, velocity, acc)
        await rec.configure(
            channels, max(seconds, travel_s + FRF_TAIL_S) if with_position else seconds
        )
        await self.io.write(self._signal(SIG_KIND), SIG_PRBS)
        await self.io.write(self._signal(SIG_AMPLITUDE), CHIRP_SHARE * drive.limit_torque)
        await self.io.write(self._signal(SIG_F0), CHIRP_F0_HZ)
        await self.io.write(self._signal(SIG_F1), min(0.25 * drive.rate_hz, 4000.0))
        await self.io.write(self._signal(SIG_DURATION), CHIRP_S)
        await self._move(drive, low, velocity, acc)
        travel = self._moves[-1]
        await self.io.sleep(0.06)
        await rec.start()
        await self.io.write(self._signal(SIG_CONTROL), 1)
        try:
            await self.io.sleep(seconds)
        finally:
            await _quietly(self.io.write(self._signal(SIG_CONTROL), 0))
        whole = await rec.finish()
        await self._check_healthy()
        await self._wait_reached(1.0)
        # The travel ramps included (until the second session of 2026-11-27 counted without).
        self.axis_time_s += travel_s
        if with_position:
            self._account(drive, whole[POSITION], np.zeros(0))
            guard.observe(travel, whole[POSITION])
        else:
            self.excursion = (
                min(self.excursion[0], (low - start) / drive.counts_per_rev),
                max(self.excursion[1], (high - start) / drive.counts_per_rev),
            )
        # The response from the test signal's second only, as before the tail was recorded.
        n = min(whole.samples, round(seconds * whole.rate_hz))
        recording = Recording(whole.rate_hz, {a: x[:n] for a, x in whole.channels.items()})
        # Back up to the rest the identification moves start from, at twice the speed (since
        # the second session of 2026-11-27).
        drive.home = drive.start_counts - math.floor(drive.verify_distance / 2.0)
        await self._run_moves(drive, [drive.home], 2.0 * velocity, acc, 0.05, settle=True)
        rad = 2.0 * math.pi / drive.counts_per_rev
        velocity_rad = recording[VELOCITY] * rad
        self._account(drive, np.zeros(0), recording[t_addr])
        nperseg = 1 << max(8, round(math.log2(recording.rate_hz / 8.0)))
        self._frf_record = (recording.rate_hz, recording[r_addr], recording[t_addr], velocity_rad)
        return frequency_response(
            recording.rate_hz,
            recording[r_addr],
            recording[t_addr],
            velocity_rad,
            nperseg=min(nperseg, recording.samples),
            f_min_hz=CHIRP_F0_HZ,
        )

    def _travel_load(self, inertia: float) -> tuple[float, float]:
        """The frequency response's travel: its mean load torque [N m], friction and gravity
        (:func:`travel_load_torque`; ``inertia`` for its small inertial share), and its mean
        speed [rad/s]. ValueError without that record or where it is too short."""
        if self._frf_record is None:
            raise ValueError("no frequency response recorded")
        rate, _signal, torque, speed = self._frf_record
        return travel_load_torque(rate, torque, speed, inertia), float(np.mean(speed))

    def _moves_inertia(self, inertia: float) -> tuple[float, float] | None:
        """A compliant axis's inertia from the double integral of its identification moves
        (:func:`inertia_from_moves`) and how far the moves' own inertias spread
        (:attr:`MovesInertia.spread`), or None where that cannot be trusted. Only the moves in
        the frequency response's direction are taken: the mean torque of its constant-speed
        travel is their friction and gravity (:func:`travel_load_torque`, within 1 % on the
        benchmark's axes where the moves' fit was up to 25 % off), and the way back would need
        the gravity apart. ``inertia``: the estimate so far, for the travel's small inertial
        share. Taken when friction is a small share of every move's double integral and the
        moves agree (:data:`MOVES_INERTIAL_SHARE_MIN`, :data:`MOVES_SPREAD_MAX`); fitted with a
        viscous friction where that changes it (:data:`MOVES_VISCOUS_PART`)."""
        if self._moves_record is None:
            return None
        rate, torque, position, demand = self._moves_record
        try:
            load, speed = self._travel_load(inertia)
            way = 1.0 if speed >= 0.0 else -1.0
            spans = [(a, b) for a, b in demand_spans(demand) if (demand[b] - demand[a]) * way > 0]
            moves = inertia_from_moves(rate, torque, position, spans, load, load_speed=speed)
        except ValueError as exc:
            log.debug("no inertia from the moves' double integral: %s", exc)
            return None
        log.debug("inertia from the moves' double integral: %s", moves)
        if moves.inertial_share < MOVES_INERTIAL_SHARE_MIN or moves.spread > MOVES_SPREAD_MAX:
            return None
        j = moves.inertia
        if abs(moves.with_viscous / j - 1.0) > MOVES_VISCOUS_PART:
            j = moves.with_viscous
        return (j, moves.spread) if j > 0.0 else None

    def _moves_gravity(self, inertia: float) -> float | None:
        """A compliant axis's gravity torque [N m] from its identification moves back and
        forth (:func:`moves_gravity`), or None without their record or a move each way."""
        if self._moves_record is None:
            return None
        rate, torque, position, demand = self._moves_record
        try:
            g = moves_gravity(rate, torque, position, demand_spans(demand), inertia)
        except ValueError as exc:
            log.debug("no gravity from the moves: %s", exc)
            return None
        log.debug("gravity from the moves back and forth: %.5g N m", g)
        return g

    def _travel_friction(self, inertia: float, gravity: float) -> float | None:
        """The Coulomb friction [N m] from the frequency response's travel: its mean load
        torque (:func:`travel_load_torque`, friction and gravity at a slow constant speed)
        less the moves' ``gravity``; None without that record or where it gives none."""
        try:
            load, speed = self._travel_load(inertia)
        except ValueError as exc:
            log.debug("no friction from the travel: %s", exc)
            return None
        way = 1.0 if speed >= 0.0 else -1.0
        friction = way * (load - gravity)
        log.debug("friction from the travel: %.5g N m (load torque %.5g)", friction, load)
        return friction if friction > 0.0 else None

    async def _sharpen(self, resonances: list[Resonance]) -> tuple[list[Resonance], float | None]:
        """Each two-mass resonance refined from the whole record
        (:func:`resonance_from_record`): its damping and anti-resonance always (the Welch
        estimate smears a sharp mode wide, and puts a low anti-resonance where a few coarse
        bins fall: R30-100Hz's 18 Hz at 20-21 Hz, which split the inertia 45 % wrong), its
        frequency when the two estimates differ by more than 3 % (a noise bump moved the
        Welch peak). Also returns the total inertia of the lowest mode's fit (None without
        one)."""
        if self._frf_record is None:
            return resonances, None
        out = []
        total: float | None = None
        lowest = min(resonances, key=lambda r: r.freq_hz) if resonances else None
        for r in resonances:
            fit = await self._record_fit(r)
            if fit is None:
                out.append(r)
                continue
            fr = fit.freq_hz if abs(fit.freq_hz / r.freq_hz - 1.0) > 0.03 else r.freq_hz
            anti = fit.anti_freq_hz if fit.anti_freq_hz is not None else r.anti_freq_hz
            if anti is not None and anti >= fr:
                anti = r.anti_freq_hz
            out.append(replace(r, freq_hz=fr, anti_freq_hz=anti, damping_estimate=fit.damping))
            if r is lowest:
                total = fit.total_inertia
        return out, total

    async def _anti_below_band(
        self, resonances: list[Resonance], j_frf: float
    ) -> tuple[list[Resonance], RecordFit | None]:
        """The lowest resonance with its anti-resonance from the record fit when the response
        shows a peak without a dip and the test moves did not place one
        (:func:`with_hidden_anti_resonance`); (resonances, the fit when it placed one).

        A two-mass mode whose anti-resonance lies just below the band measured: a load 10 x the
        motor on a 60 Hz shaft has it at 18 Hz. The moves, sized for an anti-resonance at the band's
        edge (:func:`_lowest_anti`), fit 35 % of the inertia there, which puts the anti-resonance at
        33 Hz, inside the band, so the rule above does not apply. The record fit is started with the
        anti-resonance at the band's lower edge, and both it and the motor's inertia are free
        parameters of the fit: on that axis it returns 17.9-18.1 Hz and the total inertia within 6 %
        (docs/tuning.md). It is taken only when the fitted anti-resonance lies below the band or
        within a bin of its edge (:data:`BELOW_BAND_EDGE`; further inside, the dip would have shown)
        and the fitted motor inertia agrees with the response's (:data:`BELOW_BAND_MOTOR_TOL`):
        otherwise the peak is not such a mode."""
        if self._frf_record is None or not resonances:
            return resonances, None
        i = min(range(len(resonances)), key=lambda k: resonances[k].freq_hz)
        r = resonances[i]
        if r.anti_freq_hz is not None:
            return resonances, None
        fit = await self._record_fit(replace(r, anti_freq_hz=BAND_LOW_HZ))
        if (
            fit is None
            or fit.anti_freq_hz is None
            or fit.motor_inertia is None
            or not fit.anti_freq_hz < BELOW_BAND_EDGE * BAND_LOW_HZ
            or abs(fit.motor_inertia / j_frf - 1.0) > BELOW_BAND_MOTOR_TOL
        ):
            return resonances, None
        log.debug("anti-resonance below the band from the record fit: %s", fit)
        out = list(resonances)
        out[i] = replace(r, freq_hz=fit.freq_hz, anti_freq_hz=fit.anti_freq_hz)
        return out, fit

    async def _record_fit(self, resonance: Resonance) -> RecordFit | None:
        """:func:`resonance_from_record` on the frequency response's record, in the design's
        worker process when offloading: one fit is 20-40 ms of arithmetic, a tuning runs up to
        four, and the event loop carries the operator's heartbeats meanwhile."""
        assert self._frf_record is not None
        return await self._compute(
            functools.partial(resonance_from_record, *self._frf_record, resonance)
        )

    def _resonances(self, frf: Frf, inertia: float, drive: _Drive) -> list[Resonance]:
        """Resonances up to an eighth of the loop rate (plant files allow no higher), and
        below twice the current loop bandwidth: above that the measured response is the
        current loop's roll-off and quantisation, not the machine's."""
        top = drive.rate_hz / 8.0
        if drive.current_loop_hz:
            top = min(top, 2.0 * drive.current_loop_hz)
        return find_resonances(frf, inertia, min_freq_hz=BAND_LOW_HZ, max_freq_hz=top)

    def _inertia_from_frf(self, frf: Frf, drive: _Drive, band: tuple[float, float]) -> float:
        try:
            return inertia_from_frf(frf, band, current_loop_hz=drive.current_loop_hz)
        except ValueError as exc:
            raise TuningFailed(
                f"the frequency response gives no inertia: {exc}",
                hint="check that the axis is free to move and the torque limit is not tiny",
            ) from exc

    def _inertia_corrected(
        self, frf: Frf, drive: _Drive, resonances: list[Resonance], rough: float
    ) -> tuple[float, bool]:
        """The total inertia from the rigid-body band below the lowest anti-resonance, the
        two-mass shape divided out (identify.py); (estimate, True when the band was wide
        enough: at least 15 Hz above the lowest frequency measured)."""
        anti = [r.anti_freq_hz for r in resonances if r.anti_freq_hz]
        top = min(0.7 * min(anti), 400.0) if anti else min(400.0, 0.05 * drive.rate_hz)
        lo = BAND_LOW_HZ
        if top < lo + 15.0:
            return rough, False
        try:
            j = inertia_from_frf(
                frf, (lo, top), current_loop_hz=drive.current_loop_hz, resonances=resonances
            )
        except ValueError:
            return rough, False
        return j, True

    def _move_profile(
        self, drive: _Drive, inertia: float, resonances: list[Resonance], distance: float
    ) -> tuple[float, float]:
        """(velocity, acceleration) in counts/s and counts/s² for identification moves."""
        acc_rad = MOVE_TORQUE_SHARE * drive.limit_torque / inertia
        f_ar = _lowest_anti(resonances)
        if f_ar is not None:
            # Accelerate for MOVE_AR_PERIODS periods of the lowest anti-resonance or longer:
            # t_acc = sqrt(d / a) for a triangular move.
            d_rad = distance * 2.0 * math.pi / drive.counts_per_rev
            acc_rad = min(acc_rad, d_rad * (f_ar / MOVE_AR_PERIODS) ** 2)
        acc = acc_rad * drive.counts_per_rev / (2.0 * math.pi)
        # A cruise at constant speed between the ramps: Coulomb and viscous friction show
        # there, apart from the inertia (accelerating) and the standstill (stick) samples.
        velocity = min(0.6 * math.sqrt(acc * distance), 0.95 * drive.max_velocity)
        return velocity, acc

    async def _instrumented(self, resonances: list[Resonance]) -> bool:
        """Whether the test moves' fit is instrumented by the drive's position demand
        (:func:`identify_rigid`): on a rigid axis (no resonance in the frequency response)
        of a drive that records its following error 60F4h. On a compliant axis the moves'
        fit smooths over the shaft's oscillation, and its inertia is not the one taken."""
        return not resonances and await self._has(FOLLOWING_ERROR)

    async def _identify(
        self,
        drive: _Drive,
        j_frf: float,
        resonances: list[Resonance],
        fallback_inertia: float | None = None,
        *,
        instrumented: bool = False,
    ) -> tuple[InertiaEstimate, float]:
        """Inertia and friction from test moves, and the moves' cruise speed [rad/s].
        ``fallback_inertia``: the record fit's, taken when the moves' fit gives a negative
        inertia (their friction is still used). ``instrumented``: record the following error
        with the moves and instrument the fit with the position demand
        (:meth:`_instrumented`). A compliant axis's moves record it too, kept for their double
        integral (:meth:`_moves_inertia`), and rest :data:`COMPLIANT_MOVES_REST_S` apart."""
        wanted = distance = min(IDENT_REV * drive.counts_per_rev, IDENT_WINDOW_SHARE * drive.width)
        inertia = j_frf
        est: InertiaEstimate | None = None
        f_ar = _lowest_anti(resonances)
        window_s = max(0.0005, 4.0 / f_ar) if f_ar is not None else 0.0005
        # A compliant axis's moves record the demand too, for their double integral
        # (_moves_inertia), and rest until the load has stopped swinging.
        with_demand = instrumented or (bool(resonances) and await self._has(FOLLOWING_ERROR))
        rest_s = COMPLIANT_MOVES_REST_S if resonances else 0.01
        for _attempt in range(2):
            # Their overshoot inside the bound (the moves go home -> home + d and back; the
            # frequency response's moves told the factory gains' run-on).
            distance, velocity, acc = await self._fit_profile(
                drive,
                functools.partial(self._move_profile, drive, inertia, resonances),
                distance,
                VERIFY_SETTLE_S,
                "the identification moves",
            )
            if distance < MIN_IDENT_SHARE * wanted:
                # Moves that short, on an axis that overshoots that far, tell neither its
                # inertia nor a compliance below the band (the rigid-body check below): a load
                # 100 x the motor behind a 3 Hz anti-resonance passed it with moves of 0.028
                # rev, and its gains never settled on the real axis.
                raise TuningFailed(
                    f"the test moves would have to be shortened to "
                    f"{distance / drive.counts_per_rev:.3g} rev (from "
                    f"{wanted / drive.counts_per_rev:.3g}) to keep the axis's overshoot inside "
                    f"the travel window: too short to identify it",
                    hint="give a wider travel window, or tune this axis by hand, starting from "
                    "low gains",
                )
            rec, _spans = await self._run_moves(
                drive,
                [drive.home + distance, drive.home] * 3,
                velocity,
                acc,
                rest_s,
                extra=[FOLLOWING_ERROR] if with_demand else None,
            )
            rad = 2.0 * math.pi / drive.counts_per_rev
            # The recorded torque command is the one reaching the current loop on that tick
            # (the compute delay is behind it); the torque at the shaft is that through the
            # current loop, a first-order lag at its bandwidth.
            torque = rec[self._signal(SIG_TORQUE)]
            if drive.current_loop_hz:
                alpha = 1.0 - math.exp(-2.0 * math.pi * drive.current_loop_hz / rec.rate_hz)
                torque = lfilter([alpha], [1.0, alpha - 1.0], torque)
            position = rec[POSITION] * rad
            # 60F4h: the demand minus the position (CiA 402-2 §6.9.2); summed in counts, as
            # radians their sum would change by rounding at rest (demand_spans).
            demand = (rec[POSITION] + rec[FOLLOWING_ERROR]) * rad if with_demand else None
            if demand is not None and resonances:
                self._moves_record = (rec.rate_hz, torque, position, demand)
            try:
                # In the worker: its Savitzky-Golay filters over the moves' record take 40-90 ms.
                est = await self._compute(
                    functools.partial(
                        identify_rigid,
                        rec.rate_hz,
                        torque,
                        position_rad=position,
                        window_s=window_s,
                        instrument_rad=demand if instrumented else None,
                    )
                )
            except ValueError as exc:
                raise TuningFailed(f"the test moves give no inertia: {exc}") from exc
            log.debug("identification pass: sized for J=%.4g, got %s", inertia, est)
            if not est.inertia > 0.0:
                if fallback_inertia is None:
                    raise TuningFailed("the test moves give a negative inertia")
                # A load 6 x the motor on a 60 Hz shaft: the moves, sized for an anti-resonance
                # at the band's edge, accelerate so gently that their inertial torque (0.015
                # N m) is a sixth of the friction, and the fit gives -9.6e-5 kg m^2.
                log.debug("negative inertia from the moves; the record fit's %g", fallback_inertia)
                est = replace(est, inertia=fallback_inertia)
                break
            if 0.7 <= est.inertia / inertia <= 1.4:
                break
            # The moves were sized for another inertia: once more, unless the anti-resonance
            # rather than the inertia set their acceleration (the same moves again).
            resized = self._move_profile(drive, est.inertia, resonances, distance)[1]
            if abs(resized / acc - 1.0) < 0.05:
                break
            inertia = est.inertia
        assert est is not None
        spread = float(np.std(torque))
        if not resonances and spread > 0.0 and est.residual_rms > RIGID_RESIDUAL_MAX * spread:
            # No resonance in the frequency response, yet the moves are no rigid body: the
            # machine has a compliance below the band measured, and a design for what the
            # moves and the response show would be for the motor alone (a load 100 x the
            # motor behind a 3 Hz anti-resonance kept 5 deg of phase margin).
            raise TuningFailed(
                f"the test moves do not fit a rigid axis (the fit leaves "
                f"{100.0 * est.residual_rms / spread:.0f} % of the torque unexplained), and the "
                f"frequency response from {BAND_LOW_HZ:.0f} Hz shows no resonance: the axis "
                f"has a compliance too low to measure (a soft belt, a very heavy or hanging "
                f"load), and gains designed for what can be seen would not be safe",
                hint="tune this axis by hand, starting from low gains",
            )
        if window_s > FRICTION_WINDOW_S:
            with contextlib.suppress(ValueError):
                fr = await self._compute(
                    functools.partial(
                        identify_rigid,
                        rec.rate_hz,
                        torque,
                        position_rad=position,
                        window_s=FRICTION_WINDOW_S,
                    )
                )
                log.debug("friction with a %g s window: %s", FRICTION_WINDOW_S, fr)
                est = replace(est, viscous=fr.viscous, coulomb=fr.coulomb, gravity=fr.gravity)
        return est, velocity * rad

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

    async def _redesign(
        self,
        model: PlantModel,
        nominal: ModelMoves | None,
        records: list[RecordedMove],
        drive: _Drive,
        design_job: Callable[
            [PlantModel, ServoGains | None], tuple[Callable[[], SearchResult], bool]
        ],
        first: ServoGains,
        split_only: bool = False,
    ) -> Redesign | None:
        """The gain search again on ``model`` with the inertias the tries' ``records`` fit
        (services/tuning/calibrate.py) on ``nominal``, the simulation the search ranks ``model``
        with, where they clearly fit better than the model's: the output error at most
        :data:`CALIBRATE_ERROR_SHARE` of the model's and an inertia moved by at least
        :data:`CALIBRATE_MIN_CHANGE`, and where the new winner settles on that model in less
        than :data:`TRY_CLEAR_SHARE` of the time of ``first``, the pick so far, run there as the
        winner was. None otherwise. ``split_only``: the total inertia is trusted (the moves'
        double integral gave it) and only its split between motor and load is fitted
        (:func:`~servodesk.services.tuning.calibrate.fit_split`)."""
        if nominal is None or not records:
            return None
        # In the worker: some 80 replays of the recorded moves, 1.3 s of arithmetic on
        # R10-200Hz, which on the event loop held every session's traffic that long.
        fit = await self._compute(
            functools.partial(
                fit_split if split_only else fit_inertias, nominal.params, records, drive.rate_hz
            )
        )
        log.debug("the tries' records fit the inertias x %s", fit)
        moved = max(abs(fit.motor - 1.0), abs(fit.load - 1.0))
        refit: dict[str, Any] = {
            "motor_inertia_factor": fit.motor,
            "load_inertia_factor": fit.load,
            # Only the split was fitted: the moves' double integral gave the total.
            "total_held": split_only,
            "error_rms_counts_before": math.sqrt(fit.error_before),
            "error_rms_counts_after": math.sqrt(fit.error_after),
            "outcome": "fit_not_used",
            "searched_settling_s": None,
            "first_settling_s": None,
        }
        self._refit = refit
        if (
            moved < CALIBRATE_MIN_CHANGE
            or fit.error_after > CALIBRATE_ERROR_SHARE * fit.error_before
        ):
            return None
        fitted = replace(
            model,
            motor_inertia=model.motor_inertia * fit.motor,
            load_inertia=model.load_inertia * fit.load,
        )
        note = (
            f"the tries' recordings fit the motor inertia {100.0 * (fit.motor - 1.0):+.2g} % and "
            f"the load's {100.0 * (fit.load - 1.0):+.2g} % off the identification"
            f"{', the total held' if split_only else ''} (position error RMS "
            f"{math.sqrt(fit.error_before):.3g} -> {math.sqrt(fit.error_after):.3g} counts): "
            "gains searched again on that"
        )
        self.progress(0.86, "searching the gains again with the inertias the tries fit")
        job, _ = design_job(fitted, first)
        found = await self._search(job)
        held = found.incumbent_metrics
        refit["searched_settling_s"] = found.metrics.settling_10_s
        refit["first_settling_s"] = held.settling_10_s if held is not None else None
        if (
            found.gains != first
            and held is not None
            and found.metrics.settling_10_s >= TRY_CLEAR_SHARE * held.settling_10_s
        ):
            # Not clearly ahead on the fitted model either: the first pick stays, and the
            # runners-up are tried on the axis as where nothing was refitted (R30-100Hz seed 1:
            # 378 ms on the fitted model against the first pick's 388, on the axis 636 ms
            # against 388, docs/tuning.md).
            self._notes.append(
                f"{note}; they settle in {1e3 * found.metrics.settling_10_s:.3g} ms on it, the "
                f"first pick in {1e3 * held.settling_10_s:.3g} ms: not clearly ahead, the first "
                "kept"
            )
            refit["outcome"] = "first_kept"
            return None
        self._notes.append(note)
        refit["outcome"] = "searched_again"
        return Redesign(found, fitted)

    async def _try_alternatives(
        self,
        drive: _Drive,
        profile: tuple[float, float, float],
        design: SearchResult,
        step: dict[str, Any],
        model: PlantModel,
        *,
        trust_model: bool = True,
        redesign: Callable[[list[RecordedMove], ServoGains], Awaitable[Redesign | None]]
        | None = None,
    ) -> tuple[ServoGains, dict[str, Any], SearchResult, PlantModel]:
        """The model's winner and runners-up (:func:`~servodesk.domain.tuning.search.
        alternatives_of`) tried on the axis itself with a brisk move (the verification move's
        distance at :data:`RANK_TORQUE_SHARE` of the torque limit, like the reference move of
        search.py), there and back (:meth:`_try_key`: settling to +-10 counts of the error's
        5 ms mean, then the drive's following error RMS, each averaged over the two moves). The
        identified model is not the machine: its friction and damping decide between integral
        times and position gains that all meet the margins, and the axis settles that where it
        clearly can. ``trust_model``: a runner-up replaces the pick so far only where it settles
        in less than :data:`TRY_CLEAR_SHARE` of its time (a smaller lead is within what the two
        moves of one try disagree by); otherwise (the frequency response did not show the
        anti-resonance, and the model's moves are the least like the axis's) the better key
        wins, the following error breaking ties.

        ``redesign``: with the recordings of the winner's try, the search again on the model
        with the inertias they fit (:meth:`_redesign`). Where that runs, its winner is the pick
        and no runner-up is tried: the model then replays the axis's own move to 10-20 counts
        RMS, while on those axes (100-200 Hz, heavy loads) most tries do not settle within
        their watch and the rest rank against the noiseless settling at random (R1-200Hz seed
        5: tries of 0.03, 0.25 and 0.14 s for gains that settle in 22, 14 and 11 ms).
        Each try stays within the axis-time budget of a tuning. Returns the gains, their
        verification move, and the search result and model they came from (the gains' figures
        are that result's)."""
        # The winner's try also feeds the refit: it runs where the ranking offers no runner-up
        # too (R1-200Hz seed 7: none within 1.5 x the winner, so no try and no fit, and gains
        # that settle in 25.5 ms; fitted, 16.3 ms; the oracle 11.0 ms).
        if not design.alternatives and redesign is None:
            return design.gains, step, design, model
        distance, _velocity, acc = profile
        acc *= RANK_TORQUE_SHARE * 3.0  # The verification move accelerates at a third.

        def brisk_speed(d: float) -> tuple[float, float]:
            return min(0.8 * math.sqrt(acc * d), 0.95 * drive.max_velocity), acc

        # Each try's brisk move keeps its overshoot inside the bound: 1.5 x the model's, and a
        # share of the move where the gains have not moved the axis that fast
        # (travel.py); shortened where it must.
        brisk = await self._fit_profile(
            drive, brisk_speed, distance, watch_for(design), "the tries on the axis", design.gains
        )
        return await self._tries(drive, profile, brisk, design, step, model, trust_model, redesign)

    async def _tries(
        self,
        drive: _Drive,
        profile: tuple[float, float, float],
        brisk: tuple[float, float, float],
        design: SearchResult,
        step: dict[str, Any],
        model: PlantModel,
        trust_model: bool,
        redesign: Callable[[list[RecordedMove], ServoGains], Awaitable[Redesign | None]] | None,
    ) -> tuple[ServoGains, dict[str, Any], SearchResult, PlantModel]:
        """:meth:`_try_alternatives` with its brisk move fitted to the bound."""
        # Axis time of one try and of the verification move that follows a change (each is
        # there and back): the winner's try, one runner-up (where there is one), that move and
        # the way back to the start must fit to start.
        try_s = 2.0 * _move_time(*brisk)
        verify_s = 2.0 * _move_time(*profile) + self._return_s(drive, profile)
        tries = 2.0 if design.alternatives else 1.0
        if self.axis_time_s + tries * try_s + verify_s > AXIS_BUDGET_S:
            return design.gains, step, design, model
        if not await self._fits_there_and_back(drive, brisk, design.gains, watch_for(design)):
            self._notes.append(
                "no gains tried on the axis: the brisk move of a try may overshoot past the "
                "travel window"
            )
            return design.gains, step, design, model
        best = design.gains
        watch = watch_for(design)
        records: list[RecordedMove] = []
        best_key = await self._try_key(drive, brisk, watch, best, records)
        first = last = design.gains
        redone = await redesign(records, design.gains) if redesign is not None else None
        if redone is not None:
            design, model = redone.design, redone.model
            best = design.gains
        for i, g in enumerate(design.alternatives if redone is None else ()):
            if self.axis_time_s + try_s + verify_s > AXIS_BUDGET_S:
                break
            if not await self._fits_there_and_back(drive, brisk, g, watch):
                self._notes.append(
                    f"runner-up {i + 1} not tried on the axis: its brisk move may overshoot "
                    f"past the travel window"
                )
                continue
            # After a search again (0.86) the progress goes on from there.
            self.progress(min(0.87 + 0.03 * i, 0.97), f"trying runner-up {i + 1} on the axis")
            await self.write_gains(g)
            last = g
            key = await self._try_key(drive, brisk, watch)
            await self._check_healthy()
            log.debug("runner-up %d on the axis: %s (the pick: %s)", i + 1, key, best_key)
            # Trusting the model, a clear lead only: where no try settles within the watch
            # (inf) the axis cannot tell them apart and the model's order stands, and one that
            # settles beats one that does not.
            clear = key[0] < TRY_CLEAR_SHARE * best_key[0]
            better = clear if trust_model else key < best_key
            if better:
                verdict = "taken"
            elif trust_model:
                verdict = (
                    f"not clearly ahead (under {TRY_CLEAR_SHARE:g} x the pick's time), "
                    "the pick kept"
                )
            else:
                verdict = "the pick kept"
            self._notes.append(
                f"runner-up {i + 1} tried on the axis: {_settling_text(key[0], watch)}, the pick "
                f"so far {_settling_text(best_key[0], watch)} (each the faster of a move there "
                f"and back): {verdict}"
            )
            if better:
                best, best_key = g, key
        if last != best:
            await self.write_gains(best)
        if best != first:
            step = await self._verify_move(drive, profile)
            await self._check_healthy()
        return best, step, design.with_gains(best, drive.rate_hz, model), model

    async def _try_key(
        self,
        drive: _Drive,
        profile: tuple[float, float, float],
        watch: float = VERIFY_SETTLE_S,
        gains: ServoGains | None = None,
        records: list[RecordedMove] | None = None,
    ) -> tuple[float, float]:
        """How well the gains move the axis there and back: settling to +-10 counts of the
        error's 5 ms mean [s] (the plain figure is the end of the record on a noisy axis:
        :func:`smoothed_settling`; ``watch`` where a move does not settle within it, or only in
        its last :data:`TRY_SETTLED_HOLD_S`), the faster of the two moves (until the first
        session of 2026-12-04 their mean), then the drive's following error RMS [counts], the
        mean of the two moves. The way back used to be driven but not watched:
        watching it gives each try two samples of the torque noise at no extra motion. Which
        noise a try happened to see decides the pick (starting the tries a few milliseconds
        later changed 20 of the benchmark's 104 rows, docs/tuning.md).

        Not the settling to +-100 counts, which used to come between the two: where no try
        came within +-10 counts in the observation window (the slowest axes), it chose gains
        that approach sooner and then creep (R30-400Hz 2.5 -> 1.8 x the oracle on two of four
        seeds without it; docs/tuning.md).

        ``records``: each move as services/tuning/calibrate.py fits the model to it, where the
        recording shows it at the loop rate with the following error (``gains``: those the
        axis ran with)."""
        distance, velocity, acc = profile
        start = float(drive.home)
        keys = []
        for origin, target in ((start, start + distance), (start + distance, start)):
            # The way back waits for arrival too: the next try starts from rest.
            rec, span, fe_rms = await self._watched_move(
                drive, origin, target, velocity, acc, settle=target == start, watch=watch
            )
            settled = smoothed_settling(
                rec.t, target, rec[POSITION], span[1], hold_s=TRY_SETTLED_HOLD_S
            )
            # A move that did not settle within its watch took at least that long: counted
            # so (a censored time), the other move of the try still tells (TRY_SETTLED_HOLD_S).
            keys.append((min(settled, watch), math.inf if fe_rms is None else fe_rms))
            if (
                records is not None
                and gains is not None
                and fe_rms is not None
                and rec.rate_hz == drive.rate_hz
            ):
                written_v, written_acc = _as_written(drive, velocity, acc)
                m = recorded_move(
                    position=rec[POSITION],
                    following_error=rec[FOLLOWING_ERROR],
                    torque=rec[self._signal(SIG_TORQUE)],
                    rate_hz=drive.rate_hz,
                    origin=round(origin),
                    target=round(target),
                    velocity=float(written_v),
                    acc=float(written_acc),
                    gains=gains,
                    torque_limit=drive.limit_torque,
                )
                if m is not None:
                    records.append(m)
        a, b = keys
        # The faster move's settling, not the mean of the two: torque noise delays the
        # settling of the error's 5 ms mean (an excursion past the band after the move has
        # come in restarts it), it can hardly advance it, so the slower of two moves of the
        # same gains is the noisier figure (R1-200Hz seed 1: the model's pick 38 ms and not
        # within its 250 ms watch, 144 ms as a mean, lost to a runner-up's 28 / 31 ms that
        # settles 2.5 x slower without noise).
        return (min(a[0], b[0]), (a[1] + b[1]) / 2.0)

    async def _watched_move(
        self,
        drive: _Drive,
        origin: float,
        target: float,
        velocity: float,
        acc: float,
        *,
        settle: bool,
        watch: float = VERIFY_SETTLE_S,
    ) -> tuple[Recording, tuple[float, float], float | None]:
        """One move from ``origin`` to ``target`` [counts], watched for ``watch`` seconds
        (:data:`VERIFY_SETTLE_S` unless a try asks longer) after its profile (a try on the
        axis, the verification move): its recording (with the drive's following error 60F4h
        where it records one), its span and that following error's RMS over it [counts], None
        without 60F4h. ``settle``: wait for target reached (:meth:`_run_moves`)."""
        fe = [FOLLOWING_ERROR] if await self._has(FOLLOWING_ERROR) else []
        rec, spans = await self._run_moves(
            drive, [target], velocity, acc, watch, settle=settle, extra=fe, origin=origin
        )
        return rec, spans[0], _following_error_rms(rec, spans[0]) if fe else None

    def _verify_profile(
        self, drive: _Drive, inertia: float, distance: float | None = None
    ) -> tuple[float, float, float]:
        """(distance, velocity, acceleration) of the verification move, the same before and
        after: a quarter revolution (or half a smaller window, or ``distance``) at a third of
        the limit."""
        if distance is None:
            distance = drive.verify_distance
        acc = (drive.limit_torque / 3.0) / inertia * drive.counts_per_rev / (2.0 * math.pi)
        velocity = min(0.8 * math.sqrt(acc * distance), 0.95 * drive.max_velocity)
        return distance, velocity, acc

    async def _verify_move(
        self, drive: _Drive, profile: tuple[float, float, float]
    ) -> dict[str, Any]:
        distance, velocity, acc = profile
        start = float(drive.home)
        rec, span, fe_rms = await self._watched_move(
            drive, start, start + distance, velocity, acc, settle=False
        )
        # The way back counts its whole profile. Measured from the start it looked like no
        # move, and only its acceleration and braking (2 v / a) were counted: for this
        # profile 22 % short, the whole tuning's axis time 1-3 % (until 2026-11-27).
        back, _ = await self._run_moves(
            drive, [start], velocity, acc, 0.05, settle=True, origin=start + distance
        )
        del back
        pos = rec[POSITION]
        t = rec.t
        t_end = span[1]
        m = move_metrics(t, start + distance, pos, t_end)
        keep = max(1, len(t) // 800)  # The page draws about 800 points.
        return {
            "t_s": [round(float(x), 6) for x in t[::keep]],
            "position": [float(x - start) for x in pos[::keep]],
            "target": distance,
            "unit": "counts",
            "metrics": {
                # The page's figures (docs/tuning.md): settling to +-100 counts after the end
                # of the commanded profile, overshoot as a fraction of the move, the drive's
                # following error RMS during it [counts].
                "settling_s": m.settling_100_s,
                "overshoot": m.overshoot_counts / distance,
                "following_error_rms": fe_rms,
                "settling_10_s": m.settling_10_s,
                "settling_100_s": m.settling_100_s,
                "settling_10_smoothed_s": smoothed_settling(t, start + distance, pos, t_end),
                "overshoot_counts": m.overshoot_counts,
            },
        }

    # ------------------------------------------------------------------ the result

    def _travel_result(self, drive: _Drive) -> dict[str, Any]:
        """The bound and how far the axis went from the start, from the drive's recordings of
        every move (its position at the loop rate, or a divider of it on long records)."""
        g = self.guard
        b = drive.bound
        reach = max(-g.lowest, g.highest)
        return {
            **b.as_dict(drive.counts_per_rev),
            "lowest": round(b.start + g.lowest),
            "highest": round(b.start + g.highest),
            "max_excursion": round(reach),
            "max_excursion_rev": reach / drive.counts_per_rev,
            "software_limits": self._writable(SOFT_LIMIT_MIN) and self._writable(SOFT_LIMIT_MAX),
        }

    def _travel_notes(self, drive: _Drive) -> list[str]:
        g = self.guard
        cpr = drive.counts_per_rev
        reach = max(-g.lowest, g.highest)
        out = [
            f"the axis went at most {reach / cpr:.4g} rev ({reach:.0f} counts) from where it "
            f"stood, within ±{drive.bound.half / cpr:.4g} rev ({drive.bound.half} counts)"
        ]
        if g.surprises:
            worst = max(g.surprises, key=lambda s: s[1] - s[0])
            out.append(
                f"{len(g.surprises)} move(s) ran on past their target further than foretold "
                f"(worst {worst[1]:.0f} counts against {worst[0]:.0f}); what followed was "
                f"sized by what they showed"
            )
        return out

    def _result(
        self,
        drive: _Drive,
        before: ServoGains,
        design: Any,
        est: InertiaEstimate,
        frictions: tuple[float | None, float],
        cruise_rad_s: float,
        resonances: list[Resonance],
        model: PlantModel,
        frf: Frf,
        step_before: dict[str, Any],
        step_after: dict[str, Any],
    ) -> dict[str, Any]:
        """The job's result (docs/tuning.md ``TuningResult``). ``frictions``: the Coulomb
        friction the frequency response's slow travel measured (None where it gave none) and
        the one the ranking's model took. ``cruise_rad_s``: the test moves' cruise speed."""
        travel_friction, ranking_friction = frictions
        new: ServoGains = design.gains
        gains = []
        b, a = before.as_dict(), new.as_dict()
        for name, g in self.spec.gains.items():
            gains.append(
                {
                    "name": name,
                    "object": g.object,
                    "unit": g.unit,
                    "before": b[name],
                    "after": a[name],
                    "raw_before": b[name] / g.scale,
                    "raw_after": a[name] / g.scale,
                }
            )
        loop = LoopModel(model, drive.rate_hz, new)
        w = 2.0 * math.pi * frf.f_hz
        # The identified plant as the recorder measures it: the mechanics behind the drive's
        # current loop (2109h), the command held over each period and the velocity read at its
        # end (the twin's 606Ch is the plant's velocity after each step, not a differenced
        # encoder, so no loop delay). The mechanics alone were 15 dB above the generic twin's
        # measurement at its 2 kHz Nyquist frequency (docs/tuning.md, "Bode plot").
        g_model = model.sampled_velocity_response(w, drive.rate_hz)
        jm = model.motor_inertia
        return {
            "kind": "gains",
            "status": "done",
            "error": None,
            "mode": self.request.mode,
            "identified": {
                "inertia_kgm2": est.inertia,
                "inertia_ratio": (est.inertia - jm) / jm if model.resonance_hz else None,
                "coulomb_nm": est.coulomb,
                "viscous_nms": est.viscous,
                # What the moves measured: their friction at their cruise speed, c + b v. They
                # run at one speed, where the fit cannot tell c from b (it may trade them to a
                # negative b); the sum is what it measured.
                "moves_friction_nm": est.coulomb + est.viscous * cruise_rad_s,
                "moves_speed_rad_s": cruise_rad_s,
                "gravity_nm": est.gravity,
                # The Coulomb friction the frequency response's slow travel measured (the
                # moves' c and b come from one brisk speed); None where it gave none.
                "travel_friction_nm": travel_friction,
                # The one the ranking's model took: the travel's, or the moves' c + b v at
                # their cruise speed (c alone below a low anti-resonance).
                "ranking_friction_nm": ranking_friction,
                "resonances": [
                    {
                        "freq_hz": r.freq_hz,
                        "anti_freq_hz": r.anti_freq_hz,
                        "peak_db": r.peak_db,
                        # The damping the design used (plant_from_identification's rule).
                        "damping": model_damping(r.damping_estimate),
                    }
                    for r in resonances
                ],
                # The inertias the winner's try fitted and what came of it (:meth:`_redesign`):
                # None where no try was fitted (a rigid axis ranked on the instrumented inertia,
                # a response that did not show the anti-resonance, the basic and low levels, no
                # axis time left).
                "refit": self._refit,
            },
            "bode": {
                "freq_hz": _round(frf.f_hz),
                "measured_mag_db": _round(20.0 * np.log10(np.abs(frf.g))),
                "measured_phase_deg": _round(np.degrees(np.angle(frf.g))),
                "coherence": _round(frf.coherence),
                "model_mag_db": _round(20.0 * np.log10(np.abs(g_model))),
                "model_phase_deg": _round(np.degrees(np.angle(g_model))),
            },
            "margins": {
                "phase_margin_deg": design.margins.phase_margin_deg,
                "gain_margin_db": design.margins.gain_margin_db,
                "crossover_hz": design.margins.crossover_hz,
                "bandwidth_hz": design.bandwidth_hz,
            },
            "notes": [
                *design.notes,
                *self._notes,
                *self._travel_notes(drive),
                f"gains ranked for a 0.5 rev move accelerating at 70 % of "
                f"{100.0 * drive.move_torque / drive.rated_torque:.0f} % of the rated torque "
                + (
                    "(the machine's move torque given)"
                    if self.request.move_torque_pct is not None
                    else "(the tuning's torque limit: give the machine's move torque to tune "
                    "for its moves)"
                ),
            ],
            "gains": gains,
            "step": {"before": step_before, "after": step_after},
            "axis_time_s": self.axis_time_s,
            "excursion_rev": self.excursion[1] - self.excursion[0],
            "travel": self._travel_result(drive),
            "peak_torque_pct": 100.0 * self.peak_torque / drive.rated_torque,
            # From the drive's recordings of every test move, tick by tick: not polled.
            "peak_torque_polled_s": None,
            "loop_rate_hz": drive.rate_hz,
            "counts_per_rev": drive.counts_per_rev,
            "applied": True,
            "stored": False,
            "_loop": loop,
        }


#: A verification move that does not settle and overshoots this many times as far as the
#: one with the previous gains means the new gains are worse, whatever the model said ...
WORSE_OVERSHOOT = 1.25
#: ... when its overshoot matters at all (a share of the move): a slow axis that crept in
#: without overshoot before must not fail the tuning over a few counts past the target now.
WORSE_OVERSHOOT_MIN = 0.05


def refuse_if_worse(before: dict[str, Any], after: dict[str, Any]) -> None:
    """Raise :class:`TuningFailed` when the new gains moved the axis worse than the old ones:
    the verification move did not settle to +-100 counts where it did before, or it settled
    neither time and overshot :data:`WORSE_OVERSHOOT` times as far (and more than
    :data:`WORSE_OVERSHOOT_MIN` of the move). The model behind the
    gains was then not the machine (stress-soft60Hz: an anti-resonance at 11 Hz, below the
    frequency response's 20 Hz, left the tuner with the motor's inertia alone; its gains had
    6 deg of phase margin on the real axis and overshot 71 % of the move, the factory gains
    28 %)."""
    b, a = before["metrics"], after["metrics"]
    if math.isfinite(a["settling_100_s"]):
        return
    if math.isfinite(b["settling_100_s"]):
        raise TuningFailed(
            "the verification move did not settle to +-100 counts with the new gains (it did "
            f"with the previous ones in {1e3 * b['settling_100_s']:.0f} ms); "
            "the previous gains are back",
            hint="tune with a lower response level",
        )
    if a["overshoot"] > max(WORSE_OVERSHOOT * b["overshoot"], WORSE_OVERSHOOT_MIN):
        raise TuningFailed(
            "the new gains moved the axis worse than the previous ones: the verification move "
            f"overshot {100.0 * a['overshoot']:.0f} % of its distance, against "
            f"{100.0 * b['overshoot']:.0f} % before, and settled neither time; "
            "the previous gains are back",
            hint="the axis may have a resonance below 20 Hz that the frequency response "
            "cannot measure (a long belt, a soft coupling to a heavy load): tune it by hand, "
            "starting from low gains",
        )


def _lowest_anti(resonances: list[Resonance]) -> float | None:
    """The lowest anti-resonance [Hz], for sizing test moves; None on a rigid axis. When the
    lowest resonance has none, it lies below the band measured (a two-mass mode always has one
    below its peak), and the lowest frequency measured stands in for it."""
    if not resonances:
        return None
    if min(resonances, key=lambda r: r.freq_hz).anti_freq_hz is None:
        return BAND_LOW_HZ
    return min(r.anti_freq_hz for r in resonances if r.anti_freq_hz)


#: Gains no move has run and no model has foretold: what a move of gains not yet known needs
#: in reserve (TravelGuard.fresh_share; _fit_profile ``also_fresh``).
_FRESH = ServoGains(kp_pos=math.nan)


def watch_for(design: SearchResult) -> float:
    """How long a try on the axis is watched after its profile [s]. A slow axis is watched as
    long as the model watched its reference move (10 periods of the design's bandwidth,
    search.REF_HOLD_PERIODS), at least :data:`VERIFY_SETTLE_S`, up to :data:`TRY_WATCH_MAX_S`:
    the tries are judged by their settling, and a 10 Hz axis settles over hundreds of
    milliseconds (the oracle's gains on R30-100Hz: 195 ms). Watching is not motion: the axis
    time does not grow."""
    if design.bandwidth_hz > 0.0:
        return min(TRY_WATCH_MAX_S, max(VERIFY_SETTLE_S, REF_HOLD_PERIODS / design.bandwidth_hz))
    return VERIFY_SETTLE_S


def _settling_text(seconds: float, watch: float) -> str:
    """A try's settling (:meth:`OwnTuning._try_key`, the mean of its two moves) for the notes:
    a try whose moves did not settle counts as its watch."""
    if seconds >= watch:
        return f"not settled within its {1e3 * watch:.3g} ms watch"
    return f"settles in {1e3 * seconds:.3g} ms"


def _as_written(drive: _Drive, velocity: float, acc: float) -> tuple[int, int]:
    """The profile velocity (6081h) and acceleration (6083h, 6084h) a move writes, in whole
    counts per second and per second²: within the drive's 607Fh, and within UNSIGNED32 so
    that a wild estimate does not become a refused write."""
    v = min(velocity, drive.max_velocity, 0xFFFFFFFF)
    return max(1, round(v)), max(1, round(min(acc, 0xFFFFFFFF)))


def _move_time(distance: float, velocity: float, acc: float) -> float:
    """Duration of one trapezoidal profile move [s] (the drive's profile position, 6081h/6083h)."""
    cruise = max(0.0, distance / velocity - velocity / acc)
    return 2.0 * velocity / acc + cruise


def _following_error_rms(rec: Recording, span: tuple[float, float]) -> float | None:
    """The drive's own following error (60F4h) RMS over a move's commanded profile [counts];
    None when the recording holds no sample of it."""
    t = rec.t
    during = rec[FOLLOWING_ERROR][(t >= span[0]) & (t <= span[1])]
    return float(np.sqrt(np.mean(during**2))) if len(during) else None


def json_safe(x: Any) -> Any:
    """The result as JSON allows it: a figure that is not finite (a move that did not settle
    in the observation window, a following error without a demand) becomes null."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.floating):
        return json_safe(float(x))
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    return x


def _round(x: np.ndarray) -> list[float]:
    return [round(float(v), 4) if math.isfinite(float(v)) else 0.0 for v in x]


async def _quietly(aw: Any) -> None:
    """Best effort (restoring after a failure): a second error must not hide the first."""
    try:
        await aw
    except Exception as exc:
        log.warning("tuning: restoring failed: %s", exc)


async def run_own_tuning(
    session: Session, request: OwnTuningRequest, progress: Progress, client: str | None = None
) -> dict[str, Any]:
    """Tune the drive of ``session``; returns the TuningResult JSON (docs/tuning.md)."""
    result = await OwnTuning(SessionIO(session, client), request, progress).run()
    result.pop("_loop", None)
    return dict(json_safe(result))
