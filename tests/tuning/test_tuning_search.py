"""The tuner's ranking step: friction that sticks in the batch simulation, the identification
set, and the ranking itself (domain/tuning/simulate.py, domain/tuning/search.py)."""

from __future__ import annotations

import math
import pickle
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from servodesk.benchmarks.tuning import plant_names, true_plant_metrics
from servodesk.domain.tuning.design import FF_FACTOR, STUCK_GM_MIN_DB, STUCK_PM_MIN, design_gains
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.metrics import MoveMetrics
from servodesk.domain.tuning.model import LoopModel, PlantModel, VibrationMode
from servodesk.domain.tuning.promise import RESONANCE_DRIFT, RESONANCE_TOL, RESONANCE_TOL_PEAK
from servodesk.domain.tuning.search import (
    ALTERNATIVE_SETTLING_FACTOR,
    CONFIRM_TOP,
    DIVERGED,
    FF_SWEEP,
    FF_SWEEP_TOP,
    GM_MIN_DB,
    INERTIA_TOL,
    MOTOR_SPLIT_TOL_LOW_ANTI,
    PM_MIN,
    REF_HOLD_S,
    REFINE_LEAD,
    REFINE_TI,
    RIGID_VARIATIONS,
    STRUCTURE_FF_FACTORS,
    STUCK_LOAD_DAMPING,
    TUNER_GM_EXTRA_DB,
    TUNER_PM_EXTRA_DEG,
    VARIATIONS,
    alternatives_of,
    candidates_around,
    confirmed,
    drift_set,
    ff_swept,
    identification_set,
    mechanical,
    rank_gains,
    reference_move,
    refined,
    stuck_load_set,
    tune_on_model,
    worth_trying,
)
from servodesk.domain.tuning.simulate import friction_step, simulate_batch
from servodesk.model.plant import PlantParams
from servodesk.model.plantfile import PlantSpec
from servodesk.model.replay import ModelMoves, OwnMove, WorstOf, run_move

RATE = 16000.0
JM = 3.7e-5
PEAK = 4.46
CPR = 1 << 20

#: Gains the tuner once chose for a two-mass axis (R = 1, 400 Hz, 2 % Coulomb friction on the
#: load): linear margins 47 deg / 9 dB on the exact plant, yet on the drive the axis hunted at
#: 380 Hz, +-190 counts, because the load sticks at rest.
HUNTING = ServoGains(
    kp_pos=315.3,
    kp_vel=0.12557,
    ti_vel=0.0023149,
    vel_ff=1.0,
    inertia_ff=5.868e-05,
    notch1_hz=398.57,
    notch1_width=0.3,
    notch1_depth=0.0,
)


def test_friction_holds_breaks_away_and_stops_at_zero() -> None:
    fc, k = 0.1, 1.0
    w = np.array([0.0, 0.0, 0.0, 0.5, 0.01, -0.01])
    drive = np.array([0.05, -0.1, 0.3, 0.0, 0.05, 0.2])
    out = friction_step(w, drive, 0.0, fc, k)
    assert out[0] == 0.0 and out[1] == 0.0  # At rest, |drive| <= Coulomb: held.
    assert out[2] == pytest.approx(0.2)  # Breaks away with drive - Fc.
    assert out[3] == pytest.approx(0.4)  # Moving: decelerated by Fc.
    assert out[4] == 0.0  # Would cross zero while friction could hold it: stops.
    # Driven through zero by more than Fc: moves on (friction opposes the velocity the step
    # started with, as model/plant.py's RigidMechanics does).
    assert out[5] == pytest.approx(-0.01 + 0.2 + 0.1)
    # Without Coulomb friction it is the plain viscous step.
    plain = friction_step(w, drive, 0.5, 0.0, k)
    assert plain == pytest.approx(w + drive - 0.5 * w)


def _hunting_tail(coulomb: float) -> float:
    plant = PlantModel(JM, JM, 400.0, 0.03, 0.0, 2000.0)
    move = reference_move(plant.total_inertia, PEAK, CPR, RATE)
    model = mechanical(plant, counts_per_rev=CPR, torque_limit=PEAK, coulomb=coulomb)
    tr = simulate_batch(model, [HUNTING], RATE, move.p, move.v, move.a)
    err = tr.position_counts[0] - move.target_counts
    tail = err[move.t > move.t[-1] - 0.3]
    return float(tail.max() - tail.min())


def test_the_batch_simulation_shows_a_friction_limit_cycle() -> None:
    # The stuck load leaves the motor ringing against the shaft: the simulation hunts as the
    # drive did, so the ranking sees that these gains never settle. Without friction the same
    # gains settle to within a few counts.
    assert _hunting_tail(0.02 * PEAK) > 150.0
    assert _hunting_tail(0.0) < 5.0


#: stress-soft60Hz (J_L = 30 J_M, 60 Hz, damping 0.01) as noise seed 8's tuning identified it:
#: the damping 5.7 x the truth and a viscous term the moves lent from friction.
SOFT60_SEED8 = PlantModel(3.6974454e-05, 1.1542322e-03, 60.5877046, 0.0566485, 0.0023322, 2000.0)
#: The gains that tuning chose: they met every member of the set without a light damping and
#: had PM 43.7 deg on the true plant.
SOFT60_SEED8_GAINS = ServoGains(
    kp_pos=19.9786582,
    kp_vel=0.107115928,
    ti_vel=0.0283578463,
    vel_ff=1.0,
    inertia_ff=9.61899389e-04,
    notch1_hz=60.5877046,
    notch1_width=1.0,
    notch1_depth=0.0,
)


