"""Homing: the family's methods, starting a homing run and following it (CiA 402-2 §6.8).

The method list comes from the profile (``homing_methods``) described by the shared CiA 402
table (:mod:`servodesk.domain.homing`) and, for vendor methods, by the profile's
``homing_method_equivalent`` quirk. A run is started the same way on every family: mode 6,
the homing parameters (6098h, 6099h:01/02, 609Ah, 607Ch), then a rising edge of controlword
bit 4. Progress is decoded from statusword bits 13/12/10 (the table is the same in CiA 402-2
§6.8.1, 000 §3.2.4 table 3.2.4.3, 003 §4-4-3 and 004 §20.6.6) and sent as WebSocket ``homing``
messages from the session's state poll.

Every run started through servodesk is a :class:`HomingRun`: its plan (the travel, the speeds in
position units, the estimated duration and the time-out, :mod:`servodesk.domain.homing`), the
time it has run and how it ended. A run that moves the axis is a motion (services/motion/):
the motion's end (attained, error, halted, quick stop, dead-man, loss of control, time-out)
ends the run and is published as the last ``homing`` message, so that the panel never stays on
"running" after the axis stopped. The statusword cannot tell that on every family: after a
cancelled run the CTMM04x clears bits 13, 12 and 10 alike (003 §4-4-7, "ホーミングモード
キャンセル"), which CiA 402-2 §6.8.1 reads as "in progress".

Over 700 lines: the plan, the run and its tracker are one state machine of CiA 402-2 §6.8
(statusword bits 13/12/10 against the motion's end); the tables are already in domain/homing.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import time
import weakref
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any, Literal

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CONTROLWORD,
    CW_ENABLE,
    CW_HALT,
    HOME_OFFSET,
    HOMING_ACC,
    HOMING_METHOD,
    HOMING_SPEED_SWITCH,
    HOMING_SPEED_ZERO,
    MAX_PROFILE_VELOCITY,
    MODE,
    MODE_DISPLAY,
    POSITION,
    STATUSWORD,
    SW_HOMING_ATTAINED,
    SW_HOMING_ERROR,
    SW_TARGET_REACHED,
    Mode,
)
from servodesk.domain.datatypes import coerce_int
from servodesk.domain.homing import (
    CW_HOMING_START,
    MAX_TIMEOUT_S,
    SLOW_PHASE_S,
    HomingEstimate,
    HomingGeometry,
    default_timeout,
    estimate_duration,
    format_seconds,
    phase_from_statusword,
    register_acceleration,
    resolve_method,
    speed_multiplier,
    twin_geometry,
)
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.ramps import ramp_kind
from servodesk.errors import DriveStateError, ServodeskError, ValidationError
from servodesk.services.session import DriveState, Session

log = logging.getLogger(__name__)

HOMING_MODE = int(Mode.HOMING)


def methods(profile: DeviceProfile) -> list[dict[str, Any]]:
    """``HomingMethod`` entries for the family's documented methods, in the profile's order."""
    spec = profile.spec(HOMING_METHOD)
    texts = spec.values if spec is not None and spec.values else {}
    equiv = profile.quirk("homing_method_equivalent")
    out: list[dict[str, Any]] = []
    for m in profile.homing_methods:
        info = resolve_method(m, equiv)
        if info is None:
            out.append(
                {
                    "method": m,
                    "name": texts.get(m, f"Vendor method {m}"),
                    "description": (
                        "Documented by the family but not described well enough to simulate; "
                        "the simulated drive refuses it."
                    ),
                    "uses": [],
                    "direction": None,
                    "section": spec.section if spec is not None else None,
                    "equivalent": None,
                    "needs_enable": True,
                }
            )
            continue
        section = info.section
        if not info.vendor and spec is not None and spec.section:
            section = f"{info.section}; {spec.section}"
        out.append(
            {
                "method": m,
                "name": info.name,
                "description": info.description,
                "uses": list(info.uses),
                "direction": info.direction_name,
                "section": section,
                "equivalent": info.equivalent,
                "needs_enable": m not in _no_enable(profile),
            }
        )
    return out


def _check_method(profile: DeviceProfile, method: int) -> None:
    if method not in profile.homing_methods:
        raise ValidationError(
            f"homing method {method} is not documented for {profile.name}",
            field="method",
            hint=f"use one of {list(profile.homing_methods)} (GET .../homing/methods)",
        )


def _no_enable(profile: DeviceProfile) -> frozenset[int]:
    return frozenset(coerce_int(m) for m in profile.quirk("homing_without_enable", None) or ())


def decode(statusword: int, mode: int | None) -> str:
    """idle / running / attained / error from statusword bits 13/12/10 in homing mode."""
    if mode != HOMING_MODE:
        return "idle"
    if statusword & SW_HOMING_ERROR:
        return "error"
    attained = bool(statusword & SW_HOMING_ATTAINED)
    reached = bool(statusword & SW_TARGET_REACHED)
    if attained and reached:
        return "attained"
    if reached:
        return "idle"  # Interrupted or not started.
    return "running"


def _bits(statusword: int) -> dict[str, bool]:
    return {
        "target_reached": bool(statusword & SW_TARGET_REACHED),
        "homing_attained": bool(statusword & SW_HOMING_ATTAINED),
        "homing_error": bool(statusword & SW_HOMING_ERROR),
    }


_MESSAGES = {
    "idle": "homing not started or interrupted",
    "running": "homing in progress",
    "attained": "homing attained: the position is the home offset (607Ch)",
    "error": "homing error: a required switch was not found or a limit was reached",
}

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1

#: How a run ended; "running" while it lasts.
Outcome = Literal[
    "running",
    "attained",
    "error",
    "halted",
    "stopped",
    "deadman",
    "control_lost",
    "timeout",
    "interrupted",
]

#: The motion's end state (services/motion/ ``Motion.state``) as the run's outcome.
_OUTCOME_OF_MOTION: dict[str, Outcome] = {
    "done": "attained",
    "reached": "attained",
    "error": "error",
    "halted": "halted",
    "stopped": "stopped",
    "deadman": "deadman",
    "timeout": "timeout",
    "replaced": "interrupted",
}


@dataclass(frozen=True, slots=True)
class HomingPlan:
    """What a run is expected to take, decided before it starts (nothing moves yet)."""

    method: int
    estimate: HomingEstimate | None
    #: Where the travel came from, or why there is no estimate.
    basis: str
    travel: float | None
    #: 6099h:01, 6099h:02 in position units per s and 609Ah in position units per s² (None:
    #: not known in those units).
    speed_switch: float | None
    speed_zero: float | None
    acceleration: float | None
    timeout_s: float
    timeout_source: Literal["user", "estimate", "default"]
    warnings: tuple[str, ...] = ()

    def summary(self) -> str:
        """The motion's message while the run lasts (services/motion/)."""
        est = self.estimate
        up_to = f", up to {format_seconds(est.seconds)}" if est is not None else ""
        return f"homing method {self.method}{up_to}, time-out {format_seconds(self.timeout_s)}"

    def as_dict(self) -> dict[str, Any]:
        return {
            "estimate_s": round(self.estimate.seconds, 3) if self.estimate else None,
            "estimate": self.estimate.as_dict() if self.estimate else None,
            "basis": self.basis,
            "travel": self.travel,
            "speed_switch": self.speed_switch,
            "speed_zero": self.speed_zero,
            "acceleration": self.acceleration,
            "timeout_s": self.timeout_s,
            "timeout_source": self.timeout_source,
            "warnings": list(self.warnings),
        }


