"""A move on a simulated axis, tick by tick: the drive's cascade (servo.py) on the plant
(plant.py), as the simulated drive runs them.

Three users:

- the tuning benchmark measures tuned and oracle gains with it on the true plant
  (benchmarks/tuning.py);
- servodesk's own tuning ranks its candidate gains with it on the plant it identified
  (:class:`ModelMoves`, passed to ``search.tune_on_model``). The vectorised batch model of
  domain/tuning/simulate.py integrates the shaft by Euler steps and lets friction stick at
  slightly other places; at +-10 counts that ordered the best 40 candidates of R1-200Hz no
  better than chance against the true plant (rank correlation 0.0), where this simulation of
  the identified model reached 0.7 (docs/tuning.md, "Ranking");
- the same tuning fits its model to the moves the axis ran under known gains
  (:func:`run_recorded_move`: a profile-position move as the drive generates it, from the rest
  the recording starts in; services/tuning/calibrate.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.metrics import MoveMetrics, move_metrics
from servodesk.domain.tuning.model import PlantModel
from servodesk.domain.tuning.search import ReferenceMove, Rerank, reference_move
from servodesk.model.fused import applies, fused_move, fused_ticks
from servodesk.model.plant import Plant, PlantParams, TwoMassMechanics, mechanics_for
from servodesk.model.profile_position import CONTROL_PERIOD_S, pp_step
from servodesk.model.servo import POSITION, ServoLoop

FloatArray = npt.NDArray[np.float64]

#: Seconds the loop holds a hanging load at rest before the move (its integral builds up).
GRAVITY_HOLD_S = 0.3


def run_move(
    params: PlantParams,
    gains: ServoGains,
    rate_hz: float,
    torque_limit: float,
    move: ReferenceMove,
) -> FloatArray:
    """The motor position per tick [counts] of ``move`` on the axis ``params`` describes under
    ``gains``; NaN from the tick the loop's torque stops being finite.

    A noiseless axis runs through the fused tick loop of model/fused.py (the same arithmetic,
    several times faster); one with noise or a dead time through :func:`run_move_stepwise`."""
    if not applies(params):
        return run_move_stepwise(params, gains, rate_hz, torque_limit, move)
    # Start where the axis rests under gravity: the loop holds it with its integral.
    hold = int(GRAVITY_HOLD_S * rate_hz) if params.gravity else 0
    pos = fused_move(params, gains, rate_hz, torque_limit, move.p, move.v, move.a, hold)
    assert pos is not None
    return pos


def run_move_stepwise(
    params: PlantParams,
    gains: ServoGains,
    rate_hz: float,
    torque_limit: float,
    move: ReferenceMove,
) -> FloatArray:
    """:func:`run_move` through ``ServoLoop.update`` and ``Plant.step``, one call each per
    tick, as the simulated drive's engine composes them: any plant (noise, dead time)."""
    plant = Plant(params, mechanics_for(params))
    dt = 1.0 / rate_hz
    loop = ServoLoop(gains, rate_hz, params.counts_per_rev, torque_limit)
    step = plant.step
    update = loop.update
    if params.gravity:
        for _ in range(int(GRAVITY_HOLD_S * rate_hz)):
            step(update(0.0, 0.0, 0.0, plant.encoder_counts), dt)
    p, v, a = move.p.tolist(), move.v.tolist(), move.a.tolist()
    pos = np.empty(len(p))
    for k in range(len(p)):
        enc = plant.encoder_counts
        pos[k] = enc
        tau = update(p[k], v[k], a[k], enc)
        if not math.isfinite(tau):
            pos[k:] = math.nan
            break
        step(tau, dt)
    return pos