def _worst_pm(models: list[PlantModel], gains: ServoGains) -> float:
    return min(
        min(loop.velocity_margins().phase_margin_deg, loop.position_margins().phase_margin_deg)
        for loop in (LoopModel(m, RATE, gains) for m in models)
    )


def test_a_light_damping_refuses_gains_that_miss_the_margins_on_a_sharper_mode() -> None:
    true = PlantModel(JM, 30 * JM, 60.0, 0.01, 0.0, 2000.0)
    pm_min = PM_MIN + TUNER_PM_EXTRA_DEG
    assert _worst_pm([true], SOFT60_SEED8_GAINS) < PM_MIN
    # Without it every member passes the gains: the set checks one parameter at a time, and
    # the true plant is off in three at once (resonance, damping, viscous damping).
    plain = identification_set(SOFT60_SEED8, RESONANCE_TOL)
    assert _worst_pm(plain, SOFT60_SEED8_GAINS) >= pm_min
    light = identification_set(SOFT60_SEED8, RESONANCE_TOL, 0.25 * SOFT60_SEED8.damping)
    assert _worst_pm(light, SOFT60_SEED8_GAINS) < pm_min
    added = [m for m in light if m not in plain]
    assert len(added) == 3
    assert all(m.damping == pytest.approx(0.25 * SOFT60_SEED8.damping) for m in added)
    assert all(m.viscous == 0.0 for m in added)
    assert sorted(m.resonance_hz / SOFT60_SEED8.resonance_hz for m in added if m.resonance_hz) == [
        pytest.approx(1.0 - RESONANCE_TOL),
        pytest.approx(1.0),
        pytest.approx(1.0 + RESONANCE_TOL),
    ]


def test_identification_set_adds_a_lighter_motor_below_a_low_anti_resonance() -> None:
    stiff = PlantModel(JM, 3 * JM, 400.0, 0.03, 0.001, 2000.0)  # f_ar = 200 Hz
    soft = PlantModel(JM, 30 * JM, 100.0, 0.03, 0.001, 2000.0)  # f_ar = 18 Hz
    for plant, tol in ((stiff, INERTIA_TOL), (soft, INERTIA_TOL)):
        models = identification_set(plant)
        assert models[0] == plant
        inertias = sorted(m.total_inertia / plant.total_inertia for m in models)
        assert inertias[0] == pytest.approx(1.0 - tol) and inertias[-1] == pytest.approx(1.0 + tol)
        res = sorted(
            {
                m.resonance_hz / 400.0 if plant is stiff else m.resonance_hz / 100.0
                for m in models
                if m.resonance_hz
            }
        )
        assert res[0] == pytest.approx(1.0 - RESONANCE_TOL) and res[-1] == pytest.approx(
            1.0 + RESONANCE_TOL
        )
        assert any(m.damping == pytest.approx(0.5 * plant.damping) for m in models)
        assert any(m.viscous == 0.0 for m in models)
        # Below a low anti-resonance the motor's share of the inertia is uncertain too: a
        # member with a lighter motor, the same total and the same (well measured) resonance.
        split = [
            m
            for m in models
            if m.motor_inertia < 0.99 * plant.motor_inertia
            and m.total_inertia == pytest.approx(plant.total_inertia)
        ]
        if plant is soft:
            assert len(split) == 1
            m = split[0]
            assert m.motor_inertia == pytest.approx(JM * (1.0 - MOTOR_SPLIT_TOL_LOW_ANTI))
            assert m.total_inertia == pytest.approx(plant.total_inertia)
            assert m.resonance_hz == plant.resonance_hz
            assert m.anti_resonance_hz is not None and m.anti_resonance_hz < 18.0
        else:
            assert split == []


def test_variations_also_try_the_other_notch_depth() -> None:
    design = ServoGains(
        kp_pos=100.0, kp_vel=0.1, ti_vel=0.01, inertia_ff=1e-4, notch1_hz=400.0, notch1_width=1.0
    )
    depths = {g.notch1_depth for g in candidates_around(design)}
    assert depths == {0.0, 0.3}  # A full notch, and one that lets the loop damp the mode.
    assert all(g.notch1_hz == 400.0 and g.notch1_width == 1.0 for g in candidates_around(design))
    rigid = replace(design, notch1_hz=0.0, notch1_width=0.0)
    assert {g.notch1_depth for g in candidates_around(rigid)} == {0.0}
    assert len(candidates_around(design)) == 2 * len(candidates_around(rigid))


def test_ranking_puts_the_hunting_gains_last() -> None:
    plant = PlantModel(JM, JM, 400.0, 0.03, 0.0, 2000.0)
    move = reference_move(plant.total_inertia, PEAK, CPR, RATE)
    model = mechanical(plant, counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.02 * PEAK)
    calm = ServoGains(
        kp_pos=150.0,
        kp_vel=0.06,
        ti_vel=0.008,
        vel_ff=1.0,
        inertia_ff=6.0e-05,
        notch1_hz=400.0,
        notch1_width=1.0,
        notch1_depth=0.0,
    )
    ranked = rank_gains(plant, RATE, [HUNTING, calm], move, model, pm_min=0.0, gm_min_db=0.0)
    assert ranked.n_feasible == 2
    assert [g for g, _ in ranked.order] == [calm, HUNTING]
    assert math.isfinite(ranked.order[0][1].settling_100_s)
    assert not math.isfinite(ranked.order[1][1].settling_100_s)
    # The margins alone would have let the hunting gains through (PM >= 45 deg, GM >= 8 dB).
    assert rank_gains(plant, RATE, [HUNTING], move, model).n_feasible == 1


