"""The simulated LECSN-T's built-in one-touch tuning (004 §20.8.7, objects §20.9.3.5(27)-(31)).

What the manual says (004 §20.8.7, Japanese text; translated):

- "For one-touch tuning, refer to section 6.2. Using One-touch tuning mode (P11600), one-touch
  tuning is possible from the master." (§6.2 is not in the source.)
- P11600 (2D50h, U8 R/W): "setting 1 to 3 starts one-touch tuning; when it completes, the
  setting changes to 0 automatically". 0 stopped, 1 basic mode, 2 high mode, 3 low mode.
- P11601 (2D51h): "regardless of whether one-touch tuning completed normally, the value
  changes to 100 % on completion" (unit %, range 00h-64h, §20.9.3.5(28)).
- P11602 (2D52h, W): "writing 1EA5h stops one-touch tuning; writing any value other than 1EA5h
  triggers error number 0x02 (low or high limit exceeded)".
- P11603 (2D53h, W): "the parameters changed by one-touch tuning can be returned to the values
  before the change. 0000h: return to the default values; 0001h: return to the values before
  one-touch tuning. The restored setting values are saved to EEP-ROM."
- P11604 (2D54h, R): 0000h normal end, C000h cancelled, C001h overshoot exceeded, C002h
  servo-off during tuning, C003h control mode error, C004h time-out, C005h load to motor
  inertia ratio misestimated (§20.9.3.5(31): inertia estimation failed), C00Fh disabled.
- Procedure §20.8.7(2): "rotate the servo motor from the master (one-touch tuning is not
  possible while the servo motor is not operating)"; while it is driven, write the response
  mode to P11600; "gains and filters are adjusted automatically"; check P11604; if the result
  is bad, return to the pre-tuning or initial values with P11603.

The manual does not say how the drive tunes, which parameters it sets (§6.2) or what the
conditions behind each error are. The twin's choices (a MELSERVO-style drive; "[U]" marks
general product knowledge of the MR-J4 family this drive is a rebadge of, unverified here):

- **Start (P11600 <- 1/2/3).** Accepted in any state; the checks run at once and a failed one
  ends the run immediately (status 100 %, mode back to 0): servo not on (CiA 402 state not
  Operation enabled) -> C002h; a control mode outside the quirk's ``modes`` -> C003h (the
  LECSN-T profile lists pp 1 and the vendor point-table / indexer modes -101 / -103; pp, ip 7
  and csp 8 are the default for a profile that lists none; MR-J4 also tunes in speed control
  [U], the twin does not, since the overshoot check needs a position command; the twin has no
  set-point generator for -101 / -103 yet, so a run there ends with C004h). Writing 1-3 while
  a run is in progress is refused (0800 0022h: device state; PROFIdrive 11h). Writing 0 is
  accepted and does nothing (0 is the read-back "stopped"; stopping is P11602's job).
- **Motion.** The drive watches its own position command (the set-point generator's demand
  velocity, as a real drive sees the master's command): a *move* starts when the demand
  velocity leaves 0 and ends when it is 0 again or reverses. A move counts when the encoder
  travelled at least ``counts_per_rev / 100`` during it (the axis really moved). Each counted
  move is one acceleration and one deceleration event. Like MR-J4's user-command method, which
  needs several reciprocating moves, the twin needs :data:`ESTIMATE_MOVES` moves (two
  back-and-forth cycles) to estimate, then :data:`VERIFY_MOVES` moves with the new gains.
  P11601 = 10 % per event during the estimation (80 % after four moves), 90 % after the first
  verification move, 100 % at the end.
- **Time-out (C004h).** No counted move within :data:`TIMEOUT_S` = 10 s of simulated time after
  the start or after the previous counted move (MR-J4: one operation cycle over 30 s [U]; the
  twin uses 10 s so that its tests stay short).
- **Estimation.** Recursive least squares (no forgetting) on the drive's own signals, once per
  1 ms control cycle while estimating: encoder position (velocity by differencing), and the
  torque it produces (the current-loop output it reports in 6077h). Model
  ``tau = J a + B w + C sign(w) + d`` (inertia, viscous, Coulomb, constant load such as
  gravity), all terms integrated over a sliding window of :data:`WINDOW` cycles so that the
  acceleration is a velocity difference (quantisation noise of a double difference would bias
  J low) and the torque its exactly matching trapezoidal average. Regressors are normalised
  to the rated torque, so ``theta[0] = J / J_M = 1 + ratio``. J_M is the motor's own inertia,
  which the drive knows from the motor it identifies through the encoder; the load is never
  read from the plant.
- **Inertia estimation failed (C005h)** when: the peak acceleration/deceleration torque
  ``J_est * a`` stayed under 10 % of the rated torque (MR-J4's condition for one-touch tuning
  [U]: too little acceleration to estimate); the ratio is below -0.2 or above
  :data:`MAX_RATIO` = 100 (MR-J4: one-touch tuning needs a ratio of 100 times or less [U]);
  or the estimate after the first back-and-forth cycle differs from the final one by more
  than :data:`CONSISTENCY` = 20 % (the load changed, or the model does not fit).
- **Gains** (MELSERVO parameters; chapter 5 of the manual, with their units and ranges, is not
  in the source, so the units are the twin's, labelled "simulation value" in the profile):
  PB06 load to motor inertia ratio [0.01 times]; PB07 model loop gain [0.1 rad/s]; PB08
  position loop gain [0.1 rad/s]; PB09 speed loop gain [rad/s]; PB10 speed integral
  compensation [0.1 ms]. The response mode picks a level of the MELSERVO auto-tuning response
  table (:data:`RESPONSE_HZ`, PA09 1-40, "guideline machine resonance frequency"; "anchors"
  below is the shared reference note anchors-tuning.md): the highest level whose velocity
  bandwidth ``w_v = 2 pi f`` keeps the phase margin of the mode (:data:`PHASE_MARGIN_DEG`:
  high 45°, basic 55°, low 65°) with the twin's own loop delay (half a control period of
  zero-order hold plus the current loop's time constant) and ``Ti = 4 / w_v`` (Yaskawa
  "stable gain"; anchors §0). A rigid twin has no resonance, so that delay is its only limit
  (high 121.7 Hz, basic 75.6 Hz, low 41.7 Hz at 1 kHz and 0.2 ms). Then
  ``PB09 = w_v (1 + ratio)`` (MR-J3: speed loop response = PB09 / ((1 + ratio) 2 pi), anchors
  §1.1), ``PB10 = 4 / w_v``, ``PB08 = w_v / 4`` (Delta: f_p < f_v / 4), ``PB07 = w_v / 10``
  (the factory ratio PB07/PB08 = 15/37 of MR-J4 [U]). High mode gives the higher loop gains
  and the shorter integral time.
- **Acting gains** (:func:`controller_gains_from_pb`, applied to the engine's
  :class:`~servodesk.sim.engine.ControllerGains` at power-on, after every write of PB06-PB10,
  after tuning and after P11603): velocity P gain ``J_M * PB09``, integral rate ``1 / PB10``,
  position gain PB08, inertia (acceleration) feed-forward ``J_M (1 + PB06)``. PB07 is stored
  but has no counterpart in the engine's cascade (it has no reference model; its velocity
  feed-forward is always 100 %). The factory values (MR-J4's [U]: PB06 7.00, PB07 15.0 rad/s,
  PB08 37.0 rad/s, PB09 823 rad/s, PB10 33.7 ms) therefore make the twin softer than a tuned
  one and over-estimate the inertia feed-forward of the twin's ratio-3 load.
- **Verification and overshoot (C001h).** After the estimation the new gains act at once (on
  the next control cycle) and the drive checks the next :data:`VERIFY_MOVES` moves: from the
  end of each commanded move until the next one starts (or :data:`SETTLE_S` later), the
  position past the command in the direction of travel is the overshoot; more than the
  in-position range PA10 (MR-J4: C001h when the overshoot exceeds PA10 [U]; 004 §20.5.3.2(3)
  names PA10 the in-position range) ends with C001h.
- **Every error and the stop** (C000h-C005h) return the parameters and gains to the values
  before the run. **Success** leaves the new PB values in RAM like any network write (004
  §20.8.14: lost at power-off unless stored with P4112); the manual promises EEP-ROM only for
  P11603. During the run the servo must stay on (C002h, also for a fault or quick stop) and
  the mode allowed (C003h).
- **Stop (P11602).** 1EA5h while running: C000h, status 100 %, mode 0. 1EA5h while idle:
  nothing changes. Any other value: refused with SDO abort 0609 0030h (value range of
  parameter exceeded; the CANopen-hosted twin's form of PROFIdrive error 02h "low or high
  limit exceeded", which §20.8.7 prints; the MR-J5 CoE object manual describes the same write
  as a "parameter out of range error", anchors §1.1). The printed range "0000h, 1EA5h"
  (§20.9.3.5(29)) is the read-back default, not an accepted command.
- **Clear (P11603).** 0000h: PB06-PB10 <- the profile defaults; 0001h: <- the values before the
  last successful run. Both act at once and are saved to EEP-ROM (the non-volatile copy that
  P4112 writes, so an NMT reset node keeps them). The pre-tuning values are kept in the
  drive's non-volatile memory, so undo works after a power cycle too; with no successful run
  since the twin was built, 0001h is refused with 0800 0022h. While tuning runs, both are
  refused with 0800 0022h.
- **Power cycle** (NMT reset node): a run in progress is lost; P11600/P11601/P11604 read 0 again
  (RAM objects, "EEP-ROM: not possible" in §20.9.3.5(27)-(31)); the gains follow the stored
  PB values.
- C00Fh (disabled) is never raised: the chapter does not say what disables one-touch tuning.

Cost: idle, one early return per control cycle; running, a 4x4 RLS update per cycle.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from servodesk.domain.cia402 import State
from servodesk.domain.datatypes import Value, coerce_int
from servodesk.domain.profile import DeviceProfile

if TYPE_CHECKING:
    from servodesk.sim.engine import ControllerGains, SimulatedDrive

# P11600 response modes (004 §20.9.3.5(27)).
STOPPED, BASIC, HIGH, LOW = 0, 1, 2, 3
# P11604 codes (004 §20.9.3.5(31)).
OK = 0x0000
CANCELED = 0xC000
OVERSHOOT = 0xC001
SERVO_OFF = 0xC002
MODE_ERROR = 0xC003
TIMEOUT = 0xC004
ESTIMATION_FAILED = 0xC005
#: P11602: the stop command (004 §20.9.3.5(29)).
STOP_VALUE = 0x1EA5
#: P11603 values (004 §20.9.3.5(30)).
CLEAR_DEFAULTS, CLEAR_BEFORE = 0, 1

#: CiA 301 abort codes the tuning answers with.
ABORT_RANGE = 0x06090030  # Value range of parameter exceeded (PROFIdrive error 02h).
ABORT_STATE = 0x08000022  # ... because of the present device state (PROFIdrive error 11h).

#: Moves (command accelerations and decelerations) needed for the estimation; 10 % per event.
ESTIMATE_MOVES = 4
#: Moves watched with the new gains for overshoot.
VERIFY_MOVES = 2
#: Seconds of simulated time without a counted move before C004h.
TIMEOUT_S = 10.0
#: Seconds after a verification move's command stops during which overshoot is watched.
SETTLE_S = 0.3
#: Control cycles over which acceleration and torque are integrated for the estimation.
WINDOW = 4
#: Largest load to motor inertia ratio one-touch tuning accepts.
MAX_RATIO = 100.0
#: Smallest ratio accepted (a slightly negative estimate is taken as 0).
MIN_RATIO = -0.2
#: Largest relative change of the estimate between half-way and the end.
CONSISTENCY = 0.2
#: Smallest peak acceleration torque, as a fraction of the rated torque.
MIN_ACCEL_TORQUE = 0.10

#: MELSERVO auto-tuning response levels 1-40 (PA09) and their "guideline machine resonance
#: frequency" [Hz]. Levels 1, 19, 39 and 40 are checked against the MR-J4 manual (anchors
#: §1.1: 2.7, 52.9, 571.5, 642.7 Hz); the others follow that table as commonly reproduced [U].
RESPONSE_HZ: tuple[float, ...] = (
    2.7, 3.6, 4.9, 6.6, 10.0, 11.3, 12.7, 14.3, 16.1, 18.1,
    20.4, 23.0, 25.9, 29.2, 32.9, 37.0, 41.7, 47.0, 52.9, 59.6,
    67.1, 75.6, 85.2, 95.9, 108.0, 121.7, 137.1, 154.4, 173.9, 195.9,
    220.6, 248.5, 279.9, 315.3, 355.1, 400.0, 446.6, 501.2, 571.5, 642.7,
)  # fmt: skip
#: Phase margin of the velocity loop each response mode keeps (high > basic > low response).
PHASE_MARGIN_DEG = {HIGH: 45.0, BASIC: 55.0, LOW: 65.0}

#: The parameters one-touch tuning sets, in quirk key order.
PARAMETERS = (
    "inertia_ratio",
    "model_loop_gain",
    "position_loop_gain",
    "speed_loop_gain",
    "speed_integral",
)

#: (abort code, detail) of a refused write.
Refusal = tuple[int, str]
Getter = Callable[[], Value | None]

_IDLE, _ESTIMATING, _VERIFYING = 0, 1, 2
#: Velocity that normalises the viscous regressor [rad/s] (3000 r/min).
_V_REF = 100.0 * math.pi


def _key(index: int, subindex: int) -> int:
    return index << 8 | subindex


def _address(text: Any) -> int:
    """``"0x2086:00"`` -> object key."""
    index, _, sub = str(text).partition(":")
    return _key(coerce_int(index), coerce_int(sub or "0"))


@dataclass(frozen=True, slots=True)
class PbGains:
    """The gain parameters as stored (raw units, see the module docstring)."""

    #: PB06 load to motor inertia ratio [0.01 times].
    inertia_ratio: int
    #: PB07 model loop gain [0.1 rad/s].
    model_loop_gain: int
    #: PB08 position loop gain [0.1 rad/s].
    position_loop_gain: int
    #: PB09 speed loop gain [rad/s].
    speed_loop_gain: int
    #: PB10 speed integral compensation [0.1 ms].
    speed_integral: int

    def as_tuple(self) -> tuple[int, int, int, int, int]:
        return (
            self.inertia_ratio,
            self.model_loop_gain,
            self.position_loop_gain,
            self.speed_loop_gain,
            self.speed_integral,
        )


def loop_delay(control_period: float, current_tau: float) -> float:
    """Effective delay of the twin's velocity loop [s]: zero-order hold over one control
    period (half of it) plus the current loop's first-order lag."""
    return 0.5 * control_period + current_tau


