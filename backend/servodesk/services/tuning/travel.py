"""The travel bound of servodesk's own tuning: every move is planned, checked and measured
against it (docs/tuning.md, "Travel window").

The user confirms a window W; the axis stays within ``start +- floor(W / 2)`` position units
(domain/tuning/travel.py). What a profile-position move may reach is more than its
set-points:

- the loop's overshoot past the target, which the integral's wind-up against friction or the
  torque limit lengthens, and which a soft axis's swinging load makes many times what a rigid
  one shows: up to 35 % of the move on the motor with gains designed for a model that was not
  the machine (bench/plants: a load 6 x the motor on a 60 Hz shaft, the first brisk try of the
  design's gains);
- a stop's run-out: the dead-man halts (605Dh) and then quick-stops (605Ah) the axis, and a
  stop ramp gentler than the move's own braking runs past the target
  (:func:`~servodesk.domain.tuning.travel.stop_overrun`; the generic profile's 6085h of 38
  rev/s² against identification moves braking at up to 1700 rev/s²: 1.6 rev from 11 rev/s).
  The tuning raises the quick-stop deceleration 6085h to each move's own where it can, so that
  term is zero there.

:class:`TravelGuard` keeps what is known about the first: the largest run-on time each gain
set showed (the overshoot past the target over the move's peak speed: the distance the axis
ran on at that speed, which for a given loop grows with the speed, not with the distance), and
what the identified model predicts for a planned move (:func:`model_overshoots`, the drive's
set-point generator and loop on the model: the integral and the torque limit included). A
move's reserve past its target is :data:`RESERVE_FACTOR` times the larger of the two, and at
least :data:`NEW_GAINS_SHARE` of its distance where its gains have not yet run a move that
fast: the model's prediction was 1.7-6.8 x short for the first brisk try of new gains on the
soft axes of bench/plants (docs/tuning.md). A move whose envelope, set-points plus reserve,
leaves the bound is not sent (:meth:`TravelGuard.require`); the procedure sizes its moves so
that they fit (services/tuning/own).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.travel import TravelBound, stop_overrun
from servodesk.errors import ServodeskError
from servodesk.model.plant import PlantParams
from servodesk.model.profile_position import pp_duration_s
from servodesk.model.replay import RecordedMove, run_recorded_move

#: A move's reserve past its target: this many times the larger of its gains' measured run-on
#: at its speed and the model's prediction. On R30-100Hz the factory gains' run-on at the
#: frequency response's 0.39 rev/s foretold their identification moves' overshoot at 1.3 rev/s
#: within 1.25 x (0.0185 for 0.023 rev), and more than their verification move's at 4 rev/s;
#: the identified model foretold the new gains' verification moves within 1.2 x where the
#: frequency response showed the anti-resonance (R30-100Hz, stress-soft60Hz, soft-30x-40hz),
#: and their brisk tries on R1-100Hz 1.7 x short, which NEW_GAINS_SHARE covers.
RESERVE_FACTOR = 1.5
#: The least reserve past the target of a move whose gains have not yet run one as fast [share
#: of its distance]: the largest overshoot measured on the motor in such a move over the
#: benchmark's 26 plants and bench/plants was 35 % (the design's gains on a load 6 x the motor
#: behind a 60 Hz shaft, whose anti-resonance the frequency response did not show, in their
#: first brisk try; the model foretold 5 %).
NEW_GAINS_SHARE = 0.45
#: The same where the model is not the machine (services/tuning/own ``_model_foretold``):
#: the frequency response did not show the anti-resonance, the simulation lacks a mode of the
#: model, or the present gains' verification move ran on past what the model foretold. There
#: the design's gains ran on 50 % of the verification move (a load 10 x the motor behind a
#: 60 Hz shaft, with two resonances identified), and this is RESERVE_FACTOR x that. The
#: verification move and the tries are shortened to keep it (at a 0.5 rev window, to 0.154 of
#: 0.25 rev).
UNSEEN_SHARE = 0.75
#: A verification move of the present gains that ran on further than the model's reserve by
#: more than this share of its distance says the model is not the machine (UNSEEN_SHARE): on
#: soft-8x-60hz-d0.01 13 % against the model's 1.5 %; a model that was the machine ran on
#: within its reserve or a few hundredths of the move past it (noise, friction's stick).
DISTRUST_SHARE = 0.05
#: And at least this share of the half-window, whatever was measured: below it the run-on is
#: the torque noise's scatter from one move to the next (R1-rigid's verification move ran on
#: 411 counts one way and 832 the other; 1 % of a 0.5 rev window's half is 2621 counts at
#: 2^20 counts per revolution).
MIN_RESERVE_SHARE = 0.01


class TravelExceeded(ServodeskError):
    """A planned move would leave the travel bound the user confirmed."""


@dataclass(frozen=True, slots=True)
class PlannedMove:
    """A profile-position move as the tuning writes it: from where the demand rests to the
    target [position units], at the profile velocity and acceleration (= deceleration) as
    written [units/s, units/s²], under ``gains``."""

    origin: float
    target: float
    velocity: float
    acc: float
    gains: ServoGains
    #: The reserve past the target it was sent with (TravelGuard.require) [units].
    reserve: float = 0.0

    @property
    def distance(self) -> float:
        return self.target - self.origin

    @property
    def peak_speed(self) -> float:
        """The profile's top speed: the velocity, or less where a triangle cannot reach it."""
        d = abs(self.distance)
        if self.velocity <= 0.0 or self.acc <= 0.0:
            return 0.0
        return min(self.velocity, math.sqrt(self.acc * d))

    def key(self) -> tuple[ServoGains, int, int, int]:
        return (self.gains, round(self.distance), round(self.velocity), round(self.acc))


