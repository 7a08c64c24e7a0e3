"""Tuning jobs of drive sessions (issue 8; docs/tuning.md "Service and API").

One job per session at a time, started by the client that holds control. What a job does
depends on the family (:func:`tuning_kind`):

- ``builtin`` (LECSN-T): the drive's own one-touch tuning (004 §20.8.7, P11600-P11604). The
  manual needs the motor turning under the master's command while it tunes, so servodesk moves
  the axis back and forth inside the travel window the user confirmed (profile position, under
  the client's dead-man: :meth:`MotionService.start_tuning_motion`), writes the response mode
  to P11600, follows P11601 (progress) until P11600 is 0 again, reads P11604 and decodes it
  with the profile's ``tuning`` error table. Before and after, a short step (a relative move
  recorded by the drive-side recorder, or polled over SDO where there is none) shows what the
  gains do; the gains PB06-PB10 are read before and after.
- ``gains`` (profiles with a gain map): servodesk's own tuning,
  :func:`servodesk.services.tuning_own.run_own_tuning`, under the same dead-man.
- ``none``: nothing to tune; :func:`tuning_kind` says why and what applies instead.

A stop, a missing heartbeat, the socket closing, losing control, a fault or a software limit
ends the tuning motion: the job then stops the drive's tuning (1EA5h to P11602), halts the
axis, puts the gains from before the run back and restores the torque limit. Undo (P11603 on
the builtin kind; the recorded values otherwise) and store (the session's store procedure) run
only when asked.

Choices where the manual leaves room (documented once):

- The travel window is a total width centred on the position where the axis stands when the
  job starts: the bound is start +- half of it, rounded down to whole position units
  (domain/tuning/travel.py), and the job, the page and the result say it in revolutions and in
  units side by side. servodesk's own tuning keeps every move's overshoot and a stop's run-out
  inside it and sets the drive's software limits 607Dh there (services/tuning_travel.py); the
  drive's one-touch tuning is commanded between the two ends, and what it overshoots past them
  is the drive's (the job's message says so). Position units per revolution come from 6064h's
  unit (``deg``: 360 / scale) or else the profile's simulation setting (``counts_per_rev``,
  608Fh's once the session read it), which the info names as the source: on a real drive the
  electronic gear decides.
- The back-and-forth runs at :data:`TUNING_SPEED_RPS` (600 r/min; MR-J4's one-touch tuning
  asks for at least 150 r/min [general product knowledge, unverified here]), lower where
  607Fh says so, converted to 6081h's unit (``r/min`` with its scale, else position units per
  s). Ramps given as times (LECSN-T ms) are the drive's own: servodesk does not guess the speed
  they refer to; ramps in position units per s² are set for :data:`RAMP_S` to full speed.
- The torque limit is written to 6072h for the run (never raising the drive's own value) and
  restored afterwards.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import itertools
import logging
import math
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    FOLLOWING_ERROR,
    MAX_TORQUE,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    TARGET_POSITION,
    TORQUE_ACTUAL,
)
from servodesk.domain.datatypes import DataType, Value, codec, coerce_int
from servodesk.domain.profile import DeviceProfile, ObjectSpec, RecorderSpec
from servodesk.domain.ramps import ramp_kind
from servodesk.domain.tuning.promise import mode_promise
from servodesk.domain.tuning.travel import TravelBound, bound_text, half_window
from servodesk.errors import (
    ConflictError,
    DriveStateError,
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.motion import Limits, Motion, MotionService
from servodesk.services.session import Session, error_info

log = logging.getLogger(__name__)

Kind = Literal["builtin", "gains", "none"]
ModeName = Literal["low", "basic", "high"]
MODES: tuple[ModeName, ...] = ("low", "basic", "high")
#: P11600 values of the response modes (004 §20.9.3.5(27)).
BUILTIN_MODE: dict[str, int] = {"basic": 1, "high": 2, "low": 3}
#: P11602: the stop command (004 §20.9.3.5(29)).
STOP_VALUE = 0x1EA5
#: P11603 values (004 §20.9.3.5(30)).
CLEAR_VALUE: dict[str, int] = {"before": 0x0001, "defaults": 0x0000}
#: The LECSN-T gain parameters one-touch tuning sets (004 §20.8.7; the twin's sim/onetouch.py).
BUILTIN_SYMBOLS = ("PB06", "PB07", "PB08", "PB09", "PB10")
BUILTIN_LABELS = {
    "PB06": "Load to motor inertia ratio",
    "PB07": "Model loop gain",
    "PB08": "Position loop gain",
    "PB09": "Speed loop gain",
    "PB10": "Speed integral compensation",
}

#: The safety inputs the UI and the CLI start from.
DEFAULTS: dict[str, Any] = {"mode": "basic", "travel_window_rev": 0.5, "torque_limit_pct": 100.0}
#: What the travel window means, per kind of tuning (GET .../tuning ``travel_rule``).
TRAVEL_RULE: dict[str, str] = {
    "gains": (
        "The travel window is the total width, centred on where the axis stands: the axis "
        "stays within ± half of it (rounded down to whole position units). servodesk sizes "
        "every move so that its overshoot and a stop's run-out stay inside, and sets the "
        "drive's software position limits (607Dh) there for the run where the drive has them."
    ),
    "builtin": (
        "The travel window is the total width, centred on where the axis stands: servodesk "
        "commands the axis between its two ends (± half of it, rounded down to whole position "
        "units). The drive tunes its own gains meanwhile, and how far it overshoots those ends "
        "is the drive's: keep room beyond them."
    ),
}
MAX_TRAVEL_REV = 100.0
MAX_TORQUE_PCT = 300.0
#: The peak torque of the machine's moves the own tuning ranks its gains for (% of rated): only
#: arithmetic on the model, never a limit of the drive, so it may exceed MAX_TORQUE_PCT.
MAX_MOVE_TORQUE_PCT = 1000.0
#: Speed of the back-and-forth motion of a builtin tuning [rev/s].
TUNING_SPEED_RPS = 10.0
#: Share of the drive's max profile velocity (607Fh) the tuning uses at most.
SPEED_SHARE = 0.8
#: Time to full speed where servodesk sets the ramps (position units per s² only) [s].
RAMP_S = 0.1
#: Pause at each end of the window [s] (the drive sees one move end before the next starts).
#: The shuttle's longest wait for target reached before the next move [s].
SHUTTLE_WAIT_S = 3.0
DWELL_S = 0.25
#: The step of the step response [rev], at most a quarter of the window.
STEP_REV = 0.05
#: Recording of the step response [s] and its sample rate [Hz].
STEP_RECORD_S = 0.5
STEP_RATE_HZ = 1000.0
#: The drive's one-touch tuning must end within this [s] (the twin gives up after 10 s idle).
BUILTIN_TIMEOUT_S = 180.0
POLL_S = 0.1
#: How long stop() waits for the job to wind down [s].
STOP_WAIT_S = 15.0


def _quirk_dict(profile: DeviceProfile, quirk: str) -> dict[str, Any] | None:
    q = profile.quirk(quirk)
    return q if isinstance(q, dict) else None


def tuning_kind(profile: DeviceProfile) -> tuple[Kind, str]:
    """How ``profile``'s family is tuned, and in plain words why (for ``none``: what applies).

    The profile's ``tuning:`` block decides where it exists; without one the family's quirks
    do (``one_touch_tuning``: built-in; otherwise nothing servodesk can tune).
    """
    spec = getattr(profile, "tuning", None)
    kind = getattr(spec, "kind", None) if spec is not None else None
    note = getattr(spec, "note", None) if spec is not None else None
    if kind == "builtin" or (kind is None and profile.quirk("one_touch_tuning") is not None):
        return "builtin", (
            f"The {profile.name} tunes itself: its one-touch tuning (004 §20.8.7, P11600-P11604) "
            "estimates the load to motor inertia ratio and sets the gains while the motor turns "
            "under the master's command. servodesk moves the axis back and forth inside the "
            "travel window you confirm, starts the drive's tuning, follows its progress and "
            "decodes its result."
        )
    if kind == "gains":
        return "gains", (
            f"servodesk tunes the {profile.name} itself through the profile's gain map: it "
            "identifies the axis, measures its frequency response, designs the gains and "
            "filters, and verifies them (docs/tuning.md)."
        )
    return "none", _none_reason(profile, note if kind == "none" else None)


def _none_reason(profile: DeviceProfile, note: str | None) -> str:
    if profile.quirk("no_tuning_gains"):
        return (
            f"Nothing to tune: the {profile.name} outputs pulse trains to external drives "
            "(003 §1), so it has no current, velocity or position loop and no gain to set. Tune "
            "each external drive with its own tool. What applies on this unit: the pulse output "
            "settings (pulse format, encoder, operation settings) and the speed and ramp "
            "settings, on the Parameters page."
        )
    text = (
        f"No documented gain map for servodesk's tuning: the {profile.name} profile does not "
        "say which objects hold the servo gains and in which units, so servodesk cannot tune it."
    )
    if note:
        text += f" {note}"
    q = _quirk_dict(profile, "tuning_gains")
    gain_objs = [
        spec
        for spec in profile.variables.values()
        if "gain" in spec.name.lower() and spec.access.writable
    ]
    if q:
        text += (
            f" What applies: its gain and filter objects ({', '.join(sorted(q.values()))}) are "
            "raw numbers without documented units; set them by hand on the Parameters page "
            "(group Tuning) and save them to non-volatile memory there."
        )
    elif gain_objs:
        names = ", ".join(f"{s.name} ({s.address})" for s in gain_objs[:3])
        text += (
            f" What applies: set its gain parameters by hand on the Parameters page ({names}; "
            "type, range and unit are in the drive's user manual), or use the drive "
            "maker's tuning tool."
        )
    else:
        text += " What applies: the drive maker's tuning tool, and the Parameters page."
    return text


def applies_instead(profile: DeviceProfile) -> list[dict[str, str]]:
    """For kind ``none``: the pages and parameter groups that apply instead (UI links).

    Only groups the Parameters page lists: those with a writable object that is not a process
    value (HIWIN's "Motor" holds read-only data, 3000h/3001h/6075h/6076h: a link to it opened
    another group, issue 48).
    """
    wanted = ("pulse_output", "velocity", "tuning", "pt_parameters", "motor")
    listed = {s.group for s in profile.variables.values() if not s.process and s.access.writable}
    out: list[dict[str, str]] = []
    for g in profile.groups:
        if g.id in wanted and g.id in listed:
            out.append({"page": "parameters", "group": g.id, "label": f"Parameters: {g.name}"})
    if not out:
        out.append({"page": "parameters", "group": "", "label": "Parameters"})
    return out


@dataclass(frozen=True, slots=True)
class GainRef:
    """One gain the tuning reads and changes: SI / engineering value = raw * ``scale``."""

    name: str
    label: str
    address: ObjectAddress
    unit: str | None
    scale: float
    raw_unit: str | None
    symbol: str | None
    data_type: DataType
    default: Value | None


def gain_refs(profile: DeviceProfile, kind: Kind) -> list[GainRef]:
    """The gains of the family: PB06-PB10 by symbol (builtin), the gain map (gains)."""
    out: list[GainRef] = []
    if kind == "builtin":
        by_symbol = {s.symbol: s for s in profile.variables.values() if s.symbol}
        q = _quirk_dict(profile, "one_touch_tuning") or {}
        params = q.get("parameters") if isinstance(q.get("parameters"), dict) else {}
        by_address: dict[ObjectAddress, str] = {}
        for name, addr in (params or {}).items():
            with contextlib.suppress(ServodeskError, ValueError):
                by_address[ObjectAddress.parse(str(addr))] = str(name)
        specs = [by_symbol[s] for s in BUILTIN_SYMBOLS if s in by_symbol]
        if not specs:  # No symbols: the quirk's own list.
            specs = [s for a in by_address if (s := profile.spec(a)) is not None]
        for spec in specs:
            sym = spec.symbol
            name = by_address.get(spec.address) or (sym or str(spec.address)).lower()
            label = BUILTIN_LABELS.get(sym or "", name.replace("_", " ").capitalize())
            out.append(_ref(spec, name, f"{sym} {label}" if sym else label, spec.unit, spec.scale))
        return out
    if kind == "gains":
        tspec = getattr(profile, "tuning", None)
        gains = getattr(tspec, "gains", None) or {}
        for name, g in gains.items():
            address = ObjectAddress.parse(str(getattr(g, "object", "")))
            found = profile.spec(address)
            if found is None:
                continue
            spec = found
            unit = getattr(g, "unit", None)
            scale = float(getattr(g, "scale", 1.0) or 1.0)
            out.append(_ref(spec, str(name), str(name), unit, scale))
    return out


def _ref(spec: ObjectSpec, name: str, label: str, unit: str | None, scale: float) -> GainRef:
    default: Value | None = None
    with contextlib.suppress(ValueError, ServodeskError):
        default = spec.default_value()
    return GainRef(
        name=name,
        label=label,
        address=spec.address,
        unit=unit,
        scale=scale,
        raw_unit=spec.raw_unit,
        symbol=spec.symbol,
        data_type=spec.data_type,
        default=default,
    )


def units_per_rev(profile: DeviceProfile) -> tuple[float, str]:
    """Position units (6064h raw) per motor revolution, and where that number comes from."""
    spec = profile.spec(POSITION)
    raw = (spec.raw_unit if spec else None) or "units"
    if spec is not None and spec.scale > 0 and spec.unit in ("deg", "°"):
        return 360.0 / spec.scale, f"6064h: {spec.scale:g} deg per {raw}"
    if spec is not None and spec.scale > 0 and spec.unit in ("rev", "r"):
        return 1.0 / spec.scale, f"6064h: {spec.scale:g} rev per {raw}"
    uu = _quirk_dict(profile, "user_units_factor_group")
    if uu and isinstance(uu.get("counts_per_rev"), int):
        return float(uu["counts_per_rev"]), "quirk user_units_factor_group: counts_per_rev"
    cpr = profile.simulation.counts_per_rev
    return float(cpr), (
        f"{cpr} {raw} per revolution: the profile's simulation setting; on a real drive the "
        "electronic gear decides"
    )


def speed_raw(profile: DeviceProfile, rps: float, upr: float) -> int | None:
    """``rps`` revolutions per second in 6081h's raw unit (None: the family has no 6081h)."""
    spec = profile.spec(PROFILE_VELOCITY)
    if spec is None:
        return None
    if spec.unit in ("r/min", "rpm", "min-1") and spec.scale > 0:
        return max(1, round(rps * 60.0 / spec.scale))
    return max(1, round(rps * upr))


