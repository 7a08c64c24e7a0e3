"""The fused tick loop (model/fused.py) computes exactly what the servo loop and the plant compute
call by call (model/replay.py ``run_move_stepwise``): the tuning ranks its candidates and the
benchmark's oracle is chosen with it, so a difference of one count would move both."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.search import ReferenceMove, reference_move
from servodesk.model import fused, replay
from servodesk.model.fused import applies, fused_move
from servodesk.model.plant import PlantParams
from servodesk.model.replay import RecordedMove

RATE = 16000.0
COUNTS = 1 << 20

#: A two-mass axis as a plant file gives it (exact integration, a current-loop bandwidth),
#: with Coulomb friction on the load, so the load sticks at the end of the move.
TWO_MASS = PlantParams(
    motor_inertia=3.7e-5,
    load_inertia=3.7e-4,
    viscous=0.0,
    coulomb=0.09,
    peak_torque=4.46,
    counts_per_rev=COUNTS,
    current_loop_hz=2000.0,
    resonance_hz=200.0,
    damping=0.03,
    exact=True,
)
RIGID = replace(TWO_MASS, resonance_hz=None, viscous=2e-4)

#: A design like the tuner's for the two-mass axis: notch at the resonance, a second one and
#: a low-pass, so every filter stage runs.
FILTERED = ServoGains(
    kp_pos=120.0,
    kp_vel=0.12,
    ti_vel=0.004,
    vel_ff=1.0,
    inertia_ff=3.4e-4,
    torque_lpf_hz=1500.0,
    notch1_hz=200.0,
    notch1_width=0.3,
    notch1_depth=0.3,
    notch2_hz=900.0,
    notch2_width=0.5,
    notch2_depth=0.0,
)
PLAIN = ServoGains(kp_pos=80.0, kp_vel=0.05, ti_vel=0.008, vel_ff=1.0, inertia_ff=4.0e-4)


def _move(params: PlantParams, torque: float, hold_s: float = 0.15) -> ReferenceMove:
    return reference_move(params.inertia, torque, params.counts_per_rev, RATE, hold_s=hold_s)


def _both(
    params: PlantParams, gains: ServoGains, limit: float, move: ReferenceMove
) -> tuple[np.ndarray, np.ndarray]:
    fused = replay.run_move(params, gains, RATE, limit, move)
    stepwise = replay.run_move_stepwise(params, gains, RATE, limit, move)
    return fused, stepwise


@pytest.mark.parametrize(
    ("params", "gains"),
    [
        (TWO_MASS, FILTERED),
        (TWO_MASS, PLAIN),
        (replace(TWO_MASS, gravity=0.4, viscous=1e-4), FILTERED),
        (replace(TWO_MASS, coulomb=0.0), PLAIN),
        (RIGID, PLAIN),
        (replace(RIGID, gravity=0.5), FILTERED),
        (replace(RIGID, exact=False, current_loop_hz=None, current_tau=0.0), PLAIN),
    ],
    ids=[
        "two-mass-filters",
        "two-mass-plain",
        "two-mass-gravity",
        "two-mass-frictionless",
        "rigid",
        "rigid-gravity",
        "rigid-semi-implicit",
    ],
)
def test_the_fused_loop_gives_the_stepwise_positions_to_the_count(
    params: PlantParams, gains: ServoGains
) -> None:
    move = _move(params, 3.0)
    fused, stepwise = _both(params, gains, 4.46, move)
    assert fused.shape == stepwise.shape == move.p.shape
    # Every tick equal, not close: float for float the same operations.
    assert np.array_equal(fused, stepwise)
    # The move went somewhere and came to rest near the target (the cases are not trivial).
    assert abs(fused[-1] - move.target_counts) < 0.01 * COUNTS


def test_the_fused_loop_matches_where_the_torque_clamp_and_the_integral_hold_act() -> None:
    # A torque limit far below what the move asks for: the loop saturates through the
    # acceleration and the conditional integration holds the integral.
    move = _move(TWO_MASS, 3.0)
    fused, stepwise = _both(TWO_MASS, FILTERED, 0.6, move)
    assert np.array_equal(fused, stepwise)


def test_numpy_scalars_in_the_model_give_the_same_positions() -> None:
    # An identified model carries numpy scalars; the fused loop turns them into floats.
    params = replace(
        TWO_MASS,
        motor_inertia=np.float64(TWO_MASS.motor_inertia),
        load_inertia=np.float64(TWO_MASS.load_inertia),
        coulomb=np.float64(TWO_MASS.coulomb),
    )
    gains = replace(FILTERED, inertia_ff=np.float64(3.4e-4), ti_vel=np.float64(0.004))
    move = _move(params, 3.0)
    fused, stepwise = _both(params, gains, 4.46, move)
    assert np.array_equal(fused, stepwise)
    assert np.array_equal(fused, replay.run_move(TWO_MASS, FILTERED, RATE, 4.46, move))


def test_a_loop_that_stops_being_finite_reads_nan_from_that_tick_on_both_ways() -> None:
    move = _move(TWO_MASS, 3.0)
    broken = replace(PLAIN, inertia_ff=math.inf)
    fused, stepwise = _both(TWO_MASS, broken, math.inf, move)
    first = int(np.argmax(np.isnan(fused)))
    assert np.isnan(fused[first:]).all() and np.isfinite(fused[:first]).all()
    assert first > 0
    assert np.array_equal(fused, stepwise, equal_nan=True)


def test_a_noisy_plant_takes_the_stepwise_path() -> None:
    noisy = replace(TWO_MASS, torque_noise=0.02, seed=3)
    assert not applies(noisy)
    move = _move(noisy, 3.0)
    assert fused_move(noisy, PLAIN, RATE, 4.46, [0.0], [0.0], [0.0]) is None
    assert np.array_equal(
        replay.run_move(noisy, PLAIN, RATE, 4.46, move),
        replay.run_move_stepwise(noisy, PLAIN, RATE, 4.46, move),
    )
    # The noise is in: the same move without it ends elsewhere.
    quiet = replay.run_move(TWO_MASS, PLAIN, RATE, 4.46, move)
    assert not np.array_equal(quiet, replay.run_move(noisy, PLAIN, RATE, 4.46, move))


def test_the_tick_loop_runs_compiled() -> None:
    # numba is a dependency: without it every tuning's ranking would run the loop as Python,
    # over twenty times slower (bench/bench_replay.py), and nothing else would say so.
    assert fused.COMPILED
    move = _move(TWO_MASS, 3.0)
    replay.run_move(TWO_MASS, FILTERED, RATE, 4.46, move)
    assert fused._compiled is not None and fused._compiled.signatures


@pytest.mark.parametrize(
    ("params", "gains", "limit", "hold"),
    [
        (TWO_MASS, FILTERED, 4.46, 0),
        (TWO_MASS, FILTERED, 0.6, 40),
        (replace(TWO_MASS, gravity=0.4), PLAIN, 4.46, 0),
        (RIGID, PLAIN, 4.46, 25),
        (replace(RIGID, exact=False, current_loop_hz=None, current_tau=0.0), FILTERED, 4.46, 0),
        (TWO_MASS, replace(PLAIN, inertia_ff=math.inf), math.inf, 0),
    ],
    ids=[
        "two-mass",
        "two-mass-clamped-held",
        "two-mass-gravity",
        "rigid-held",
        "rigid-semi",
        "nan",
    ],
)
def test_the_compiled_loop_gives_the_python_loops_positions_to_the_bit(
    params: PlantParams, gains: ServoGains, limit: float, hold: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The same source runs compiled and as Python; no fast-math, so no fused multiply-add or
    # reordering may change a bit (a count moved would move the tuning's ranking).
    move = _move(params, 3.0)
    args = (params, gains, RATE, limit, list(move.p), list(move.v), list(move.a), hold)
    compiled = fused_move(*args)
    monkeypatch.setattr(fused, "COMPILED", False)
    python = fused_move(*args)
    assert compiled is not None and python is not None
    assert np.array_equal(compiled, python, equal_nan=True)


def _recorded(gains: ServoGains, *, offset: float, hold: float, distance: float) -> RecordedMove:
    """A try's move as the tuning records it (services/tuning_calibrate.recorded_move): only
    its length and the generator's inputs matter to a replay."""
    return RecordedMove(
        gains=gains,
        distance=distance,
        velocity=2.0e6,
        acc=1.5e8,
        offset=offset,
        hold_torque=hold,
        torque_limit=4.46,
        position=np.zeros(int(0.3 * RATE)),
    )


