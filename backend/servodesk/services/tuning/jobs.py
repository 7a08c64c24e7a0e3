"""Tuning jobs of drive sessions (issue 8; docs/tuning.md "Service and API").

One job per session at a time, started by the client that holds control. What a job does
depends on the family (:func:`~servodesk.services.tuning.capabilities.tuning_kind`):

- ``builtin`` (LECSN-T): the drive's own one-touch tuning, driven by
  :mod:`servodesk.services.tuning.builtin`.
- ``gains`` (profiles with a gain map): servodesk's own tuning,
  :func:`servodesk.services.tuning.own.run_own_tuning`, under the same dead-man.
- ``none``: nothing to tune; ``tuning_kind`` says why and what applies instead.

A stop, a missing heartbeat, the socket closing, losing control, a fault or a software limit
ends the tuning motion: the job then stops the drive's tuning (1EA5h to P11602), halts the
axis, puts the gains from before the run back and restores the torque limit. Undo (P11603 on
the builtin kind; the recorded values otherwise) and store (the session's store procedure) run
only when asked.

The travel window is a total width centred on the position where the axis stands when the job
starts: the bound is start +- half of it, rounded down to whole position units
(domain/tuning/travel.py), and the job, the page and the result say it in revolutions and in
units side by side. servodesk's own tuning keeps every move's overshoot and a stop's run-out
inside it and sets the drive's software limits 607Dh there (services/tuning/travel.py). Position
units per revolution come from 6064h's unit (``deg``: 360 / scale) or else the profile's
simulation setting (``counts_per_rev``, 608Fh's once the session read it), which the info names
as the source: on a real drive the electronic gear decides.

About 700 lines: the job lifecycle (start, progress, stop, undo, store, shutdown) of every
tuning kind, one state machine under the dead-man; the kinds' own work is in builtin.py and
own/.
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
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import MAX_TORQUE, POSITION
from servodesk.domain.datatypes import Value
from servodesk.domain.tuning.promise import mode_promise
from servodesk.errors import (
    ConflictError,
    NotFoundError,
    ServodeskError,
    ValidationError,
)
from servodesk.services.backup import drive_key, new_id
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.motion import Motion, MotionService
from servodesk.services.session import Session
from servodesk.services.tuning import builtin
from servodesk.services.tuning.capabilities import (
    CLEAR_VALUE,
    DEFAULTS,
    MAX_MOVE_TORQUE_PCT,
    MAX_TORQUE_PCT,
    MAX_TRAVEL_REV,
    MODES,
    STOP_VALUE,
    TRAVEL_RULE,
    GainRef,
    applies_instead,
    builtin_objects,
    gain_refs,
    read_int,
    read_raw,
    read_value,
    si,
    tuning_kind,
    units_per_rev,
)
from servodesk.services.tuning.records import (
    Job,
    Run,
    bound,
    bound_text,
    check_window,
    job_result,
    reason_error,
)

log = logging.getLogger(__name__)

#: How long stop() waits for the job to wind down [s].
STOP_WAIT_S = 15.0
#: How long shutdown waits for the last results to reach the store [s].
STORE_WAIT_S = 10.0


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
        #: Keeps an ended job in the store (services/tuning_store.py ``TuningStore.add``;
        #: blocking, run in a thread). None: results live in memory only.
        self.recorder: Callable[[dict[str, Any]], None] | None = None
        #: The store writes under way (awaited, briefly, at shutdown).
        self._writes: set[asyncio.Task[None]] = set()

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
                position["actual"] = await read_int(session, POSITION)
            with contextlib.suppress(ServodeskError):
                lim = await self.motion.limits(sid)
                position["min"], position["max"] = lim.position_min, lim.position_max
                position["limits_source"] = lim.sources.get("position_min")
            spec = p.spec(MAX_TORQUE)
            if spec is not None and spec.access.writable:
                torque["object"] = str(MAX_TORQUE)
                with contextlib.suppress(ServodeskError):
                    raw = await read_int(session, MAX_TORQUE)
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
                raw = await read_value(session, g.address)
                row["raw"] = raw
                row["value"] = si(raw, g.scale)
            except ServodeskError as exc:
                row["error"] = exc.message
            rows.append(row)
        return rows

    async def _loop_rate(self, session: Session) -> float | None:
        spec = getattr(session.profile, "tuning", None)
        address = getattr(spec, "loop_rate_address", None)
        if isinstance(address, ObjectAddress):
            with contextlib.suppress(ServodeskError):
                v = await read_value(session, address)
                if isinstance(v, int | float) and not isinstance(v, bool):
                    return float(v)
        return None

    def _step_source(self, session: Session) -> str:
        from servodesk.services.scope_recorder import recorder_of

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
        user: str | None = None,
    ) -> dict[str, Any]:
        """Check the preconditions, begin the tuning motion and run the job in the background.

        ``move_torque_pct``: the peak torque of the machine's own moves, which servodesk's own
        tuning ranks its gains for (the reference move accelerates at 70 % of it); None: the
        tuning's torque limit. The drive's built-in tuning has no use for it (400). ``user``:
        who started it, for the stored result (None: the client's label stands in).

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
            user=user,
        )
        run = Run(session=session, refs=gain_refs(p, kind))
        if kind == "builtin":
            body = await builtin.prepare(self, job, run)
        else:
            body = await self._prepare_own(job, run)
        self._jobs[sid] = job
        job.task = asyncio.get_running_loop().create_task(
            self._run(job, run, body), name=f"tuning {sid}"
        )
        self._publish(job)
        return job.as_dict()

    def on_motion_end(self, job: Job) -> Callable[[Motion], None]:
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

    async def _prepare_own(
        self, job: Job, run: Run
    ) -> Callable[[], Awaitable[tuple[str, str, dict[str, Any]]]]:
        session = run.session
        sid = session.id
        # servodesk's own tuning moves the axis inside the window too: the same check.
        lim = await self.motion.limits(sid)
        await bound(job, run)
        check_window(session.profile, lim, run, job.travel_window_rev)
        run.before = await read_raw(session, run.refs)
        job.motion = await self.motion.start_tuning_motion(
            sid,
            job.owner,
            window=None,
            message=f"servodesk tuning ({job.mode}) within {bound_text(run)}",
            on_end=self.on_motion_end(job),
        )
        self._before[sid] = dict(run.before)
        return lambda: self._own(job, run)

    # The job ----------------------------------------------------------------------------

    async def _run(
        self,
        job: Job,
        run: Run,
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
        self._record(job, run.session, result)

    async def _wind_down(
        self,
        job: Job,
        run: Run,
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
                after = await read_raw(s, run.refs)
                changed = [g for g in run.refs if after.get(g.name) != run.before.get(g.name)]
                for g in changed:
                    await s.write_object(g.address, run.before[g.name], client=job.owner)
                if changed:
                    after = await read_raw(s, run.refs)
            except ServodeskError as e:
                problems.append(f"the gains from before could not be put back: {e.message}")
        try:
            await builtin.restore_torque_limit(self, job, run)
        except ServodeskError as e:
            problems.append(f"the torque limit could not be restored: {e.message}")
        try:
            await builtin.restore_profile(job, run)
        except ServodeskError as e:
            problems.append(f"the profile velocity and ramps could not be restored: {e.message}")
        if problems:
            message = f"{message}; " + "; ".join(problems)
            job.message = message
        p = s.profile
        soft = [p.spec(ObjectAddress(0x607D, n)) for n in (1, 2)]
        if job.kind == "gains" and not all(x is not None and x.access.writable for x in soft):
            # What the tuning's own result says when it ends done (own._set_safety).
            run.notes.append(
                f"{p.name} has no writable software position limits (607Dh): only servodesk's "
                f"own bound ({bound_text(run)}) applied, not the drive's"
            )
        if exc is not None:
            error = reason_error(type(exc).__name__, exc.message, exc.hint)
        elif state == "stopped":
            error = reason_error("Stopped", message, "Start the tuning again when ready.")
        else:
            error = reason_error(
                "Tuning aborted",
                message,
                "Check the axis and the drive's state; servo on again before the next run.",
            )
        return job_result(job, run, state, error, after or run.before, applied=False)

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

    def _record(self, job: Job, session: Session, result: dict[str, Any]) -> None:
        """Keep the ended job in the store (issue 49: tuning results live in the store).

        A task of its own, the write in a thread: the job has ended when this returns, so a
        stop (which waits for the job) never waits for the database, nor does the event loop.
        A store error is logged and changes nothing of the tuning's end (safety first).
        """
        if self.recorder is None:
            return
        try:
            key = drive_key(session)
        except Exception:  # A closed session's identity: the tuning has ended all the same.
            log.exception("tuning %s: its drive is unknown, the result is not stored", job.id)
            return
        record = {
            # Lower case: an id that check_id takes (GET /tuning/results/{id}).
            "id": new_id("tuning-").lower(),
            "drive_key": key,
            "session": job.sid,
            "kind": job.kind,
            "mode": job.mode,
            "status": job.state,
            "started": job.started,
            "ended": job.ended if job.ended is not None else time.time(),
            "by": job.user or job.owner,
            "client": job.owner,
            "applied": bool(result.get("applied")),
            # A copy: undo and store change the in-memory result's top-level keys later.
            "result": dict(result),
        }
        task = asyncio.get_running_loop().create_task(
            self._write(job, record), name=f"tuning {job.id} store"
        )
        self._writes.add(task)
        task.add_done_callback(self._writes.discard)

    async def _write(self, job: Job, record: dict[str, Any]) -> None:
        recorder = self.recorder
        if recorder is None:
            return
        try:
            await asyncio.to_thread(recorder, record)
        except Exception:  # The store's failure is not the tuning's: log it, go on.
            log.exception("tuning %s: its result could not be kept in the store", job.id)

    def progress(self, job: Job, fraction: float, step: str) -> None:
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

    # servodesk's own tuning ---------------------------------------------------------------

    async def _own(self, job: Job, run: Run) -> tuple[str, str, dict[str, Any]]:
        # Imported on the first tuning, not with the backend: its numerical stack (scipy)
        # took 3 s of every start-up (servodesk serve, each test's server). In a thread, so
        # that the event loop carries the heartbeats and the other sessions meanwhile.
        await asyncio.to_thread(importlib.import_module, "servodesk.services.tuning.own")
        from servodesk.services.tuning import own

        s = run.session
        request = own.OwnTuningRequest(
            mode=job.mode,  # type: ignore[arg-type]
            travel_window_rev=job.travel_window_rev,
            torque_limit_pct=job.torque_limit_pct,
            move_torque_pct=job.move_torque_pct,
            # Exactly the bound the job confirmed (in 6064h's units), not one recomputed from
            # the encoder's counts per revolution.
            half_window_counts=run.window[1] - run.start,
        )

        def progress(fraction: float, step: str) -> None:
            self.progress(job, fraction, step)

        out = await own.run_own_tuning(s, request, progress)
        job.closing_motion = True
        if job.motion is not None:
            await self.motion.end_tuning_motion(s.id, job.motion, "done", "tuning done")
        after = await read_raw(s, run.refs)
        base = job_result(job, run, "done", None, after, applied=True)
        found = out if isinstance(out, dict) else {}
        result = {**base, **found}
        # The job's notes and the tuning's; what the moves reached, with the bound as the job
        # confirmed it (in 6064h's units and words).
        result["notes"] = [*base["notes"], *found.get("notes", [])]
        result["travel"] = {**(found.get("travel") or {}), **(base["travel"] or {})}
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
        # The results of the jobs that just ended, before the store closes.
        if self._writes:
            await asyncio.wait(set(self._writes), timeout=STORE_WAIT_S)


def _uncancel() -> None:
    """The job winds down after a cancellation: let its remaining awaits run."""
    task = asyncio.current_task()
    while task is not None and task.cancelling():
        task.uncancel()