_run_ids = itertools.count(1)


@dataclass(eq=False)
class HomingRun:
    """One homing run started through servodesk, from its start to its end."""

    #: Weak: the session keeps its last run (``_RUNS``), not the other way round.
    session_ref: weakref.ref[Session] = field(repr=False)
    method: int
    plan: HomingPlan
    #: time.monotonic() and time.time() at the start.
    started: float
    started_at: float
    id: int = field(default_factory=lambda: next(_run_ids))
    #: Under the client's dead-man as a motion (services/motion/); False: the drive was not
    #: enabled, nothing moves (quirk ``homing_without_enable``).
    watched: bool = False
    outcome: Outcome = "running"
    message: str = ""
    ended: float | None = None
    #: What statusword bits 13/12/10 said last (CiA 402-2 §6.8.1).
    phase: str | None = None

    @property
    def session(self) -> Session | None:
        return self.session_ref()

    @property
    def active(self) -> bool:
        return self.outcome == "running"

    def elapsed(self, now: float | None = None) -> float:
        end = self.ended if self.ended is not None else (now or time.monotonic())
        return max(0.0, end - self.started)

    def timed_out(self, now: float | None = None) -> bool:
        return self.active and self.elapsed(now) >= self.plan.timeout_s

    def timeout_message(self, now: float | None = None) -> str:
        return (
            f"homing timed out after {self.elapsed(now):.0f} s (time-out "
            f"{format_seconds(self.plan.timeout_s)}): halted, then quick-stopped"
        )

    def as_dict(self, now: float | None = None) -> dict[str, Any]:
        return {
            "id": self.id,
            "method": self.method,
            "active": self.active,
            "outcome": self.outcome,
            "message": self.message,
            "watched": self.watched,
            "started_at": self.started_at,
            "elapsed_s": round(self.elapsed(now), 3),
            "phase": self.phase,
            **self.plan.as_dict(),
        }


