"""The profile-position set-point generator of the simulated drives (CiA 402-2 §6.5): one
trapezoidal step toward the target per control cycle.

Two users: the drive engine (engine.py) steps it every cycle in mode pp, and the own tuning
replays a try the axis ran (replay.py :func:`~servodesk.model.replay.run_recorded_move`) through
the same steps, so that the model and the record see the same demand to the count."""

from __future__ import annotations

import math
from typing import NamedTuple

#: The drives' control cycle [s]: the set-point generators step once per cycle, the servo loop
#: runs the cycle's sub-steps (docs/tuning.md).
CONTROL_PERIOD_S = 1e-3


class PpStep(NamedTuple):
    """One cycle of the generator: the demand position [counts], velocity [counts/s] and
    acceleration [counts/s²] after it; ``done``: the demand rests on the target (it snapped
    there from within half a count at a speed one deceleration step stops)."""

    dp: float
    dv: float
    da: float
    done: bool


def pp_step(
    dp: float, dv: float, target: float, vmax: float, acc: float, dec: float, period: float
) -> PpStep:
    """The demand one ``period`` later, from ``dp`` moving at ``dv`` toward ``target`` with
    the profile velocity ``vmax`` (already limited by 607Fh), acceleration ``acc`` (6083h) and
    deceleration ``dec`` (6084h)."""
    e = target - dp
    if -0.5 <= e <= 0.5 and -dec * period <= dv <= dec * period:
        return PpStep(target, 0.0, 0.0, True)
    # Discrete braking curve: the speed from which stepping down by dec*T per cycle stops
    # exactly at the target (v²/2a + vT/2 = distance).
    h = 0.5 * dec * period
    vb = -h + math.sqrt(h * h + 2.0 * dec * abs(e))
    vdes = min(vmax, vb)
    if e < 0:
        vdes = -vdes
    v = dv
    rate = acc if abs(vdes) > abs(v) and v * vdes >= 0.0 else dec
    step_v = vdes - v
    lim = rate * period
    if step_v > lim:
        step_v = lim
    elif step_v < -lim:
        step_v = -lim
    v += step_v
    step = v * period
    if (step >= e > 0) or (step <= e < 0):
        # Arrives within this cycle.
        return PpStep(target, 0.0, -dv / period, False)
    return PpStep(dp + step, v, step_v / period, False)


def pp_duration_s(distance: float, velocity: float, acc: float) -> float:
    """How long the profile takes [s], to within a cycle: a trapezoid at ``velocity``, or a
    triangle where the distance is too short to reach it (acceleration = deceleration)."""
    d = abs(distance)
    if velocity <= 0.0 or acc <= 0.0:
        return 0.0
    if d * acc < velocity * velocity:
        return 2.0 * math.sqrt(d / acc)
    return d / velocity + velocity / acc
