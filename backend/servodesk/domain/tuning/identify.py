"""System identification from recorded drive signals: inertia and friction, FRF, resonances.

Three estimators (anchors-tuning.md §2.2-2.4):

- :func:`identify_rigid`: batch least squares on the torque equation
  ``tau = J alpha + b w + Tc sign(w) + g`` over a test move, with velocity and acceleration from
  a zero-phase Savitzky-Golay differentiator;
- :func:`frequency_response`: the plant velocity / torque FRF measured in closed loop, with the
  injected test signal as the instrument (Welch averaging);
- :func:`inertia_from_frf` and :func:`find_resonances`: the rigid-body line ``1 / (J w)`` and the
  peaks that stand above it.

:func:`plant_from_identification` turns the results into a :class:`~.model.PlantModel` for
``design.design_gains``.

Over 700 lines: three estimators (least squares, FRF, resonances) and the plant built from their
results share the signal conditioning (differentiator, windows, bands) and the checks on a
record; each estimator alone is 150-300 lines.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import optimize, signal  # type: ignore[import-untyped]

from servodesk.domain.tuning.model import PlantModel, VibrationMode

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]

TWO_PI = 2.0 * math.pi


# ----------------------------------------------------------------------------------------------
# Inertia and friction from a test move


@dataclass(frozen=True, slots=True)
class InertiaEstimate:
    """Least-squares fit of ``tau = J alpha + b w + Tc sign(w) + g`` (SI units).

    ``residual_rms`` is the RMS of the fit residual [N m] over the ``n`` samples used.
    """

    inertia: float
    viscous: float
    coulomb: float
    gravity: float
    residual_rms: float
    n: int


def _sample_period(t: npt.ArrayLike | float) -> float:
    """Sample period from a rate [Hz] or from a uniformly sampled time vector."""
    if np.ndim(t) == 0:
        rate = float(t)  # type: ignore[arg-type]
        if not rate > 0.0:
            raise ValueError(f"sample rate must be positive, not {rate}")
        return 1.0 / rate
    tt = np.asarray(t, dtype=np.float64)
    if len(tt) < 2:
        raise ValueError("need at least two samples")
    dt = np.diff(tt)
    period = float(np.median(dt))
    if not period > 0.0 or np.max(np.abs(dt - period)) > 0.01 * period:
        raise ValueError("samples must be uniformly spaced in time")
    return period


def identify_rigid(
    t: npt.ArrayLike | float,
    torque: npt.ArrayLike,
    position_rad: npt.ArrayLike | None = None,
    velocity: npt.ArrayLike | None = None,
    *,
    window_s: float = 0.004,
    polyorder: int = 3,
    min_speed_fraction: float = 0.05,
    torque_delay_s: float = 0.0,
    fit_viscous: bool = True,
    fit_gravity: bool = True,
    instrument_rad: npt.ArrayLike | None = None,
    instrument_window_s: float = 0.002,
) -> InertiaEstimate:
    """Inertia, viscous and Coulomb friction and a constant (gravity) torque from a test move.

    ``t`` is the time vector [s] or the sample rate [Hz]; give either ``position_rad`` (the
    encoder angle) or ``velocity`` [rad/s]. Every signal, the torque included, goes through the
    same Savitzky-Golay filter (``window_s`` long, cubic): it is zero-phase, so no lag appears
    between torque and acceleration, and filtering both sides of the regression alike keeps the
    linear terms unbiased (anchors-tuning.md §2.2: "zero-phase filtering"). The window sets the
    regression bandwidth, ~``1.3 / window_s`` for cubic fits: keep it below ``f_ar / 3`` of a
    compliant axis (§2.2 rule), i.e. ``window_s >= 4 / f_ar``.

    Samples are left out of the regression where ``|w| < min_speed_fraction * max |w|``: near
    standstill ``sign(w)`` is ill-defined and the friction is static (stick), not Coulomb. Half a
    window is also dropped at both ends (the filter's edge fits are less accurate).

    ``torque_delay_s`` aligns the torque command with the motion when the current loop and
    computation delay are known (the torque is shifted later by that much, by linear
    interpolation).

    ``instrument_rad``: the drive's position demand, sampled with the rest. In a closed loop
    the torque answers the same quantised position the acceleration is taken from, so the
    regressor's noise is correlated with the torque and a plain least squares is biased
    (R1-rigid +1.7 %, R30-rigid -1.5 % with the encoder's counts; anchors-tuning.md §2.2 on
    closed-loop identification). The demand's acceleration (through a Savitzky-Golay filter
    ``instrument_window_s`` long: the profile generator's speed is a staircase between its
    cycles) is correlated with the motion and not with that noise: it instruments the inertia
    column, the other columns their own (instrumental variables, ``(Z^T X) c = Z^T y``).
    """
    dt = _sample_period(t)
    tau = np.asarray(torque, dtype=np.float64)
    n = len(tau)
    win = max(polyorder + 2, round(window_s / dt))
    if win % 2 == 0:
        win += 1
    if n < 3 * win:
        raise ValueError(f"need at least {3 * win} samples for a {window_s} s window, got {n}")
    if torque_delay_s:
        k = np.arange(n, dtype=np.float64)
        tau = np.interp(k - torque_delay_s / dt, k, tau)
    sg = {"window_length": win, "polyorder": polyorder, "mode": "interp"}
    if position_rad is not None:
        pos = np.asarray(position_rad, dtype=np.float64)
        w = signal.savgol_filter(pos, deriv=1, delta=dt, **sg)
        alpha = signal.savgol_filter(pos, deriv=2, delta=dt, **sg)
    elif velocity is not None:
        vel = np.asarray(velocity, dtype=np.float64)
        w = signal.savgol_filter(vel, deriv=0, **sg)
        alpha = signal.savgol_filter(vel, deriv=1, delta=dt, **sg)
    else:
        raise ValueError("give position_rad or velocity")
    tau_f = signal.savgol_filter(tau, deriv=0, **sg)

    keep = np.ones(n, dtype=bool)
    keep[: win // 2 + 1] = False
    keep[-(win // 2 + 1) :] = False
    keep &= np.abs(w) >= min_speed_fraction * np.max(np.abs(w))
    if keep.sum() < 10:
        raise ValueError("too few moving samples to identify")
    cols = [alpha[keep]]
    names = ["J"]
    if fit_viscous:
        cols.append(w[keep])
        names.append("b")
    cols.append(np.sign(w[keep]))
    names.append("Tc")
    if fit_gravity:
        cols.append(np.ones(int(keep.sum())))
        names.append("g")
    a = np.column_stack(cols)
    y = tau_f[keep]
    # Scale the columns so that lstsq's rank decision does not depend on units.
    scale = np.maximum(np.max(np.abs(a), axis=0), 1e-300)
    if instrument_rad is None:
        coef, *_ = np.linalg.lstsq(a / scale, y, rcond=None)
    else:
        z = np.asarray(instrument_rad, dtype=np.float64)
        if z.shape != tau.shape:
            raise ValueError("the instrument must be sampled with the torque")
        zwin = max(polyorder + 2, round(instrument_window_s / dt)) | 1  # Odd, as savgol asks.
        zsg = {"window_length": zwin, "polyorder": polyorder, "mode": "interp"}
        # The speed, sign(w) and 1 are their own instruments: the speed's noise is the
        # acceleration's integrated, and an instrumented speed traded the Coulomb friction
        # against the viscous term (5 % low on a simulated loop).
        zcols = [signal.savgol_filter(z, deriv=2, delta=dt, **zsg)[keep], *cols[1:]]
        zm = np.column_stack(zcols) / scale
        coef, *_ = np.linalg.lstsq(zm.T @ (a / scale), zm.T @ y, rcond=None)
    coef = coef / scale
    resid = y - a @ coef
    vals = dict(zip(names, (float(c) for c in coef), strict=True))
    return InertiaEstimate(
        inertia=vals["J"],
        viscous=vals.get("b", 0.0),
        coulomb=vals["Tc"],
        gravity=vals.get("g", 0.0),
        residual_rms=float(np.sqrt(np.mean(resid**2))),
        n=int(keep.sum()),
    )


def _torque_and(
    t: npt.ArrayLike | float, torque: npt.ArrayLike, other: npt.ArrayLike, name: str
) -> tuple[float, FloatArray, FloatArray]:
    """The sample period, the torque and a signal recorded with it, as float arrays."""
    tau = np.asarray(torque, dtype=np.float64)
    x = np.asarray(other, dtype=np.float64)
    if tau.shape != x.shape:
        raise ValueError(f"torque and {name} must be sampled together")
    return _sample_period(t), tau, x


def travel_load_torque(
    t: npt.ArrayLike | float,
    torque: npt.ArrayLike,
    velocity: npt.ArrayLike,
    inertia: float,
    *,
    end_s: float = 0.005,
) -> float:
    """The mean load torque of a travel at constant speed [N m]: friction and gravity.

    Over any stretch of record ``J (w_end - w_start) = integral (tau - load) dt``, so the load
    torque is the mean torque less the inertial share ``J dw / T``. No derivative is taken, a
    zero-mean test signal added to the torque (the frequency response's PRBS) and the torque
    noise average out, and what the test signal leaves in the speed is in ``dw``. ``w_start``
    and ``w_end`` are the mean speeds [rad/s] over the first and last ``end_s`` seconds (the
    speed ripples with the test signal). Positive when the load pulls against a positive
    speed: ``Tc sign(w) + b w + g`` of :class:`InertiaEstimate`."""
    dt, tau, w = _torque_and(t, torque, velocity, "velocity")
    m = max(1, round(end_s / dt))
    if len(tau) < 4 * m:
        raise ValueError(f"need at least {4 * m} samples, got {len(tau)}")
    dw = float(np.mean(w[-m:]) - np.mean(w[:m]))
    # The two end means sit half a window inside the record: the span between them.
    span = (len(tau) - m) * dt
    return float(np.mean(tau[m // 2 : len(tau) - (m - m // 2)])) - inertia * dw / span


@dataclass(frozen=True, slots=True)
class MovesInertia:
    """The inertia of each move (:func:`inertia_from_moves`) and how far to trust them.

    ``inertial_share``: the smallest share, over the moves, of the torque's double integral
    that is inertial rather than friction (near 1: the moves accelerate hard against little
    friction; near 0: the inertia is the small difference of two large numbers).
    ``with_viscous``: the inertia fitted together with a viscous friction ``viscous`` [N m s/rad]
    on top of the load torque, over every end point from :data:`VISCOUS_FIT_FROM` of each move
    on (the friction then changes with the speed along the move; the moves' ends alone cannot
    tell it from inertia, as every move has the same profile)."""

    per_move: tuple[float, ...]
    inertial_share: float
    with_viscous: float
    viscous: float

    @property
    def inertia(self) -> float:
        return float(np.mean(self.per_move))

    @property
    def spread(self) -> float:
        """The moves' standard deviation relative to their mean."""
        return float(np.std(self.per_move) / abs(np.mean(self.per_move)))


#: The joint fit of inertia and viscous friction (:class:`MovesInertia`) takes each move's end
#: points from this share of it on: near the start the angle has hardly moved.
VISCOUS_FIT_FROM = 0.3


def demand_spans(demand: npt.ArrayLike, *, min_gap: int = 32) -> list[tuple[int, int]]:
    """The sample ranges ``[a, b]`` over which a recorded position demand moves: from the
    sample before its first change to the sample of its last (runs closer than ``min_gap``
    samples are one move: a profile generator may hold its demand for a cycle). A change
    below a billionth of the demand's range is rounding, not motion."""
    z = np.asarray(demand, dtype=np.float64)
    if len(z) < 2:
        return []
    tol = 1e-9 * float(np.max(z) - np.min(z))
    idx = np.nonzero(np.abs(np.diff(z)) > tol)[0]
    if len(idx) == 0:
        return []
    breaks = np.nonzero(np.diff(idx) > min_gap)[0]
    starts = [int(idx[0]), *(int(idx[i + 1]) for i in breaks)]
    ends = [*(int(idx[i]) + 1 for i in breaks), int(idx[-1]) + 1]
    return list(zip(starts, ends, strict=True))


#: The span of the speed's mean at each end of a move in :func:`moves_gravity` [s]: a move's
#: ends are near standstill, and a longer mean reaches into its ramps.
MOVES_GRAVITY_END_S = 0.001


def moves_gravity(
    t: npt.ArrayLike | float,
    torque: npt.ArrayLike,
    position_rad: npt.ArrayLike,
    spans: Sequence[tuple[int, int]],
    inertia: float,
) -> float:
    """The constant (gravity) torque [N m] from test moves back and forth: the mean, over the
    two directions, of each move's mean load torque.

    Each move's load torque is :func:`travel_load_torque` over its span (``spans``: the
    samples over which the drive's demand moves, :func:`demand_spans`): ``Tc sign(w) + g`` on
    an axis with Coulomb friction. The friction changes sign with the direction and the
    gravity does not, so the two directions' means average to the gravity. Each move's own
    figure is off, on a compliant axis, by up to 40 % of the friction (the same on every move
    of a tuning; its cause was not studied further), but by the same in either direction, so
    it cancels from the gravity: within 0.02 % of the peak torque on the
    benchmark's compliant axes over two seeds, with and without a gravity of 5-10 %, where the
    least squares of :func:`identify_rigid` were up to 0.054 % off the same way on every seed
    (on the compliant R3 axes only; why, was not studied).
    ValueError without a whole move in each direction."""
    dt, tau, pos = _torque_and(t, torque, position_rad, "position")
    speed = np.gradient(pos, dt)
    way: dict[bool, list[float]] = {True: [], False: []}
    for a, b in spans:
        if b - a < 8 or b >= len(tau):
            continue
        load = travel_load_torque(
            1.0 / dt, tau[a:b], speed[a:b], inertia, end_s=MOVES_GRAVITY_END_S
        )
        way[bool(pos[b] > pos[a])].append(load)
    if not way[True] or not way[False]:
        raise ValueError("need a move in each direction for the gravity")
    return 0.5 * (float(np.mean(way[True])) + float(np.mean(way[False])))


def inertia_from_moves(
    t: npt.ArrayLike | float,
    torque: npt.ArrayLike,
    position_rad: npt.ArrayLike,
    spans: Sequence[tuple[int, int]],
    load_torque: float,
    *,
    load_speed: float = 0.0,
    speed_window_s: float = 0.003,
) -> MovesInertia:
    """The inertia of a whole axis, motor and load, from each move's double integral.

    Over ``[a, b]`` the momentum of motor and load grows by the integral of the torque less the
    load torque; integrated once more, ``J (x(b) - x(a) - w(a) (b - a)) = integral_a^b
    integral_a^t (tau - F) ds dt`` for the motor angle ``x``, as long as the shaft's twist is
    the same at both ends and the load moves with the motor when the move starts. Nothing is
    differentiated: the shaft's oscillation during the move, which a fit of ``tau = J alpha``
    must smooth over (identify_rigid's window), does not enter, and the torque noise is
    integrated. ``w(a)``: the slope of the angle over the ``speed_window_s`` before ``a``
    (an axis that has not come to rest, or creeps back, starts with that momentum).

    ``spans``: sample ranges of moves in one direction (:func:`demand_spans`); ``load_torque``
    [N m]: the friction and gravity against that direction at the speed ``load_speed``
    [rad/s], e.g. a travel's (:func:`travel_load_torque`), signed like it. A viscous friction
    ``b`` makes the load torque ``load_torque + b (w - load_speed)`` along a move, and the
    per-move values come out high by its share; ``with_viscous`` fits it (the double integral
    of ``w - load_speed`` is the single integral of the angle travelled, again no derivative)."""
    dt, tau, x = _torque_and(t, torque, position_rad, "position")
    m = max(2, round(speed_window_s / dt))
    per_move: list[float] = []
    shares: list[float] = []
    rows_y: list[FloatArray] = []
    rows_x: list[FloatArray] = []
    for a, b in spans:
        if not 0 <= a < b < len(tau) or b - a < 4:
            raise ValueError(f"move span {a}..{b} is not inside the record of {len(tau)}")
        span = (b - a) * dt
        # Torque sample k holds over [t_k, t_k + dt]: its double integral to b weighs it by
        # the time left after its midpoint.
        weight = (span - (np.arange(b - a) + 0.5) * dt) * dt
        whole = float(np.dot(tau[a:b], weight))
        inertial = whole - load_torque * float(np.sum(weight))
        lo = max(0, a - m)
        w0 = float(np.polyfit((np.arange(lo, a) - a) * dt, x[lo:a], 1)[0]) if a - lo >= 2 else 0.0
        travel = x[b] - x[a] - w0 * span
        if travel == 0.0 or whole == 0.0:
            raise ValueError(f"move span {a}..{b} does not move")
        per_move.append(inertial / travel)
        shares.append(inertial / whole)
        # The same to every end point t of the move: sum_k f_k (t - t_k - dt/2) dt by running
        # sums, against the angle travelled and the integral of the angle beyond load_speed.
        n = b - a
        tk = np.arange(n) * dt
        ends = tk + dt
        f = tau[a:b] - load_torque
        y = ends * np.cumsum(f) * dt - np.cumsum(f * (tk + 0.5 * dt)) * dt
        angle = x[a + 1 : b + 1] - x[a] - w0 * ends
        beyond = np.cumsum(x[a:b] - x[a] - load_speed * tk) * dt
        keep = np.arange(n) >= VISCOUS_FIT_FROM * n
        rows_y.append(y[keep])
        rows_x.append(np.column_stack([angle[keep], beyond[keep]]))
    if not per_move:
        raise ValueError("no moves to integrate")
    a_mat = np.vstack(rows_x)
    scale = np.maximum(np.max(np.abs(a_mat), axis=0), 1e-300)
    coef, *_ = np.linalg.lstsq(a_mat / scale, np.concatenate(rows_y), rcond=None)
    j_b, visc = (float(c) for c in coef / scale)
    return MovesInertia(tuple(per_move), min(shares), j_b, visc)


# ----------------------------------------------------------------------------------------------
# Frequency response


@dataclass(frozen=True, slots=True)
class Frf:
    """A measured frequency response: ``g`` (velocity / torque, rad/s per N m) at ``f_hz``.

    ``coherence`` is the smaller of the coherences instrument -> torque and instrument ->
    velocity (0..1): the estimate is only as good as the weaker of the two spectra it divides.
    """

    f_hz: FloatArray
    g: ComplexArray
    coherence: FloatArray
    averages: int = 0

    def band(self, f_lo: float, f_hi: float) -> Frf:
        """The part within ``f_lo <= f <= f_hi``."""
        m = (self.f_hz >= f_lo) & (self.f_hz <= f_hi)
        return Frf(self.f_hz[m], self.g[m], self.coherence[m], self.averages)


def frequency_response(
    t: npt.ArrayLike | float,
    injected: npt.ArrayLike,
    torque_cmd: npt.ArrayLike,
    velocity: npt.ArrayLike,
    nperseg: int = 4096,
    *,
    noverlap: int | None = None,
    window: str = "hann",
    detrend: str | bool = "linear",
    f_min_hz: float = 0.0,
) -> Frf:
    """Plant FRF ``G = S_rv / S_r,tau`` measured inside a closed loop.

    ``r`` (``injected``) is the test signal added to the torque command, ``tau`` the torque
    command the plant actually received (docs/tuning.md 2110h:07) and ``v`` the measured
    velocity. Inside the loop the torque is correlated with the measurement noise fed back by the
    controller, so the plain H1 estimate ``S_tau,v / S_tau,tau`` is biased towards ``-1/C``
    wherever the loop gain is high. ``r`` is independent of that noise and drives both signals:
    with it as the instrument, ``S_rv / S_r,tau = (S_r,tau G) / S_r,tau = G`` without bias
    (the standard "indirect / instrumental" closed-loop estimate; anchors-tuning.md §2.3).

    Welch averaging with ``nperseg`` samples per segment (resolution ``rate / nperseg``; keep it
    below a tenth of the lowest anti-resonance, §2.3) and 50 % overlap by default.
    """
    dt = _sample_period(t)
    fs = 1.0 / dt
    r = np.asarray(injected, dtype=np.float64)
    tau = np.asarray(torque_cmd, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    if not len(r) == len(tau) == len(v):
        raise ValueError("injected, torque and velocity must have the same length")
    nperseg = min(nperseg, len(r))
    kw = {
        "fs": fs,
        "nperseg": nperseg,
        "noverlap": noverlap,
        "window": window,
        "detrend": detrend,
    }
    f, s_rv = signal.csd(r, v, **kw)
    _, s_rt = signal.csd(r, tau, **kw)
    _, s_rr = signal.welch(r, **kw)
    _, s_tt = signal.welch(tau, **kw)
    _, s_vv = signal.welch(v, **kw)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = s_rv / s_rt
        coh_t = np.abs(s_rt) ** 2 / (s_rr * s_tt)
        coh_v = np.abs(s_rv) ** 2 / (s_rr * s_vv)
    coh = np.nan_to_num(np.minimum(coh_t, coh_v), nan=0.0)
    step = nperseg - (noverlap if noverlap is not None else nperseg // 2)
    averages = max(1, 1 + (len(r) - nperseg) // max(step, 1))
    m = (f > max(f_min_hz, 0.0)) & np.isfinite(g)
    return Frf(
        np.asarray(f[m], dtype=np.float64),
        np.asarray(g[m], dtype=np.complex128),
        np.asarray(coh[m], dtype=np.float64),
        averages,
    )


def inertia_from_frf(
    frf: Frf,
    band: tuple[float, float],
    *,
    min_coherence: float = 0.8,
    current_loop_hz: float | None = None,
    resonances: Sequence[Resonance] = (),
) -> float:
    """Total inertia from the rigid-body band of an FRF, where ``|G| = 1 / |J jw + b|``.

    Weighted least squares of ``|1/G|^2 = J^2 w^2 + b^2`` (linear in ``J^2`` and ``b^2``) over
    the points of ``band`` with coherence at least ``min_coherence``, weights = coherence. Using
    the magnitude only makes the fit insensitive to the loop's dead time (a pure phase);
    ``current_loop_hz`` divides out the first-order current-loop magnitude if known.

    Choose the band above the friction-distorted low frequencies and well below the lowest
    anti-resonance (anchors-tuning.md §2.2, "From the FRF"): a two-mass axis is already 25 %
    off the rigid line at half its anti-resonance when R = 3. With the ``resonances`` found by
    :func:`find_resonances` their two-mass shape (:func:`two_mass_shape`) is divided out first,
    so the band may reach up to about half the lowest anti-resonance.
    """
    sel = (frf.f_hz >= band[0]) & (frf.f_hz <= band[1]) & (frf.coherence >= min_coherence)
    if sel.sum() < 2:
        raise ValueError(f"fewer than two coherent FRF points in {band[0]}..{band[1]} Hz")
    f = frf.f_hz[sel]
    mag = np.abs(frf.g[sel])
    if current_loop_hz:
        mag = mag * np.sqrt(1.0 + (f / current_loop_hz) ** 2)
    for r in resonances:
        if r.anti_freq_hz is not None:
            mag = mag / np.abs(two_mass_shape(f, r.freq_hz, r.anti_freq_hz, r.damping_estimate))
    w = TWO_PI * f
    y = 1.0 / mag**2
    wt = frf.coherence[sel]
    a = np.column_stack([w**2, np.ones_like(w)])
    sw = np.sqrt(wt)
    coef, *_ = np.linalg.lstsq(a * sw[:, None], y * sw, rcond=None)
    j2 = float(coef[0])
    if j2 <= 0.0 or float(coef[1]) < 0.0:
        # A negative friction term is noise: fit J alone.
        j2 = float(np.sum(wt * y * w**2) / np.sum(wt * w**4))
    return math.sqrt(j2)


# ----------------------------------------------------------------------------------------------
# Resonances


@dataclass(frozen=True, slots=True)
class Resonance:
    """A resonance of the motor-side FRF.

    ``freq_hz``: peak of ``|G|``; ``anti_freq_hz``: the anti-resonance below it (deepest dip of
    ``|G| J w`` between the previous resonance and this one; None if there is no clear dip);
    ``peak_db``: height of the peak above the rigid-body line ``1 / (J w)``; ``damping_estimate``
    from the half-power width of the peak, ``(f2 - f1) / (2 f_r)``.
    """

    freq_hz: float
    anti_freq_hz: float | None
    peak_db: float
    damping_estimate: float


def two_mass_shape(
    f: npt.ArrayLike, f_r: float, f_ar: float, zeta: float = 0.03, zeta_ar: float | None = None
) -> ComplexArray:
    """Motor-side two-mass response relative to the rigid line ``1 / (J_tot s)``.

    ``(1 + 2 z_a s / w_ar + s^2 / w_ar^2) / (1 + 2 z s / w_r + s^2 / w_r^2)`` (anchors-tuning.md
    §2.1: the load's zero pair at the anti-resonance, the pole pair at the resonance; the shaft
    damper gives ``z_a = z w_ar / w_r``).
    """
    s = 1j * np.asarray(f, dtype=np.float64) / f_r
    q = f_r / f_ar
    za = zeta / q if zeta_ar is None else zeta_ar
    num = 1.0 + 2.0 * za * q * s + (q * s) ** 2
    return num / (1.0 + 2.0 * zeta * s + s * s)  # type: ignore[no-any-return]


def find_resonances(
    frf: Frf,
    inertia: float,
    *,
    min_coherence: float = 0.6,
    min_prominence_db: float = 6.0,
    min_freq_hz: float = 0.0,
    max_freq_hz: float | None = None,
    max_count: int = 3,
) -> list[Resonance]:
    """Resonances of a motor-side FRF, lowest first.

    The FRF is divided by the rigid-body line ``1 / (J w)`` (``inertia`` = the total inertia),
    which leaves 0 dB in the rigid band, a dip at each anti-resonance and a peak at each
    resonance; a two-mass axis ends on the motor-alone plateau ``20 log10(1 + R)``.

    Thresholds (documented choices):

    - coherence gating: points with coherence below ``min_coherence`` (0.6) are dropped: at
      ~20 averages the magnitude of such points scatters by several dB and would make peaks;
    - the ratio is smoothed over 3 points in dB (median) against single-bin spikes;
    - a peak must stand ``min_prominence_db`` (6 dB, i.e. a factor of 2) above its surroundings
      (scipy ``find_peaks`` prominence): a lightly damped mode (zeta <= 0.1) stands 10-30 dB
      above the motor-alone line, while current-loop roll-off, dead time and the ZOH are smooth
      and monotonic and never make a 6 dB bump;
    - at most ``max_count`` resonances, the most prominent, are returned.

    Each peak is then refined by a weighted least-squares fit (weights = coherence) of the
    two-mass shape (:func:`two_mass_shape`, plus a dB offset absorbing an error of ``inertia``)
    to the ratio in dB between the previous peak (or a tenth of this one's frequency) and
    1.5 x this one: the anti-resonance itself is usually gated out (little motion there, low
    coherence), but the slopes on both sides of it fix it (anchors-tuning.md §2.3, "Fit"). The
    peak frequency falls back to a parabola through the three highest points when the fit
    fails or moves it by more than 5 %.
    """
    ok = (frf.coherence >= min_coherence) & (frf.f_hz > max(min_freq_hz, 0.0))
    if max_freq_hz is not None:
        ok &= frf.f_hz <= max_freq_hz
    f = frf.f_hz[ok]
    if len(f) < 5:
        return []
    ratio_db = 20.0 * np.log10(np.abs(frf.g[ok]) * inertia * TWO_PI * f)
    coh = frf.coherence[ok]
    smooth = signal.medfilt(ratio_db, 3)
    smooth[0], smooth[-1] = ratio_db[0], ratio_db[-1]
    peaks, props = signal.find_peaks(smooth, prominence=min_prominence_db)
    if len(peaks) == 0:
        return []
    order = np.argsort(props["prominences"])[::-1][:max_count]
    peaks = np.sort(peaks[order])
    out: list[Resonance] = []
    prev_f = 0.0
    for p in peaks:
        f_peak = _refine_peak(f, ratio_db, int(p))
        lo = max(prev_f * 1.2, 0.1 * f_peak)
        fit = _fit_two_mass(f, ratio_db, coh, f_peak, lo, 1.5 * f_peak)
        zeta = _half_power_damping(f, np.abs(frf.g[ok]), int(p), f_peak)
        fr, anti = f_peak, None
        if fit is not None:
            fr_fit, far_fit, zeta_fit = fit
            if abs(fr_fit / f_peak - 1.0) < 0.05:
                fr = fr_fit
            if far_fit < 0.97 * fr:
                anti = far_fit
            if not math.isfinite(zeta):
                zeta = zeta_fit
        out.append(Resonance(fr, anti, float(smooth[p]), zeta))
        prev_f = fr
    return out


def _fit_two_mass(
    f: FloatArray, ratio_db: FloatArray, coh: FloatArray, fr0: float, lo: float, hi: float
) -> tuple[float, float, float] | None:
    """``(f_r, f_ar, zeta)`` of the two-mass shape fitted to ``ratio_db`` in ``lo..hi``."""
    sel = (f >= lo) & (f <= hi)
    if sel.sum() < 8:
        return None
    ff, yy, ww = f[sel], ratio_db[sel], np.sqrt(coh[sel])
    below = ff < fr0
    if not below.any():
        return None
    far0 = float(ff[below][np.argmin(yy[below])])
    far0 = min(max(far0, 0.1 * fr0), 0.9 * fr0)

    def resid(x: FloatArray) -> FloatArray:
        fr, far, zr, za, off = math.exp(x[0]), math.exp(x[1]), math.exp(x[2]), math.exp(x[3]), x[4]
        model = 20.0 * np.log10(np.abs(two_mass_shape(ff, fr, far, zr, za))) + off
        return (model - yy) * ww  # type: ignore[no-any-return]

    x0 = np.array([math.log(fr0), math.log(far0), math.log(0.03), math.log(0.03), 0.0])
    lb = [math.log(0.9 * fr0), math.log(0.05 * fr0), math.log(1e-3), math.log(1e-3), -6.0]
    ub = [math.log(1.1 * fr0), math.log(0.999 * fr0), math.log(0.5), math.log(0.5), 6.0]
    try:
        res = optimize.least_squares(resid, x0, bounds=(lb, ub), x_scale=1.0)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not res.success:
        return None
    return math.exp(res.x[0]), math.exp(res.x[1]), math.exp(res.x[2])


@dataclass(frozen=True)
class RecordFit:
    """A two-mass resonance fitted to a whole record (:func:`resonance_from_record`)."""

    freq_hz: float
    damping: float
    #: None when the fitted numerator has no anti-resonance below the resonance.
    anti_freq_hz: float | None
    #: The inertia the response shows above the anti-resonance (kg m^2): the motor's, from
    #: the numerator's leading coefficient ``1 / J_M``.
    motor_inertia: float | None = None

    @property
    def total_inertia(self) -> float | None:
        """Motor and load, ``J_M (f_r / f_ar)^2`` (the two-mass relation)."""
        if self.motor_inertia is None or self.anti_freq_hz is None:
            return None
        return self.motor_inertia * (self.freq_hz / self.anti_freq_hz) ** 2


#: The lightest damping a model is given (an estimate below it is raised to it).
ZETA_FLOOR = 0.002
#: Record fit (:func:`resonance_from_record`): the band's bins are summed in about this many
#: groups (each of 2..32 bins) to form the moment conditions.
RECORD_GROUPS = 16
#: The velocity measurement's lag behind the torque that the record fit allows, in seconds.
RECORD_MAX_DELAY_S = 1e-3


def resonance_from_record(
    t: npt.ArrayLike | float,
    injected: npt.ArrayLike,
    torque_cmd: npt.ArrayLike,
    velocity: npt.ArrayLike,
    resonance: Resonance,
) -> RecordFit | None:
    """``resonance`` fitted to the whole record at once; None if the fit fails.

    Welch averaging (:func:`frequency_response`) cuts the record into segments of 1/8 s and
    windows them: at 100 Hz a mode of damping 0.03 is 6 Hz wide at half power, narrower than the
    window's main lobe (+-2 bins of 8 Hz), so the peak comes out several times too wide and the
    mode looks well damped. A design trusting that leaves too little phase on the real mode.

    Here the two-mass model ``G(s) = e^(-s d) (b2 s^2 + b1 s + b0) / (s (s^2 + 2 zeta w_r s +
    w_r^2))`` is fitted to the transforms of the whole record (0.98 Hz bins for 1 s), between
    half the anti-resonance and 1.6 x the resonance, in two ways that each removed a bias
    measured on the tuner's records (docs/tuning.md):

    - *Leakage.* The record is not periodic, so each transform also holds the transient of the
      states at its ends: ``V = G T + P(s) / D(s)`` exactly, with ``D`` the model's denominator
      and ``P`` a polynomial of low degree (Pintelon and Schoukens, System Identification,
      ch. 6). Fitting ``P`` along removes the leakage that a window only reduces: without noise
      a 60 Hz mode of damping 0.01 comes out 0.0100 (a Tukey-windowed magnitude fit: 0.018).
    - *The loop's own noise.* The torque ``T`` the loop commands contains the noise it fed
      back, correlated with the noise on ``V``; a fit of ``V`` on ``T`` is then biased, most
      where the loop gain is high, that is at low resonances: 0.10 for a true 0.01 at 60 Hz,
      0.05-0.08 for 0.03 at 100 Hz. The injected signal ``R`` is independent of that noise, so
      the fit uses it as the instrument: the residuals ``conj(R_k) (V_k - G T_k - P / D)``
      are summed over groups of neighbouring bins (:data:`RECORD_GROUPS`) and those sums
      minimised. The model is still evaluated bin by bin, so the grouping costs no resolution;
      it only averages the noise's correlation out. The groups are weighted by the expected
      spread of their sum, ``sqrt(sum |R_k G_k|^2)``, from a first pass.

    For given ``(f_r, zeta, d)`` the numerator and ``P`` enter linearly and are solved by least
    squares (variable projection); the three are searched from four starting dampings, ``f_r``
    within 0.8-1.25 x the peak finder's (whose peak a low, light mode can pull 17 % high). The
    anti-resonance comes from the fitted numerator. On the tuner's records of the benchmark's
    compliant axes (two noise seeds) the damping comes out 0.92-1.08 x the truth at 200-800
    Hz and 0.76-1.26 x at 100 Hz (the windowed magnitude fit it replaces: 0.8-1.6 x and
    1.3-2.8 x); a lightly damped mode below 100 Hz is barely resolved (0.01 at 60 Hz is 1.2 Hz
    wide at half power, about a bin) and comes out anywhere from 0.24 to 5.7 x (eight noise
    seeds; the old fit's 10 x left an axis unstable), so the design allows for a lighter one
    (search.identification_set, ``light_damping``). The anti-resonance comes out within 2 %
    everywhere (the Welch bins: up to 17 % at 18 Hz, 32 % at 11 Hz).
    The motor's inertia is ``1 / b2``: within 3 % up to 400 Hz, about 10 % high at 800 Hz (the
    current loop's roll-off, not in this model, bends the band's top), so the whole axis's
    ``J_M (f_r / f_ar)^2`` is used below a low anti-resonance only. It costs 20-200 ms.
    """
    if resonance.anti_freq_hz is None:
        return None
    r = np.asarray(injected, dtype=np.float64)
    tau = np.asarray(torque_cmd, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    n = len(r)
    if n < 64 or not len(tau) == len(v) == n:
        return None
    fs = 1.0 / _sample_period(t)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    fr0, far0 = resonance.freq_hz, resonance.anti_freq_hz
    idx = np.nonzero((f >= max(0.5 * far0, 2.0 * fs / n)) & (f <= 1.6 * fr0))[0]
    size = int(min(32, max(2, len(idx) // RECORD_GROUPS)))
    idx = idx[: len(idx) // size * size]
    if len(idx) // size < 6:
        return None
    starts = np.arange(0, len(idx), size)
    s = 2j * math.pi * f[idx]
    r_k = np.fft.rfft(r)[idx]
    t_k = np.fft.rfft(tau)[idx]
    v_k = np.fft.rfft(v)[idx]
    if not np.abs(r_k).any() or not np.abs(v_k).any():
        return None
    v_scale = float(np.max(np.abs(v_k)))
    v_k = v_k / v_scale
    r_c = np.conj(r_k)
    weight = 1.0 / np.sqrt(np.add.reduceat(np.abs(r_k) ** 2, starts))
    powers = np.stack([s**i for i in range(3)], axis=1)
    moments_v = np.add.reduceat(r_c * v_k, starts)

    def solve(x: FloatArray) -> tuple[FloatArray, FloatArray, ComplexArray]:
        wr, zeta, delay = TWO_PI * math.exp(x[0]), math.exp(x[1]), float(x[2])
        den = s * (s * s + 2.0 * zeta * wr * s + wr * wr)
        cols = np.concatenate(
            [(np.exp(-s * delay) * t_k / den)[:, None] * powers, powers / den[:, None]], axis=1
        )
        a = np.add.reduceat(r_c[:, None] * cols, starts, axis=0) * weight[:, None]
        y = moments_v * weight
        a_r = np.vstack([a.real, a.imag])
        y_r = np.concatenate([y.real, y.imag])
        norm = np.linalg.norm(a_r, axis=0)
        norm[norm == 0.0] = 1.0
        c = np.linalg.lstsq(a_r / norm, y_r, rcond=None)[0] / norm
        # The residuals, the coefficients (b0, b1, b2, then P's) and G at each bin (no delay).
        return a_r @ c - y_r, c, (powers @ c[:3]) / den

    lb = [math.log(0.8 * fr0), math.log(1e-4), -RECORD_MAX_DELAY_S]
    ub = [math.log(1.25 * fr0), math.log(0.7), RECORD_MAX_DELAY_S]
    scale = [0.01, 0.3, 1e-4]
    try:
        best = None
        for z0 in (0.005, 0.02, 0.05, 0.15):
            x0 = np.array([math.log(fr0), math.log(z0), 0.0])
            fit = optimize.least_squares(lambda x: solve(x)[0], x0, bounds=(lb, ub), x_scale=scale)
            if best is None or fit.cost < best.cost:
                best = fit
        assert best is not None
        # Second pass: each group weighted by the spread its sum has under the fitted model.
        g = solve(best.x)[2]
        spread = np.sqrt(np.add.reduceat(np.abs(r_k * g) ** 2, starts))
        if not (np.isfinite(spread).all() and (spread > 0.0).all()):
            return None
        weight = 1.0 / spread
        best = optimize.least_squares(lambda x: solve(x)[0], best.x, bounds=(lb, ub), x_scale=scale)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not best.success or not np.isfinite(best.x).all():
        return None
    fr, zeta = math.exp(float(best.x[0])), math.exp(float(best.x[1]))
    # The numerator is b2 (s^2 + 2 zeta_a w_a s + w_a^2): the anti-resonance from b0 / b2.
    b = solve(best.x)[1]
    anti = math.sqrt(b[0] / b[2]) / TWO_PI if b[2] > 0.0 and b[0] > 0.0 else None
    if anti is not None and not 0.05 * fr < anti < fr:
        anti = None
    jm = 1.0 / (b[2] * v_scale) if b[2] > 0.0 else None
    return RecordFit(fr, zeta, anti, jm)


def _refine_peak(f: FloatArray, y: FloatArray, i: int) -> float:
    if i <= 0 or i >= len(f) - 1:
        return float(f[i])
    x = np.log(f[i - 1 : i + 2])
    yy = y[i - 1 : i + 2]
    c2, c1, _ = np.polyfit(x - x[1], yy, 2)
    if c2 >= 0.0:
        return float(f[i])
    dx = float(np.clip(-c1 / (2.0 * c2), x[0] - x[1], x[2] - x[1]))
    return float(f[i] * math.exp(dx))


def _half_power_damping(f: FloatArray, mag: FloatArray, i: int, fr: float) -> float:
    """``(f2 - f1) / (2 f_r)`` from the -3 dB points of ``|G|`` around the peak."""
    level = mag[i] / math.sqrt(2.0)
    lo = i
    while lo > 0 and mag[lo] > level:
        lo -= 1
    hi = i
    while hi < len(f) - 1 and mag[hi] > level:
        hi += 1
    if mag[lo] > level or mag[hi] > level:
        return math.nan

    def cross(a: int, b: int) -> float:
        # Linear interpolation of the crossing between samples a and b.
        ma, mb = mag[a], mag[b]
        frac = (ma - level) / (ma - mb) if ma != mb else 0.0
        return float(f[a] + frac * (f[b] - f[a]))

    f1 = cross(lo + 1, lo)
    f2 = cross(hi - 1, hi)
    return max(0.0, (f2 - f1) / (2.0 * fr))


# ----------------------------------------------------------------------------------------------
# Model from the identification


def with_hidden_anti_resonance(
    resonances: Sequence[Resonance],
    motor_inertia: float,
    total_inertia: float,
    band_low_hz: float,
) -> list[Resonance]:
    """``resonances`` with the anti-resonance of the lowest one placed from the inertias when
    it lay below the band measured (``anti_freq_hz`` None); the others as they are.

    Above a two-mass mode's anti-resonance the FRF shows the motor alone (``motor_inertia``),
    the test moves the whole axis (``total_inertia``); ``R = J_L / J_M = (f_r / f_ar)^2 - 1``
    (anchors-tuning.md §2.1) gives ``f_ar = f_r sqrt(J_M / J)``. A belt or a long shaft on a
    heavy load (the benchmark's stress-soft60Hz: 60 Hz, load 30 x the motor, anti-resonance
    11 Hz) puts it below 20 Hz, where the PRBS record says little. Unchanged when the two
    inertias do not tell such a mode: the moves found no more than 1.3 x the motor's inertia
    (their fit runs up to 20 % high on a compliant axis), or the anti-resonance they imply lies
    inside the band, where it would have been seen.
    """
    out = list(resonances)
    if not out or not (motor_inertia > 0.0 and total_inertia > 1.3 * motor_inertia):
        return out
    i = min(range(len(out)), key=lambda k: out[k].freq_hz)
    r = out[i]
    if r.anti_freq_hz is not None:
        return out  # The lowest mode's anti-resonance was measured.
    f_ar = r.freq_hz * math.sqrt(motor_inertia / total_inertia)
    if f_ar >= band_low_hz:
        return out
    out[i] = Resonance(r.freq_hz, f_ar, r.peak_db, r.damping_estimate)
    return out


def plant_from_identification(
    inertia: float,
    resonances: Sequence[Resonance] = (),
    *,
    viscous: float = 0.0,
    current_loop_hz: float | None = 2000.0,
    default_damping: float = 0.03,
) -> PlantModel:
    """A :class:`PlantModel` from the total inertia and the resonances found.

    The first resonance that has an anti-resonance becomes the two-mass model: its ratio
    ``R = (f_r / f_ar)^2 - 1`` (anchors-tuning.md §2.1) splits ``J`` into ``J_M = J / (1 + R)``
    and ``J_L``. Further resonances become extra modes whose modal gain is estimated from the
    peak height: at its resonance a mode ``A s / (s^2 + 2 z w s + w^2)`` adds the real
    ``A / (2 z w)`` to the imaginary baseline ``1 / (j J_base w)`` (``J_base`` the inertia the
    FRF shows there), so ``A = 2 z w sqrt(|G_peak|^2 - 1 / (J_base w)^2)``. Damping estimates
    that are missing or above 0.3 are replaced by ``default_damping``; below 0.002
    (:data:`ZETA_FLOOR`) raised to it.
    """
    main: Resonance | None = None
    for r in resonances:
        if r.anti_freq_hz is not None and r.anti_freq_hz < r.freq_hz:
            main = r
            break
    if main is None:
        base = PlantModel(inertia, 0.0, None, default_damping, viscous, current_loop_hz)
        jm_base = inertia
    else:
        assert main.anti_freq_hz is not None
        ratio = (main.freq_hz / main.anti_freq_hz) ** 2 - 1.0
        jm = inertia / (1.0 + ratio)
        base = PlantModel(
            jm,
            inertia - jm,
            main.freq_hz,
            model_damping(main.damping_estimate, default_damping),
            viscous,
            current_loop_hz,
        )
        jm_base = jm
    modes: list[VibrationMode] = []
    for r in resonances:
        if r is main:
            continue
        zeta = model_damping(r.damping_estimate, default_damping)
        wr = TWO_PI * r.freq_hz
        j_here = jm_base if main is not None and r.freq_hz > main.freq_hz else inertia
        # At resonance the mode term is real and the baseline 1/(j J w) imaginary.
        g_peak = 10.0 ** (r.peak_db / 20.0) / (inertia * wr)
        g_base = 1.0 / (j_here * wr)
        excess = math.sqrt(max(g_peak**2 - g_base**2, (0.5 * g_base) ** 2))
        modes.append(VibrationMode(r.freq_hz, zeta, 2.0 * zeta * wr * excess))
    if modes:
        return PlantModel(
            base.motor_inertia,
            base.load_inertia,
            base.resonance_hz,
            base.damping,
            base.viscous,
            base.current_loop_hz,
            tuple(modes),
        )
    return base


def model_damping(zeta: float, default: float = 0.03) -> float:
    """The damping a model is given for the estimate ``zeta``: ``default`` when there is none
    or it is above 0.3, at least :data:`ZETA_FLOOR`."""
    # Below 0.002 the estimate says "very sharp", which the floor keeps on the cautious side;
    # an estimate above 0.3 or none at all says nothing, and the default stands in.
    if not math.isfinite(zeta) or zeta > 0.3:
        return default
    return max(zeta, ZETA_FLOOR)
