"""Identification on synthetic data generated here (not by the package's own model code)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from servodesk.domain.tuning.identify import (
    Frf,
    Resonance,
    demand_spans,
    find_resonances,
    frequency_response,
    identify_rigid,
    inertia_from_frf,
    inertia_from_moves,
    moves_gravity,
    plant_from_identification,
    resonance_from_record,
    travel_load_torque,
    with_hidden_anti_resonance,
)

RATE = 16000.0
TWO_PI = 2.0 * math.pi


def _rigid_run(
    j: float, b: float, tc: float, g: float, seconds: float, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integrate J dw/dt = tau - b w - Tc sign(w) - g (with sticking) at 4 substeps per sample.

    Returns the sample times, the recorded torque (with noise), the quantised encoder angle
    (2^20 counts/rev) and the true velocity.
    """
    rng = np.random.default_rng(seed)
    n = round(seconds * RATE)
    t = np.arange(n) / RATE
    # Reciprocating torque well above friction, plus gravity compensation on average.
    tau = g + 0.5 * np.sin(TWO_PI * 3.0 * t) + 0.25 * np.sin(TWO_PI * 7.3 * t + 1.0)
    sub = 4
    h = 1.0 / (RATE * sub)
    w = 0.0
    th = 0.0
    pos = np.empty(n)
    vel = np.empty(n)
    for k in range(n):
        pos[k] = th
        vel[k] = w
        u = tau[k]
        for _ in range(sub):
            if w == 0.0 and abs(u - g) <= tc:
                continue  # stuck
            s = math.copysign(1.0, w) if w != 0.0 else math.copysign(1.0, u - g)
            w_new = w + h * (u - b * w - tc * s - g) / j
            if w != 0.0 and (w_new > 0.0) != (w > 0.0) and abs(u - g) <= tc:
                w_new = 0.0
            w = w_new
            th += h * w
    counts = 2**20 / TWO_PI
    enc = np.floor(pos * counts) / counts
    return t, tau + rng.normal(0.0, 0.005, n), enc, vel


@pytest.fixture(scope="module")
def rigid_run() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return _rigid_run(j=4.07e-4, b=2e-3, tc=0.09, g=0.3, seconds=2.0, seed=1)


