"""The identified axis fitted to the moves it ran under known gains: the own tuning's tries.

The frequency response and the test moves leave the motor's and the load's inertia 0.5-3 %
off on the benchmark's 100-200 Hz axes, and there the gains that settle fastest move by 2 x
with that error (docs/tuning.md, "the ninth session of 2026-11-29"). A try is a brisk move
under gains the tuner chose, recorded at the loop rate with the drive's following error; its
motor position answers exactly the inertias those gains meet. This module replays the move on
the model (model/replay.py :func:`~servodesk.model.replay.run_recorded_move`: the drive's own
set-point generator and loop) and fits the two inertias to the recording by output error, the
square difference of the motor positions summed over the move and the settling after it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize, minimize_scalar  # type: ignore[import-untyped]

from servodesk.domain.tuning.gains import ServoGains
from servodesk.model.plant import PlantParams
from servodesk.model.profile_position import CONTROL_PERIOD_S, pp_duration_s, pp_step
from servodesk.model.replay import RecordedMove, run_recorded_move

FloatArray = npt.NDArray[np.float64]

#: Seconds after the commanded profile that a recorded move is fitted over: the settling the
#: gains are chosen for, before the torque noise at rest is all the record holds.
SETTLE_S = 0.1
#: The search's first step and its last, as a fraction of each inertia; and how far it may go
#: (the identification set's inertia tolerance, search.identification_set).
FIRST_STEP = 0.02
LAST_STEP = 0.0025
REACH = 0.06
#: A move is fitted only if the axis rested within this share of the move's distance of where
#: the demand rested: the replay starts from rest, and an axis still creeping toward the last
#: target (slow gains, a try that did not settle) starts with a velocity and an integral the
#: recording does not show (factory gains on R1-200Hz: 6404 counts short, 470 counts off).
REST_SHARE = 1e-3


@dataclass(frozen=True, slots=True)
class InertiaFit:
    """The motor's and the load's inertia as factors on the model's, and the output error
    (mean square motor position difference [counts²]) at the model and at the fit."""

    motor: float
    load: float
    error_before: float
    error_after: float
    evaluations: int


def recorded_move(
    *,
    position: FloatArray,
    following_error: FloatArray,
    torque: FloatArray,
    rate_hz: float,
    origin: float,
    target: float,
    velocity: float,
    acc: float,
    gains: ServoGains,
    torque_limit: float,
) -> RecordedMove | None:
    """The move as :func:`~servodesk.model.replay.run_recorded_move` replays it, from a recording
    at the loop rate of the motor position (6064h), the following error (60F4h) and the torque
    command [N m]; ``origin`` is where the demand rested, the velocity and acceleration as
    written (6081h, 6083h = 6084h). None where the recording does not show the move's first
    tick or the axis did not rest where the demand did (:data:`REST_SHARE`).

    The recording is aligned by the demand it holds (position + following error): the first
    sample the demand has left its rest is a tick of the move's first control cycle, and which
    one follows from the generator's first step (the demand moves by the same amount each tick
    of a cycle)."""
    n = round(rate_hz * CONTROL_PERIOD_S)
    if n < 1 or len(position) < 2 or len(following_error) != len(position):
        return None
    distance = target - origin
    first = pp_step(0.0, 0.0, distance, velocity, acc, acc, CONTROL_PERIOD_S).dp / n
    if abs(first) < 1.0:
        return None
    demand = position + following_error - origin
    moved = np.flatnonzero(np.abs(demand) > 0.5)
    if not len(moved):
        return None
    i0 = int(moved[0])
    k0 = round(float(demand[i0]) / first)  # Which tick of the first cycle sample i0 is.
    if not 1 <= k0 <= n:
        return None
    # The sample of tick 1: the axis has not moved yet (the loop's command reaches the current
    # loop a tick later), so it shows where the axis rested and the torque that held it. A
    # recording that began later does not show that state: refused.
    start = i0 - (k0 - 1)
    if start < 0:
        return None
    profile_s = pp_duration_s(distance, velocity, acc)
    length = min(len(position) - start, round((profile_s + SETTLE_S) * rate_hz))
    if length < n:
        return None
    offset = float(position[start] - origin)
    if abs(offset) > REST_SHARE * abs(distance):
        return None
    return RecordedMove(
        gains=gains,
        distance=distance,
        velocity=velocity,
        acc=acc,
        offset=offset,
        hold_torque=float(torque[start]),
        torque_limit=torque_limit,
        position=position[start : start + length] - origin,
    )


def output_error(params: PlantParams, moves: Sequence[RecordedMove], rate_hz: float) -> float:
    """Mean square difference of the motor position [counts²] between the recordings and
    their replays on ``params``, over all the moves' samples (inf where a replay diverged)."""
    total = 0.0
    count = 0
    for m in moves:
        sim = run_recorded_move(params, m, rate_hz)
        diff = m.position - sim
        if not np.isfinite(diff).all():
            return math.inf
        total += float(np.sum(diff**2))
        count += len(diff)
    return total / count if count else math.inf