def step_metrics(
    t: list[float], position: list[float], target: float, fe: list[float] | None = None
) -> dict[str, float | None]:
    """Settling time, overshoot and following error of a step response.

    ``position`` is relative to the start and ``target`` the commanded step. The band is 2 %
    of the step (at least one unit); the response starts at the first sample outside the band
    around 0 and settles at the first sample after which it stays inside the band around the
    target. Overshoot is the largest excursion past the target as a fraction of the step.
    The following error is the RMS of ``fe`` (60F4h) over the response, else None.
    """
    out: dict[str, float | None] = {
        "settling_s": None,
        "overshoot": None,
        "following_error_rms": None,
    }
    if not position or target == 0 or len(t) != len(position):
        return out
    x = np.asarray(position, dtype=np.float64) * math.copysign(1.0, target)
    tt = np.asarray(t, dtype=np.float64)
    size = abs(target)
    band = max(0.02 * size, 1.0)
    moving = np.nonzero(np.abs(x) > band)[0]
    if len(moving) == 0:
        return out
    i0 = int(moving[0])
    out["overshoot"] = round(max(0.0, float(np.max(x)) - size) / size, 4)
    outside = np.nonzero(np.abs(x - size) > band)[0]
    if len(outside) == 0:
        out["settling_s"] = 0.0
    elif int(outside[-1]) + 1 < len(x):
        out["settling_s"] = round(float(tt[int(outside[-1]) + 1] - tt[i0]), 4)
    if fe is not None and len(fe) == len(position):
        e = np.asarray(fe, dtype=np.float64)[i0:]
        out["following_error_rms"] = round(float(np.sqrt(np.mean(e * e))), 3) if len(e) else None
    return out