#: The last run of each session (a closed session's run goes with it).
_RUNS: weakref.WeakKeyDictionary[Session, HomingRun] = weakref.WeakKeyDictionary()


def current_run(session: Session) -> HomingRun | None:
    """The session's last run started through servodesk (running or ended), if any."""
    return _RUNS.get(session)


def _status_dict(
    session: Session,
    run: HomingRun | None,
    statusword: int,
    mode: int | None,
    position: int | None,
    method: int | None,
) -> dict[str, Any]:
    """``HomingStatus``: the statusword's word on the run, and the run's own."""
    state = decode(statusword, mode)
    message = _MESSAGES[state]
    if run is not None and not run.active:
        # The run is over whatever the bits say (the CTMM04x clears 13/12/10 on a cancel,
        # 003 §4-4-7, which reads as "in progress").
        if state == "running":
            state = "idle"
        message = run.message or message
    elif run is not None and state == "running":
        est = run.plan.estimate
        of = f" of up to {format_seconds(est.seconds)}" if est is not None else ""
        message = (
            f"homing in progress: {format_seconds(run.elapsed())}{of}, time-out "
            f"{format_seconds(run.plan.timeout_s)}"
        )
    return {
        "session": session.id,
        "method": method,
        "state": state,
        "position": position,
        "statusword_bits": _bits(statusword),
        "message": message,
        "run": run.as_dict() if run is not None else None,
    }


def _publish(run: HomingRun, st: DriveState | None) -> None:
    session = run.session
    if session is None:
        return
    body = _status_dict(
        session,
        run,
        st.statusword if st is not None else 0,
        st.mode if st is not None else None,
        st.position if st is not None else None,
        run.method,
    )
    session.hub.publish({"type": "homing", **body}, session=session.id)


def finish(run: HomingRun, outcome: Outcome, message: str) -> None:
    """End the run (once) and publish its end; a run that is no longer the session's
    current one (a new run replaced it) ends quietly, so its end cannot hide the new one."""
    if not run.active:
        return
    run.outcome = outcome
    run.message = message
    run.ended = time.monotonic()
    session = run.session
    if session is None:
        return
    _stop_trackers(session, run)
    log.info("homing on %s ended: %s (%s)", session.id, outcome, message)
    if _RUNS.get(session) is run:
        _publish(run, session.last_state)