@dataclass(frozen=True, slots=True)
class ModelMoves:
    """Candidate gains run through a move on the exact simulation of an identified axis.

    Picklable (the tuning's search runs in a worker process). Build it with :meth:`of`.
    """

    params: PlantParams
    rate_hz: float
    torque_limit: float

    @classmethod
    def of(
        cls,
        plant: PlantModel,
        rate_hz: float,
        *,
        counts_per_rev: float,
        torque_limit: float,
        coulomb: float = 0.0,
        gravity: float = 0.0,
    ) -> ModelMoves | None:
        """The simulation of ``plant`` with its friction and gravity torque [N m]; None when
        the model has modes the simulated mechanics do not (a second resonance)."""
        if plant.extra_modes or plant.load_viscous:
            return None
        cl = plant.current_loop_hz or None
        params = PlantParams(
            motor_inertia=plant.motor_inertia,
            load_inertia=plant.load_inertia,
            viscous=plant.viscous,
            coulomb=max(coulomb, 0.0),
            # The torque clamp is the loop's (ServoLoop); the plant's must not cut below it.
            peak_torque=2.0 * torque_limit,
            counts_per_rev=round(counts_per_rev),
            current_tau=0.0,
            current_loop_hz=cl,
            resonance_hz=plant.resonance_hz,
            damping=plant.damping,
            gravity=gravity,
            exact=True,
        )
        return cls(params, rate_hz, torque_limit)

    def __call__(
        self, gains: Sequence[ServoGains], move: ReferenceMove
    ) -> list[MoveMetrics | None]:
        """The move's metrics per gain set (None: the loop diverged)."""
        demand = move.p * self.params.counts_per_rev / (2.0 * math.pi)
        out: list[MoveMetrics | None] = []
        for g in gains:
            pos = run_move(self.params, g, self.rate_hz, self.torque_limit, move)
            if not np.isfinite(pos).all():
                out.append(None)
                continue
            out.append(move_metrics(move.t, move.target_counts, pos, move.t_end, demand))
        return out


@dataclass(frozen=True, slots=True)
class OwnMove:
    """An identified axis with another inertia, run on the reference move built for that
    inertia rather than on the move it is handed (whose hold after the profile it keeps).

    The reference move accelerates at a share of the machine's move torque over the inertia
    (search.reference_move): an axis heavier than identified makes the machine's own move
    gentler, and one lighter makes it harder. ``moves`` simulates the axis with ``inertia``
    [kg m^2]; picklable like it."""

    moves: ModelMoves
    inertia: float

    def __call__(
        self, gains: Sequence[ServoGains], move: ReferenceMove
    ) -> list[MoveMetrics | None]:
        own = reference_move(
            self.inertia,
            self.moves.torque_limit,
            self.moves.params.counts_per_rev,
            self.moves.rate_hz,
            hold_s=float(move.t[-1] - move.t_end),
        )
        return self.moves(gains, own)


@dataclass(frozen=True, slots=True)
class WorstOf:
    """Candidate gains run on several simulated axes; each candidate's metrics are those of
    the axis it settles worst on (:meth:`MoveMetrics.key`), None if it diverges on any.

    The own tuning (services/tuning/own/) ranks a rigid axis on the identified axis and on
    it a little lighter and heavier: with an inertia feed-forward near the inertia, settling
    to +-10 counts is a knife edge (the oracle's gains settle 7-33 x slower with their
    feed-forward 2 % off, docs/tuning.md), and gains that are fast only on the nominal axis
    would stake the result on the inertia being known better than it is."""

    members: tuple[Rerank, ...]

    def __call__(
        self, gains: Sequence[ServoGains], move: ReferenceMove
    ) -> list[MoveMetrics | None]:
        runs = [m(gains, move) for m in self.members]
        out: list[MoveMetrics | None] = []
        for per_axis in zip(*runs, strict=True):
            if any(m is None for m in per_axis):
                out.append(None)
            else:
                out.append(max((m for m in per_axis if m is not None), key=MoveMetrics.key))
        return out


@dataclass(frozen=True, slots=True)
class RecordedMove:
    """A profile-position move the axis ran under known gains, as the drive's recorder saw it
    at the loop rate: what the own tuning fits its model to (services/tuning/calibrate.py).

    Counts are relative to where the demand rested before the move. ``position[0]`` is the
    sample after the first loop tick of the move's first control cycle."""

    gains: ServoGains
    #: Target less the demand's rest [counts].
    distance: float
    #: The profile velocity and acceleration (= deceleration) as written [counts/s, counts/s²].
    velocity: float
    acc: float
    #: Where the axis rested [counts] and the torque command that held it there [N m].
    offset: float
    hold_torque: float
    #: The drive's torque limit (6072h) [N m].
    torque_limit: float
    #: The motor position per loop tick [counts].
    position: FloatArray