def test_identify_rigid_recovers_inertia_and_friction(
    rigid_run: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    t, tau, enc, _vel = rigid_run
    est = identify_rigid(t, tau, position_rad=enc)
    assert est.inertia == pytest.approx(4.07e-4, rel=0.01)
    assert est.viscous == pytest.approx(2e-3, rel=0.01)
    assert est.coulomb == pytest.approx(0.09, rel=0.01)
    assert est.gravity == pytest.approx(0.3, rel=0.01)
    assert est.n > 0.8 * len(t)
    assert est.residual_rms < 0.01


def test_identify_rigid_from_velocity_and_rate(
    rigid_run: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    _t, tau, _enc, vel = rigid_run
    est = identify_rigid(RATE, tau, velocity=vel)
    assert est.inertia == pytest.approx(4.07e-4, rel=0.01)
    assert est.coulomb == pytest.approx(0.09, rel=0.01)
    with pytest.raises(ValueError, match="position_rad or velocity"):
        identify_rigid(RATE, tau)


def test_identify_rigid_with_an_instrument(
    rigid_run: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    # The motion itself, unquantised, instruments the fit as a drive's position demand does
    # (correlated with the motion, not with the encoder's quantisation): the same estimates.
    t, tau, enc, vel = rigid_run
    exact = np.concatenate([[0.0], np.cumsum(vel[:-1]) / RATE])
    est = identify_rigid(t, tau, position_rad=enc, instrument_rad=exact)
    assert est.inertia == pytest.approx(4.07e-4, rel=0.01)
    assert est.viscous == pytest.approx(2e-3, rel=0.02)
    assert est.coulomb == pytest.approx(0.09, rel=0.01)
    assert est.gravity == pytest.approx(0.3, rel=0.01)
    with pytest.raises(ValueError, match="instrument must be sampled with the torque"):
        identify_rigid(t, tau, position_rad=enc, instrument_rad=exact[:-1])


def test_identify_rigid_without_the_sign_exclusion_is_worse(
    rigid_run: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    # The exclusion of near-standstill samples is what makes the Coulomb term identifiable.
    t, tau, enc, _vel = rigid_run
    good = identify_rigid(t, tau, position_rad=enc)
    bad = identify_rigid(t, tau, position_rad=enc, min_speed_fraction=0.0)
    assert abs(bad.coulomb / 0.09 - 1) > abs(good.coulomb / 0.09 - 1)


def _two_mass_tf(
    jm: float, jl: float, fr: float, zeta: float, b: float
) -> tuple[list[float], list[float]]:
    """Motor velocity / torque of the two-mass axis as continuous polynomials (anchors §2.1)."""
    wr = TWO_PI * fr
    k = wr**2 * jm * jl / (jm + jl)
    c = 2 * zeta * math.sqrt(k * jm * jl / (jm + jl))
    num = [jl, c, k]
    # (J_M s + b)(J_L s^2 + c s + k) + J_L s (c s + k)
    den = np.polyadd(np.polymul([jm, b], [jl, c, k]), [jl * c, jl * k, 0.0])
    return num, list(den)


def _closed_loop_run(
    num_c: list[float],
    den_c: list[float],
    kp: float,
    seconds: float,
    noise: float,
    seed: int,
    torque_noise: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A discrete plant B/A (ZOH of num_c/den_c) in a P velocity loop, driven by a random
    test torque r, with white noise n on the measured velocity and d on the plant's torque:
    tau = r - kp (v + n), v = B / A (tau + d) give
    tau = (A (r - kp n) - kp B d) / (A + kp B), v_m = (B (r + d) + A n) / (A + kp B).
    """
    bz, az, _ = signal.cont2discrete((num_c, den_c), 1.0 / RATE, method="zoh")
    bz = np.atleast_1d(np.squeeze(bz))
    az = np.atleast_1d(az)
    bz = np.pad(bz, (0, len(az) - len(bz))) if len(bz) < len(az) else bz
    cl = np.polyadd(az, kp * bz)
    assert np.all(np.abs(np.roots(cl)) < 1.0)
    rng = np.random.default_rng(seed)
    m = round(seconds * RATE)
    r = rng.normal(0.0, 0.1, m)
    n = rng.normal(0.0, noise, m)
    d = rng.normal(0.0, torque_noise, m)
    tau = signal.lfilter(az, cl, r - kp * n) - kp * signal.lfilter(bz, cl, d)
    v_m = signal.lfilter(bz, cl, r + d) + signal.lfilter(az, cl, n)
    return r, tau, v_m, bz, az


def test_frequency_response_in_closed_loop_is_unbiased() -> None:
    jm, jl = 3.7e-5, 3 * 3.7e-5
    num, den = _two_mass_tf(jm, jl, 400.0, 0.03, 1e-3)
    kp = (jm + jl) * TWO_PI * 150.0  # a stiff velocity loop: the fed-back noise matters
    r, tau, v_m, bz, az = _closed_loop_run(num, den, kp, 32.0, noise=0.5, seed=3)
    frf = frequency_response(RATE, r, tau, v_m, nperseg=4096)
    assert frf.averages > 200
    _, truth = signal.freqz(bz, az, worN=TWO_PI * frf.f_hz / RATE)
    band = (frf.f_hz > 5.0) & (frf.f_hz < 2000.0) & (frf.coherence > 0.5)
    assert band.sum() > 200
    err = np.abs(frf.g[band] / truth[band] - 1.0)
    assert np.median(err) < 0.06
    assert np.percentile(err, 95) < 0.15
    # The plain H1 estimate from the loop's own torque is biased by the fed-back noise
    # (towards -1/C where the loop gain is high), which the instrument removes.
    _, s_tv = signal.csd(tau, v_m, fs=RATE, nperseg=4096)
    _, s_tt = signal.welch(tau, fs=RATE, nperseg=4096)
    f_h1 = np.fft.rfftfreq(4096, 1 / RATE)
    h1 = (s_tv / s_tt)[np.isin(f_h1, frf.f_hz)]
    err_h1 = np.abs(h1[band] / truth[band] - 1.0)
    assert np.median(err_h1) > 4 * np.median(err)


@pytest.fixture(scope="module")
def two_mass_frf() -> Frf:
    jm, jl = 3.7e-5, 3 * 3.7e-5  # R = 3: f_ar = f_r / 2
    num, den = _two_mass_tf(jm, jl, 400.0, 0.03, 1e-4)
    kp = (jm + jl) * TWO_PI * 20.0
    r, tau, v_m, _, _ = _closed_loop_run(num, den, kp, 6.0, noise=0.5, seed=7)
    return frequency_response(RATE, r, tau, v_m, nperseg=8192)


def test_inertia_from_frf_rigid_band(two_mass_frf: Frf) -> None:
    j_true = 4 * 3.7e-5
    # Well below the 200 Hz anti-resonance the axis is one rigid inertia.
    assert inertia_from_frf(two_mass_frf, (10.0, 30.0)) == pytest.approx(j_true, rel=0.03)
    # Closer to it, the two-mass shape bends the line (25 % off at 100 Hz) ...
    j_raw = inertia_from_frf(two_mass_frf, (30.0, 110.0))
    assert j_raw > 1.08 * j_true
    # ... unless the resonance found is divided out.
    res = find_resonances(two_mass_frf, j_raw)
    j = inertia_from_frf(two_mass_frf, (30.0, 110.0), resonances=res)
    assert j == pytest.approx(j_true, rel=0.03)
    with pytest.raises(ValueError, match="coherent"):
        inertia_from_frf(two_mass_frf, (30.0, 30.5))


def test_find_resonances_two_mass(two_mass_frf: Frf) -> None:
    res = find_resonances(two_mass_frf, 4 * 3.7e-5)
    assert len(res) == 1
    r = res[0]
    assert r.freq_hz == pytest.approx(400.0, rel=0.02)
    assert r.anti_freq_hz is not None
    assert r.anti_freq_hz == pytest.approx(200.0, rel=0.02)
    assert 0.015 < r.damping_estimate < 0.06
    # Above the resonance the axis is the motor alone: (1 + R) above the rigid line, and the
    # peak stands well above that.
    assert r.peak_db > 20 * math.log10(4) + 6
    plant = plant_from_identification(4 * 3.7e-5, res, current_loop_hz=None)
    assert plant.resonance_hz == pytest.approx(400.0, rel=0.02)
    assert plant.inertia_ratio == pytest.approx(3.0, rel=0.1)
    assert plant.total_inertia == pytest.approx(4 * 3.7e-5)


def test_find_resonances_ignores_a_rigid_axis_and_noise() -> None:
    f = np.arange(1, 4000) * 2.0
    rng = np.random.default_rng(0)
    g = 1 / (1j * TWO_PI * f * 1e-4) * np.exp(-1j * TWO_PI * f * 1.25e-4) / (1 + 1j * f / 2000)
    g = g * (1 + 0.05 * rng.normal(size=len(f)))
    coh = np.full(len(f), 0.95)
    coh[rng.integers(0, len(f), 40)] = 0.1  # a few poor bins are gated out
    g[coh < 0.5] *= 10.0
    assert find_resonances(Frf(f, g, coh), 1e-4) == []


def test_plant_from_identification_rigid_and_second_mode() -> None:
    p = plant_from_identification(1e-3, [])
    assert p.resonance_hz is None and p.total_inertia == 1e-3
    res = [Resonance(300.0, 150.0, 25.0, 0.03), Resonance(900.0, None, 20.0, 0.02)]
    p = plant_from_identification(1e-3, res)
    assert p.resonance_hz == 300.0 and p.inertia_ratio == pytest.approx(3.0)
    assert len(p.extra_modes) == 1 and p.extra_modes[0].freq_hz == 900.0


def test_an_anti_resonance_below_the_band_is_placed_from_the_two_inertias() -> None:
    """A 60 Hz mode with a load 30 x the motor: its anti-resonance (10.8 Hz) lies below the 20 Hz
    where the frequency response starts, which then shows the motor alone; the test moves show
    the whole axis. The two-mass relation places the anti-resonance, and the model built from it
    splits the inertia as the machine does."""
    jm, j = 3.7e-5, 31 * 3.7e-5
    res = [Resonance(60.0, None, 15.0, 0.3), Resonance(900.0, None, 10.0, 0.02)]
    out = with_hidden_anti_resonance(res, jm, j, 20.0)
    assert out[0].anti_freq_hz == pytest.approx(60.0 / math.sqrt(31.0))
    assert out[1] == res[1]  # Only the lowest mode: the one the moves' inertia belongs to.
    p = plant_from_identification(j, out)
    assert p.motor_inertia == pytest.approx(jm) and p.total_inertia == pytest.approx(j)
    # Nothing to place: a rigid axis, inertias that agree (the moves' fit runs up to 20 % high
    # on a compliant axis), or an anti-resonance that would have been inside the band.
    assert with_hidden_anti_resonance([], jm, j, 20.0) == []
    assert with_hidden_anti_resonance(res, j, 1.2 * j, 20.0) == res
    assert with_hidden_anti_resonance(res, jm, 4 * jm, 20.0) == res  # 30 Hz: it was measured
    known = [Resonance(400.0, 200.0, 20.0, 0.03)]
    assert with_hidden_anti_resonance(known, jm, j, 20.0) == known
    # A second mode without a dip of its own is not the one the moves' inertia speaks of.
    second = [Resonance(60.0, 15.0, 15.0, 0.03), Resonance(900.0, None, 10.0, 0.02)]
    assert with_hidden_anti_resonance(second, jm, j, 20.0) == second


def test_resonance_from_record_sees_a_sharp_low_mode_that_welch_smears() -> None:
    # R = 3, 100 Hz, damping 0.03: 6 Hz wide at half power. The tuner's one-second PRBS
    # record averaged in 1/8 s segments (8 Hz bins) makes the mode look several times better
    # damped than it is; the fit over the whole record sees it as it is.
    jm, jl, zeta = 3.7e-5, 3 * 3.7e-5, 0.03
    num, den = _two_mass_tf(jm, jl, 100.0, zeta, 0.0)
    kp = (jm + jl) * TWO_PI * 15.0
    r, tau, v_m, _, _ = _closed_loop_run(num, den, kp, 1.0, noise=0.05, seed=11)
    frf = frequency_response(RATE, r, tau, v_m, nperseg=round(RATE / 8))
    found = find_resonances(frf, jm + jl, min_freq_hz=20.0)
    assert len(found) == 1 and found[0].anti_freq_hz is not None
    welch = found[0]
    assert welch.damping_estimate > 2.0 * zeta  # The smeared estimate this fixes.
    fit = resonance_from_record(RATE, r, tau, v_m, welch)
    assert fit is not None
    assert fit.freq_hz == pytest.approx(100.0, rel=0.03)
    assert fit.damping == pytest.approx(zeta, rel=0.35)
    assert fit.anti_freq_hz == pytest.approx(50.0, rel=0.03)
    # Without an anti-resonance (not a two-mass peak) there is nothing to fit.
    assert resonance_from_record(RATE, r, tau, v_m, replace(welch, anti_freq_hz=None)) is None


def test_the_record_fit_sees_a_light_low_mode_through_the_loops_own_noise() -> None:
    """A load 30 x the motor on a 60 Hz shaft of damping 0.01, measured inside a velocity loop
    with torque noise on the plant. The loop feeds that noise back into the torque it commands,
    so a fit of the velocity on that torque is biased (0.03-0.07 here, 0.10 on the tuner's
    record of such an axis, where a design trusting it left the true axis unstable); with the
    injected signal as the instrument the damping comes out near the truth. Without noise the
    record's transients (leakage) are modelled exactly: a windowed fit gave 0.018 there."""
    jm, jl, fr, zeta = 3.7e-5, 30 * 3.7e-5, 60.0, 0.01
    num, den = _two_mass_tf(jm, jl, fr, zeta, 0.0)
    kp = jm * TWO_PI * 150.0
    # The peak finder's rough guesses: a Welch peak 5 % high, the anti-resonance 10 % high.
    rough = Resonance(1.05 * fr, 1.1 * fr / math.sqrt(31.0), 20.0, 0.1)
    r, tau, v_m, _, _ = _closed_loop_run(num, den, kp, 1.0, noise=0.0, seed=0)
    clean = resonance_from_record(RATE, r, tau, v_m, rough)
    assert clean is not None
    assert clean.freq_hz == pytest.approx(fr, rel=0.002)
    assert clean.damping == pytest.approx(zeta, rel=0.03)
    assert clean.anti_freq_hz == pytest.approx(fr / math.sqrt(31.0), rel=0.01)
    assert clean.motor_inertia == pytest.approx(jm, rel=0.01)
    assert clean.total_inertia == pytest.approx(jm + jl, rel=0.02)
    for seed in (0, 1, 2):
        r, tau, v_m, _, _ = _closed_loop_run(
            num, den, kp, 1.0, noise=0.0, seed=seed, torque_noise=0.005
        )
        fit = resonance_from_record(RATE, r, tau, v_m, rough)
        assert fit is not None
        assert fit.freq_hz == pytest.approx(fr, rel=0.02)
        assert 0.7 * zeta < fit.damping < 1.5 * zeta
        assert fit.anti_freq_hz == pytest.approx(fr / math.sqrt(31.0), rel=0.03)
        # The whole axis, where the response's few rigid-body bins are too close to 0 Hz.
        assert fit.total_inertia == pytest.approx(jm + jl, rel=0.06)


def _travel_run(j: float, tc: float, g: float, seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    """A travel under a speed PI loop with a +-0.3 N m random binary torque added (the
    frequency response's test signal), torque noise and a speed set-point that ramps from 10
    to 30 rad/s: J dw/dt = tau - Tc sign(w) - g. Returns the torque command, the speed and the
    inertial share J dw / T the ramp leaves in the mean torque."""
    rng = np.random.default_rng(seed)
    n = round(RATE)
    h = 1.0 / RATE
    kv, ki = 0.05, 0.05 * 2.0 * math.pi * 20.0 * h
    test = 0.3 * rng.choice([-1.0, 1.0], n)
    w = 10.0
    integ = tc + g
    tau = np.empty(n)
    vel = np.empty(n)
    for k in range(n):
        e = 10.0 + 20.0 * k / n - w
        integ += ki * e
        u = kv * e + integ + test[k]
        tau[k] = u
        vel[k] = w
        w += h * (u + rng.normal(0.0, 0.02) - tc * math.copysign(1.0, w) - g) / j
    return tau, vel, j * (vel[-80:].mean() - vel[:80].mean()) / (n * h)


def test_travel_load_torque_is_friction_and_gravity_under_a_test_signal() -> None:
    tau, vel, inertial = _travel_run(j=4.0e-4, tc=0.09, g=0.05, seed=3)
    load = travel_load_torque(RATE, tau, vel, 4.0e-4)
    assert load == pytest.approx(0.09 + 0.05, rel=0.005)
    # The speed ramp's inertial share is what the subtraction removes: without it the mean
    # torque is several percent off.
    assert abs(inertial) > 0.03 * 0.14
    assert abs(travel_load_torque(RATE, tau, vel, 0.0) / 0.14 - 1.0) > 0.03
    # The same travel mirrored (torque and speed negated): the load torque is too.
    back = travel_load_torque(RATE, -tau, -vel, 4.0e-4)
    assert back == pytest.approx(-(0.09 + 0.05), rel=0.005)


def test_travel_load_torque_refuses_what_it_cannot_use() -> None:
    with pytest.raises(ValueError, match="sampled together"):
        travel_load_torque(RATE, np.zeros(1000), np.zeros(999), 1e-4)
    with pytest.raises(ValueError, match="at least"):
        travel_load_torque(RATE, np.zeros(100), np.zeros(100), 1e-4)


def _two_mass_moves(
    jm: float,
    jl: float,
    f_r: float,
    tc: float,
    move_s: float,
    rest_s: float,
    seed: int,
    viscous: float = 0.0,
    gravity: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Moves of 0.2 rev there and back, twice, on a motor and a load coupled by a shaft
    resonating at ``f_r``, under a collocated PD loop at 30 Hz with the demand's acceleration
    as feed-forward; Coulomb friction ``tc`` at the load (smoothed over 0.01 rad/s),
    ``viscous`` friction and a constant ``gravity`` torque there, torque noise. Semi-implicit
    Euler at 8 substeps of the 16 kHz loop. Returns the recorded torque, the motor angle and
    the demand."""
    rng = np.random.default_rng(seed)
    j = jm + jl
    k = jm * jl / j * (TWO_PI * f_r) ** 2
    c = 2.0 * 0.02 * math.sqrt(k * jm * jl / j)
    wc = TWO_PI * 30.0
    kp, kd = j * wc**2, 1.4 * j * wc
    # A smooth (cosine) acceleration profile of move_s per move.
    dist = 0.2 * TWO_PI
    n_move, n_rest = round(move_s * RATE), round(rest_s * RATE)
    s = np.arange(n_move) / n_move
    acc = dist * TWO_PI / move_s**2 * np.sin(TWO_PI * s)
    demand_a = np.concatenate(
        [np.zeros(n_rest), acc, np.zeros(n_rest), -acc] * 2 + [np.zeros(n_rest)]
    )
    demand_v = np.cumsum(demand_a) / RATE
    demand = np.cumsum(demand_v) / RATE
    sub = 8
    h = 1.0 / (RATE * sub)
    xm = wm = xl = wl = 0.0
    n = len(demand)
    tau = np.empty(n)
    pos = np.empty(n)
    for i in range(n):
        pos[i] = xm
        u = kp * (demand[i] - xm) + kd * (demand_v[i] - wm) + j * demand_a[i]
        tau[i] = u
        u += rng.normal(0.0, 0.005)
        for _ in range(sub):
            shaft = k * (xm - xl) + c * (wm - wl)
            wm += h * (u - shaft) / jm
            wl += h * (shaft - tc * math.tanh(wl / 0.01) - viscous * wl - gravity) / jl
            xm += h * wm
            xl += h * wl
    return tau, pos, demand


def test_inertia_from_moves_sees_the_whole_compliant_axis() -> None:
    jm, jl = 3.7e-5, 10 * 3.7e-5
    tau, pos, demand = _two_mass_moves(jm, jl, 400.0, 0.09, 0.04, 0.1, seed=5)
    spans = demand_spans(demand)
    assert len(spans) == 4
    there = [(a, b) for a, b in spans if demand[b] > demand[a]]
    back = [(a, b) for a, b in spans if demand[b] < demand[a]]
    for moves, load in ((there, 0.09), (back, -0.09)):
        est = inertia_from_moves(RATE, tau, pos, moves, load)
        assert est.inertia == pytest.approx(jm + jl, rel=0.01)
        assert est.spread < 0.01
        assert est.inertial_share > 0.6
    # The friction is part of the double integral: taken as none, the inertia is far off.
    assert inertia_from_moves(RATE, tau, pos, there, 0.0).inertia > 1.1 * (jm + jl)


@pytest.mark.parametrize("gravity", [0.0, 0.3])
def test_moves_back_and_forth_give_the_gravity_apart_from_the_friction(gravity: float) -> None:
    jm, jl = 3.7e-5, 3 * 3.7e-5
    tau, pos, demand = _two_mass_moves(jm, jl, 400.0, 0.09, 0.04, 0.1, seed=7, gravity=gravity)
    spans = demand_spans(demand)
    g = moves_gravity(RATE, tau, pos, spans, jm + jl)
    # Within 1 % of the friction, which the response's travel less this gravity then is.
    assert g == pytest.approx(gravity, abs=0.0009)
    # One direction alone holds friction and gravity together: refused.
    there = [(a, b) for a, b in spans if demand[b] > demand[a]]
    with pytest.raises(ValueError, match="each direction"):
        moves_gravity(RATE, tau, pos, there, jm + jl)


def test_viscous_friction_is_fitted_with_the_inertia() -> None:
    # 0.002 N m s/rad at the load: 0.05 N m more at the moves' top speed than at rest, which
    # the plain double integral books as inertia.
    jm, jl = 3.7e-5, 10 * 3.7e-5
    tau, pos, demand = _two_mass_moves(jm, jl, 400.0, 0.09, 0.04, 0.1, seed=5, viscous=0.002)
    there = [(a, b) for a, b in demand_spans(demand) if demand[b] > demand[a]]
    # The load torque as a travel at 2.5 rad/s measures it.
    est = inertia_from_moves(RATE, tau, pos, there, 0.09 + 0.002 * 2.5, load_speed=2.5)
    assert est.inertia > 1.05 * (jm + jl)
    assert est.with_viscous == pytest.approx(jm + jl, rel=0.02)
    assert est.viscous == pytest.approx(0.002, rel=0.2)
    # Without it the two agree, and the fit finds little viscous friction.
    tau, pos, demand = _two_mass_moves(jm, jl, 400.0, 0.09, 0.04, 0.1, seed=5)
    est = inertia_from_moves(RATE, tau, pos, there, 0.09, load_speed=2.5)
    assert est.with_viscous == pytest.approx(est.inertia, rel=0.03)
    assert abs(est.viscous) < 0.0005


def test_gentle_moves_against_friction_say_their_inertia_is_uncertain() -> None:
    # Four times slower: a sixteenth of the inertial torque against the same friction.
    jm, jl = 3.7e-5, 10 * 3.7e-5
    tau, pos, demand = _two_mass_moves(jm, jl, 400.0, 0.09, 0.16, 0.1, seed=5)
    there = [(a, b) for a, b in demand_spans(demand) if demand[b] > demand[a]]
    assert inertia_from_moves(RATE, tau, pos, there, 0.09).inertial_share < 0.6


def test_inertia_from_moves_refuses_what_it_cannot_use() -> None:
    with pytest.raises(ValueError, match="sampled together"):
        inertia_from_moves(RATE, np.zeros(100), np.zeros(99), [(10, 50)], 0.1)
    with pytest.raises(ValueError, match="not inside"):
        inertia_from_moves(RATE, np.zeros(100), np.zeros(100), [(10, 200)], 0.1)
    with pytest.raises(ValueError, match="does not move"):
        inertia_from_moves(RATE, np.ones(100), np.zeros(100), [(10, 50)], 0.1)
    with pytest.raises(ValueError, match="no moves"):
        inertia_from_moves(RATE, np.ones(100), np.zeros(100), [], 0.1)
    assert demand_spans(np.zeros(50)) == []