def end_with_motion(run: HomingRun, state: str, message: str, *, control_lost: bool) -> None:
    """The motion of a watched run ended (services/motion/ ``Motion.on_end``)."""
    outcome: Outcome = _OUTCOME_OF_MOTION.get(state, "interrupted")
    if control_lost and outcome in ("halted", "deadman"):
        # Stopped because control moved or was released (services/control.py), which the
        # motion reports as a halt or as the dead-man's stop.
        outcome = "control_lost"
    finish(run, outcome, message)


class _Tracker:
    """Sends ``homing`` WebSocket messages from the session's state poll while a run lasts:
    elapsed time and the phase statusword bits 13/12/10 tell. A watched run ends with its
    motion (:func:`end_with_motion`); an unwatched one (nothing moves) on the statusword, or
    at its time-out."""

    def __init__(self, session: Session, run: HomingRun) -> None:
        self.session = session
        self.run = run
        self.method = run.method
        self.last: str | None = None
        self.seen_running = False

    def __call__(self, st: DriveState) -> None:
        run = self.run
        state = decode(st.statusword, st.mode)
        if st.mode == HOMING_MODE:
            run.phase = phase_from_statusword(st.statusword)
        if state == "running":
            self.seen_running = True
        if state != self.last or state == "running":
            _publish(run, st)
        self.last = state
        if run.watched:
            return
        if state == "attained":
            finish(run, "attained", f"homing attained at {st.position}")
        elif state == "error":
            finish(run, "error", f"homing error at {st.position} (bit 13)")
        elif state == "idle" and self.seen_running:
            finish(run, "interrupted", f"homing interrupted at {st.position}")
        elif run.timed_out():
            message = run.timeout_message()
            finish(run, "timeout", message)
            _spawn_stop(self.session, message)

    def stop(self) -> None:
        if self in self.session.state_listeners:
            self.session.state_listeners.remove(self)


_background: set[asyncio.Task[None]] = set()


def _spawn_stop(session: Session, why: str) -> None:
    """Halt, then quick-stop a run nobody watches (``start`` from a script) at its time-out."""

    async def stop() -> None:
        try:
            sw = await _read_int(session, STATUSWORD) or 0
            if cia402.decode_state(sw) is cia402.State.OPERATION_ENABLED:
                await session.write_object(CONTROLWORD, CW_ENABLE | CW_HALT, client="servodesk")
                await session.command("quick_stop")
        except ServodeskError as exc:
            log.error("stopping the homing of %s (%s) failed: %s", session.id, why, exc.message)

    with contextlib.suppress(RuntimeError):  # No running loop: nothing to stop from.
        task = asyncio.get_running_loop().create_task(stop())
        _background.add(task)
        task.add_done_callback(_background.discard)


def _stop_trackers(session: Session, run: HomingRun | None = None) -> None:
    """Stop following the session's runs (only ``run``'s, when given)."""
    for cb in list(session.state_listeners):
        if isinstance(cb, _Tracker) and (run is None or cb.run is run):
            cb.stop()


async def _read_int(session: Session, address: ObjectAddress) -> int | None:
    if session.profile.spec(address) is None:
        return None
    value = (await session.read_object(address)).value
    return value if isinstance(value, int) else None


async def _try_read(session: Session, address: ObjectAddress) -> int | None:
    """An object the plan would like to know; None when the drive does not give it."""
    spec = session.profile.spec(address)
    if spec is None or not spec.access.readable:
        return None
    try:
        return await _read_int(session, address)
    except ServodeskError:
        return None


async def status(session: Session) -> dict[str, Any]:
    """``HomingStatus`` read from the drive, with the last run started through servodesk."""
    sw = await _read_int(session, STATUSWORD) or 0
    mode = await _read_int(session, MODE_DISPLAY)
    method = await _read_int(session, HOMING_METHOD)
    position = await _read_int(session, POSITION)
    return _status_dict(session, current_run(session), sw, mode, position, method)


# Plan: travel, speeds in position units, estimate and time-out -----------------------------