def response_level(mode: int, delay: float) -> int:
    """The highest response level (1-40) whose velocity bandwidth keeps the mode's phase
    margin with ``Ti = 4 / w_v`` and a pure delay ``delay``:
    ``90° - atan(1/4) - w_v * delay >= margin``."""
    margin = PHASE_MARGIN_DEG[mode]
    budget = math.radians(90.0 - margin) - math.atan(0.25)
    w_max = budget / delay if delay > 0.0 else math.inf
    level = 1
    for i, f in enumerate(RESPONSE_HZ, 1):
        if 2.0 * math.pi * f <= w_max:
            level = i
    return level


def design_gains(ratio: float, mode: int, delay: float) -> PbGains:
    """PB06-PB10 for an estimated load to motor inertia ratio and a response mode."""
    w = 2.0 * math.pi * RESPONSE_HZ[response_level(mode, delay) - 1]  # rad/s
    return PbGains(
        inertia_ratio=round(ratio / 0.01),
        model_loop_gain=max(10, round(w / 10.0 / 0.1)),
        position_loop_gain=max(10, round(w / 4.0 / 0.1)),
        speed_loop_gain=max(20, round(w * (1.0 + ratio))),
        speed_integral=max(1, round(4.0 / w / 1e-4)),
    )


def controller_gains_from_pb(
    pb: PbGains, motor_inertia: float, counts_per_rev: int
) -> ControllerGains:
    """The engine's cascade gains (drive units: counts, N m) for PB06-PB10.

    ``kp_vel = J_M * PB09`` (so the speed loop response is PB09 / (1 + true ratio)),
    ``ki_vel = 1 / PB10``, ``kp_pos = PB08``, ``acc_ff = J_M * (1 + PB06)``; PB07 does not act.
    """
    from servodesk.sim.engine import ControllerGains  # The engine imports this module.

    rad_per_count = 2.0 * math.pi / counts_per_rev
    ti = pb.speed_integral * 1e-4
    return ControllerGains(
        kp_pos=max(pb.position_loop_gain, 0) * 0.1,
        kp_vel=motor_inertia * max(pb.speed_loop_gain, 0) * rad_per_count,
        ki_vel=1.0 / ti if ti > 0.0 else 0.0,
        acc_ff=motor_inertia * (1.0 + max(pb.inertia_ratio, 0) * 0.01) * rad_per_count,
    )


