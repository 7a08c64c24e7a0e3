"""The simulated plant: current loop, motor and load mechanics, encoder.

Pure Python in the per-step path (one axis is a handful of floats, and scalar arithmetic is
faster than array calls at this size; numpy only draws the torque noise in blocks).
Fixed-step integration; :meth:`Plant.step` advances one step.

The mechanics sit behind the small :class:`Mechanics` protocol. :class:`RigidMechanics` is
motor and load as one inertia; :class:`TwoMassMechanics` couples them by a shaft spring and
damper (docs/tuning.md, "Plant files": ``k = w_r^2 J_M J_L / (J_M + J_L)``, ``c = 2 zeta
sqrt(k J_M J_L / (J_M + J_L))``), so that the motor velocity shows the anti-resonance at
``w_r / sqrt(1 + J_L/J_M)`` and the resonance at ``w_r``. :func:`mechanics_for` picks one from
:class:`PlantParams` (``resonance_hz`` None: rigid).

Integration (``PlantParams.exact``, set for plant files and, since the third session of
2026-11-29, for the profile twins unless their ``simulation.exact_integration`` is false):
with ``exact`` the plant follows a
torque command held over each step (zero-order hold), so it is what a sampled drive sees at
any loop rate: the current loop's first-order lag is solved exactly and the mechanics get its
mean over the step (exact for the velocity change); :class:`RigidMechanics` moves by the step's
mean velocity. Without it (what every profile twin did until then) the mechanics get the lag's
value at the end of the step and the rigid axis moves semi-implicitly (position with the new
velocity): the position is then half a step ahead of a held torque, a phase lead of
``w dt / 2`` that makes a fast loop look better damped (at 4 kHz a 200 Hz velocity loop on a
ratio-1 axis: damping 0.57 instead of 0.24; at 16 kHz the difference is small), and a tuning's
identification on the generic twin (4 kHz) found its inertia 0.5 % light, its friction at the
test moves' speed 39 % high and a gravity of -1.8 mN m where there is none (exact: +0.2 %,
+1.6 %, 0.03 mN m).
:class:`TwoMassMechanics` always advances with the matrix exponential of its linear dynamics
(computed once per step size), exact for the torque it is given: a semi-implicit Euler step
made the closed loop look better damped than it is near an 800-1000 Hz resonance at 16 kHz
(0.08 instead of 0.065) and turned an unstable 4 kHz loop (400 Hz resonance) into a
well-damped one. Friction and gravity enter as a torque held over the step, with the sign of
the Coulomb torque from the start of the step; a velocity that crosses zero within the step
stops there when static friction can hold it (no chatter).

Disturbances: Coulomb friction (with sticking) and gravity act on the load, viscous friction on
the motor; ``torque_noise`` is white, one Gaussian draw per plant step added to the air-gap
torque (seeded, so a run is repeatable; drawn by numpy in blocks of 4096, as one
``random.gauss`` per step cost more than the servo loop's tick); the encoder (on the motor)
is quantised by ``floor`` and may carry Gaussian count noise (``noise_counts``, tests only).
"""

from __future__ import annotations

