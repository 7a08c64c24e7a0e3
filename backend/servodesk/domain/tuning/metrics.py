"""The test move and its figures of merit (anchors-tuning.md §3.2 and §3.3).

- :func:`jerk_limited_profile`: the point-to-point move of the benchmark, a velocity trapezoid
  with its acceleration steps turned into ramps of ``jerk_time``;
- :func:`move_metrics`: settling times to +-10 / +-100 counts, overshoot and following error,
  with the definitions of §3.3;
- :func:`step_response` and :func:`simulate_move`: the same move run on the linear loop model
  (``model.simulate``), a quick stand-in for the real simulated servo loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from servodesk.domain.tuning.model import LoopModel, simulate

FloatArray = npt.NDArray[np.float64]

TWO_PI = 2.0 * math.pi


class Profile(NamedTuple):
    """A sampled motion profile: time [s], position [rad], velocity [rad/s], acceleration
    [rad/s^2]. The last sample is at or after the end of the move."""

    t: FloatArray
    p: FloatArray
    v: FloatArray
    a: FloatArray


@dataclass(frozen=True, slots=True)
class _Trapezoid:
    distance: float  # >= 0
    accel: float
    peak: float  # peak velocity
    ta: float  # acceleration time
    tc: float  # constant-velocity time

    @property
    def duration(self) -> float:
        return 2.0 * self.ta + self.tc

    @classmethod
    def plan(cls, distance: float, v_max: float, a_max: float, min_cruise: float) -> _Trapezoid:
        """The velocity trapezoid with a constant-velocity phase of at least ``min_cruise``.

        The peak velocity is ``v_max`` if the move is long enough, else the root of
        ``D = v^2 / a + v min_cruise`` (acceleration phase, cruise, deceleration phase).
        """
        a, tj = a_max, min_cruise
        v = min(v_max, 0.5 * (-a * tj + math.sqrt(a * a * tj * tj + 4.0 * a * distance)))
        if v <= 0.0:
            return cls(distance, a, 0.0, 0.0, 0.0)
        ta = v / a
        return cls(distance, a, v, ta, max(0.0, distance / v - ta))

    def position(self, t: FloatArray) -> FloatArray:
        a, ta, t2, t3 = self.accel, self.ta, self.ta + self.tc, self.duration
        return np.select(
            [t <= 0.0, t <= ta, t <= t2, t <= t3],
            [
                np.zeros_like(t),
                0.5 * a * t * t,
                0.5 * a * ta * ta + self.peak * (t - ta),
                self.distance - 0.5 * a * (t3 - t) ** 2,
            ],
            self.distance,
        )

    def velocity(self, t: FloatArray) -> FloatArray:
        a, ta, t2, t3 = self.accel, self.ta, self.ta + self.tc, self.duration
        return np.select(
            [t <= 0.0, t <= ta, t <= t2, t <= t3],
            [np.zeros_like(t), a * t, np.full_like(t, self.peak), a * (t3 - t)],
            0.0,
        )

    def integral(self, t: FloatArray) -> FloatArray:
        """``int_0^t position``: piecewise cubic, exact."""
        a, ta, t2, t3 = self.accel, self.ta, self.ta + self.tc, self.duration
        d = self.distance
        p_ta = 0.5 * a * ta * ta
        i_ta = a * ta**3 / 6.0
        i_t2 = i_ta + p_ta * (t2 - ta) + 0.5 * self.peak * (t2 - ta) ** 2
        i_t3 = i_t2 + d * (t3 - t2) - a * (t3 - t2) ** 3 / 6.0
        return np.select(
            [t <= 0.0, t <= ta, t <= t2, t <= t3],
            [
                np.zeros_like(t),
                a * t**3 / 6.0,
                i_ta + p_ta * (t - ta) + 0.5 * self.peak * (t - ta) ** 2,
                i_t2 + d * (t - t2) - a * ((t3 - t2) ** 3 - (t3 - t) ** 3) / 6.0,
            ],
            i_t3 + d * (t - t3),
        )


def profile_duration(distance_rad: float, v_max: float, a_max: float, jerk_time: float) -> float:
    """Duration [s] of :func:`jerk_limited_profile` (the commanded end ``t_end``)."""
    return _Trapezoid.plan(abs(distance_rad), v_max, a_max, jerk_time).duration + jerk_time


def jerk_limited_profile(
    distance_rad: float,
    v_max: float,
    a_max: float,
    jerk_time: float,
    rate: float,
    hold_s: float = 0.0,
) -> Profile:
    """S-curve point-to-point move sampled at ``rate`` [Hz], from rest at 0 to ``distance_rad``.

    Built as a velocity trapezoid (``v_max``, ``a_max``) passed through a moving average of
    ``jerk_time`` seconds, evaluated in closed form: every acceleration step of the trapezoid
    becomes a ramp lasting ``jerk_time``, so ``|jerk| <= a_max / jerk_time``. For that the
    trapezoid keeps a constant-velocity phase of at least ``jerk_time`` (a short move gets a
    lower peak velocity instead of a triangle, whose +a -> -a reversal would ramp at twice the
    jerk). A moving average of bounded signals keeps ``|v| <= v_max`` and ``|a| <= a_max``, and
    it preserves the end position, which is set exactly from ``t_end = profile_duration(...)``
    on. ``hold_s`` adds samples at rest after the move (the observation window of
    anchors-tuning.md §3.2).
    """
    if v_max <= 0.0 or a_max <= 0.0 or jerk_time < 0.0 or rate <= 0.0:
        raise ValueError("v_max, a_max and rate must be positive, jerk_time not negative")
    sign = 1.0 if distance_rad >= 0.0 else -1.0
    trap = _Trapezoid.plan(abs(distance_rad), v_max, a_max, jerk_time)
    t_end = trap.duration + jerk_time
    n = math.ceil(t_end * rate - 1e-9) + 1 + max(0, round(hold_s * rate))
    t = np.arange(n, dtype=np.float64) / rate
    if jerk_time > 0.0:
        tj = jerk_time
        p = (trap.integral(t) - trap.integral(t - tj)) / tj
        v = (trap.position(t) - trap.position(t - tj)) / tj
        a = (trap.velocity(t) - trap.velocity(t - tj)) / tj
    else:
        p = trap.position(t)
        v = trap.velocity(t)
        a = np.select(
            [t < trap.ta, t < trap.ta + trap.tc, t < trap.duration],
            [trap.accel, 0.0, -trap.accel],
            0.0,
        )
        a = np.asarray(a, dtype=np.float64)
    done = t >= t_end
    p[done] = trap.distance
    v[done] = 0.0
    a[done] = 0.0
    return Profile(t, sign * p, sign * v, sign * a)


@dataclass(frozen=True, slots=True)
class MoveMetrics:
    """Figures of merit of one move (anchors-tuning.md §3.3), in seconds and encoder counts.

    ``settling_N_s``: time of the last sample with ``|position - target| > N`` minus the end of
    the commanded profile (0 if within the band from ``t_end`` on; ``inf`` if the last sample of
    the record is outside the band: not settled in the observation window). ``overshoot_counts``:
    the largest excursion past the target after ``t_end`` in the direction of the move (0 if
    none). ``fe_rms_counts`` / ``fe_max_counts``: following error ``demand - position`` over
    ``[t_start, t_end]``.
    """

    settling_10_s: float
    settling_100_s: float
    overshoot_counts: float
    fe_rms_counts: float
    fe_max_counts: float

    def key(self) -> tuple[float, float, float]:
        """Lexicographic objective of the oracle (§3.4): t_s(10), then t_s(100), then FE_rms."""
        return (self.settling_10_s, self.settling_100_s, self.fe_rms_counts)


def _settling(
    t: FloatArray, err: FloatArray, band: float, t_end: float, hold_s: float = 0.0
) -> float:
    out = np.nonzero(np.abs(err) > band)[0]
    if len(out) == 0:
        return 0.0
    last = int(out[-1])
    if last == len(err) - 1 or float(t[-1]) - float(t[last]) < hold_s:
        return math.inf
    return max(0.0, float(t[last]) - t_end)


def smoothed_settling(
    t: npt.ArrayLike,
    target_counts: float,
    position_counts: npt.ArrayLike,
    t_end: float,
    band: float = 10.0,
    window_s: float = 0.005,
    hold_s: float = 0.0,
) -> float:
    """Settling time to ``+-band`` counts of the position error's trailing mean over
    ``window_s``: what a noisy axis shows of the settling that its noise hides. ``hold_s``:
    the mean must stay inside the band for at least that long before the record ends, or the
    axis did not settle within it (inf).

    With torque noise a compliant axis jitters by 5-30 counts RMS at rest under any gains, so
    the plain +-10 count settling is the end of every record. Averaged over 5 ms, the jitter
    falls below the band while the slow approach (friction, integral action) stays: over the
    tuner's candidates on the benchmark's 400-800 Hz axes this ranked like the noiseless
    +-10 count settling (rank correlation 0.6-0.8, against 0.1-0.4 for the raw figure).
    """
    tt = np.asarray(t, dtype=np.float64)
    err = np.asarray(position_counts, dtype=np.float64) - target_counts
    if len(tt) < 2:
        return math.inf
    dt = float(np.median(np.diff(tt)))
    n = max(1, round(window_s / dt)) if dt > 0.0 else 1
    c = np.concatenate(([0.0], np.cumsum(err)))
    k = np.arange(1, len(err) + 1)
    lo = np.maximum(0, k - n)
    return _settling(tt, (c[k] - c[lo]) / (k - lo), band, t_end, hold_s)


def move_metrics(
    t: npt.ArrayLike,
    target_counts: float,
    position_counts: npt.ArrayLike,
    t_end: float,
    demand: npt.ArrayLike | None = None,
    *,
    t_start: float | None = None,
    start_counts: float | None = None,
) -> MoveMetrics:
    """Metrics of a recorded move (see :class:`MoveMetrics`).

    ``demand`` is the commanded position per sample [counts] (needed for the following error,
    NaN without it); the move direction is the sign of ``target - start`` with ``start`` the
    first demand sample (or ``start_counts``, or the first position sample).
    """
    tt = np.asarray(t, dtype=np.float64)
    pos = np.asarray(position_counts, dtype=np.float64)
    if len(tt) != len(pos):
        raise ValueError("t and position_counts must have the same length")
    dem = None if demand is None else np.asarray(demand, dtype=np.float64)
    if start_counts is None:
        start_counts = float(dem[0]) if dem is not None else float(pos[0])
    err = pos - target_counts
    s10 = _settling(tt, err, 10.0, t_end)
    s100 = _settling(tt, err, 100.0, t_end)
    direction = 1.0 if target_counts >= start_counts else -1.0
    after = tt >= t_end
    overshoot = float(np.max(direction * err[after])) if after.any() else 0.0
    overshoot = max(0.0, overshoot)
    if dem is None:
        fe_rms = fe_max = math.nan
    else:
        t0 = float(tt[0]) if t_start is None else t_start
        win = (tt >= t0) & (tt <= t_end)
        fe = dem[win] - pos[win]
        fe_rms = float(np.sqrt(np.mean(fe * fe))) if len(fe) else math.nan
        fe_max = float(np.max(np.abs(fe))) if len(fe) else math.nan
    return MoveMetrics(s10, s100, overshoot, fe_rms, fe_max)


# ----------------------------------------------------------------------------------------------
# Linear-model simulation of the move


def step_response(
    loop: LoopModel, amplitude_rad: float = 1e-3, duration_s: float = 0.05
) -> tuple[FloatArray, FloatArray]:
    """Position step response of the cascade (no feed-forward): ``(t, theta)``."""
    n = max(2, round(duration_s * loop.rate_hz))
    t = np.arange(n) / loop.rate_hz
    theta, _, _ = simulate(loop, np.full(n, amplitude_rad))
    return t, theta


def benchmark_move(
    total_inertia: float,
    peak_torque: float,
    rate: float,
    distance_rev: float = 0.5,
    v_max_rev_s: float = 50.0,
    accel_fraction: float = 0.7,
    jerk_time: float = 0.002,
    observe_s: float = 0.5,
) -> tuple[Profile, float]:
    """The move of anchors-tuning.md §3.2 (0.5 rev, a_max = 0.7 T_peak / J, 50 rev/s, 2 ms
    jerk ramp, 0.5 s observation): ``(profile, t_end)``."""
    a_max = accel_fraction * peak_torque / total_inertia
    dist = TWO_PI * distance_rev
    vmax = TWO_PI * v_max_rev_s
    prof = jerk_limited_profile(dist, vmax, a_max, jerk_time, rate, hold_s=observe_s)
    return prof, profile_duration(dist, vmax, a_max, jerk_time)


def simulate_move(
    loop: LoopModel,
    profile: Profile,
    t_end: float,
    counts_per_rev: int = 1 << 20,
    coulomb: float = 0.0,
) -> MoveMetrics:
    """Run ``profile`` on the linear loop model (plus smooth Coulomb friction on the load) and
    score it with :func:`move_metrics`. No torque limit, noise or quantisation: a quick,
    optimistic stand-in for the simulated servo loop."""
    theta, _, _ = simulate(loop, profile.p, profile.v, profile.a, coulomb=coulomb)
    scale = counts_per_rev / TWO_PI
    return move_metrics(
        profile.t,
        float(profile.p[-1]) * scale,
        theta * scale,
        t_end,
        profile.p * scale,
    )