class _Rls:
    """Recursive least squares without forgetting, ``y = phi . theta``, dimension 4."""

    __slots__ = ("p", "theta")

    def __init__(self, n: int = 4, p0: float = 1e4) -> None:
        self.theta = [0.0] * n
        self.p = [[p0 if i == j else 0.0 for j in range(n)] for i in range(n)]

    def update(self, phi: list[float], y: float) -> None:
        p = self.p
        n = len(phi)
        pphi = [sum(p[i][j] * phi[j] for j in range(n)) for i in range(n)]
        denom = 1.0 + sum(phi[i] * pphi[i] for i in range(n))
        gain = [x / denom for x in pphi]
        err = y - sum(phi[i] * self.theta[i] for i in range(n))
        for i in range(n):
            self.theta[i] += gain[i] * err
        for i in range(n):
            gi = gain[i]
            row = p[i]
            for j in range(n):
                row[j] -= gi * pphi[j]


class OneTouchTuning:
    """The one-touch tuning of one :class:`~servodesk.sim.engine.SimulatedDrive` (built by it
    when the profile has the quirk ``one_touch_tuning``). All methods run under the drive's
    lock. It reads the engine's set-point generator state (``_dp``, ``_dv``, ``_pos_offset``)
    and object store (``_values``, ``_defaults``, ``_nv``): it is part of the simulated drive,
    as sim/recorder.py is, and sets the drive's :attr:`~SimulatedDrive.gains`."""

    def __init__(self, drive: SimulatedDrive, profile: DeviceProfile) -> None:
        self.drive = drive
        q = profile.quirk("one_touch_tuning")
        cfg: dict[str, Any] = q if isinstance(q, dict) else {}
        self._mode_key = _address(cfg.get("mode", "0x2D50:00"))
        self._status_key = _address(cfg.get("status", "0x2D51:00"))
        self._stop_key = _address(cfg.get("stop", "0x2D52:00"))
        self._clear_key = _address(cfg.get("clear", "0x2D53:00"))
        self._error_key = _address(cfg.get("error", "0x2D54:00"))
        params = cfg.get("parameters")
        if not isinstance(params, dict) or any(p not in params for p in PARAMETERS):
            raise ValueError(f"quirk one_touch_tuning needs parameters: {', '.join(PARAMETERS)}")
        self._pb_keys = tuple(_address(params[p]) for p in PARAMETERS)
        limit = cfg.get("overshoot_limit")
        self._limit_key = _address(limit) if limit is not None else None
        self.modes = frozenset(coerce_int(m) for m in cfg.get("modes", (1, 7, 8)))
        self._owned = frozenset(
            k >> 8 for k in (self._mode_key, self._stop_key, self._clear_key, *self._pb_keys)
        )
        self._min_travel = drive.plant_params.counts_per_rev / 100.0
        self._delay = loop_delay(drive.CONTROL_PERIOD, drive.plant_params.current_tau)
        #: The values before the last successful run (non-volatile: kept across resets).
        self.undo_values: PbGains | None = None
        drive.on_cycle(self._on_cycle)
        self.reset()

    # ------------------------------------------------------------------ engine interface

    def owns(self, index: int) -> bool:
        """True for the objects whose writes the tuning checks or acts on."""
        return index in self._owned

    def live(self) -> dict[int, Getter]:
        """Getters of the objects the tuning reports (mode, status, error code) by key."""
        return {
            self._mode_key: lambda: self.mode,
            self._status_key: lambda: self.status,
            self._error_key: lambda: self.error,
        }

    def reset(self) -> None:
        """Power-on: nothing running, status and error 0, gains from the PB values."""
        self._phase = _IDLE
        self.mode = STOPPED
        self.status = 0
        self.error = OK
        #: The load to motor inertia ratio of the last estimation (None: none yet).
        self.estimate: float | None = None
        self._before: PbGains | None = None
        self._rls = _Rls()
        self._half: float | None = None
        self._peak_phi = 0.0
        self._moves = 0
        self._verified = 0
        self._t_event = 0.0
        self._p_prev = 0
        self._v: deque[float] = deque(maxlen=WINDOW + 1)
        self._tq: deque[float] = deque(maxlen=WINDOW + 1)
        self._move_dir = 0
        self._move_start = 0
        self._move_travel = 0
        #: (command end point, direction, watch until) of a verification move.
        self._watch: tuple[float, int, float] | None = None
        self._overshoot = 0.0
        self.apply_gains()

    @property
    def running(self) -> bool:
        return self._phase != _IDLE

    def write(self, index: int, subindex: int, value: Value) -> Refusal | None:
        """Check (and act on) a write; the drive then stores the value."""
        k = _key(index, subindex)
        if k in self._pb_keys:
            # PB06-PB10 act at once (the drive stores the value after this returns).
            self.apply_gains({k: coerce_int(value)})
            return None
        running = self._phase != _IDLE
        if k == self._mode_key:
            if value == STOPPED:
                return None
            if running:
                return (ABORT_STATE, "one-touch tuning runs: stop it with 1EA5h first")
            self._start(coerce_int(value))
            return None
        if k == self._stop_key:
            if value != STOP_VALUE:
                return (ABORT_RANGE, f"write 0x{STOP_VALUE:04X} to stop one-touch tuning")
            if running:
                self._finish(CANCELED)
            return None
        if k == self._clear_key:
            if running:
                return (ABORT_STATE, "one-touch tuning runs")
            if value == CLEAR_BEFORE:
                if self.undo_values is None:
                    return (ABORT_STATE, "no one-touch tuning result to undo")
                self._restore(self.undo_values, store=True)
            else:
                self._restore(self._defaults(), store=True)
            return None
        return None

    # ------------------------------------------------------------------ parameters

    def pb_values(self) -> PbGains | None:
        """PB06-PB10 as the drive holds them now (None while one has no value)."""
        values = self.drive._values
        raw = [values.get(k) for k in self._pb_keys]
        if not all(isinstance(v, int) for v in raw):
            return None
        return PbGains(*(int(v) for v in raw if isinstance(v, int)))

    def _defaults(self) -> PbGains | None:
        raw = [self.drive._defaults.get(k) for k in self._pb_keys]
        if not all(isinstance(v, int) for v in raw):
            return None
        return PbGains(*(int(v) for v in raw if isinstance(v, int)))

    def apply_gains(self, override: dict[int, int] | None = None) -> None:
        """Set the engine's gains from PB06-PB10 (with ``override`` values by key)."""
        values = self.drive._values
        raw = [(override or {}).get(k, values.get(k)) for k in self._pb_keys]
        if not all(isinstance(v, int) for v in raw):
            return  # No complete set: the engine keeps its own gains.
        pb = PbGains(*(int(v) for v in raw if isinstance(v, int)))
        p = self.drive.plant_params
        self.drive.gains = controller_gains_from_pb(pb, p.motor_inertia, p.counts_per_rev)

    def _set(self, pb: PbGains, *, store: bool) -> None:
        values = self.drive._values
        nv = self.drive._nv
        for k, v in zip(self._pb_keys, pb.as_tuple(), strict=True):
            values[k] = v
            if store:
                nv[k] = v  # "Saved to EEP-ROM" (004 §20.9.3.5(30)): kept by a reset node.
        self.apply_gains()

    def _restore(self, pb: PbGains | None, *, store: bool) -> None:
        if pb is not None:
            self._set(pb, store=store)

    # ------------------------------------------------------------------ the run

    def _start(self, mode: int) -> None:
        d = self.drive
        self.mode = mode
        self.status = 0
        self.error = OK
        self._before = self.pb_values()
        self._phase = _ESTIMATING
        if d.state is not State.OPERATION_ENABLED:
            self._finish(SERVO_OFF)
            return
        if d.mode not in self.modes:
            self._finish(MODE_ERROR)
            return
        self._rls = _Rls()
        self._half = None
        self._peak_phi = 0.0
        self._moves = 0
        self._verified = 0
        self._t_event = d.time
        p = d.plant.encoder_counts
        self._p_prev = p
        self._v.clear()
        self._tq.clear()
        self._move_dir = 0
        self._move_start = p
        self._move_travel = 0
        self._watch = None
        self._overshoot = 0.0

    def _finish(self, code: int) -> None:
        if code != OK and self._phase == _VERIFYING:
            self._restore(self._before, store=False)  # Back to the values before the run.
        if code == OK:
            self.undo_values = self._before
        self._phase = _IDLE
        self.mode = STOPPED
        self.drive._values[self._mode_key] = STOPPED  # "Changes to 0 automatically."
        self.status = 100
        self.error = code

    def _on_cycle(self) -> None:
        if self._phase == _IDLE:
            return
        d = self.drive
        if d.state is not State.OPERATION_ENABLED:
            self._finish(SERVO_OFF)
            return
        if d.mode not in self.modes:
            self._finish(MODE_ERROR)
            return
        # The drive's own measurements after this control cycle.
        p = d.plant.encoder_counts
        v = (p - self._p_prev) / d.CONTROL_PERIOD
        self._p_prev = p
        self._v.append(v)
        self._tq.append(d.plant.torque)
        if self._phase == _ESTIMATING and len(self._v) > WINDOW:
            self._sample()
        self._track_moves(p)
        if self._phase != _IDLE and d.time - self._t_event > TIMEOUT_S + 1e-9:
            self._finish(TIMEOUT)

    def _sample(self) -> None:
        """One RLS update over the last WINDOW cycles (module docstring, "Estimation")."""
        d = self.drive
        pp = d.plant_params
        v, tq = self._v, self._tq
        if not any(v):
            return  # At rest: static friction, nothing to learn.
        scale = 1.0 / d.plant.counts_per_rad  # counts -> rad
        rated = pp.rated_torque
        n = WINDOW
        t_win = n * d.CONTROL_PERIOD
        # Trapezoidal averages over the window (velocity differences integrate the torque of
        # the cycles between them: half of the two end cycles, all of the ones inside).
        tau = (0.5 * (tq[0] + tq[n]) + sum(tq[i] for i in range(1, n))) / n
        w = (0.5 * (v[0] + v[n]) + sum(v[i] for i in range(1, n))) / n * scale
        sg = (0.5 * (_sign(v[0]) + _sign(v[n])) + sum(_sign(v[i]) for i in range(1, n))) / n
        acc = (v[n] - v[0]) / t_win * scale
        phi_j = pp.motor_inertia * acc / rated
        self._rls.update([phi_j, w / _V_REF, sg, 1.0], tau / rated)
        self._peak_phi = max(self._peak_phi, abs(phi_j))

    def _track_moves(self, p: int) -> None:
        """Moves of the drive's position command (module docstring, "Motion")."""
        d = self.drive
        dv = d._dv
        move = self._move_dir
        ended = move != 0 and (dv == 0.0 or (dv > 0.0) != (move > 0))
        started = dv != 0.0 and (move == 0 or ended)
        if move:
            self._move_travel = max(self._move_travel, abs(p - self._move_start))
        watch = self._watch
        if watch is not None:
            target, direction, until = watch
            self._overshoot = max(self._overshoot, direction * (p + d._pos_offset - target))
            if started or d.time >= until - 1e-9:
                self._watch = None
                self._verified += 1
                if self._end_verification():
                    return
        if ended:
            self._move_dir = 0
            if self._move_travel >= self._min_travel:
                self._t_event = d.time
                self._moved(move)
                if self._phase == _IDLE:
                    return
        if started:
            self._move_dir = 1 if dv > 0.0 else -1
            self._move_start = p
            self._move_travel = 0

    def _moved(self, direction: int) -> None:
        """A counted move (its acceleration and deceleration) has ended."""
        if self._phase == _ESTIMATING:
            self._moves += 1
            self.status = min(80, 20 * self._moves)
            if self._moves == ESTIMATE_MOVES // 2:
                self._half = self._rls.theta[0]
            if self._moves >= ESTIMATE_MOVES:
                self._estimated()
        elif self._phase == _VERIFYING and self._watch is None:
            # Watch the overshoot past this move's command end point.
            self._overshoot = 0.0
            self._watch = (self.drive._dp, direction, self.drive.time + SETTLE_S)

    def _estimated(self) -> None:
        """The estimation moves are done: check the estimate, set the gains, verify."""
        theta = self._rls.theta[0]
        ratio = theta - 1.0
        half = self._half
        if (
            not math.isfinite(theta)
            or theta * self._peak_phi < MIN_ACCEL_TORQUE
            or not MIN_RATIO <= ratio <= MAX_RATIO
            or half is None
            or abs(half - theta) > CONSISTENCY * abs(theta)
        ):
            self._finish(ESTIMATION_FAILED)
            return
        self.estimate = max(ratio, 0.0)
        self._set(design_gains(self.estimate, self.mode, self._delay), store=False)
        self._phase = _VERIFYING

    def _end_verification(self) -> bool:
        """A verification move has settled; True when the run ended."""
        limit = self._overshoot_limit()
        if limit is not None and self._overshoot > limit:
            self._finish(OVERSHOOT)
            return True
        self.status = min(99, 80 + 10 * self._verified)
        if self._verified >= VERIFY_MOVES:
            self._finish(OK)
            return True
        return False

    def _overshoot_limit(self) -> float | None:
        if self._limit_key is None:
            return None
        v = self.drive._values.get(self._limit_key)
        return float(v) if isinstance(v, int) else None


def _sign(x: float) -> float:
    return 1.0 if x > 0.0 else -1.0 if x < 0.0 else 0.0