def decode_tuning_error(profile: DeviceProfile, code: int) -> dict[str, Any]:
    """P11604 with the profile's ``tuning`` error table: code, name, cause, remedy."""
    e = profile.error("tuning", code)
    if e is not None:
        info = error_info(e)
        return {k: info[k] for k in ("code", "code_hex", "name", "cause", "remedy", "section")}
    return {
        "code": code,
        "code_hex": f"0x{code:04X}",
        "name": f"Unknown one-touch tuning code 0x{code:04X}",
        "cause": "The drive reported a code the profile's tuning table does not list.",
        "remedy": "See the drive manual's one-touch tuning chapter.",
        "section": None,
    }


def _reason_error(name: str, cause: str, remedy: str | None = None) -> dict[str, Any]:
    return {"code": None, "code_hex": None, "name": name, "cause": cause, "remedy": remedy}


# Jobs -----------------------------------------------------------------------------------------


@dataclass(eq=False)
class Job:
    id: str
    sid: str
    kind: Kind
    mode: str
    owner: str
    travel_window_rev: float
    torque_limit_pct: float
    #: The peak torque of the machine's moves (own tuning only; None: the tuning's limit).
    move_torque_pct: float | None = None
    state: str = "running"
    progress: float = 0.0
    step: str = "starting"
    started: float = field(default_factory=time.time)
    ended: float | None = None
    message: str = ""
    error: dict[str, Any] | None = None
    task: asyncio.Task[None] | None = None
    motion: Motion | None = None
    #: (state, message) asked for by a stop, the dead-man, a fault: the job winds down.
    abort: tuple[str, str] | None = None
    #: The job ends its own motion now: the motion's end is not an abort.
    closing_motion: bool = False
    #: The travel bound the window gives around the start (``bound`` of the job's JSON).
    bound: dict[str, Any] | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "session": self.sid,
            "kind": self.kind,
            "mode": self.mode,
            "state": self.state,
            "progress": round(self.progress, 3),
            "step": self.step,
            "owner": self.owner,
            "started": self.started,
            "ended": self.ended,
            "message": self.message,
            "error": self.error,
            "travel_window_rev": self.travel_window_rev,
            "bound": self.bound,
            "torque_limit_pct": self.torque_limit_pct,
            "move_torque_pct": self.move_torque_pct,
        }


@dataclass(eq=False)
class _Run:
    """What a running job did so far (for its result and for putting things back)."""

    session: Session
    refs: list[GainRef]
    start: int = 0
    window: tuple[int, int] = (0, 0)
    upr: float = 1.0
    step: int = 0
    velocity: int | None = None
    acceleration: int | None = None
    before: dict[str, Value] = field(default_factory=dict)
    drive_started: bool = False
    torque_restore: int | None = None
    torque_set: bool = False
    #: Profile objects the motion writes (6081h, 6083h, 6084h) as they were, to put back;
    #: and whether each was already written since the last store (Session.dirty).
    profile_restore: dict[ObjectAddress, Value] = field(default_factory=dict)
    profile_dirty: set[ObjectAddress] = field(default_factory=set)
    step_before: dict[str, Any] | None = None
    step_after: dict[str, Any] | None = None
    axis_time_s: float = 0.0
    excursion: float = 0.0
    peak_torque_pct: float | None = None
    notes: list[str] = field(default_factory=list)


