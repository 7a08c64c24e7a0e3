"""Time-domain simulation of the servo cascade on a plant model, many gain sets at once.

The tuner ranks candidate gains by what they do to a move (settling time, overshoot,
following error), not only by margins: the same objective the benchmark's oracle uses
(anchors-tuning.md §3.4). It cannot run candidates on the drive, so it runs them on the plant
it identified; the benchmark's oracle runs the same candidates on the exact plant.

The controller arithmetic is the drive's, tick for tick (model/servo.py documents it and
docs/tuning.md states it): position P with velocity feed-forward, velocity PI with conditional
integration, inertia feed-forward, low-pass and two notches (transposed direct form II), the
clamp, and the one-tick compute delay; velocity by a backward difference of the quantised
encoder. The plant is the model's: current loop as a first-order lag (exact discretisation),
rigid or two-mass mechanics by semi-implicit Euler with ``substeps`` steps per tick, viscous
friction at the motor, Coulomb friction with sticking (as model/plant.py, vectorised:
:func:`friction_step`) and a constant gravity torque at the load.

Sticking is what the drive's plant does (model/plant.py), so the ranking sees the same friction:
on a two-mass axis a load held by static friction leaves the motor ringing against the shaft,
and gains whose linear margins are fine can hunt in a friction limit cycle (R1-400Hz of the
benchmark: 380 Hz, +-190 counts, at 47 deg / 9 dB). The smooth ``tanh`` sign used before shows
that cycle too, but it stops and restarts the load at other places than the plant does, and at
+-10 counts (3.4 arcsec at 2^20 counts/rev) that changes which candidate settles first.

Every state is a numpy array over the batch, so one Python loop over the ticks serves every
candidate: a few hundred candidates cost about as much as a handful.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from servodesk.domain.tuning.filters import lowpass_coefficients, notch_coefficients
from servodesk.domain.tuning.gains import ServoGains

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class MechanicalModel:
    """The plant a simulation runs (SI units at the motor shaft)."""

    motor_inertia: float
    load_inertia: float
    resonance_hz: float | None = None
    damping: float = 0.03
    viscous: float = 0.0
    coulomb: float = 0.0
    gravity: float = 0.0
    current_loop_hz: float = 2000.0
    peak_torque: float = 4.46
    counts_per_rev: int = 1 << 20

    @property
    def inertia(self) -> float:
        return self.motor_inertia + self.load_inertia


@dataclass(frozen=True, slots=True)
class Trace:
    """Motor position [counts, float] and torque command [N m] per tick, one row per candidate."""

    position_counts: FloatArray
    torque: FloatArray
    #: A candidate whose state left any sane bound (diverged) is marked, its rows are NaN.
    diverged: NDArray[np.bool_]


def _filter_arrays(
    gains: Sequence[ServoGains], rate: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per candidate (b0, b1, a1) of the low-pass and (b0, b1, b2, a1, a2) of each notch."""
    nyq = 0.5 * rate
    lp = np.zeros((len(gains), 3))
    n1 = np.zeros((len(gains), 5))
    n2 = np.zeros((len(gains), 5))
    for i, g in enumerate(gains):
        if 0.0 < g.torque_lpf_hz < nyq:
            b0, b1, _b2, a1, _a2 = lowpass_coefficients(g.torque_lpf_hz, rate)
            lp[i] = (b0, b1, a1)
        else:
            lp[i] = (1.0, 0.0, 0.0)
        for arr, (f, w, d) in (
            (n1, (g.notch1_hz, g.notch1_width, g.notch1_depth)),
            (n2, (g.notch2_hz, g.notch2_width, g.notch2_depth)),
        ):
            arr[i] = notch_coefficients(f, w, d, rate) if 0.0 < f < nyq else (1, 0, 0, 0, 0)
    return lp, n1, n2


def friction_step(
    w: FloatArray, drive: FloatArray, viscous: float, coulomb: float, dt_over_j: float
) -> FloatArray:
    """The velocity after one step of an inertia driven by ``drive`` (N m, gravity included)
    against viscous friction and Coulomb friction with sticking, per candidate:
    ``RigidMechanics.advance`` of model/plant.py, vectorised. At rest the inertia stays at rest
    while ``|drive|`` does not exceed the Coulomb torque; a velocity that would cross zero
    within the step while the friction could hold it stops at zero."""
    if coulomb <= 0.0:
        return w + (drive - viscous * w) * dt_over_j
    held = np.abs(drive) <= coulomb
    sign_w = np.sign(w)
    moving = w + (drive - viscous * w - coulomb * sign_w) * dt_over_j
    starting = np.where(held, 0.0, (drive - coulomb * np.sign(drive)) * dt_over_j)
    stops = held & (np.sign(moving) != sign_w)
    return np.where(w == 0.0, starting, np.where(stops, 0.0, moving))