def test_alternatives_differ_in_integral_time_or_position_gain() -> None:
    base = ServoGains(kp_pos=200.0, kp_vel=0.1, ti_vel=0.01, vel_ff=1.0, inertia_ff=1e-4)
    near = ServoGains(kp_pos=210.0, kp_vel=0.1, ti_vel=0.011, vel_ff=1.0, inertia_ff=0.9e-4)
    slow_i = ServoGains(kp_pos=200.0, kp_vel=0.1, ti_vel=0.02, vel_ff=1.0, inertia_ff=1e-4)
    slow_i2 = ServoGains(kp_pos=205.0, kp_vel=0.09, ti_vel=0.021, vel_ff=1.0, inertia_ff=1e-4)
    stiff_p = ServoGains(kp_pos=300.0, kp_vel=0.1, ti_vel=0.01, vel_ff=1.0, inertia_ff=1e-4)
    order = [base, near, slow_i, slow_i2, stiff_p]
    # Near-copies of the winner or of a picked runner-up are passed over.
    assert alternatives_of(order) == (slow_i, stiff_p)
    assert alternatives_of(order, 1) == (slow_i,)
    assert alternatives_of([base]) == () and alternatives_of([]) == ()
    # A runner-up with a higher velocity gain than the winner is never tried on the axis.
    faster = ServoGains(kp_pos=200.0, kp_vel=0.12, ti_vel=0.03, vel_ff=1.0, inertia_ff=1e-4)
    assert alternatives_of([base, faster, slow_i]) == (slow_i,)


def test_only_runners_up_the_model_cannot_tell_from_the_winner_go_to_the_axis() -> None:
    # The tries on the axis measure one move through the drive's torque noise: they may decide
    # between gains the model puts close together, not overrule a clear prediction.
    def settling(ms: float) -> MoveMetrics:
        return MoveMetrics(ms / 1e3, ms / 1e3, 0.0, 100.0, 200.0)

    g = [ServoGains(kp_pos=200.0 + k, kp_vel=0.1, ti_vel=0.01, vel_ff=1.0) for k in range(4)]
    order = [(g[0], settling(9.4)), (g[1], settling(14.0)), (g[2], settling(28.6))]
    assert ALTERNATIVE_SETTLING_FACTOR == 1.5
    assert worth_trying(order) == [g[0], g[1]]  # 14.0 <= 1.5 x 9.4 < 28.6
    assert worth_trying(order, factor=4.0) == [g[0], g[1], g[2]]
    # A winner that never settles on the model leaves the axis to decide among all.
    never = [(g[0], settling(math.inf)), (g[3], settling(math.inf))]
    assert worth_trying(never) == [g[0], g[3]]
    assert worth_trying([]) == []


def _true_tail(gains: ServoGains) -> float:
    """Peak-to-peak error over the last 0.3 s of the reference move on the drive's own plant
    simulation (model/plant.py: exact two-mass, Coulomb friction sticking on the load)."""
    params = PlantParams(
        motor_inertia=JM,
        load_inertia=JM,
        viscous=0.0,
        coulomb=0.02 * PEAK,
        peak_torque=PEAK,
        counts_per_rev=CPR,
        current_loop_hz=2000.0,
        resonance_hz=400.0,
        damping=0.03,
        exact=True,
    )
    move = reference_move(2 * JM, PEAK, CPR, RATE)
    err = run_move(params, gains, RATE, PEAK, move) - move.target_counts
    tail = err[move.t > move.t[-1] - 0.3]
    return float(tail.max() - tail.min())


def test_stuck_load_models_refuse_the_hunting_gains() -> None:
    plant = PlantModel(JM, JM, 400.0, 0.03, 0.0, 2000.0)
    stuck = stuck_load_set(plant)
    z = math.sqrt(plant.stiffness * plant.load_inertia)
    assert [m.load_viscous for m in stuck] == pytest.approx([x * z for x in STUCK_LOAD_DAMPING])
    assert stuck_load_set(PlantModel(JM, JM)) == []  # A rigid axis has no shaft to hold.
    # The free axis meets the margins with these gains; held by friction it is unstable.
    assert LoopModel(plant, RATE, HUNTING).velocity_margins().meets(45.0, 8.0)
    assert not all(LoopModel(p, RATE, HUNTING).is_stable() for p in stuck)
    move = reference_move(plant.total_inertia, PEAK, CPR, RATE)
    model = mechanical(plant, counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.02 * PEAK)
    assert rank_gains(plant, RATE, [HUNTING], move, model, stuck_plants=stuck).n_feasible == 0
    # And the drive's plant does hunt with them.
    assert _true_tail(HUNTING) > 150.0


def test_the_tuned_axis_does_not_hunt_when_its_load_sticks() -> None:
    plant = PlantModel(JM, JM, 400.0, 0.03, 0.0, 2000.0)
    result = tune_on_model(
        plant, RATE, "high", counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.02 * PEAK
    )
    assert all(LoopModel(p, RATE, result.gains).is_stable() for p in stuck_load_set(plant))
    assert result.gains.notch1_hz == pytest.approx(400.0)
    assert _true_tail(result.gains) <= 10.0


