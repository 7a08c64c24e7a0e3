"""Linear model of the drive's discrete servo cascade: frequency responses, margins, stability.

What is modelled (docs/tuning.md, "The servo loop of the simulated drives"):

- the mechanics (:class:`PlantModel`): one rigid inertia ``1 / (J s + b)``, or the two-mass axis
  of anchors-tuning.md §2.1 measured at the motor (resonance ``f_r``, anti-resonance
  ``f_r / sqrt(1 + R)``), optionally with extra motor-side modes in modal form;
- the current loop as a first-order lag at ``current_loop_hz``;
- the sampled-data loop *exactly*: the continuous plant is discretised with a zero-order hold
  (ZOH) at the loop period ``T``, the position is sampled (encoder), the velocity is the backward
  difference ``(p[k] - p[k-1]) / T``, and the torque computed at tick ``k`` reaches the current
  loop after ``compute_delay`` samples;
- the PI velocity controller exactly as the drive runs it (``i += Kv e T / Ti`` then
  ``tau = Kv e + i``: ``C(z) = Kv (1 + (T / Ti) / (1 - z^-1))``), the torque low-pass and notches
  as the drive's biquads (``filters.py``) evaluated at ``z = e^(j w T)``, and the P position loop.

Dead time. anchors-tuning.md §2.1 / §3.1 lump "computation + ZOH + velocity differencing" into
``T_d = 1.5..2 T``. Here only the computation delay is a parameter (``compute_delay``, samples,
default 1: the torque computed from the sample at tick ``k`` is applied from tick ``k + 1``, as in
§3.1). The ZOH (half a sample of equivalent delay) and the backward difference (another half)
are not approximated as delays: they are in the exact discretisation. The equivalent dead time
at low frequency is therefore ``compute_delay + 1`` samples (2 T by default, 1.5 T with
``compute_delay = 0.5``). A fractional ``compute_delay`` is modelled exactly too: the ZOH input
then switches within the sample, which splits the input matrix in two (the "modified
z-transform" of a fractional delay).

Stability (:meth:`LoopModel.is_stable`) is decided on the eigenvalues of the closed-loop
discrete state-space model of the whole cascade (plant, delay line, differencing, PI, filters,
position loop) built by :meth:`LoopModel.closed_loop`: unlike a Nyquist count on a frequency
grid it cannot miss a lightly damped mode or mis-count encirclements around the double pole of
the PI + inertia at ``z = 1``. The same matrices drive :func:`simulate`.

Margins (:func:`margins`) are geometric: the phase margin is the smallest angular distance of
``L`` from ``-1`` at any gain crossing, the gain margin the smallest ``1/|L|`` at any crossing
of the negative real axis inside the unit circle, and ``M_s = max |1 / (1 + L)|``. They say how
far a loop is from instability, not whether it is stable: check :meth:`LoopModel.is_stable`
(the ``stable`` field of the margins returned by :class:`LoopModel`).

Over 700 lines: the plant, the discretised loop, the filters and the margins are one transfer-
function algebra on the same frequency grid and sample period; a module a block would import
each other in a ring.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache

import numpy as np
import numpy.typing as npt
import scipy.linalg  # type: ignore[import-untyped]

from servodesk.domain.tuning.filters import (
    Biquad,
    lowpass_coefficients,
    notch_coefficients,
)
from servodesk.domain.tuning.gains import ServoGains

__all__ = [
    "Biquad",
    "LoopModel",
    "Margins",
    "PlantModel",
    "VibrationMode",
    "biquad_response",
    "frequency_grid",
    "lowpass_coefficients",
    "margins",
    "notch_coefficients",
    "simulate",
]

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]

TWO_PI = 2.0 * math.pi


# ----------------------------------------------------------------------------------------------
# Plant


@dataclass(frozen=True, slots=True)
class VibrationMode:
    """An extra motor-side vibration mode in modal form: ``gain * s / (s^2 + 2 z w s + w^2)``.

    Added to the motor velocity / torque response of the main model (a second resonance, e.g. the
    250/900 Hz stress case of anchors-tuning.md §3.1). ``gain`` is in 1/(kg m^2): for the mode of
    a two-mass axis it would be ``J_L / (J_M (J_M + J_L))``.
    """

    freq_hz: float
    damping: float
    gain: float


@dataclass(frozen=True, slots=True)
class PlantModel:
    """Mechanics of one axis at the motor shaft, plus its current loop (SI units).

    ``resonance_hz = None``: one rigid inertia ``motor_inertia + load_inertia``. Otherwise the
    two-mass model of docs/tuning.md ("Plant files"): shaft stiffness
    ``k = w_r^2 J_M J_L / (J_M + J_L)``, damper ``c = 2 damping sqrt(k J_M J_L / (J_M + J_L))``,
    viscous friction on the motor. ``current_loop_hz`` None or 0: ideal torque.

    ``load_viscous`` is a damper from the load to the frame (two-mass only): the describing
    function of Coulomb friction on the load, ``4 F_c / (pi V_L)`` at a load velocity amplitude
    ``V_L``, used to check a loop against a load that sticks (0: free, large: locked).
    """

    motor_inertia: float
    load_inertia: float = 0.0
    resonance_hz: float | None = None
    damping: float = 0.03
    viscous: float = 0.0
    current_loop_hz: float | None = 2000.0
    extra_modes: tuple[VibrationMode, ...] = ()
    load_viscous: float = 0.0

    def __post_init__(self) -> None:
        if not self.motor_inertia > 0.0:
            raise ValueError(f"motor inertia must be positive, not {self.motor_inertia}")
        if self.load_inertia < 0.0:
            raise ValueError(f"load inertia must not be negative, not {self.load_inertia}")
        if self.resonance_hz is not None:
            if not self.resonance_hz > 0.0:
                raise ValueError(f"resonance must be positive, not {self.resonance_hz}")
            if self.load_inertia <= 0.0:
                raise ValueError("a two-mass model needs a load inertia")
        if self.load_viscous > 0.0 and self.resonance_hz is None:
            raise ValueError("a load damper needs a two-mass model")
        if self.damping < 0.0 or self.viscous < 0.0 or self.load_viscous < 0.0:
            raise ValueError("damping and viscous friction must not be negative")

    @property
    def total_inertia(self) -> float:
        return self.motor_inertia + self.load_inertia

    @property
    def inertia_ratio(self) -> float:
        """R = J_L / J_M."""
        return self.load_inertia / self.motor_inertia

    @property
    def anti_resonance_hz(self) -> float | None:
        """``f_r / sqrt(1 + R)`` (anchors-tuning.md §2.1); None for a rigid axis."""
        if self.resonance_hz is None:
            return None
        return self.resonance_hz / math.sqrt(1.0 + self.inertia_ratio)

    @property
    def stiffness(self) -> float:
        """Shaft stiffness k [N m/rad] (0 for a rigid axis)."""
        if self.resonance_hz is None:
            return 0.0
        jm, jl = self.motor_inertia, self.load_inertia
        return (TWO_PI * self.resonance_hz) ** 2 * jm * jl / (jm + jl)

    @property
    def shaft_damping(self) -> float:
        """Shaft damper c [N m s/rad] (0 for a rigid axis)."""
        if self.resonance_hz is None:
            return 0.0
        jm, jl = self.motor_inertia, self.load_inertia
        return 2.0 * self.damping * math.sqrt(self.stiffness * jm * jl / (jm + jl))

    def scaled(self, inertia: float = 1.0, resonance: float = 1.0) -> PlantModel:
        """The same axis with the load inertia and every resonance frequency scaled.

        Used for robustness checks (anchors-tuning.md §3.3: J_L x 0.8 / 1.25, f_r x 0.9 / 1.1).
        The shaft stiffness follows the scaled resonance (the two-mass ratio of f_r / f_ar is
        kept by the inertias).
        """
        modes = tuple(
            VibrationMode(m.freq_hz * resonance, m.damping, m.gain / inertia)
            for m in self.extra_modes
        )
        return PlantModel(
            motor_inertia=self.motor_inertia,
            load_inertia=self.load_inertia * inertia,
            resonance_hz=None if self.resonance_hz is None else self.resonance_hz * resonance,
            damping=self.damping,
            viscous=self.viscous,
            current_loop_hz=self.current_loop_hz,
            extra_modes=modes,
            load_viscous=self.load_viscous * inertia,
        )

    def resonances_hz(self) -> list[tuple[float, float]]:
        """(frequency, damping) of every resonance of the model, lowest first."""
        out = [(m.freq_hz, m.damping) for m in self.extra_modes]
        if self.resonance_hz is not None:
            out.append((self.resonance_hz, self.damping))
        return sorted(out)

    def response(self, w: npt.ArrayLike) -> ComplexArray:
        """Motor velocity / air-gap torque ``G(jw)`` of the mechanics (no current loop, no delay).

        Rigid: ``1 / (J s + b)``. Two-mass (viscous b on the motor, shaft k and c, load damper
        b_L): ``(J_L s^2 + (c + b_L) s + k) / ((J_M s + b)(J_L s^2 + (c + b_L) s + k)
        + (J_L s + b_L)(c s + k))``.
        """
        s = 1j * np.asarray(w, dtype=np.float64)
        b = self.viscous
        g: ComplexArray
        if self.resonance_hz is None:
            g = np.asarray(1.0 / (self.total_inertia * s + b), dtype=np.complex128)
        else:
            jm, jl = self.motor_inertia, self.load_inertia
            k, c = self.stiffness, self.shaft_damping
            bl = self.load_viscous
            num = jl * s**2 + (c + bl) * s + k
            g = num / ((jm * s + b) * num + (jl * s + bl) * (c * s + k))
        for m in self.extra_modes:
            wm = TWO_PI * m.freq_hz
            g = g + m.gain * s / (s**2 + 2.0 * m.damping * wm * s + wm**2)
        return g

    def sampled_velocity_response(self, w: npt.ArrayLike, rate_hz: float) -> ComplexArray:
        """Velocity / torque command as a drive running at ``rate_hz`` measures it: the command
        held over each period (zero-order hold) through the current loop and the mechanics,
        the velocity read at the end of that period and recorded with the command (what the
        simulated drives' recorder pairs: 2110h:07 and 606Ch of the same tick).

        :meth:`response` is the mechanics alone. Near the loop's Nyquist frequency the two part:
        the hold and the sampling turn the phase up to 0 deg at ``rate_hz / 2``, and the current
        loop takes the magnitude down (generic twin, 4 kHz with its 796 Hz current loop: 5 dB
        below the mechanics at 1 kHz, 15 dB at 2 kHz; docs/tuning.md, "Bode plot")."""
        a, _bu, _bw, c = self.state_space()
        # The motor velocity is d(c x)/dt = c A x: the command does not reach the position
        # directly (c B_u = 0), and an extra mode's position output is its q. Read at the end
        # of the period the command was held over: one step ahead of the state it acts on.
        dp = replace(discretise(self, float(rate_hz), 0.0), c=c @ a)
        ww = np.asarray(w, dtype=np.float64)
        return np.asarray(
            np.exp(1j * ww / rate_hz) * _solve_response(dp, ww, rate_hz), dtype=np.complex128
        )

    def state_space(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Continuous ``(A, B_u, B_w, C)``: input torque command (into the current loop) ``u``,
        external torque on the load ``w`` (positive accelerates), output motor position [rad].

        States: [current-loop torque (if any), motor angle, motor velocity, shaft twist
        (two-mass), load velocity (two-mass), (q, dq/dt) per extra mode].
        """
        n_cur = 1 if self.current_loop_hz else 0
        two = self.resonance_hz is not None
        n = n_cur + 2 + (2 if two else 0) + 2 * len(self.extra_modes)
        a = np.zeros((n, n))
        bu = np.zeros(n)
        bw = np.zeros(n)
        c = np.zeros(n)
        # "drive" is the air-gap torque: the current-loop state, or u itself.
        drive = np.zeros(n)
        drive_u = 0.0
        if n_cur:
            wc = TWO_PI * float(self.current_loop_hz or 0.0)
            a[0, 0] = -wc
            bu[0] = wc
            drive[0] = 1.0
        else:
            drive_u = 1.0
        th, vm = n_cur, n_cur + 1
        a[th, vm] = 1.0
        c[th] = 1.0
        if not two:
            jt = self.total_inertia
            a[vm] += drive / jt
            bu[vm] += drive_u / jt
            a[vm, vm] -= self.viscous / jt
            bw[vm] = 1.0 / jt
            nxt = vm + 1
        else:
            jm, jl = self.motor_inertia, self.load_inertia
            k, cd = self.stiffness, self.shaft_damping
            tw, vl = vm + 1, vm + 2
            a[vm] += drive / jm
            bu[vm] += drive_u / jm
            a[vm, vm] -= (self.viscous + cd) / jm
            a[vm, tw] -= k / jm
            a[vm, vl] += cd / jm
            a[tw, vm] = 1.0
            a[tw, vl] = -1.0
            a[vl, tw] = k / jl
            a[vl, vm] = cd / jl
            a[vl, vl] = -(cd + self.load_viscous) / jl
            bw[vl] = 1.0 / jl
            nxt = vl + 1
        for m in self.extra_modes:
            wm = TWO_PI * m.freq_hz
            q, dq = nxt, nxt + 1
            a[q, dq] = 1.0
            a[dq] += m.gain * drive
            bu[dq] += m.gain * drive_u
            a[dq, q] -= wm * wm
            a[dq, dq] -= 2.0 * m.damping * wm
            c[q] = 1.0
            nxt += 2
        return a, bu, bw, c


# ----------------------------------------------------------------------------------------------
# Frequency grid and margins


def frequency_grid(
    rate_hz: float,
    centres_hz: Iterable[tuple[float, float]] = (),
    n: int = 900,
    f_min_hz: float = 0.5,
) -> FloatArray:
    """Angular frequencies [rad/s] for loop analysis: log-spaced ``f_min_hz .. 0.499 rate``
    plus dense clusters around ``(frequency, damping)`` centres (resonances, notches).

    A lightly damped peak is only ``2 zeta f`` wide at half power (6 % at zeta = 0.03): a plain
    log grid of ~1 % spacing would sample it with a handful of points and misjudge ``M_s`` and the
    gain margin, so each centre gets 49 points spread over +-6 zeta (spacing zeta / 4, peak error
    below 0.1 dB).
    """
    f_max = 0.499 * rate_hz
    parts = [np.geomspace(f_min_hz, f_max, n)]
    for f0, zeta in centres_hz:
        z = max(float(zeta), 0.004)
        cluster = f0 * (1.0 + z * np.linspace(-6.0, 6.0, 49))
        parts.append(cluster[(cluster > f_min_hz) & (cluster < f_max)])
    f = np.unique(np.concatenate(parts))
    return TWO_PI * f


@dataclass(frozen=True, slots=True)
class Margins:
    """Stability margins of one loop (see the module docstring for the definitions).

    ``phase_margin_deg`` / ``gain_margin_db`` are the worst over all crossings (``inf`` when there
    is none); ``crossover_hz`` is the gain crossing that sets the phase margin (NaN if none),
    ``phase_crossover_hz`` the negative-real-axis crossing that sets the gain margin.
    ``stable`` is the eigenvalue verdict when known (margins from :class:`LoopModel`), else None.
    ``left_crossings``: crossings of the negative real axis left of -1 (see
    :func:`margins_batch`); a design requires 0 (no conditionally stable loops).
    """

    phase_margin_deg: float
    gain_margin_db: float
    crossover_hz: float
    ms_db: float
    phase_crossover_hz: float = math.nan
    stable: bool | None = None
    left_crossings: int = 0

    def meets(self, pm_min: float = 45.0, gm_min_db: float = 8.0, ms_max_db: float = 6.0) -> bool:
        """True when stable (or unknown), not conditionally stable, and every margin meets its
        target."""
        return (
            self.stable is not False
            and self.left_crossings == 0
            and self.phase_margin_deg >= pm_min
            and self.gain_margin_db >= gm_min_db
            and self.ms_db <= ms_max_db
        )


@dataclass(frozen=True, slots=True)
class MarginArrays:
    """Vectorised margins (see :func:`margins_batch`), each of the loops' leading shape."""

    pm_deg: FloatArray
    gm_db: FloatArray
    crossover_hz: FloatArray
    ms_db: FloatArray
    phase_crossover_hz: FloatArray
    #: Crossings of the negative real axis left of -1 (plus one if the loop starts there).
    left_crossings: npt.NDArray[np.int64]


def _row_min(
    n_rows: int, rows: npt.NDArray[np.intp], vals: FloatArray, where: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Per-row minimum of sparse ``vals`` and the ``where`` value at it (inf / NaN if none)."""
    best = np.full(n_rows, np.inf)
    at = np.full(n_rows, np.nan)
    if len(rows):
        order = np.lexsort((vals, rows))
        r, v, wv = rows[order], vals[order], where[order]
        first = np.ones(len(r), dtype=bool)
        first[1:] = r[1:] != r[:-1]
        best[r[first]] = v[first]
        at[r[first]] = wv[first]
    return best, at


def margins_batch(w: FloatArray, loop: ComplexArray) -> MarginArrays:
    """Vectorised :func:`margins` over the leading axes of ``loop`` (frequency last).

    Between two grid points ``L`` is interpolated linearly in the complex plane (the grid is
    dense enough for this to be exact to well under a degree), so no phase unwrapping is needed
    and a fast-turning resonance cannot be mistaken for a wrap. Crossings are sparse, so they
    are located on the whole array and evaluated only where they are.

    ``left_crossings`` counts the crossings of the negative real axis *outside* the unit circle
    (left of -1), plus one when the loop starts (lowest frequency) in the second quadrant, i.e.
    already past -180 deg: with the open-loop poles of this cascade (all stable except the
    integrators at ``z = 1``) a loop with ``left_crossings == 0`` and a positive phase margin
    is stable; otherwise the geometric margins can look fine on an unstable loop (e.g. a
    low-pass far below the crossover turning the phase through -180 deg at high gain).
    """
    loop = np.asarray(loop, dtype=np.complex128)
    lead = loop.shape[:-1]
    nf = loop.shape[-1]
    flat = loop.reshape(-1, nf)
    n_rows = flat.shape[0]
    f = np.asarray(w, dtype=np.float64) / TWO_PI
    re, im = flat.real, flat.imag
    m2 = re * re + im * im

    # Gain crossings: |L| passes 1.
    above = m2 > 1.0
    rows, cols = np.nonzero(above[:, :-1] != above[:, 1:])
    lo, hi = flat[rows, cols], flat[rows, cols + 1]
    llo = 0.5 * np.log(np.maximum(m2[rows, cols], 1e-300))
    lhi = 0.5 * np.log(np.maximum(m2[rows, cols + 1], 1e-300))
    frac = llo / (llo - lhi)
    lc = lo + frac * (hi - lo)
    pm_v = 180.0 - np.degrees(np.abs(np.angle(lc)))
    fc_v = f[cols] * np.exp(frac * np.log(f[cols + 1] / f[cols]))
    pm, fc = _row_min(n_rows, rows, pm_v, fc_v)

    # Phase crossings: Im(L) changes sign where Re(L) < 0 (the negative real axis).
    pos = im > 0.0
    rows, cols = np.nonzero(pos[:, :-1] != pos[:, 1:])
    i0, i1 = im[rows, cols], im[rows, cols + 1]
    pfrac = i0 / (i0 - i1)
    re_c = re[rows, cols] + pfrac * (re[rows, cols + 1] - re[rows, cols])
    inside = (re_c < 0.0) & (re_c > -1.0)
    with np.errstate(divide="ignore"):
        gm_v = -20.0 * np.log10(np.maximum(-re_c[inside], 1e-300))
    fp_v = f[cols] * np.exp(pfrac * np.log(f[cols + 1] / f[cols]))
    gm, fp = _row_min(n_rows, rows[inside], gm_v, fp_v[inside])
    left = np.bincount(rows[re_c <= -1.0], minlength=n_rows).astype(np.int64)
    left += ((re[:, 0] < 0.0) & (im[:, 0] > 0.0) & (m2[:, 0] > 1.0)).astype(np.int64)

    d2 = (re + 1.0) ** 2 + im * im
    with np.errstate(divide="ignore"):
        ms = -10.0 * np.log10(np.min(d2, axis=-1))
    return MarginArrays(
        pm.reshape(lead),
        gm.reshape(lead),
        fc.reshape(lead),
        ms.reshape(lead),
        fp.reshape(lead),
        left.reshape(lead),
    )


def margins(w: npt.ArrayLike, loop: npt.ArrayLike) -> Margins:
    """Phase / gain margins, crossover and ``M_s`` of the open loop ``loop`` sampled at ``w``.

    ``w`` in rad/s, increasing (log-spaced recommended, see :func:`frequency_grid`). Robust to
    multiple crossings: each margin is the worst over all of them.
    """
    m = margins_batch(np.asarray(w, dtype=np.float64), np.asarray(loop, dtype=np.complex128))
    return Margins(
        float(m.pm_deg),
        float(m.gm_db),
        float(m.crossover_hz),
        float(m.ms_db),
        float(m.phase_crossover_hz),
        left_crossings=int(m.left_crossings),
    )


def first_below(w: FloatArray, mag: FloatArray, level: float) -> FloatArray:
    """Frequency [Hz] where ``mag`` (leading axes batched) first falls below ``level``
    (log-log interpolation); NaN where it never does."""
    f = w / TWO_PI
    below = mag < level
    has = below.any(axis=-1)
    i = np.argmax(below, axis=-1)
    i0 = np.maximum(i - 1, 0)
    m0 = np.take_along_axis(mag, i0[..., None], axis=-1)[..., 0]
    m1 = np.take_along_axis(mag, i[..., None], axis=-1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.log(m0 / level) / np.log(m0 / m1)
    frac = np.where((i > 0) & np.isfinite(frac), np.clip(frac, 0.0, 1.0), 0.0)
    out = f[i0] * np.exp(frac * np.log(f[i] / f[i0]))
    return np.where(has & (i > 0), out, np.nan)


# ----------------------------------------------------------------------------------------------
# Discrete pieces


def biquad_response(coeffs: Biquad, w: npt.ArrayLike, rate_hz: float) -> ComplexArray:
    """``H(e^(j w T))`` of a biquad ``(b0, b1, b2, a1, a2)``."""
    zi = np.exp(-1j * np.asarray(w, dtype=np.float64) / rate_hz)  # z^-1
    b0, b1, b2, a1, a2 = coeffs
    return (b0 + b1 * zi + b2 * zi**2) / (1.0 + a1 * zi + a2 * zi**2)  # type: ignore[no-any-return]


def gain_filters(gains: ServoGains, rate_hz: float) -> list[Biquad]:
    """The active biquads of the torque-command chain, in drive order (LPF, notch 1, notch 2)."""
    out: list[Biquad] = []
    if gains.torque_lpf_hz > 0.0:
        out.append(lowpass_coefficients(gains.torque_lpf_hz, rate_hz))
    if gains.notch1_hz > 0.0:
        out.append(
            notch_coefficients(gains.notch1_hz, gains.notch1_width, gains.notch1_depth, rate_hz)
        )
    if gains.notch2_hz > 0.0:
        out.append(
            notch_coefficients(gains.notch2_hz, gains.notch2_width, gains.notch2_depth, rate_hz)
        )
    return out


def filters_response(filters: Sequence[Biquad], w: FloatArray, rate_hz: float) -> ComplexArray:
    out = np.ones(w.shape, dtype=np.complex128)
    for bq in filters:
        out = out * biquad_response(bq, w, rate_hz)
    return out


def pi_response(kp_vel: float, ti_vel: float, w: npt.ArrayLike, rate_hz: float) -> ComplexArray:
    """``Kv (1 + (T / Ti) / (1 - z^-1))``: the drive's ``i += Kv e T / Ti; tau = Kv e + i``."""
    zi = np.exp(-1j * np.asarray(w, dtype=np.float64) / rate_hz)
    if ti_vel > 0.0:
        return kp_vel * (1.0 + (1.0 / (rate_hz * ti_vel)) / (1.0 - zi))  # type: ignore[no-any-return]
    return kp_vel * np.ones_like(zi)  # type: ignore[no-any-return]


@dataclass(frozen=True, slots=True)
class DiscretePlant:
    """ZOH discretisation of a :class:`PlantModel` with the computation delay.

    ``x[k+1] = ad x[k] + b_now u[k-m] + b_prev u[k-m-1] + bw w[k]``, ``theta[k] = c x[k]``, with
    ``m = floor(compute_delay)``; ``b_prev`` is zero for a whole-sample delay.
    """

    ad: FloatArray
    b_now: FloatArray
    b_prev: FloatArray
    bw: FloatArray
    c: FloatArray
    delay_whole: int
    fractional: bool


def _zoh(a: FloatArray, b: FloatArray, h: float) -> tuple[FloatArray, FloatArray]:
    """``(e^(A h), int_0^h e^(A s) ds B)`` from one matrix exponential of ``[[A, B], [0, 0]]``."""
    n = a.shape[0]
    m = b.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n] = a * h
    big[:n, n:] = b * h
    e = scipy.linalg.expm(big)
    return np.asarray(e[:n, :n]), np.asarray(e[:n, n:])


@lru_cache(maxsize=256)
def discretise(plant: PlantModel, rate_hz: float, compute_delay: float) -> DiscretePlant:
    """Exact ZOH discretisation of the plant with a (possibly fractional) input delay.

    Cached (the plant is immutable and design searches discretise the same few models many
    times); the returned arrays must not be modified."""
    if compute_delay < 0.0:
        raise ValueError(f"compute delay must not be negative, not {compute_delay}")
    a, bu, bw, c = plant.state_space()
    t = 1.0 / rate_hz
    m = math.floor(compute_delay + 1e-12)
    delta = compute_delay - m
    if delta < 1e-9:
        delta = 0.0
    ad, gam = _zoh(a, np.column_stack([bu, bw]), t)
    b_full, bw_d = gam[:, 0], gam[:, 1]
    if delta == 0.0:
        return DiscretePlant(ad, b_full, np.zeros_like(b_full), bw_d, c, m, False)
    # Within each sample the held input switches at delta T from u[k-m-1] to u[k-m].
    e1, g1 = _zoh(a, bu[:, None], delta * t)
    e2, g2 = _zoh(a, bu[:, None], (1.0 - delta) * t)
    del e1
    b_prev = (e2 @ g1)[:, 0]
    b_now = g2[:, 0]
    return DiscretePlant(ad, b_now, b_prev, bw_d, c, m, True)


#: Entries :func:`plant_position_response` keeps (0: none). A design search checks the margins
#: of every candidate on the same few plants, on frequency grids that depend on the plant and
#: the notches only (:attr:`LoopModel.grid`), and the solve below was about 60 % of a margin
#: check (bench/bench_tuning_design.py).
RESPONSE_CACHE_SIZE = 64
_responses: dict[tuple[int, float, bytes], tuple[DiscretePlant, ComplexArray]] = {}


def plant_position_response(dp: DiscretePlant, w: FloatArray, rate_hz: float) -> ComplexArray:
    """Encoder angle / torque command (after the filters) at ``z = e^(j w T)``.

    Recent results are kept (:data:`RESPONSE_CACHE_SIZE`) and returned read-only."""
    w = np.asarray(w, dtype=np.float64)
    key = (id(dp), rate_hz, w.tobytes())
    hit = _responses.get(key)
    # The entry holds the plant itself, so its id cannot have been reused by another.
    if hit is not None and hit[0] is dp:
        return hit[1]
    out = _solve_response(dp, w, rate_hz)
    if RESPONSE_CACHE_SIZE > 0:
        if len(_responses) >= RESPONSE_CACHE_SIZE:
            _responses.clear()
        out.setflags(write=False)
        _responses[key] = (dp, out)
    return out


def _solve_response(dp: DiscretePlant, w: FloatArray, rate_hz: float) -> ComplexArray:
    z = np.exp(1j * w / rate_hz)
    n = dp.ad.shape[0]
    mat = z[:, None, None] * np.eye(n)[None] - dp.ad[None]
    rhs = np.broadcast_to(np.column_stack([dp.b_now, dp.b_prev]), (len(z), n, 2))
    sol = np.linalg.solve(mat, rhs)
    x = sol[:, :, 0] + sol[:, :, 1] / z[:, None]
    return (x @ dp.c) * z ** (-dp.delay_whole)  # type: ignore[no-any-return]


# ----------------------------------------------------------------------------------------------
# The loop


@dataclass(frozen=True, slots=True)
class ClosedLoop:
    """Closed-loop discrete state-space model of the cascade.

    Inputs: ``[p_demand, v_demand, a_demand, tau_test, load_torque]`` (rad, rad/s, rad/s^2,
    N m added to the torque command before the filters, N m on the load). Outputs:
    ``[theta (encoder angle, rad), torque command after the filters (N m), measured velocity
    (rad/s)]``. ``x[k+1] = a x[k] + b u[k]``, ``y[k] = c x[k] + d u[k]``.
    ``translation_mode`` is True when the position loop is open (``kp_pos = 0``): the closed
    loop then has one eigenvalue at exactly 1 (the axis may rest anywhere).
    """

    a: FloatArray
    b: FloatArray
    c: FloatArray
    d: FloatArray
    translation_mode: bool


def _series(
    s1: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    s2: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Discrete state-space ``s2 after s1`` (outputs of s1 feed s2)."""
    a1, b1, c1, d1 = s1
    a2, b2, c2, d2 = s2
    n1, n2 = a1.shape[0], a2.shape[0]
    a = np.zeros((n1 + n2, n1 + n2))
    a[:n1, :n1] = a1
    a[n1:, :n1] = b2 @ c1
    a[n1:, n1:] = a2
    b = np.vstack([b1, b2 @ d1])
    c = np.hstack([d2 @ c1, c2])
    d = d2 @ d1
    return a, b, c, d


@dataclass(frozen=True)
class LoopModel:
    """The cascade of one axis: plant, discrete loop and gains (see the module docstring).

    Frequencies ``w`` are in rad/s. When ``w`` is omitted the analysis methods use
    :attr:`grid`, a :func:`frequency_grid` refined around the plant's resonances and the
    notches.
    """

    plant: PlantModel
    rate_hz: float
    gains: ServoGains = field(default_factory=ServoGains)
    compute_delay: float = 1.0

    @property
    def period(self) -> float:
        return 1.0 / self.rate_hz

    def with_gains(self, gains: ServoGains) -> LoopModel:
        return LoopModel(self.plant, self.rate_hz, gains, self.compute_delay)

    @cached_property
    def discrete_plant(self) -> DiscretePlant:
        return discretise(self.plant, self.rate_hz, self.compute_delay)

    @cached_property
    def grid(self) -> FloatArray:
        centres = list(self.plant.resonances_hz())
        far = self.plant.anti_resonance_hz
        if far is not None:
            centres.append((far, self.plant.damping))
        g = self.gains
        for hz, width in ((g.notch1_hz, g.notch1_width), (g.notch2_hz, g.notch2_width)):
            if hz > 0.0:
                centres.append((hz, max(0.25 * width, 0.01)))
        return frequency_grid(self.rate_hz, centres)

    def _w(self, w: npt.ArrayLike | None) -> FloatArray:
        return self.grid if w is None else np.atleast_1d(np.asarray(w, dtype=np.float64))

    # Responses -----------------------------------------------------------------------------

    def position_plant_response(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        """Encoder angle / torque command after the filters (delay, current loop, ZOH)."""
        ww = self._w(w)
        return plant_position_response(self.discrete_plant, ww, self.rate_hz)

    def plant_response(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        """Measured velocity / torque command after the filters: what an FRF measures
        (``identify.frequency_response`` with 2110h:07 as input and 606Ch as output)."""
        ww = self._w(w)
        zi = np.exp(-1j * ww / self.rate_hz)
        return self.position_plant_response(ww) * (1.0 - zi) * self.rate_hz  # type: ignore[no-any-return]

    def filter_response(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        ww = self._w(w)
        return filters_response(gain_filters(self.gains, self.rate_hz), ww, self.rate_hz)

    def controller_response(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        ww = self._w(w)
        return pi_response(self.gains.kp_vel, self.gains.ti_vel, ww, self.rate_hz)

    def velocity_open_loop(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        """``L_v = C_PI F G`` broken at the velocity error."""
        ww = self._w(w)
        return self.controller_response(ww) * self.filter_response(ww) * self.plant_response(ww)

    def velocity_closed_loop(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        """Measured velocity / velocity command ``L_v / (1 + L_v)``."""
        lv = self.velocity_open_loop(w)
        return lv / (1.0 + lv)

    def position_open_loop(self, w: npt.ArrayLike | None = None) -> ComplexArray:
        """``L_p = Kp C F P_theta / (1 + L_v)`` broken at the position error (velocity loop
        closed; the feed-forwards do not enter the loop)."""
        ww = self._w(w)
        cf = self.controller_response(ww) * self.filter_response(ww)
        pth = self.position_plant_response(ww)
        zi = np.exp(-1j * ww / self.rate_hz)
        lv = cf * pth * (1.0 - zi) * self.rate_hz
        return self.gains.kp_pos * cf * pth / (1.0 + lv)  # type: ignore[no-any-return]

    # Analysis ------------------------------------------------------------------------------

    def velocity_margins(self, w: npt.ArrayLike | None = None) -> Margins:
        ww = self._w(w)
        m = margins(ww, self.velocity_open_loop(ww))
        return _with_stable(m, self.is_stable(position_loop=False))

    def position_margins(self, w: npt.ArrayLike | None = None) -> Margins:
        ww = self._w(w)
        m = margins(ww, self.position_open_loop(ww))
        return _with_stable(m, self.is_stable(position_loop=True))

    def velocity_bandwidth_hz(self, w: npt.ArrayLike | None = None) -> float:
        """-3 dB frequency of ``|T_v|`` relative to its low-frequency value (first crossing)."""
        ww = self._w(w)
        t = np.abs(self.velocity_closed_loop(ww))
        if not t[0] > 0.0:
            return math.nan
        return float(first_below(ww, t / t[0], 1.0 / math.sqrt(2.0)))

    def closed_loop(self) -> ClosedLoop:
        """The closed-loop discrete state-space model of the whole cascade (see
        :class:`ClosedLoop`); linear: no torque limit, no anti-windup, no quantisation."""
        g = self.gains
        t = self.period
        kv, kp = g.kp_vel, g.kp_pos
        gi = kv * t / g.ti_vel if g.ti_vel > 0.0 else 0.0
        # Controller before the filters: states [theta_prev, (i_prev)], inputs
        # [theta, p_dem, v_dem, a_dem, tau_test], output the torque command.
        # e_v = -(Kp + 1/T) theta + theta_prev / T + Kp p + vff v; i = i_prev + gi e_v;
        # tau = Kv e_v + i + Jff a + tau_test.
        ev_x = np.array([1.0 / t])
        ev_u = np.array([-(kp + 1.0 / t), kp, g.vel_ff, 0.0, 0.0])
        ka = np.zeros((1, 1))
        kb = np.zeros((1, 5))
        kb[0, 0] = 1.0
        kc = (kv + gi) * ev_x[None, :]
        kd = ((kv + gi) * ev_u + np.array([0.0, 0.0, 0.0, g.inertia_ff, 1.0]))[None, :]
        if gi > 0.0:
            ka = np.array([[0.0, 0.0], [gi / t, 1.0]])
            kb = np.vstack([kb, gi * ev_u[None, :]])
            kc = np.array([[(kv + gi) / t, 1.0]])
        ctrl = (ka, kb, kc, kd)
        for b0, b1, b2, a1, a2 in gain_filters(g, self.rate_hz):
            # Transposed direct form II: y = b0 x + s1; s1' = b1 x - a1 y + s2; s2' = b2 x - a2 y.
            fa = np.array([[-a1, 1.0], [-a2, 0.0]])
            fb = np.array([[b1 - a1 * b0], [b2 - a2 * b0]])
            fc = np.array([[1.0, 0.0]])
            fd = np.array([[b0]])
            ctrl = _series(ctrl, (fa, fb, fc, fd))
        ka, kb, kc, kd = ctrl
        nk = ka.shape[0]

        # Plant with the delay line: states [x, u[k-1], ..., u[k-M]].
        dp = self.discrete_plant
        m = dp.delay_whole
        big_m = m + 1 if dp.fractional else m
        npl = dp.ad.shape[0]
        n_p = npl + big_m
        pa = np.zeros((n_p, n_p))
        pb = np.zeros(n_p)
        pa[:npl, :npl] = dp.ad
        # b_now multiplies u[k-m] (u[k] itself when m = 0), b_prev u[k-m-1].
        for coef, lag in ((dp.b_now, m), (dp.b_prev, m + 1)):
            if lag == 0:
                pb[:npl] += coef
            elif lag <= big_m:
                pa[:npl, npl + lag - 1] += coef
        if big_m:
            pb[npl] = 1.0
            for j in range(1, big_m):
                pa[npl + j, npl + j - 1] = 1.0
        pw = np.zeros(n_p)
        pw[:npl] = dp.bw
        pc = np.zeros(n_p)
        pc[:npl] = dp.c

        # Close the loop: u = kc xk + kd[:, 0] theta + kd[:, 1:] r; theta = pc xp.
        n = nk + n_p
        a = np.zeros((n, n))
        a[:nk, :nk] = ka
        a[:nk, nk:] = np.outer(kb[:, 0], pc)
        a[nk:, :nk] = np.outer(pb, kc[0])
        a[nk:, nk:] = pa + np.outer(pb, kd[0, 0] * pc)
        b = np.zeros((n, 5))
        b[:nk, :4] = kb[:, 1:]
        b[nk:, :4] = np.outer(pb, kd[0, 1:])
        b[nk:, 4] = pw
        c = np.zeros((3, n))
        d = np.zeros((3, 5))
        c[0, nk:] = pc
        c[1, :nk] = kc[0]
        c[1, nk:] = kd[0, 0] * pc
        d[1, :4] = kd[0, 1:]
        # Measured velocity (theta - theta_prev) / T; theta_prev is controller state 0 (the
        # filters are appended after it by _series).
        c[2, nk:] = pc / t
        c[2, 0] = -1.0 / t
        return ClosedLoop(a, b, c, d, translation_mode=(kp == 0.0))

    def eigenvalues(self) -> npt.NDArray[np.complex128]:
        """Closed-loop eigenvalues, without the translation mode when the position loop is
        open."""
        cl = self.closed_loop()
        ev = np.linalg.eigvals(cl.a)
        if cl.translation_mode and len(ev):
            i = int(np.argmin(np.abs(ev - 1.0)))
            if abs(ev[i] - 1.0) < 1e-6:
                ev = np.delete(ev, i)
        return np.asarray(ev, dtype=np.complex128)

    def is_stable(self, position_loop: bool = True) -> bool:
        """True when every closed-loop eigenvalue is inside the unit circle.

        ``position_loop=False`` checks the velocity loop alone (``kp_pos`` taken as 0).
        """
        model = self if position_loop else self.with_gains(self.gains.replace(kp_pos=0.0))
        ev = model.eigenvalues()
        return bool(np.all(np.abs(ev) < 1.0 - 1e-9))


def _with_stable(m: Margins, stable: bool) -> Margins:
    return Margins(
        m.phase_margin_deg,
        m.gain_margin_db,
        m.crossover_hz,
        m.ms_db,
        m.phase_crossover_hz,
        stable,
        m.left_crossings,
    )


def simulate(
    loop: LoopModel,
    p_demand: npt.ArrayLike,
    v_demand: npt.ArrayLike | None = None,
    a_demand: npt.ArrayLike | None = None,
    tau_test: npt.ArrayLike | None = None,
    load_torque: npt.ArrayLike | None = None,
    coulomb: float = 0.0,
    coulomb_velocity: float = 0.05,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Simulate the closed loop sample by sample from rest at 0 rad.

    Inputs are sampled at the loop rate (one value per tick). ``coulomb`` adds a smooth Coulomb
    friction ``-Tc tanh(v_load / coulomb_velocity)`` on the load (held over each tick), the one
    nonlinearity worth having for settling studies (anchors-tuning.md §3.7, integrator hunting).
    Returns ``(theta, torque_command, measured_velocity)`` per tick.
    """
    cl = loop.closed_loop()
    p = np.asarray(p_demand, dtype=np.float64)
    n = len(p)
    u = np.zeros((n, 5))
    u[:, 0] = p
    for col, arr in ((1, v_demand), (2, a_demand), (3, tau_test), (4, load_torque)):
        if arr is not None:
            u[:, col] = np.asarray(arr, dtype=np.float64)
    a, b, c, d = cl.a, cl.b, cl.c, cl.d
    # The input terms of every tick at once; the loop then costs one mat-vec per tick.
    bu = u @ b.T
    xs = np.empty((n, a.shape[0]))
    x = np.zeros(a.shape[0])
    if coulomb > 0.0:
        vel_row = _load_velocity_row(loop, a.shape[0])
        bw = b[:, 4] * -coulomb
        inv_v0 = 1.0 / coulomb_velocity
        tanh = math.tanh
        for k in range(n):
            xs[k] = x
            x = a @ x + bu[k] + bw * tanh(float(vel_row @ x) * inv_v0)
    else:
        for k in range(n):
            xs[k] = x
            x = a @ x + bu[k]
    y = xs @ c.T + u @ d.T
    return y[:, 0], y[:, 1], y[:, 2]


def _load_velocity_row(loop: LoopModel, n: int) -> FloatArray:
    """Selector of the load velocity in the closed-loop state (motor velocity if rigid)."""
    plant = loop.plant
    n_cur = 1 if plant.current_loop_hz else 0
    idx = n_cur + (3 if plant.resonance_hz is not None else 1)
    dp = loop.discrete_plant
    n_p = dp.ad.shape[0] + (dp.delay_whole + (1 if dp.fractional else 0))
    nk = n - n_p
    row = np.zeros(n)
    row[nk + idx] = 1.0
    return row
