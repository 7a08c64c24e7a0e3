"""What every part of the simulated drive shares: object keys, fallbacks, the abort, the state.

sim/engine.py composes :class:`~servodesk.sim.engine.SimulatedDrive` from the parts in the
``engine_*`` modules; this one holds what they all read: the object keys of the control cycle,
the values used when a profile lacks an object, :class:`SimAbort`, the cascade gains, and
:class:`DriveBase`, which declares the drive's state once (types only: the constructor and
``_reset_runtime`` set it) and turns the parameters into the control cycle's copy
(:meth:`DriveBase._refresh`).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from servodesk.domain.cia402 import State
from servodesk.domain.datatypes import Value
from servodesk.domain.profile import DeviceProfile, ObjectSpec, SimSettings
from servodesk.domain.sdo_abort import ABORT_CODES
from servodesk.model.plant import Plant, PlantParams

if TYPE_CHECKING:
    from servodesk.model.servo import ServoLoop
    from servodesk.sim.engine_pdo_rules import MappingRules
    from servodesk.sim.faults import FaultModel
    from servodesk.sim.homing import HomingProcedure, SwitchLayout
    from servodesk.sim.onetouch import OneTouchTuning
    from servodesk.sim.recorder import Recorder
    from servodesk.sim.siggen import SignalGenerator

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
FALLBACK: dict[int, int] = {
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
NO_RAMP = 10**12

ENABLED_STATES = (State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE, State.FAULT_REACTION_ACTIVE)
POSITION_MODES = frozenset((1, 6, 7, 8))
NMT_ALIASES = {
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

# Control kinds (what the cycle controls: the servo loop has modes of its own, model/servo.py).
CTRL_OFF, CTRL_POSITION, CTRL_VELOCITY, CTRL_TORQUE = 0, 1, 2, 3


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
class Stop:
    """A deceleration in progress and what happens when the axis has stopped."""

    decel: float
    then: Callable[[], None]
    settle: float = 0.0


def key(index: int, subindex: int) -> int:
    return index << 8 | subindex


def norm(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name.strip().lower()).strip("_")


class DriveBase:
    """The state of one simulated axis, declared once for the parts that share it.

    The parts (engine_servo, engine_setpoints, engine_states, engine_objects) read and write
    the same demand and status variables in every 1 ms control cycle, under one lock; they
    are methods on one object so that the cycle's arithmetic stays plain attribute access, as
    it was in one class (see sim/engine.py for why they are a chain of base classes).
    """

    # ---- built once by the constructor (sim/engine.py)
    profile: DeviceProfile
    node_id: int
    _lock: threading.RLock
    _emcy_listeners: list[EmcyListener]
    _write_listeners: list[WriteListener]
    _cycle_hooks: list[StepHook]
    _step_hooks: list[StepHook]
    _substep_hooks: tuple[StepHook, ...]
    _events: list[tuple[int, int, bytes]]
    _specs: dict[int, ObjectSpec]
    _subs: dict[int, set[int]]
    _defaults: dict[int, Value | None]
    _values: dict[int, Value | None]
    _nv: dict[int, Value | None]
    _history_len: int
    _modes: frozenset[int]
    #: What 6060h accepts: the modes, and 0 (no mode) where the profile lists it.
    _mode_values: frozenset[int]
    _homing_methods: frozenset[int]
    _store_cmd: tuple[int, int | None, int]
    _restore_cmd: tuple[int, int | None, int]
    _cw_min_interval: float
    _qs_statusword: int | None
    _bit7_resets: bool
    _pdo_rules: MappingRules
    _homing_equiv: object
    _rate_fclk: float
    _rate_registers: frozenset[int]
    _homing_no_enable: frozenset[int]
    _homing_cancel_clears: bool
    faults: FaultModel
    plant_params: PlantParams
    sim_settings: SimSettings
    plant: Plant
    gains: ControllerGains
    loop_rate_hz: int
    _substeps: int
    _T: float
    _sub_dt: float
    _rated: float
    _counts_per_rad: float
    _vmax_sim: float
    _limits_in_pv: bool
    switches: SwitchLayout
    _homing_max_travel: float
    _i2t_tau: float
    _i2t_limit: float
    _i2t: float
    nmt_state: str
    _cycles: int
    _sub_k: int
    _acc_time: float
    _inputs: int
    recorder: Recorder | None
    one_touch: OneTouchTuning | None
    # ---- the servo loop (engine_servo._init_servo)
    servo: ServoLoop | None
    siggen: SignalGenerator | None
    _gain_keys: dict[int, tuple[str, float]]
    _loop_rate_key: int | None
    _sig_index: int
    _srv_vlim: float
    _raw0: float
    _dv0: float
    _inc: float
    # ---- runtime, set again by every reset (SimulatedDrive._reset_runtime)
    _c: dict[int, int]
    _state: State
    _enabled: bool
    _kind: int
    _cw: int
    _cw_time: float
    _pos_offset: int
    _mode: int
    _stop: Stop | None
    _halted: bool
    _hold: bool
    _dp: float
    _dv: float
    _da: float
    _integ: float
    _tq_demand: float
    _sat: bool
    _clipped: bool
    _fe: float
    _fe_time: float
    _fe_flag: bool
    _reached: bool
    _win_time: float
    _pp_target: float
    _pp_done: bool
    _pp_buffer: float | None
    _csp_target: float
    _csp_cycle: int
    _sp_ack: bool
    _homing_started: bool
    _homing_cancelled: bool
    _homed: bool
    _homing: HomingProcedure | None
    _homing_error: bool
    _limit_prev: int
    _live: dict[int, Callable[[], Value | None]]

    @property
    def time(self) -> float:
        """Simulated time in seconds (whole control cycles)."""
        return self._cycles * self._T

    def _refresh(self) -> None:
        """Copy the parameters the control cycle reads into ``_c`` (after every write)."""
        values = self._values
        c = self._c
        for k, fallback in FALLBACK.items():
            v = values.get(k)
            c[k] = v if isinstance(v, int) else fallback
        spec = self._specs.get(K_MAX_PROFILE_VEL)
        if spec is not None and spec.raw_unit in ("rpm", "r/min") and c[K_MAX_PROFILE_VEL] > 0:
            # 607Fh in whole r/min (smartris 001 §6-4), not in position units per second:
            # the control cycle limits in counts/s.
            c[K_MAX_PROFILE_VEL] = round(
                c[K_MAX_PROFILE_VEL] / 60.0 * self.plant_params.counts_per_rev
            )
        for k in (K_PROFILE_ACC, K_PROFILE_DEC, K_QS_DEC):
            # 0 is "no ramp" (not valid in CiA 402, but so in some families).
            c[k] = max(1, round(self._acceleration(k, c[k]))) if c[k] > 0 else NO_RAMP

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