def test_a_finer_simulation_orders_the_variations() -> None:
    plant = PlantModel(JM, 3 * JM, 800.0, 0.03, 0.0, 2000.0)
    finer = ModelMoves.of(plant, RATE, counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.09)
    assert finer is not None
    result = tune_on_model(
        plant, RATE, "high", counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.09, rerank=finer
    )
    move = reference_move(plant.total_inertia, PEAK, CPR, RATE)
    # The result's move figures are the finer simulation's, and no variation it ranked
    # settles sooner than the chosen one.
    chosen = finer([result.gains], move)[0]
    assert chosen is not None and chosen == result.metrics
    others = [m for m in finer(result.alternatives, move) if m is not None]
    assert all(chosen.key() <= m.key() for m in others)
    # When the drive picks a runner-up, the result reports that runner-up's own move and
    # margins, not the model winner's.
    assert result.alternatives, "a two-mass axis has runners-up to try on the drive"
    runner = result.alternatives[0]
    picked = result.with_gains(runner, RATE, plant)
    assert picked.gains == runner and picked.metrics == finer([runner], move)[0]
    assert picked.metrics != result.metrics
    own = LoopModel(plant, RATE, runner).velocity_margins()
    assert picked.margins.phase_margin_deg == pytest.approx(own.phase_margin_deg)
    assert result.with_gains(result.gains, RATE, plant) is result
    with pytest.raises(ValueError, match="runners-up"):
        result.with_gains(replace(runner, kp_vel=2.0 * runner.kp_vel), RATE, plant)
    assert any("tick-by-tick" in n for n in result.notes)
    # The tuning service hands it to a worker process; a model the simulated mechanics cannot
    # represent (a second resonance) gets none and the batch model's order stands.
    assert pickle.loads(pickle.dumps(finer)) == finer
    two = replace(plant, extra_modes=(VibrationMode(900.0, 0.03, 1000.0),))
    assert ModelMoves.of(two, RATE, counts_per_rev=CPR, torque_limit=PEAK) is None


def _on_model(plant: PlantModel) -> dict[str, Any]:
    """tune_on_model's keywords as the service gives them for ``plant`` with 0.09 N m of
    Coulomb friction, ranked on its tick-by-tick simulation."""
    finer = ModelMoves.of(plant, RATE, counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.09)
    assert finer is not None
    return {"counts_per_rev": CPR, "torque_limit": PEAK, "coulomb": 0.09, "rerank": finer}


def test_the_axis_only_tries_runners_up_the_model_puts_near_the_winner() -> None:
    # On a load 3 x the motor behind an 800 Hz shaft the model ranks one runner-up within
    # 1.5 x the winner's settling time and another further behind; only the first is worth
    # a move on the axis (a noisy try once took one the model put 3 x slower).
    plant = PlantModel(JM, 3 * JM, 800.0, 0.03, 0.0, 2000.0)
    kw = _on_model(plant)
    near = tune_on_model(plant, RATE, "high", **kw)
    every = tune_on_model(plant, RATE, "high", try_factor=math.inf, **kw)
    assert near.gains == every.gains
    limit = ALTERNATIVE_SETTLING_FACTOR * near.metrics.settling_10_s
    assert near.alternative_metrics
    assert all(m.settling_10_s <= limit for m in near.alternative_metrics)
    assert any(m.settling_10_s > limit for m in every.alternative_metrics)


def test_an_incumbent_is_measured_on_the_model_as_the_winner_was() -> None:
    # The gains chosen on an earlier model of the axis, run on this one through the same
    # simulation and confirmation: the winner itself measures as the winner.
    plant = PlantModel(JM, 3 * JM, 800.0, 0.03, 0.0, 2000.0)
    kw = _on_model(plant)
    off = ModelMoves.of(plant, RATE, counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.09 * 1.02)
    assert off is not None
    first = tune_on_model(plant, RATE, "high", confirm=off, **kw)
    assert first.incumbent_metrics is None
    again = tune_on_model(plant, RATE, "high", confirm=off, incumbent=first.gains, **kw)
    assert again.gains == first.gains and again.incumbent_metrics == first.metrics
    other = first.alternatives[0]
    third = tune_on_model(plant, RATE, "high", confirm=off, incumbent=other, **kw)
    assert third.incumbent_metrics is not None
    assert third.incumbent_metrics.key() >= third.metrics.key()


def test_confirmed_ranks_the_first_by_their_worst_move_and_a_divergence_last() -> None:
    g = [ServoGains(kp_vel=0.01 * (i + 1)) for i in range(CONFIRM_TOP + 2)]
    ms = [MoveMetrics(0.010 + 0.001 * i, 0.005, 0.0, 1.0, 2.0) for i in range(len(g))]
    order = list(zip(g, ms, strict=True))
    # Off the model, the winner settles in 40 ms, the runner-up diverges, the rest as before.
    off = {g[0]: replace(ms[0], settling_10_s=0.040), g[1]: None}

    def confirm(gains: Any, move: Any) -> list[MoveMetrics | None]:
        assert len(gains) == CONFIRM_TOP  # Only the first are run again.
        return [off.get(x, ms[g.index(x)]) for x in gains]

    out = confirmed(order, confirm, None)  # type: ignore[arg-type]
    head = [x for x, _ in out[:CONFIRM_TOP]]
    assert head == [*g[2:CONFIRM_TOP], g[0], g[1]]
    assert out[CONFIRM_TOP - 2][1].settling_10_s == 0.040 and out[CONFIRM_TOP - 1][1] == DIVERGED
    assert out[CONFIRM_TOP:] == order[CONFIRM_TOP:]  # The rest keep their place.
    assert confirmed([], confirm, None) == []  # type: ignore[arg-type]