import functools
import math
import random
from collections import deque
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from servodesk.domain.profile import SimSettings

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class PlantParams:
    """Physical parameters of one axis (SI units: kg m², N m, N m s/rad, s)."""

    motor_inertia: float = 3.7e-5
    load_inertia: float = 1.11e-4
    #: Viscous friction at the motor [N m s/rad].
    viscous: float = 1.0e-4
    #: Coulomb friction at the load [N m].
    coulomb: float = 0.02
    rated_torque: float = 1.27
    peak_torque: float = 3.8
    counts_per_rev: int = 1 << 17
    #: Current (torque) loop as a first-order lag with this time constant.
    current_tau: float = 2.0e-4
    #: Transport delay of the torque command (PWM and computation), rounded to whole steps.
    dead_time: float = 0.0
    #: Standard deviation of the encoder reading in counts (0: ideal encoder).
    noise_counts: float = 0.0
    seed: int = 0
    #: Shaft resonance of the two-mass model [Hz]; None: motor and load are rigid.
    resonance_hz: float | None = None
    #: Damping ratio of the shaft mode (two-mass model only).
    damping: float = 0.03
    #: Constant load torque [N m], pulling toward negative positions (a hanging load).
    gravity: float = 0.0
    #: White torque noise at the motor [N m rms], one draw per plant step (0: none).
    torque_noise: float = 0.0
    #: Current loop bandwidth [Hz]; when given it sets ``current_tau = 1 / (2 pi f)``.
    current_loop_hz: float | None = None
    #: Integrate exactly for a torque held over each step (module docstring); False: the
    #: semi-implicit step (a profile with ``simulation.exact_integration: false``).
    exact: bool = False

    def __post_init__(self) -> None:
        if self.current_loop_hz is not None:
            if not self.current_loop_hz > 0.0:
                raise ValueError(f"current_loop_hz must be > 0, not {self.current_loop_hz}")
            # The first-order lag whose -3 dB bandwidth is current_loop_hz.
            object.__setattr__(self, "current_tau", 1.0 / (TWO_PI * self.current_loop_hz))
        if self.resonance_hz is not None and not self.resonance_hz > 0.0:
            raise ValueError(f"resonance_hz must be > 0 or None, not {self.resonance_hz}")

    @property
    def inertia(self) -> float:
        """Total inertia seen by the motor (rigid coupling)."""
        return self.motor_inertia + self.load_inertia

    @property
    def inertia_ratio(self) -> float:
        """Load to motor inertia ratio ``J_L / J_M``."""
        return self.load_inertia / self.motor_inertia

    @property
    def antiresonance_hz(self) -> float | None:
        """The anti-resonance of the motor velocity (two-mass model), None when rigid."""
        if self.resonance_hz is None:
            return None
        return self.resonance_hz / math.sqrt(1.0 + self.inertia_ratio)

    @classmethod
    def from_settings(cls, s: SimSettings, **overrides: Any) -> PlantParams:
        """Parameters from a profile's ``simulation`` section (integrated exactly unless its
        ``exact_integration`` is false); keyword overrides win."""
        p = cls(
            motor_inertia=s.motor_inertia,
            load_inertia=s.motor_inertia * s.load_inertia_ratio,
            viscous=s.viscous,
            coulomb=s.coulomb,
            rated_torque=s.rated_torque,
            peak_torque=s.peak_torque,
            counts_per_rev=s.counts_per_rev,
            exact=s.exact_integration,
        )
        return replace(p, **overrides) if overrides else p


class Mechanics(Protocol):
    """The moving parts: integrates the air-gap torque into motion.

    Positions in rad and velocities in rad/s, at the motor shaft (where the encoder sits).
    """

    position: float
    velocity: float

    def advance(self, torque: float, dt: float) -> None: ...

    @property
    def load_position(self) -> float: ...

    @property
    def load_velocity(self) -> float: ...

    def reset(self, position: float = 0.0) -> None: ...


class RigidMechanics:
    """Motor and load as one rigid inertia with viscous and Coulomb friction and gravity.

    Coulomb friction is modelled with sticking: at rest the axis stays at rest while the
    torque (less gravity) does not exceed the Coulomb torque, and a velocity that would cross
    zero within a step stops at zero instead of chattering.
    """

    __slots__ = ("coulomb", "exact", "gravity", "inv_inertia", "position", "velocity", "viscous")

    def __init__(
        self,
        inertia: float,
        viscous: float,
        coulomb: float,
        gravity: float = 0.0,
        exact: bool = False,
    ) -> None:
        self.inv_inertia = 1.0 / inertia
        self.viscous = viscous
        self.coulomb = coulomb
        self.gravity = gravity
        #: Position by the step's mean velocity (exact for a held torque) instead of the new
        #: velocity (semi-implicit Euler, the profile twins' old step).
        self.exact = exact
        self.position = 0.0
        self.velocity = 0.0

    @property
    def load_position(self) -> float:
        return self.position

    @property
    def load_velocity(self) -> float:
        return self.velocity

    def reset(self, position: float = 0.0) -> None:
        self.position = position
        self.velocity = 0.0

    def advance(self, torque: float, dt: float) -> None:
        w = self.velocity
        c = self.coulomb
        drive = torque - self.gravity
        if w == 0.0:
            if -c <= drive <= c:
                return  # Static friction holds the axis.
            net = drive - c if drive > 0.0 else drive + c
            w_new = net * self.inv_inertia * dt
        else:
            net = drive - self.viscous * w - (c if w > 0.0 else -c)
            w_new = w + net * self.inv_inertia * dt
            if (w > 0.0) != (w_new > 0.0) and -c <= drive <= c:
                w_new = 0.0  # Friction brought it to rest within the step.
        self.velocity = w_new
        if self.exact:
            self.position += 0.5 * (w + w_new) * dt  # Exact for a torque held over the step.
        else:
            self.position += w_new * dt  # Semi-implicit Euler.


