"""The drive's own one-touch tuning, driven by servodesk (LECSN-T, 004 §20.8.7, P11600-P11604).

The manual needs the motor turning under the master's command while it tunes, so servodesk moves
the axis back and forth inside the travel window the user confirmed (profile position, under the
client's dead-man: :meth:`MotionService.start_tuning_motion`), writes the response mode to
P11600, follows P11601 (progress) until P11600 is 0 again, reads P11604 and decodes it with the
profile's ``tuning`` error table. Before and after, a short step (a relative move recorded by the
drive-side recorder, or polled over SDO where there is none) shows what the gains do; the gains
PB06-PB10 are read before and after. The job around it (start, stop, putting things back) is
:class:`~servodesk.services.tuning.jobs.TuningService`'s.

Choices where the manual leaves room (documented once):

- The back-and-forth runs at :data:`TUNING_SPEED_RPS` (600 r/min; MR-J4's one-touch tuning
  asks for at least 150 r/min [general product knowledge, unverified here]), lower where
  607Fh says so, converted to 6081h's unit (``r/min`` with its scale, else position units per
  s). Ramps given as times (LECSN-T ms) are the drive's own: servodesk does not guess the speed
  they refer to; ramps in position units per s² are set for :data:`RAMP_S` to full speed.
- The torque limit is written to 6072h for the run (never raising the drive's own value) and
  restored afterwards; so are the profile velocity and ramps the back-and-forth writes.
- The drive's one-touch tuning is commanded between the two ends of the window, and what it
  overshoots past them is the drive's (the job's message says so).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from servodesk.domain.cia402 import (
    FOLLOWING_ERROR,
    MAX_TORQUE,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    TORQUE_ACTUAL,
)
from servodesk.domain.profile import RecorderSpec
from servodesk.domain.ramps import ramp_kind
from servodesk.errors import DriveStateError, ObjectAccessError, ServodeskError, ValidationError
from servodesk.services.tuning.capabilities import (
    BUILTIN_MODE,
    builtin_objects,
    decode_tuning_error,
    read_int,
    read_raw,
    read_value,
    si,
    speed_raw,
)
from servodesk.services.tuning.records import (
    POLL_S,
    Job,
    Run,
    bound,
    bound_text,
    check_window,
    job_result,
)

if TYPE_CHECKING:
    from servodesk.services.tuning.jobs import TuningService

#: Speed of the back-and-forth motion of a builtin tuning [rev/s].
TUNING_SPEED_RPS = 10.0
#: Share of the drive's max profile velocity (607Fh) the tuning uses at most.
SPEED_SHARE = 0.8
#: Time to full speed where servodesk sets the ramps (position units per s² only) [s].
RAMP_S = 0.1
#: The shuttle's longest wait for target reached before the next move [s].
SHUTTLE_WAIT_S = 3.0
#: Pause at each end of the window [s] (the drive sees one move end before the next starts).
DWELL_S = 0.25
#: The step of the step response [rev], at most a quarter of the window.
STEP_REV = 0.05
#: Recording of the step response [s] and its sample rate [Hz].
STEP_RECORD_S = 0.5
STEP_RATE_HZ = 1000.0
#: The drive's one-touch tuning must end within this [s] (the twin gives up after 10 s idle).
BUILTIN_TIMEOUT_S = 180.0


async def prepare(
    svc: TuningService, job: Job, run: Run
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
    lim = await svc.motion.limits(sid)
    half = await bound(job, run)
    check_window(p, lim, run, job.travel_window_rev)
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
    job.motion = await svc.motion.start_tuning_motion(
        sid,
        job.owner,
        window=run.window,
        message=f"one-touch tuning ({job.mode}) between the ends of "
        f"{bound_text(run)}; how far the drive's own tuning overshoots them is the "
        "drive's",
        on_end=svc.on_motion_end(job),
    )
    return lambda: tune(svc, job, run)


async def tune(svc: TuningService, job: Job, run: Run) -> tuple[str, str, dict[str, Any]]:
    s = run.session
    sid = s.id
    p = s.profile
    q = builtin_objects(p)
    motion = job.motion
    assert motion is not None
    svc.progress(job, 0.01, "reading the gains before tuning")
    run.before = await read_raw(s, run.refs)
    await _set_torque_limit(svc, job, run)
    await _save_profile(run)
    svc.progress(job, 0.03, "step response with the present gains")
    run.step_before = await _step_response(svc, job, run)
    code = BUILTIN_MODE[job.mode]
    svc.progress(
        job, 0.1, f"starting the drive's one-touch tuning ({job.mode}: {q['mode']} = {code})"
    )
    run.drive_started = True
    await s.write_object(q["mode"], code, client=job.owner)
    shuttle = asyncio.get_running_loop().create_task(
        _shuttle(svc, job, run), name=f"tuning motion {sid}"
    )
    try:
        await _watch(svc, job, run, shuttle)
    finally:
        shuttle.cancel()
        with contextlib.suppress(asyncio.CancelledError, ServodeskError):
            await shuttle
    run.drive_started = False  # It ended by itself (P11600 back to 0).
    code_now = await read_int(s, q["error"]) or 0
    decoded = decode_tuning_error(p, code_now)
    ok = code_now == 0
    svc.progress(job, 0.91, "back to the start position")
    await move(svc, job, run, run.start)
    after = await read_raw(s, run.refs)
    if ok:
        svc.progress(job, 0.94, "step response with the new gains")
        run.step_after = await _step_response(svc, job, run)
    await restore_torque_limit(svc, job, run)
    await restore_profile(job, run)
    job.closing_motion = True
    await svc.motion.end_tuning_motion(sid, motion, "done", "tuning motion done")
    ratio = None
    for g in run.refs:
        if g.symbol == "PB06" and isinstance(after.get(g.name), int | float):
            ratio = si(after[g.name], g.scale)
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
    result = job_result(
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


async def _watch(svc: TuningService, job: Job, run: Run, shuttle: asyncio.Task[None]) -> None:
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
        mode_now = await read_int(s, q["mode"])
        status = await read_int(s, q["status"]) or 0
        await _sample_axis(run)
        if status != last:
            last = status
            svc.progress(
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


async def _shuttle(svc: TuningService, job: Job, run: Run) -> None:
    """Back and forth between the ends of the window until cancelled."""
    ends = (run.window[1], run.window[0])
    i = 0
    while True:
        await move(svc, job, run, ends[i % 2], must_reach=False)
        i += 1
        await asyncio.sleep(DWELL_S)


async def move(
    svc: TuningService, job: Job, run: Run, target: int, *, must_reach: bool = True
) -> int:
    """One move; ``must_reach`` False (the shuttle): at most SHUTTLE_WAIT_S past its
    expected end for target reached, then on to the next."""
    assert job.motion is not None
    t0 = time.monotonic()
    pos = await svc.motion.tuning_move(
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


async def _sample_axis(run: Run) -> None:
    s = run.session
    with contextlib.suppress(ObjectAccessError):
        pos = await read_int(s, POSITION)
        if pos is not None:
            run.excursion = max(run.excursion, abs(pos - run.start))
    spec = s.profile.spec(TORQUE_ACTUAL)
    if spec is not None and spec.unit == "%":
        with contextlib.suppress(ObjectAccessError):
            tq = await read_int(s, TORQUE_ACTUAL)
            if tq is not None:
                pct = abs(tq) * spec.scale
                run.peak_torque_pct = round(max(run.peak_torque_pct or 0.0, pct), 1)


async def _set_torque_limit(svc: TuningService, job: Job, run: Run) -> None:
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
        old = await read_int(s, MAX_TORQUE)
    new = round(job.torque_limit_pct / spec.scale)
    if old is not None and old > 0:
        new = min(new, old)  # Never raise the drive's own limit.
    if isinstance(spec.max, int):
        new = min(new, spec.max)
    if old is not None and new == old:
        run.notes.append(f"torque limit {new * spec.scale:g} % ({MAX_TORQUE}, unchanged)")
        return
    await s.write_object(MAX_TORQUE, new, client=job.owner)
    svc.motion.invalidate_limits(s.id)
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


async def restore_torque_limit(svc: TuningService, job: Job, run: Run) -> None:
    if not run.torque_set:
        return
    run.torque_set = False
    if run.torque_restore is not None:
        await run.session.write_object(MAX_TORQUE, run.torque_restore, client=job.owner)
        svc.motion.invalidate_limits(run.session.id)


async def _save_profile(run: Run) -> None:
    """The profile velocity and ramps the tuning motion writes, as they are now."""
    s = run.session
    wanted = [(PROFILE_VELOCITY, run.velocity)]
    wanted += [(PROFILE_ACC, run.acceleration), (PROFILE_DEC, run.acceleration)]
    for address, value in wanted:
        if value is None:
            continue
        with contextlib.suppress(ObjectAccessError):
            run.profile_restore[address] = await read_value(s, address)
            if address in s.dirty:
                run.profile_dirty.add(address)


async def restore_profile(job: Job, run: Run) -> None:
    s = run.session
    todo, run.profile_restore = run.profile_restore, {}
    for address, value in todo.items():
        await s.write_object(address, value, client=job.owner)
        if address not in run.profile_dirty:
            s.dirty.discard(address)  # Back to the value the drive had stored.


async def _step_response(svc: TuningService, job: Job, run: Run) -> dict[str, Any]:
    """A relative move of ``run.step`` from the start position, recorded; then back."""
    from servodesk.services.scope_recorder import recorder_of
    from servodesk.services.tuning.io import DriveRecorder, SessionIO

    s = run.session
    p = s.profile
    base = run.start
    target = base + run.step
    fe_spec = p.spec(FOLLOWING_ERROR)
    spec = recorder_of(s)
    busy = svc.recorder_busy is not None and svc.recorder_busy(s.id)
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
        await move(svc, job, run, target)
        recording = await rec.finish(timeout_s=STEP_RECORD_S * 4 + 2.0)
        x = recording[POSITION]
        t = [round(float(v), 6) for v in recording.t]
        pos = [float(v - x[0]) for v in x]
        if FOLLOWING_ERROR in channels:
            fe = [float(v) for v in recording[FOLLOWING_ERROR]]
        source, rate = "recorder", recording.rate_hz
        note = f"the drive's recorder at {rate:g} Hz"
    else:
        t, pos = await _poll_step(svc, job, run, target)
        source = "sdo"
        rate = (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 0.0
        why = "the scope uses the drive's recorder" if busy else "the drive has no recorder"
        note = f"SDO polling of {POSITION} ({why}): sample times jitter by milliseconds"
    await move(svc, job, run, base)
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


async def _poll_step(
    svc: TuningService, job: Job, run: Run, target: int
) -> tuple[list[float], list[float]]:
    s = run.session
    moving = asyncio.get_running_loop().create_task(move(svc, job, run, target))
    t0 = time.monotonic()
    t: list[float] = []
    pos: list[float] = []
    try:
        while time.monotonic() - t0 < STEP_RECORD_S or not moving.done():
            v = await read_int(s, POSITION)
            t.append(round(time.monotonic() - t0, 6))
            pos.append(float((v or 0) - run.start))
            if moving.done() and moving.exception() is not None:
                break
    finally:
        if not moving.done():
            moving.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await moving  # Raises the move's error.
    return t, pos


# The step response's figures ------------------------------------------------------------


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