@pytest.mark.parametrize(
    ("params", "move"),
    [
        (TWO_MASS, _recorded(FILTERED, offset=-3.0, hold=0.05, distance=262144.0)),
        (TWO_MASS, _recorded(PLAIN, offset=2.0, hold=-0.08, distance=-262144.0)),
        (replace(TWO_MASS, gravity=0.3), _recorded(FILTERED, offset=0.0, hold=0.3, distance=1e5)),
        (RIGID, _recorded(PLAIN, offset=5.0, hold=0.02, distance=262144.0)),
    ],
    ids=["two-mass-filtered", "two-mass-back", "two-mass-gravity", "rigid"],
)
def test_a_recorded_move_replays_fused_as_it_does_stepwise(
    params: PlantParams, move: RecordedMove
) -> None:
    # The fit of the inertias to a try (services/tuning/calibrate.py) replays its moves some
    # 80 times; the fused loop must give the per-cycle path's positions to the count, from the
    # rest the recording found the axis in (the integral holding a torque, the shaft wound).
    fused_pos = replay.run_recorded_move(params, move, RATE)
    stepwise = replay.run_recorded_move_stepwise(params, move, RATE)
    assert len(fused_pos) == len(stepwise) == len(move.position)
    assert np.array_equal(fused_pos, stepwise)
    # It moved: the replay ends near the target, not where it started.
    assert abs(fused_pos[-1] - move.offset - move.distance) < 0.05 * abs(move.distance)