class TwoMassMechanics:
    """Motor inertia and load inertia coupled by a shaft spring ``k`` and damper ``c``.

    ``J_M dw_M/dt = T - k (p_M - p_L) - c (w_M - w_L) - b w_M`` (viscous ``b`` at the motor);
    ``J_L dw_L/dt = k (p_M - p_L) + c (w_M - w_L) - g - F_c sign(w_L)`` (gravity ``g`` and
    Coulomb ``F_c`` with sticking at the load, as :class:`RigidMechanics` does for the whole
    axis). ``position`` and ``velocity`` are the motor's (the encoder side).

    Each step is the exact solution for a torque held over the step (zero-order hold; module
    docstring): ``(q, w_M, w_L, p_M)`` (``q`` the shaft twist) advance by a matrix computed
    once per step size from the matrix exponential. While the load sticks, a second exact
    model (the motor on the shaft against a fixed load) applies.
    """

    __slots__ = (
        "_dt",
        "_lock",
        "_move",
        "coulomb",
        "damper",
        "gravity",
        "inv_jl",
        "inv_jm",
        "load_pos",
        "load_vel",
        "position",
        "stiffness",
        "velocity",
        "viscous",
    )

    def __init__(
        self,
        motor_inertia: float,
        load_inertia: float,
        stiffness: float,
        damper: float,
        viscous: float = 0.0,
        coulomb: float = 0.0,
        gravity: float = 0.0,
    ) -> None:
        self.inv_jm = 1.0 / motor_inertia
        self.inv_jl = 1.0 / load_inertia
        self.stiffness = stiffness
        self.damper = damper
        self.viscous = viscous
        self.coulomb = coulomb
        self.gravity = gravity
        self.position = 0.0
        self.velocity = 0.0
        self.load_pos = 0.0
        self.load_vel = 0.0
        self._dt = -1.0
        self._move: tuple[float, ...] = ()
        self._lock: tuple[float, ...] = ()

    @classmethod
    def from_resonance(
        cls,
        motor_inertia: float,
        load_inertia: float,
        resonance_hz: float,
        damping: float,
        viscous: float = 0.0,
        coulomb: float = 0.0,
        gravity: float = 0.0,
    ) -> TwoMassMechanics:
        """Spring and damper placing the shaft mode at ``resonance_hz`` with ``damping``
        (docs/tuning.md: ``k = w_r^2 J_M J_L / (J_M + J_L)``, ``c = 2 zeta sqrt(k mu)``)."""
        mu = motor_inertia * load_inertia / (motor_inertia + load_inertia)
        w = TWO_PI * resonance_hz
        k = w * w * mu
        c = 2.0 * damping * math.sqrt(k * mu)
        return cls(motor_inertia, load_inertia, k, c, viscous, coulomb, gravity)

    @property
    def load_position(self) -> float:
        return self.load_pos

    @property
    def load_velocity(self) -> float:
        return self.load_vel

    def reset(self, position: float = 0.0) -> None:
        """Both masses at rest at ``position`` with the shaft relaxed."""
        self.position = position
        self.load_pos = position
        self.velocity = 0.0
        self.load_vel = 0.0

    def _discretise(self, dt: float) -> None:
        """The zero-order-hold matrices for step ``dt`` (exp of the augmented system)."""
        self._dt = dt
        self._move, self._lock = _zoh_matrices(
            float(self.stiffness),
            float(self.damper),
            float(self.viscous),
            float(self.inv_jm),
            float(self.inv_jl),
            float(dt),
        )

    def advance(self, torque: float, dt: float) -> None:
        if dt != self._dt:
            self._discretise(dt)
        pm = self.position
        q = pm - self.load_pos
        wm = self.velocity
        wl = self.load_vel
        fc = self.coulomb
        g = self.gravity
        if wl == 0.0 and fc > 0.0:
            drive = self.stiffness * q + self.damper * wm - g
            if -fc <= drive <= fc:
                # Static friction holds the load; the motor winds the shaft (exact model).
                a00, a01, a02, a10, a11, a12 = self._lock
                q1 = a00 * q + a01 * wm + a02 * torque
                self.velocity = a10 * q + a11 * wm + a12 * torque
                self.position = pm + q1 - q
                return
            f = -g - (fc if drive > 0.0 else -fc)
        else:
            f = -g - (fc if wl > 0.0 else -fc if wl < 0.0 else 0.0)
        (
            q0, q1_, q2, q3, q4,
            m0, m1, m2, m3, m4,
            l0, l1, l2, l3, l4,
            p0, p1, p2, p3, p4,
        ) = self._move  # fmt: skip
        q_new = q0 * q + q1_ * wm + q2 * wl + q3 * torque + q4 * f
        wm_new = m0 * q + m1 * wm + m2 * wl + m3 * torque + m4 * f
        wl_new = l0 * q + l1 * wm + l2 * wl + l3 * torque + l4 * f
        pm_new = pm + p0 * q + p1 * wm + p2 * wl + p3 * torque + p4 * f
        if wl != 0.0 and (wl > 0.0) != (wl_new > 0.0):
            drive = self.stiffness * q_new + self.damper * wm_new - g
            if -fc <= drive <= fc:
                wl_new = 0.0  # Friction brought the load to rest within the step.
        self.position = pm_new
        self.velocity = wm_new
        self.load_pos = pm_new - q_new
        self.load_vel = wl_new