class _Errors:
    """The output error (:func:`output_error`) of ``params`` with its motor's and load's
    inertia scaled by ``a`` and ``b``, each replay run once (the searches come back to points
    they ran); inf beyond :data:`REACH` of the model."""

    def __init__(self, params: PlantParams, moves: Sequence[RecordedMove], rate_hz: float) -> None:
        self.params, self.moves, self.rate_hz = params, moves, rate_hz
        self.cache: dict[tuple[float, float], float] = {}

    def __call__(self, a: float, b: float) -> float:
        if abs(a - 1.0) > REACH or abs(b - 1.0) > REACH:
            return math.inf
        key = (round(a, 7), round(b, 7))
        if key not in self.cache:
            p = replace(
                self.params,
                motor_inertia=self.params.motor_inertia * a,
                load_inertia=self.params.load_inertia * b,
            )
            self.cache[key] = output_error(p, self.moves, self.rate_hz)
        return self.cache[key]

    def fit(self, a: float, b: float, found: float) -> InertiaFit:
        """The fit at ``(a, b)`` whose error the search found as ``found``, or the model's own
        inertias where that is no better than the model."""
        before = self(1.0, 1.0)
        if not found < before:
            a, b = 1.0, 1.0
        return InertiaFit(a, b, before, min(found, before), len(self.cache))


def fit_inertias(params: PlantParams, moves: Sequence[RecordedMove], rate_hz: float) -> InertiaFit:
    """The motor's and the load's inertia (factors on ``params``'s) whose replays come closest
    to the recorded moves, within :data:`REACH` of the model: a Nelder-Mead search from it
    (first steps :data:`FIRST_STEP`, to :data:`LAST_STEP`). The output error's valley runs
    diagonally (a heavier motor with a lighter load moves the motor alike) and is narrow across
    the load: R10-200Hz's error grows 20 x with the load 1 % off and 2 x with the motor 2 %
    off, where a search along the axes stopped 5 % off the motor's inertia."""
    errors = _Errors(params, moves, rate_hz)
    errors(1.0, 1.0)
    simplex = np.array([[0.0, 0.0], [FIRST_STEP, 0.0], [0.0, FIRST_STEP / 4.0]])
    res = minimize(
        lambda x: errors(1.0 + float(x[0]), 1.0 + float(x[1])),
        np.zeros(2),
        method="Nelder-Mead",
        options={"initial_simplex": simplex, "xatol": LAST_STEP / 2.0, "fatol": 0.0, "maxfev": 80},
    )
    return errors.fit(1.0 + float(res.x[0]), 1.0 + float(res.x[1]), float(res.fun))


def fit_split(params: PlantParams, moves: Sequence[RecordedMove], rate_hz: float) -> InertiaFit:
    """The motor's share of the inertia fitted to the recorded moves with the total held: the
    motor's factor ``a`` and the load's ``b`` with ``a J_M + b J_L = J_M + J_L``, each within
    :data:`REACH` of the model (a bounded scalar search, to :data:`LAST_STEP` / 2).

    For a model whose total inertia the moves' double integral gave (within 0.25 % at the
    median on the benchmark's 400-800 Hz axes) and whose split follows from where the
    anti-resonance lies: a free fit of both there also took up what the friction and damping
    were off by (R3-800Hz seed 1: the motor 4.1 % heavier, gains that settled 2 x slower),
    and held to the split it moved R10-400Hz seed 3's pick from 51.2 to 19.6 ms (the oracle
    60.0 ms) and no tuning of the benchmark's 208 the other way (docs/tuning.md)."""
    errors = _Errors(params, moves, rate_hz)
    jm, jl = params.motor_inertia, params.load_inertia

    def load(x: float) -> float:  # The load's factor that keeps the total at the motor's 1 + x.
        return 1.0 - x * jm / jl

    errors(1.0, 1.0)
    reach = min(REACH, REACH * jl / jm)
    res = minimize_scalar(
        lambda x: errors(1.0 + float(x), load(float(x))),
        bounds=(-reach, reach),
        method="bounded",
        options={"xatol": LAST_STEP / 2.0, "maxiter": 40},
    )
    x = float(res.x)
    return errors.fit(1.0 + x, load(x), float(res.fun))