def run_recorded_move(params: PlantParams, move: RecordedMove, rate_hz: float) -> FloatArray:
    """The motor position per loop tick [counts] of ``move`` on the axis ``params`` describes
    (no noise), aligned with ``move.position``.

    As the simulated drive runs it (engine.py): the set-point generator steps once per control
    cycle, the loop ticks the cycle's sub-steps with the demand interpolated from the cycle's
    start, the cycle's velocity and acceleration fed forward. The axis starts at rest where the
    recording found it: the loop's integral holding the torque it held, and on a two-mass axis
    the shaft wound by that torque (the load held by its friction, the motor by the shaft).

    A noiseless axis runs through the fused tick loop of model/fused.py, the generator's demand
    laid out per tick beforehand: the same arithmetic as :func:`run_recorded_move_stepwise`
    (tests/sim/test_fused_move.py holds the two equal to the count), some 25 times faster
    (bench/bench_replay.py). The fit of the inertias to a try replays its moves some 80 times
    (services/tuning/calibrate.py)."""
    plant, loop = _at_rest(params, move, rate_hz)
    if not applies(params):
        return _replayed_stepwise(plant, loop, params, move, rate_hz)
    n = max(1, round(rate_hz * CONTROL_PERIOD_S))
    rad = 2.0 * math.pi / params.counts_per_rev
    total = len(move.position)
    # The encoder after each tick is the one the next tick starts with: one tick more.
    cycles = -(-(total + 1) // n)
    # Per control cycle: where the demand starts, its step per tick, velocity, acceleration.
    start, inc, vel, acc = (np.empty(cycles) for _ in range(4))
    dp, dv = 0.0, 0.0
    done = False
    for c in range(cycles):
        raw0 = dp
        if done:
            da = dv = 0.0
        else:
            dp, dv, da, done = pp_step(
                dp, dv, move.distance, move.velocity, move.acc, move.acc, CONTROL_PERIOD_S
            )
        start[c], inc[c], vel[c], acc[c] = raw0, (dp - raw0) / n, dv * rad, da * rad
    # As ServoLoop.run forms the demand: (p0 + inc * k) * rad on tick k = 1..n of the cycle.
    k = np.arange(1, n + 1, dtype=np.float64)
    p = ((start[:, None] + inc[:, None] * k) * rad).ravel()[: total + 1]
    v = np.repeat(vel, n)[: total + 1]
    a = np.repeat(acc, n)[: total + 1]
    pos = fused_ticks(plant, loop, rate_hz, p, v, a)
    return np.asarray(pos[1 : total + 1], dtype=np.float64)


def run_recorded_move_stepwise(
    params: PlantParams, move: RecordedMove, rate_hz: float
) -> FloatArray:
    """:func:`run_recorded_move` through ``ServoLoop.run`` and ``Plant.step_counts``, a control
    cycle at a time as the simulated drive's engine runs them: any plant (noise)."""
    plant, loop = _at_rest(params, move, rate_hz)
    return _replayed_stepwise(plant, loop, params, move, rate_hz)


def _at_rest(params: PlantParams, move: RecordedMove, rate_hz: float) -> tuple[Plant, ServoLoop]:
    """The axis and its loop where the recording found them (:func:`run_recorded_move`)."""
    mech = mechanics_for(params)
    plant = Plant(params, mech)
    plant.set_position_counts(move.offset)
    plant.torque = move.hold_torque
    if isinstance(mech, TwoMassMechanics) and mech.stiffness > 0.0:
        mech.load_pos = mech.position - move.hold_torque / mech.stiffness
    loop = ServoLoop(move.gains, rate_hz, params.counts_per_rev, move.torque_limit)
    loop.hold(plant.encoder_counts, move.hold_torque)
    return plant, loop


def _replayed_stepwise(
    plant: Plant, loop: ServoLoop, params: PlantParams, move: RecordedMove, rate_hz: float
) -> FloatArray:
    n = max(1, round(rate_hz * CONTROL_PERIOD_S))
    dt = 1.0 / rate_hz
    rad = 2.0 * math.pi / params.counts_per_rev
    total = len(move.position)
    out: list[float] = []
    append = out.append

    def after(_k: int) -> None:
        append(float(plant.encoder_counts))

    dp, dv = 0.0, 0.0
    done = False
    counts = plant.encoder_counts
    while len(out) < total:
        raw0 = dp
        if done:
            da = dv = 0.0
        else:
            step = pp_step(
                dp, dv, move.distance, move.velocity, move.acc, move.acc, CONTROL_PERIOD_S
            )
            dp, dv, da, done = step
        counts, _ = loop.run(
            n,
            plant.step_counts,
            dt,
            counts,
            mode=POSITION,
            p0=raw0,
            inc=(dp - raw0) / n,
            v_demand=dv * rad,
            a_demand=da * rad,
            after=after,
        )
        if not math.isfinite(loop.command):
            out.extend([math.nan] * (total - len(out)))
    return np.asarray(out[:total], dtype=np.float64)