@dataclass
class TravelGuard:
    """What the tuning knows about how far its moves reach, against ``bound``."""

    bound: TravelBound
    #: The gentlest stop ramp that may act on a dead-man stop [units/s²] where servodesk
    #: cannot raise it (6085h read-only under quick-stop option 2); None: every stop brakes at
    #: least as hard as the move (6084h, the torque limit, or 6085h raised per move).
    stop_deceleration: float | None = None
    #: The largest run-on time measured per gain set [s], and the fastest peak speed each ran.
    run_on: dict[ServoGains, float] = field(default_factory=dict)
    fastest: dict[ServoGains, float] = field(default_factory=dict)
    #: The model's predicted overshoot past the target per planned move (PlannedMove.key).
    predicted: dict[tuple[ServoGains, int, int, int], float] = field(default_factory=dict)
    #: Measured extremes of the position relative to the start [units].
    lowest: float = 0.0
    highest: float = 0.0
    #: Moves that overshot past their reserve (the reserve, what was measured) [units]: the
    #: run-on learnt from them sizes what follows.
    surprises: list[tuple[float, float]] = field(default_factory=list)
    #: The least reserve of a move faster than its gains have run, as a share of its distance.
    fresh_share: float = NEW_GAINS_SHARE
    #: Instead, this reserve [units] (the tuning's first move: what the window leaves).
    fresh_reserve: float | None = None
    #: Every move observed and how far it ran on past its target [units].
    log: list[tuple[PlannedMove, float]] = field(default_factory=list)

    def reserve(self, move: PlannedMove) -> float:
        """How far past its target ``move`` may run [units] (module docstring)."""
        v = move.peak_speed
        measured = self.run_on.get(move.gains, 0.0) * v
        model = self.predicted.get(move.key(), 0.0)
        r = max(RESERVE_FACTOR * max(measured, model), MIN_RESERVE_SHARE * self.bound.half)
        if self.fastest.get(move.gains, 0.0) < v * (1.0 - 1e-9):
            fresh = self.fresh_reserve
            r = max(r, self.fresh_share * abs(move.distance) if fresh is None else fresh)
        return r + stop_overrun(v, move.acc, self.stop_deceleration)

    def envelope(self, move: PlannedMove) -> tuple[float, float]:
        """The lowest and highest position ``move`` may reach [units]."""
        r = self.reserve(move)
        lo = min(move.origin, move.target)
        hi = max(move.origin, move.target)
        if move.target > move.origin:
            hi += r
        elif move.target < move.origin:
            lo -= r
        return lo, hi

    def fits(self, move: PlannedMove) -> bool:
        lo, hi = self.envelope(move)
        return self.bound.contains(lo, hi)

    def require(self, move: PlannedMove) -> PlannedMove:
        """``move`` with the reserve it is sent with; :class:`TravelExceeded` where it may
        leave the bound."""
        lo, hi = self.envelope(move)
        if not self.bound.contains(lo, hi):
            b = self.bound
            raise TravelExceeded(
                f"a move to {move.target:.0f} may reach {lo:.0f} .. {hi:.0f} with its "
                f"overshoot and a stop's run-out, outside the travel window {b.low} .. {b.high} "
                f"(±{b.half} of {b.start}); nothing was sent",
                hint="give a wider travel window, or tune with a lower response level",
            )
        return replace(move, reserve=self.reserve(move))

    def observe(self, move: PlannedMove, position: np.ndarray) -> None:
        """What ``move`` did, from the recorder's positions over it and until the next move
        [units]: the extremes relative to the start, and the run-on of its gains."""
        if not len(position):
            return
        start = self.bound.start
        self.lowest = min(self.lowest, float(position.min()) - start)
        self.highest = max(self.highest, float(position.max()) - start)
        d = move.distance
        v = move.peak_speed
        if d == 0.0 or v <= 0.0:
            return
        past = float(np.max((position - move.target) * math.copysign(1.0, d)))
        past = max(past, 0.0)
        self.log.append((move, past))
        if past > move.reserve:
            self.surprises.append((move.reserve, past))
        self.run_on[move.gains] = max(self.run_on.get(move.gains, 0.0), past / v)
        self.fastest[move.gains] = max(self.fastest.get(move.gains, 0.0), v)

    def foretold(self, move: PlannedMove, past: float) -> bool:
        """Whether the model foretold ``move``'s run-on ``past``: within the reserve it would
        give it and :data:`DISTRUST_SHARE` of the move (False where it foretold nothing)."""
        model = self.predicted.get(move.key())
        if model is None:
            return False
        reserve = max(RESERVE_FACTOR * model, MIN_RESERVE_SHARE * self.bound.half)
        return past <= reserve + DISTRUST_SHARE * abs(move.distance)

    def needs_model(self, moves: Sequence[PlannedMove]) -> list[PlannedMove]:
        """The moves the model has not yet predicted."""
        return [m for m in moves if m.key() not in self.predicted and m.distance != 0.0]

    def learn_model(self, moves: Sequence[PlannedMove], overshoots: Sequence[float]) -> None:
        for m, o in zip(moves, overshoots, strict=True):
            self.predicted[m.key()] = o


def model_overshoots(
    params: PlantParams,
    rate_hz: float,
    torque_limit: float,
    moves: Sequence[tuple[ServoGains, float, float, float]],
    watch_s: float,
) -> list[float]:
    """How far each move (gains, distance, velocity, acceleration as written) runs past its
    target on the simulated axis ``params`` [units]: the drive's set-point generator and loop
    from rest (the loop's integral holding the axis's constant torque), watched ``watch_s``
    after its profile (model/replay.py :func:`run_recorded_move`, 0.2-0.4 ms each). A move the
    loop does not keep finite gives infinity. Picklable, for the design worker."""
    out: list[float] = []
    for gains, distance, velocity, acc in moves:
        n = max(2, round((pp_duration_s(distance, velocity, acc) + watch_s) * rate_hz))
        move = RecordedMove(
            gains=gains,
            distance=distance,
            velocity=velocity,
            acc=acc,
            offset=0.0,
            hold_torque=params.gravity,
            torque_limit=torque_limit,
            position=np.zeros(n),
        )
        pos = run_recorded_move(params, move, rate_hz)
        if not np.isfinite(pos).all():
            out.append(math.inf)
            continue
        out.append(max(0.0, float(np.max((pos - distance) * math.copysign(1.0, distance)))))
    return out
