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
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from servodesk.domain.cia402 import STATE_BITS, State, device_transition
from servodesk.domain.datatypes import Value, codec, coerce_int
from servodesk.domain.encoder_units import INCREMENT_UNITS
from servodesk.domain.homing import resolve_method
from servodesk.domain.profile import DeviceProfile, ErrorEntry, ObjectSpec, SimSettings
from servodesk.domain.sdo_abort import ABORT_CODES
from servodesk.model.plant import Plant, PlantParams
from servodesk.model.profile_position import CONTROL_PERIOD_S, pp_step
from servodesk.model.servo import POSITION, TORQUE, VELOCITY, ServoGains, ServoLoop
from servodesk.sim.faults import FaultModel
from servodesk.sim.homing import HomingProcedure, SwitchLayout
from servodesk.sim.onetouch import OneTouchTuning
from servodesk.sim.pdo import pdo_kind
from servodesk.sim.recorder import Recorder
from servodesk.sim.siggen import (
    SUB_AMPLITUDE,
    SUB_CONTROL,
    SUB_DURATION,
    SUB_F_END,
    SUB_F_START,
    SUB_KIND,
    SUB_TORQUE,
    SUB_VALUE,
    SignalConfig,
    SignalGenerator,
)

# Object keys: index << 8 | subindex (ints are the fastest dict keys in the control cycle).
K_ERROR_REGISTER = 0x100100
K_ERROR_HISTORY = 0x1003
K_HEARTBEAT = 0x101700
K_IDENTITY_SERIAL = 0x101804
K_ERROR_CODE = 0x603F00
K_CONTROLWORD = 0x604000
K_STATUSWORD = 0x604100
K_QS_OPTION = 0x605A00
K_SHUTDOWN_OPTION = 0x605B00
K_DISABLE_OP_OPTION = 0x605C00
K_HALT_OPTION = 0x605D00
K_FAULT_OPTION = 0x605E00
K_MODE = 0x606000
K_MODE_DISPLAY = 0x606100
K_POSITION = 0x606400
K_FE_WINDOW = 0x606500
K_FE_TIMEOUT = 0x606600
K_POS_WINDOW = 0x606700
K_POS_WINDOW_TIME = 0x606800
K_VELOCITY = 0x606C00
K_VEL_WINDOW = 0x606D00
K_VEL_WINDOW_TIME = 0x606E00
K_VEL_THRESHOLD = 0x606F00
K_TARGET_TORQUE = 0x607100
K_MAX_TORQUE = 0x607200
K_TORQUE = 0x607700
K_TARGET_POSITION = 0x607A00
K_HOME_OFFSET = 0x607C00
K_SW_LIMIT_MIN = 0x607D01
K_SW_LIMIT_MAX = 0x607D02
#: Profile velocity toward a software limit: how long the axis runs on behind a braking demand
#: (_limit_wall).
LIMIT_WALL_LAG_S = 0.002
#: ... and where it stops: this far inside the limit [position units].
LIMIT_WALL_MARGIN = 50
K_MAX_PROFILE_VEL = 0x607F00
K_PROFILE_VEL = 0x608100
K_PROFILE_ACC = 0x608300
K_PROFILE_DEC = 0x608400
K_QS_DEC = 0x608500
K_TORQUE_SLOPE = 0x608700
K_HOMING_METHOD = 0x609800
K_HOMING_SPEED_SWITCH = 0x609901
K_HOMING_SPEED_ZERO = 0x609902
K_HOMING_ACC = 0x609A00
K_FE_ACTUAL = 0x60F400
K_INPUTS = 0x60FD00
K_TARGET_VELOCITY = 0x60FF00

SIGNATURE_SAVE = 0x65766173  # "save" (CiA 301 §7.5.2.13)
SIGNATURE_LOAD = 0x64616F6C  # "load" (CiA 301 §7.5.2.14)