def test_the_first_candidates_must_also_settle_with_the_friction_a_little_off() -> None:
    # stress-loop8k seed 1 as the tuner identified it: a load 3 x the motor behind a 400 Hz
    # shaft, an 8 kHz loop, the friction its moves measured. The model's fastest gains settle
    # only at exactly that friction (on the axis: 99 ms where the model said 12, docs/tuning.md).
    plant = PlantModel(3.748e-5, 1.1069e-4, 398.885, 0.0303, 0.0, 2000.0)
    rate, coulomb = 8000.0, 0.0945

    def moves(f: float) -> ModelMoves:
        m = ModelMoves.of(plant, rate, counts_per_rev=CPR, torque_limit=PEAK, coulomb=coulomb * f)
        assert m is not None
        return m

    kw: dict[str, Any] = {"counts_per_rev": CPR, "torque_limit": PEAK, "coulomb": coulomb}
    off = WorstOf((moves(0.98), moves(1.02)))
    plain = tune_on_model(plant, rate, "high", rerank=moves(1.0), **kw)
    sure = tune_on_model(plant, rate, "high", rerank=moves(1.0), confirm=off, **kw)
    move = reference_move(plant.total_inertia, PEAK, CPR, rate, REF_HOLD_S)
    fragile = off([plain.gains], move)[0]
    assert fragile is None or fragile.settling_10_s > 2.0 * plain.metrics.settling_10_s
    # The confirmed winner's metrics are its worst over the three frictions, and it settles.
    worst = [m([sure.gains], move)[0] for m in (moves(0.98), moves(1.0), moves(1.02))]
    assert all(w is not None for w in worst)
    assert sure.metrics.settling_10_s == max(w.settling_10_s for w in worst if w is not None)
    assert sure.metrics.settling_10_s < 0.06
    assert fragile is None or sure.metrics.settling_10_s < fragile.settling_10_s
    assert any("re-ranked by their worst move" in n for n in sure.notes)
    assert not any("re-ranked" in n for n in plain.notes)


def test_an_axis_of_another_inertia_runs_the_move_that_inertia_makes() -> None:
    # The reference move accelerates at a share of the machine's move torque over the inertia:
    # on an axis 1 % heavier than identified the machine's move is 1 % gentler.
    plant = PlantModel(JM, 3 * JM, 400.0, 0.03, 0.0, 2000.0)
    heavy = replace(plant, motor_inertia=1.01 * JM, load_inertia=1.01 * 3 * JM)
    m = ModelMoves.of(heavy, RATE, counts_per_rev=CPR, torque_limit=PEAK, coulomb=0.09)
    assert m is not None
    handed = reference_move(plant.total_inertia, PEAK, CPR, RATE, REF_HOLD_S)
    own = reference_move(heavy.total_inertia, PEAK, CPR, RATE, REF_HOLD_S)
    assert own.t_end > handed.t_end
    g = design_gains(plant, RATE, "basic").gains
    got = OwnMove(m, heavy.total_inertia)([g], handed)[0]
    assert got is not None
    assert got == m([g], own)[0]
    assert got != m([g], handed)[0]
    # Picklable, like the ModelMoves it wraps (the search runs in a worker process).
    assert pickle.loads(pickle.dumps(OwnMove(m, heavy.total_inertia))).inertia == pytest.approx(
        heavy.total_inertia
    )


def _identified_moves(
    plant: PlantModel, coulomb: float, gravity: float
) -> Callable[..., ModelMoves]:
    """The reference move on an identified axis, its inertia scaled by ``scale`` and its
    Coulomb friction by ``f`` (as services/tuning/own/ builds its ranking and confirmation)."""

    def moves(scale: float = 1.0, f: float = 1.0) -> ModelMoves:
        axis = replace(
            plant,
            motor_inertia=plant.motor_inertia * scale,
            load_inertia=plant.load_inertia * scale,
        )
        m = ModelMoves.of(
            axis, RATE, counts_per_rev=CPR, torque_limit=PEAK, coulomb=coulomb * f, gravity=gravity
        )
        assert m is not None
        return m

    return moves


def _search_kw(coulomb: float, gravity: float, **more: Any) -> dict[str, Any]:
    """``tune_on_model``'s keywords as the service passes them on a compliant axis."""
    return {
        "counts_per_rev": CPR,
        "torque_limit": PEAK,
        "coulomb": coulomb,
        "gravity": gravity,
        "structure_runs": 100,
        **more,
    }


def test_the_first_candidates_must_also_settle_with_the_inertia_a_little_off() -> None:
    # stress-noise4x seed 2 as the tuner identified it (a load 3 x the motor behind a 400 Hz
    # shaft, torque noise 2 % of peak): the inertia 1.2 % light, the moves' inertias 1.17 %
    # apart. Confirmed with the friction +-2 % alone, the model's winner settled in 18 ms on
    # the model and 108 ms on the true plant (the oracle: 10.6 ms); with the inertia +-1.17 %
    # too, each on the move that inertia makes, in 12 ms (docs/tuning.md).
    plant = PlantModel(
        3.644660553312745e-05, 0.00010983079524594678, 400.9069528408022, 0.027494213821098033
    )
    coulomb, gravity = 0.08781675336980779, 0.00036264534755948985

    moves = _identified_moves(plant, coulomb, gravity)

    friction = (moves(f=0.98), moves(f=1.02))
    spread = 0.011662819159076
    inertia = tuple(
        OwnMove(moves(1.0 + d), plant.total_inertia * (1.0 + d)) for d in (-spread, spread)
    )
    kw = _search_kw(coulomb, gravity, resonance_tol=RESONANCE_TOL_PEAK)
    fragile = tune_on_model(plant, RATE, "high", rerank=moves(), confirm=WorstOf(friction), **kw)
    sure = tune_on_model(
        plant, RATE, "high", rerank=moves(), confirm=WorstOf(friction + inertia), **kw
    )
    true = true_plant_metrics(PlantSpec(inertia_ratio=3.0, resonance_hz=400.0, noise_torque=0.02))
    assert true(fragile.gains).settling_10_s > 0.05
    assert true(sure.gains).settling_10_s < 0.015
    # The confirmed winner's metrics are its worst over the model and the four axes off it.
    move = reference_move(plant.total_inertia, PEAK, CPR, RATE, REF_HOLD_S)
    runs = [m([sure.gains], move)[0] for m in (moves(), *friction, *inertia)]
    assert sure.metrics.settling_10_s == max(r.settling_10_s for r in runs if r is not None)


