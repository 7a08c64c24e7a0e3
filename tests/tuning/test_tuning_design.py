"""Gain design, the benchmark move and its metrics, and the oracle."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from servodesk.domain.tuning.design import design_gains
from servodesk.domain.tuning.metrics import (
    MoveMetrics,
    jerk_limited_profile,
    move_metrics,
    profile_duration,
    simulate_move,
    smoothed_settling,
    step_response,
)
from servodesk.domain.tuning.model import LoopModel, PlantModel
from servodesk.domain.tuning.oracle import linear_simulator, oracle_search

RATE = 16000.0
JM = 3.7e-5
TWO_PI = 2.0 * math.pi


def _check_margins(plant: PlantModel, gains: object) -> None:
    from servodesk.domain.tuning.gains import ServoGains

    assert isinstance(gains, ServoGains)
    loop = LoopModel(plant, RATE, gains)
    vm = loop.velocity_margins()
    pm = loop.position_margins()
    assert vm.stable and pm.stable
    assert vm.phase_margin_deg >= 45.0 and vm.gain_margin_db >= 8.0 and vm.ms_db <= 6.0
    assert pm.phase_margin_deg >= 45.0 and pm.gain_margin_db >= 8.0 and pm.ms_db <= 6.0
    assert vm.left_crossings == 0 and pm.left_crossings == 0


PLANTS = [PlantModel(JM, JM * r) for r in (1.0, 10.0, 30.0)] + [
    PlantModel(JM, JM * r, fr, 0.03) for r in (1.0, 3.0, 10.0, 30.0) for fr in (100, 400, 800)
]


@pytest.mark.wallclock  # Each design is also timed (under 2 s).
@pytest.mark.parametrize(
    "plant",
    PLANTS,
    ids=lambda p: f"R{p.inertia_ratio:g}-{p.resonance_hz or 'rigid'}",
)
def test_design_meets_margins_and_levels_are_ordered(plant: PlantModel) -> None:
    bws = []
    for level in ("high", "basic", "low"):
        t0 = time.perf_counter()
        d = design_gains(plant, RATE, level)
        assert time.perf_counter() - t0 < 2.0  # ~0.1-0.2 s on one idle core
        _check_margins(plant, d.gains)
        assert d.margins.meets() and d.position_margins.meets()
        # The design also holds on the uncertainty set it was made for.
        assert d.worst_margins.phase_margin_deg >= 45.0
        assert d.gains.vel_ff == 1.0 and 0.0 < d.gains.inertia_ff <= plant.total_inertia
        assert d.gains.ti_vel > 0.0 and d.gains.kp_pos > 0.0
        bws.append(d.bandwidth_hz)
    assert bws[0] > bws[1] > bws[2] > 0.0


def test_design_is_robust_to_the_identification_tolerance() -> None:
    # Designed on a model whose resonance and inertia are 3 % off the true plant's.
    true = PlantModel(JM, 3 * JM, 400.0, 0.03)
    for model in (
        PlantModel(JM, 3 * JM, 412.0, 0.03),
        PlantModel(JM, 3 * JM, 388.0, 0.03),
        PlantModel(1.03 * JM, 3.09 * JM, 400.0, 0.03),
    ):
        _check_margins(true, design_gains(model, RATE).gains)


def test_rigid_bandwidth_near_the_analytic_ceiling() -> None:
    # anchors-tuning.md §2.5: 423 Hz for PM 45 with Ti = 4 / w_v at 16 kHz, T_d = 2 T, 2 kHz
    # current loop (nominal bandwidth K_v / (2 pi J)).
    d = design_gains(PlantModel(JM, JM), RATE)
    assert 360.0 < d.nominal_bandwidth_hz < 520.0


def test_notch_is_used_where_it_pays_and_skipped_where_it_does_not() -> None:
    # A high resonance with a large ratio: a notch at f_r raises the bandwidth.
    hi = design_gains(PlantModel(JM, 3 * JM, 800.0, 0.03), RATE)
    assert hi.gains.notch1_hz == pytest.approx(800.0)
    # R = 1 with f_r = 100 Hz, far below the achievable crossover (anchors §2.4, §3.6):
    # notching it costs more phase than it removes.
    lo = design_gains(PlantModel(JM, JM, 100.0, 0.03), RATE)
    assert lo.gains.notch1_hz == 0.0


def test_design_for_a_requested_bandwidth() -> None:
    plant = PlantModel(JM, 10 * JM)
    d = design_gains(plant, RATE, 100.0)
    assert d.bandwidth_hz == pytest.approx(100.0, rel=0.1)
    _check_margins(plant, d.gains)
    with pytest.raises(ValueError, match="response"):
        design_gains(plant, RATE, "medium")


# ----------------------------------------------------------------------------------------------
# Profile and metrics


@pytest.mark.parametrize(
    ("dist", "vmax", "amax", "tj"),
    [
        (math.pi, 314.0, 8.4e4, 0.002),  # the §3.2 move at R = 1: trapezoid
        (-math.pi, 314.0, 2.7e3, 0.002),  # R = 30, negative: triangle (v_max not reached)
        (1e-3, 10.0, 100.0, 0.005),  # tiny move, ramps longer than the acceleration
        (2.0, 5.0, 50.0, 0.0),  # no jerk limit
    ],
)
def test_jerk_limited_profile(dist: float, vmax: float, amax: float, tj: float) -> None:
    prof = jerk_limited_profile(dist, vmax, amax, tj, RATE, hold_s=0.01)
    t_end = profile_duration(dist, vmax, amax, tj)
    assert prof.p[0] == 0.0 and prof.v[0] == 0.0
    assert prof.p[-1] == dist  # exactly
    assert np.all(prof.p[prof.t >= t_end] == dist)
    assert np.max(np.abs(prof.v)) <= vmax * (1 + 1e-12)
    assert np.max(np.abs(prof.a)) <= amax * (1 + 1e-12)
    # Monotonic towards the target, and the arrays are consistent derivatives.
    assert np.all(np.diff(prof.p) * np.sign(dist) >= -1e-15)
    dt = 1.0 / RATE
    assert np.allclose(np.diff(prof.p) / dt, 0.5 * (prof.v[1:] + prof.v[:-1]), atol=vmax * 1e-3)
    if tj > 0.0:
        assert np.max(np.abs(np.diff(prof.a))) <= amax / tj * dt * (1 + 1e-9)
        assert np.allclose(np.diff(prof.v) / dt, 0.5 * (prof.a[1:] + prof.a[:-1]), atol=amax * 0.02)


def test_move_metrics_on_hand_made_arrays() -> None:
    t = np.arange(11) * 0.01  # 0 .. 0.1 s
    demand = np.array([0, 100, 300, 500, 500, 500, 500, 500, 500, 500, 500], dtype=float)
    pos = np.array([0, 90, 270, 480, 530, 508, 495, 502, 500, 499, 500], dtype=float)
    m = move_metrics(t, 500.0, pos, t_end=0.03, demand=demand)
    # |e| > 10: samples at 0.03 (-20), 0.04 (+30); the last is 0.04 -> 0.01 s after t_end.
    assert m.settling_10_s == pytest.approx(0.01)
    # |e| > 100: last at 0.02 (-230), before t_end -> 0.
    assert m.settling_100_s == 0.0
    assert m.overshoot_counts == pytest.approx(30.0)
    fe = np.array([0, 10, 30, 20])
    assert m.fe_rms_counts == pytest.approx(math.sqrt(np.mean(fe**2)))
    assert m.fe_max_counts == pytest.approx(30.0)
    # Not settled by the end of the record: infinite.
    pos2 = pos.copy()
    pos2[-1] = 520.0
    assert move_metrics(t, 500.0, pos2, 0.03, demand).settling_10_s == math.inf
    # A negative move: overshoot is measured in the direction of motion.
    m3 = move_metrics(t, -500.0, -pos, 0.03, -demand)
    assert m3.overshoot_counts == pytest.approx(30.0)
    assert m3.key() == (m3.settling_10_s, m3.settling_100_s, m3.fe_rms_counts)
    assert math.isnan(move_metrics(t, 500.0, pos, 0.03).fe_rms_counts)


def test_smoothed_settling_sees_through_jitter_but_not_a_slow_approach() -> None:
    rate = 16000.0
    t = np.arange(int(0.5 * rate)) / rate
    rng = np.random.default_rng(1)
    jitter = 25.0 * np.sign(rng.standard_normal(len(t)))  # +-25 counts, zero mean
    # Settles (exponentially, tau 10 ms) from 2000 counts off at t_end = 0.1 s.
    approach = np.where(t < 0.1, 2000.0, 2000.0 * np.exp(-(t - 0.1) / 0.01))
    pos = 1000.0 + approach + jitter
    # The plain figure: the jitter keeps leaving +-10 counts to the end of the record.
    assert move_metrics(t, 1000.0, pos, 0.1).settling_10_s == math.inf
    # The 5 ms mean: in the band once the approach is (ln(2000/10) tau = 53 ms), give or take
    # the window and the residual jitter of the mean.
    s = smoothed_settling(t, 1000.0, pos, 0.1)
    assert 0.045 < s < 0.065
    # A constant offset is not jitter: never settled.
    assert smoothed_settling(t, 1000.0, pos + 30.0, 0.1) == math.inf


def test_a_settling_the_record_ends_within_holds_out_counts_as_not_settled() -> None:
    # A try on a heavy axis: its 5 ms mean jitters by about +-15 counts at rest, so its last
    # crossing of +-10 counts is wherever the noise put it, a few ms before the record ends.
    rate = 16000.0
    t = np.arange(int(0.8 * rate)) / rate
    rng = np.random.default_rng(3)
    slow = np.convolve(rng.standard_normal(len(t) + 400), np.ones(400) / 20.0, "valid")[: len(t)]
    pos = 1000.0 + 15.0 * slow / np.std(slow)
    last_noise = smoothed_settling(t, 1000.0, pos, 0.1)
    assert 0.6 < last_noise < math.inf  # the plain rule reads that as settled
    assert smoothed_settling(t, 1000.0, pos, 0.1, hold_s=0.1) == math.inf
    # A real settling, 0.35 s before the end, stands.
    calm = 1000.0 + np.where(t < 0.3, 500.0, 0.0)
    assert smoothed_settling(t, 1000.0, calm, 0.1, hold_s=0.1) == pytest.approx(0.205, abs=0.001)


def test_linear_move_settles_with_the_design() -> None:
    plant = PlantModel(JM, 3 * JM)
    d = design_gains(plant, RATE)
    m = linear_simulator(plant, RATE)(d.gains)
    assert isinstance(m, MoveMetrics)
    assert m.settling_10_s < 0.01
    assert m.overshoot_counts < 10.0
    # Without feed-forward the following error is much larger.
    prof = jerk_limited_profile(math.pi, 314.0, 0.7 * 4.46 / plant.total_inertia, 0.002, RATE, 0.1)
    t_end = profile_duration(math.pi, 314.0, 0.7 * 4.46 / plant.total_inertia, 0.002)
    no_ff = d.gains.replace(vel_ff=0.0, inertia_ff=0.0)
    m2 = simulate_move(LoopModel(plant, RATE, no_ff), prof, t_end)
    assert m2.fe_rms_counts > 5 * m.fe_rms_counts


def test_step_response_of_a_design() -> None:
    plant = PlantModel(JM, 10 * JM)
    loop = LoopModel(plant, RATE, design_gains(plant, RATE).gains)
    t, theta = step_response(loop, 1e-3, 0.05)
    assert len(t) == len(theta) == 800
    assert theta[0] == 0.0
    assert abs(theta[-1] - 1e-3) < 1e-6
    assert np.max(theta) < 1.5e-3  # position PM >= 45 deg: bounded overshoot


# ----------------------------------------------------------------------------------------------
# Oracle


def test_oracle_without_callback_ranks_by_bandwidth() -> None:
    plant = PlantModel(JM, 3 * JM, 400.0, 0.03)
    o = oracle_search(plant, RATE)
    _check_margins(plant, o.gains)
    d = design_gains(plant, RATE)
    assert o.bandwidth_hz >= d.bandwidth_hz
    assert math.isnan(o.settling_10_s) and o.metrics is None and o.n_simulated == 0


def test_oracle_with_a_simulation_is_at_least_as_good_as_the_design() -> None:
    plant = PlantModel(JM, 10 * JM)
    sim = linear_simulator(plant, RATE)
    calls: list[float] = []

    def counted(g: object) -> MoveMetrics:
        calls.append(1.0)
        return sim(g)  # type: ignore[arg-type]

    o = oracle_search(plant, RATE, counted, max_simulations=12)
    _check_margins(plant, o.gains)
    assert o.n_simulated == len(calls) <= 12
    assert o.metrics is not None
    assert o.metrics.key() <= sim(design_gains(plant, RATE).gains).key()
    assert o.settling_10_s == o.metrics.settling_10_s
