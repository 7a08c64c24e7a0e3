"""The simulated CiA 402 drive: object store, state machine, modes, controllers, faults.

:class:`SimulatedDrive` is the device behaviour without any bus code: a fieldbus front-end
(``canopen_device``) turns SDO requests into :meth:`SimulatedDrive.read_bytes` /
:meth:`SimulatedDrive.write_bytes` and forwards the EMCY events the drive emits. Everything
family-specific comes from the :class:`~servodesk.domain.profile.DeviceProfile`: objects,
limits, defaults, supported modes and homing methods, error texts and quirks.

Time is simulated: :meth:`SimulatedDrive.step` advances it; the control cycle runs at 1 kHz
with several plant sub-steps per cycle. The drive is thread-safe: requests may arrive on a
bus thread while a runner thread steps it. Events (EMCY, written objects) are delivered to
listeners after the internal lock is released, so a listener may call back into the drive.

Choices where the standard leaves room (documented here once):

- Statusword bit 4 (voltage enabled) is set in Ready to switch on, Switched on, Operation
  enabled, Quick stop active and Fault reaction active: the simulated DC link is always
  charged, and the bit tells that the master has asked for the power stage (CiA 402-2 §6.2.1).
- Disable operation (605Ch = 1), shutdown (605Bh = 1), quick stop and fault reaction ramps:
  the drive reports the source state until the axis has stopped, then changes state.
- Quick stop options 3/7 (current limit) and 4/8 (voltage limit) both stop at the torque
  limit 6072h: the simulation has no DC-link model that would make them differ.
- Quirk ``controlword_min_interval_ms``: a controlword written sooner than the interval after
  the previously accepted one is confirmed on the bus but not acted upon, and 6040h keeps the
  accepted value (smartris 001 §5 caution: "send the next controlword command at least 40 ms
  later"; the manual does not say what happens otherwise, and a dropped command is the
  failure a master that ignores the rule must be able to see).
- Faults are reset by the rising edge of controlword bit 7 unless the profile says otherwise
  (quirk ``no_fault_reset_bit7`` or a ``fault_reset`` other than ``bit7_edge``); then only a
  node reset (:meth:`reset_node`, NMT reset node) clears them.
- Homing (mode 6) runs every method the profile lists and can describe (sim/homing.py,
  domain/homing.py; vendor methods through the quirk ``homing_method_equivalent``); 6098h
  refuses the others with 0609 0030h. Faults use the family's codes from the quirk
  ``sim_fault_codes`` (following error, limit switch outside homing, I²t overload) and its
  alarm objects (sim/faults.py); a condition the family has no code for raises no fault.
- PDO mapping objects (1600h-17FFh, 1A00h-1BFFh) without their own ``writable_in`` accept
  writes in the NMT state named by ``pdo.mapping_state`` ("preop" by default, "any" for no
  restriction) or whenever the PDO is invalid (bit 31 of its COB-ID set): CiA 301 §7.5.2.36
  re-mapping procedure, which disables the PDO first and so may run in OPERATIONAL too.
  Setting a mapping's count checks the entries (0604 0041h), the family's entry and bit limits
  (0604 0042h) and, where ``pdo.allow_duplicates`` is false or the quirk
  ``pdo_no_duplicate_entries`` is set, an object mapped twice (0604 0043h); setting 1C12h/1C13h
  sub 0 checks the assigned mapping objects against ``max_entries`` and ``max_bytes`` (HIWIN
  000 §3.1.2 note 1: 0604 0042h). The quirks ``pdo_state_abort`` and
  ``pdo_unknown_object_abort`` give a family's own abort codes for a mapping write in the
  wrong state and for an entry naming no object.
- Process data (sim/pdo.py) reaches the objects through :meth:`SimulatedDrive.write_process`
  and :meth:`SimulatedDrive.sample`; hooks registered with :meth:`SimulatedDrive.on_cycle`
  run after every control cycle, so event timers and inhibit times follow simulated time.
- Hooks registered with :meth:`SimulatedDrive.on_substep` run after every plant sub-step (the
  drive-side recorder, sim/recorder.py, samples there); with none registered the plant runs a
  cycle's sub-steps in one call, and with some it runs them one at a time with the same
  arithmetic, so a hook never changes the simulation.
- The loop rate (``simulation.loop_rate_hz``, or a plant file's ``[loop] rate_hz`` given to
  the constructor) sets the plant sub-steps: rate / 1000 per 1 ms control cycle. A profile
  with ``tuning.kind: gains`` (docs/tuning.md) runs the servo loop of model/servo.py once per
  sub-step, its gains read from the mapped objects (raw * scale) and reloaded after every
  write to one of them (and after a node reset restores them); the control cycle only
  generates the demand, which the loop interpolates linearly across the cycle. The test
  signal generator (sim/siggen.py) adds its torque in the loop while it runs; it starts only
  in Operation enabled (0800 0022h otherwise) and stops when the drive is disabled. Other
  profiles keep the cycle-rate cascade (:class:`ControllerGains`) with the torque held over
  the cycle's sub-steps; it tracks the demand as it stood at the start of the cycle and feeds
  forward the acceleration of the cycle ahead (:meth:`SimulatedDrive._control`). A plant
  with another encoder resolution than the profile's keeps the profile's speeds, switch
  positions and homing travel in revolutions.

How the class is built (issue 51 item 3): :class:`SimulatedDrive` is the one class callers use;
its parts live in modules named for what they hold, and it is the last of a chain of base
classes, each of which may call the ones before it:

- sim/engine_base.py: the object keys, the fallbacks, :class:`SimAbort`, the cascade gains and
  :class:`~servodesk.sim.engine_base.DriveBase`, the state declared once;
- sim/engine_servo.py: servo glue (the model's servo loop or the cycle-rate cascade, the
  plant's sub-steps, the test signal);
- sim/engine_setpoints.py: set-point generators (pp, pv, csp, csv, torque; stop ramps; homing);
- sim/engine_states.py: the CiA 402 state machine, faults, monitoring, the statusword;
- sim/engine_objects.py: object access (reads, writes, their checks and side effects, store and
  restore, process data), with the PDO mapping rules a collaborator of their own
  (sim/engine_pdo_rules.py, ``MappingRules``, which keeps no state);
- this module: construction from the profile (every quirk the parts act on is read here, once),
  the public surface, the hooks, the resets and the control cycle that runs the parts in order.

Why a chain of base classes rather than collaborators: the state machine, the generators, the
servo glue and the monitoring read and write the same dozen demand and status variables
(``_dp``, ``_dv``, ``_kind``, ``_state``, ``_reached``, ...) in every 1 ms cycle, under one
lock. As collaborators they would reach them through a shared object, one more attribute hop
per access in the cycle (the twin is to run at >= 20x real time, bench/bench_sim.py), and the
arithmetic the tests pin would have to be rewritten; as one chain the code moved unchanged, and
each part's calls into the parts before it are type-checked without stubs. The order is that of
their calls: object access drives the state machine, which starts the generators, which feed
the servo glue. A part that needs none of the shared state is a collaborator (``MappingRules``,
sim/faults.py, sim/homing.py, sim/recorder.py, sim/onetouch.py).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable

from servodesk.domain.cia402 import State
from servodesk.domain.datatypes import Value, coerce_int
from servodesk.domain.encoder_units import INCREMENT_UNITS
from servodesk.domain.profile import DeviceProfile, ObjectSpec, SimSettings
from servodesk.model.plant import Plant, PlantParams
from servodesk.model.profile_position import CONTROL_PERIOD_S
from servodesk.sim.engine_base import (
    CTRL_OFF,
    CTRL_POSITION,
    CTRL_TORQUE,
    CTRL_VELOCITY,
    K_CONTROLWORD,
    K_ERROR_CODE,
    K_ERROR_HISTORY,
    K_ERROR_REGISTER,
    K_FE_ACTUAL,
    K_HALT_OPTION,
    K_HEARTBEAT,
    K_IDENTITY_SERIAL,
    K_INPUTS,
    K_MODE,
    K_MODE_DISPLAY,
    K_POSITION,
    K_STATUSWORD,
    K_TORQUE,
    K_VEL_THRESHOLD,
    K_VELOCITY,
    NMT_ALIASES,
    POSITION_MODES,
    SIGNATURE_LOAD,
    SIGNATURE_SAVE,
    ControllerGains,
    EmcyListener,
    SimAbort,
    StepHook,
    WriteListener,
    key,
    norm,
)
from servodesk.sim.engine_objects import ObjectAccess, command_quirk
from servodesk.sim.engine_pdo_rules import MappingRules
from servodesk.sim.faults import FaultModel
from servodesk.sim.homing import SwitchLayout
from servodesk.sim.onetouch import OneTouchTuning
from servodesk.sim.pdo import pdo_kind
from servodesk.sim.recorder import Recorder
from servodesk.sim.siggen import SUB_CONTROL, SUB_TORQUE, SUB_VALUE

# What callers import from here (the front-ends, sim/onetouch.py, tests): the one class, its
# abort, the cascade gains, the store/restore signatures and the heartbeat object's key.
__all__ = [
    "K_HEARTBEAT",
    "SIGNATURE_LOAD",
    "SIGNATURE_SAVE",
    "ControllerGains",
    "SimAbort",
    "SimulatedDrive",
]


class SimulatedDrive(ObjectAccess):
    """One simulated CiA 402 axis, built from a device profile."""

    CONTROL_PERIOD = CONTROL_PERIOD_S

    def __init__(
        self,
        profile: DeviceProfile,
        node_id: int,
        serial: int | None = None,
        *,
        plant_params: PlantParams | None = None,
        plant_substeps: int | None = None,
        gains: ControllerGains | None = None,
        loop_rate_hz: int | None = None,
        max_velocity: float | None = None,
    ) -> None:
        """``max_velocity``: the machine's top speed [counts/s], which caps every profile
        (default: the profile's simulation setting, in revolutions per second at the plant's
        encoder)."""
        self.profile = profile
        self.node_id = node_id
        self._lock = threading.RLock()
        self._emcy_listeners = []
        self._write_listeners = []
        self._cycle_hooks = []
        self._step_hooks = []
        # A tuple, replaced on change: a hook may remove itself while the cycle runs the hooks.
        self._substep_hooks = ()
        self._events = []

        # Object store.
        self._specs = {}
        self._subs = {}
        self._defaults = {}
        for spec in profile.variables.values():
            k = key(spec.index, spec.subindex)
            self._specs[k] = spec
            self._subs.setdefault(spec.index, set()).add(spec.subindex)
            d = spec.default_value(node_id)
            if isinstance(d, bool):
                d = int(d)
            self._defaults[k] = d
        if K_IDENTITY_SERIAL in self._specs:
            if serial is not None:
                self._defaults[K_IDENTITY_SERIAL] = serial
            elif self._defaults[K_IDENTITY_SERIAL] is None:
                self._defaults[K_IDENTITY_SERIAL] = profile.simulation.serial_number
        self._values = dict(self._defaults)
        #: The non-volatile copy: persist objects saved by "store parameters".
        self._nv = {}
        self._history_len = len(self._subs.get(K_ERROR_HISTORY, {0})) - 1

        # Profile data read once.
        self._modes = frozenset(profile.modes)
        # 6060h = 0 is "no mode change / no mode assigned" (CiA 402-2), not a mode: accepted
        # where the profile lists 0 among 6060h's values, as the manuals of the drives that
        # start at 0 do (000 §3.2 6060h, 001 §5-4 6060h); a restore writes it back.
        mode_spec = self._specs.get(K_MODE)
        no_mode = mode_spec is not None and 0 in (mode_spec.values or {})
        self._mode_values = self._modes | ({0} if no_mode else set())
        self._homing_methods = frozenset(profile.homing_methods)
        self._store_cmd = command_quirk(profile, "store_parameters", 0x1010, SIGNATURE_SAVE)
        self._restore_cmd = command_quirk(profile, "restore_defaults", 0x1011, SIGNATURE_LOAD)
        q = profile.quirk("controlword_min_interval_ms")
        self._cw_min_interval = float(q) / 1000.0 if q else 0.0
        q = profile.quirk("quick_stop_statusword")
        self._qs_statusword = coerce_int(q) if q is not None else None
        reset_id = profile.quirk("fault_reset", "bit7_edge")
        self._bit7_resets = not profile.quirk("no_fault_reset_bit7", False) and reset_id in (
            None,
            "bit7_edge",
        )
        # Quirk pdo_state_abort (HIWIN 000 §2.8.1 note 1: 0601 0002h): the abort answering a
        # write of a mapping or assignment object outside the state that allows it.
        q = profile.quirk("pdo_state_abort")
        state_abort = coerce_int(q) if q is not None else 0x08000022
        # Quirk pdo_unknown_object_abort (smartris 001 §2-8 note 1, HIWIN 000 §2.8.1 note 2:
        # 0602 0000h): the abort for a mapping entry naming no object (CiA 301: 0604 0041h).
        q = profile.quirk("pdo_unknown_object_abort")
        unknown_abort = coerce_int(q) if q is not None else 0x06040041
        self._pdo_rules = MappingRules(
            profile.pdo,
            mapping_state=NMT_ALIASES.get(norm(profile.pdo.mapping_state), "any"),
            state_abort=state_abort,
            unknown_abort=unknown_abort,
            # PROFIdrive telegrams pad with Reserved entries (004 §20.1.2).
            reserved=pdo_kind(profile) == "telegram",
            # HIWIN 000 §3.1 (1600h): an object may be mapped only once (quirk or pdo rule).
            duplicates=profile.pdo.allow_duplicates
            and not profile.quirk("pdo_no_duplicate_entries", False),
        )
        self._homing_equiv = profile.quirk("homing_method_equivalent")
        # Quirk ramp_rate_registers (003 §5-3-1): 609Ah is a PMC842SR rate register, not
        # counts/s²; with multiplier 1 the ramp is Fclk/8 / register [pulses/s²].
        rr = profile.quirk("ramp_rate_registers")
        # The objects it names (6083h, 6084h, 609Ah) are rate registers.
        regs = rr if isinstance(rr, dict) and rr.get("fclk_hz") else {}
        self._rate_fclk = float(regs.get("fclk_hz", 0.0))
        self._rate_registers = frozenset(
            coerce_int(regs[key]) for key in ("accel", "decel", "homing") if regs.get(key)
        )
        self._homing_no_enable = frozenset(
            coerce_int(m) for m in profile.quirk("homing_without_enable", None) or ()
        )
        # Quirk homing_cancel_clears_status (CTMM04x 003 §4-4-7, "ホーミングモードキャンセル"):
        # clearing bit 4 before the end leaves bits 13, 12 and 10 all 0, which CiA 402-2
        # §6.8.1 reads as "in progress"; elsewhere bit 10 comes on once the axis stands.
        self._homing_cancel_clears = bool(profile.quirk("homing_cancel_clears_status", False))
        #: Family fault codes and alarm objects (quirks sim_fault_codes, alarm_history).
        self.faults = FaultModel(profile)

        # Physics and control.
        sim = profile.simulation
        self.plant_params = plant_params or PlantParams.from_settings(sim)
        if self.plant_params.counts_per_rev != sim.counts_per_rev:
            # A plant file's encoder: keep the travel, speeds and switches in revolutions,
            # and so the objects' defaults in increments (607Fh, 6081h, 6065h, ...).
            f = self.plant_params.counts_per_rev / sim.counts_per_rev
            sim = _rescaled(sim, self.plant_params.counts_per_rev)
            self._defaults.update(_rescaled_defaults(self._specs, self._defaults, f))
            self._values = dict(self._defaults)
        if max_velocity is not None:
            if not max_velocity > 0.0:
                raise ValueError(f"max_velocity {max_velocity}: must be positive (counts/s)")
            sim = sim.model_copy(update={"max_velocity": float(max_velocity)})
        #: The simulation settings in effect (the profile's, rescaled to the plant's encoder).
        self.sim_settings = sim
        self.plant = Plant(self.plant_params)
        self.gains = gains or ControllerGains.from_plant(self.plant_params)
        if plant_substeps is not None:
            rate = 1000 * max(1, plant_substeps)
        else:
            rate = loop_rate_hz if loop_rate_hz is not None else sim.loop_rate_hz
        if rate < 1000 or rate % 1000:
            raise ValueError(f"loop rate {rate} Hz: a multiple of 1000 Hz (whole ticks per cycle)")
        #: Servo loop and plant rate [Hz]: loop_rate_hz / 1000 plant sub-steps per cycle.
        self.loop_rate_hz = int(rate)
        self._substeps = self.loop_rate_hz // 1000
        self._T = self.CONTROL_PERIOD
        self._sub_dt = self._T / self._substeps
        self._rated = self.plant_params.rated_torque
        self._counts_per_rad = self.plant.counts_per_rad
        self._vmax_sim = float(sim.max_velocity)
        self._limits_in_pv = sim.software_limits_in_pv
        self.switches = SwitchLayout.from_settings(sim)
        self._homing_max_travel = sim.homing_max_travel_revs * sim.counts_per_rev
        self._i2t_tau = max(sim.i2t_time_constant, 1e-3)
        self._i2t_limit = sim.i2t_limit_ratio**2
        self._i2t = 0.0
        self._init_servo(profile)

        #: NMT (or ESM) state, set by the front-end: "init", "preop", "op", "stopped".
        self.nmt_state = "preop"
        self._cycles = 0
        #: Plant sub-steps of the current cycle done (inside a sub-step hook: the one just done).
        self._sub_k = self._substeps
        self._acc_time = 0.0
        self._inputs = 0
        #: The drive-side recorder (docs/scope.md), where the profile gives the drive one.
        self.recorder = None
        if profile.recorder is not None:
            self.recorder = Recorder(self, profile.recorder)
        #: Built-in one-touch tuning (quirk one_touch_tuning, 004 §20.8.7; sim/onetouch.py).
        self.one_touch = None
        if profile.quirk("one_touch_tuning") is not None:
            self.one_touch = OneTouchTuning(self, profile)
        self._reset_runtime()

    # ------------------------------------------------------------------ public surface

    @property
    def state(self) -> State:
        return self._state

    @property
    def statusword(self) -> int:
        with self._lock:
            return self._statusword()

    @property
    def mode(self) -> int:
        return self._mode

    @property
    def position(self) -> int:
        """Position actual value (6064h), counts."""
        with self._lock:
            return self.plant.encoder_counts + self._pos_offset

    @property
    def velocity(self) -> float:
        return self.plant.velocity_counts

    @property
    def error_code(self) -> int:
        return int(self._values.get(K_ERROR_CODE) or 0)

    def error_text(self, code: int | None = None) -> str:
        """The profile's name for an error code (603Fh table), e.g. "Following error"."""
        c = self.error_code if code is None else code
        e = self._error_entry(c)
        return e.name if e is not None else f"Error 0x{c:04X}"

    def on_emcy(self, listener: EmcyListener) -> None:
        """Call ``listener(code, error_register, manufacturer_data)`` for every EMCY."""
        self._emcy_listeners.append(listener)

    def on_write(self, listener: WriteListener) -> None:
        """Call ``listener(index, subindex, value)`` after every accepted write."""
        self._write_listeners.append(listener)

    def on_cycle(self, hook: StepHook) -> None:
        """Call ``hook()`` after every control cycle, under the drive's lock (keep it short:
        the process-data engine evaluates event timers and inhibit times here)."""
        self._cycle_hooks.append(hook)

    def on_substep(self, hook: StepHook) -> None:
        """Call ``hook()`` after every plant sub-step, under the drive's lock (keep it short:
        it runs at the plant rate); :attr:`plant_steps` is the step just done."""
        with self._lock:
            self._substep_hooks = (*self._substep_hooks, hook)

    def remove_substep_hook(self, hook: StepHook) -> None:
        """Stop calling a hook added with :meth:`on_substep` (no error when it is not there)."""
        with self._lock:
            self._substep_hooks = tuple(h for h in self._substep_hooks if h is not hook)

    @property
    def plant_steps(self) -> int:
        """Plant sub-steps since the drive was built: the plant's simulated time is
        ``plant_steps * plant_period``."""
        return (self._cycles - 1) * self._substeps + self._sub_k

    @property
    def plant_period(self) -> float:
        """Seconds per plant sub-step (the control period / ``plant_substeps``)."""
        return self._sub_dt

    def sampler(self, index: int, subindex: int = 0) -> Callable[[], Value | None]:
        """A function returning an object's value when called, for sampling inside the
        control cycle (the drive-side recorder): the live value of the plant-derived objects,
        the stored value of the others. 60F4h is the cycle's position demand minus the
        position at that moment (CiA 402-2 §6.5.7), while the drive controls position."""
        k = key(index, subindex)
        if k == K_FE_ACTUAL:
            return self._following_error_now
        live = self._live.get(k)
        if live is not None:
            return live
        return lambda: self._values.get(k)

    def _following_error_now(self) -> int:
        if self._enabled and self._kind == CTRL_POSITION:
            if self.servo is not None:
                # The servo loop's interpolated demand at this sub-step (docs/tuning.md).
                return round(self._raw0 + self._inc * self._sub_k - self.plant.encoder_counts)
            return round(self._dp - (self.plant.encoder_counts + self._pos_offset))
        return round(self._fe)

    def on_step(self, hook: StepHook) -> None:
        """Call ``hook()`` at the end of every :meth:`step`, after the lock is released."""
        self._step_hooks.append(hook)

    @property
    def lock(self) -> threading.RLock:
        """The drive's lock: hold it to read several objects as one consistent sample."""
        return self._lock

    def set_inputs(self, bits: int) -> None:
        """Set the digital inputs (60FDh) the drive reports."""
        with self._lock:
            self._inputs = bits & 0xFFFFFFFF

    def step(self, dt: float) -> None:
        """Advance the simulation by ``dt`` seconds (whole control cycles; remainder kept)."""
        with self._lock:
            self._acc_time += dt
            n = int(self._acc_time / self._T + 1e-9)
            if n > 0:
                self._acc_time -= n * self._T
                cycle = self._cycle
                hooks = self._cycle_hooks
                for _ in range(n):
                    cycle()
                    for hook in hooks:
                        hook()
        self._flush()
        for hook in self._step_hooks:
            hook()

    def raise_fault(self, code: int) -> None:
        """Raise a fault as the drive's monitoring would (603Fh, 1001h, 1003h, EMCY)."""
        with self._lock:
            self._fault(code)
        self._flush()

    def reset_node(self) -> None:
        """Application reset (power cycle): stored values, Switch on disabled, faults gone."""
        with self._lock:
            self._values = dict(self._defaults)
            self._values.update(self._nv)
            self._reset_runtime()
            # Position restarts from the encoder (homing offset is lost).

    def factory_reset(self) -> None:
        """Every stored value forgotten, then a power cycle: the defaults apply (a PROFINET
        reset to factory in mode 8, 004 §20.4.5)."""
        with self._lock:
            self._nv.clear()
        self.reset_node()

    def reset_communication(self) -> None:
        """Communication reset: the 1000h-1FFFh parameters get their stored values."""
        with self._lock:
            for k, spec in self._specs.items():
                if 0x1000 <= spec.index <= 0x1FFF and not spec.process:
                    self._values[k] = self._nv.get(k, self._defaults[k])
            self._refresh()

    # ------------------------------------------------------ reset and the control cycle

    def _reset_runtime(self) -> None:
        self._c = {}
        self._refresh()
        self._state = State.NOT_READY_TO_SWITCH_ON
        self._enabled = False
        self._kind = CTRL_OFF
        self._cw = int(self._values.get(K_CONTROLWORD) or 0)
        self._cw_time = -1e9
        self._pos_offset = 0
        mode = self._values.get(K_MODE)
        self._mode = int(mode) if isinstance(mode, int) and mode in self._modes else 0
        self._stop = None
        self._halted = False
        self._hold = False
        self._dp = float(self.plant.encoder_counts)
        self._dv = 0.0
        self._da = 0.0
        self._integ = 0.0
        self._tq_demand = 0.0
        self._sat = False
        self._clipped = False
        self._fe = 0.0
        self._fe_time = 0.0
        self._fe_flag = False
        self._reached = False
        self._win_time = 0.0
        self._pp_target = self._dp
        self._pp_done = True
        self._pp_buffer = None
        self._csp_target = self._dp
        self._csp_cycle = 0
        self._sp_ack = False
        self._homing_started = False
        self._homing_cancelled = False
        self._homed = False
        self._homing = None
        self._homing_error = False
        self._limit_prev = 0
        self._i2t = 0.0
        self._values[K_ERROR_CODE] = 0
        if K_ERROR_REGISTER in self._specs:
            self._values[K_ERROR_REGISTER] = 0
        self._live = {
            K_STATUSWORD: self._statusword,
            K_MODE_DISPLAY: lambda: self._mode,
            K_POSITION: lambda: self.plant.encoder_counts + self._pos_offset,
            K_VELOCITY: lambda: round(self.plant.velocity_counts),
            K_TORQUE: self._torque_actual,
            K_FE_ACTUAL: lambda: round(self._fe),
            K_INPUTS: lambda: self._inputs | self.switches.inputs(self.plant.encoder_counts),
        }
        if self.recorder is not None:
            self.recorder.reset()  # RAM: a power cycle loses the recording (sim/recorder.py).
            self._live.update(self.recorder.live())
        if self.one_touch is not None:
            self.one_touch.reset()  # A run is lost; the gains follow the PB values.
            self._live.update(self.one_touch.live())
        if self.servo is not None:
            self._load_gains()
            self.servo.reset(self.plant.encoder_counts)
            if self._loop_rate_key is not None:
                self._live[self._loop_rate_key] = lambda: self.loop_rate_hz
        if self.siggen is not None:
            self.siggen.stop()
            base = self._sig_index << 8
            self._live[base | SUB_CONTROL] = lambda: self.siggen.status if self.siggen else 0
            self._live[base | SUB_TORQUE] = lambda: self.servo.command if self.servo else 0.0
            # The test signal itself, recordable: the instrument of the frequency response.
            self._live[base | SUB_VALUE] = lambda: self.siggen.value if self.siggen else 0.0
        if self.servo is not None:
            # What a drive knows of its motor and loops (the tuning reads them): encoder
            # resolution 608Fh, rated torque 6076h (mN m) and the current loop bandwidth.
            pp = self.plant_params
            self._live[key(0x608F, 1)] = lambda: pp.counts_per_rev
            self._live[key(0x608F, 2)] = lambda: 1
            self._live[key(0x6076, 0)] = lambda: round(pp.rated_torque * 1000.0)
            tuning = self.profile.tuning
            cur = tuning.current_loop_address if tuning is not None else None
            if cur is not None:
                hz = 1.0 / (2.0 * math.pi * pp.current_tau) if pp.current_tau > 0.0 else 0.0
                self._live[key(cur.index, cur.subindex)] = lambda: hz

    def _cycle(self) -> None:
        self._cycles += 1
        plant = self.plant
        if self._state is State.NOT_READY_TO_SWITCH_ON:
            self._state = State.SWITCH_ON_DISABLED  # Transition 1: initialisation done.
        p_act = plant.encoder_counts + self._pos_offset
        v_act = plant.velocity_counts
        torque = 0.0
        # The position demand at the start of the cycle (raw counts), for the servo loop's
        # interpolation toward this cycle's demand (docs/tuning.md).
        raw0 = self._dp - self._pos_offset
        self._raw0 = raw0
        #: The demand velocity at the start of the cycle, with raw0 the reference the
        #: cycle-rate controller tracks (:meth:`_control`).
        self._dv0 = self._dv
        if self._enabled:
            # 1. Demand (set-point generators, stop ramps, halt).
            stop = self._stop
            halt_now = self._cw & 0x100 and self._state is State.OPERATION_ENABLED and stop is None
            if stop is not None:
                # Done when the demand is 0 and the axis has come to rest (or 0.5 s later).
                if self._ramp_down(stop.decel):
                    stop.settle += self._T
                    if abs(v_act) <= self._c[K_VEL_THRESHOLD] or stop.settle > 0.5:
                        self._stop = None
                        stop.then()
            elif halt_now:
                if not self._halted:
                    self._halted = True
                    if self._kind == CTRL_TORQUE:
                        self._dv = v_act
                        self._dp = float(p_act)
                    self._kind = CTRL_POSITION if self._mode in POSITION_MODES else CTRL_VELOCITY
                if self._ramp_down(self._decel_for(self._c[K_HALT_OPTION])):
                    self._reached = abs(v_act) <= self._c[K_VEL_THRESHOLD]
            elif self._hold:
                self._dv = 0.0
                self._da = 0.0
            else:
                if self._halted:
                    self._halted = False
                    self._begin_motion()
                m = self._mode
                if m == 1:
                    if not self._pp_done:
                        self._pp_generate()
                    else:
                        self._dv = 0.0
                        self._da = 0.0
                    if self._sp_ack and not self._cw & 0x10 and self._pp_buffer is None:
                        self._sp_ack = False
                elif m == 3:
                    self._pv_generate()
                elif m == 6 and self._homing is not None:
                    self._homing_step()
                elif m == 8:
                    self._csp_generate()
                elif m == 9:
                    self._csv_generate()
                elif m not in (4, 10):
                    self._dv = 0.0
                    self._da = 0.0
            if not self._enabled:
                # A stop just finished by disabling the drive.
                self._dp = float(p_act)
            else:
                torque = self._control(p_act, v_act)
        else:
            self._dp = float(p_act)
            self._dv = 0.0
            self._fe = 0.0
        hooks = self._substep_hooks
        if self.servo is not None:
            self._servo_substeps(raw0, hooks)
        elif hooks:
            self._substeps_hooked(torque, hooks)
        else:
            plant.step_n(torque, self._sub_dt, self._substeps)
        # I²t of the motor current (torque ratio to rated), a first-order thermal model.
        r = plant.torque / self._rated
        self._i2t += (r * r - self._i2t) * (self._T / self._i2t_tau)
        if self._enabled:
            self._monitor(p_act, v_act)


