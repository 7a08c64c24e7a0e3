"""Set-point generators of the simulated drive: pp, pv, csp, csv, torque kinds, homing glue.

Part of :class:`~servodesk.sim.engine.SimulatedDrive` (sim/engine.py says why the parts are a
chain of base classes). Each control cycle one generator steps the demand (``_dp`` position,
``_dv`` velocity, ``_da`` acceleration, in counts) for the active mode of operation; the stop
ramps (disable, quick stop, halt, fault reaction) share :meth:`SetPoints._ramp_down`. The
controlword bits 4-6 and 8 that start a set-point or a homing are here too
(:meth:`SetPoints._mode_bits`), as is the glue to the homing search of sim/homing.py.

- Profile position (CiA 402-2 §6.5) is one step of
  :func:`~servodesk.model.profile_position.pp_step` per cycle (shared with the tuning's
  replay); a new set-point while one runs is buffered unless bit 5 (change immediately) is
  set, and targets are clipped to 607Dh (both 0: no limits, §6.5.4).
- Profile velocity ramps at 6083h/6084h, capped by 607Fh and the machine's top speed, and,
  where the profile says the drive does it (``simulation.software_limits_in_pv``), brakes
  to stop :data:`LIMIT_WALL_MARGIN` inside a software limit (:meth:`SetPoints._limit_wall`).
- Cyclic sync position follows 607Ah linearly over the time since the previous set-point
  (§6.10: the master's cycle, there is no SYNC); cyclic sync velocity takes 60FFh as is.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from servodesk.domain.homing import resolve_method
from servodesk.model.profile_position import pp_step
from servodesk.sim.engine_base import (
    CTRL_POSITION,
    CTRL_TORQUE,
    CTRL_VELOCITY,
    K_HOME_OFFSET,
    K_HOMING_ACC,
    K_HOMING_METHOD,
    K_HOMING_SPEED_SWITCH,
    K_HOMING_SPEED_ZERO,
    K_MAX_PROFILE_VEL,
    K_PROFILE_ACC,
    K_PROFILE_DEC,
    K_PROFILE_VEL,
    K_SW_LIMIT_MAX,
    K_SW_LIMIT_MIN,
    K_TARGET_POSITION,
    K_TARGET_VELOCITY,
    NO_RAMP,
    POSITION_MODES,
    Stop,
)
from servodesk.sim.engine_servo import ServoGlue
from servodesk.sim.homing import HomingProcedure

#: Profile velocity toward a software limit: how long the axis runs on behind a braking demand
#: (_limit_wall).
LIMIT_WALL_LAG_S = 0.002
#: ... and where it stops: this far inside the limit [position units].
LIMIT_WALL_MARGIN = 50


class SetPoints(ServoGlue):
    """The demand of the active mode, the stop ramps, homing started and stepped."""

    def _begin_motion(self) -> None:
        """Set the control kind for the active mode (after enable, mode change, resume)."""
        m = self._mode
        if m in (3, 9):
            self._kind = CTRL_VELOCITY
        elif m in (4, 10):
            self._kind = CTRL_TORQUE
            self._tq_demand = self.plant.torque
        else:
            if self._kind != CTRL_POSITION:
                self._dp = float(self.plant.encoder_counts + self._pos_offset)
            self._kind = CTRL_POSITION
            self._csp_target = self._dp
            self._csp_cycle = self._cycles
            if m == 1 and not self._pp_done:
                return
            self._pp_target = self._dp
            self._pp_done = True

    def _enter_mode(self, mode: int) -> None:
        self._mode = mode
        self._reached = False
        self._win_time = 0.0
        self._sp_ack = False
        self._pp_buffer = None
        self._homing_started = False
        self._homing_cancelled = False
        self._homing = None
        self._homing_error = False
        self._pp_done = True
        if self._enabled and self._stop is None and not self._hold:
            if self._kind == CTRL_TORQUE:
                self._dv = self.plant.velocity_counts
            self._begin_motion()

    def _mode_bits(self, cw: int, prev: int) -> None:
        """Controlword bits 4-6 and 8 in Operation enabled (CiA 402-2 §6.2.1)."""
        m = self._mode
        rising4 = cw & 0x10 and not prev & 0x10
        if prev & 0x100 and not cw & 0x100:
            self._reached = False  # Halt released: motion resumes (recomputed next cycle).
        if m == 1:
            if rising4 and self._pp_buffer is None:
                value = self._c[K_TARGET_POSITION]
                base = self._pp_target if cw & 0x40 else 0.0
                target = self._clip(base + value)
                if cw & 0x20 or self._pp_done:
                    self._pp_target = target
                    self._pp_done = False
                    self._reached = False
                    self._win_time = 0.0
                else:
                    self._pp_buffer = target
                self._sp_ack = True
            elif not cw & 0x10 and self._pp_buffer is None:
                self._sp_ack = False
        elif m == 6:
            if rising4:
                self._home()
            elif not cw & 0x10 and self._homing_started and not self._homed:
                self._homing_started = False  # Homing interrupted.
                self._homing_cancelled = self._homing_cancel_clears and not self._homing_error

    def _clip(self, target: float) -> float:
        lo, hi = self._c[K_SW_LIMIT_MIN], self._c[K_SW_LIMIT_MAX]
        self._clipped = False
        if lo == 0 and hi == 0:
            return target  # CiA 402-2 §6.5.4: both 0 switches the limits off.
        if target < lo:
            self._clipped = True
            return float(lo)
        if target > hi:
            self._clipped = True
            return float(hi)
        return target

    def _home(self) -> None:
        """Start the homing method in 6098h (CiA 402-2 §6.8; sim/homing.py does the search)."""
        method = self._c[K_HOMING_METHOD]
        self._homing_started = True
        self._homing_cancelled = False
        self._homed = False
        self._homing_error = False
        self._reached = False
        self._homing = None
        info = resolve_method(method, self._homing_equiv)
        if info is None or method not in self._homing_methods:
            self._homing_error = True  # 000 §3.2.4: an unsupported method sets bit 13.
            return
        if info.current_position:
            home = self._c[K_HOME_OFFSET]
            raw = self.plant.encoder_counts
            self._pos_offset = home - raw
            self._dp = float(home)
            self._dv = 0.0
            self._pp_target = self._dp
            self._homed = True
            self._reached = True
            return
        if not self._enabled:
            self._homing_error = True
            return
        if self._kind != CTRL_POSITION:
            self._dp = float(self.plant.encoder_counts + self._pos_offset)
            self._dv = 0.0
            self._kind = CTRL_POSITION
        self._homing = HomingProcedure(
            info,
            self.switches,
            switch_speed=min(self._homing_speed(K_HOMING_SPEED_SWITCH), self._vmax_sim),
            zero_speed=min(self._homing_speed(K_HOMING_SPEED_ZERO), self._vmax_sim),
            acceleration=self._homing_acceleration(),
            period=self._T,
            max_travel=self._homing_max_travel,
        )

    def _homing_speed(self, k: int) -> float:
        """A homing speed in counts/s; 6099h in r/min (004 §20.9.3.11(3)) is converted."""
        raw = float(self._c[k])
        spec = self._specs.get(k)
        if spec is not None and spec.unit in ("r/min", "rpm") and spec.raw_unit != "inc/s":
            return raw * spec.scale / 60.0 * self.plant_params.counts_per_rev
        return raw

    def _homing_acceleration(self) -> float:
        """609Ah in counts/s², from a rate register or an acceleration time constant."""
        acc = float(self._c[K_HOMING_ACC])
        return self._acceleration(K_HOMING_ACC, acc) if acc > 0 else acc

    def _homing_step(self) -> None:
        """One control cycle of a running homing procedure (or its interruption)."""
        proc = self._homing
        assert proc is not None
        T = self._T
        if not self._homing_started:
            # Controlword bit 4 cleared: interrupted; stop at the homing acceleration.
            if self._ramp_down(self._homing_acceleration() or NO_RAMP):
                self._homing = None
            return
        off = self._pos_offset
        v, snap = proc.step(float(self.plant.encoder_counts), self._dp - off, self._dv)
        self._da = (v - self._dv) / T
        self._dv = v
        self._dp = snap + off if snap is not None else self._dp + v * T
        if not proc.done:
            return
        self._homing = None
        if proc.error or proc.home_raw is None:
            self._homing_error = True
            return
        # 000 §3.2.4, 003 §4-4-7: at the home point 6062h = 6064h = 607Ch.
        new_off = self._c[K_HOME_OFFSET] - proc.home_raw
        self._dp += new_off - off
        self._pos_offset = new_off
        self._pp_target = self._dp
        self._homed = True

    def _start_stop(self, decel: float, then: Callable[[], None]) -> None:
        if self._kind == CTRL_TORQUE:
            self._dv = self.plant.velocity_counts
            self._dp = float(self.plant.encoder_counts + self._pos_offset)
        self._kind = (
            CTRL_POSITION if self._mode in POSITION_MODES or self._mode == 0 else CTRL_VELOCITY
        )
        self._stop = Stop(max(decel, 1.0), then)
        self._reached = False

    def _ramp_down(self, decel: float) -> bool:
        """Bring the velocity demand to 0 at ``decel``; True once it is 0."""
        v = self._dv
        step = decel * self._T
        if -step <= v <= step:
            self._da = -v / self._T
            self._dv = 0.0
            self._dp += 0.5 * v * self._T
            return True
        nv = v - step if v > 0.0 else v + step
        self._da = (nv - v) / self._T
        self._dv = nv
        self._dp += nv * self._T
        return False

    def _pp_generate(self) -> None:
        """Trapezoidal profile toward ``_pp_target`` (6081h, 6083h, 6084h, limited by 607Fh):
        one step of :func:`~servodesk.model.profile_position.pp_step`."""
        vmax = float(self._c[K_PROFILE_VEL])
        lim = self._c[K_MAX_PROFILE_VEL]
        if lim:
            vmax = min(vmax, float(lim))
        vmax = min(vmax, self._vmax_sim)
        s = pp_step(
            self._dp,
            self._dv,
            self._pp_target,
            vmax,
            float(self._c[K_PROFILE_ACC]),
            float(self._c[K_PROFILE_DEC]),
            self._T,
        )
        self._dp, self._dv, self._da = s.dp, s.dv, s.da
        if s.done:
            self._pp_done = True
            if self._pp_buffer is not None:
                self._pp_target = self._pp_buffer
                self._pp_buffer = None
                self._pp_done = False
                self._reached = False
                self._win_time = 0.0

    def _pv_generate(self) -> None:
        tgt = float(self._c[K_TARGET_VELOCITY])
        vmax = float(self._c[K_MAX_PROFILE_VEL]) or self._vmax_sim
        vmax = min(vmax, self._vmax_sim)
        self._clipped = abs(tgt) > vmax
        tgt = self._limit_wall(max(-vmax, min(vmax, tgt)))
        v = self._dv
        rate = (
            self._c[K_PROFILE_ACC]
            if abs(tgt) > abs(v) and v * tgt >= 0.0
            else self._c[K_PROFILE_DEC]
        )
        d = tgt - v
        lim = rate * self._T
        if d > lim:
            d = lim
        elif d < -lim:
            d = -lim
        self._da = d / self._T
        self._dv = v + d

    def _limit_wall(self, tgt: float) -> float:
        """Profile velocity toward a software position limit (607Dh): the demand is held
        under the speed from which the profile deceleration (6084h) stops the axis
        :data:`LIMIT_WALL_MARGIN` inside the limit, and brought back there if the axis crept
        past it, as drives that supervise 607Dh in every mode do (CiA 402-2 §6.5.4 leaves the
        velocity modes to the manufacturer). servodesk's own monitor halts continuous motion
        before this (services/motion/); this is the backstop when the monitor's samples
        come late. Internal limit active (bit 11) while it holds the demand. Only where the
        profile says the drive does this (``simulation.software_limits_in_pv``)."""
        lo, hi = self._c[K_SW_LIMIT_MIN], self._c[K_SW_LIMIT_MAX]
        dec = float(self._c[K_PROFILE_DEC])
        if not self._limits_in_pv or (lo == 0 and hi == 0) or tgt == 0.0 or dec <= 0.0:
            return tgt
        p = float(self.plant.encoder_counts + self._pos_offset)
        # Less what the axis covers while its velocity follows the demand (a few cycles of
        # the velocity loop): the demand stops first, the axis a little behind it.
        lag = abs(self.plant.velocity_counts) * LIMIT_WALL_LAG_S
        room = (hi - p if tgt > 0.0 else p - lo) - LIMIT_WALL_MARGIN - lag
        # The discrete braking curve of _pp_generate: stepping down by dec*T per cycle from
        # this speed stops within ``room``; negative room (past the stop) gives a speed back.
        h = 0.5 * dec * self._T
        vb = math.copysign(-h + math.sqrt(h * h + 2.0 * dec * abs(room)), room)
        if abs(tgt) <= vb:
            return tgt
        self._clipped = True
        return vb if tgt > 0.0 else -vb

    def _csp_generate(self) -> None:
        """Cyclic sync position (CiA 402-2 §6.10): follow 607Ah, moving linearly to each new
        set-point over the time since the previous one (the master's cycle: there is no SYNC)."""
        tgt = self._clip(float(self._c[K_TARGET_POSITION]))
        if tgt != self._csp_target:
            n = self._cycles - self._csp_cycle
            self._csp_cycle = self._cycles
            self._csp_target = tgt
            # A set-point after a long pause (or the first) is a step, as on a real drive.
            self._dv = (tgt - self._dp) / ((n if 0 < n <= 100 else 1) * self._T)
        rest = self._csp_target - self._dp
        step = self._dv * self._T
        if step == 0.0 or abs(step) >= abs(rest) or (step > 0.0) != (rest > 0.0):
            self._dp = self._csp_target
            self._dv = 0.0
        else:
            self._dp += step
        self._da = 0.0

    def _csv_generate(self) -> None:
        """Cyclic sync velocity (CiA 402-2 §6.11): 60FFh is the velocity demand, no ramp."""
        vmax = min(float(self._c[K_MAX_PROFILE_VEL]) or self._vmax_sim, self._vmax_sim)
        tgt = float(self._c[K_TARGET_VELOCITY])
        self._clipped = abs(tgt) > vmax
        self._dv = max(-vmax, min(vmax, tgt))
        self._da = 0.0
