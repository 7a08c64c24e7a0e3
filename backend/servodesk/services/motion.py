"""Motion of a drive session: jog, moves, velocity, torque, cyclic set-points, homing, dead-man.

Every motion is started by the holder of control (:mod:`servodesk.services.control`) and
lives while the heartbeats of its bound WebSocket arrive. The dead-man's watch runs on a
thread of its own (:mod:`servodesk.services.deadman`): once the last heartbeat is
``deadman_s`` old it puts a quick stop on the wire without the event loop where the link can
(``DriveLink.stop_frame``), and the loop then halts (controlword bit 8) and quick-stops the
axis through the link as before. Losing the holder (its socket closing, release, force take)
and shutting the backend down stop it the same way, and losing the holder also disables the
drive at standstill (:meth:`MotionService.make_safe`).

Before anything is sent, a request is checked against the family's modes (profile) and the
drive's own limits, read from the drive and cached per session (refreshed after any write
through the API): software position limits 607Dh, max profile velocity 607Fh, max torque 6072h,
max acceleration / deceleration 60C5h / 60C6h. A refused request names the limit and its
value and nothing reaches the bus. A limit object the drive refuses (SDO abort) is unknown
(None, with the reason in ``sources``); only a dead link fails the read.

Jog and profile velocity have no target to check: a command toward a software limit the axis
is at or beyond is refused, and while they run the monitor halts the axis once the distance it
needs to stop (sampling lead plus braking at the halt deceleration) reaches the limit.
Homing started through the API is a motion too (kind ``homing``), under the same dead-man.

Choices where CiA 402 leaves room (documented once):

- Motion needs Operation enabled: servo on is the user's explicit step (``POST /state`` with
  ``enable``, which walks the state machine with the family's controlword spacing).
- The mode (6060h) is set by the motion that needs it. Quirk ``mode_change_at_standstill``
  refuses a change while the axis moves; quirk ``mode_change_refused`` (states where 6060h is
  refused) is handled by disable operation -> 6060h -> enable operation at standstill.
- Profile position: bit 5 (change set immediately) comes from ``immediate``; a set-point that
  is not immediate joins the drive's set-point buffer (set of set-points) and is sent only when
  set-point acknowledge (statusword bit 12) is 0, since drives discard it otherwise
  (quirk ``pp_set_point_buffer``: HIWIN 000 §3.2.2, CTMM 003 §4-4-5).
- Cyclic modes (csp, csv, cst) need the family to list mode 8/9/10. Without PDOs the backend
  writes the set-point by SDO every ``cyclic_period`` seconds; the drive interpolates between
  them. Before csp starts, 607Ah is set to the actual position (HIWIN 000 quirk
  ``csp_align_target_before_enable``: otherwise the axis jumps). ``duration`` is rounded up to
  whole periods of the waveform so the set-point ends where it started. The waveform's time is
  counted in set-points: a stall of the backend stretches it (the drive holds the last
  set-point) rather than skipping part of it, which would step the set-point. The motion's
  message says how often and how long it stalled, while it runs and after it ends.
- Limits 607Dh min = max = 0 switch the position limits off (CiA 402-2 §6.5.4); 607Fh = 0 is
  read as "no extra limit", as the simulated drive does. Objects a family lists in the quirk
  ``objects_not_usable`` are not read.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import AsyncIterator, Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CONTROLWORD,
    HALT_OPTION,
    MODE,
    MODE_DISPLAY,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    QUICK_STOP_DEC,
    STATUSWORD,
    TARGET_POSITION,
    TARGET_TORQUE,
    TARGET_VELOCITY,
    TORQUE_ACTUAL,
    TORQUE_SLOPE,
    VELOCITY,
    VELOCITY_THRESHOLD,
)
from servodesk.domain.datatypes import DataType, Value, codec
from servodesk.domain.ramps import ramp_kind
from servodesk.domain.values import encode_write
from servodesk.errors import (
    ConflictError,
    DriveStateError,
    LinkError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.services import homing
from servodesk.services.control import ControlService
from servodesk.services.deadman import DeadmanWatch, thread_stop
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.session import BORROW, Borrowed, Session

log = logging.getLogger(__name__)

LIMIT_OBJECTS: dict[str, ObjectAddress] = {
    "position_min": ObjectAddress(0x607D, 1),
    "position_max": ObjectAddress(0x607D, 2),
    "max_velocity": ObjectAddress(0x607F),
    "max_torque": ObjectAddress(0x6072),
    "max_acceleration": ObjectAddress(0x60C5),
    "max_deceleration": ObjectAddress(0x60C6),
}

# Controlword bits (CiA 402-2 §6.2.1): enable operation, and the mode-specific bits.
CW_ENABLE = 0x000F
CW_NEW_SETPOINT = 0x0010
CW_IMMEDIATE = 0x0020
CW_RELATIVE = 0x0040
CW_HALT = 0x0100
SW_TARGET_REACHED = 1 << 10
SW_SETPOINT_ACK = 1 << 12

PP, PV, TQ, HM, CSP, CSV, CST = 1, 3, 4, 6, 8, 9, 10
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
CYCLIC_MODES = {"csp": CSP, "csv": CSV, "cst": CST}
#: Standstill when |velocity| is within 606Fh; this when the drive has no 606Fh (inc/s).
DEFAULT_STANDSTILL = 1000
#: Continuous motion (jog, profile velocity) near a software position limit: the monitor
#: samples the position this often, and assumes this stopping time when the family's
#: deceleration is not in position units per s² (LECSN-T ms ramps, CTMM04x rate registers).
LIMIT_GUARD_PERIOD = 0.02
FALLBACK_STOP_S = 0.5
#: A homing run whose statusword already shows an end state (a drive with an absolute encoder
#: keeps bit 12 set) is taken as ended only when it stays so this long without running.
HOMING_SETTLE_S = 0.3
#: Losing the holder: how long the axis gets to come to standstill before the power stage is
#: switched off anyway (a drive whose quick stop does not end; it then coasts).
SAFE_STOP_S = 5.0
#: States with the power stage on or about to be (CiA 402-2 §6.2, figure 9).
_ENERGISED = {
    cia402.State.SWITCHED_ON,
    cia402.State.OPERATION_ENABLED,
    cia402.State.QUICK_STOP_ACTIVE,
}


@dataclass(frozen=True, slots=True)
class Limits:
    position_min: int | None
    position_max: int | None
    max_velocity: int | None
    max_torque: int | None
    max_acceleration: int | None
    max_deceleration: int | None
    modes: list[int]
    units: dict[str, dict[str, Any]]
    sources: dict[str, str]

    def as_dict(self) -> dict[str, Any]:
        return {
            "position_min": self.position_min,
            "position_max": self.position_max,
            "max_velocity": self.max_velocity,
            "max_torque": self.max_torque,
            "max_acceleration": self.max_acceleration,
            "max_deceleration": self.max_deceleration,
            "modes": self.modes,
            "mode_names": {str(m): cia402.mode_name(m) for m in self.modes},
            "units": self.units,
            "sources": self.sources,
        }


@dataclass(eq=False)
class Motion:
    kind: str
    owner: str
    mode: int
    target: float | None
    #: time.monotonic() when the motion was asked for: the dead-man counts from here too.
    started: float
    active: bool = True
    state: str = "running"
    message: str = ""
    tasks: list[asyncio.Task[None]] = field(default_factory=list)
    #: Continuous motion near software limits: the limits and the deceleration the halt uses
    #: (position units per s², None: unknown), for the monitor's stop-before-the-limit check.
    guard: Limits | None = None
    halt_decel: float | None = None
    acceleration: float | None = None
    #: The commanded speed in position units per s (None: 60FFh is in other units).
    speed_cap: float | None = None
    #: 606Ch is in position units per s: the monitor reads it rather than differentiating
    #: the position (whose sample times jitter with the event loop).
    read_velocity: bool = False
    #: Called once with the motion when it ends, however it ends (the tuning service stops
    #: its job when the dead-man, a stop or a fault ends the tuning motion).
    on_end: list[Callable[[Motion], None]] = field(default_factory=list)


#: Ends of a motion the audit log records as failures: it did not end as asked.
_FAILED = frozenset({"deadman", "error", "fault", "lost"})


def _facts(motion: Motion) -> dict[str, Any]:
    """What the audit log keeps of a motion."""
    return {
        "kind": motion.kind,
        "owner": motion.owner,
        "mode": motion.mode,
        "target": motion.target,
    }


@dataclass(eq=False)
class _Axis:
    session: Session
    limits: Limits | None = None
    limits_gen: int = 0
    motion: Motion | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    #: Bumped by every stop: a start in progress sees it and does not send its "go".
    epoch: int = 0
    #: A start sent its "go" after a stop began: the stop sends its commands again.
    rehalt: bool = False
    last_target: float | None = None
    #: The settings the axis's motions wrote and give back when they end (session.BORROW).
    borrowed: Borrowed = field(default_factory=dict)

    @property
    def sid(self) -> str:
        return self.session.id


class MotionService:
    def __init__(
        self,
        manager: SessionManager,
        control: ControlService,
        hub: EventHub,
        *,
        deadman_s: float = 0.25,
        watchdog_period: float = 0.01,
        cyclic_period: float = 0.01,
    ) -> None:
        self.manager = manager
        self.control = control
        self.hub = hub
        self.deadman_s = deadman_s
        self.watchdog_period = watchdog_period
        self.cyclic_period = cyclic_period
        self._axes: dict[str, _Axis] = {}
        self._background: set[asyncio.Task[Any]] = set()
        #: Making a drive safe after its holder was lost, per session (make_safe).
        self._safing: dict[str, asyncio.Task[str | None]] = {}
        #: The dead-man's watch, on a thread of its own (services/deadman.py).
        self._deadman = DeadmanWatch(period_s=min(watchdog_period, 0.005))
        control.on_lost(self._control_lost)
        control.on_bound(self._control_bound)

    # Axes and limits ----------------------------------------------------------------------

    def _axis(self, sid: str) -> _Axis:
        session = self.manager.get(sid)
        axis = self._axes.get(sid)
        if axis is None or axis.session is not session:
            axis = _Axis(session)
            self._axes[sid] = axis
        return axis

    def invalidate_limits(self, sid: str) -> None:
        """A write went (or goes) to the drive: read the limits again before the next use."""
        axis = self._axes.get(sid)
        if axis is not None:
            axis.limits = None
            axis.limits_gen += 1

    async def limits(self, sid: str) -> Limits:
        axis = self._axis(sid)
        if axis.limits is not None:
            return axis.limits
        gen = axis.limits_gen
        lim = await self._read_limits(axis.session)
        if axis.limits_gen == gen:
            axis.limits = lim
        return lim

    async def _read_limits(self, session: Session) -> Limits:
        profile = session.profile
        unusable = {str(a).upper() for a in profile.quirk("objects_not_usable", []) or []}
        values: dict[str, int | None] = {}
        sources: dict[str, str] = {}
        for name, address in LIMIT_OBJECTS.items():
            values[name] = None
            spec = profile.spec(address)
            if spec is None or not spec.access.readable:
                sources[name] = f"unknown: {profile.name} has no readable {address}"
                continue
            if f"0X{address.index:04X}" in unusable or str(address).upper() in unusable:
                sources[name] = f"unknown: {address} is not usable (quirk objects_not_usable)"
                continue
            try:
                v = await self._read_int(session, address)
            except ObjectAccessError as exc:
                # A limit the drive does not have or refuses to give is unknown, not an
                # error: the checks that need it are skipped. Only a dead link (LinkError)
                # fails the whole read.
                sources[name] = (
                    f"unknown: the drive refused {address} (abort 0x{exc.code:08X}: {exc.meaning})"
                )
                continue
            except ValidationError as exc:  # An answer that does not decode as the type.
                sources[name] = f"unknown: {address} could not be read ({exc.message})"
                continue
            values[name] = v
            if v is not None:
                sources[name] = str(address)
        if values["position_min"] == 0 and values["position_max"] == 0:
            # CiA 402-2 §6.5.4: min = max = 0 switches the software limits off.
            values["position_min"] = values["position_max"] = None
            sources["position_min"] = sources["position_max"] = "607Dh = 0/0: limits off"
        if values["max_velocity"] == 0:
            values["max_velocity"] = None
            sources["max_velocity"] = "607Fh = 0: no extra limit"
        # Without the drive objects, the profile's own range of the set-point objects.
        for name, address in (
            ("max_velocity", TARGET_VELOCITY),
            ("max_torque", TARGET_TORQUE),
            ("max_acceleration", PROFILE_ACC),
            ("max_deceleration", PROFILE_DEC),
        ):
            spec = profile.spec(address)
            if values[name] is None and spec is not None and isinstance(spec.max, int):
                values[name] = spec.max
                why = sources.get(name)
                sources[name] = f"profile {address} max" + (f" ({why})" if why else "")
        units: dict[str, dict[str, Any]] = {}
        for kind, candidates in (
            ("position", (POSITION, TARGET_POSITION)),
            ("velocity", (VELOCITY, TARGET_VELOCITY)),
            ("torque", (TARGET_TORQUE, TORQUE_ACTUAL)),
            ("acceleration", (PROFILE_ACC,)),
        ):
            for address in candidates:
                spec = profile.spec(address)
                if spec is not None:
                    dv = spec.default_value()
                    units[kind] = {
                        "raw_unit": spec.raw_unit,
                        "unit": spec.unit,
                        "scale": spec.scale,
                        # The family's own default of that object: where a ramp is neither a
                        # rate nor a time (CTMM04x: PMC842SR rate registers, 003 §5-3-1), the
                        # panels start from it.
                        "default": dv if isinstance(dv, int) and not isinstance(dv, bool) else None,
                    }
                    if kind == "acceleration":
                        # What the ramp objects hold, so the UI need not parse the unit.
                        units[kind]["ramp"] = ramp_kind(spec.raw_unit)
                    break
        return Limits(
            position_min=values["position_min"],
            position_max=values["position_max"],
            max_velocity=values["max_velocity"],
            max_torque=values["max_torque"],
            max_acceleration=values["max_acceleration"],
            max_deceleration=values["max_deceleration"],
            modes=sorted(profile.modes),
            units=units,
            sources=sources,
        )

    @staticmethod
    async def _read_int(session: Session, address: ObjectAddress) -> int | None:
        spec = session.profile.spec(address)
        raw = await session.link.read(address)
        v = codec(spec.data_type if spec else DataType.INTEGER32).decode(raw)
        return int(v) if isinstance(v, int | bool) else None

    # Checks (nothing is sent) -------------------------------------------------------------

    @staticmethod
    def _need_mode(axis: _Axis, mode: int, what: str) -> None:
        p = axis.session.profile
        if mode not in p.modes:
            have = ", ".join(cia402.mode_name(m) for m in sorted(p.modes)) or "none"
            raise ValidationError(
                f"{p.name} ({p.id}) has no {cia402.mode_name(mode)}, which {what} needs; "
                f"its modes: {have}",
                field="mode",
                hint="use a motion this family supports (see GET /limits: modes)",
            )

    @staticmethod
    def _check_abs(
        value: float, limit: int | None, name: str, field_name: str, lim: Limits
    ) -> None:
        if limit is not None and abs(value) > limit:
            src = lim.sources.get(name, name)
            raise ValidationError(
                f"{field_name} {value:g} exceeds the {name.replace('_', ' ')} {limit} ({src}); "
                "nothing was sent",
                field=field_name,
                hint=f"stay within ±{limit}, or raise the limit on the drive",
            )

    @staticmethod
    def _check_position(value: float, lim: Limits, field_name: str) -> None:
        lo, hi = lim.position_min, lim.position_max
        if lo is not None and value < lo:
            raise ValidationError(
                f"{field_name} {value:g} is below the software position limit min {lo} "
                f"({lim.sources.get('position_min', '607Dh:01')}); nothing was sent",
                field=field_name,
                hint=f"stay within {lo} .. {hi}",
            )
        if hi is not None and value > hi:
            raise ValidationError(
                f"{field_name} {value:g} is above the software position limit max {hi} "
                f"({lim.sources.get('position_max', '607Dh:02')}); nothing was sent",
                field=field_name,
                hint=f"stay within {lo} .. {hi}",
            )

    async def _check_toward_limit(
        self, axis: _Axis, lim: Limits, direction: float, field_name: str
    ) -> None:
        """Refuse continuous motion toward a software limit the axis is already at or beyond."""
        lo, hi = lim.position_min, lim.position_max
        if not (direction > 0 and hi is not None) and not (direction < 0 and lo is not None):
            return
        pos = await self._read_int(axis.session, POSITION)
        if pos is None:
            return
        if direction > 0 and hi is not None and pos >= hi:
            which, value, src = "max", hi, lim.sources.get("position_max", "607Dh:02")
        elif direction < 0 and lo is not None and pos <= lo:
            which, value, src = "min", lo, lim.sources.get("position_min", "607Dh:01")
        else:
            return
        raise ValidationError(
            f"the axis is at {pos}, at or beyond the software position limit {which} {value} "
            f"({src}); {field_name} {direction:g} moves toward it, so it was refused and "
            "nothing was sent",
            field=field_name,
            hint=f"move the other way, back inside {lo} .. {hi}",
        )

    async def _rate(
        self, axis: _Axis, address: ObjectAddress, requested: int | None
    ) -> float | None:
        """An acceleration or deceleration in position units per s², when it is in those units.

        ``requested`` is the value the motion writes; without it the drive's value is read.
        """
        spec = axis.session.profile.spec(address)
        if spec is None or not _per_s2(spec.raw_unit):
            return None
        value: int | None = requested
        if value is None:
            with contextlib.suppress(ObjectAccessError, ValidationError):
                value = await self._read_int(axis.session, address)
        return float(value) if value is not None and value > 0 else None

    async def _halt_rate(self, axis: _Axis, requested: int | None) -> float | None:
        """The deceleration a halt uses: CiA 402-2 §6.3.4 halt option code 605Dh.

        1 (and vendor values): the slow-down ramp 6084h; 2: the quick-stop ramp 6085h; 3/4: the
        current or voltage limit, at least as hard as 6084h, so 6084h is a safe estimate.
        """
        option = 1
        if axis.session.profile.spec(HALT_OPTION) is not None:
            with contextlib.suppress(ObjectAccessError, ValidationError):
                option = await self._read_int(axis.session, HALT_OPTION) or 1
        if option == 2:
            return await self._rate(axis, QUICK_STOP_DEC, None)
        return await self._rate(axis, PROFILE_DEC, requested)

    async def _guard(
        self,
        axis: _Axis,
        lim: Limits,
        velocity: int,
        acceleration: int | None,
        deceleration: int | None,
    ) -> dict[str, Any]:
        """What the monitor needs to halt continuous motion before a software limit."""
        lo, hi = lim.position_min, lim.position_max
        if lo in (None, INT32_MIN) and hi in (None, INT32_MAX):
            return {}  # No limit, or the whole INTEGER32 range (the generic default).
        p = axis.session.profile
        spec = p.spec(TARGET_VELOCITY)
        # The commanded velocity bounds the speed ahead when 60FFh is in position units per s.
        cap = float(abs(velocity)) if spec is not None and _per_s(spec.raw_unit) else None
        actual = p.spec(VELOCITY)
        return {
            "guard": lim,
            "halt_decel": await self._halt_rate(axis, deceleration),
            "acceleration": await self._rate(axis, PROFILE_ACC, acceleration),
            "speed_cap": cap,
            "read_velocity": actual is not None and _per_s(actual.raw_unit),
        }

    @staticmethod
    def _encode(
        axis: _Axis, writes: list[tuple[ObjectAddress, Value]]
    ) -> list[tuple[ObjectAddress, Value]]:
        """Validate every planned write against the profile before the first one is sent."""
        p = axis.session.profile
        for address, value in writes:
            spec = p.spec(address)
            if spec is None and p.variables:
                raise ValidationError(
                    f"{p.name} ({p.id}) has no object {address}, which this motion needs",
                    field=str(address),
                    hint="this family does not support that part of the motion",
                )
            encode_write(address, spec, value)
        return writes

    # Bus helpers --------------------------------------------------------------------------

    async def _statusword(self, axis: _Axis) -> int:
        return await self._read_int(axis.session, STATUSWORD) or 0

    async def _require_enabled(self, axis: _Axis) -> int:
        sw = await self._statusword(axis)
        state = cia402.decode_state(sw)
        if state is not cia402.State.OPERATION_ENABLED:
            raise DriveStateError(
                f"the servo is off ({state.value}); motion needs Operation enabled",
                hint='servo on first: POST /state {"command": "enable"}',
            )
        return sw

    async def _standstill(self, axis: _Axis) -> bool:
        s = axis.session
        threshold = DEFAULT_STANDSTILL
        if s.profile.spec(VELOCITY_THRESHOLD) is not None:
            with contextlib.suppress(ServodeskError):
                threshold = await self._read_int(s, VELOCITY_THRESHOLD) or threshold
        v = await self._read_int(s, VELOCITY) if s.profile.spec(VELOCITY) else 0
        return abs(v or 0) <= threshold

    async def _ensure_mode(self, axis: _Axis, mode: int, who: str) -> None:
        s = axis.session
        current = await self._read_int(s, MODE_DISPLAY)
        if current == mode:
            return
        p = s.profile
        moving = not await self._standstill(axis)
        if moving and p.quirk("mode_change_at_standstill"):
            raise DriveStateError(
                f"{p.name} changes the mode of operation only at standstill "
                "(quirk mode_change_at_standstill); the axis moves",
                hint="halt first, then start the motion again",
            )
        refused = p.quirk("mode_change_refused")
        states = refused.get("states", []) if isinstance(refused, dict) else []
        if "operation_enabled" in [str(x).lower() for x in states]:
            # The family refuses 6060h in Operation enabled: disable operation, set the mode,
            # enable again (at standstill only: disabling drops the holding torque).
            if moving:
                raise DriveStateError(
                    f"{p.name} refuses a mode change in Operation enabled and the axis moves",
                    hint="halt first, then start the motion again",
                )
            await s.command("disable_operation")
            await s.write_object(MODE, mode, client=who)
            await s.command("enable_operation")
        else:
            await s.write_object(MODE, mode, client=who)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            if await self._read_int(s, MODE_DISPLAY) == mode:
                return
            await asyncio.sleep(0.005)
        raise DriveStateError(
            f"the drive did not switch to {cia402.mode_name(mode)} (6061h)",
            hint="check the drive's error code and whether it allows this mode now",
        )

    async def _write_all(
        self, axis: _Axis, writes: list[tuple[ObjectAddress, Value]], who: str
    ) -> None:
        with self._borrowing(axis):
            for address, value in writes:
                await axis.session.write_object(address, value, client=who)

    @staticmethod
    @contextlib.contextmanager
    def _borrowing(axis: _Axis) -> Iterator[None]:
        """The settings written in this block are the motion's: given back when it ends."""
        token = BORROW.set(axis.borrowed)
        try:
            yield
        finally:
            BORROW.reset(token)

    async def _give_back(self, axis: _Axis) -> None:
        """Put back the settings the ended motion wrote (6081h, 6083h, 6084h, 6098h, ...).

        Issue "Motion safety" item 6: after a jog the CTMM04x's 6081h read 819 instead of the
        5000 the user had saved, and the next "Save to EEPROM" stored it with the user's own
        edit. They go back once the axis stands (a halt ramps down with 6084h, CiA 402-2
        §6.4.3) and not while another motion runs (that one gives them back when it ends). A
        setting that cannot be put back stays marked as written since the last save, and the
        clients are told which."""
        async with axis.lock:
            if not axis.borrowed or (axis.motion is not None and axis.motion.active):
                return
            end = time.monotonic() + SAFE_STOP_S
            with contextlib.suppress(ServodeskError):
                while not await self._standstill(axis):
                    if time.monotonic() > end:
                        break
                    await asyncio.sleep(0.02)  # Polling the drive: no event to wait on.
            given: list[str] = []
            kept: list[str] = []
            for address, (raw, _was_dirty) in list(axis.borrowed.items()):
                del axis.borrowed[address]
                if raw is None:
                    axis.session.dirty.add(address)
                    kept.append(f"{address}: it could not be read before the motion")
                    continue
                try:
                    await axis.session.write_raw(address, raw)
                    given.append(str(address))
                except ServodeskError as exc:
                    axis.session.dirty.add(address)
                    kept.append(f"{address}: {exc.message}")
            log.info("%s: settings given back %s, kept %s", axis.sid, given, kept)
            self.hub.publish(
                {"type": "motion_settings", "session": axis.sid, "restored": given, "kept": kept},
                session=axis.sid,
            )
            if kept:
                self.hub.publish({"type": "sessions_changed"})

    async def _controlword(self, axis: _Axis, word: int, who: str) -> None:
        await axis.session.write_object(CONTROLWORD, word, client=who)

    @contextlib.asynccontextmanager
    async def _starting(self, axis: _Axis) -> AsyncIterator[int]:
        try:
            async with axis.lock:
                yield axis.epoch
        finally:
            m = axis.motion
            if axis.borrowed and (m is None or not m.active):
                # The start failed after writing its settings: nothing runs to give them back.
                self._spawn(self._give_back(axis))

    async def _go(self, axis: _Axis, epoch: int, word: int, who: str) -> None:
        """Send a controlword that starts motion, unless a stop came meanwhile."""
        if axis.epoch != epoch:
            raise ConflictError(
                "a halt or stop came while the motion was starting; it was not started",
                hint="start it again",
            )
        await self._controlword(axis, word, who)
        if axis.epoch != epoch:
            axis.rehalt = True

    def _begin(self, axis: _Axis, motion: Motion, *extra: Callable[[], Any]) -> None:
        old = axis.motion
        if old is not None and old.active:
            self._cancel_tasks(old)
            old.active = False
            self._deadman.disarm(old)
            old.state, old.message = "replaced", f"replaced by {motion.kind}"
            self.control.audit.record(
                "motion.stopped", drive=axis.sid, message=old.message, details=_facts(old)
            )
            self._notify_end(old)
        axis.motion = motion
        loop = asyncio.get_running_loop()
        self._arm(axis, motion, loop)
        motion.tasks.append(
            loop.create_task(self._monitor(axis, motion), name=f"motion {axis.sid}")
        )
        for make in extra:
            motion.tasks.append(loop.create_task(make(), name=f"setpoints {axis.sid}"))
        log.info("%s on %s by %s: %s", motion.kind, axis.sid, motion.owner, motion.message)
        self.control.audit.record(
            "motion.started", drive=axis.sid, message=motion.message, details=_facts(motion)
        )
        self._publish(axis)

    def _arm(self, axis: _Axis, motion: Motion, loop: asyncio.AbstractEventLoop) -> None:
        """Hand the motion to the dead-man's thread: it stops the axis when the holder's
        heartbeats (services/control) are ``deadman_s`` old, without the event loop."""
        sid, control = axis.sid, self.control
        # The dead-man counts from when the motion really starts, not from the request: a
        # start that waited (the axis lock held while the last motion's settings are given
        # back at standstill) was otherwise stopped at once, its heartbeat older than the
        # deadline (bench_deadman: 1 run in 20, the stop before the client's last heartbeat).
        armed = time.monotonic()

        def last() -> float:
            return max(control.last_heartbeat(sid) or 0.0, motion.started, armed)

        def fired(since: float, sent: float | None) -> None:
            if not loop.is_closed():
                loop.call_soon_threadsafe(self._deadman_fired, axis, motion, since, sent)

        self._deadman.arm(
            motion,
            deadline_s=self.deadman_s,
            last=last,
            stop=thread_stop(axis.session),
            fired=fired,
        )

    def _deadman_fired(self, axis: _Axis, motion: Motion, since: float, sent: float | None) -> None:
        """On the loop, after the thread's stop frame: the orderly rest of the stop."""
        if not motion.active:
            return
        ms = round((time.monotonic() - since) * 1000)
        self._spawn(
            self._lost_operator(
                axis,
                motion,
                f"no heartbeat from client {motion.owner!r} for {ms} ms",
                since,
                frame_at=sent,
            )
        )

    @staticmethod
    def _cancel_tasks(motion: Motion) -> None:
        me = asyncio.current_task()
        for t in motion.tasks:
            if t is not me:
                t.cancel()

    def _end(self, axis: _Axis, motion: Motion, state: str, message: str) -> None:
        if not motion.active:
            return
        motion.active = False
        motion.state = state
        motion.message = message
        self._deadman.disarm(motion)
        self._cancel_tasks(motion)
        if axis.borrowed:
            self._spawn(self._give_back(axis))
        log.info("motion on %s ended: %s (%s)", axis.sid, state, message)
        self._notify_end(motion)
        self._publish(axis)
        # After the listeners (a tuning's stop): the record is queued, it never waits on the
        # database (services/audit.py). A stop's reason is its message.
        self.control.audit.record(
            "motion.stopped",
            drive=axis.sid,
            ok=state not in _FAILED,
            message=message,
            details={**_facts(motion), "state": state},
        )

    @staticmethod
    def _notify_end(motion: Motion) -> None:
        listeners, motion.on_end = motion.on_end, []
        for cb in listeners:
            try:
                cb(motion)
            except Exception:  # A listener's bug must not keep the axis from stopping.
                log.exception("motion end listener failed")

    # Motion commands ----------------------------------------------------------------------

    async def jog(self, sid: str, client: str, velocity: int, acceleration: int) -> dict[str, Any]:
        """Profile velocity at ``velocity`` while the client's heartbeats arrive."""
        started = time.monotonic()
        axis = self._axis(sid)
        self._need_mode(axis, PV, "jog")
        lim = await self.limits(sid)
        self._check_abs(velocity, lim.max_velocity, "max_velocity", "velocity", lim)
        self._check_abs(acceleration, lim.max_acceleration, "max_acceleration", "acceleration", lim)
        self._check_abs(acceleration, lim.max_deceleration, "max_deceleration", "acceleration", lim)
        writes = self._encode(
            axis,
            [(PROFILE_ACC, acceleration), (PROFILE_DEC, acceleration), (TARGET_VELOCITY, velocity)],
        )
        await self._check_toward_limit(axis, lim, velocity, "velocity")
        guard = await self._guard(axis, lim, velocity, acceleration, acceleration)
        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            await self._ensure_mode(axis, PV, client)
            await self._write_all(axis, writes, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            self._begin(
                axis,
                Motion("jog", client, PV, velocity, started, message=f"jog at {velocity}", **guard),
            )
        return self.status(sid)

    async def velocity(
        self,
        sid: str,
        client: str,
        velocity: int,
        acceleration: int | None,
        deceleration: int | None,
    ) -> dict[str, Any]:
        started = time.monotonic()
        axis = self._axis(sid)
        self._need_mode(axis, PV, "profile velocity")
        lim = await self.limits(sid)
        self._check_abs(velocity, lim.max_velocity, "max_velocity", "velocity", lim)
        plan: list[tuple[ObjectAddress, Value]] = []
        if acceleration is not None:
            self._check_abs(
                acceleration, lim.max_acceleration, "max_acceleration", "acceleration", lim
            )
            plan.append((PROFILE_ACC, acceleration))
        if deceleration is not None:
            self._check_abs(
                deceleration, lim.max_deceleration, "max_deceleration", "deceleration", lim
            )
            plan.append((PROFILE_DEC, deceleration))
        plan.append((TARGET_VELOCITY, velocity))
        writes = self._encode(axis, plan)
        await self._check_toward_limit(axis, lim, velocity, "velocity")
        guard = await self._guard(axis, lim, velocity, acceleration, deceleration)
        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            await self._ensure_mode(axis, PV, client)
            await self._write_all(axis, writes, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            self._begin(
                axis,
                Motion(
                    "velocity",
                    client,
                    PV,
                    velocity,
                    started,
                    message=f"velocity {velocity}",
                    **guard,
                ),
            )
        return self.status(sid)

    async def torque(self, sid: str, client: str, torque: int, slope: int | None) -> dict[str, Any]:
        started = time.monotonic()
        axis = self._axis(sid)
        self._need_mode(axis, TQ, "profile torque")
        lim = await self.limits(sid)
        self._check_abs(torque, lim.max_torque, "max_torque", "torque", lim)
        plan: list[tuple[ObjectAddress, Value]] = []
        if slope is not None:
            plan.append((TORQUE_SLOPE, slope))
        plan.append((TARGET_TORQUE, torque))
        writes = self._encode(axis, plan)
        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            await self._ensure_mode(axis, TQ, client)
            await self._write_all(axis, writes, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            self._begin(
                axis, Motion("torque", client, TQ, torque, started, message=f"torque {torque}")
            )
        return self.status(sid)

    async def move(
        self,
        sid: str,
        client: str,
        *,
        relative: bool,
        target: int,
        velocity: int | None,
        acceleration: int | None,
        deceleration: int | None,
        immediate: bool,
    ) -> dict[str, Any]:
        """Profile position: one set-point, or one more of a set of set-points."""
        started = time.monotonic()
        axis = self._axis(sid)
        s = axis.session
        self._need_mode(axis, PP, "a move")
        lim = await self.limits(sid)
        plan: list[tuple[ObjectAddress, Value]] = []
        if velocity is not None:
            self._check_abs(velocity, lim.max_velocity, "max_velocity", "velocity", lim)
            plan.append((PROFILE_VELOCITY, velocity))
        if acceleration is not None:
            self._check_abs(
                acceleration, lim.max_acceleration, "max_acceleration", "acceleration", lim
            )
            plan.append((PROFILE_ACC, acceleration))
        if deceleration is not None:
            self._check_abs(
                deceleration, lim.max_deceleration, "max_deceleration", "deceleration", lim
            )
            plan.append((PROFILE_DEC, deceleration))
        moving_pp = (
            axis.motion is not None
            and axis.motion.active
            and axis.motion.kind == "move"
            and axis.last_target is not None
        )
        if relative:
            # CiA 402-2 §6.5: relative to the present target while a move runs, else to the
            # actual position (the drive's demand position at rest).
            base = (
                axis.last_target
                if moving_pp and axis.last_target is not None
                else float(await self._read_int(s, POSITION) or 0)
            )
            final = base + target
        else:
            final = float(target)
        self._check_position(final, lim, "target")
        plan.append((TARGET_POSITION, target))
        writes = self._encode(axis, plan)
        q = s.profile.quirk("pp_set_point_buffer")
        reversal_rejected = (
            isinstance(q, dict) and q.get("change_immediately_reversal") == "rejected"
        )
        bits = CW_ENABLE | (CW_RELATIVE if relative else 0) | (CW_IMMEDIATE if immediate else 0)
        async with self._starting(axis) as epoch:
            sw = await self._require_enabled(axis)
            if not immediate and moving_pp and sw & SW_SETPOINT_ACK:
                raise ConflictError(
                    "the drive's set-point buffer is full (set-point acknowledge, statusword "
                    "bit 12, is still 1); a new set-point now would be discarded",
                    hint="wait until the running move is done, or send it with immediate: true",
                )
            if immediate and moving_pp and reversal_rejected:
                v = await self._read_int(s, VELOCITY) or 0
                pos = await self._read_int(s, POSITION) or 0
                if v * (final - pos) < 0:
                    raise ValidationError(
                        f"{s.profile.name} rejects a new target in the opposite direction "
                        "during a move (quirk pp_set_point_buffer)",
                        field="target",
                        hint="halt first, then move the other way",
                    )
            await self._ensure_mode(axis, PP, client)
            await self._write_all(axis, writes, client)
            # New set-point on the rising edge of bit 4 (CiA 402-2 §6.5.1); halt bit cleared.
            if axis.epoch != epoch:
                raise ConflictError("a halt or stop came while the move was starting")
            await self._controlword(axis, bits, client)
            await self._go(axis, epoch, bits | CW_NEW_SETPOINT, client)
            acked = await self._wait_bits(axis, SW_SETPOINT_ACK, True, 0.3)
            await self._controlword(axis, bits, client)  # Bit 4 back to 0 for the next set-point.
            if not acked:
                raise DriveStateError(
                    "the drive did not acknowledge the set-point (statusword bit 12)",
                    hint="check the drive's error code and the mode of operation",
                )
            kind = "relative" if relative else "absolute"
            axis.last_target = final
            if moving_pp and axis.motion is not None and not immediate:
                # The buffered set-point belongs to the running move: keep its watchdog.
                axis.motion.target = final
                axis.motion.message = f"{kind} move, next target {final:g} buffered"
                self._publish(axis)
            else:
                self._begin(
                    axis,
                    Motion("move", client, PP, final, started, message=f"{kind} move to {final:g}"),
                )
        return self.status(sid)

    async def home(
        self,
        sid: str,
        client: str,
        method: int,
        *,
        speed_switch: int | None = None,
        speed_zero: int | None = None,
        acceleration: int | None = None,
        offset: int | None = None,
        max_travel: int | None = None,
        timeout_s: float | None = None,
    ) -> dict[str, Any]:
        """Start a homing run (services/homing.py) under the client's dead-man, like a jog.

        A run on an enabled drive moves the axis: it is a motion of kind ``homing`` that ends
        when the statusword shows homing attained or a homing error (CiA 402-2 §6.8.1), and a
        missing heartbeat, the client's socket closing, losing control or the backend shutting
        down halt it (the halt bit interrupts homing) and then quick-stop it. So does its
        time-out (``timeout_s``; by default from the estimated duration, domain/homing.py),
        which ends it ``timeout``. However the motion ends, the run's end is published as the
        last ``homing`` message. A method the family runs without Operation enabled (quirk
        ``homing_without_enable``) on a drive that is not enabled does not move anything and
        is not watched.
        """
        started = time.monotonic()
        axis = self._axis(sid)
        s = axis.session
        lim = await self.limits(sid)
        # The estimate and the time-out before anything is sent (a bad timeout_s is refused).
        plan = await homing.plan(
            s,
            method,
            speed_switch=speed_switch,
            speed_zero=speed_zero,
            acceleration=acceleration,
            max_travel=max_travel,
            timeout_s=timeout_s,
            limits=(lim.position_min, lim.position_max),
        )
        async with self._starting(axis) as epoch:
            enabled = (
                cia402.decode_state(await self._statusword(axis)) is cia402.State.OPERATION_ENABLED
            )

            async def set_mode() -> None:
                await self._ensure_mode(axis, HM, client)

            async def go(word: int) -> None:
                await self._go(axis, epoch, word, client)

            # A watched run's settings (6098h, 6099h, 609Ah, 607Ch) are given back at its end.
            borrowing = self._borrowing(axis) if enabled else contextlib.nullcontext()
            with borrowing:
                await homing.begin(
                    s,
                    method,
                    speed_switch=speed_switch,
                    speed_zero=speed_zero,
                    acceleration=acceleration,
                    offset=offset,
                    client=client,
                    set_mode=set_mode if enabled else None,
                    go=go,
                    plan_=plan,
                    watched=enabled,
                )
            axis.last_target = None  # Homing moves the position's origin.
            run = homing.current_run(s)
            if enabled:
                motion = Motion("homing", client, HM, None, started, message=plan.summary())
                if run is not None:

                    def ended(m: Motion) -> None:
                        # Taken over or released: the halt was a loss of control.
                        lost = self.control.owner(sid) != m.owner
                        homing.end_with_motion(run, m.state, m.message, control_lost=lost)

                    motion.on_end.append(ended)
                self._begin(axis, motion)
        return await homing.status(s)

    async def _wait_bits(self, axis: _Axis, mask: int, on: bool, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while True:
            sw = await self._statusword(axis)
            if bool(sw & mask) == on:
                return True
            if time.monotonic() > end:
                return False
            await asyncio.sleep(0.002)

    async def cyclic(
        self,
        sid: str,
        client: str,
        *,
        mode_name: str,
        waveform: str,
        amplitude: float,
        frequency: float,
        duration: float,
    ) -> dict[str, Any]:
        """A backend set-point generator in csp, csv or cst (families that list the mode)."""
        started = time.monotonic()
        axis = self._axis(sid)
        s = axis.session
        mode = CYCLIC_MODES[mode_name]
        self._need_mode(axis, mode, f"the cyclic {mode_name} generator")
        lim = await self.limits(sid)
        if frequency * self.cyclic_period > 0.1:
            raise ValidationError(
                f"frequency {frequency:g} Hz is too high for set-points every "
                f"{self.cyclic_period * 1000:g} ms (at most {0.1 / self.cyclic_period:g} Hz)",
                field="frequency",
                hint="lower the frequency",
            )
        # Peak rate of change of the waveform per unit amplitude.
        slope = 2 * math.pi * frequency if waveform == "sine" else 4 * frequency
        periods = max(1, math.ceil(duration * frequency - 1e-9))
        run_s = periods / frequency
        if mode == CSP:
            position = await self._read_int(s, POSITION) or 0
            self._check_position(position + amplitude, lim, "amplitude")
            self._check_position(position - amplitude, lim, "amplitude")
            self._check_abs(
                amplitude * slope, lim.max_velocity, "max_velocity", "peak velocity", lim
            )
            address = TARGET_POSITION
        elif mode == CSV:
            self._check_abs(amplitude, lim.max_velocity, "max_velocity", "amplitude", lim)
            self._check_abs(
                amplitude * slope,
                lim.max_acceleration,
                "max_acceleration",
                "peak acceleration",
                lim,
            )
            address, position = TARGET_VELOCITY, 0
        else:
            self._check_abs(amplitude, lim.max_torque, "max_torque", "amplitude", lim)
            address, position = TARGET_TORQUE, 0
        spec = s.profile.spec(address)
        self._encode(
            axis, [(address, round(position + amplitude)), (address, round(position - amplitude))]
        )

        def wave(t: float) -> float:
            x = frequency * t
            if waveform == "sine":
                return math.sin(2 * math.pi * x)
            return 2 / math.pi * math.asin(math.sin(2 * math.pi * x))  # Triangle, starts at 0.

        async with self._starting(axis) as epoch:
            await self._require_enabled(axis)
            if mode == CSP:
                # HIWIN 000 quirk csp_align_target_before_enable: 607Ah = 6064h before csp.
                position = await self._read_int(s, POSITION) or 0
            await s.write_object(address, position, client=client)
            await self._ensure_mode(axis, mode, client)
            await self._go(axis, epoch, CW_ENABLE, client)
            motion = Motion(
                "cyclic",
                client,
                mode,
                amplitude,
                started,
                message=f"{mode_name} {waveform} ±{amplitude:g} at {frequency:g} Hz for "
                f"{run_s:g} s",
            )
            base = position
            data_codec = codec(spec.data_type if spec else DataType.INTEGER32)
            running_message = motion.message

            async def generate() -> None:
                # write_raw: by SDO, or into the RPDO output image when cyclic data carries
                # the set-point (services/cyclic.py).
                write = s.write_raw
                period = self.cyclic_period
                due = time.monotonic()
                k = 0
                stalls: list[float] = []

                def stalled() -> str:
                    # What the user sees in the motion's status, running and ended: the
                    # waveform is not the one asked for when the stream stalled.
                    if not stalls:
                        return ""
                    return (
                        f"; the set-point stream stalled {len(stalls)} x (longest "
                        f"{max(stalls) * 1000:.0f} ms, {sum(stalls) * 1000:.0f} ms in all): "
                        "the drive held the set-point, the waveform ran that much longer"
                    )

                try:
                    while motion.active:
                        k += 1
                        due += period
                        late = time.monotonic() - due
                        if late > period:
                            # The backend stalled: the waveform is stretched by the stall (the
                            # drive holds the last set-point) instead of skipping ahead, so the
                            # set-point never steps by more than one period's change.
                            log.warning(
                                "the %s set-point stream stalled for %.0f ms; the waveform "
                                "resumes where it stopped",
                                mode_name,
                                late * 1000,
                            )
                            due += late
                            stalls.append(late)
                            motion.message = running_message + stalled()
                            self._publish(axis)
                        await asyncio.sleep(max(0.0, due - time.monotonic()))
                        # The waveform's time is counted in periods, not read off the clock.
                        t = k * period
                        if t >= run_s:
                            break
                        value = round(base + amplitude * wave(t))
                        await write(address, data_codec.encode(value))
                    if motion.active:
                        await write(address, data_codec.encode(base))
                        self._end(axis, motion, "done", f"{mode_name} {waveform} done{stalled()}")
                except ServodeskError as exc:
                    self._end(
                        axis,
                        motion,
                        "error",
                        f"set-point stream failed: {exc.message}{stalled()}",
                    )

            self._begin(axis, motion, generate)
        return self.status(sid)

    # Tuning motion (services/tuning.py) ----------------------------------------------------

    async def start_tuning_motion(
        self,
        sid: str,
        client: str,
        *,
        window: tuple[int, int] | None,
        message: str,
        on_end: Callable[[Motion], None] | None = None,
    ) -> Motion:
        """Begin a motion of kind ``tuning`` under the client's dead-man, like a jog.

        Nothing moves yet. With ``window`` (lowest and highest position the tuning may reach),
        the window is checked against the software position limits (607Dh) and the target
        range, and the mode becomes profile position: the tuning then moves the axis with
        :meth:`tuning_move`. Without it the mode is left alone (servodesk's own tuning excites
        the axis through the drive's test signal while the loops hold it). A missing
        heartbeat, the socket closing, losing control, a halt, a quick stop or the drive
        leaving Operation enabled end the motion (the axis is halted and, for the dead-man,
        quick-stopped) and call ``on_end``.
        """
        started = time.monotonic()
        axis = self._axis(sid)
        if window is not None:
            self._need_mode(axis, PP, "the tuning motion")
            lim = await self.limits(sid)
            for end in window:
                self._check_position(float(end), lim, "travel_window_rev")
            self._encode(axis, [(TARGET_POSITION, window[0]), (TARGET_POSITION, window[1])])
        async with self._starting(axis):
            await self._require_enabled(axis)
            if window is not None:
                await self._ensure_mode(axis, PP, client)
            motion = Motion(
                "tuning", client, PP if window is not None else 0, None, started, message=message
            )
            if on_end is not None:
                motion.on_end.append(on_end)
            self._begin(axis, motion)
        return motion

    async def tuning_move(
        self,
        sid: str,
        motion: Motion,
        target: int,
        *,
        velocity: int | None = None,
        acceleration: int | None = None,
        deceleration: int | None = None,
        timeout: float = 30.0,
        must_reach: bool = True,
    ) -> int:
        """One absolute profile-position move of a tuning motion; returns the position once
        the drive reports the target reached (statusword bit 10, set-point acknowledge 0).

        Raises :class:`DriveStateError` when the motion ended meanwhile (dead-man, stop) or
        the target is not reached within ``timeout`` seconds; with ``must_reach`` False it
        returns the position then instead (a drive tuning itself may hunt around the target
        for a while: the next move must still come).
        """
        axis = self._axis(sid)
        self._still_tuning(axis, motion)
        lim = await self.limits(sid)
        self._check_position(float(target), lim, "target")
        plan: list[tuple[ObjectAddress, Value]] = []
        if velocity is not None:
            plan.append((PROFILE_VELOCITY, velocity))
        if acceleration is not None:
            plan.append((PROFILE_ACC, acceleration))
        if deceleration is not None:
            plan.append((PROFILE_DEC, deceleration))
        plan.append((TARGET_POSITION, target))
        writes = self._encode(axis, plan)
        bits = CW_ENABLE | CW_IMMEDIATE
        who = motion.owner
        async with self._starting(axis) as epoch:
            self._still_tuning(axis, motion)
            await self._write_all(axis, writes, who)
            await self._controlword(axis, bits, who)
            await self._go(axis, epoch, bits | CW_NEW_SETPOINT, who)
            acked = await self._wait_bits(axis, SW_SETPOINT_ACK, True, 0.3)
            await self._controlword(axis, bits, who)
            if not acked:
                raise DriveStateError(
                    "the drive did not acknowledge the set-point (statusword bit 12)",
                    hint="check the drive's error code and the mode of operation",
                )
        axis.last_target = float(target)
        motion.target = float(target)
        end = time.monotonic() + timeout
        while True:
            self._still_tuning(axis, motion)
            sw = await self._statusword(axis)
            if sw & SW_TARGET_REACHED and not sw & SW_SETPOINT_ACK:
                return await self._read_int(axis.session, POSITION) or 0
            if time.monotonic() > end:
                if not must_reach:
                    return await self._read_int(axis.session, POSITION) or 0
                raise DriveStateError(
                    f"the axis did not reach {target} within {timeout:g} s",
                    hint="check the drive's speed, ramps and torque limit",
                )
            await asyncio.sleep(0.01)

    async def end_tuning_motion(self, sid: str, motion: Motion, state: str, message: str) -> None:
        """End a tuning motion that finished its moves (the axis stands; nothing is sent)."""
        axis = self._axis(sid)
        self._end(axis, motion, state, message)

    @staticmethod
    def _still_tuning(axis: _Axis, motion: Motion) -> None:
        if axis.motion is not motion or not motion.active:
            raise DriveStateError(
                f"the tuning motion ended ({motion.state}: {motion.message})",
                hint="start the tuning again once the cause is cleared",
            )

    # Stopping -----------------------------------------------------------------------------

    async def halt(self, sid: str, client: str | None) -> dict[str, Any]:
        """Halt (controlword bit 8): any client, always; the axis stays enabled."""
        axis = self._axis(sid)
        sent = await self._stop_axis(
            axis, quick=False, state="halted", message="halted", who=client or "unknown"
        )
        if not sent:
            st = axis.motion
            if st is None or not st.active:
                axis.motion = Motion("halt", client or "", 0, None, time.monotonic(), False)
                axis.motion.state = "idle"
                axis.motion.message = (
                    "not in Operation enabled: nothing to halt (the halt bit is only sent "
                    "there, where it cannot enable the drive)"
                )
        return self.status(sid)

    async def stop(self, sid: str, client: str | None) -> dict[str, Any]:
        """Quick stop: any client, always."""
        axis = self._axis(sid)
        await self._stop_axis(
            axis,
            quick=True,
            state="stopped",
            message="quick stop",
            halt=False,
            who=client or "unknown",
        )
        return self.status(sid)

    async def _send_halt(self, axis: _Axis, who: str) -> bool:
        """Controlword bit 8, only in Operation enabled (elsewhere 0x010F could enable)."""
        sw = await self._statusword(axis)
        if cia402.decode_state(sw) is not cia402.State.OPERATION_ENABLED:
            return False
        await self._controlword(axis, CW_ENABLE | CW_HALT, who)
        return True

    async def _stop_axis(
        self,
        axis: _Axis,
        *,
        quick: bool,
        state: str,
        message: str,
        halt: bool = True,
        who: str = "servodesk",
    ) -> bool:
        """End the motion and stop the axis: halt, then quick stop when asked."""
        axis.epoch += 1
        motion = axis.motion
        if motion is not None and motion.active:
            self._end(axis, motion, state, message)
        elif motion is not None:
            motion.state, motion.message = state, message
        sent = False
        s = axis.session
        try:
            if halt:
                sent = await self._send_halt(axis, who)
            if quick:
                await s.command("quick_stop")
                sent = True
        finally:
            # A start that was already past its checks may have sent its "go" after us.
            async with axis.lock:
                if axis.rehalt:
                    axis.rehalt = False
                    if halt:
                        await self._send_halt(axis, who)
                    if quick:
                        await s.command("quick_stop")
        self._publish(axis)
        return sent

    async def _lost_operator(
        self,
        axis: _Axis,
        motion: Motion,
        reason: str,
        since: float,
        *,
        frame_at: float | None = None,
    ) -> None:
        """Dead-man: halt, then quick stop; report the latency from ``since``.

        ``frame_at``: when the dead-man's thread already put a quick stop on the wire
        (monotonic); the halt is then skipped by itself (the drive left Operation enabled)."""
        try:
            t0 = time.monotonic()
            axis.epoch += 1
            self._end(axis, motion, "deadman", reason)
            halted = await self._send_halt(axis, f"dead-man of {motion.owner}")
            t_halt = time.monotonic()
            await axis.session.command("quick_stop")
            t_stop = time.monotonic()
            async with axis.lock:
                if axis.rehalt:
                    axis.rehalt = False
                    await axis.session.command("quick_stop")
        except ServodeskError as exc:
            log.error("dead-man stop of %s failed: %s", axis.sid, exc.message)
            self.hub.publish(
                {
                    "type": "deadman",
                    "session": axis.sid,
                    "reason": reason,
                    "latency_ms": None,
                    "message": f"the stop could not be sent: {exc.message}",
                },
                session=axis.sid,
            )
            return
        first = t_halt if halted else t_stop
        if frame_at is not None:
            first = min(first, frame_at)
        msg = {
            "type": "deadman",
            "session": axis.sid,
            "reason": reason,
            "client": motion.owner,
            "latency_ms": round((first - since) * 1000.0, 1),
            "detect_ms": round((t0 - since) * 1000.0, 1),
            "quick_stop_ms": round((t_stop - since) * 1000.0, 1),
            "stop_frame_ms": None if frame_at is None else round((frame_at - since) * 1000.0, 1),
            "from": "dead-man thread" if frame_at is not None else "event loop",
        }
        log.warning("dead-man on %s: %s (%s ms)", axis.sid, reason, msg["latency_ms"])
        self.hub.publish(msg, session=axis.sid)

    async def _monitor(self, axis: _Axis, motion: Motion) -> None:
        """Ends a move at its target, a homing run at its end, and any motion when the drive
        leaves Operation enabled; halts continuous motion before a software position limit."""
        guard = motion.guard
        if motion.kind == "move":
            period = 0.02
        elif guard is not None:
            period = LIMIT_GUARD_PERIOD
        else:
            period = 0.05
        s = axis.session
        failures = 0
        last: tuple[float, int] | None = None
        seen_running = False
        settled_since: float | None = None
        while motion.active:
            await asyncio.sleep(period)
            try:
                sw = await self._statusword(axis)
                pos = await self._read_int(s, POSITION) if guard is not None else None
                now = time.monotonic()
                vel = await self._read_int(s, VELOCITY) if motion.read_velocity else None
                mode = await self._read_int(s, MODE_DISPLAY) if motion.kind == "homing" else None
            except LinkError as exc:
                failures += 1
                if failures >= 3:
                    self._end(axis, motion, "error", f"the drive does not answer: {exc.message}")
                    return
                continue
            except ServodeskError:
                continue
            failures = 0
            state = cia402.decode_state(sw)
            if state is not cia402.State.OPERATION_ENABLED:
                self._end(
                    axis, motion, "error", f"the drive left Operation enabled ({state.value})"
                )
                return
            if motion.kind == "move" and sw & SW_TARGET_REACHED and not sw & SW_SETPOINT_ACK:
                pos = await self._read_int(s, POSITION)
                self._end(axis, motion, "reached", f"target reached at {pos}")
                return
            if motion.kind == "homing":
                run = homing.current_run(s)
                if run is not None and run.timed_out(now):
                    # The run's time-out (the user's, or from the estimate): stop it as the
                    # dead-man does, halt (bit 4 low interrupts homing, CiA 402-2 §6.8.1)
                    # then quick stop, and say so.
                    late = run.timeout_message(now)
                    log.warning("homing on %s: %s", axis.sid, late)
                    await self._stop_for(
                        axis, motion, late, quick=True, state="timeout", who="homing time-out"
                    )
                    return
                hs = homing.decode(sw, mode)
                if hs == "running":
                    seen_running, settled_since = True, None
                    continue
                settled_since = settled_since if settled_since is not None else now
                if not seen_running and now - settled_since < HOMING_SETTLE_S:
                    continue
                where: int | None = None
                with contextlib.suppress(ServodeskError):
                    where = await self._read_int(s, POSITION)
                if hs == "attained":
                    self._end(axis, motion, "done", f"homing attained at {where}")
                elif hs == "error":
                    self._end(axis, motion, "error", f"homing error at {where} (bit 13)")
                else:
                    self._end(axis, motion, "halted", f"homing interrupted at {where}")
                return
            if guard is not None and pos is not None:
                why = _limit_ahead(motion, guard, pos, vel, last, now)
                last = (now, pos)
                if why is not None and axis.motion is motion and motion.active:
                    log.warning("%s on %s: %s", motion.kind, axis.sid, why)
                    await self._stop_for(
                        axis,
                        motion,
                        why,
                        quick=False,
                        state="halted",
                        who="software position limit",
                    )
                    return

    async def _stop_for(
        self, axis: _Axis, motion: Motion, why: str, *, quick: bool, state: str, who: str
    ) -> None:
        """The monitor stops the axis itself (halt, and quick stop when asked) for ``why``;
        a stop that cannot be sent ends the motion in error saying so."""
        try:
            await self._stop_axis(
                axis, quick=quick, state=state, message=why, who=f"servodesk ({who})"
            )
        except ServodeskError as exc:
            what = "stop" if quick else "halt"
            self._end(axis, motion, "error", f"{why}; the {what} failed: {exc.message}")

    # Clients and lifecycle ----------------------------------------------------------------

    def _spawn(self, coro: Any) -> None:
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        task: asyncio.Task[None] = loop.create_task(coro)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    def _control_bound(self, sid: str) -> None:
        """The holder's dead-man is on: arm the drive's own watchdog too (a dead PC)."""
        self._spawn(self._arm_watchdog(sid))

    async def _arm_watchdog(self, sid: str) -> None:
        try:
            session = self.manager.get(sid)
            await session.link.arm_watchdog()
        except ServodeskError as exc:
            log.warning("%s: the drive's watchdog was not armed: %s", sid, exc.message)
        self._publish_protection(sid)

    async def _disarm_watchdog(self, sid: str) -> None:
        try:
            session = self.manager.get(sid)
        except ServodeskError:
            return
        if session.link.watchdog is None:
            return
        try:
            await session.link.disarm_watchdog()
        except ServodeskError as exc:
            log.warning("%s: the drive's watchdog was not disarmed: %s", sid, exc.message)
        self._publish_protection(sid)

    def _publish_protection(self, sid: str) -> None:
        with contextlib.suppress(ServodeskError):
            self.hub.publish({"type": "protection", "session": sid, **self.protection(sid)})

    def _control_lost(self, sid: str, client: str, reason: str) -> None:
        """The holder is gone or changed (services/control): make the drive safe."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        task = loop.create_task(self.make_safe(sid, client, reason))
        self._background.add(task)
        task.add_done_callback(self._background.discard)
        self._safing[sid] = task

    async def settled(self, sid: str) -> None:
        """Wait until making the drive safe after a lost holder is done: a servo on or a
        motion of the next holder must not be undone by it a moment later."""
        task = self._safing.get(sid)
        if task is not None and not task.done():
            with contextlib.suppress(Exception):
                await asyncio.wait_for(asyncio.shield(task), SAFE_STOP_S + 2.0)

    async def make_safe(self, sid: str, client: str, reason: str) -> str | None:
        """Stop the axis and bring the drive to Switch on disabled; the state it ended in.

        The motion (if any) ends as the dead-man ends it: halt, then quick stop. The power
        stage is switched off only at standstill (or once the drive left Operation enabled
        by itself): disable voltage while the axis still brakes would let it coast (CiA 402-2
        §6.2, transition 12 from Quick stop active, 9 from Operation enabled). A drive that
        was never enabled is left alone. Nobody is in control meanwhile, so nothing the user
        asks can race it; a new holder's start waits for the axis lock.
        """
        since = time.monotonic()
        try:
            session = self.manager.get(sid)
        except ServodeskError:
            return None  # The session closed meanwhile: its close stopped the motion.
        axis = self._axis(sid)
        m = axis.motion
        moving = m is not None and m.active
        if m is not None and m.active:
            await self._lost_operator(axis, m, reason, since)
        try:
            state = cia402.decode_state(await self._statusword(axis))
            acted = moving or state in _ENERGISED
            if state in _ENERGISED:
                if state is cia402.State.OPERATION_ENABLED and not await self._standstill(axis):
                    await session.command("quick_stop")
                end = time.monotonic() + SAFE_STOP_S
                while not await self._standstill(axis):
                    if time.monotonic() > end:
                        break
                    await asyncio.sleep(0.02)  # Polling the drive: no event to wait on.
                await session.command("disable")
            final = cia402.decode_state(await self._statusword(axis))
        except ServodeskError as exc:
            log.error("making %s safe failed: %s", sid, exc.message)
            # To every client, not only the session's watchers: it is about control, which
            # every tab shows, and the holder's own tab may have closed.
            self.hub.publish(
                {
                    "type": "safe_state",
                    "session": sid,
                    "reason": reason,
                    "client": client,
                    "ok": False,
                    "message": f"the drive could not be disabled: {exc.message}",
                }
            )
            return None
        if self.control.owner(sid) is None or not self.control.info(sid, None)["bound"]:
            # Nobody's dead-man is on any more: the drive's own watchdog goes back too.
            await self._disarm_watchdog(sid)
        if acted:
            log.warning("%s: %s; the drive is now %s", sid, reason, final.value)
            # To every client, not only the session's watchers: it is about control, which
            # every tab shows, and the holder's own tab may have closed.
            self.hub.publish(
                {
                    "type": "safe_state",
                    "session": sid,
                    "reason": reason,
                    "client": client,
                    "ok": final is cia402.State.SWITCH_ON_DISABLED,
                    "state": final.value,
                    "message": f"{reason}: the axis was stopped and the drive disabled "
                    f"({final.value})",
                }
            )
        return final.value

    async def stop_session(self, sid: str, reason: str) -> None:
        """The session is about to close: stop its motion first."""
        await self._disarm_watchdog(sid)
        axis = self._axes.get(sid)
        if axis is None:
            return
        m = axis.motion
        if m is not None and m.active:
            with contextlib.suppress(ServodeskError):
                await self._stop_axis(axis, quick=True, state="stopped", message=reason)
        self._axes.pop(sid, None)

    async def shutdown(self) -> None:
        """Backend shutdown: every running motion is halted and quick-stopped."""
        for axis in list(self._axes.values()):
            m = axis.motion
            if m is not None and m.active:
                try:
                    await self._lost_operator(axis, m, "the server shuts down", time.monotonic())
                except ServodeskError:
                    log.exception("stopping %s at shutdown", axis.sid)
        for session in self.manager.all():
            await self._disarm_watchdog(session.id)
        # Stops already under way (a socket that just closed) finish; nothing else runs on.
        if self._background:
            await asyncio.wait(list(self._background), timeout=2.0)
        for axis in self._axes.values():
            if axis.motion is not None:
                self._cancel_tasks(axis.motion)
        self._deadman.close()

    # Status -------------------------------------------------------------------------------

    def protection(self, sid: str) -> dict[str, Any]:
        """What stops this drive when its operator is lost, as the Operation page shows it."""
        session = self.manager.get(sid)
        thread = thread_stop(session) is not None
        ms = round(self.deadman_s * 1000)
        path = "dead-man thread" if thread else "event loop"
        where = (
            f"servodesk's own thread sends the quick stop on the {session.link.fieldbus} link"
            if thread
            else f"the quick stop goes out through the event loop ({session.link.fieldbus} "
            "has no path beside it yet)"
        )
        return {
            "deadman_ms": ms,
            "stop_path": path,
            "drive_watchdog": session.link.watchdog,
            "summary": f"Heartbeats older than {ms} ms stop the axis: {where}. "
            + (
                f"If this PC dies: {session.link.watchdog}."
                if session.link.watchdog
                else "No drive-side watchdog is armed: if this PC dies, the drive's own "
                "communication settings decide."
            ),
        }

    def status(self, sid: str) -> dict[str, Any]:
        axis = self._axes.get(sid)
        if axis is None:
            self.manager.get(sid)  # 404 for an unknown session.
        m = axis.motion if axis is not None else None
        if m is None:
            return {
                "session": sid,
                "active": False,
                "kind": None,
                "owner": None,
                "mode": None,
                "target": None,
                "state": "idle",
                "message": "",
            }
        return {
            "session": sid,
            "active": m.active,
            "kind": m.kind if m.kind != "halt" else None,
            "owner": m.owner or None,
            "mode": m.mode or None,
            "target": m.target,
            "state": m.state,
            "message": m.message,
        }

    def _publish(self, axis: _Axis) -> None:
        self.hub.publish({"type": "motion", **self.status(axis.sid)}, session=axis.sid)


def _per_s2(raw_unit: str | None) -> bool:
    """True when a ramp object's raw unit is position units per s² (domain/ramps.py); with a
    time or a register the stopping distance is estimated with ``FALLBACK_STOP_S``."""
    return ramp_kind(raw_unit) == "rate"


def _per_s(raw_unit: str | None) -> bool:
    """True when a velocity object's raw unit is position units per second."""
    if raw_unit is None:
        return True
    unit = raw_unit.replace(" ", "")
    return ("/s" in unit) and not _per_s2(raw_unit)


def _limit_ahead(
    motion: Motion,
    lim: Limits,
    pos: int,
    vel: int | None,
    last: tuple[float, int] | None,
    now: float,
) -> str | None:
    """Why continuous motion must halt now to stop before a software limit (None: it need not).

    The velocity is 606Ch when it is in position units per second, else the difference of
    two position samples. The stopping distance is what the axis covers until the next sample
    and the halt take effect, plus the braking distance at the halt deceleration
    (``FALLBACK_STOP_S`` of braking when that deceleration is not known in position units).
    """
    lo, hi = lim.position_min, lim.position_max
    if vel is not None:
        v = float(vel)
    elif last is not None and now > last[0]:
        v = (pos - last[1]) / (now - last[0])
    else:
        v = 0.0
    direction = v if v != 0 else (motion.target or 0.0)
    # Until the next sample and the halt reach the drive: three periods, more when the last
    # samples came late (a busy event loop), since the next one may come as late.
    interval = now - last[0] if last is not None else LIMIT_GUARD_PERIOD
    lead = max(3 * LIMIT_GUARD_PERIOD, 1.5 * interval + LIMIT_GUARD_PERIOD)
    speed = abs(v) + (motion.acceleration or 0.0) * lead
    if motion.speed_cap is not None:
        # Still accelerating: not beyond the commanded speed (nor below the measured one).
        speed = max(abs(v), min(speed, motion.speed_cap))
    if motion.halt_decel:
        braking = speed * speed / (2.0 * motion.halt_decel)
    else:
        braking = speed * FALLBACK_STOP_S / 2.0
    distance = speed * lead + braking
    if direction > 0 and hi is not None and pos + distance >= hi:
        which, value, src = "max", hi, lim.sources.get("position_max", "607Dh:02")
    elif direction < 0 and lo is not None and pos - distance <= lo:
        which, value, src = "min", lo, lim.sources.get("position_min", "607Dh:01")
    else:
        return None
    return (
        f"halted at {pos} before the software position limit {which} {value} ({src}): "
        f"at {abs(v):.0f}/s the axis needs about {distance:.0f} to stop"
    )