def test_the_first_are_also_run_at_other_feed_forwards_and_ranked_by_their_worst_move() -> None:
    j = 1.5e-4
    g = [ServoGains(kp_vel=0.01 * (i + 1), inertia_ff=0.85 * j) for i in range(FF_SWEEP_TOP + 2)]
    ms = [MoveMetrics(0.030 + 0.001 * i, 0.005, 0.0, 1.0, 2.0) for i in range(len(g))]
    order = list(zip(g, ms, strict=True))

    def at(x: ServoGains) -> float:
        return round(x.inertia_ff / j, 2)

    # On the model the runner-up settles in 8 ms at 0.65 J, but only there: a little off the
    # identified axis 80 ms. At 0.7 J it settles in 12 ms on both; at 0.9 J it diverges off it.
    def nominal(gains: Any, move: Any) -> list[MoveMetrics | None]:
        return [
            replace(ms[1], settling_10_s=0.008)
            if x.kp_vel == g[1].kp_vel and at(x) == 0.65
            else replace(ms[1], settling_10_s=0.012)
            if x.kp_vel == g[1].kp_vel and at(x) == 0.7
            else ms[g.index(replace(x, inertia_ff=0.85 * j))]
            for x in gains
        ]

    def off(gains: Any, move: Any) -> list[MoveMetrics | None]:
        out = nominal(gains, move)
        return [
            None if at(x) == 0.9 else replace(m, settling_10_s=0.080) if at(x) == 0.65 else m
            for x, m in zip(gains, out, strict=True)
        ]

    out = ff_swept(order, nominal, off, None, j)  # type: ignore[arg-type]
    best, metrics = out[0]
    assert best == replace(g[1], inertia_ff=0.7 * j) and metrics.settling_10_s == 0.012
    # The first as they were, and each at the feed-forwards of the sweep but its own 0.85 J
    # and the 0.9 J that diverged off the identified axis; the rest keep their place behind.
    head = out[: len(out) - 2]
    assert len(head) == FF_SWEEP_TOP + FF_SWEEP_TOP * (len(FF_SWEEP) - 2)
    assert all(at(x) != 0.9 for x, _ in head)
    assert [x for x, _ in head if at(x) == 0.85] == g[:FF_SWEEP_TOP]
    assert out[-2:] == order[FF_SWEEP_TOP:]
    assert ff_swept([], nominal, off, None, j) == []  # type: ignore[arg-type]


def test_a_feed_forward_the_variations_miss_is_found_where_it_settles_on_every_axis_off() -> None:
    # stress-noise4x seed 4 as the tuner identified it (a load 3 x the motor behind a 400 Hz
    # shaft, torque noise 2 % of peak; the inertia 0.44 % light, the moves' inertias 1.22 %
    # apart). The confirmed winner, at 0.81 J, settled in 29 ms on the model and on the true
    # plant; the same gains at 0.7 J in 17 ms at worst on the model and the axes off it, and
    # 11 ms on the true plant (the oracle: 10.6 ms at 0.7 J; docs/tuning.md).
    plant = PlantModel(
        3.7280191829261645e-05, 0.00011007416068226349, 398.7336709407047, 0.030637165558528304
    )
    coulomb, gravity, spread = 0.08678049211598564, 0.0016617220054061244, 0.012228444575776098

    moves = _identified_moves(plant, coulomb, gravity)

    off = WorstOf(
        (
            moves(f=0.98),
            moves(f=1.02),
            *(OwnMove(moves(1.0 + d), plant.total_inertia * (1.0 + d)) for d in (-spread, spread)),
        )
    )
    kw = _search_kw(
        coulomb,
        gravity,
        resonance_tol=RESONANCE_TOL,
        confirm=off,
        light_damping=0.25 * plant.damping,
    )
    plain = tune_on_model(plant, RATE, "high", rerank=moves(), **kw)
    # The sweep alone: the refinement between the variations' steps that follows it picks
    # gains 10 % ahead at worst on the model here which settle in 20.6 ms on the true plant
    # (a loss the benchmark shows on this row; docs/tuning.md, second session of 2026-12-01).
    swept = tune_on_model(plant, RATE, "high", rerank=moves(), ff_sweep=True, refine=False, **kw)
    true = true_plant_metrics(PlantSpec(inertia_ratio=3.0, resonance_hz=400.0, noise_torque=0.02))
    assert true(plain.gains).settling_10_s > 0.025
    assert true(swept.gains).settling_10_s < 0.015
    assert swept.metrics.settling_10_s < 0.8 * plain.metrics.settling_10_s
    # A feed-forward the variations do not have (theirs: 0.85 and 0.81 J).
    ff = swept.gains.inertia_ff / plant.total_inertia
    assert min(abs(ff - x) for x in (0.85, 0.85 * 0.95)) > 0.01
    assert any("feed-forwards of 0.6-1 x J" in n for n in swept.notes)
    assert not any("feed-forwards of" in n for n in plain.notes)


