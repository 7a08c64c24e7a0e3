"""The CiA 402 state machine of the simulated drive, its fault handling and monitoring.

Part of :class:`~servodesk.sim.engine.SimulatedDrive` (sim/engine.py says why the parts are a
chain of base classes). The transitions come from domain/cia402.py (``device_transition``, the
table of CiA 402-2 §6.2.1); this module does what each one means for the axis:

- Disable operation (605Ch = 1), shutdown (605Bh = 1), quick stop (605Ah, §6.3.4) and the
  fault reaction (605Eh) ramp the axis down and report the source state until it has stopped,
  then change state; quick stop options 3/7 and 4/8 both stop at the torque limit 6072h (no
  DC-link model would make them differ).
- A fault (:meth:`StateMachine._fault`) sets 603Fh, the error register 1001h (the class bits
  of CiA 301 §7.5.2.2 table 21 unless the profile's error entry gives its own), the error
  history 1003h and the family's alarm objects (sim/faults.py), and queues an EMCY that
  :meth:`StateMachine._flush` delivers after the drive's lock is released.
- The statusword is computed when read (:meth:`StateMachine._statusword`); the monitoring
  after every cycle (:meth:`StateMachine._monitor`) raises the following error, I²t
  overload and limit switch faults with the family's codes, and sets target reached.
"""

from __future__ import annotations

from servodesk.domain.cia402 import STATE_BITS, State, device_transition
from servodesk.domain.datatypes import coerce_int
from servodesk.domain.profile import ErrorEntry
from servodesk.sim.engine_base import (
    CTRL_OFF,
    CTRL_POSITION,
    K_CONTROLWORD,
    K_DISABLE_OP_OPTION,
    K_ERROR_CODE,
    K_ERROR_HISTORY,
    K_ERROR_REGISTER,
    K_FAULT_OPTION,
    K_FE_TIMEOUT,
    K_FE_WINDOW,
    K_HOMING_METHOD,
    K_MAX_TORQUE,
    K_POS_WINDOW,
    K_POS_WINDOW_TIME,
    K_PROFILE_DEC,
    K_QS_DEC,
    K_QS_OPTION,
    K_SHUTDOWN_OPTION,
    K_TARGET_TORQUE,
    K_TARGET_VELOCITY,
    K_VEL_THRESHOLD,
    K_VEL_WINDOW,
    K_VEL_WINDOW_TIME,
)
from servodesk.sim.engine_setpoints import SetPoints

_VOLTAGE_STATES = frozenset(
    (
        State.READY_TO_SWITCH_ON,
        State.SWITCHED_ON,
        State.OPERATION_ENABLED,
        State.QUICK_STOP_ACTIVE,
        State.FAULT_REACTION_ACTIVE,
    )
)


