"""The servo loop of the simulated drives: the discrete cascade of docs/tuning.md.

One :class:`ServoLoop` per axis runs at the loop rate (``simulation.loop_rate_hz`` of the
profile, ``[loop] rate_hz`` of a plant file). Per tick (docs/tuning.md, "The servo loop of
the simulated drives")::

    e      = p_demand - p_measured                     rad   (encoder counts -> rad)
    v_meas = (p_measured - p_measured_prev) / T        rad/s (velocity by differencing)
    v_cmd  = Kp * e + Kvff * v_demand                  rad/s (velocity mode: v_demand)
    e_v    = v_cmd - v_meas
    i     += Kv * e_v * T / Ti                         (Ti = 0: none; held while saturated)
    tau    = Kv * e_v + i + Jff * a_demand + tau_test  N m
    tau    = notch2(notch1(lowpass(tau)))              (a stage with frequency 0 is off)
    tau    = clamp(tau, +-limit)

Dead time: the velocity comes from differencing the quantised encoder (a backward difference:
half a tick of delay, plus the count quantisation noise ``2 pi / counts / T``), and the torque
computed on a tick reaches the current loop on the next one (the drive samples at the start of
the period and writes the PWM at the start of the following one): :meth:`ServoLoop.update`
returns the command computed on the previous tick. Together about 1.5 ticks (94 µs at 16 kHz,
375 µs at 4 kHz) before the current loop's own lag.

Anti-windup: the integral is held while the last output was clamped and the velocity error
would drive it further into the limit (conditional integration). Torque mode
(:meth:`ServoLoop.update_torque`) passes the torque demand through the filters and the clamp,
with the speed limit the drive engine has always had: above ``v_limit`` the command is cut to
``Kv * (v_limit - v_meas)`` so a free motor cannot run away.

:meth:`ServoLoop.run` runs a whole control cycle's ticks with the loop state in locals and
the plant stepped in between: the same arithmetic as the per-tick methods (a test holds them
equal), at a fraction of the per-tick cost (the engine's hot path). :meth:`ServoLoop.set_gains`
takes effect on the next tick; a filter whose coefficients change starts from its steady state
at the last input. A notch width below 0.001 counts as 0.001 and its depth is clamped to 0..1;
a filter at or above half the loop rate is off.

Filters are discrete: the first-order low-pass and the notches use the bilinear transform
pre-warped at their corner / centre frequency (:func:`lowpass_coefficients`,
:func:`notch_coefficients`), so the gain at that frequency is exactly the continuous one.
A notch is ``(s^2 + 2 d z w s + w^2) / (s^2 + 2 z w s + w^2)``, ``z = width / 2`` (width: the
-3 dB bandwidth over the frequency for a full notch), ``d`` = depth (the gain at ``w``).

:class:`ServoGains` (domain/tuning/gains.py) and the filter coefficients
(domain/tuning/filters.py, :func:`lowpass_coefficients` a first-order section as a biquad with
``b2 = a2 = 0``, :func:`notch_coefficients`) are the domain's, re-exported here: the tuning's
loop model (domain/tuning/model.py) evaluates exactly what this loop runs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import fields

# The canonical gains and the filter coefficients are the domain's (one definition for the
# simulated loop and the tuning's loop model): re-exported here for the simulator's users.
from servodesk.domain.tuning.filters import Biquad, lowpass_coefficients, notch_coefficients
from servodesk.domain.tuning.gains import ServoGains

__all__ = [
    "POSITION",
    "TORQUE",
    "VELOCITY",
    "Biquad",
    "ServoGains",
    "ServoLoop",
    "default_gains",
    "gain_names",
    "lowpass_coefficients",
    "notch_coefficients",
]

TWO_PI = 2.0 * math.pi

#: Control kinds of :meth:`ServoLoop.run`.
POSITION, VELOCITY, TORQUE = 1, 2, 3

#: ``tick(command, dt) -> counts``: advance the plant one tick with a torque command and read
#: the encoder (:meth:`servodesk.model.plant.Plant.step_counts`).
Tick = Callable[[float, float], int]


def gain_names() -> tuple[str, ...]:
    """The canonical gain names, in order (the keys of a profile's ``tuning.gains``)."""
    return tuple(f.name for f in fields(ServoGains))


def default_gains(
    inertia: float,
    bandwidth_hz: float = 30.0,
    *,
    integral_ratio: float = 4.0,
    position_ratio: float = 5.0,
    inertia_margin: float = 1.0,
    torque_lpf_hz: float = 0.0,
    vel_ff: float = 1.0,
) -> ServoGains:
    """A conservative design for a rigid ``inertia`` [kg m²]: velocity loop crossover at
    ``bandwidth_hz`` (``Kv = J w``); integral time ``integral_ratio / w_min`` and position gain
    ``w_min / position_ratio``, where ``w_min = w / inertia_margin`` is the crossover on an axis
    ``inertia_margin`` times heavier (1: a normal design for this inertia, the PI corner a
    quarter of the crossover leaving some 76° of phase, the position loop a fifth of it); full
    velocity and inertia feed-forward.

    The generic profile's defaults are this design, rounded, for its own inertia with a margin
    up to a ratio-30 axis: ``default_gains(1.48e-4, 50.0, integral_ratio=3.0,
    position_ratio=4.0, inertia_margin=31 / 4)`` (profiles/cia402-generic/profile.yaml).
    """
    w = TWO_PI * bandwidth_hz
    w_min = w / inertia_margin
    return ServoGains(
        kp_pos=w_min / position_ratio,
        kp_vel=inertia * w,
        ti_vel=integral_ratio / w_min,
        vel_ff=vel_ff,
        inertia_ff=inertia,
        torque_lpf_hz=torque_lpf_hz,
    )


_OFF_BIQUAD: Biquad = (1.0, 0.0, 0.0, 0.0, 0.0)


class ServoLoop:
    """The cascade of one axis (module docstring), one call per tick at ``rate_hz``.

    ``counts_per_rev`` converts the encoder counts the loop is fed into rad; ``torque_limit``
    [N m] is the clamp (the engine sets it from 6072h every control cycle). Set ``tau_test``
    [N m] before a tick to add a test signal (docs/tuning.md, "Test signal generator").
    """

    __slots__ = (
        "_gains",
        "_jff",
        "_ki",
        "_kp",
        "_kv",
        "_kvff",
        "_lp",
        "_lp_on",
        "_lp_z",
        "_n1",
        "_n1_on",
        "_n1_z1",
        "_n1_z2",
        "_n2",
        "_n2_on",
        "_n2_z1",
        "_n2_z2",
        "_next",
        "_prev",
        "_rad",
        "_rate",
        "_rr",
        "_x_last",
        "command",
        "integral",
        "rate_hz",
        "saturated",
        "tau_test",
        "torque_limit",
        "velocity",
    )

    def __init__(
        self, gains: ServoGains, rate_hz: float, counts_per_rev: int, torque_limit: float
    ) -> None:
        if not rate_hz > 0.0:
            raise ValueError(f"loop rate {rate_hz} Hz must be > 0")
        self.rate_hz = float(rate_hz)
        self._rate = float(rate_hz)
        self._rad = TWO_PI / counts_per_rev
        #: rad/s per count of difference between two ticks.
        self._rr = self._rad * self._rate
        self.torque_limit = torque_limit
        self.tau_test = 0.0
        self._x_last = 0.0
        self._lp = _OFF_BIQUAD
        self._n1 = _OFF_BIQUAD
        self._n2 = _OFF_BIQUAD
        self._lp_on = self._n1_on = self._n2_on = False
        self.reset(0)
        self.set_gains(gains)

    # ------------------------------------------------------------------ configuration

    @property
    def gains(self) -> ServoGains:
        return self._gains

    def set_gains(self, gains: ServoGains) -> None:
        """New gains from the next tick on. The loop state is kept; a filter that changes
        starts from its steady state at the last input, so a new filter adds no step."""
        rate = self._rate
        nyq = 0.5 * rate
        self._gains = gains
        self._kp = gains.kp_pos
        self._kv = gains.kp_vel
        self._ki = gains.kp_vel / (gains.ti_vel * rate) if gains.ti_vel > 0.0 else 0.0
        self._kvff = gains.vel_ff
        self._jff = gains.inertia_ff
        x = self._x_last
        # A corner or notch at or above Nyquist cannot be realised: the stage is off.
        lp_on = 0.0 < gains.torque_lpf_hz < nyq
        lp = lowpass_coefficients(gains.torque_lpf_hz, rate) if lp_on else _OFF_BIQUAD
        if lp != self._lp or lp_on != self._lp_on:
            self._lp = lp
            self._lp_on = lp_on
            self._lp_z = x - lp[0] * x  # Steady state at x (DC gain 1).
        n1_on = 0.0 < gains.notch1_hz < nyq
        n1 = (
            _notch(gains.notch1_hz, gains.notch1_width, gains.notch1_depth, rate)
            if n1_on
            else _OFF_BIQUAD
        )
        if n1 != self._n1 or n1_on != self._n1_on:
            self._n1 = n1
            self._n1_on = n1_on
            self._n1_z1, self._n1_z2 = _steady(n1, x)
        n2_on = 0.0 < gains.notch2_hz < nyq
        n2 = (
            _notch(gains.notch2_hz, gains.notch2_width, gains.notch2_depth, rate)
            if n2_on
            else _OFF_BIQUAD
        )
        if n2 != self._n2 or n2_on != self._n2_on:
            self._n2 = n2
            self._n2_on = n2_on
            self._n2_z1, self._n2_z2 = _steady(n2, x)

    def reset(self, p_meas_counts: int) -> None:
        """Start over at a measured position (enable): no integral, filters and the delayed
        command at 0, velocity 0."""
        self._prev = p_meas_counts
        self._next = 0.0
        self._x_last = 0.0
        self._lp_z = 0.0
        self._n1_z1 = self._n1_z2 = 0.0
        self._n2_z1 = self._n2_z2 = 0.0
        self.integral = 0.0
        self.command = 0.0
        self.velocity = 0.0
        self.saturated = 0

    def hold(self, p_meas_counts: int, torque: float) -> None:
        """At rest at a measured position, holding ``torque`` [N m] with its integral: the
        state a move starts from once the axis has come to rest against friction or gravity
        (the filters in steady state at it, the delayed command equal to it). The own tuning
        replays a try on the axis from there (replay.run_recorded_move)."""
        self.reset(p_meas_counts)
        self.integral = torque
        self._x_last = torque
        self._next = torque
        self.command = torque
        self._lp_z = torque - self._lp[0] * torque
        self._n1_z1, self._n1_z2 = _steady(self._n1, torque)
        self._n2_z1, self._n2_z2 = _steady(self._n2, torque)

    # ------------------------------------------------------------------ one tick

    def update(
        self, p_demand_rad: float, v_demand: float, a_demand: float, p_meas_counts: int
    ) -> float:
        """A position-control tick: demands in rad, rad/s, rad/s²; the measured position in
        encoder counts. Returns the torque command [N m] that reaches the current loop now
        (computed on the previous tick)."""
        v_meas = (p_meas_counts - self._prev) * self._rr
        self._prev = p_meas_counts
        self.velocity = v_meas
        e = p_demand_rad - p_meas_counts * self._rad
        return self._velocity_loop(self._kp * e + self._kvff * v_demand - v_meas, a_demand)

    def update_velocity(self, v_demand: float, a_demand: float, p_meas_counts: int) -> float:
        """A velocity-control tick: ``v_cmd = v_demand`` (no position loop)."""
        v_meas = (p_meas_counts - self._prev) * self._rr
        self._prev = p_meas_counts
        self.velocity = v_meas
        return self._velocity_loop(v_demand - v_meas, a_demand)

    def update_torque(
        self, tau_demand: float, p_meas_counts: int, v_limit: float = math.inf
    ) -> float:
        """A torque-control tick: the demand (plus ``tau_test``) through the filters and the
        clamp, cut back above the speed limit ``v_limit`` [rad/s]."""
        v_meas = (p_meas_counts - self._prev) * self._rr
        self._prev = p_meas_counts
        self.velocity = v_meas
        tau = tau_demand
        if v_meas > v_limit:
            cut = self._kv * (v_limit - v_meas)
            if tau > cut:
                tau = cut
        elif v_meas < -v_limit:
            cut = self._kv * (-v_limit - v_meas)
            if tau < cut:
                tau = cut
        self.integral = 0.0
        return self._output(tau + self.tau_test)

    def run(
        self,
        n: int,
        tick: Tick,
        dt: float,
        counts: int,
        *,
        mode: int = POSITION,
        p0: float = 0.0,
        inc: float = 0.0,
        v_demand: float = 0.0,
        a_demand: float = 0.0,
        tau_demand: float = 0.0,
        v_limit: float = math.inf,
        signal: Callable[[], float] | None = None,
        after: Callable[[int], None] | None = None,
    ) -> tuple[int, bool]:
        """``n`` ticks of one control cycle, the plant stepped by ``tick`` after each.

        The same arithmetic as ``n`` calls of :meth:`update` (``mode`` POSITION, demand
        ``(p0 + inc * k) * rad`` on tick ``k`` = 1..n, ``p0`` and ``inc`` in encoder counts),
        :meth:`update_velocity` or :meth:`update_torque`, each followed by ``counts =
        tick(command, dt)``, with the loop state held in locals (the per-tick cost is what
        limits the real-time factor). ``counts`` is the encoder reading before the first tick;
        ``signal()`` gives ``tau_test`` for each tick; ``after(k)`` runs after tick ``k`` with
        :attr:`command` and :attr:`velocity` current. Returns the last encoder reading and
        whether the command was clamped on any tick.
        """
        rad = self._rad
        rr = self._rr
        kp = self._kp
        kv = self._kv
        ki = self._ki
        kvff = self._kvff
        jff = self._jff
        lp_on = self._lp_on
        lb0, lb1, _, la1, _ = self._lp
        n1_on = self._n1_on
        p10, p11, p12, q11, q12 = self._n1
        n2_on = self._n2_on
        p20, p21, p22, q21, q22 = self._n2
        lz = self._lp_z
        z11 = self._n1_z1
        z12 = self._n1_z2
        z21 = self._n2_z1
        z22 = self._n2_z2
        prev = self._prev
        integ = self.integral
        s = self.saturated
        nxt = self._next
        lim = self.torque_limit
        tt = self.tau_test
        x = self._x_last
        out = self.command
        vm = self.velocity
        clamped = False
        torque = mode == TORQUE
        position = mode == POSITION
        if torque:
            integ = 0.0
        ff = jff * a_demand
        vff = kvff * v_demand
        for k in range(1, n + 1):
            if signal is not None:
                tt = signal()
            vm = (counts - prev) * rr
            prev = counts
            if torque:
                x = tau_demand
                if vm > v_limit:
                    cut = kv * (v_limit - vm)
                    if x > cut:
                        x = cut
                elif vm < -v_limit:
                    cut = kv * (-v_limit - vm)
                    if x < cut:
                        x = cut
                x = x + tt
            else:
                if position:
                    ev = kp * ((p0 + inc * k) * rad - counts * rad) + vff - vm
                else:
                    ev = v_demand - vm
                if ki and not ((s > 0 and ev > 0.0) or (s < 0 and ev < 0.0)):
                    integ += ki * ev
                x = kv * ev + integ + ff + tt
            y = x
            if lp_on:
                y0 = lb0 * y + lz
                lz = lb1 * y - la1 * y0
                y = y0
            if n1_on:
                y0 = p10 * y + z11
                z11 = p11 * y - q11 * y0 + z12
                z12 = p12 * y - q12 * y0
                y = y0
            if n2_on:
                y0 = p20 * y + z21
                z21 = p21 * y - q21 * y0 + z22
                z22 = p22 * y - q22 * y0
                y = y0
            if y > lim:
                y = lim
                s = 1
                clamped = True
            elif y < -lim:
                y = -lim
                s = -1
                clamped = True
            else:
                s = 0
            out = nxt
            nxt = y
            counts = tick(out, dt)
            if after is not None:
                self.command = out
                self.velocity = vm
                self.saturated = s
                after(k)
        self._lp_z = lz
        self._n1_z1 = z11
        self._n1_z2 = z12
        self._n2_z1 = z21
        self._n2_z2 = z22
        self._prev = prev
        self.integral = integ
        self.saturated = s
        self._next = nxt
        self._x_last = x
        self.command = out
        self.velocity = vm
        self.tau_test = tt
        return counts, clamped

    def _velocity_loop(self, ev: float, a_demand: float) -> float:
        ki = self._ki
        if ki:
            s = self.saturated
            # Conditional integration: hold while clamped and e_v pushes into the limit.
            if not ((s > 0 and ev > 0.0) or (s < 0 and ev < 0.0)):
                self.integral += ki * ev
        return self._output(self._kv * ev + self.integral + self._jff * a_demand + self.tau_test)

    def _output(self, x: float) -> float:
        """Filters, clamp and the one-tick compute delay."""
        self._x_last = x
        if self._lp_on:
            b0, b1, _, a1, _ = self._lp
            y = b0 * x + self._lp_z
            self._lp_z = b1 * x - a1 * y
            x = y
        if self._n1_on:
            b0, b1, b2, a1, a2 = self._n1
            y = b0 * x + self._n1_z1
            self._n1_z1 = b1 * x - a1 * y + self._n1_z2
            self._n1_z2 = b2 * x - a2 * y
            x = y
        if self._n2_on:
            b0, b1, b2, a1, a2 = self._n2
            y = b0 * x + self._n2_z1
            self._n2_z1 = b1 * x - a1 * y + self._n2_z2
            self._n2_z2 = b2 * x - a2 * y
            x = y
        lim = self.torque_limit
        if x > lim:
            x = lim
            self.saturated = 1
        elif x < -lim:
            x = -lim
            self.saturated = -1
        else:
            self.saturated = 0
        out = self._next
        self._next = x
        self.command = out
        return out


def _notch(f: float, width: float, depth: float, rate: float) -> Biquad:
    """A notch from gains as a drive takes them: a width below 0.001 counts as 0.001 and the
    depth is clamped to 0..1 (the objects' limits normally keep them there)."""
    return notch_coefficients(f, max(width, 1e-3), min(max(depth, 0.0), 1.0), rate)


def _steady(c: Biquad, x: float) -> tuple[float, float]:
    """Transposed direct form II states of a biquad at rest with input ``x`` (DC gain 1)."""
    b0, _b1, b2, _a1, a2 = c
    y = x
    return (y - b0 * x, b2 * x - a2 * y)
