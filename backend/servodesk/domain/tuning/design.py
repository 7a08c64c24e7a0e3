"""Gain and filter design for the cascade from an identified plant model.

:func:`design_gains` is step 7 of anchors-tuning.md §2.8: given the identified
:class:`~.model.PlantModel` and the loop rate it chooses the torque filters (notches, low-pass),
the PI velocity loop, the P position loop and the feed-forwards, meeting the robustness targets
of the "stiff" commercial preset (Kollmorgen PST, anchors §0: PM >= 45 deg, GM >= 8 dB, and
M_s <= 6 dB from §3.3) on every loop.

How (all in the frequency domain on the exact discrete loop of ``model.py``, vectorised over
gain candidates with numpy):

1. Robustness set. The margins must hold not only on the identified model but also on
   perturbed copies: total inertia x (1 - tol) (a smaller inertia means more loop gain) and every
   resonance x (1 +- tol); ``tol`` defaults to 3 %, the identification accuracy anchors §3.5 calls
   excellent, so that a design that meets its margins on the model also meets them on the true
   plant. (The notch width therefore has to cover the resonance's uncertainty.) On a two-mass
   axis the caller may add stuck-load models: Coulomb friction on the load acts, for a load
   velocity amplitude V, as a damper ``4 F_c / (pi V)`` to the frame (its describing function),
   so a load that sticks at rest is the same axis with a load damper from 0 to very large
   (:attr:`~.model.PlantModel.load_viscous`). A loop that is unstable for some damper in that
   range has a friction limit cycle at standstill (seen as hunting at a few hundred hertz once
   the notch is narrow); on these models it must only be stable with small margins.
2. Filter configurations. For each resonance (the two lowest): no notch, or a notch centred on
   it (anchors §2.4: on the motor-side peak f_r, not the anti-resonance) with width in
   {0.3, 0.6, 1.0, 1.4} and depth in {0, 0.3}; each with a torque low-pass off, at rate/8,
   rate/16 or 0.6 f_r. Both options are *evaluated*, as anchors §2.4 asks ("when not to
   notch"): a notch on a resonance far above the crossover costs phase for nothing, a notch on
   a low resonance next to its anti-resonance costs more phase at the crossover than it
   removes; the search keeps whatever gives the highest velocity gain (coordinate search over
   the resonances, notch and low-pass jointly). A configuration with more filters must win by
   2 %.
3. Velocity loop. ``kp_vel = J w_v`` (J the identified total inertia, w_v the "nominal"
   bandwidth, anchors §2.5) with ``ti_vel = alpha / w_v``. For each configuration the largest
   ``w_v`` on a geometric grid (28 points from 1 Hz to rate/10, then 8 finer steps) meeting all
   margins on the robustness set is found at ``alpha = 4`` (the Yaskawa "Ti >= 4 / w_v" rule).
   For the chosen configuration alpha in {3, 4, 5, 6, 8} is then searched, keeping the largest
   integral gain ``Kv / Ti`` (proportional to ``kp^2 / alpha``: what removes a load torque or
   friction offset, anchors §3.7) among the alphas whose gain is within 78 % of the best
   alpha's. On a rigid axis this picks alpha = 4 at ~80 % of the gain alpha = 8 would allow:
   on the linear model with Coulomb friction alpha = 4 settled best (study over the 20 core
   cases, see the report of the change). A candidate is feasible when every model of the set
   meets PM, GM, M_s and has no negative-real-axis crossing left of -1 (no conditionally stable
   loops, :func:`~.model.margins_batch`); the final design is also checked on the closed-loop
   eigenvalues of every model and stepped down by 10 % if needed.
4. Position loop. ``kp_pos`` is the largest value up to ``w_v / 1.5`` whose position loop
   (velocity loop closed) meets the same targets (PM >= pm_min, GM, M_s) on the set. With the
   feed-forwards the position loop only corrects the residual error, and a stiffer one settles
   it sooner: on the linear model ``w_v / 1.5 .. w_v / 2`` settled faster than the textbook
   ``w_v / 4`` (anchors §2.5) in most core cases; the margins, not a fixed ratio, set the limit.
5. Feed-forwards: ``vel_ff = 1`` and ``inertia_ff = 0.85 J`` (ODrive, anchors §2.5). The
   feed-forward torque reaches the shaft ``compute_delay + 1/2`` samples plus the current-loop
   lag (~0.17 ms at 16 kHz / 2 kHz) after the demand, so a full ``J a`` arrives late at the end
   of the deceleration and overshoots; a slightly short one leaves a small lag that the
   position loop removes without crossing the target. Over the 20 core cases on the linear
   model (0.5 rev §3.2 move, 2 % Coulomb friction) 0.85 gave the best median settling among
   {0.7, 0.8, 0.85, 0.9, 1.0}; an anti-resonance-dependent factor (``J_M + J_L / (1 + (f_v /
   f_ar)^2)``, the inertia the load presents when the loop is faster than its anti-resonance)
   was tried and did worse. ``ff_factor`` overrides it.
6. Response levels. "high" = the highest velocity gain the rules above give; "basic" = 0.6 x
   and "low" = 0.35 x of that gain (same filters; ``ti`` and ``kp_pos`` re-designed for the lower
   gain): conservative presets in the spirit of the commercial "response level" scales. A
   number asks for that -3 dB velocity bandwidth in Hz (capped at the "high" design).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from servodesk.domain.tuning.filters import Biquad, lowpass_coefficients, notch_coefficients
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.model import (
    LoopModel,
    MarginArrays,
    Margins,
    PlantModel,
    discretise,
    first_below,
    frequency_grid,
    margins_batch,
    plant_position_response,
)

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]
#: The response levels a tuning offers (docs/tuning.md): how far the gains go, :data:`LEVELS`.
ResponseLevel = Literal["low", "basic", "high"]

TWO_PI = 2.0 * math.pi

#: Response levels as fractions of the highest feasible velocity gain.
LEVELS: dict[str, float] = {"high": 1.0, "basic": 0.6, "low": 0.35}
#: Integral time factors alpha (ti = alpha / w_v) searched; 4 is the Yaskawa rule.
ALPHAS: tuple[float, ...] = (3.0, 4.0, 5.0, 6.0, 8.0)
NOTCH_WIDTHS: tuple[float, ...] = (0.3, 0.6, 1.0, 1.4)
NOTCH_DEPTHS: tuple[float, ...] = (0.0, 0.3)
#: Position loop: kp_pos <= w_v / POS_RATIO_MIN (and its own margins).
POS_RATIO_MIN = 1.5
#: Integral-time choice: designs within this fraction of the best bandwidth compete on
#: integral gain.
ALPHA_BANDWIDTH_FRACTION = 0.78
#: Stuck-load models (module docstring, step 1): stable with at least these margins. Not the
#: full targets: the margins a loop has against a load held by friction are not the ones its
#: moves see, and the oracle's gains, which settle best on the simulated plants, keep only 12 deg
#: and 4.5 dB on the most locked model of the 800 Hz / R = 1 axis.
STUCK_PM_MIN = 10.0
STUCK_GM_MIN_DB = 3.0
#: inertia_ff / J (module docstring, step 5).
FF_FACTOR = 0.85


@dataclass(frozen=True, slots=True)
class Design:
    """A designed gain set and what it achieves on the (nominal) identified model.

    ``margins`` / ``position_margins``: velocity / position loop on the nominal model;
    ``worst_margins``: the velocity loop's worst case over the robustness set;
    ``bandwidth_hz``: -3 dB bandwidth of the closed velocity loop; ``nominal_bandwidth_hz``:
    ``kp_vel / (2 pi J)``; ``max_bandwidth_hz``: -3 dB bandwidth of the "high" design.
    """

    gains: ServoGains
    margins: Margins
    position_margins: Margins
    worst_margins: Margins
    bandwidth_hz: float
    nominal_bandwidth_hz: float
    max_bandwidth_hz: float
    notes: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class FilterConfig:
    """Torque filters of one candidate: low-pass corner (0 off) and up to two notches."""

    lpf_hz: float = 0.0
    notches: tuple[tuple[float, float, float], ...] = ()

    @property
    def n_filters(self) -> int:
        return (1 if self.lpf_hz > 0.0 else 0) + len(self.notches)

    def biquads(self, rate_hz: float) -> list[Biquad]:
        out: list[Biquad] = []
        if self.lpf_hz > 0.0:
            out.append(lowpass_coefficients(self.lpf_hz, rate_hz))
        for f, wdt, dep in self.notches:
            out.append(notch_coefficients(f, wdt, dep, rate_hz))
        return out

    def apply(self, gains: ServoGains) -> ServoGains:
        n1 = self.notches[0] if len(self.notches) > 0 else (0.0, 0.0, 0.0)
        n2 = self.notches[1] if len(self.notches) > 1 else (0.0, 0.0, 0.0)
        return gains.replace(
            torque_lpf_hz=self.lpf_hz,
            notch1_hz=n1[0],
            notch1_width=n1[1],
            notch1_depth=n1[2],
            notch2_hz=n2[0],
            notch2_width=n2[1],
            notch2_depth=n2[2],
        )


def robustness_set(plant: PlantModel, tol: float) -> list[PlantModel]:
    """The nominal model and its perturbations (see the module docstring, step 1)."""
    out = [plant]
    if tol <= 0.0:
        return out
    out.append(
        PlantModel(
            plant.motor_inertia * (1.0 - tol),
            plant.load_inertia * (1.0 - tol),
            plant.resonance_hz,
            plant.damping,
            plant.viscous,
            plant.current_loop_hz,
            tuple(type(m)(m.freq_hz, m.damping, m.gain / (1.0 - tol)) for m in plant.extra_modes),
        )
    )
    if plant.resonances_hz():
        out.append(plant.scaled(resonance=1.0 - tol))
        out.append(plant.scaled(resonance=1.0 + tol))
    return out


@dataclass(frozen=True, slots=True)
class Worst:
    """Worst margins over the models (axis 1 of a ``(candidates, models)`` batch): over the
    first ``n_main`` models, and apart over the stuck-load models after them (inf when none)."""

    pm: FloatArray
    gm: FloatArray
    ms: FloatArray
    left: npt.NDArray[np.int64]
    stuck_pm: FloatArray
    stuck_gm: FloatArray

    @classmethod
    def of(cls, m: MarginArrays, n_main: int | None = None) -> Worst:
        n = m.pm_deg.shape[1] if n_main is None else n_main
        rows = m.pm_deg.shape[0]
        stuck = m.pm_deg.shape[1] > n
        return cls(
            m.pm_deg[:, :n].min(axis=1),
            m.gm_db[:, :n].min(axis=1),
            m.ms_db[:, :n].max(axis=1),
            m.left_crossings[:, :n].max(axis=1),
            m.pm_deg[:, n:].min(axis=1) if stuck else np.full(rows, np.inf),
            m.gm_db[:, n:].min(axis=1) if stuck else np.full(rows, np.inf),
        )


class Evaluator:
    """Vectorised margin evaluation of gain candidates on a set of plant models.

    The plant responses are computed once on a common grid; a candidate is
    ``(FilterConfig, kp_vel, ti_vel)``, and a batch of ``kp_vel`` / ``ti_vel`` values for one
    filter configuration costs a few numpy passes over ``(candidates, models, frequencies)``.
    """

    def __init__(
        self,
        plants: Sequence[PlantModel],
        rate_hz: float,
        compute_delay: float = 1.0,
        extra_centres: Sequence[tuple[float, float]] = (),
        n_grid: int = 500,
        stuck_plants: Sequence[PlantModel] = (),
    ) -> None:
        #: The models the margin targets hold on, then the stuck-load ones (Targets.stuck_*).
        self.n_main = len(plants)
        self.plants = list(plants) + list(stuck_plants)
        self.rate_hz = rate_hz
        self.compute_delay = compute_delay
        self.inertia = self.plants[0].total_inertia
        centres: list[tuple[float, float]] = list(extra_centres)
        for p in self.plants:
            centres.extend(p.resonances_hz())
            if p.anti_resonance_hz is not None:
                centres.append((p.anti_resonance_hz, p.damping))
        self.w = frequency_grid(rate_hz, centres, n=n_grid)
        self.zi = np.exp(-1j * self.w / rate_hz)
        pth = np.array(
            [
                plant_position_response(discretise(p, rate_hz, compute_delay), self.w, rate_hz)
                for p in self.plants
            ]
        )
        self.p_theta: ComplexArray = pth
        self.g: ComplexArray = pth * (1.0 - self.zi) * rate_hz
        # 1 / (1 - z^-1) / rate: the integrator of the drive's PI per unit (T / Ti) = 1.
        self.integ: ComplexArray = 1.0 / (1.0 - self.zi)
        self._fcache: dict[FilterConfig, ComplexArray] = {}

    def filt(self, cfg: FilterConfig) -> ComplexArray:
        h = self._fcache.get(cfg)
        if h is None:
            h = np.ones(self.w.shape, dtype=np.complex128)
            for b0, b1, b2, a1, a2 in cfg.biquads(self.rate_hz):
                z1 = self.zi
                h = h * (b0 + b1 * z1 + b2 * z1 * z1) / (1.0 + a1 * z1 + a2 * z1 * z1)
            self._fcache[cfg] = h
        return h

    def controller(self, kp: FloatArray, ti: FloatArray) -> ComplexArray:
        """PI responses, shape ``(len(kp), n_freq)``; ``ti = 0``: no integral."""
        with np.errstate(divide="ignore"):
            gi = np.where(ti > 0.0, 1.0 / (self.rate_hz * np.where(ti > 0, ti, 1.0)), 0.0)
        return kp[:, None] * (1.0 + gi[:, None] * self.integ[None, :])

    def velocity_loops(self, cfg: FilterConfig, kp: FloatArray, ti: FloatArray) -> ComplexArray:
        """``L_v`` of shape ``(candidates, models, freq)``."""
        c = self.controller(kp, ti) * self.filt(cfg)[None, :]
        return c[:, None, :] * self.g[None, :, :]

    def velocity_margins(self, cfg: FilterConfig, kp: FloatArray, ti: FloatArray) -> Worst:
        """Worst margins over the models, per candidate."""
        return Worst.of(margins_batch(self.w, self.velocity_loops(cfg, kp, ti)), self.n_main)

    def position_margins(
        self, cfg: FilterConfig, kp_vel: float, ti: float, kp_pos: FloatArray
    ) -> Worst:
        """Worst position-loop margins over the models, per ``kp_pos`` candidate."""
        c = self.controller(np.array([kp_vel]), np.array([ti]))[0] * self.filt(cfg)
        lv = c[None, :] * self.g
        h = c[None, :] * self.p_theta / (1.0 + lv)  # (models, freq)
        lp = kp_pos[:, None, None] * h[None, :, :]
        return Worst.of(margins_batch(self.w, lp), self.n_main)

    def bandwidth_hz(self, cfg: FilterConfig, kp: FloatArray, ti: FloatArray) -> FloatArray:
        """-3 dB bandwidth of the closed velocity loop on the nominal model, per candidate."""
        c = self.controller(kp, ti) * self.filt(cfg)[None, :]
        lv = c * self.g[0][None, :]
        t = np.abs(lv / (1.0 + lv))
        return first_below(self.w, t / t[:, :1], 1.0 / math.sqrt(2.0))


@dataclass(frozen=True, slots=True)
class Targets:
    """The margin targets a candidate must meet on every model, and the lesser ones on the
    stuck-load models (stable with a little margin: see :data:`STUCK_PM_MIN`)."""

    pm_min: float = 45.0
    gm_min_db: float = 8.0
    ms_max_db: float = 6.0
    stuck_pm_min: float = STUCK_PM_MIN
    stuck_gm_min_db: float = STUCK_GM_MIN_DB

    def ok(self, m: Worst) -> npt.NDArray[np.bool_]:
        return np.asarray(
            (m.pm >= self.pm_min)
            & (m.gm >= self.gm_min_db)
            & (m.ms <= self.ms_max_db)
            & (m.left == 0)
            & (m.stuck_pm >= self.stuck_pm_min)
            & (m.stuck_gm >= self.stuck_gm_min_db)
        )


def _kp_grid(inertia: float, rate_hz: float, n: int = 28) -> FloatArray:
    """Coarse candidate velocity gains: nominal bandwidth 1 Hz .. rate / 10."""
    return inertia * TWO_PI * np.geomspace(1.0, 0.1 * rate_hz, n)


def max_velocity_gain(
    ev: Evaluator,
    cfg: FilterConfig,
    alpha: float,
    targets: Targets,
    kp_hi: float | None = None,
) -> float:
    """Largest ``kp_vel`` (``ti = alpha / w_v``; alpha = inf: no integral) meeting the targets
    on every model; 0 if none does. Coarse geometric grid, then a fine one above the best."""
    j = ev.inertia
    kp = _kp_grid(j, ev.rate_hz)
    if kp_hi is not None:
        kp = kp[kp <= kp_hi * 1.0000001]
        if len(kp) == 0 or kp[-1] < kp_hi:
            kp = np.append(kp, kp_hi)

    def feasible(k: FloatArray) -> npt.NDArray[np.bool_]:
        ti = alpha * j / k if math.isfinite(alpha) else np.zeros_like(k)
        return targets.ok(ev.velocity_margins(cfg, k, ti))

    ok = feasible(kp)
    if not ok.any():
        return 0.0
    # The largest feasible gain of the lowest feasible run (so that every lower gain of that
    # run is feasible too: the levels scale the gain down).
    i0 = int(np.argmax(ok))
    i = i0
    while i + 1 < len(kp) and ok[i + 1]:
        i += 1
    best = float(kp[i])
    if i + 1 < len(kp):
        fine = np.geomspace(kp[i], kp[i + 1], 10)[1:-1]
        okf = feasible(fine)
        for k, good in zip(fine, okf, strict=True):
            if not good:
                break
            best = float(k)
    return best


def _filter_options(
    plant: PlantModel, rate_hz: float
) -> tuple[list[float], list[list[tuple[float, float, float] | None]]]:
    """LPF corners and, per notchable resonance (the two lowest), the notch options."""
    nyq = 0.5 * rate_hz
    lpfs = [rate_hz / 8.0, rate_hz / 16.0]
    per_res: list[list[tuple[float, float, float] | None]] = []
    for f, _z in plant.resonances_hz()[:2]:
        opts: list[tuple[float, float, float] | None] = [None]
        if f < 0.45 * nyq:
            for wdt in NOTCH_WIDTHS:
                for dep in NOTCH_DEPTHS:
                    opts.append((f, wdt, dep))
        per_res.append(opts)
        c = 0.6 * f
        if c < rate_hz / 4.0 and all(abs(c - x) > 0.15 * c for x in lpfs):
            lpfs.append(c)
    return lpfs, per_res


def choose_filters(
    ev: Evaluator, plant: PlantModel, targets: Targets
) -> tuple[FilterConfig, float, list[str]]:
    """The filter configuration with the highest feasible velocity gain at alpha = 4.

    Coordinate search over the resonances (twice when there are two): the notch options of one
    resonance times the low-pass corners (joint: a wide notch often pays only together with a
    low-pass above it), the other resonance's choice held. A configuration with more filters
    must beat the incumbent by 2 %.
    """
    lpfs, per_res = _filter_options(plant, ev.rate_hz)
    cache: dict[FilterConfig, float] = {}

    def gain(cfg: FilterConfig) -> float:
        if cfg not in cache:
            cache[cfg] = max_velocity_gain(ev, cfg, 4.0, targets)
        return cache[cfg]

    def better(cfg: FilterConfig, kp: float, inc: FilterConfig, inc_kp: float) -> bool:
        if kp <= 0.0:
            return False
        if cfg.n_filters > inc.n_filters:
            return kp > 1.02 * inc_kp
        if cfg.n_filters < inc.n_filters:
            return kp >= inc_kp / 1.02
        return kp > inc_kp

    chosen: list[tuple[float, float, float] | None] = [None] * len(per_res)
    best_cfg = FilterConfig()
    best_kp = gain(best_cfg)
    base_kp = best_kp
    for _ in range(2 if len(per_res) > 1 else 1):
        for r, opts in enumerate(per_res):
            for opt in opts:
                trial = list(chosen)
                trial[r] = opt
                for lpf in (0.0, *lpfs):
                    cfg = FilterConfig(lpf, tuple(n for n in trial if n is not None))
                    kp = gain(cfg)
                    if better(cfg, kp, best_cfg, best_kp):
                        best_cfg, best_kp, chosen = cfg, kp, trial
    if not per_res:
        for lpf in lpfs:
            cfg = FilterConfig(lpf, ())
            kp = gain(cfg)
            if better(cfg, kp, best_cfg, best_kp):
                best_cfg, best_kp = cfg, kp

    notes: list[str] = []
    j = ev.inertia
    for f, _z in plant.resonances_hz()[:2]:
        hit = [n for n in best_cfg.notches if n[0] == f]
        if hit:
            notes.append(
                f"notch at the {f:.0f} Hz resonance (width {hit[0][1]:g}, depth {hit[0][2]:g}): "
                f"nominal velocity bandwidth {base_kp / (TWO_PI * j):.0f} -> "
                f"{best_kp / (TWO_PI * j):.0f} Hz"
            )
        else:
            notes.append(
                f"no notch for the {f:.0f} Hz resonance: a notch does not raise the bandwidth"
            )
    if best_cfg.lpf_hz > 0.0:
        notes.append(f"torque low-pass at {best_cfg.lpf_hz:.0f} Hz")
    return best_cfg, best_kp, notes


def choose_alpha(
    ev: Evaluator, cfg: FilterConfig, targets: Targets, kp_cap: float | None = None
) -> tuple[float, float]:
    """``(alpha, kp)``: integral time factor with the largest integral gain ``kp^2 / alpha``
    among those within ``ALPHA_BANDWIDTH_FRACTION`` of the best reachable gain (optionally
    capped at ``kp_cap``)."""
    res = [(a, max_velocity_gain(ev, cfg, a, targets, kp_hi=kp_cap)) for a in ALPHAS]
    top = max(k for _, k in res)
    if top <= 0.0:
        return 4.0, 0.0
    cands = [(k * k / a, a, k) for a, k in res if k >= ALPHA_BANDWIDTH_FRACTION * top]
    _, a, k = max(cands)
    return a, k


def design_position_gain(
    ev: Evaluator, cfg: FilterConfig, kp_vel: float, ti: float, targets: Targets
) -> tuple[float, str]:
    """Largest ``kp_pos <= w_v / 1.5`` whose position loop (velocity loop closed) meets the
    targets on every model (see the module docstring, step 4)."""
    wv = kp_vel / ev.inertia
    kpp = wv / np.geomspace(POS_RATIO_MIN, 60.0, 48)
    pos_t = targets
    ok = pos_t.ok(ev.position_margins(cfg, kp_vel, ti, kpp))
    if not ok.any():
        return float(kpp[-1]), "position loop: no gain met the margins; minimal gain used"
    k = float(kpp[int(np.argmax(ok))])
    why = "w_v / 1.5 cap" if k == float(kpp[0]) else "position loop margins"
    return k, f"position gain {k:.0f} 1/s ({why})"


def _current_lag_us(plant: PlantModel) -> float:
    return 1e6 / (TWO_PI * plant.current_loop_hz) if plant.current_loop_hz else 0.0


def _stable_everywhere(
    plants: Sequence[PlantModel], rate_hz: float, delay: float, g: ServoGains
) -> bool:
    return all(LoopModel(p, rate_hz, g, delay).is_stable() for p in plants)


def design_gains(
    plant: PlantModel,
    rate_hz: float,
    response: ResponseLevel | str | float = "high",
    pm_min: float = 45.0,
    gm_min_db: float = 8.0,
    ms_max_db: float = 6.0,
    *,
    compute_delay: float = 1.0,
    tolerance: float = 0.03,
    ff_factor: float = FF_FACTOR,
    robust_plants: Sequence[PlantModel] | None = None,
    stuck_plants: Sequence[PlantModel] = (),
) -> Design:
    """Design filters and gains for ``plant`` (see the module docstring for the rules).

    ``response``: "low", "basic", "high" or a -3 dB velocity bandwidth in Hz (any other string
    raises :class:`ValueError`). Raises :class:`ValueError` when no gain meets the margins.
    ``robust_plants``: the models every margin must hold on (default: :func:`robustness_set`
    of ``plant`` with ``tolerance``; the first must be ``plant``). ``stuck_plants``: models of
    the load held by friction, where the loop need only be stable with the margins of
    :data:`STUCK_PM_MIN` (module docstring, step 1).
    """
    if isinstance(response, str) and response not in LEVELS:
        raise ValueError(f"response must be one of {sorted(LEVELS)} or a bandwidth in Hz")
    if not isinstance(response, str) and not float(response) > 0.0:
        raise ValueError(f"a requested bandwidth must be positive, not {response}")
    targets = Targets(pm_min, gm_min_db, ms_max_db)
    plants = list(robust_plants) if robust_plants else robustness_set(plant, tolerance)
    ev = Evaluator(plants, rate_hz, compute_delay, stuck_plants=stuck_plants)
    j = plant.total_inertia
    notes: list[str] = []

    cfg, kp4, fnotes = choose_filters(ev, plant, targets)
    notes.extend(fnotes)
    if kp4 <= 0.0:
        raise ValueError("no velocity gain meets the margins on this plant")
    alpha_hi, kp_max = choose_alpha(ev, cfg, targets)
    ti_hi = alpha_hi * j / kp_max
    max_bw = float(ev.bandwidth_hz(cfg, np.array([kp_max]), np.array([ti_hi]))[0])

    if isinstance(response, str):
        kp_target = LEVELS[response] * kp_max
        notes.append(
            f"response {response!r}: velocity gain {LEVELS[response]:g} x the highest gain "
            f"meeting the margins"
        )
    else:
        # The gain whose -3 dB bandwidth is closest to the request (at most the maximum).
        kps = np.geomspace(kp_max / 50.0, kp_max, 60)
        bws = ev.bandwidth_hz(cfg, kps, alpha_hi * j / kps)
        good = np.isfinite(bws)
        if not good.any():
            kp_target = kp_max
        else:
            i = int(np.argmin(np.where(good, np.abs(np.log(bws / float(response))), np.inf)))
            kp_target = float(kps[i])
        if float(response) > max_bw:
            notes.append(
                f"requested {float(response):.0f} Hz exceeds the highest bandwidth meeting the "
                f"margins ({max_bw:.0f} Hz)"
            )

    if kp_target < kp_max:
        alpha, kp = choose_alpha(ev, cfg, targets, kp_cap=kp_target)
        if kp <= 0.0:
            alpha, kp = alpha_hi, kp_max
    else:
        alpha, kp = alpha_hi, kp_max
    ti = alpha * j / kp

    # Final eigenvalue check on every model; step the gain down (and re-derive ti) if needed.
    kp_pos, pnote = design_position_gain(ev, cfg, kp, ti, targets)
    ff = ff_factor
    gains = cfg.apply(
        ServoGains(kp_pos=kp_pos, kp_vel=kp, ti_vel=ti, vel_ff=1.0, inertia_ff=ff * j)
    )
    for _ in range(20):
        if _stable_everywhere(ev.plants, rate_hz, compute_delay, gains):
            break
        kp *= 0.9
        ti = alpha * j / kp
        kp_pos, pnote = design_position_gain(ev, cfg, kp, ti, targets)
        gains = gains.replace(kp_vel=kp, ti_vel=ti, kp_pos=kp_pos)
        notes.append("velocity gain reduced by 10 %: closed loop not stable on every model")
    else:
        raise ValueError("no stable design found")
    notes.append(pnote)
    notes.append(f"integral time {ti * 1e3:.2f} ms (alpha = {alpha:g}: ti = alpha / w_v)")
    notes.append(
        f"inertia feed-forward {ff:.2f} x J: the feed-forward torque reaches the shaft "
        f"{(compute_delay + 0.5) * 1e6 / rate_hz + _current_lag_us(plant):.0f} us after the "
        f"demand; full J over-drives the end of the deceleration"
    )

    model = LoopModel(plant, rate_hz, gains, compute_delay)
    vm = model.velocity_margins(ev.w)
    pmg = model.position_margins(ev.w)
    wm = ev.velocity_margins(cfg, np.array([kp]), np.array([ti]))
    worst = Margins(
        float(wm.pm[0]), float(wm.gm[0]), math.nan, float(wm.ms[0]), left_crossings=int(wm.left[0])
    )
    bw = float(ev.bandwidth_hz(cfg, np.array([kp]), np.array([ti]))[0])
    return Design(
        gains=gains,
        margins=vm,
        position_margins=pmg,
        worst_margins=worst,
        bandwidth_hz=bw,
        nominal_bandwidth_hz=kp / (TWO_PI * j),
        max_bandwidth_hz=max_bw,
        notes=tuple(notes),
    )