def _rescaled(sim: SimSettings, counts_per_rev: int) -> SimSettings:
    """``sim`` for another encoder resolution: the counts-valued settings (speeds, switch
    positions, index offset) keep their value in revolutions."""
    f = counts_per_rev / sim.counts_per_rev

    def scale(v: int | None) -> int | None:
        return None if v is None else round(v * f)

    return sim.model_copy(
        update={
            "counts_per_rev": counts_per_rev,
            "max_velocity": sim.max_velocity * f,
            "limit_negative": scale(sim.limit_negative),
            "limit_positive": scale(sim.limit_positive),
            "home_switch_low": scale(sim.home_switch_low),
            "home_switch_high": scale(sim.home_switch_high),
            "index_offset": round(sim.index_offset * f),
            "rated_speed": None if sim.rated_speed is None else sim.rated_speed * f,
        }
    )


def _rescaled_defaults(
    specs: dict[int, ObjectSpec], defaults: dict[int, Value | None], f: float
) -> dict[int, Value]:
    """The defaults of the objects counted in increments (``raw_unit`` inc, inc/s, inc/s²)
    times ``f``, the ratio of a plant file's encoder to the profile's: the profile's 607Fh of
    1,000,000 inc/s is 7.6 rev/s at its 2^17 counts and would be 0.95 rev/s at 2^20. Integers
    are rounded and kept inside their type (607Dh's +-2^31 stays the "no limit" it was)."""
    out: dict[int, Value] = {}
    for k, spec in specs.items():
        d = defaults.get(k)
        if spec.raw_unit not in INCREMENT_UNITS or isinstance(d, (bytes, str)) or d is None:
            continue
        v = d * f
        rng = spec.data_type.range
        if rng is not None:
            out[k] = min(max(round(v), rng[0]), rng[1])
        elif spec.data_type.is_real:
            out[k] = float(v)
    return out
