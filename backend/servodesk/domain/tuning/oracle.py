"""The reference ("oracle") tuning: a global search with exact plant knowledge.

anchors-tuning.md §3.4: the benchmark scores the tuner against the best gains of the *same*
feature set (PI velocity, P position, velocity and torque feed-forward, torque low-pass, two
notches) found with full knowledge of the plant, subject to PM >= 45 deg, GM >= 8 dB and
M_s <= 6 dB, ranked lexicographically by settling time to +-10 counts, then +-100 counts, then
following-error RMS.

Two stages, so that the expensive time-domain runs are spent only on candidates that are
already known to be robust:

1. Frequency domain (vectorised, ``design.Evaluator`` on the exact plant, no uncertainty set):
   every filter configuration of a richer grid than :func:`~.design.design_gains` uses (notch
   widths x depths at each resonance, low-pass corners at fractions of the loop rate and of each
   resonance) gets its highest feasible velocity gain; the best configurations then get it for
   every integral-time factor ``alpha``. A candidate is feasible when both the velocity and the
   position loop meet the targets, no negative-real-axis crossing lies left of -1, and the
   closed-loop eigenvalues are inside the unit circle.
2. Time domain: the caller's ``simulate(gains) -> MoveMetrics`` (the bench passes a run of the
   real simulated servo loop on the exact plant) ranks the feasible candidates: first one run
   per (configuration, alpha) structure at its highest gain, then a coordinate search on the best
   structures over the velocity-gain fraction, the position-gain ratio and the feed-forward
   factor, twice. The rule-based :func:`~.design.design_gains` result on the exact plant is
   one more candidate (so the oracle is never worse than the tuner with perfect
   identification). ``max_simulations`` bounds the number of runs (about 60-80 by default: a few
   seconds with a 30 ms callback). Without a callback the candidates are ranked by the -3 dB
   velocity bandwidth.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from servodesk.domain.tuning.design import (
    FF_FACTOR,
    POS_RATIO_MIN,
    Evaluator,
    FilterConfig,
    Targets,
    design_gains,
    max_velocity_gain,
)
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.metrics import MoveMetrics, benchmark_move, simulate_move
from servodesk.domain.tuning.model import LoopModel, Margins, PlantModel

TWO_PI = 2.0 * math.pi

Simulate = Callable[[ServoGains], MoveMetrics]


@dataclass(frozen=True, slots=True)
class OracleResult:
    """The best candidate found and how it was found.

    ``margins`` / ``position_margins`` on the exact plant; ``bandwidth_hz`` the -3 dB velocity
    bandwidth, ``nominal_bandwidth_hz`` = ``kp_vel / (2 pi J)``; the settling / FE fields come
    from the ``simulate`` callback (NaN without one). ``n_feasible``: (configuration, alpha)
    structures with a feasible gain; ``n_simulated``: callback runs.
    """

    gains: ServoGains
    margins: Margins
    position_margins: Margins
    bandwidth_hz: float
    nominal_bandwidth_hz: float
    settling_10_s: float
    settling_100_s: float
    fe_rms_counts: float
    metrics: MoveMetrics | None
    n_feasible: int
    n_simulated: int
    elapsed_s: float


@dataclass(frozen=True, slots=True)
class _Structure:
    cfg: FilterConfig
    alpha: float
    kp_max: float


def _options(
    plant: PlantModel,
    rate_hz: float,
    widths: Sequence[float],
    depths: Sequence[float],
) -> tuple[list[float], list[list[tuple[float, float, float] | None]]]:
    lpfs = [0.0, rate_hz / 8.0, rate_hz / 16.0, rate_hz / 32.0]
    per_res: list[list[tuple[float, float, float] | None]] = []
    for f, _z in plant.resonances_hz()[:2]:
        opts: list[tuple[float, float, float] | None] = [None]
        if f < 0.2 * rate_hz:
            opts += [(f, w, d) for w in widths for d in depths]
        per_res.append(opts)
        for k in (0.5, 0.8):
            c = k * f
            if c < 0.25 * rate_hz and all(abs(c - x) > 0.1 * c for x in lpfs if x > 0.0):
                lpfs.append(c)
    return lpfs, per_res


def _configs(
    ev: Evaluator,
    plant: PlantModel,
    targets: Targets,
    widths: Sequence[float],
    depths: Sequence[float],
) -> dict[FilterConfig, float]:
    """Highest feasible velocity gain at alpha = 4 per filter configuration: the full product
    for one resonance, a coordinate search (two passes) for two."""
    lpfs, per_res = _options(plant, ev.rate_hz, widths, depths)
    out: dict[FilterConfig, float] = {}

    def gain(cfg: FilterConfig) -> float:
        if cfg not in out:
            out[cfg] = max_velocity_gain(ev, cfg, 4.0, targets)
        return out[cfg]

    if len(per_res) <= 1:
        for opt in per_res[0] if per_res else [None]:
            for lpf in lpfs:
                gain(FilterConfig(lpf, () if opt is None else (opt,)))
        return out
    chosen: list[tuple[float, float, float] | None] = [None, None]
    for _ in range(2):
        for r in range(2):
            best: tuple[float, list[tuple[float, float, float] | None]] = (-1.0, chosen)
            for opt in per_res[r]:
                trial = list(chosen)
                trial[r] = opt
                notches = tuple(n for n in trial if n is not None)
                k = max(gain(FilterConfig(lpf, notches)) for lpf in lpfs)
                if k > best[0]:
                    best = (k, trial)
            chosen = best[1]
    return out


def oracle_search(
    plant: PlantModel,
    rate_hz: float,
    simulate: Simulate | None = None,
    *,
    pm_min: float = 45.0,
    gm_min_db: float = 8.0,
    ms_max_db: float = 6.0,
    compute_delay: float = 1.0,
    notch_widths: Sequence[float] = (0.2, 0.3, 0.45, 0.6, 0.8, 1.0, 1.4),
    notch_depths: Sequence[float] = (0.0, 0.1, 0.3, 0.5),
    alphas: Sequence[float] = (2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 12.0),
    top_configs: int = 4,
    kp_fractions: Sequence[float] = (1.0, 0.85, 0.7, 0.55),
    pos_ratios: Sequence[float] = (1.5, 2.0, 3.0, 4.0, 6.0),
    ff_factors: Sequence[float] = (0.7, 0.85, 1.0),
    max_simulations: int = 80,
    check_plants: Sequence[PlantModel] = (),
    stuck_plants: Sequence[PlantModel] = (),
    collect: list[tuple[ServoGains, MoveMetrics]] | None = None,
) -> OracleResult:
    """Best gains for ``plant`` with full knowledge of it (see the module docstring).

    The tuner runs the same search on the plant it identified: ``check_plants`` then replace
    ``plant`` as the set every candidate's margins must hold on (search.identification_set),
    ``stuck_plants`` the set it must be stable on (search.stuck_load_set), and ``collect``
    receives every candidate the callback ran, with its metrics."""
    t0 = time.perf_counter()
    targets = Targets(pm_min, gm_min_db, ms_max_db)
    ev = Evaluator(list(check_plants) or [plant], rate_hz, compute_delay, stuck_plants=stuck_plants)
    j = plant.total_inertia

    # Stage 1: filter configurations, then alpha for the best of them.
    per_cfg = _configs(ev, plant, targets, notch_widths, notch_depths)
    ranked = sorted(
        ((k, -c.n_filters, i, c) for i, (c, k) in enumerate(per_cfg.items()) if k > 0.0),
        key=lambda x: (x[0], x[1], -x[2]),
        reverse=True,
    )
    if not ranked:
        raise ValueError("no velocity gain meets the margins on this plant")
    structures: list[_Structure] = []
    for _k, _n, _i, cfg in ranked[:top_configs]:
        for a in alphas:
            kp = max_velocity_gain(ev, cfg, a, targets)
            if kp > 0.0:
                structures.append(_Structure(cfg, a, kp))

    pos_cache: dict[tuple[FilterConfig, float, float], np.ndarray] = {}

    def pos_ok(cfg: FilterConfig, kp: float, ti: float, ratios: np.ndarray) -> np.ndarray:
        key = (cfg, kp, ti)
        if key not in pos_cache:
            kpp = (kp / j) / np.asarray(pos_ratios, dtype=np.float64)
            pos_cache[key] = targets.ok(ev.position_margins(cfg, kp, ti, kpp))
        return pos_cache[key]

    def make(s: _Structure, frac: float, ratio: float, ff: float) -> ServoGains | None:
        kp = s.kp_max * frac
        ti = s.alpha * j / kp
        # Lower gains of a structure are re-checked: feasibility need not be monotonic.
        if (
            frac != 1.0
            and not targets.ok(ev.velocity_margins(s.cfg, np.array([kp]), np.array([ti])))[0]
        ):
            return None
        i = list(pos_ratios).index(ratio)
        if not pos_ok(s.cfg, kp, ti, np.asarray(pos_ratios))[i]:
            return None
        g = s.cfg.apply(
            ServoGains(kp_pos=kp / j / ratio, kp_vel=kp, ti_vel=ti, vel_ff=1.0, inertia_ff=ff * j)
        )
        if not LoopModel(plant, rate_hz, g, compute_delay).is_stable():
            return None
        return g

    def default_ratio(s: _Structure, frac: float) -> float | None:
        kp = s.kp_max * frac
        ok = pos_ok(s.cfg, kp, s.alpha * j / kp, np.asarray(pos_ratios))
        for r, good in zip(pos_ratios, ok, strict=True):
            if good and r >= POS_RATIO_MIN:
                return r
        return None

    def bandwidth(g: ServoGains) -> float:
        bw = ev.bandwidth_hz(
            FilterConfig(
                g.torque_lpf_hz,
                tuple(
                    (f, w, d)
                    for f, w, d in (
                        (g.notch1_hz, g.notch1_width, g.notch1_depth),
                        (g.notch2_hz, g.notch2_width, g.notch2_depth),
                    )
                    if f > 0.0
                ),
            ),
            np.array([g.kp_vel]),
            np.array([g.ti_vel]),
        )[0]
        return float(bw) if math.isfinite(bw) else 0.0

    n_sim = 0
    best_g: ServoGains | None = None
    best_m: MoveMetrics | None = None

    # The rule-based design on the exact plant (with its default uncertainty set and without
    # one) is a candidate too: the oracle is never worse than the tuner itself would be with
    # perfect identification.
    seeds: list[ServoGains] = []
    for tol in (0.03, 0.0):
        with contextlib.suppress(ValueError):  # no feasible design: just no seed
            seeds.append(
                design_gains(
                    plant,
                    rate_hz,
                    "high",
                    pm_min,
                    gm_min_db,
                    ms_max_db,
                    compute_delay=compute_delay,
                    tolerance=tol,
                    robust_plants=list(check_plants) or None,
                    stuck_plants=stuck_plants,
                ).gains
            )

    if simulate is None:
        # Rank the structures at their highest gain by the -3 dB bandwidth.
        scored: list[tuple[float, ServoGains]] = []
        scored.extend((bandwidth(g), g) for g in seeds)
        for s in structures:
            r = default_ratio(s, 1.0)
            if r is None:
                continue
            g = make(s, 1.0, r, FF_FACTOR)
            if g is not None:
                scored.append((bandwidth(g), g))
        if not scored:
            raise ValueError("no candidate meets the margins on both loops")
        best_g = max(scored, key=lambda x: x[0])[1]
    else:
        seen: dict[tuple[int, float, float, float], tuple[float, float, float]] = {}

        def run(si: int, frac: float, ratio: float, ff: float) -> tuple[float, float, float]:
            nonlocal n_sim, best_g, best_m
            key = (si, frac, ratio, ff)
            if key in seen:
                return seen[key]
            bad = (math.inf, math.inf, math.inf)
            if n_sim >= max_simulations:
                return bad
            g = make(structures[si], frac, ratio, ff)
            if g is None:
                seen[key] = bad
                return bad
            m = simulate(g)
            n_sim += 1
            if collect is not None:
                collect.append((g, m))
            k = tuple(x if math.isfinite(x) else math.inf for x in m.key())
            kk = (k[0], k[1], k[2])
            seen[key] = kk
            if best_m is None or kk < _key(best_m):
                best_g, best_m = g, m
            return kk

        for g in seeds[:max_simulations]:
            m = simulate(g)
            n_sim += 1
            if collect is not None:
                collect.append((g, m))
            if best_m is None or _key(m) < _key(best_m):
                best_g, best_m = g, m
        # Structures: one run each at the highest gain.
        heads: list[tuple[tuple[float, float, float], int, float]] = []
        for si, s in enumerate(structures):
            r = default_ratio(s, 1.0)
            if r is None:
                continue
            heads.append((run(si, 1.0, r, FF_FACTOR), si, r))
        heads.sort()
        # Coordinate search on the best structures.
        for _score, si, r in heads[:2]:
            cur = (1.0, r, FF_FACTOR)
            for _ in range(2):
                for axis, values in ((0, kp_fractions), (1, pos_ratios), (2, ff_factors)):
                    trials = []
                    for v in values:
                        cand = list(cur)
                        cand[axis] = v
                        trials.append((run(si, cand[0], cand[1], cand[2]), tuple(cand)))
                    cur = min(trials)[1]  # type: ignore[assignment]
        if best_g is None:
            raise ValueError("no candidate meets the margins on both loops")

    assert best_g is not None
    model = LoopModel(plant, rate_hz, best_g, compute_delay)
    mm: MoveMetrics | None = best_m
    return OracleResult(
        gains=best_g,
        margins=model.velocity_margins(ev.w),
        position_margins=model.position_margins(ev.w),
        bandwidth_hz=bandwidth(best_g),
        nominal_bandwidth_hz=best_g.kp_vel / (TWO_PI * j),
        settling_10_s=mm.settling_10_s if mm else math.nan,
        settling_100_s=mm.settling_100_s if mm else math.nan,
        fe_rms_counts=mm.fe_rms_counts if mm else math.nan,
        metrics=mm,
        n_feasible=len(structures),
        n_simulated=n_sim,
        elapsed_s=time.perf_counter() - t0,
    )


def _key(m: MoveMetrics) -> tuple[float, float, float]:
    k = tuple(x if math.isfinite(x) else math.inf for x in m.key())
    return (k[0], k[1], k[2])


def linear_simulator(
    plant: PlantModel,
    rate_hz: float,
    *,
    peak_torque: float = 4.46,
    counts_per_rev: int = 1 << 20,
    coulomb: float | None = None,
    compute_delay: float = 1.0,
) -> Simulate:
    """A ``simulate`` callback on the linear loop model: the §3.2 move (0.5 rev, 0.7 T_peak / J,
    50 rev/s, 2 ms jerk ramp, 0.5 s observation) with smooth Coulomb friction on the load
    (default 2 % of ``peak_torque``, §3.1). No torque limit, noise or encoder quantisation: for
    tests and quick studies; the bench passes the real simulated servo loop instead."""
    prof, t_end = benchmark_move(plant.total_inertia, peak_torque, rate_hz)
    tc = 0.02 * peak_torque if coulomb is None else coulomb

    def run(g: ServoGains) -> MoveMetrics:
        return simulate_move(
            LoopModel(plant, rate_hz, g, compute_delay), prof, t_end, counts_per_rev, tc
        )

    return run