def _per_second(raw_unit: str | None) -> bool:
    """A speed object's raw unit is position units per second (pps, inc/s, ...)."""
    if raw_unit is None:
        return True
    unit = raw_unit.replace(" ", "").lower()
    return unit == "pps" or ("/s" in unit and ramp_kind(raw_unit) != "rate")


def _speed(session: Session, address: ObjectAddress, raw: int | None) -> float | None:
    """6099h:01/02 in position units per s: as it is when the object holds units per second;
    0.01 r/min (LECSN-T 004 §20.9.3.11(3)) on a twin, whose position is in encoder counts."""
    spec = session.profile.spec(address)
    if raw is None or spec is None:
        return None
    if _per_second(spec.raw_unit):
        return float(raw)
    if spec.unit in ("r/min", "rpm") and session.simulated:
        return raw * spec.scale / 60.0 * session.counts_per_rev
    return None


async def _acceleration(session: Session, raw: int | None) -> float | None:
    """609Ah in position units per s², where its unit allows: a rate as it is, a PMC842SR
    rate register from the CTMM04x formula (003 §5-3-1, quirk ``ramp_rate_registers``, with
    the speed multiplier 607Fh selects, table 5-3-1-2), a time constant to the rated speed
    (LECSN-T 004 §20.9.3.11(4)) only on a twin (the rated speed in counts is the twin's)."""
    spec = session.profile.spec(HOMING_ACC)
    if raw is None or spec is None or raw <= 0:
        return None
    kind = ramp_kind(spec.raw_unit)
    if kind == "rate":
        return float(raw)
    profile = session.profile
    if kind == "time":
        if not session.simulated:
            return None
        sim = profile.simulation
        rated = sim.rated_speed or sim.max_velocity
        return rated * (session.counts_per_rev / sim.counts_per_rev) / (raw * 0.001)
    regs = profile.quirk("ramp_rate_registers")
    if not isinstance(regs, dict) or coerce_int(regs.get("homing", 0)) != HOMING_ACC.index:
        return None
    table = profile.quirk("speed_multiplier")
    multiplier = 1
    if isinstance(table, dict):
        vmax = await _try_read(session, MAX_PROFILE_VELOCITY)
        multiplier = speed_multiplier(table.get("table"), vmax)
    return register_acceleration(float(regs.get("fclk_hz", 0)), raw, multiplier)


def _geometry(
    session: Session, max_travel: int | None, limits: tuple[int | None, int | None] | None
) -> HomingGeometry | None:
    """The travel the estimate assumes: the user's maximum travel, else the software position
    limits (607Dh, when both are set and narrower than the whole INTEGER32 range), else the
    twin's switch layout. The index spacing (one motor revolution in position units) and the
    home switch width are known on a twin only."""
    twin = (
        twin_geometry(
            session.profile.simulation, session.counts_per_rev, session.profile_counts_per_rev
        )
        if session.simulated
        else None
    )
    index = twin.index_spacing if twin is not None else None
    width = twin.switch_width if twin is not None else None
    if max_travel is not None:
        return HomingGeometry(float(max_travel), "your maximum travel", index, width)
    lo, hi = limits if limits is not None else (None, None)
    if lo is not None and hi is not None and hi > lo and (lo, hi) != (INT32_MIN, INT32_MAX):
        return HomingGeometry(
            float(hi - lo), f"the software position limits 607Dh ({lo} .. {hi})", index, width
        )
    return twin


