"""The plant: mechanics, friction, torque limit, current lag, encoder."""

from __future__ import annotations

import math
import statistics

import pytest

from servodesk.model.plant import Plant, PlantParams

FRICTIONLESS = PlantParams(viscous=0.0, coulomb=0.0, current_tau=0.0)


def test_constant_torque_accelerates_by_t_over_j_and_conserves_energy() -> None:
    p = Plant(FRICTIONLESS)
    torque, dt, n = 0.5, 1e-4, 1000
    work = 0.0
    for _ in range(n):
        w0 = p.velocity_rad
        p.step(torque, dt)
        work += torque * 0.5 * (w0 + p.velocity_rad) * dt
    j = FRICTIONLESS.inertia
    assert p.velocity_rad == pytest.approx(torque / j * n * dt, rel=1e-9)
    assert 0.5 * j * p.velocity_rad**2 == pytest.approx(work, rel=1e-3)
    assert p.position_rad == pytest.approx(0.5 * torque / j * (n * dt) ** 2, rel=1e-2)


def test_viscous_friction_limits_velocity_to_torque_over_b() -> None:
    params = PlantParams(viscous=1e-3, coulomb=0.0, current_tau=0.0)
    p = Plant(params)
    for _ in range(20000):
        p.step(0.01, 1e-4)
    assert p.velocity_rad == pytest.approx(0.01 / 1e-3, rel=1e-3)


def test_coulomb_friction_holds_below_and_stops_a_coasting_axis() -> None:
    params = PlantParams(viscous=0.0, coulomb=0.05, current_tau=0.0)
    p = Plant(params)
    for _ in range(100):
        p.step(0.049, 1e-4)
    assert p.velocity_rad == 0.0 and p.position_rad == 0.0
    for _ in range(100):
        p.step(0.2, 1e-4)
    assert p.velocity_rad > 0
    for _ in range(5000):
        p.step(0.0, 1e-4)
    assert p.velocity_rad == 0.0  # Stopped, and stays stopped (no chatter around zero).
    pos = p.position_rad
    p.step(0.0, 1e-4)
    assert p.position_rad == pos


def test_torque_is_limited_to_peak() -> None:
    p = Plant(FRICTIONLESS)
    p.step(100.0, 1e-4)
    assert p.torque == pytest.approx(FRICTIONLESS.peak_torque)
    assert p.torque_limited
    p.step(-100.0, 1e-4)
    assert p.torque == pytest.approx(-FRICTIONLESS.peak_torque)
    p.step(1.0, 1e-4)
    assert not p.torque_limited


def test_current_loop_is_a_first_order_lag() -> None:
    params = PlantParams(current_tau=2e-4)
    p = Plant(params)
    steps = 20
    for _ in range(steps):
        p.step(1.0, 1e-5)  # 200 µs = one time constant.
    assert p.torque == pytest.approx(1.0 - math.exp(-1.0), rel=1e-6)


def test_dead_time_delays_the_torque() -> None:
    p = Plant(PlantParams(current_tau=0.0, dead_time=1e-3, coulomb=0.0))
    for _ in range(9):
        p.step(1.0, 1e-4)
    assert p.torque == 0.0
    for _ in range(2):
        p.step(1.0, 1e-4)
    assert p.torque == 1.0


def test_encoder_is_quantised_to_counts() -> None:
    p = Plant(PlantParams(counts_per_rev=1000))
    p.set_position_counts(10.7)
    assert p.encoder_counts == 10
    p.set_position_counts(-0.3)
    assert p.encoder_counts == -1
    p.set_position_counts(1000.0)
    assert p.position_rad == pytest.approx(2 * math.pi)
    assert p.encoder_counts == 1000


def test_encoder_noise_option() -> None:
    p = Plant(PlantParams(noise_counts=3.0, seed=1))
    p.set_position_counts(1000.5)
    samples = [p.encoder_counts for _ in range(2000)]
    assert statistics.pstdev(samples) == pytest.approx(3.0, rel=0.15)
    assert statistics.mean(samples) == pytest.approx(1000.0, abs=0.5)
