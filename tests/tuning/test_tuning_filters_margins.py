"""Filter coefficients, margins and the loop model against textbook results."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servodesk.domain.tuning.filters import IDENTITY, lowpass_coefficients, notch_coefficients
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.model import (
    LoopModel,
    PlantModel,
    biquad_response,
    margins,
    simulate,
)

RATE = 16000.0
TWO_PI = 2.0 * math.pi


def _analog_notch(f: np.ndarray, f0: float, width: float, depth: float) -> np.ndarray:
    s = 1j * TWO_PI * f
    w = TWO_PI * f0
    z = width / 2.0
    return (s**2 + 2 * depth * z * w * s + w**2) / (s**2 + 2 * z * w * s + w**2)


def _warp(f: np.ndarray, f0: float, rate: float) -> np.ndarray:
    """Frequency of the analog prototype that the bilinear map (pre-warped at f0) puts at f."""
    k = TWO_PI * f0 / math.tan(math.pi * f0 / rate)
    return k * np.tan(math.pi * f / rate) / TWO_PI


def test_servo_gains_dict_round_trip_and_unknown_key() -> None:
    g = ServoGains(kp_pos=100.0, kp_vel=0.2, ti_vel=0.004, notch1_hz=400.0, notch1_width=0.5)
    assert ServoGains.from_dict(g.as_dict()) == g
    assert list(g.as_dict())[:3] == ["kp_pos", "kp_vel", "ti_vel"]
    assert len(g.as_dict()) == 12
    with pytest.raises(ValueError, match="kp_velo"):
        ServoGains.from_dict({"kp_velo": 1.0})
    with pytest.raises(ValueError, match="notch3_hz"):
        g.replace(notch3_hz=1.0)
    assert g.replace(kp_pos=5.0).kp_pos == 5.0
    with pytest.raises(ValueError, match="finite"):
        ServoGains.from_dict({"kp_pos": float("nan")})


def test_lowpass_is_minus_3db_at_corner_and_matches_warped_prototype() -> None:
    fc = 1000.0
    c = lowpass_coefficients(fc, RATE)
    assert c[2] == 0.0 and c[4] == 0.0
    h = biquad_response(c, np.array([TWO_PI * fc]), RATE)[0]
    assert abs(h) == pytest.approx(1.0 / math.sqrt(2.0), rel=1e-12)
    assert math.degrees(np.angle(h)) == pytest.approx(-45.0, abs=1e-9)
    f = np.geomspace(1.0, 7000.0, 200)
    fa = _warp(f, fc, RATE)
    analog = 1.0 / (1.0 + 1j * fa / fc)
    assert np.max(np.abs(biquad_response(c, TWO_PI * f, RATE) - analog)) < 1e-12
    # Low frequencies: the continuous filter, but for the pre-warp's frequency scaling of
    # tan(pi fc / rate) / (pi fc / rate) - 1 = 1.3 % at 1 kHz / 16 kHz.
    h10 = biquad_response(c, np.array([TWO_PI * 10.0]), RATE)[0]
    assert abs(h10 - 1 / (1 + 0.01j)) < 2e-4
    assert abs(h10 - 1 / (1 + 0.01j / 1.013)) < 1e-5
    assert lowpass_coefficients(0.0, RATE) == IDENTITY


@pytest.mark.parametrize(("f0", "width", "depth"), [(400.0, 0.6, 0.0), (1500.0, 0.3, 0.2)])
def test_notch_matches_analog_prototype(f0: float, width: float, depth: float) -> None:
    c = notch_coefficients(f0, width, depth, RATE)
    h0 = biquad_response(c, np.array([TWO_PI * f0]), RATE)[0]
    assert abs(h0) == pytest.approx(depth, abs=1e-12)
    f = np.geomspace(1.0, 7900.0, 400)
    ref = _analog_notch(_warp(f, f0, RATE), f0, width, depth)
    assert np.max(np.abs(biquad_response(c, TWO_PI * f, RATE) - ref)) < 1e-12
    # Unity at DC and at Nyquist, like the prototype at 0 and infinity.
    assert sum(c[:3]) / (1 + c[3] + c[4]) == pytest.approx(1.0)
    # Width: the full-depth prototype's -3 dB points are (1 -+ z) f0 apart by width * f0
    # (exactly: f2 - f1 = 2 z f0); the pre-warped discrete notch is close for f0 << rate.
    if depth == 0.0:
        ff = np.linspace(0.5 * f0, 1.5 * f0, 20001)
        mag = np.abs(biquad_response(c, TWO_PI * ff, RATE))
        inside = ff[mag < 1.0 / math.sqrt(2.0)]
        assert (inside[-1] - inside[0]) / f0 == pytest.approx(width, rel=0.03)


def test_filter_arguments_are_checked() -> None:
    with pytest.raises(ValueError, match="Nyquist"):
        lowpass_coefficients(9000.0, RATE)
    with pytest.raises(ValueError, match="depth"):
        notch_coefficients(400.0, 0.5, 1.5, RATE)
    with pytest.raises(ValueError, match="width"):
        notch_coefficients(400.0, 0.0, 0.0, RATE)


@pytest.mark.parametrize(("k", "tdelay"), [(100.0, 1e-3), (300.0, 2e-3), (1000.0, 1e-4)])
def test_margins_of_integrator_with_dead_time(k: float, tdelay: float) -> None:
    # L = K e^{-sT} / s: |L| = 1 at w = K, so PM = 90 - K T (deg); the phase reaches -180 deg at
    # w = pi / (2 T) where |L| = 2 K T / pi: GM = 20 log10(pi / (2 K T)).
    w = TWO_PI * np.geomspace(0.1, 2.0 / tdelay, 4000)
    s = 1j * w
    m = margins(w, k * np.exp(-s * tdelay) / s)
    assert m.phase_margin_deg == pytest.approx(90.0 - math.degrees(k * tdelay), abs=0.05)
    assert m.gain_margin_db == pytest.approx(20 * math.log10(math.pi / (2 * k * tdelay)), abs=0.02)
    assert m.crossover_hz == pytest.approx(k / TWO_PI, rel=1e-3)
    assert m.phase_crossover_hz == pytest.approx(1.0 / (4.0 * tdelay), rel=1e-3)
    # M_s = 1 / min |1 + L|, checked on a much finer grid.
    wf = TWO_PI * np.geomspace(0.1, 2.0 / tdelay, 200000)
    ms = -20 * math.log10(np.min(np.abs(1 + k * np.exp(-1j * wf * tdelay) / (1j * wf))))
    assert m.ms_db == pytest.approx(ms, abs=0.01)


def test_margins_take_the_worst_of_several_crossings() -> None:
    # A resonant bump above the first crossover makes two more gain crossings; the PM is the
    # worst of the three and the crossover is the one that sets it.
    w = TWO_PI * np.geomspace(1.0, 1e4, 20000)
    s = 1j * w
    wr = TWO_PI * 1000.0
    base = 200.0 / s * np.exp(-s * 2e-4)
    bump = 1 + 60 * (2 * 0.02 * wr * s) / (s**2 + 2 * 0.02 * wr * s + wr**2)
    m = margins(w, base * bump)
    f = w / TWO_PI
    lm = np.abs(base * bump)
    cross = np.nonzero(np.diff(np.sign(lm - 1)))[0]
    assert len(cross) == 3
    pms = [180 - abs(math.degrees(np.angle((base * bump)[i]))) for i in cross]
    assert m.phase_margin_deg == pytest.approx(min(pms), abs=0.5)
    assert m.crossover_hz == pytest.approx(f[cross[int(np.argmin(pms))]], rel=0.01)
    assert m.crossover_hz > 500.0


def test_discrete_plant_has_two_samples_of_dead_time() -> None:
    # Measured velocity / torque = current loop x mechanics x e^{-s 2T} (1 sample compute,
    # half a sample ZOH, half a sample differencing) up to the ZOH / difference sinc magnitudes.
    plant = PlantModel(3.7e-5, 3.7e-4, 400.0, 0.03, viscous=1e-4)
    loop = LoopModel(plant, RATE)
    f = np.array([10.0, 100.0, 300.0, 1000.0])
    w = TWO_PI * f
    ref = plant.response(w) / (1 + 1j * f / 2000.0) * np.exp(-1j * w * 2 / RATE)
    ratio = loop.plant_response(w) / ref
    assert np.max(np.abs(np.angle(ratio, deg=True))) < 0.01
    assert np.max(np.abs(np.abs(ratio) - 1)) < 0.015
    half = LoopModel(plant, RATE, compute_delay=0.5).plant_response(w) / loop.plant_response(w)
    assert np.angle(half, deg=True) == pytest.approx(360 * f * 0.5 / RATE, abs=0.01)


def test_two_mass_response_has_its_anti_resonance_and_resonance() -> None:
    plant = PlantModel(3.7e-5, 3 * 3.7e-5, 400.0, 0.03)
    assert plant.anti_resonance_hz == pytest.approx(200.0)
    f = np.linspace(100.0, 600.0, 50001)
    mag = np.abs(plant.response(TWO_PI * f))
    assert f[np.argmin(mag)] == pytest.approx(200.0, rel=0.005)
    assert f[np.argmax(mag * f)] == pytest.approx(400.0, rel=0.01)


def test_a_load_damper_turns_the_axis_into_a_motor_on_a_spring() -> None:
    # The stuck-load models (search.stuck_load_set): with a damper from the load to the frame
    # the continuous state space still matches the response, and a very large one holds the
    # load, leaving the motor on its shaft: s / (J_M s^2 + c s + k).
    free = PlantModel(3.7e-5, 3.7e-4, 300.0, 0.05, 1e-4, None)
    k, c = free.stiffness, free.shaft_damping
    w = TWO_PI * np.geomspace(5.0, 5000.0, 40)
    for bl in (0.0, 0.05, 5.0):
        plant = replace(free, load_viscous=bl)
        a, bu, _bw, cc = plant.state_space()
        ss = np.array([cc @ np.linalg.solve(1j * x * np.eye(len(a)) - a, bu) * 1j * x for x in w])
        assert np.max(np.abs(ss / plant.response(w) - 1.0)) < 1e-9
    held = replace(free, load_viscous=1e6).response(w)
    s = 1j * w
    assert np.max(np.abs(held / (s / (3.7e-5 * s**2 + (c + 1e-4) * s + k)) - 1.0)) < 1e-3
    with pytest.raises(ValueError):
        PlantModel(3.7e-5, 3.7e-4, load_viscous=0.1)  # No shaft: nothing to hold.
    with pytest.raises(ValueError):
        replace(free, load_viscous=-1.0)


def _gains(plant: PlantModel, fv: float) -> ServoGains:
    wv = TWO_PI * fv
    kv = plant.total_inertia * wv
    return ServoGains(kp_pos=wv / 4, kp_vel=kv, ti_vel=4 / wv, torque_lpf_hz=1500.0)


def test_state_space_matches_frequency_response() -> None:
    # The closed-loop matrices (stability, simulation) and the loop transfer functions
    # (margins) are built separately; the position step response of both must agree.
    plant = PlantModel(3.7e-5, 3.7e-4, 300.0, 0.05)
    g = _gains(plant, 40.0).replace(notch1_hz=300.0, notch1_width=0.5, notch1_depth=0.1)
    loop = LoopModel(plant, RATE, g, compute_delay=1.5)
    cl = loop.closed_loop()
    w = TWO_PI * np.geomspace(1.0, 7000.0, 60)
    z = np.exp(1j * w / RATE)
    n = cl.a.shape[0]
    x = np.linalg.solve(
        z[:, None, None] * np.eye(n) - cl.a, np.broadcast_to(cl.b[:, :1], (len(z), n, 1))
    )
    h = (cl.c[0] @ x)[:, 0] + cl.d[0, 0]
    lp = loop.position_open_loop(w)
    assert np.max(np.abs(h - lp / (1 + lp))) < 1e-8


def test_is_stable_detects_unstable_gains() -> None:
    plant = PlantModel(3.7e-5, 3.7e-4)
    stable = LoopModel(plant, RATE, _gains(plant, 150.0))
    assert stable.is_stable()
    assert stable.velocity_margins().stable
    # Far beyond the ceiling (PM < 0): unstable, and the margins say so.
    too_fast = LoopModel(plant, RATE, _gains(plant, 2500.0))
    assert not too_fast.is_stable()
    assert too_fast.velocity_margins().stable is False
    assert not too_fast.velocity_margins().meets()
    # A two-mass axis tuned on its total inertia crosses over in the motor-only region with
    # (1 + R) times the gain (anchors-tuning.md §2.1): unstable at a gain fine for rigid.
    soft = LoopModel(PlantModel(3.7e-5, 3.7e-4, 400.0, 0.03), RATE, _gains(plant, 150.0))
    assert not soft.is_stable()
    # The linear simulation agrees: bounded vs. growing.
    p = np.full(4000, 1e-3)
    assert np.max(np.abs(simulate(stable, p)[0][-200:] - 1e-3)) < 1e-5
    assert np.max(np.abs(simulate(soft, p)[0][-200:])) > 1.0


def test_low_pass_far_below_crossover_is_flagged_not_trusted() -> None:
    # Phase-wise this loop "looks" fine at its crossover, but a 60 Hz low-pass under a 1 kHz
    # crossover turns the phase through -180 deg at high gain: unstable.
    plant = PlantModel(3.7e-5, 3.7e-5 * 30)
    loop = LoopModel(plant, RATE, _gains(plant, 1600.0).replace(ti_vel=0.0, torque_lpf_hz=60.0))
    m = loop.velocity_margins()
    assert m.left_crossings > 0
    assert m.stable is False
    assert not m.meets()


def test_plant_response_cache_gives_the_solved_response_read_only(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A design search checks every candidate's margins on the same plants and grids: the
    plant's response is kept, and must be exactly what solving it again gives, per plant (two
    axes on the same grid are two entries: a shared one would check the margins of the wrong
    axis) and per grid."""
    from servodesk.domain.tuning import model as loop_model

    monkeypatch.setattr(loop_model, "_responses", {})
    light, heavy = PlantModel(1.5e-4), PlantModel(1.6e-4)  # Rigid: the same grid.
    soft = PlantModel(3.7e-5, 1.1e-4, 400.0, 0.03)
    axes = (light, heavy, soft)
    gains = ServoGains(kp_pos=200.0, kp_vel=0.3, ti_vel=0.004, notch1_hz=400.0, notch1_width=0.5)
    assert np.array_equal(LoopModel(light, RATE, gains).grid, LoopModel(heavy, RATE, gains).grid)
    first = {p: LoopModel(p, RATE, gains).position_plant_response() for p in axes}
    again = {p: LoopModel(p, RATE, gains).position_plant_response() for p in axes}
    kept = {p: LoopModel(p, RATE, gains).velocity_margins() for p in axes}
    other = LoopModel(soft, RATE, replace(gains, notch1_hz=300.0))
    other_kept = other.position_plant_response()
    monkeypatch.setattr(loop_model, "RESPONSE_CACHE_SIZE", 0)
    solved = {p: LoopModel(p, RATE, gains).position_plant_response() for p in axes}
    for p in axes:
        assert again[p] is first[p]
        np.testing.assert_array_equal(first[p], solved[p])
        assert kept[p] == LoopModel(p, RATE, gains).velocity_margins()
        with pytest.raises(ValueError):
            first[p][0] = 0.0
    assert not np.array_equal(first[light], first[heavy])
    np.testing.assert_array_equal(other_kept, other.position_plant_response())