# Values used when a profile does not have the object (raw units of the generic profile).
_FALLBACK: dict[int, int] = {
    K_QS_OPTION: 2,
    K_SHUTDOWN_OPTION: 0,
    K_DISABLE_OP_OPTION: 1,
    K_HALT_OPTION: 1,
    K_FAULT_OPTION: 2,
    K_FE_WINDOW: 0xFFFFFFFF,
    K_FE_TIMEOUT: 0,
    K_POS_WINDOW: 100,
    K_POS_WINDOW_TIME: 0,
    K_VEL_WINDOW: 1000,
    K_VEL_WINDOW_TIME: 0,
    K_VEL_THRESHOLD: 1000,
    K_MAX_TORQUE: 3000,
    K_MAX_PROFILE_VEL: 0,  # 0: no extra limit beyond the simulation's max_velocity.
    K_PROFILE_VEL: 200_000,
    K_PROFILE_ACC: 1_000_000,
    K_PROFILE_DEC: 1_000_000,
    K_QS_DEC: 5_000_000,
    K_TORQUE_SLOPE: 0,  # 0: torque set-point applies at once.
    K_HOME_OFFSET: 0,
    K_HOMING_METHOD: 0,
    K_HOMING_SPEED_SWITCH: 100_000,
    K_HOMING_SPEED_ZERO: 20_000,
    K_HOMING_ACC: 1_000_000,
    K_SW_LIMIT_MIN: 0,
    K_SW_LIMIT_MAX: 0,
    K_TARGET_POSITION: 0,
    K_TARGET_VELOCITY: 0,
    K_TARGET_TORQUE: 0,
}

#: Acceleration standing in for "no ramp" (counts/s²): reaches any speed within a cycle.
_NO_RAMP = 10**12

_ENABLED_STATES = (State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE, State.FAULT_REACTION_ACTIVE)
_VOLTAGE_STATES = frozenset(
    (
        State.READY_TO_SWITCH_ON,
        State.SWITCHED_ON,
        State.OPERATION_ENABLED,
        State.QUICK_STOP_ACTIVE,
        State.FAULT_REACTION_ACTIVE,
    )
)
_POSITION_MODES = frozenset((1, 6, 7, 8))
_NMT_ALIASES = {
    "preop": "preop",
    "pre_operational": "preop",
    "preoperational": "preop",
    "op": "op",
    "operational": "op",
    "stopped": "stopped",
    "init": "init",
    "initialising": "init",
    "safeop": "safeop",
}

EmcyListener = Callable[[int, int, bytes], None]
WriteListener = Callable[[int, int, Value], None]
StepHook = Callable[[], None]

# Control kinds.
_OFF, _POSITION, _VELOCITY, _TORQUE = 0, 1, 2, 3


class SimAbort(Exception):
    """The simulated device refuses an access; ``code`` is the CiA 301 SDO abort code."""

    def __init__(self, code: int, detail: str = "") -> None:
        text = ABORT_CODES.get(code, "Unknown abort code")
        super().__init__(f"0x{code:08X} {text}" + (f": {detail}" if detail else ""))
        self.code = code


@dataclass(slots=True)
class ControllerGains:
    """Cascade gains, in drive units (counts, counts/s, N m).

    ``kp_pos`` [1/s]: velocity command per position error; ``kp_vel`` [N m per count/s];
    ``ki_vel`` [1/s]: integral rate of the velocity PI (integral gain = kp_vel * ki_vel);
    ``acc_ff`` [N m per count/s²]: acceleration (inertia) feed-forward.
    """

    kp_pos: float
    kp_vel: float
    ki_vel: float
    acc_ff: float

    @classmethod
    def from_plant(cls, p: PlantParams, bandwidth_hz: float = 60.0) -> ControllerGains:
        """Gains placing the velocity loop at ``bandwidth_hz`` for the rigid inertia.

        The usual cascade rule of thumb: integral corner at a quarter of the velocity
        bandwidth, position bandwidth a fifth of it; leaves some 45° of phase margin with
        the 1 ms cycle and the current-loop lag.
        """
        w = 2.0 * math.pi * bandwidth_hz
        rad_per_count = 2.0 * math.pi / p.counts_per_rev
        return cls(
            kp_pos=w / 5.0,
            kp_vel=p.inertia * w * rad_per_count,
            ki_vel=w / 4.0,
            acc_ff=p.inertia * rad_per_count,
        )


