"""The simulated plant: current loop, motor and load mechanics, encoder.

Pure Python (no numpy: one axis is a handful of floats, and scalar arithmetic is faster than
array calls at this size). Fixed-step integration; :meth:`Plant.step` advances one step.

The mechanics sit behind the small :class:`Mechanics` protocol so that a two-mass model
(motor and load coupled by a spring and damper, for resonance studies) can replace
:class:`RigidMechanics` without touching the plant or the drive engine.
"""

from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, replace
from typing import Any, Protocol

from servodesk.domain.profile import SimSettings

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class PlantParams:
    """Physical parameters of one axis (SI units: kg m², N m, N m s/rad, s)."""

    motor_inertia: float = 3.7e-5
    load_inertia: float = 1.11e-4
    viscous: float = 1.0e-4
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

    @property
    def inertia(self) -> float:
        """Total inertia seen by the motor (rigid coupling)."""
        return self.motor_inertia + self.load_inertia

    @classmethod
    def from_settings(cls, s: SimSettings, **overrides: Any) -> PlantParams:
        """Parameters from a profile's ``simulation`` section; keyword overrides win."""
        p = cls(
            motor_inertia=s.motor_inertia,
            load_inertia=s.motor_inertia * s.load_inertia_ratio,
            viscous=s.viscous,
            coulomb=s.coulomb,
            rated_torque=s.rated_torque,
            peak_torque=s.peak_torque,
            counts_per_rev=s.counts_per_rev,
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

    def reset(self, position: float = 0.0) -> None: ...


class RigidMechanics:
    """Motor and load as one rigid inertia with viscous and Coulomb friction.

    Coulomb friction is modelled with sticking: at rest the axis stays at rest while the
    torque does not exceed the Coulomb torque, and a velocity that would cross zero within a
    step stops at zero instead of chattering.
    """

    __slots__ = ("coulomb", "inv_inertia", "position", "velocity", "viscous")

    def __init__(self, inertia: float, viscous: float, coulomb: float) -> None:
        self.inv_inertia = 1.0 / inertia
        self.viscous = viscous
        self.coulomb = coulomb
        self.position = 0.0
        self.velocity = 0.0

    @property
    def load_position(self) -> float:
        return self.position

    def reset(self, position: float = 0.0) -> None:
        self.position = position
        self.velocity = 0.0

    def advance(self, torque: float, dt: float) -> None:
        w = self.velocity
        c = self.coulomb
        if w == 0.0:
            if -c <= torque <= c:
                return  # Static friction holds the axis.
            net = torque - c if torque > 0.0 else torque + c
            w_new = net * self.inv_inertia * dt
        else:
            net = torque - self.viscous * w - (c if w > 0.0 else -c)
            w_new = w + net * self.inv_inertia * dt
            if (w > 0.0) != (w_new > 0.0) and -c <= torque <= c:
                w_new = 0.0  # Friction brought it to rest within the step.
        # Semi-implicit Euler: position uses the new velocity (stable for stiff loops).
        self.velocity = w_new
        self.position += w_new * dt


class Plant:
    """Current loop + mechanics + encoder of one axis."""

    __slots__ = (
        "_alpha",
        "_alpha_dt",
        "_delay",
        "_delay_dt",
        "_rng",
        "_scale",
        "mechanics",
        "params",
        "torque",
        "torque_limited",
    )

    def __init__(self, params: PlantParams, mechanics: Mechanics | None = None) -> None:
        self.params = params
        self.mechanics: Mechanics = mechanics or RigidMechanics(
            params.inertia, params.viscous, params.coulomb
        )
        #: Actual (air-gap) torque in N m, the output of the current loop.
        self.torque = 0.0
        #: True when the last command was clipped at the peak torque.
        self.torque_limited = False
        self._scale = params.counts_per_rev / TWO_PI
        self._alpha = 1.0
        self._alpha_dt = -1.0
        self._delay: deque[float] = deque()
        self._delay_dt = -1.0
        self._rng = random.Random(params.seed)

    # Encoder side (what the drive firmware sees) -------------------------------------

    @property
    def counts_per_rad(self) -> float:
        return self._scale

    @property
    def encoder_counts(self) -> int:
        """The quantised encoder reading (floor, like an incremental counter)."""
        x = self.mechanics.position * self._scale
        if self.params.noise_counts:
            x += self._rng.gauss(0.0, self.params.noise_counts)
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

    def step(self, torque_cmd: float, dt: float) -> None:
        """Advance ``dt`` seconds with the torque command ``torque_cmd`` (N m)."""
        pk = self.params.peak_torque
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
            # Exact discretisation of the first-order lag for this step size.
            self._alpha_dt = dt
            tau = self.params.current_tau
            self._alpha = 1.0 - math.exp(-dt / tau) if tau > 0.0 else 1.0
        self.torque += (torque_cmd - self.torque) * self._alpha
        self.mechanics.advance(self.torque, dt)

    def step_n(self, torque_cmd: float, dt: float, n: int) -> None:
        """``n`` steps of ``dt`` with the same torque command (one control cycle)."""
        if self.params.dead_time > 0.0:
            for _ in range(n):
                self.step(torque_cmd, dt)
            return
        pk = self.params.peak_torque
        self.torque_limited = not -pk <= torque_cmd <= pk
        if self.torque_limited:
            torque_cmd = pk if torque_cmd > 0.0 else -pk
        if dt != self._alpha_dt:
            self._alpha_dt = dt
            tau = self.params.current_tau
            self._alpha = 1.0 - math.exp(-dt / tau) if tau > 0.0 else 1.0
        alpha = self._alpha
        advance = self.mechanics.advance
        torque = self.torque
        for _ in range(n):
            torque += (torque_cmd - torque) * alpha
            advance(torque, dt)
        self.torque = torque

    def _delayed(self, value: float, dt: float) -> float:
        if dt != self._delay_dt:
            n = max(1, round(self.params.dead_time / dt))
            self._delay = deque([self.torque] * n, maxlen=n)
            self._delay_dt = dt
        out = self._delay[0]
        self._delay.append(value)
        return out