async def plan(
    session: Session,
    method: int,
    *,
    speed_switch: int | None = None,
    speed_zero: int | None = None,
    acceleration: int | None = None,
    max_travel: int | None = None,
    timeout_s: float | None = None,
    limits: tuple[int | None, int | None] | None = None,
) -> HomingPlan:
    """The run's estimate and time-out, from the speeds it will use (the request's, else the
    drive's) and the travel (:func:`_geometry`). Reads the drive; writes nothing."""
    _check_method(session.profile, method)
    if timeout_s is not None and not 0 < timeout_s <= MAX_TIMEOUT_S:
        raise ValidationError(
            f"timeout_s {timeout_s:g} is outside 0 .. {MAX_TIMEOUT_S:g} s",
            field="timeout_s",
            hint="leave it out for the default from the estimate",
        )
    if max_travel is not None and max_travel <= 0:
        raise ValidationError(
            f"max_travel {max_travel} must be positive (position units)",
            field="max_travel",
            hint="the span the homing searches may cover, e.g. between the limit switches",
        )
    info = resolve_method(method, session.profile.quirk("homing_method_equivalent"))
    raw1 = (
        speed_switch if speed_switch is not None else await _try_read(session, HOMING_SPEED_SWITCH)
    )
    raw2 = speed_zero if speed_zero is not None else await _try_read(session, HOMING_SPEED_ZERO)
    raw_a = acceleration if acceleration is not None else await _try_read(session, HOMING_ACC)
    v1 = _speed(session, HOMING_SPEED_SWITCH, raw1)
    v2 = _speed(session, HOMING_SPEED_ZERO, raw2)
    acc = await _acceleration(session, raw_a)
    geometry = _geometry(session, max_travel, limits)
    estimate: HomingEstimate | None = None
    if info is None:
        basis = f"no estimate: method {method} is not described well enough"
    elif info.current_position:
        estimate = estimate_duration(info, HomingGeometry(0.0, "none"), 0.0, 0.0, None)
        basis = "no motion"
    elif v2 is None or (info.edge is not None and v1 is None):
        basis = "no estimate: the homing speeds (6099h) are not in position units per second"
    elif geometry is None:
        basis = (
            "no estimate: the travel is not known (give a maximum travel, or set the software "
            "position limits 607Dh)"
        )
    else:
        estimate = estimate_duration(info, geometry, v1 or 0.0, v2, acc)
        basis = f"travel {geometry.travel:.0f} from {geometry.travel_source}"
        if estimate is None:
            basis = "no estimate: a homing speed is 0, the run would never end"
    source: Literal["user", "estimate", "default"] = "user"
    if timeout_s is not None:
        timeout = float(timeout_s)
    else:
        timeout = default_timeout(estimate.seconds if estimate is not None else None)
        source = "estimate" if estimate is not None else "default"
    warnings: list[str] = []
    if estimate is not None:
        for ph in estimate.phases:
            if ph.seconds > SLOW_PHASE_S:
                warnings.append(
                    f"{ph.name}: {ph.distance:.0f} at {ph.speed:g}/s takes up to "
                    f"{format_seconds(ph.seconds)}; a higher {ph.speed_object} shortens it"
                )
        if timeout < estimate.seconds:
            warnings.append(
                f"the time-out ({format_seconds(timeout)}) is shorter than the estimate (up to "
                f"{format_seconds(estimate.seconds)}): the run may be stopped before it ends"
            )
    return HomingPlan(
        method=method,
        estimate=estimate,
        basis=basis,
        travel=geometry.travel if geometry is not None else None,
        speed_switch=v1,
        speed_zero=v2,
        acceleration=acc,
        timeout_s=timeout,
        timeout_source=source,
        warnings=tuple(warnings),
    )


#: Sends the controlword that starts the run (the motion service checks that no stop came).
StartSender = Callable[[int], Awaitable[None]]


