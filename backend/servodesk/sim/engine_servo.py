"""Servo glue of the simulated drive: the model's servo loop and plant stepped in the cycle.

Part of :class:`~servodesk.sim.engine.SimulatedDrive` (sim/engine.py says why the parts are a
chain of base classes). A profile with ``tuning.kind: gains`` (docs/tuning.md) runs the servo
loop of model/servo.py once per plant sub-step, its gains read from the mapped objects (raw *
scale) and reloaded after every write to one of them; the control cycle only generates the
demand, which the loop interpolates linearly across the cycle, and the test signal generator
(sim/siggen.py) adds its torque in the loop while it runs. Other profiles keep the cycle-rate
cascade (:class:`~servodesk.sim.engine_base.ControllerGains`, :meth:`ServoGlue._control`)
with the torque held over the cycle's sub-steps. The physics itself (plant, loop) is in
``servodesk.model``, shared with the tuning; this module only feeds it the drive's demand.
"""

from __future__ import annotations

import math

from servodesk.domain.cia402 import State
from servodesk.domain.datatypes import Value
from servodesk.domain.profile import DeviceProfile
from servodesk.model.servo import POSITION, TORQUE, VELOCITY, ServoGains, ServoLoop
from servodesk.sim.engine_base import (
    CTRL_POSITION,
    CTRL_TORQUE,
    CTRL_VELOCITY,
    K_MAX_PROFILE_VEL,
    K_MAX_TORQUE,
    K_TARGET_TORQUE,
    K_TORQUE_SLOPE,
    DriveBase,
    SimAbort,
    StepHook,
    key,
)
from servodesk.sim.siggen import (
    SUB_AMPLITUDE,
    SUB_CONTROL,
    SUB_DURATION,
    SUB_F_END,
    SUB_F_START,
    SUB_KIND,
    SignalConfig,
    SignalGenerator,
)