def simulate_batch(
    model: MechanicalModel,
    gains: Sequence[ServoGains],
    rate_hz: float,
    p_demand: FloatArray,
    v_demand: FloatArray,
    a_demand: FloatArray,
    *,
    torque_limit: float | None = None,
    substeps: int = 1,
) -> Trace:
    """Run every gain set on ``model`` through the demand (rad, rad/s, rad/s² per tick).

    The axis starts at rest at position 0 with the loop reset (no integral, filters at 0). The
    gravity torque is held by the integral only after it has built up, as on the drive.
    """
    n = len(gains)
    ticks = len(p_demand)
    T = 1.0 / rate_hz
    lim = model.peak_torque if torque_limit is None else torque_limit
    rad = 2.0 * math.pi / model.counts_per_rev
    cpr = 1.0 / rad
    kp = np.array([g.kp_pos for g in gains])
    kv = np.array([g.kp_vel for g in gains])
    ki = np.array([g.kp_vel / (g.ti_vel * rate_hz) if g.ti_vel > 0.0 else 0.0 for g in gains])
    kvff = np.array([g.vel_ff for g in gains])
    jff = np.array([g.inertia_ff for g in gains])
    lp, n1, n2 = _filter_arrays(gains, rate_hz)
    lb0, lb1, la1 = lp.T
    ab0, ab1, ab2, aa1, aa2 = n1.T
    bb0, bb1, bb2, ba1, ba2 = n2.T

    # Plant constants.
    alpha = 1.0 - math.exp(-T * 2.0 * math.pi * model.current_loop_hz)
    dt = T / substeps
    jm = model.motor_inertia
    jl = model.load_inertia
    two_mass = model.resonance_hz is not None and jl > 0.0
    if two_mass:
        assert model.resonance_hz is not None
        jr = jm * jl / (jm + jl)
        wr = 2.0 * math.pi * model.resonance_hz
        k = wr * wr * jr
        c = 2.0 * model.damping * math.sqrt(k * jr)
    else:
        jm = model.inertia
        k = c = 0.0
    fc = model.coulomb

    # States.
    thm = np.zeros(n)
    wm = np.zeros(n)
    thl = np.zeros(n)
    wl = np.zeros(n)
    tau_a = np.zeros(n)
    prev = np.zeros(n)
    integ = np.zeros(n)
    lpz = np.zeros(n)
    a1z1 = np.zeros(n)
    a1z2 = np.zeros(n)
    b1z1 = np.zeros(n)
    b1z2 = np.zeros(n)
    nxt = np.zeros(n)
    sat = np.zeros(n)
    pos = np.empty((n, ticks))
    trq = np.empty((n, ticks))
    with np.errstate(over="ignore", invalid="ignore"):  # A diverging candidate.
        for t in range(ticks):
            enc = np.floor(thm * cpr)
            pos[:, t] = enc
            v_meas = (enc - prev) * (rad * rate_hz)
            prev = enc
            ev = kp * (p_demand[t] - enc * rad) + kvff * v_demand[t] - v_meas
            hold = ((sat > 0) & (ev > 0)) | ((sat < 0) & (ev < 0))
            integ = np.where(hold, integ, integ + ki * ev)
            x = kv * ev + integ + jff * a_demand[t]
            y = lb0 * x + lpz
            lpz = lb1 * x - la1 * y
            x = y
            y = ab0 * x + a1z1
            a1z1 = ab1 * x - aa1 * y + a1z2
            a1z2 = ab2 * x - aa2 * y
            x = y
            y = bb0 * x + b1z1
            b1z1 = bb1 * x - ba1 * y + b1z2
            b1z2 = bb2 * x - ba2 * y
            x = np.clip(y, -lim, lim)
            sat = np.where(y > lim, 1.0, np.where(y < -lim, -1.0, 0.0))
            out = nxt
            nxt = x
            trq[:, t] = out
            # The plant over one tick.
            tau_a += (out - tau_a) * alpha
            for _ in range(substeps):
                if two_mass:
                    spring = k * (thm - thl) + c * (wm - wl)
                    wm = wm + (tau_a - model.viscous * wm - spring) * (dt / jm)
                    wl = friction_step(wl, spring - model.gravity, 0.0, fc, dt / jl)
                    thm = thm + wm * dt
                    thl = thl + wl * dt
                else:
                    wm = friction_step(wm, tau_a - model.gravity, model.viscous, fc, dt / jm)
                    thm = thm + wm * dt
    diverged = ~np.isfinite(pos).all(axis=1) | (np.abs(pos).max(axis=1) > 1e12)
    pos[diverged] = np.nan
    return Trace(position_counts=pos, torque=trq, diverged=diverged)