class StateMachine(SetPoints):
    """Controlword transitions, enable and disable, faults and their reset, monitoring."""

    def _statusword(self) -> int:
        st = self._state
        if st is State.QUICK_STOP_ACTIVE and self._qs_statusword is not None:
            return self._qs_statusword
        sw = STATE_BITS.get(st, 0) | 0x0200  # Bit 9 remote: the bus controls the drive.
        if st in _VOLTAGE_STATES:
            sw |= 0x0010
        if self._reached:
            sw |= 0x0400
        if self._sat or self._clipped:
            sw |= 0x0800  # Internal limit active: torque limit or a clipped set-point.
        m = self._mode
        if m == 1:
            if self._sp_ack:
                sw |= 0x1000
            if self._fe_flag:
                sw |= 0x2000
        elif m == 3:
            if abs(self.plant.velocity_counts) <= self._c[K_VEL_THRESHOLD]:
                sw |= 0x1000
        elif m in (8, 9, 10) and st is State.OPERATION_ENABLED and not self._halted:
            sw |= 0x1000  # csp/csv/cst bit 12: the drive follows the command value.
        elif m == 6:
            if self._homed:
                sw |= 0x1000
            if self._homing_error:
                sw |= 0x2000
        return sw

    def _torque_actual(self) -> int:
        return round(self.plant.torque / self._rated * 1000.0)

    def _controlword(self, cw: int) -> None:
        if self._cw_min_interval and self.time - self._cw_time < self._cw_min_interval - 1e-9:
            return  # Too soon after the last one: the drive drops it (sim/engine.py docstring).
        prev = self._cw
        self._cw = cw
        self._cw_time = self.time
        self._values[K_CONTROLWORD] = cw
        st = self._state
        if st is State.FAULT:
            if self._bit7_resets and cw & 0x80 and not prev & 0x80:
                self._fault_reset()
            return
        t = device_transition(st, cw, prev, self._c[K_QS_OPTION])
        if t is not None:
            self._take(t.number)
        if self._state is State.OPERATION_ENABLED:
            self._mode_bits(cw, prev)
        elif (
            self._mode == 6
            and cw & 0x10
            and not prev & 0x10
            and self._c[K_HOMING_METHOD] in self._homing_no_enable
        ):
            # Quirk homing_without_enable (000 §3.2.4 table 3.2.4.4: methods 37 and -3 do
            # not need Operation enabled): the current position becomes home at once.
            self._home()

    def _take(self, number: int) -> None:
        S = State
        if number == 2:
            self._state = S.READY_TO_SWITCH_ON
        elif number == 3:
            self._state = S.SWITCHED_ON
        elif number in (4, 34):
            self._state = S.OPERATION_ENABLED
            self._enable()
        elif number == 5:
            self._disable_with(K_DISABLE_OP_OPTION, S.SWITCHED_ON)
        elif number == 6:
            self._state = S.READY_TO_SWITCH_ON
        elif number in (7, 10):
            self._state = S.SWITCH_ON_DISABLED
        elif number == 8:
            self._disable_with(K_SHUTDOWN_OPTION, S.READY_TO_SWITCH_ON)
        elif number in (9, 12):
            self._disable()
            self._state = S.SWITCH_ON_DISABLED
        elif number == 11:
            self._quick_stop()
        elif number == 16:
            # Back from Quick stop active (605Ah 5..8): the interrupted move is dropped.
            self._state = S.OPERATION_ENABLED
            self._stop = None
            self._hold = False
            self._pp_done = True
            self._pp_buffer = None
            self._begin_motion()

    def _disable_with(self, option_key: int, target: State) -> None:
        """Transitions 5 and 8: free wheel (option 0) or slow-down ramp, then disable."""
        if self._c[option_key] == 1 and self._enabled:

            def done() -> None:
                self._disable()
                self._state = target

            self._start_stop(float(self._c[K_PROFILE_DEC]), done)
        else:
            self._disable()
            self._state = target

    def _quick_stop(self) -> None:
        """Transition 11 and the quick stop function (605Ah, CiA 402-2 §6.3.4)."""
        opt = self._c[K_QS_OPTION]
        self._state = State.QUICK_STOP_ACTIVE
        if opt <= 0 or not self._enabled:
            self._disable()
            self._state = State.SWITCH_ON_DISABLED
            return
        decel = self._decel_for(opt if opt <= 4 else opt - 4)

        def done() -> None:
            if opt <= 4:
                self._disable()
                self._state = State.SWITCH_ON_DISABLED  # Transition 12, automatic.
            else:
                self._hold = True
                self._reached = True

        self._start_stop(decel, done)

    def _decel_for(self, ramp: int) -> float:
        """1: slow-down ramp (6084h), 2: quick-stop ramp (6085h), 3/4: torque limit."""
        if ramp == 1:
            return float(self._c[K_PROFILE_DEC])
        if ramp == 2:
            return float(self._c[K_QS_DEC])
        limit = self._c[K_MAX_TORQUE] / 1000.0 * self._rated
        return limit / self.plant_params.inertia * self._counts_per_rad

    def _fault(self, code: int) -> None:
        if self._state in (State.FAULT, State.FAULT_REACTION_ACTIVE):
            return
        entry = self._error_entry(code)
        reg = 0x01
        extra = entry.extra.get("error_register") if entry is not None else None
        if isinstance(extra, int | str):
            reg = coerce_int(extra) | 0x01
        else:
            reg |= _register_bits(code)
        # Alarm numbers wider than 603Fh (LECSN-T XXXXVVVVh, 004 §20.9.3.3) are reported in
        # the family's current-alarm object; 603Fh and the EMCY then carry FF00h
        # (manufacturer specific) and the EMCY data the alarm number.
        wide = code > 0xFFFF
        self._values[K_ERROR_CODE] = 0xFF00 if wide else code
        if K_ERROR_REGISTER in self._specs:
            self._values[K_ERROR_REGISTER] = reg
        self._push_history(0xFF00 if wide else code)
        self.faults.on_fault(self._values, code, int(self.time // 3600))
        data = code.to_bytes(4, "little") + b"\x00" if wide else bytes(5)
        self._events.append((0xFF00 if wide else code, reg, data))
        self._state = State.FAULT_REACTION_ACTIVE
        opt = self._c[K_FAULT_OPTION]

        def done() -> None:
            self._disable()
            self._state = State.FAULT

        if self._enabled and opt in (1, 2):
            self._start_stop(self._decel_for(opt), done)
        else:
            done()

    def _push_history(self, code: int) -> None:
        n = self._history_len
        if n <= 0:
            return
        base = K_ERROR_HISTORY << 8
        for s in range(n, 1, -1):
            self._values[base | s] = self._values.get(base | (s - 1))
        self._values[base | 1] = code
        count = self._values.get(base)
        self._values[base] = min(n, (count if isinstance(count, int) else 0) + 1)

    def _fault_reset(self) -> None:
        self._state = State.SWITCH_ON_DISABLED
        self._values[K_ERROR_CODE] = 0
        reg = 0
        if K_ERROR_REGISTER in self._specs:
            self._values[K_ERROR_REGISTER] = reg
        self._fe_flag = False
        self._fe_time = 0.0
        self.faults.on_reset(self._values)
        self._events.append((0, reg, bytes(5)))

    def _flush(self) -> None:
        if not self._events:
            return
        with self._lock:
            events, self._events = self._events, []
        for code, reg, data in events:
            for cb in self._emcy_listeners:
                cb(code, reg, data)

    def _enable(self) -> None:
        p = float(self.plant.encoder_counts + self._pos_offset)
        self._enabled = True
        self._dp = p
        self._dv = 0.0
        self._da = 0.0
        self._integ = 0.0
        self._stop = None
        self._hold = False
        self._fe_time = 0.0
        self._fe_flag = False
        self._pp_target = p
        self._pp_done = True
        self._pp_buffer = None
        self._win_time = 0.0
        self._tq_demand = 0.0
        # A limit switch already active at enable is not a new limit event.
        self._limit_prev = self.switches.inputs(self.plant.encoder_counts) & 0x03
        if self.servo is not None:
            self.servo.reset(self.plant.encoder_counts)
        self._begin_motion()

    def _disable(self) -> None:
        self._enabled = False
        self._kind = CTRL_OFF
        self._stop = None
        self._hold = False
        self._integ = 0.0
        self._reached = False
        self._sp_ack = False
        self._pp_buffer = None
        self._sat = False
        self._clipped = False
        self._fe_flag = False
        if self.siggen is not None:
            self.siggen.stop()  # The test signal needs the loops running.

    def _monitor(self, p_act: int, v_act: float) -> None:
        T = self._T
        # Following error (CiA 402-2 §6.5.7/§6.5.8), position control only.
        if self._kind == CTRL_POSITION:
            window = self._c[K_FE_WINDOW]
            if window != 0xFFFFFFFF and abs(self._fe) > window:
                self._fe_flag = True
                self._fe_time += T
                code = self.faults.code("following_error")
                if code is not None and self._fe_time > self._c[K_FE_TIMEOUT] * 0.001 + 1e-9:
                    self._fault(code)
                    return
            else:
                self._fe_flag = False
                self._fe_time = 0.0
        if self._i2t > self._i2t_limit:
            code = self.faults.code("overload")
            if code is not None:
                self._fault(code)
                return
        # Hardware limit switches outside homing (where they are part of the search).
        lim = self.switches.inputs(self.plant.encoder_counts) & 0x03
        rising, self._limit_prev = lim & ~self._limit_prev, lim
        if rising and self._mode != 6:
            code = self.faults.code("limit_switch")
            if code is not None:
                self._fault(code)
                return
        if self._state is not State.OPERATION_ENABLED or self._stop is not None:
            return
        if self._halted:
            return
        m = self._mode
        if m == 1:
            if self._pp_done and abs(p_act - self._pp_target) <= self._c[K_POS_WINDOW]:
                self._win_time += T
                self._reached = self._win_time >= self._c[K_POS_WINDOW_TIME] * 0.001 - 1e-9
            else:
                self._win_time = 0.0
                self._reached = False
        elif m == 3:
            tgt = self._c[K_TARGET_VELOCITY]
            if abs(v_act - tgt) <= self._c[K_VEL_WINDOW]:
                self._win_time += T
                self._reached = self._win_time >= self._c[K_VEL_WINDOW_TIME] * 0.001 - 1e-9
            else:
                self._win_time = 0.0
                self._reached = False
        elif m == 4:
            self._reached = abs(self._torque_actual() - self._c[K_TARGET_TORQUE]) <= 10
        elif m == 6:
            # CiA 402-2 §6.8.1 bits 13/12/10: bit 10 when attained, not started, interrupted
            # (once stopped; not on a family that clears it on a cancel, quirk
            # homing_cancel_clears_status), or after a homing error once the axis has stopped.
            stopped = self._homing is None and abs(v_act) <= self._c[K_VEL_THRESHOLD]
            at_home = abs(p_act - self._dp) <= self._c[K_POS_WINDOW]
            self._reached = (
                (self._homed and at_home)
                or (not self._homing_started and stopped and not self._homing_cancelled)
                or (self._homing_error and stopped)
            )

    def _error_entry(self, code: int) -> ErrorEntry | None:
        p = self.profile
        return p.error("error_code", code) or p.error("emcy", code) or p.error("alarm", code)


def _register_bits(code: int) -> int:
    """Error register (1001h) bits for an error code class (CiA 301 §7.5.2.2, table 21)."""
    hi = code >> 12
    if hi == 0x2:
        return 0x02  # Current.
    if hi == 0x3:
        return 0x04  # Voltage.
    if hi == 0x4:
        return 0x08  # Temperature.
    if code >> 8 in (0x81, 0x82):
        return 0x10  # Communication.
    if hi == 0x8 or hi == 0x7:
        return 0x20  # Device profile specific (CiA 402 monitoring, sensors).
    if code >> 8 == 0xFF:
        return 0x80  # Manufacturer specific.
    return 0x00