def test_the_oracles_structures_join_the_ranking_within_the_same_margins() -> None:
    plant = PlantModel(JM, 3 * JM, 800.0, 0.03, 0.0, 2000.0)
    kw = _on_model(plant)
    plain = tune_on_model(plant, RATE, "high", **kw)
    pooled = tune_on_model(plant, RATE, "high", structure_runs=40, **kw)
    assert any("filter structures" in n for n in pooled.notes)
    assert not any("filter structures" in n for n in plain.notes)
    # Pooled, the model's pick can only settle sooner than the variations' own; on this axis
    # it does (+-10 counts in 4 ms against 10 ms).
    assert pooled.metrics.key() < plain.metrics.key()
    # Whatever won keeps the tuner's margins on every model of the identification set and
    # its feed-forward is one the tuner allows (not the oracle's 0.7 J).
    for model in identification_set(plant):
        m = LoopModel(model, RATE, pooled.gains).velocity_margins()
        assert m.phase_margin_deg >= PM_MIN + TUNER_PM_EXTRA_DEG - 1e-6
        assert m.gain_margin_db >= GM_MIN_DB + TUNER_GM_EXTRA_DB - 1e-6
    ff = pooled.gains.inertia_ff / plant.total_inertia
    allowed = {*STRUCTURE_FF_FACTORS, *(FF_FACTOR * f for f in VARIATIONS.ff)}
    assert min(abs(ff - a) for a in allowed) < 1e-6
    # Only "high" searches; a rigid mode for "basic" stays the design.
    basic = tune_on_model(plant, RATE, "basic", structure_runs=40, **kw)
    assert not any("filter structures" in n for n in basic.notes)


def test_a_rigid_axis_is_ranked_on_its_worst_inertia_with_feed_forwards_near_it() -> None:
    # services/tuning/own/ ranks a rigid axis whose inertia the position demand instrumented
    # so: the identified inertia and 0.5 % either way, and feed-forwards up to the inertia.
    plant = PlantModel(4 * JM, 0.0, None, 0.03, 0.0, 2000.0)

    def moves(scale: float) -> ModelMoves:
        m = ModelMoves.of(
            replace(plant, motor_inertia=plant.motor_inertia * scale),
            RATE,
            counts_per_rev=CPR,
            torque_limit=PEAK,
            coulomb=0.09,
        )
        assert m is not None
        return m

    worst = WorstOf((moves(0.995), moves(1.0), moves(1.005)))
    assert pickle.loads(pickle.dumps(worst)) == worst  # It, too, goes to a worker process.
    result = tune_on_model(
        plant,
        RATE,
        "high",
        counts_per_rev=CPR,
        torque_limit=PEAK,
        coulomb=0.09,
        rerank=worst,
        variations=RIGID_VARIATIONS,
    )
    assert result.candidates == 1 + 3 * 5 * 5 * 6
    # Feed-forwards up to the inertia are among them (the design's is 0.85 J), and on this
    # axis, whose model is exact, the ranking takes one of those near the inertia.
    j = plant.total_inertia
    base = replace(result.gains, inertia_ff=FF_FACTOR * j)
    ffs = {round(g.inertia_ff / j, 4) for g in candidates_around(base, variations=RIGID_VARIATIONS)}
    assert ffs == {0.8075, 0.85, 0.96, 0.98, 0.99, 1.0}
    assert result.gains.inertia_ff / j >= 0.96
    move = reference_move(plant.total_inertia, PEAK, CPR, RATE)
    # The chosen gains' figures are their worst over the three axes, and none of the
    # runners-up is better by that measure.
    per_axis = [m([result.gains], move)[0] for m in worst.members]
    assert all(x is not None for x in per_axis)
    assert result.metrics == max((x for x in per_axis if x is not None), key=MoveMetrics.key)
    runners = worst(result.alternatives, move)
    assert all(result.metrics.key() <= m.key() for m in runners if m is not None)


def test_high_response_trusts_a_measured_resonance_and_stays_stable_off_it() -> None:
    # A load 30 x the motor behind an 800 Hz shaft: above the resonance the loop sees the
    # motor alone, 31 x its low-frequency gain, and only a notch right on the resonance lets
    # the velocity gain up. Held +-2 % off, the notch capped it at 0.6 x what the oracle uses.
    plant = PlantModel(JM, 30 * JM, 800.0, 0.03, 0.0, 2000.0)
    kw = _on_model(plant)
    wide = tune_on_model(plant, RATE, "high", **kw)
    tight = tune_on_model(plant, RATE, "high", resonance_tol=RESONANCE_TOL_PEAK, **kw)
    assert tight.gains.kp_vel > 1.3 * wide.gains.kp_vel
    assert tight.metrics.key() < wide.metrics.key()
    # The user is told which promise the gains keep.
    assert "margins held with the resonances up to 2 % off" in wide.notes
    assert (
        f"margins held with the resonances up to {100 * RESONANCE_TOL_PEAK:g} % off, "
        f"stable with them {100 * RESONANCE_DRIFT:g} % off"
    ) in tight.notes
    # Full margins within the tight tolerance ...
    for model in identification_set(plant, RESONANCE_TOL_PEAK):
        loop = LoopModel(model, RATE, tight.gains)
        for m in (loop.velocity_margins(), loop.position_margins()):
            assert m.phase_margin_deg >= PM_MIN + TUNER_PM_EXTRA_DEG - 1e-6
            assert m.gain_margin_db >= GM_MIN_DB + TUNER_GM_EXTRA_DB - 1e-6
    # ... and still stable with the resonance drifted further, where the full margins are gone.
    drifted = drift_set(plant, RESONANCE_TOL_PEAK)
    assert [d.resonance_hz for d in drifted] == pytest.approx(
        [800.0 * (1 - RESONANCE_DRIFT), 800.0 * (1 + RESONANCE_DRIFT)]
    )
    lowest_gm = math.inf
    for model in drifted:
        loop = LoopModel(model, RATE, tight.gains)
        for m in (loop.velocity_margins(), loop.position_margins()):
            assert m.stable
            assert m.phase_margin_deg >= STUCK_PM_MIN and m.gain_margin_db >= STUCK_GM_MIN_DB
            lowest_gm = min(lowest_gm, m.gain_margin_db)
    assert lowest_gm < GM_MIN_DB
    # Where the margins already hold 2 % off, nothing more is asked.
    assert drift_set(plant, RESONANCE_TOL) == []
    assert drift_set(PlantModel(4 * JM, 0.0, None, 0.03, 0.0, 2000.0), RESONANCE_TOL_PEAK) == []