class TuningService:
    """The tuning jobs of every session of a :class:`SessionManager`."""

    def __init__(
        self,
        manager: SessionManager,
        motion: MotionService,
        hub: EventHub,
        *,
        recorder_busy: Callable[[str], bool] | None = None,
    ) -> None:
        self.manager = manager
        self.motion = motion
        self.hub = hub
        self.recorder_busy = recorder_busy
        self._jobs: dict[str, Job] = {}
        self._results: dict[str, dict[str, Any]] = {}
        #: Gain values before the last run of servodesk's own tuning (undo "before").
        self._before: dict[str, dict[str, Value]] = {}
        self._ids = itertools.count(1)

    # Info -------------------------------------------------------------------------------

    async def info(self, sid: str) -> dict[str, Any]:
        """``TuningInfo`` (docs/tuning.md): kind, reason, modes, gains, inputs, job."""
        session = self.manager.get(sid)
        p = session.profile
        kind, reason = tuning_kind(p)
        refs = gain_refs(p, kind)
        gains = await self._gain_rows(session, refs)
        upr, upr_source = units_per_rev(p)
        pos_spec = p.spec(POSITION)
        position: dict[str, Any] = {
            "actual": None,
            "raw_unit": pos_spec.raw_unit if pos_spec else None,
            "unit": pos_spec.unit if pos_spec else None,
            "scale": pos_spec.scale if pos_spec else 1.0,
            "units_per_rev": upr,
            "units_per_rev_source": upr_source,
            "min": None,
            "max": None,
            "limits_source": None,
        }
        torque: dict[str, Any] = {"object": None, "present_pct": None}
        if kind != "none":
            with contextlib.suppress(ServodeskError):
                position["actual"] = await self._read_int(session, POSITION)
            with contextlib.suppress(ServodeskError):
                lim = await self.motion.limits(sid)
                position["min"], position["max"] = lim.position_min, lim.position_max
                position["limits_source"] = lim.sources.get("position_min")
            spec = p.spec(MAX_TORQUE)
            if spec is not None and spec.access.writable:
                torque["object"] = str(MAX_TORQUE)
                with contextlib.suppress(ServodeskError):
                    raw = await self._read_int(session, MAX_TORQUE)
                    if raw is not None and spec.unit == "%":
                        torque["present_pct"] = raw * spec.scale
        job = self._jobs.get(sid)
        state = session.last_state.state if session.last_state else cia402.State.UNKNOWN.value
        return {
            "session": sid,
            "profile_id": p.id,
            "profile_name": p.name,
            "kind": kind,
            "reason": reason,
            "applies": applies_instead(p) if kind == "none" else [],
            "modes": list(MODES) if kind != "none" else [],
            # What servodesk's own tuning promises at each level (the drive's own: nothing).
            "mode_notes": {m: mode_promise(m) for m in MODES} if kind == "gains" else {},
            "gains": gains,
            "loop_rate_hz": await self._loop_rate(session) if kind != "none" else None,
            "defaults": dict(DEFAULTS),
            # How the window becomes the bound (the page computes the same, tuningModel.ts).
            "travel_rule": TRAVEL_RULE[kind] if kind != "none" else None,
            "limits": {
                "travel_window_rev": {"min": 0.0, "max": MAX_TRAVEL_REV},
                "torque_limit_pct": {"min": 0.0, "max": MAX_TORQUE_PCT},
                "move_torque_pct": {"min": 0.0, "max": MAX_MOVE_TORQUE_PCT},
            },
            "position": position,
            "torque_limit": torque,
            "state": state,
            "step_source": self._step_source(session) if kind == "builtin" else None,
            "undo": {
                "before": kind == "builtin" or sid in self._before,
                "defaults": kind != "none",
                "note": (
                    "The drive returns the gains itself (P11603) and saves them to its "
                    "EEP-ROM (004 §20.9.3.5(30))."
                    if kind == "builtin"
                    else "servodesk writes the gains back; store to keep them."
                )
                if kind != "none"
                else None,
            },
            "job": job.as_dict() if job is not None else None,
            "result_available": sid in self._results,
        }

    async def _gain_rows(self, session: Session, refs: list[GainRef]) -> list[dict[str, Any]]:
        rows: list[dict[str, Any]] = []
        for g in refs:
            row: dict[str, Any] = {
                "name": g.name,
                "label": g.label,
                "object": str(g.address),
                "symbol": g.symbol,
                "unit": g.unit,
                "raw_unit": g.raw_unit,
                "scale": g.scale,
                "value": None,
                "raw": None,
                "default": g.default,
                "error": None,
            }
            try:
                raw = await self._read_value(session, g.address)
                row["raw"] = raw
                row["value"] = _si(raw, g.scale)
            except ServodeskError as exc:
                row["error"] = exc.message
            rows.append(row)
        return rows

    async def _loop_rate(self, session: Session) -> float | None:
        spec = getattr(session.profile, "tuning", None)
        address = getattr(spec, "loop_rate_address", None)
        if isinstance(address, ObjectAddress):
            with contextlib.suppress(ServodeskError):
                v = await self._read_value(session, address)
                if isinstance(v, int | float) and not isinstance(v, bool):
                    return float(v)
        return None

    def _step_source(self, session: Session) -> str:
        from servodesk.services.scope import recorder_of

        if recorder_of(session) is None:
            return "sdo"
        if self.recorder_busy is not None and self.recorder_busy(session.id):
            return "sdo"
        return "recorder"

    # Start ------------------------------------------------------------------------------

    async def start(
        self,
        sid: str,
        client: str,
        *,
        mode: str,
        travel_window_rev: float,
        torque_limit_pct: float,
        move_torque_pct: float | None = None,
    ) -> dict[str, Any]:
        """Check the preconditions, begin the tuning motion and run the job in the background.

        ``move_torque_pct``: the peak torque of the machine's own moves, which servodesk's own
        tuning ranks its gains for (the reference move accelerates at 70 % of it); None: the
        tuning's torque limit. The drive's built-in tuning has no use for it (400).

        Refused before anything moves: kind ``none`` (400 naming ``kind``), a bad input (400
        naming it), a drive that is not enabled (409), a window beyond the software position
        limits (400 naming ``travel_window_rev``), a job already running (409).
        """
        session = self.manager.get(sid)
        p = session.profile
        kind, reason = tuning_kind(p)
        if kind == "none":
            raise ValidationError(
                f"{p.name}: {reason}",
                field="kind",
                hint="see GET /tuning: reason says what applies instead",
            )
        if mode not in MODES:
            raise ValidationError(f"mode {mode!r} is not one of {', '.join(MODES)}", field="mode")
        if not (0 < travel_window_rev <= MAX_TRAVEL_REV) or not math.isfinite(travel_window_rev):
            raise ValidationError(
                f"travel_window_rev {travel_window_rev:g} is outside 0 .. {MAX_TRAVEL_REV:g} rev",
                field="travel_window_rev",
            )
        if not (0 < torque_limit_pct <= MAX_TORQUE_PCT) or not math.isfinite(torque_limit_pct):
            raise ValidationError(
                f"torque_limit_pct {torque_limit_pct:g} is outside 0 .. {MAX_TORQUE_PCT:g} %",
                field="torque_limit_pct",
            )
        if move_torque_pct is not None:
            if not (0 < move_torque_pct <= MAX_MOVE_TORQUE_PCT) or not math.isfinite(
                move_torque_pct
            ):
                raise ValidationError(
                    f"move_torque_pct {move_torque_pct:g} is outside 0 .. "
                    f"{MAX_MOVE_TORQUE_PCT:g} %",
                    field="move_torque_pct",
                )
            if kind != "gains":
                raise ValidationError(
                    f"{p.name} tunes itself (its built-in one-touch tuning): move_torque_pct "
                    "is for servodesk's own tuning",
                    field="move_torque_pct",
                    hint="leave move_torque_pct out",
                )
        running = self._jobs.get(sid)
        if running is not None and running.state == "running":
            raise ConflictError(
                f"a tuning job runs on {sid} (client {running.owner!r}: {running.step})",
                hint="stop it first: POST /tuning/stop",
            )
        job = Job(
            id=f"{sid}-t{next(self._ids)}",
            sid=sid,
            kind=kind,
            mode=mode,
            owner=client,
            travel_window_rev=travel_window_rev,
            torque_limit_pct=torque_limit_pct,
            move_torque_pct=move_torque_pct,
        )
        run = _Run(session=session, refs=gain_refs(p, kind))
        if kind == "builtin":
            body = await self._prepare_builtin(job, run)
        else:
            body = await self._prepare_own(job, run)
        job.task = asyncio.get_running_loop().create_task(
            self._run(job, run, body), name=f"tuning {sid}"
        )
        self._publish(job)
        return job.as_dict()

    def _on_motion_end(self, job: Job) -> Callable[[Motion], None]:
        def ended(motion: Motion) -> None:
            if job.state != "running" or job.closing_motion or job.abort is not None:
                return
            why = {
                "deadman": "the dead-man stopped the axis",
                "halted": "the axis was halted",
                "stopped": "the axis was quick-stopped",
                "error": "the motion failed",
                "replaced": "another motion was started",
            }.get(motion.state, f"the tuning motion ended ({motion.state})")
            job.abort = ("failed", f"{why}: {motion.message}" if motion.message else why)
            if job.task is not None and not job.task.done():
                job.task.cancel()

        return ended

    async def _prepare_builtin(
        self, job: Job, run: _Run
    ) -> Callable[[], Awaitable[tuple[str, str, dict[str, Any]]]]:
        session = run.session
        p = session.profile
        sid = session.id
        if not run.refs:
            raise ValidationError(
                f"{p.name}: the profile has no gain parameters PB06-PB10 for one-touch tuning",
                field="kind",
            )
        if 1 not in p.modes:
            raise ValidationError(
                f"{p.name} has no profile position mode; one-touch tuning needs the motor "
                "turning under a position command",
                field="kind",
            )
        lim = await self.motion.limits(sid)
        half = await self._bound(job, run)
        self._check_window(p, lim, run, job.travel_window_rev)
        run.step = max(1, min(round(STEP_REV * run.upr), half // 2))
        rps = TUNING_SPEED_RPS
        run.velocity = speed_raw(p, rps, run.upr)
        if run.velocity is not None and lim.max_velocity is not None:
            run.velocity = max(1, min(run.velocity, int(lim.max_velocity * SPEED_SHARE)))
        vspec = p.spec(PROFILE_VELOCITY)
        if run.velocity is not None and vspec is not None and isinstance(vspec.max, int):
            run.velocity = min(run.velocity, vspec.max)
        aspec = p.spec(PROFILE_ACC)
        if (
            aspec is not None
            and aspec.raw_unit is not None
            and ramp_kind(aspec.raw_unit) == "rate"
            and run.velocity is not None
        ):
            vspec_unit = vspec.unit if vspec is not None else None
            per_s = rps * run.upr if vspec_unit in ("r/min", "rpm") else float(run.velocity)
            acc = round(per_s / RAMP_S)
            if lim.max_acceleration is not None:
                acc = min(acc, lim.max_acceleration)
            run.acceleration = max(1, acc)
        else:
            run.notes.append(
                "the drive's own acceleration and deceleration (6083h/6084h) apply: they are "
                "not in position units per s², so servodesk leaves them as they are"
            )
        job.motion = await self.motion.start_tuning_motion(
            sid,
            job.owner,
            window=run.window,
            message=f"one-touch tuning ({job.mode}) between the ends of "
            f"{self._bound_text(run)}; how far the drive's own tuning overshoots them is the "
            "drive's",
            on_end=self._on_motion_end(job),
        )
        self._jobs[sid] = job
        return lambda: self._builtin(job, run)

    async def _bound(self, job: Job, run: _Run) -> int:
        """The travel bound around where the axis stands (module docstring): into ``run``
        and the job; returns half the window in position units."""
        p = run.session.profile
        run.upr, _ = units_per_rev(p)
        run.start = await self._read_int(run.session, POSITION) or 0
        half = half_window(job.travel_window_rev, run.upr)
        run.window = (run.start - half, run.start + half)
        spec = p.spec(POSITION)
        bound = TravelBound(run.start, half)
        job.bound = {
            **bound.as_dict(run.upr, spec.raw_unit if spec else None),
            "text": self._bound_text(run),
        }
        return half

    def _bound_text(self, run: _Run) -> str:
        """The bound in words, revolutions and position units side by side."""
        spec = run.session.profile.spec(POSITION)
        return bound_text(
            TravelBound(run.start, run.window[1] - run.start),
            run.upr,
            spec.raw_unit if spec else None,
            unit=spec.unit if spec else None,
            scale=spec.scale if spec else None,
        )

    def _check_window(self, p: DeviceProfile, lim: Limits, run: _Run, travel: float) -> None:
        lo, hi = run.window
        span: list[tuple[str, float | None, float | None]] = [
            (
                f"the software position limits ({lim.sources.get('position_min', '607Dh')})",
                lim.position_min,
                lim.position_max,
            )
        ]
        tspec = p.spec(TARGET_POSITION)
        if tspec is not None:
            span.append((f"the target range of {TARGET_POSITION}", tspec.min, tspec.max))
        for what, mn, mx in span:
            bad_low = mn is not None and lo < mn
            bad_high = mx is not None and hi > mx
            if not (bad_low or bad_high):
                continue
            room = min(
                run.start - mn if mn is not None else math.inf,
                mx - run.start if mx is not None else math.inf,
            )
            fits = max(0.0, 2.0 * room / run.upr)
            raise ValidationError(
                f"travel_window_rev {travel:g} ({self._bound_text(run)}) does not fit {what}: "
                f"{mn} .. {mx}; nothing was sent",
                field="travel_window_rev",
                hint=f"at most {math.floor(fits * 1000) / 1000:g} rev fits here; choose a "
                "smaller window or move the axis away from the limit",
            )

    async def _prepare_own(
        self, job: Job, run: _Run
    ) -> Callable[[], Awaitable[tuple[str, str, dict[str, Any]]]]:
        session = run.session
        sid = session.id
        # servodesk's own tuning moves the axis inside the window too: the same check.
        lim = await self.motion.limits(sid)
        await self._bound(job, run)
        self._check_window(session.profile, lim, run, job.travel_window_rev)
        run.before = await self._read_raw(session, run.refs)
        job.motion = await self.motion.start_tuning_motion(
            sid,
            job.owner,
            window=None,
            message=f"servodesk tuning ({job.mode}) within {self._bound_text(run)}",
            on_end=self._on_motion_end(job),
        )
        self._jobs[sid] = job
        self._before[sid] = dict(run.before)
        return lambda: self._own(job, run)

    # The job ----------------------------------------------------------------------------

    async def _run(
        self,
        job: Job,
        run: _Run,
        body: Callable[[], Awaitable[tuple[str, str, dict[str, Any]]]],
    ) -> None:
        try:
            state, message, result = await body()
        except asyncio.CancelledError:
            _uncancel()
            state, message = job.abort or ("stopped", "the tuning was stopped")
            result = await self._wind_down(job, run, state, message)
        except ServodeskError as exc:
            # A stop or the dead-man may have asked for the end meanwhile: that is the cause.
            _uncancel()
            if job.abort is not None:
                state, message = job.abort
                result = await self._wind_down(job, run, state, message)
            else:
                job.abort = ("failed", exc.message)
                result = await self._wind_down(job, run, "failed", exc.message, exc)
                state, message = "failed", exc.message
        except Exception as exc:  # A bug: stop everything, say so, keep the server up.
            _uncancel()
            log.exception("tuning job %s failed", job.id)
            message = f"unexpected error: {type(exc).__name__}: {exc}"
            result = await self._wind_down(job, run, "failed", message)
            state = "failed"
        self._finish(job, state, message, result)

    async def _wind_down(
        self,
        job: Job,
        run: _Run,
        state: str,
        message: str,
        exc: ServodeskError | None = None,
    ) -> dict[str, Any]:
        """Stop the drive's tuning, the axis, put the gains and the torque limit back."""
        s = run.session
        sid = s.id
        job.closing_motion = True
        job.step = "stopping: putting things back"
        self._publish(job)
        problems: list[str] = []
        if run.drive_started:
            q = builtin_objects(s.profile)
            try:
                await s.write_object(q["stop"], STOP_VALUE, client=job.owner)
                run.drive_started = False
            except ServodeskError as e:
                problems.append(f"the drive's tuning could not be stopped: {e.message}")
        m = job.motion
        if m is not None and m.active:
            try:
                await self.motion.halt(sid, job.owner)
            except ServodeskError as e:
                problems.append(f"the halt could not be sent: {e.message}")
            if m.active:
                await self.motion.end_tuning_motion(sid, m, "halted", message)
        after: dict[str, Value] = {}
        if run.before:
            try:
                after = await self._read_raw(s, run.refs)
                changed = [g for g in run.refs if after.get(g.name) != run.before.get(g.name)]
                for g in changed:
                    await s.write_object(g.address, run.before[g.name], client=job.owner)
                if changed:
                    after = await self._read_raw(s, run.refs)
            except ServodeskError as e:
                problems.append(f"the gains from before could not be put back: {e.message}")
        try:
            await self._restore_torque_limit(job, run)
        except ServodeskError as e:
            problems.append(f"the torque limit could not be restored: {e.message}")
        try:
            await self._restore_profile(job, run)
        except ServodeskError as e:
            problems.append(f"the profile velocity and ramps could not be restored: {e.message}")
        if problems:
            message = f"{message}; " + "; ".join(problems)
            job.message = message
        p = s.profile
        soft = [p.spec(ObjectAddress(0x607D, n)) for n in (1, 2)]
        if job.kind == "gains" and not all(x is not None and x.access.writable for x in soft):
            # What the tuning's own result says when it ends done (tuning_own._set_safety).
            run.notes.append(
                f"{p.name} has no writable software position limits (607Dh): only servodesk's "
                f"own bound ({self._bound_text(run)}) applied, not the drive's"
            )
        if exc is not None:
            error = _reason_error(type(exc).__name__, exc.message, exc.hint)
        elif state == "stopped":
            error = _reason_error("Stopped", message, "Start the tuning again when ready.")
        else:
            error = _reason_error(
                "Tuning aborted",
                message,
                "Check the axis and the drive's state; servo on again before the next run.",
            )
        return self._result(job, run, state, error, after or run.before, applied=False)

    def _finish(self, job: Job, state: str, message: str, result: dict[str, Any]) -> None:
        job.state = state
        job.message = job.message or message
        if state == "done":
            job.progress = 1.0
            job.step = "done"
        else:
            job.step = {"stopped": "stopped", "failed": "failed"}.get(state, state)
        job.error = result.get("error")
        job.ended = time.time()
        self._results[job.sid] = result
        log.info("tuning %s ended: %s (%s)", job.id, state, job.message)
        self._publish(job)

    def _progress(self, job: Job, fraction: float, step: str) -> None:
        if job.state != "running":
            return
        job.progress = max(0.0, min(1.0, fraction))
        job.step = step
        self._publish(job)

    def _publish(self, job: Job) -> None:
        self.hub.publish(
            {"type": "tuning", "session": job.sid, "sid": job.sid, "job": job.as_dict()},
            session=job.sid,
        )

    def _result(
        self,
        job: Job,
        run: _Run,
        status: str,
        error: dict[str, Any] | None,
        after: dict[str, Value],
        *,
        applied: bool,
        identified: dict[str, Any] | None = None,
        drive_code: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        gains = []
        for g in run.refs:
            rb, ra = run.before.get(g.name), after.get(g.name)
            gains.append(
                {
                    "name": g.name,
                    "label": g.label,
                    "object": str(g.address),
                    "symbol": g.symbol,
                    "unit": g.unit,
                    "raw_unit": g.raw_unit,
                    "before": _si(rb, g.scale),
                    "after": _si(ra, g.scale),
                    "raw_before": rb,
                    "raw_after": ra,
                }
            )
        return {
            "kind": job.kind,
            "status": status,
            "error": error,
            "drive_code": drive_code,
            "mode": job.mode,
            "identified": identified
            or {
                "inertia_kgm2": None,
                "inertia_ratio": None,
                "coulomb_nm": None,
                "viscous_nms": None,
                "gravity_nm": None,
                "travel_friction_nm": None,
                "ranking_friction_nm": None,
                "resonances": [],
            },
            "bode": None,
            "margins": None,
            "gains": gains,
            "step": {"before": run.step_before, "after": run.step_after},
            "axis_time_s": round(run.axis_time_s, 3),
            "excursion_rev": round(run.excursion / run.upr, 4) if run.upr else None,
            # The bound the window gave (servodesk's own tuning adds what it reached).
            "travel": dict(job.bound) if job.bound else None,
            "peak_torque_pct": run.peak_torque_pct,
            # The largest 6077h of the polls while the drive tuned: the drive has no recorder
            # servodesk reads, so a torque peak shorter than a poll period goes unseen (a
            # LECSN-T run on its twin read 1.7 % where the unramped moves reach the limit).
            "peak_torque_polled_s": POLL_S if run.peak_torque_pct is not None else None,
            "applied": applied,
            "stored": False,
            "notes": list(run.notes),
            "job": job.id,
        }

    # Builtin one-touch tuning -------------------------------------------------------------

    async def _builtin(self, job: Job, run: _Run) -> tuple[str, str, dict[str, Any]]:
        s = run.session
        sid = s.id
        p = s.profile
        q = builtin_objects(p)
        motion = job.motion
        assert motion is not None
        self._progress(job, 0.01, "reading the gains before tuning")
        run.before = await self._read_raw(s, run.refs)
        await self._set_torque_limit(job, run)
        await self._save_profile(run)
        self._progress(job, 0.03, "step response with the present gains")
        run.step_before = await self._step_response(job, run)
        code = BUILTIN_MODE[job.mode]
        self._progress(
            job, 0.1, f"starting the drive's one-touch tuning ({job.mode}: {q['mode']} = {code})"
        )
        run.drive_started = True
        await s.write_object(q["mode"], code, client=job.owner)
        shuttle = asyncio.get_running_loop().create_task(
            self._shuttle(job, run), name=f"tuning motion {sid}"
        )
        try:
            await self._watch_builtin(job, run, shuttle)
        finally:
            shuttle.cancel()
            with contextlib.suppress(asyncio.CancelledError, ServodeskError):
                await shuttle
        run.drive_started = False  # It ended by itself (P11600 back to 0).
        code_now = await self._read_int(s, q["error"]) or 0
        decoded = decode_tuning_error(p, code_now)
        ok = code_now == 0
        self._progress(job, 0.91, "back to the start position")
        await self._move(job, run, run.start)
        after = await self._read_raw(s, run.refs)
        if ok:
            self._progress(job, 0.94, "step response with the new gains")
            run.step_after = await self._step_response(job, run)
        await self._restore_torque_limit(job, run)
        await self._restore_profile(job, run)
        job.closing_motion = True
        await self.motion.end_tuning_motion(sid, motion, "done", "tuning motion done")
        ratio = None
        for g in run.refs:
            if g.symbol == "PB06" and isinstance(after.get(g.name), int | float):
                ratio = _si(after[g.name], g.scale)
        identified: dict[str, Any] = {
            "inertia_kgm2": None,
            "inertia_ratio": ratio if ok else None,
            "coulomb_nm": None,
            "viscous_nms": None,
            "gravity_nm": None,
            "travel_friction_nm": None,
            "ranking_friction_nm": None,
            "resonances": [],
        }
        error = None if ok else decoded
        status = "done" if ok else "failed"
        message = (
            f"one-touch tuning finished normally ({q['error']} = 0x0000)"
            if ok
            else f"the drive's one-touch tuning failed: {decoded['code_hex']} {decoded['name']}"
        )
        result = self._result(
            job,
            run,
            status,
            error,
            after,
            applied=ok,
            identified=identified,
            drive_code=decoded,
        )
        return status, message, result

    async def _watch_builtin(self, job: Job, run: _Run, shuttle: asyncio.Task[None]) -> None:
        s = run.session
        q = builtin_objects(s.profile)
        deadline = time.monotonic() + BUILTIN_TIMEOUT_S
        last = -1
        while True:
            await asyncio.sleep(POLL_S)
            if shuttle.done() and not shuttle.cancelled():
                exc = shuttle.exception()
                if exc is not None:
                    raise exc
            mode_now = await self._read_int(s, q["mode"])
            status = await self._read_int(s, q["status"]) or 0
            await self._sample_axis(run)
            if status != last:
                last = status
                self._progress(
                    job,
                    0.1 + 0.8 * min(max(status, 0), 100) / 100.0,
                    f"drive tuning {status} % ({q['status']}); the axis moves back and forth",
                )
            if mode_now == 0:
                return
            if time.monotonic() > deadline:
                raise DriveStateError(
                    f"the drive's one-touch tuning did not end within {BUILTIN_TIMEOUT_S:g} s "
                    f"({q['status']} = {status} %)",
                    hint="check that the axis moves; servodesk stopped the drive's tuning",
                )

    async def _shuttle(self, job: Job, run: _Run) -> None:
        """Back and forth between the ends of the window until cancelled."""
        ends = (run.window[1], run.window[0])
        i = 0
        while True:
            await self._move(job, run, ends[i % 2], must_reach=False)
            i += 1
            await asyncio.sleep(DWELL_S)

    async def _move(self, job: Job, run: _Run, target: int, *, must_reach: bool = True) -> int:
        """One move; ``must_reach`` False (the shuttle): at most SHUTTLE_WAIT_S past its
        expected end for target reached, then on to the next."""
        assert job.motion is not None
        t0 = time.monotonic()
        pos = await self.motion.tuning_move(
            run.session.id,
            job.motion,
            target,
            velocity=run.velocity,
            acceleration=run.acceleration,
            deceleration=run.acceleration,
            timeout=30.0 if must_reach else SHUTTLE_WAIT_S,
            must_reach=must_reach,
        )
        run.axis_time_s += time.monotonic() - t0
        run.excursion = max(run.excursion, abs(pos - run.start))
        return pos

    async def _sample_axis(self, run: _Run) -> None:
        s = run.session
        with contextlib.suppress(ObjectAccessError):
            pos = await self._read_int(s, POSITION)
            if pos is not None:
                run.excursion = max(run.excursion, abs(pos - run.start))
        spec = s.profile.spec(TORQUE_ACTUAL)
        if spec is not None and spec.unit == "%":
            with contextlib.suppress(ObjectAccessError):
                tq = await self._read_int(s, TORQUE_ACTUAL)
                if tq is not None:
                    pct = abs(tq) * spec.scale
                    run.peak_torque_pct = round(max(run.peak_torque_pct or 0.0, pct), 1)

    async def _set_torque_limit(self, job: Job, run: _Run) -> None:
        s = run.session
        spec = s.profile.spec(MAX_TORQUE)
        if spec is None or not spec.access.writable or spec.unit != "%" or spec.scale <= 0:
            run.notes.append(
                f"the torque limit {job.torque_limit_pct:g} % is not applied: "
                f"{s.profile.name} has no writable {MAX_TORQUE} in %"
            )
            return
        old: int | None = None
        with contextlib.suppress(ObjectAccessError):
            old = await self._read_int(s, MAX_TORQUE)
        new = round(job.torque_limit_pct / spec.scale)
        if old is not None and old > 0:
            new = min(new, old)  # Never raise the drive's own limit.
        if isinstance(spec.max, int):
            new = min(new, spec.max)
        if old is not None and new == old:
            run.notes.append(f"torque limit {new * spec.scale:g} % ({MAX_TORQUE}, unchanged)")
            return
        await s.write_object(MAX_TORQUE, new, client=job.owner)
        self.motion.invalidate_limits(s.id)
        run.torque_restore, run.torque_set = old, True
        if old is None:
            run.notes.append(
                f"torque limit {new * spec.scale:g} % ({MAX_TORQUE}) during the run; the drive "
                f"gave no value for {MAX_TORQUE} before, so it stays at {new * spec.scale:g} % "
                "afterwards"
            )
        else:
            run.notes.append(
                f"torque limit {new * spec.scale:g} % ({MAX_TORQUE}) during the run, "
                f"{old * spec.scale:g} % again afterwards"
            )

    async def _restore_torque_limit(self, job: Job, run: _Run) -> None:
        if not run.torque_set:
            return
        run.torque_set = False
        if run.torque_restore is not None:
            await run.session.write_object(MAX_TORQUE, run.torque_restore, client=job.owner)
            self.motion.invalidate_limits(run.session.id)

    async def _save_profile(self, run: _Run) -> None:
        """The profile velocity and ramps the tuning motion writes, as they are now."""
        s = run.session
        wanted = [(PROFILE_VELOCITY, run.velocity)]
        wanted += [(PROFILE_ACC, run.acceleration), (PROFILE_DEC, run.acceleration)]
        for address, value in wanted:
            if value is None:
                continue
            with contextlib.suppress(ObjectAccessError):
                run.profile_restore[address] = await self._read_value(s, address)
                if address in s.dirty:
                    run.profile_dirty.add(address)

    async def _restore_profile(self, job: Job, run: _Run) -> None:
        s = run.session
        todo, run.profile_restore = run.profile_restore, {}
        for address, value in todo.items():
            await s.write_object(address, value, client=job.owner)
            if address not in run.profile_dirty:
                s.dirty.discard(address)  # Back to the value the drive had stored.

    async def _step_response(self, job: Job, run: _Run) -> dict[str, Any]:
        """A relative move of ``run.step`` from the start position, recorded; then back."""
        from servodesk.services.scope import recorder_of
        from servodesk.services.tuning_io import DriveRecorder, SessionIO

        s = run.session
        p = s.profile
        base = run.start
        target = base + run.step
        fe_spec = p.spec(FOLLOWING_ERROR)
        spec = recorder_of(s)
        busy = self.recorder_busy is not None and self.recorder_busy(s.id)
        t: list[float]
        pos: list[float]
        fe: list[float] | None = None
        if spec is not None and not busy:
            channels = [POSITION]
            if fe_spec is not None and RecorderSpec.recordable(fe_spec):
                channels.append(FOLLOWING_ERROR)
            rec = DriveRecorder(SessionIO(s, job.owner), spec.rate_hz)
            divider = max(1, round(spec.rate_hz / STEP_RATE_HZ))
            await rec.configure(channels, STEP_RECORD_S, divider)
            await rec.start()
            await self._move(job, run, target)
            recording = await rec.finish(timeout_s=STEP_RECORD_S * 4 + 2.0)
            x = recording[POSITION]
            t = [round(float(v), 6) for v in recording.t]
            pos = [float(v - x[0]) for v in x]
            if FOLLOWING_ERROR in channels:
                fe = [float(v) for v in recording[FOLLOWING_ERROR]]
            source, rate = "recorder", recording.rate_hz
            note = f"the drive's recorder at {rate:g} Hz"
        else:
            t, pos = await self._poll_step(job, run, target)
            source = "sdo"
            rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 0.0
            why = "the scope uses the drive's recorder" if busy else "the drive has no recorder"
            note = f"SDO polling of {POSITION} ({why}): sample times jitter by milliseconds"
        await self._move(job, run, base)
        pspec = p.spec(POSITION)
        return {
            "t_s": t,
            "position": pos,
            "target": float(run.step),
            "unit": (pspec.raw_unit if pspec is not None else None) or "units",
            "units_per_rev": run.upr,
            "source": source,
            "rate_hz": round(rate, 1),
            "note": note,
            "metrics": step_metrics(t, pos, float(run.step), fe),
        }

    async def _poll_step(self, job: Job, run: _Run, target: int) -> tuple[list[float], list[float]]:
        s = run.session
        move = asyncio.get_running_loop().create_task(self._move(job, run, target))
        t0 = time.monotonic()
        t: list[float] = []
        pos: list[float] = []
        try:
            while time.monotonic() - t0 < STEP_RECORD_S or not move.done():
                v = await self._read_int(s, POSITION)
                t.append(round(time.monotonic() - t0, 6))
                pos.append(float((v or 0) - run.start))
                if move.done() and move.exception() is not None:
                    break
        finally:
            if not move.done():
                move.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await move  # Raises the move's error.
        return t, pos

    # servodesk's own tuning ---------------------------------------------------------------

    async def _own(self, job: Job, run: _Run) -> tuple[str, str, dict[str, Any]]:
        # Imported on the first tuning, not with the backend: its numerical stack (scipy)
        # took 3 s of every start-up (servodesk serve, each test's server). In a thread, so
        # that the event loop carries the heartbeats and the other sessions meanwhile.
        await asyncio.to_thread(importlib.import_module, "servodesk.services.tuning_own")
        from servodesk.services import tuning_own

        s = run.session
        request = tuning_own.OwnTuningRequest(
            mode=job.mode,  # type: ignore[arg-type]
            travel_window_rev=job.travel_window_rev,
            torque_limit_pct=job.torque_limit_pct,
            move_torque_pct=job.move_torque_pct,
            # Exactly the bound the job confirmed (in 6064h's units), not one recomputed from
            # the encoder's counts per revolution.
            half_window_counts=run.window[1] - run.start,
        )

        def progress(fraction: float, step: str) -> None:
            self._progress(job, fraction, step)

        out = await tuning_own.run_own_tuning(s, request, progress)
        job.closing_motion = True
        if job.motion is not None:
            await self.motion.end_tuning_motion(s.id, job.motion, "done", "tuning done")
        after = await self._read_raw(s, run.refs)
        base = self._result(job, run, "done", None, after, applied=True)
        own = out if isinstance(out, dict) else {}
        result = {**base, **own}
        # The job's notes and the tuning's; what the moves reached, with the bound as the job
        # confirmed it (in 6064h's units and words).
        result["notes"] = [*base["notes"], *own.get("notes", [])]
        result["travel"] = {**(own.get("travel") or {}), **(base["travel"] or {})}
        result.setdefault("stored", False)
        status = str(result.get("status") or "done")
        if status not in ("done", "failed", "stopped"):
            status = "done"
        result["status"] = status
        message = "tuning done" if status == "done" else f"tuning {status}"
        err = result.get("error")
        if isinstance(err, dict) and err.get("name"):
            message = f"{message}: {err['name']}"
        return status, message, result

    # Stop, result, undo, store ----------------------------------------------------------

    async def stop(self, sid: str, client: str | None) -> dict[str, Any]:
        """Stop the session's running job (any client, always): see the module docstring."""
        self.manager.get(sid)
        job = self._jobs.get(sid)
        if job is None:
            raise NotFoundError(f"no tuning job on {sid}", hint="POST /tuning/start starts one")
        if job.state == "running" and job.task is not None and not job.task.done():
            if not job.closing_motion:  # Winding down or finishing already: only wait.
                if job.abort is None:
                    job.abort = ("stopped", f"stopped by {client or 'a client'}")
                job.task.cancel()
            await asyncio.wait({job.task}, timeout=STOP_WAIT_S)
        return job.as_dict()

    def job(self, sid: str) -> dict[str, Any] | None:
        job = self._jobs.get(sid)
        return job.as_dict() if job is not None else None

    def result(self, sid: str) -> dict[str, Any]:
        self.manager.get(sid)
        r = self._results.get(sid)
        if r is None:
            raise NotFoundError(
                f"no tuning result on {sid} yet", hint="POST /tuning/start runs a tuning"
            )
        return r

    def _idle(self, sid: str, what: str) -> None:
        job = self._jobs.get(sid)
        if job is not None and job.state == "running":
            raise ConflictError(
                f"a tuning job runs on {sid}; {what} waits until it has ended",
                hint="stop it first: POST /tuning/stop",
            )

    async def undo(self, sid: str, client: str | None, to: str) -> dict[str, Any]:
        """Return the gains to the values before the last run, or to the defaults."""
        session = self.manager.get(sid)
        p = session.profile
        kind, reason = tuning_kind(p)
        if kind == "none":
            raise ValidationError(f"{p.name}: nothing to undo. {reason}", field="kind")
        if to not in CLEAR_VALUE:
            raise ValidationError(f"to {to!r} is not 'before' or 'defaults'", field="to")
        self._idle(sid, "undo")
        refs = gain_refs(p, kind)
        if kind == "builtin":
            q = builtin_objects(p)
            await session.write_object(q["clear"], CLEAR_VALUE[to], client=client)
            stored = True
            note = (
                f"{q['clear']} = {CLEAR_VALUE[to]:04X}h: the drive returned the gains to "
                + ("the values before one-touch tuning" if to == "before" else "their defaults")
                + " and saved them to its EEP-ROM (004 §20.9.3.5(30))"
            )
        else:
            if to == "before":
                values = self._before.get(sid)
                if not values:
                    raise ConflictError(
                        f"no tuning run on {sid} to undo in this session",
                        hint='undo to the defaults with {"to": "defaults"}',
                    )
            else:
                values = {g.name: g.default for g in refs if g.default is not None}
            for g in refs:
                if g.name in values:
                    await session.write_object(g.address, values[g.name], client=client)
            stored = False
            note = (
                "servodesk wrote the gains "
                + ("from before the last run" if to == "before" else "of the profile's defaults")
                + "; they are not stored: POST /tuning/store keeps them"
            )
        self.motion.invalidate_limits(sid)
        gains = await self._gain_rows(session, refs)
        last = self._results.get(sid)
        if last is not None:
            last["undone"] = to
            last["applied"] = False
        self.hub.publish({"type": "sessions_changed"})
        return {"session": sid, "to": to, "gains": gains, "stored": stored, "note": note}

    async def store(self, sid: str, client: str | None) -> dict[str, Any]:
        """Store the drive's parameters to non-volatile memory (the session's procedure)."""
        session = self.manager.get(sid)
        self._idle(sid, "storing")
        out = await session.store()
        last = self._results.get(sid)
        if last is not None:
            last["stored"] = True
        return {"session": sid, **out}

    async def shutdown(self) -> None:
        """Backend shutdown: every running job stops (and puts the gains back)."""
        tasks = []
        for job in self._jobs.values():
            if job.state == "running" and job.task is not None and not job.task.done():
                if not job.closing_motion:
                    job.abort = job.abort or ("failed", "the server shuts down")
                    job.task.cancel()
                tasks.append(job.task)
        if tasks:
            await asyncio.wait(tasks, timeout=STOP_WAIT_S)

    # Bus helpers ------------------------------------------------------------------------

    @staticmethod
    async def _read_value(session: Session, address: ObjectAddress) -> Value:
        spec = session.profile.spec(address)
        raw = await session.link.read(address)
        return codec(spec.data_type if spec else DataType.INTEGER32).decode(raw)

    async def _read_int(self, session: Session, address: ObjectAddress) -> int | None:
        v = await self._read_value(session, address)
        if isinstance(v, bool) or not isinstance(v, int | float):
            return None
        return int(v)

    async def _read_raw(self, session: Session, refs: list[GainRef]) -> dict[str, Value]:
        return {g.name: await self._read_value(session, g.address) for g in refs}


def builtin_objects(profile: DeviceProfile) -> dict[str, ObjectAddress]:
    """P11600-P11604 (quirk ``one_touch_tuning``; 2D50h-2D54h when it names none)."""
    q = _quirk_dict(profile, "one_touch_tuning") or {}
    out: dict[str, ObjectAddress] = {}
    for key, default in (
        ("mode", 0x2D50),
        ("status", 0x2D51),
        ("stop", 0x2D52),
        ("clear", 0x2D53),
        ("error", 0x2D54),
    ):
        text = q.get(key)
        out[key] = ObjectAddress.parse(str(text)) if text else ObjectAddress(default)
    return out


def _uncancel() -> None:
    """The job winds down after a cancellation: let its remaining awaits run."""
    task = asyncio.current_task()
    while task is not None and task.cancelling():
        task.uncancel()


def _si(raw: Value | None, scale: float) -> float | None:
    if raw is None or isinstance(raw, bool):
        return None
    value: float | None = None
    if isinstance(raw, int | float):
        value = float(raw) * scale
    else:
        with contextlib.suppress(ValueError, ServodeskError):
            value = float(coerce_int(raw)) * scale
    if value is None or not math.isfinite(value):
        return value
    return float(f"{value:.12g}")  # 370 * 0.1 is 37.0, not 37.000000000000004.