@dataclass(slots=True)
class _Stop:
    """A deceleration in progress and what happens when the axis has stopped."""

    decel: float
    then: Callable[[], None]
    settle: float = 0.0


def _key(index: int, subindex: int) -> int:
    return index << 8 | subindex


def _norm(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name.strip().lower()).strip("_")


class SimulatedDrive:
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
        self._emcy_listeners: list[EmcyListener] = []
        self._write_listeners: list[WriteListener] = []
        self._cycle_hooks: list[StepHook] = []
        self._step_hooks: list[StepHook] = []
        # A tuple, replaced on change: a hook may remove itself while the cycle runs the hooks.
        self._substep_hooks: tuple[StepHook, ...] = ()
        self._events: list[tuple[int, int, bytes]] = []

        # Object store.
        self._specs: dict[int, ObjectSpec] = {}
        self._subs: dict[int, set[int]] = {}
        self._defaults: dict[int, Value | None] = {}
        for spec in profile.variables.values():
            k = _key(spec.index, spec.subindex)
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
        self._values: dict[int, Value | None] = dict(self._defaults)
        #: The non-volatile copy: persist objects saved by "store parameters".
        self._nv: dict[int, Value | None] = {}
        self._history_len = len(self._subs.get(K_ERROR_HISTORY, {0})) - 1

        # Profile data read once.
        self._modes = frozenset(profile.modes)
        self._homing_methods = frozenset(profile.homing_methods)
        self._store_cmd = self._command_quirk("store_parameters", 0x1010, SIGNATURE_SAVE)
        self._restore_cmd = self._command_quirk("restore_defaults", 0x1011, SIGNATURE_LOAD)
        q = profile.quirk("controlword_min_interval_ms")
        self._cw_min_interval = float(q) / 1000.0 if q else 0.0
        q = profile.quirk("quick_stop_statusword")
        self._qs_statusword: int | None = coerce_int(q) if q is not None else None
        reset_id = profile.quirk("fault_reset", "bit7_edge")
        self._bit7_resets = not profile.quirk("no_fault_reset_bit7", False) and reset_id in (
            None,
            "bit7_edge",
        )
        self._pdo_mapping_state = _NMT_ALIASES.get(_norm(profile.pdo.mapping_state), "any")
        # Quirk pdo_state_abort (HIWIN 000 §2.8.1 note 1: 0601 0002h): the abort answering a
        # write of a mapping or assignment object outside the state that allows it.
        q = profile.quirk("pdo_state_abort")
        self._pdo_state_abort = coerce_int(q) if q is not None else 0x08000022
        # Quirk pdo_unknown_object_abort (smartris 001 §2-8 note 1, HIWIN 000 §2.8.1 note 2:
        # 0602 0000h): the abort for a mapping entry naming no object (CiA 301: 0604 0041h).
        q = profile.quirk("pdo_unknown_object_abort")
        self._pdo_unknown_abort = coerce_int(q) if q is not None else 0x06040041
        # PROFIdrive telegrams pad with Reserved entries: index 0, 0/8/16 bits (004 §20.1.2).
        self._pdo_reserved = pdo_kind(profile) == "telegram"
        # HIWIN 000 §3.1 (1600h): an object may be mapped only once (quirk or pdo rule).
        self._pdo_duplicates = profile.pdo.allow_duplicates and not profile.quirk(
            "pdo_no_duplicate_entries", False
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
        self.recorder: Recorder | None = None
        if profile.recorder is not None:
            self.recorder = Recorder(self, profile.recorder)
        #: Built-in one-touch tuning (quirk one_touch_tuning, 004 §20.8.7; sim/onetouch.py).
        self.one_touch: OneTouchTuning | None = None
        if profile.quirk("one_touch_tuning") is not None:
            self.one_touch = OneTouchTuning(self, profile)
        self._reset_runtime()

    # ------------------------------------------------------------------ public surface

    @property
    def time(self) -> float:
        """Simulated time in seconds (whole control cycles)."""
        return self._cycles * self._T

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

    def _error_entry(self, code: int) -> ErrorEntry | None:
        p = self.profile
        return p.error("error_code", code) or p.error("emcy", code) or p.error("alarm", code)

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
        k = _key(index, subindex)
        if k == K_FE_ACTUAL:
            return self._following_error_now
        live = self._live.get(k)
        if live is not None:
            return live
        return lambda: self._values.get(k)

    def _following_error_now(self) -> int:
        if self._enabled and self._kind == _POSITION:
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

    def sample(self, keys: Sequence[int]) -> list[Value | None]:
        """Current values of objects by key (``index << 8 | subindex``), for process data.

        No access checks: the caller maps only existing, readable objects.
        """
        with self._lock:
            live = self._live
            values = self._values
            return [f() if (f := live.get(k)) is not None else values.get(k) for k in keys]

    def write_process(self, items: Sequence[tuple[int, Value]]) -> None:
        """Write received process data (``(key, value)`` pairs, in mapping order).

        The normal write path runs (the objects' side effects, e.g. controlword transitions,
        and the state rules that the drive applies to any write); a value the drive refuses is
        dropped without an answer, as there is none for a PDO (CiA 301 §7.2.2). The
        controlword is acted upon last, with the other values of the same PDO in place (a new
        set-point and its target position arrive together).
        """
        done: list[tuple[int, int, Value]] = []
        refresh = False
        with self._lock:
            values = self._values
            cw: list[Value] = []
            for k, value in items:
                if k == K_CONTROLWORD:
                    cw.append(value)
                    continue
                # A PDO repeats its data every cycle: an unchanged value has nothing to do
                # (the controlword always goes through, as its handling counts commands).
                if values.get(k) == value:
                    continue
                spec = self._specs.get(k)
                if spec is None or not spec.access.writable:
                    continue
                try:
                    self._write(spec, value)
                except SimAbort:
                    continue
                done.append((spec.index, spec.subindex, value))
                refresh = refresh or k in _FALLBACK
            if refresh:
                self._refresh()
            spec = self._specs.get(K_CONTROLWORD)
            for value in cw:
                if spec is not None:
                    try:
                        self._write(spec, value)
                    except SimAbort:
                        continue
                    done.append((spec.index, spec.subindex, value))
        for index, subindex, value in done:
            for cb in self._write_listeners:
                cb(index, subindex, value)
        self._flush()

    def has_object(self, index: int, subindex: int = 0) -> bool:
        return _key(index, subindex) in self._specs

    def spec(self, index: int, subindex: int = 0) -> ObjectSpec:
        """The specification of an object, or :class:`SimAbort` as the bus would answer."""
        return self._lookup(index, subindex)

    def set_status(self, index: int, subindex: int, value: Value) -> None:
        """Set an object the device itself keeps, read-only ones too (the sync mode an
        EtherCAT slave takes from its ESC's DC registers, 1C32h / 1C33h); nothing is checked
        but that the object exists."""
        with self._lock:
            spec = self._lookup(index, subindex)
            self._values[_key(spec.index, spec.subindex)] = value
            self._refresh()

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

    def read(self, index: int, subindex: int = 0) -> Value:
        """The typed value of an object, as an SDO upload would return it."""
        with self._lock:
            spec = self._lookup(index, subindex)
            return self._read(spec)

    def read_bytes(self, index: int, subindex: int = 0) -> bytes:
        with self._lock:
            spec = self._lookup(index, subindex)
            return codec(spec.data_type).encode(self._read(spec))

    def check_download(self, index: int, subindex: int) -> None:
        """Refuse a download early (before a segmented transfer) when it cannot succeed."""
        with self._lock:
            spec = self._lookup(index, subindex)
            if not spec.access.writable:
                raise SimAbort(0x06010002)

    def write_bytes(self, index: int, subindex: int, data: bytes) -> None:
        """An SDO download: checks, in order, existence, access, length, state, value."""
        with self._lock:
            spec = self._lookup(index, subindex)
            if not spec.access.writable:
                raise SimAbort(0x06010002)
            n = spec.data_type.bits // 8
            if n:
                if len(data) > n:
                    raise SimAbort(0x06070012)
                if len(data) < n:
                    raise SimAbort(0x06070013)
            value = codec(spec.data_type).decode(bytes(data))
            if isinstance(value, bool):
                value = int(value)
            self._write(spec, value)
            self._refresh()
        self._after_write(index, subindex, value)

    def write(self, index: int, subindex: int, value: Value) -> None:
        """A typed write with the same checks as :meth:`write_bytes`."""
        with self._lock:
            spec = self._lookup(index, subindex)
            if not spec.access.writable:
                raise SimAbort(0x06010002)
            dt = spec.data_type
            if dt.is_integer:
                value = coerce_int(value, dt)
            elif dt.is_real:
                value = float(value)
            self._write(spec, value)
            self._refresh()
        self._after_write(index, subindex, value)

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

    # ------------------------------------------------------------------ object access

    def _lookup(self, index: int, subindex: int) -> ObjectSpec:
        spec = self._specs.get(_key(index, subindex))
        if spec is None:
            if index in self._subs:
                raise SimAbort(0x06090011)
            raise SimAbort(0x06020000)
        return spec

    def _read(self, spec: ObjectSpec) -> Value:
        if not spec.access.readable:
            raise SimAbort(0x06010001)
        k = _key(spec.index, spec.subindex)
        live = self._live.get(k)
        v = live() if live is not None else self._values.get(k)
        if v is None:
            raise SimAbort(0x08000024)
        return v

    def _write(self, spec: ObjectSpec, value: Value) -> None:
        k = _key(spec.index, spec.subindex)
        self._check_state(spec)
        if spec.index == K_ERROR_HISTORY and spec.subindex == 0:
            # CiA 301 §7.5.2.3: only 0 may be written (clears the history).
            if value != 0:
                raise SimAbort(0x06090030, "write 0 to clear the error history")
            for s in self._subs[K_ERROR_HISTORY]:
                self._values[_key(K_ERROR_HISTORY, s)] = self._defaults[_key(K_ERROR_HISTORY, s)]
            self._values[k] = 0
            return
        cmd = self._store_restore(spec, value)
        if cmd:
            return
        if isinstance(value, int) and spec.data_type.is_integer:
            lo, hi = spec.limits()
            if lo is not None and value < lo:
                raise SimAbort(0x06090032, f"minimum is {lo}")
            if hi is not None and value > hi:
                raise SimAbort(0x06090031, f"maximum is {hi}")
        elif isinstance(value, float) and spec.data_type.is_real:
            if spec.min is not None and value < spec.min:
                raise SimAbort(0x06090032, f"minimum is {spec.min}")
            if spec.max is not None and value > spec.max:
                raise SimAbort(0x06090031, f"maximum is {spec.max}")
        if k == K_CONTROLWORD:
            assert isinstance(value, int)
            self._controlword(value)
            return
        if k == K_MODE:
            if value not in self._modes:
                raise SimAbort(0x06090030, f"supported modes: {sorted(self._modes)}")
            self._values[k] = value
            if self._mode != value:
                self._enter_mode(int(value))
            return
        if k == K_HOMING_METHOD:
            if value not in self._homing_methods:
                raise SimAbort(0x06090030, f"supported methods: {sorted(self._homing_methods)}")
            if resolve_method(int(value), self._homing_equiv) is None:
                # A vendor method the profile does not map to a documented behaviour.
                raise SimAbort(0x06090030, f"homing method {value} is not simulated")
        if self.faults.is_clear_command(spec.index, spec.subindex):
            if not self.faults.clear(self._values, self._defaults, value):
                raise SimAbort(0x06090030, "not the documented clear value")
            return
        if _is_mapping(spec.index):
            self._check_mapping(spec, value)
        elif spec.index in (0x1C12, 0x1C13) and spec.subindex == 0:
            self._check_assignment(spec.index, value)
        elif self.recorder is not None and self.recorder.owns(spec.index):
            refusal = self.recorder.write(spec.index, spec.subindex, value)
            if refusal is not None:
                raise SimAbort(*refusal)
        elif self.one_touch is not None and self.one_touch.owns(spec.index):
            refusal = self.one_touch.write(spec.index, spec.subindex, value)
            if refusal is not None:
                raise SimAbort(*refusal)
        elif spec.index == self._sig_index:
            self._signal_write(spec.subindex, value)
        self._values[k] = value
        if k in self._gain_keys:
            self._load_gains()  # docs/tuning.md: a gain acts from the next loop tick on.

    def _after_write(self, index: int, subindex: int, value: Value) -> None:
        for cb in self._write_listeners:
            cb(index, subindex, value)
        self._flush()

    def _check_state(self, spec: ObjectSpec) -> None:
        allowed = spec.writable_in
        if not allowed and _is_mapping(spec.index):
            if self._pdo_mapping_state == "any" or self.nmt_state == self._pdo_mapping_state:
                return
            comm = self._values.get(_key(spec.index - 0x200, 1))
            if isinstance(comm, int) and comm & 0x80000000:
                return
            raise SimAbort(
                self._pdo_state_abort,
                "PDO mapping changes need PRE-OPERATIONAL or the PDO disabled",
            )
        if not allowed:
            return
        here = {self.nmt_state, self._state.name.lower()}
        if self._state not in _ENABLED_STATES:
            here.update(("disabled", "servo_off"))
        for name in allowed:
            n = _norm(name)
            if _NMT_ALIASES.get(n, n) in here:
                return
        code = self._pdo_state_abort if _is_pdo_object(spec.index) else 0x08000022
        raise SimAbort(code, f"writable only in {', '.join(allowed)}")

    def _check_mapping(self, spec: ObjectSpec, value: Value) -> None:
        """CiA 301 §7.5.2.36: mapped objects must exist, be mappable and fit the PDO."""
        assert isinstance(value, int)
        rx = spec.index < 0x1A00
        if spec.subindex == 0:
            rules = self.profile.pdo
            if value > rules.max_entries:
                raise SimAbort(0x06040042, f"at most {rules.max_entries} entries")
            bits = 0
            seen: set[int] = set()
            for i in range(1, value + 1):
                entry = self._values.get(_key(spec.index, i))
                if not isinstance(entry, int):
                    raise SimAbort(0x06040041)
                self._check_mapped_object(entry, rx)
                bits += entry & 0xFF
                obj = entry >> 8
                if not self._pdo_duplicates and entry >> 16 and obj in seen:
                    # HIWIN 000 §3.1 (1600h): the same object may not be mapped twice.
                    raise SimAbort(0x06040043, f"0x{entry:08X} is mapped twice")
                seen.add(obj)
            if bits > rules.max_bits:
                raise SimAbort(0x06040042)
        elif value:
            self._check_mapped_object(value, rx)

    def _check_assignment(self, index: int, value: Value) -> None:
        """HIWIN 000 §3.1.2 note 1: setting 1C12h/1C13h sub 0 to n checks the assigned
        mapping objects (0604 0042h when they hold too many objects or bytes)."""
        assert isinstance(value, int)
        rules = self.profile.pdo
        limit = rules.max_bytes * 8 if rules.max_bytes is not None else rules.max_bits
        total = 0
        for i in range(1, value + 1):
            mapping = self._values.get(_key(index, i))
            if not isinstance(mapping, int) or not _is_mapping(mapping):
                raise SimAbort(0x06040043, f"sub {i} names no mapping object")
            count = self._values.get(_key(mapping, 0))
            if not isinstance(count, int) or count > rules.max_entries:
                raise SimAbort(0x06040042, f"0x{mapping:04X}: over {rules.max_entries} entries")
            for s in range(1, count + 1):
                entry = self._values.get(_key(mapping, s))
                total += entry & 0xFF if isinstance(entry, int) else 0
        if total > limit:
            raise SimAbort(0x06040042, f"{total // 8} bytes assigned, at most {limit // 8}")

    def _check_mapped_object(self, entry: int, rx: bool) -> None:
        if self._pdo_reserved and not entry >> 16 and entry & 0xFF in (0, 8, 16):
            return  # A Reserved entry (004 §20.1.2).
        target = self._specs.get(entry >> 8 & 0xFFFFFF)
        if target is None:
            raise SimAbort(self._pdo_unknown_abort, f"0x{entry:08X} names no object")
        ok = target.pdo_mapping.rx if rx else target.pdo_mapping.tx
        if not ok or target.bits != entry & 0xFF:
            raise SimAbort(0x06040041, f"0x{entry:08X} cannot be mapped")

    def _command_quirk(
        self, quirk_id: str, index: int, signature: int
    ) -> tuple[int, int | None, int]:
        q = self.profile.quirk(quirk_id)
        if isinstance(q, dict):
            return (
                coerce_int(q["index"]),
                coerce_int(q.get("subindex", 1)),
                coerce_int(q.get("value", signature)),
            )
        return (index, None, signature)

    def _store_restore(self, spec: ObjectSpec, value: Value) -> bool:
        """Store (1010h) / restore (1011h) commands; True when the write was one."""
        for cmd, store in ((self._store_cmd, True), (self._restore_cmd, False)):
            index, sub, signature = cmd
            if spec.index != index:
                continue
            if (sub is None and spec.subindex == 0) or (sub is not None and spec.subindex != sub):
                continue
            if value != signature:
                raise SimAbort(0x08000020, f"write the signature 0x{signature:08X}")
            lo, hi = _scope(spec.subindex if sub is None else 1)
            for k, s in self._specs.items():
                if s.persist and lo <= s.index <= hi:
                    if store:
                        self._nv[k] = self._values.get(k)
                    else:
                        self._nv.pop(k, None)  # Defaults apply at the next reset.
            return True
        return False

    # ------------------------------------------------------------------ state machine

    def _reset_runtime(self) -> None:
        self._c: dict[int, int] = {}
        self._refresh()
        self._state = State.NOT_READY_TO_SWITCH_ON
        self._enabled = False
        self._kind = _OFF
        self._cw = int(self._values.get(K_CONTROLWORD) or 0)
        self._cw_time = -1e9
        self._pos_offset = 0
        mode = self._values.get(K_MODE)
        self._mode = int(mode) if isinstance(mode, int) and mode in self._modes else 0
        self._stop: _Stop | None = None
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
        self._pp_buffer: float | None = None
        self._csp_target = self._dp
        self._csp_cycle = 0
        self._sp_ack = False
        self._homing_started = False
        self._homing_cancelled = False
        self._homed = False
        self._homing: HomingProcedure | None = None
        self._homing_error = False
        self._limit_prev = 0
        self._i2t = 0.0
        self._values[K_ERROR_CODE] = 0
        if K_ERROR_REGISTER in self._specs:
            self._values[K_ERROR_REGISTER] = 0
        self._live: dict[int, Callable[[], Value | None]] = {
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
            self._live[_key(0x608F, 1)] = lambda: pp.counts_per_rev
            self._live[_key(0x608F, 2)] = lambda: 1
            self._live[_key(0x6076, 0)] = lambda: round(pp.rated_torque * 1000.0)
            tuning = self.profile.tuning
            cur = tuning.current_loop_address if tuning is not None else None
            if cur is not None:
                hz = 1.0 / (2.0 * math.pi * pp.current_tau) if pp.current_tau > 0.0 else 0.0
                self._live[_key(cur.index, cur.subindex)] = lambda: hz

    def _refresh(self) -> None:
        """Copy the parameters the control cycle reads into ``_c`` (after every write)."""
        values = self._values
        c = self._c
        for k, fallback in _FALLBACK.items():
            v = values.get(k)
            c[k] = v if isinstance(v, int) else fallback
        for k in (K_PROFILE_ACC, K_PROFILE_DEC, K_QS_DEC):
            # 0 is "no ramp" (not valid in CiA 402, but so in some families).
            c[k] = max(1, round(self._acceleration(k, c[k]))) if c[k] > 0 else _NO_RAMP

    def _acceleration(self, k: int, raw: float) -> float:
        """A ramp object (6083h, 6084h, 6085h, 609Ah; ``raw`` > 0) in counts/s²: a PMC842SR
        rate register (CTMM04x 003 §5-3-1: Fclk / 8 / register), a time constant from 0 to
        the rated speed (LECSN-T 004 §20.9.3.10(7), unit ms), or counts/s² as it is."""
        if (k >> 8) in self._rate_registers:
            return self._rate_fclk / 8.0 / raw
        spec = self._specs.get(k)
        if spec is not None and spec.unit == "ms":
            sim = self.sim_settings
            return (sim.rated_speed or sim.max_velocity) / (raw * 0.001)
        return raw

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
            return  # Too soon after the last one: the drive drops it (see module docstring).
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

    # ------------------------------------------------------------------ modes and motion

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
        self._kind = _OFF
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

    def _begin_motion(self) -> None:
        """Set the control kind for the active mode (after enable, mode change, resume)."""
        m = self._mode
        if m in (3, 9):
            self._kind = _VELOCITY
        elif m in (4, 10):
            self._kind = _TORQUE
            self._tq_demand = self.plant.torque
        else:
            if self._kind != _POSITION:
                self._dp = float(self.plant.encoder_counts + self._pos_offset)
            self._kind = _POSITION
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
            if self._kind == _TORQUE:
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
        if self._kind != _POSITION:
            self._dp = float(self.plant.encoder_counts + self._pos_offset)
            self._dv = 0.0
            self._kind = _POSITION
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
            if self._ramp_down(self._homing_acceleration() or _NO_RAMP):
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
        if self._kind == _TORQUE:
            self._dv = self.plant.velocity_counts
            self._dp = float(self.plant.encoder_counts + self._pos_offset)
        self._kind = _POSITION if self._mode in _POSITION_MODES or self._mode == 0 else _VELOCITY
        self._stop = _Stop(max(decel, 1.0), then)
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
        before this (services/motion.py); this is the backstop when the monitor's samples
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

    # ------------------------------------------------------------------ the control cycle

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
                    if self._kind == _TORQUE:
                        self._dv = v_act
                        self._dp = float(p_act)
                    self._kind = _POSITION if self._mode in _POSITION_MODES else _VELOCITY
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
        if kind == _TORQUE:
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
            if kind == _POSITION:
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

    # ------------------------------------------------------------------ the servo loop

    def _init_servo(self, profile: DeviceProfile) -> None:
        """The servo loop of a ``tuning.kind: gains`` profile (docs/tuning.md, model/servo.py):
        gains from the mapped objects, the loop rate object, the test signal generator."""
        #: The servo loop (None: the profile keeps the cycle-rate controller).
        self.servo: ServoLoop | None = None
        #: The test signal generator (docs/tuning.md), where the profile has its objects.
        self.siggen: SignalGenerator | None = None
        self._gain_keys: dict[int, tuple[str, float]] = {}
        self._loop_rate_key: int | None = None
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
            k = _key(a.index, a.subindex)
            if k not in self._specs:
                raise ValueError(f"tuning.gains.{name}: {g.object} is not an object")
            self._gain_keys[k] = (name, g.scale)
        addr = tuning.loop_rate_address
        if addr is not None:
            self._loop_rate_key = _key(addr.index, addr.subindex)
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
        if kind == _TORQUE:
            self._fe = 0.0
            self._torque_demand_step()
            # Speed limit (607Fh or the simulation's maximum) so a free motor cannot run away.
            vmax = float(self._c[K_MAX_PROFILE_VEL]) or self._vmax_sim
            self._srv_vlim = vmax / self._counts_per_rad
            self._dp = float(p_act)
            self._dv = v_act
        elif kind == _POSITION:
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
        if kind == _POSITION:
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
        elif kind == _VELOCITY:
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

    def _monitor(self, p_act: int, v_act: float) -> None:
        T = self._T
        # Following error (CiA 402-2 §6.5.7/§6.5.8), position control only.
        if self._kind == _POSITION:
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


def _is_mapping(index: int) -> bool:
    return 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF


def _is_pdo_object(index: int) -> bool:
    """A mapping object or a sync manager assignment (1C12h/1C13h)."""
    return _is_mapping(index) or index in (0x1C12, 0x1C13)


def _scope(sub: int) -> tuple[int, int]:
    """Index range a 1010h/1011h sub-index covers (CiA 301 §7.5.2.13)."""
    if sub == 2:
        return (0x1000, 0x1FFF)  # Communication parameters.
    if sub == 3:
        return (0x6000, 0x9FFF)  # Application (device profile) parameters.
    if sub >= 4:
        return (0x2000, 0x5FFF)  # Manufacturer-specific parameters.
    return (0x0000, 0xFFFF)  # All parameters.


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