@functools.lru_cache(maxsize=512)
def _zoh_matrices(
    k: float, c: float, b: float, im: float, il: float, dt: float
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """:meth:`TwoMassMechanics._discretise`'s matrices for shaft stiffness ``k``, damper
    ``c``, motor viscous friction ``b``, inverse inertias ``im`` / ``il`` and step ``dt``.

    Cached: the tuning builds a new axis for every candidate it simulates (hundreds per
    tuning, all with the same few mechanics), and each exponential costs about a millisecond
    of pure Python."""
    # Moving load: z = [q, w_M, w_L, p_M, T, f], f the load's external torque.
    move = [
        [0.0, 1.0, -1.0, 0.0, 0.0, 0.0],
        [-k * im, -(c + b) * im, c * im, 0.0, im, 0.0],
        [k * il, c * il, -c * il, 0.0, 0.0, il],
        [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [0.0] * 6,
        [0.0] * 6,
    ]
    e = _expm([[x * dt for x in row] for row in move])
    # Rows q', w_M', w_L' (columns q, w_M, w_L, T, f), then p_M' - p_M.
    moving = tuple(e[i][j] for i in range(4) for j in (0, 1, 2, 4, 5))
    # Load held by static friction: z = [q, w_M, T], the load fixed.
    lock = [[0.0, 1.0, 0.0], [-k * im, -(c + b) * im, im], [0.0, 0.0, 0.0]]
    e = _expm([[x * dt for x in row] for row in lock])
    return moving, tuple(e[i][j] for i in range(2) for j in range(3))


def _expm(a: list[list[float]]) -> list[list[float]]:
    """exp(a) of a small matrix by scaling and squaring a Taylor series (pure Python: run once
    per step size; double precision for the well-scaled matrices of a step)."""
    n = len(a)
    norm = max(sum(abs(x) for x in row) for row in a)
    s = max(0, math.ceil(math.log2(norm)) + 1) if norm > 0.0 else 0
    scale = 0.5**s
    x = [[v * scale for v in row] for row in a]

    def mul(p: list[list[float]], r: list[list[float]]) -> list[list[float]]:
        return [[sum(p[i][k] * r[k][j] for k in range(n)) for j in range(n)] for i in range(n)]

    result = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    term = [row[:] for row in result]
    for k in range(1, 20):
        term = [[v / k for v in row] for row in mul(term, x)]
        result = [[result[i][j] + term[i][j] for j in range(n)] for i in range(n)]
    for _ in range(s):
        result = mul(result, result)
    return result


def mechanics_for(params: PlantParams) -> Mechanics:
    """The mechanics ``params`` describe: two-mass with a resonance, rigid without."""
    if params.resonance_hz is None:
        return RigidMechanics(
            params.inertia, params.viscous, params.coulomb, params.gravity, params.exact
        )
    return TwoMassMechanics.from_resonance(
        params.motor_inertia,
        params.load_inertia,
        params.resonance_hz,
        params.damping,
        params.viscous,
        params.coulomb,
        params.gravity,
    )


class Plant:
    """Current loop + mechanics + encoder of one axis."""

    __slots__ = (
        "_alpha",
        "_alpha_dt",
        "_beta",
        "_dead",
        "_delay",
        "_delay_dt",
        "_noise",
        "_noise_buf",
        "_noise_counts",
        "_noise_i",
        "_noise_rng",
        "_peak",
        "_rng",
        "_scale",
        "mechanics",
        "params",
        "torque",
        "torque_limited",
    )

    def __init__(self, params: PlantParams, mechanics: Mechanics | None = None) -> None:
        self.params = params
        self.mechanics: Mechanics = mechanics or mechanics_for(params)
        #: Actual (air-gap) torque in N m, the output of the current loop (noise excluded).
        self.torque = 0.0
        #: True when the last command was clipped at the peak torque.
        self.torque_limited = False
        self._scale = params.counts_per_rev / TWO_PI
        self._peak = params.peak_torque
        self._dead = params.dead_time > 0.0
        self._noise = params.torque_noise
        self._noise_counts = params.noise_counts
        self._alpha = 1.0
        self._alpha_dt = -1.0
        self._beta = 0.0
        self._delay: deque[float] = deque()
        self._delay_dt = -1.0
        self._rng = random.Random(params.seed)
        # Separate streams: the torque noise must not shift when the encoder noise is read.
        self._noise_rng = np.random.default_rng(params.seed)
        self._noise_buf: list[float] = []
        self._noise_i = 0

    # Encoder side (what the drive firmware sees) -------------------------------------

    @property
    def counts_per_rad(self) -> float:
        return self._scale

    @property
    def encoder_counts(self) -> int:
        """The quantised encoder reading (floor, like an incremental counter)."""
        x = self.mechanics.position * self._scale
        if self._noise_counts:
            x += self._rng.gauss(0.0, self._noise_counts)
        return math.floor(x)

    @property
    def velocity_counts(self) -> float:
        """Shaft velocity in counts/s (an ideal velocity observer)."""
        return self.mechanics.velocity * self._scale

    @property
    def position_rad(self) -> float:
        return self.mechanics.position

    @property
    def velocity_rad(self) -> float:
        return self.mechanics.velocity

    def set_position_counts(self, counts: float) -> None:
        """Place the axis (at rest) at a position; used by tests and resets."""
        self.mechanics.reset(counts / self._scale)
        self.torque = 0.0

    # Integration -----------------------------------------------------------------------

    def _set_dt(self, dt: float) -> None:
        # Exact discretisation of the first-order current-loop lag for this step size: the
        # torque at the end of the step moves by alpha toward the command. The mechanics get
        # cmd + (start - cmd) * beta: with ``exact`` the step's mean torque (what a constant
        # torque must be to give the same velocity change), else the end value.
        self._alpha_dt = dt
        tau = self.params.current_tau
        self._alpha = 1.0 - math.exp(-dt / tau) if tau > 0.0 else 1.0
        if tau <= 0.0:
            self._beta = 0.0
        elif self.params.exact:
            self._beta = tau / dt * self._alpha
        else:
            self._beta = 1.0 - self._alpha

    def step(self, torque_cmd: float, dt: float) -> None:
        """Advance ``dt`` seconds with the torque command ``torque_cmd`` (N m)."""
        pk = self._peak
        if torque_cmd > pk:
            torque_cmd = pk
            self.torque_limited = True
        elif torque_cmd < -pk:
            torque_cmd = -pk
            self.torque_limited = True
        else:
            self.torque_limited = False
        if self.params.dead_time > 0.0:
            torque_cmd = self._delayed(torque_cmd, dt)
        if dt != self._alpha_dt:
            self._set_dt(dt)
        t0 = self.torque
        self.torque = t0 + (torque_cmd - t0) * self._alpha
        torque = torque_cmd + (t0 - torque_cmd) * self._beta
        if self._noise:
            i = self._noise_i
            if i >= len(self._noise_buf):
                i = self._refill_noise()
            torque += self._noise_buf[i]
            self._noise_i = i + 1
        self.mechanics.advance(torque, dt)

    def step_counts(self, torque_cmd: float, dt: float) -> int:
        """:meth:`step`, then the encoder reading: the servo loop's per-tick call (one call
        instead of two in the hottest loop; the same arithmetic)."""
        pk = self._peak
        if torque_cmd > pk:
            torque_cmd = pk
            self.torque_limited = True
        elif torque_cmd < -pk:
            torque_cmd = -pk
            self.torque_limited = True
        else:
            self.torque_limited = False
        if self._dead:
            torque_cmd = self._delayed(torque_cmd, dt)
        if dt != self._alpha_dt:
            self._set_dt(dt)
        t0 = self.torque
        self.torque = t0 + (torque_cmd - t0) * self._alpha
        torque = torque_cmd + (t0 - torque_cmd) * self._beta
        if self._noise:
            i = self._noise_i
            if i >= len(self._noise_buf):
                i = self._refill_noise()
            torque += self._noise_buf[i]
            self._noise_i = i + 1
        m = self.mechanics
        m.advance(torque, dt)
        x = m.position * self._scale
        if self._noise_counts:
            x += self._rng.gauss(0.0, self._noise_counts)
        return math.floor(x)

    def step_n(self, torque_cmd: float, dt: float, n: int) -> None:
        """``n`` steps of ``dt`` with the same torque command (one control cycle)."""
        if self.params.dead_time > 0.0 or self._noise:
            for _ in range(n):
                self.step(torque_cmd, dt)
            return
        pk = self._peak
        self.torque_limited = not -pk <= torque_cmd <= pk
        if self.torque_limited:
            torque_cmd = pk if torque_cmd > 0.0 else -pk
        if dt != self._alpha_dt:
            self._set_dt(dt)
        alpha = self._alpha
        beta = self._beta
        advance = self.mechanics.advance
        torque = self.torque
        for _ in range(n):
            advance(torque_cmd + (torque - torque_cmd) * beta, dt)
            torque += (torque_cmd - torque) * alpha
        self.torque = torque

    def _refill_noise(self) -> int:
        """The next block of torque noise [N m]; returns the index to read (0)."""
        self._noise_buf = (self._noise_rng.standard_normal(4096) * self._noise).tolist()
        self._noise_i = 0
        return 0

    def _delayed(self, value: float, dt: float) -> float:
        if dt != self._delay_dt:
            n = max(1, round(self.params.dead_time / dt))
            self._delay = deque([self.torque] * n, maxlen=n)
            self._delay_dt = dt
        out = self._delay[0]
        self._delay.append(value)
        return out
