"""A tuning job and its run: what the job says (:class:`Job`), what the run did so far and must
put back (:class:`Run`), the travel bound the window gives around the start, and the
``TuningResult`` both kinds of tuning start from (docs/tuning.md "Service and API").

The travel window is a total width centred on the position where the axis stands when the job
starts: the bound is start +- half of it, rounded down to whole position units
(domain/tuning/travel.py), and the job, the page and the result say it in revolutions and in
units side by side.
"""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass, field
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import POSITION, TARGET_POSITION
from servodesk.domain.datatypes import Value
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.tuning.travel import TravelBound, half_window
from servodesk.domain.tuning.travel import bound_text as travel_text
from servodesk.errors import ValidationError
from servodesk.services.motion import Limits, Motion
from servodesk.services.session import Session
from servodesk.services.tuning.capabilities import GainRef, Kind, read_int, si, units_per_rev

#: How often a drive's own tuning is polled (the result's ``peak_torque_polled_s``) [s].
POLL_S = 0.1


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
    #: The user who started it (the stored result's ``by``; the owner is the client).
    user: str | None = None
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
class Run:
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


async def bound(job: Job, run: Run) -> int:
    """The travel bound around where the axis stands (module docstring): into ``run``
    and the job; returns half the window in position units."""
    p = run.session.profile
    run.upr, _ = units_per_rev(p)
    run.start = await read_int(run.session, POSITION) or 0
    half = half_window(job.travel_window_rev, run.upr)
    run.window = (run.start - half, run.start + half)
    spec = p.spec(POSITION)
    job.bound = {
        **TravelBound(run.start, half).as_dict(run.upr, spec.raw_unit if spec else None),
        "text": bound_text(run),
    }
    return half


def bound_text(run: Run) -> str:
    """The bound in words, revolutions and position units side by side."""
    spec = run.session.profile.spec(POSITION)
    return travel_text(
        TravelBound(run.start, run.window[1] - run.start),
        run.upr,
        spec.raw_unit if spec else None,
        unit=spec.unit if spec else None,
        scale=spec.scale if spec else None,
    )


def check_window(p: DeviceProfile, lim: Limits, run: Run, travel: float) -> None:
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
            f"travel_window_rev {travel:g} ({bound_text(run)}) does not fit {what}: "
            f"{mn} .. {mx}; nothing was sent",
            field="travel_window_rev",
            hint=f"at most {math.floor(fits * 1000) / 1000:g} rev fits here; choose a "
            "smaller window or move the axis away from the limit",
        )


def job_result(
    job: Job,
    run: Run,
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
                "before": si(rb, g.scale),
                "after": si(ra, g.scale),
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


def reason_error(name: str, cause: str, remedy: str | None = None) -> dict[str, Any]:
    """The result's ``error`` where servodesk, not the drive, gives the reason."""
    return {"code": None, "code_hex": None, "name": name, "cause": cause, "remedy": remedy}