async def begin(
    session: Session,
    method: int,
    *,
    speed_switch: int | None = None,
    speed_zero: int | None = None,
    acceleration: int | None = None,
    offset: int | None = None,
    client: str | None = None,
    set_mode: Callable[[], Awaitable[None]] | None = None,
    go: StartSender | None = None,
    plan_: HomingPlan | None = None,
    watched: bool = False,
) -> bool:
    """Write the homing parameters and start the run; True when the drive was enabled.

    ``set_mode`` sets 6060h = 6 (default: a plain write); the motion service passes its own,
    which follows the family's mode-change quirks. ``go`` sends the starting controlword
    (default: a plain write). ``plan_`` is the run's estimate and time-out (default: the
    default time-out, no estimate); the run is the session's :func:`current_run` from here.
    ``watched``: the run is a motion (services/motion/) whose end ends it
    (:func:`end_with_motion`); else the statusword and the time-out end it.
    """
    profile = session.profile
    _check_method(profile, method)
    sw = await _read_int(session, STATUSWORD) or 0
    state = cia402.decode_state(sw)
    enabled = state is cia402.State.OPERATION_ENABLED
    if not enabled and method not in _no_enable(profile):
        raise DriveStateError(
            f"homing method {method} needs Operation enabled; the drive is in {state.value}",
            hint='enable the drive first (POST .../state {"command": "enable"})',
        )
    writes: list[tuple[ObjectAddress, int | None, str]] = [
        (HOMING_SPEED_SWITCH, speed_switch, "speed_switch"),
        (HOMING_SPEED_ZERO, speed_zero, "speed_zero"),
        (HOMING_ACC, acceleration, "acceleration"),
        (HOME_OFFSET, offset, "offset"),
    ]
    for address, value, name in writes:
        if value is None:
            continue
        spec = profile.spec(address)
        if spec is None or not spec.access.writable:
            raise ValidationError(
                f"{name} cannot be set on {profile.name}: {address} is not writable",
                field=name,
                hint="leave it out to use the drive's value",
            )
    # Bit 4 low before the mode change, so the run starts on a clean rising edge; halt (bit 8)
    # low too, or the drive would not move (CiA 402-2 §6.8.1: halt interrupts homing).
    cw = await _read_int(session, CONTROLWORD) or (0x0F if enabled else 0)
    cw &= ~(CW_HOMING_START | CW_HALT)
    await session.write_object(CONTROLWORD, cw, client=client)
    if set_mode is not None:
        await set_mode()
    else:
        await session.write_object(MODE, HOMING_MODE, client=client)
    await session.write_object(HOMING_METHOD, method, client=client)
    for address, value, _name in writes:
        if value is not None:
            await session.write_object(address, value, client=client)
    if plan_ is None:
        plan_ = HomingPlan(
            method, None, "no estimate", None, None, None, None, default_timeout(None), "default"
        )
    previous = current_run(session)
    _stop_trackers(session)
    run = HomingRun(
        weakref.ref(session), method, plan_, time.monotonic(), time.time(), watched=watched
    )
    _RUNS[session] = run
    session.state_listeners.append(_Tracker(session, run))
    try:
        if go is not None:
            await go(cw | CW_HOMING_START)
        else:
            await session.write_object(CONTROLWORD, cw | CW_HOMING_START, client=client)
    except BaseException:
        # Not started (a stop came, or the write failed): the previous run stays the last one.
        _stop_trackers(session)
        if previous is not None:
            _RUNS[session] = previous
        else:
            _RUNS.pop(session, None)
        raise
    if previous is not None:
        finish(previous, "interrupted", "a new homing run started")  # Quietly: not current.
    return enabled


async def start(
    session: Session,
    method: int,
    *,
    speed_switch: int | None = None,
    speed_zero: int | None = None,
    acceleration: int | None = None,
    offset: int | None = None,
    client: str | None = None,
    max_travel: int | None = None,
    timeout_s: float | None = None,
) -> dict[str, Any]:
    """Start a run without a dead-man (scripts, tests); answers the status just after.

    The API starts homing through the motion service instead (MotionService.home), which
    puts a run that moves the axis under the client's dead-man like a jog. The time-out
    applies here too: the run is halted and quick-stopped when it runs out.
    """
    p = await plan(
        session,
        method,
        speed_switch=speed_switch,
        speed_zero=speed_zero,
        acceleration=acceleration,
        max_travel=max_travel,
        timeout_s=timeout_s,
    )
    await begin(
        session,
        method,
        speed_switch=speed_switch,
        speed_zero=speed_zero,
        acceleration=acceleration,
        offset=offset,
        client=client,
        plan_=p,
    )
    return await status(session)