class ServoGlue(DriveBase):
    """The servo loop or the cycle-rate cascade, the plant's sub-steps, the test signal."""

    def _init_servo(self, profile: DeviceProfile) -> None:
        """The servo loop of a ``tuning.kind: gains`` profile (docs/tuning.md, model/servo.py):
        gains from the mapped objects, the loop rate object, the test signal generator."""
        #: The servo loop (None: the profile keeps the cycle-rate controller).
        self.servo = None
        #: The test signal generator (docs/tuning.md), where the profile has its objects.
        self.siggen = None
        self._gain_keys = {}
        self._loop_rate_key = None
        self._sig_index = -1
        self._srv_vlim = math.inf
        #: This cycle's position demand at its start (raw counts) and per tick (sub-step).
        self._raw0 = 0.0
        self._dv0 = 0.0
        self._inc = 0.0
        tuning = profile.tuning
        if tuning is None or tuning.kind != "gains":
            return
        for name, g in tuning.gains.items():
            a = g.address
            k = key(a.index, a.subindex)
            if k not in self._specs:
                raise ValueError(f"tuning.gains.{name}: {g.object} is not an object")
            self._gain_keys[k] = (name, g.scale)
        addr = tuning.loop_rate_address
        if addr is not None:
            self._loop_rate_key = key(addr.index, addr.subindex)
        self.servo = ServoLoop(
            self._gains_from_objects(),
            self.loop_rate_hz,
            self.plant_params.counts_per_rev,
            self.plant_params.peak_torque,
        )
        if tuning.signal_index is not None:
            self.siggen = SignalGenerator(self.loop_rate_hz)
            self._sig_index = tuning.signal_index

    def _gains_from_objects(self) -> ServoGains:
        """SI gains from the gain objects (raw * scale); an unmapped gain is 0, the
        :class:`ServoGains` default (its feature off: no feed-forward, no filter)."""
        si: dict[str, float] = {"kp_pos": 0.0, "kp_vel": 0.0, "ti_vel": 0.0}
        values = self._values
        for k, (name, scale) in self._gain_keys.items():
            v = values.get(k)
            if isinstance(v, int | float):
                si[name] = float(v) * scale
        return ServoGains(**si)

    def _load_gains(self) -> None:
        if self.servo is not None:
            self.servo.set_gains(self._gains_from_objects())

    @property
    def servo_gains(self) -> ServoGains | None:
        """The gains the servo loop runs with (None: no servo loop)."""
        return self.servo.gains if self.servo is not None else None

    def _signal_write(self, sub: int, value: Value) -> None:
        """A write to the test signal generator (docs/tuning.md): 1 starts and 0 stops at
        the control sub; the configuration is refused while a signal runs."""
        sig = self.siggen
        assert sig is not None
        if sub == SUB_CONTROL:
            if value == 0:
                sig.stop()
                return
            if value != 1:
                raise SimAbort(0x06090030, "write 1 to start or 0 to stop the test signal")
            if self._state is not State.OPERATION_ENABLED or not self._enabled:
                raise SimAbort(0x08000022, "the test signal needs Operation enabled")
            base = self._sig_index << 8

            def num(sub: int) -> float:
                v = self._values.get(base | sub)
                return float(v) if isinstance(v, int | float) else 0.0

            cfg = SignalConfig(
                kind=int(num(SUB_KIND)),
                amplitude=num(SUB_AMPLITUDE),
                f_start=num(SUB_F_START),
                f_end=num(SUB_F_END),
                duration=num(SUB_DURATION),
            )
            try:
                sig.start(cfg)
            except ValueError as exc:
                raise SimAbort(0x08000020, str(exc)) from exc
            return
        if sig.running:
            raise SimAbort(0x08000022, "the test signal runs: write 0 to the control object first")

    def _servo_prepare(self, p_act: int, v_act: float) -> None:
        """Per control cycle: the torque limit, and the demand of the active control kind
        (the sub-steps then run the loop, :meth:`_servo_substeps`)."""
        servo = self.servo
        assert servo is not None
        limit = self._c[K_MAX_TORQUE] * 0.001 * self._rated
        pk = self.plant_params.peak_torque
        servo.torque_limit = limit if limit < pk else pk
        kind = self._kind
        if kind == CTRL_TORQUE:
            self._fe = 0.0
            self._torque_demand_step()
            # Speed limit (607Fh or the simulation's maximum) so a free motor cannot run away.
            vmax = float(self._c[K_MAX_PROFILE_VEL]) or self._vmax_sim
            self._srv_vlim = vmax / self._counts_per_rad
            self._dp = float(p_act)
            self._dv = v_act
        elif kind == CTRL_POSITION:
            # The demand and the position at the same instant, the start of the cycle (the
            # loop reaches this cycle's demand only at its last tick).
            self._fe = self._raw0 + self._pos_offset - p_act
        else:
            self._fe = 0.0
            self._dp = float(p_act)

    def _servo_substeps(self, raw0: float, hooks: tuple[StepHook, ...]) -> None:
        """The cycle's plant sub-steps, the servo loop ticking before each (one tick per
        sub-step: the loop and the plant run at the loop rate), the test signal added, the
        position demand interpolated linearly from ``raw0`` to this cycle's demand; the
        sub-step hooks after every sub-step, as :meth:`_substeps_hooked` does."""
        servo = self.servo
        assert servo is not None
        plant = self.plant
        dt = self._sub_dt
        n = self._substeps
        if not self._enabled:
            servo.command = 0.0  # The power stage is off: no torque command.
            if hooks:
                self._substeps_hooked(0.0, hooks)
            else:
                plant.step_n(0.0, dt, n)
            return
        sig = self.siggen
        signal = sig.next if sig is not None and sig.running else None
        if signal is None:
            servo.tau_test = 0.0
        rad = 1.0 / self._counts_per_rad
        kind = self._kind
        after = self._after_tick if hooks else None
        if kind == CTRL_POSITION:
            self._inc = inc = (self._dp - self._pos_offset - raw0) / n
            _, sat = servo.run(
                n,
                plant.step_counts,
                dt,
                plant.encoder_counts,
                mode=POSITION,
                p0=raw0,
                inc=inc,
                v_demand=self._dv * rad,
                a_demand=self._da * rad,
                signal=signal,
                after=after,
            )
        elif kind == CTRL_VELOCITY:
            _, sat = servo.run(
                n,
                plant.step_counts,
                dt,
                plant.encoder_counts,
                mode=VELOCITY,
                v_demand=self._dv * rad,
                a_demand=self._da * rad,
                signal=signal,
                after=after,
            )
        else:
            _, sat = servo.run(
                n,
                plant.step_counts,
                dt,
                plant.encoder_counts,
                mode=TORQUE,
                tau_demand=self._tq_demand,
                v_limit=self._srv_vlim,
                signal=signal,
                after=after,
            )
        self._sat = sat

    def _after_tick(self, k: int) -> None:
        """After servo tick ``k`` of the cycle: the sub-step hooks (the recorder)."""
        self._sub_k = k
        for hook in self._substep_hooks:
            hook()

    def _torque_demand_step(self) -> None:
        """One cycle of the torque demand toward 6071h: cst applies the set-point at once;
        6087h (torque slope) shapes profile torque only."""
        tgt = self._c[K_TARGET_TORQUE] * 0.001 * self._rated
        slope = self._c[K_TORQUE_SLOPE] if self._mode == 4 else 0
        if slope:
            step = slope * 0.001 * self._rated * self._T
            d = tgt - self._tq_demand
            self._tq_demand += max(-step, min(step, d))
        else:
            self._tq_demand = tgt

    def _substeps_hooked(self, torque: float, hooks: tuple[StepHook, ...]) -> None:
        """The cycle's plant sub-steps one at a time, each followed by the sub-step hooks
        (Plant.step_n with n = 1 does the same arithmetic as one call for all of them)."""
        step_n = self.plant.step_n
        dt = self._sub_dt
        for k in range(1, self._substeps + 1):
            step_n(torque, dt, 1)
            self._sub_k = k
            for hook in hooks:
                hook()

    def _control(self, p_act: int, v_act: float) -> float:
        if self.servo is not None:
            self._servo_prepare(p_act, v_act)
            return 0.0
        g = self.gains
        kind = self._kind
        limit = self._c[K_MAX_TORQUE] * 0.001 * self._rated
        if kind == CTRL_TORQUE:
            self._fe = 0.0
            self._torque_demand_step()
            t = self._tq_demand
            # Speed limit (607Fh or the simulation's maximum) so a free motor cannot run away.
            vmax = float(self._c[K_MAX_PROFILE_VEL]) or self._vmax_sim
            if v_act > vmax:
                t = min(t, g.kp_vel * (vmax - v_act))
            elif v_act < -vmax:
                t = max(t, g.kp_vel * (-vmax - v_act))
            self._dp = float(p_act)
            self._dv = v_act
        else:
            # The torque set now acts over the coming cycle, so the acceleration it feeds
            # forward is the demand's for that cycle (this cycle's generator step), and the
            # loop tracks the demand as it stood at the start of the cycle: the profile runs
            # one control cycle late and the feed-forward on time. The generators step the
            # position with the new velocity (dp += v T), half a step of each velocity change
            # ahead of the motion a held torque gives, so the tracked position is that demand
            # less dv T / 2. Tracking this cycle's demand instead put the feed-forward a cycle
            # behind: the LECSN twin's tuned gains at low response overshot a 0.3 s ramp by
            # 98-122 counts on the exactly integrated plant, now 7-12 (docs/tuning.md, "The
            # other twins").
            dv0 = self._dv0
            if kind == CTRL_POSITION:
                ref = self._raw0 + self._pos_offset - 0.5 * dv0 * self._T
                err = ref - p_act
                self._fe = err
                v_cmd = g.kp_pos * err + dv0
            else:
                self._fe = 0.0
                self._dp = float(p_act)
                v_cmd = dv0
            ev = v_cmd - v_act
            t = g.kp_vel * ev + self._integ + g.acc_ff * self._da
            # Conditional integration (anti-windup): hold the integral while saturated.
            if -limit < t < limit or (t > 0.0) != (ev > 0.0):
                self._integ += g.kp_vel * g.ki_vel * ev * self._T
        if t > limit:
            self._sat = True
            return limit
        if t < -limit:
            self._sat = True
            return -limit
        self._sat = False
        return t