def test_the_result_says_when_it_held_the_margins_at_a_lighter_damping() -> None:
    kwargs: dict[str, Any] = {"counts_per_rev": CPR, "torque_limit": PEAK, "coulomb": 0.088}
    light = 0.25 * SOFT60_SEED8.damping
    plain = tune_on_model(SOFT60_SEED8, RATE, "basic", **kwargs)
    sharp = tune_on_model(SOFT60_SEED8, RATE, "basic", light_damping=light, **kwargs)
    assert not any("shaft damping" in n for n in plain.notes)
    assert any(f"shaft damping {light:.2g}" in n for n in sharp.notes)
    # And the margins held at it: on the identified axis with that damping the design keeps
    # the tuner's phase margin.
    sharp_axis = replace(SOFT60_SEED8, damping=light, viscous=0.0)
    assert _worst_pm([sharp_axis], sharp.gains) >= PM_MIN + TUNER_PM_EXTRA_DEG - 1e-6


def test_the_bench_scripts_plant_list_names_what_is_unknown() -> None:
    assert plant_names("R3-rigid,,R10-200Hz") == ["R3-rigid", "R10-200Hz"]
    with pytest.raises(ValueError, match=r"unknown plant\(s\): R3-300Hz, x \(known: R1-rigid"):
        plant_names("R3-rigid,R3-300Hz,x")


def test_gains_between_the_grids_steps_enter_the_ranking_only_with_a_clear_lead() -> None:
    j = 1.5e-4
    first = ServoGains(kp_pos=100.0, kp_vel=0.1, ti_vel=0.01, inertia_ff=0.7 * j)
    second = replace(first, kp_vel=0.09)
    tail = replace(first, kp_vel=0.08)
    base = MoveMetrics(0.100, 0.02, 0.0, 1.0, 2.0)
    order = [(first, base), (second, replace(base, settling_10_s=0.110))]
    # The last is ranked by the model alone (not confirmed): it keeps its place behind.
    order.append((tail, replace(base, settling_10_s=0.090)))

    def runner(lead: float, off: float = 1.0) -> Any:
        # The first's gains with the integral time 1.4 x settle in ``lead`` of its time (and
        # ``off`` of that a little off the identified axis); every other gain set as the first.
        def run(gains: Any, move: Any) -> list[MoveMetrics | None]:
            return [
                replace(base, settling_10_s=0.100 * lead * off)
                if x.kp_vel == 0.1 and math.isclose(x.ti_vel, 0.014) and x.kp_pos == 100.0
                else base
                for x in gains
            ]

        return run

    def keeps(g: ServoGains) -> bool:
        # The margins refuse the integral time 1.7 x.
        return not math.isclose(g.ti_vel, first.ti_vel * REFINE_TI[-1])

    asked: list[ServoGains] = []

    def nominal(gains: Any, move: Any) -> list[MoveMetrics | None]:
        asked.extend(gains)
        return runner(0.5)(gains, move)

    out = refined(order, nominal, runner(0.5, 1.6), None, j, keeps, unconfirmed=1)  # type: ignore[arg-type]
    best, metrics = out[0]
    assert math.isclose(best.ti_vel, 0.014) and best.kp_pos == 100.0
    # Ranked by its worst move: 80 ms a little off the axis, not the model's 50 ms.
    assert math.isclose(metrics.settling_10_s, 0.080)
    assert out[-1] == order[-1]
    # Both of the first two gain sets refined, at every feed-forward of the sweep, never
    # where the margins do not hold; the gains themselves are not run again.
    assert {replace(g, inertia_ff=0.0, ti_vel=0.0, kp_pos=0.0) for g in asked} == {
        replace(g, inertia_ff=0.0, ti_vel=0.0, kp_pos=0.0) for g in (first, second)
    }
    assert {round(g.inertia_ff / j, 2) for g in asked} == set(FF_SWEEP)
    assert not any(math.isclose(g.ti_vel / 0.01, REFINE_TI[-1]) for g in asked)
    assert first not in asked and second not in asked
    # A lead inside the model's resolution (R30-100Hz: 0.2-1.1 %) changes nothing.
    near = 1.0 - (1.0 - REFINE_LEAD) / 2.0
    assert refined(order, runner(near), runner(near), None, j, keeps, 1) == order  # type: ignore[arg-type]
    assert refined([], nominal, nominal, None, j, keeps) == []  # type: ignore[arg-type]
