"""servodesk's own tuning, the procedure: :class:`OwnTuning` (the phases of the package put
together, services/tuning/own) and :meth:`OwnTuning.run`, which runs them in order and puts
everything back on any failure or cancellation; :func:`run_own_tuning` for a session."""

from __future__ import annotations

from typing import Any

from servodesk.domain.cia402 import State, decode_state
from servodesk.errors import DriveStateError
from servodesk.services.session import Session
from servodesk.services.tuning.io import SessionIO
from servodesk.services.tuning.own.base import (
    VERIFY_SETTLE_S,
    OwnTuningRequest,
    Progress,
    TuningFailed,
    quietly,
)
from servodesk.services.tuning.own.report import Report, json_safe, refuse_if_worse
from servodesk.services.tuning.travel import TravelExceeded


class OwnTuning(Report):
    """One tuning run over a :class:`~servodesk.services.tuning.io.TuningIO` (a session's
    drive, or a simulated one)."""

    async def run(self) -> dict[str, Any]:
        """Tune; returns the TuningResult JSON (docs/tuning.md). On any failure or
        cancellation the previous gains and settings are back before the error propagates."""
        sw = await self._statusword()
        if decode_state(sw) is not State.OPERATION_ENABLED:
            raise DriveStateError(
                f"tuning needs Operation enabled; the drive is in {decode_state(sw).value}",
                hint="servo on first (Operation page)",
            )
        drive = await self._learn()
        before = await self.read_gains()
        saved = await self._save_settings()
        try:
            await self._set_safety(drive)
            ident = await self._identify_axis(drive)
            self.progress(0.55, "verification move with the present gains")
            model = ident.model(drive)
            est = ident.est
            self._set_travel_model(model, drive, coulomb=max(est.coulomb, 0.0), gravity=est.gravity)
            profile, step_before = await self._verify_before(drive, ident)
            self.progress(0.65, "designing gains and filters")
            ident = self._with_friction(ident, model)
            job, rigid_model = self._design_job(drive, ident, model)
            design = await self._search(job)
            self.progress(0.8, "applying the new gains and verifying")
            # The new gains' overshoot on the identified model, with the friction and gravity
            # the ranking took, before they move the axis.
            self._set_travel_model(model, drive, coulomb=ident.friction, gravity=ident.est.gravity)
            if not await self._fits_there_and_back(drive, profile, design.gains, VERIFY_SETTLE_S):
                raise TravelExceeded(
                    "the new gains may overshoot the verification move past the travel window "
                    "(on the identified model, or half the move where they have not moved the "
                    "axis yet); the previous gains are back",
                    hint="give a wider travel window, or tune with a lower response level",
                )
            await self.write_gains(design.gains)
            step_after = await self._verify_move(drive, profile)
            await self._check_healthy()
            if not rigid_model:
                # On a rigid axis with the instrumented inertia the model is the axis to
                # within its friction's few percent (its settling on the benchmark's seven
                # rigid axes matched the true plant's to 0.1 ms with the exact inertia): the
                # tries' brisk move and torque noise judged worse than it and took the old
                # design's gains back (R3-rigid 1.40 -> 1.46 x the oracle, R1-rigid 1.38 ->
                # 2.3 on two of four seeds, docs/tuning.md).
                step_after, design, model = await self._try_the_pick(
                    drive, ident, profile, design, step_after, model
                )
            refuse_if_worse(step_before, step_after)
            # Back where the axis stood, with the new gains at the verification's speed.
            await self._return_to_start(drive, profile[1], profile[2])
        except BaseException as exc:
            # The axis stops first: putting 607Dh, 6085h or the gains back while it still
            # moved would change how it stops.
            await quietly(self._come_to_rest())
            await quietly(self.write_gains(before))
            if isinstance(exc, TuningFailed | TravelExceeded) and self._slow is not None:
                # The tuning's own verdict, the axis enabled: back to the start with the
                # previous gains, as gently as their first move, whose run-on they showed.
                await quietly(self._return_to_start(drive, *self._slow))
            await quietly(self._restore_settings(saved))
            raise
        await self._restore_settings(saved)
        self.progress(1.0, "done")
        return self._result(drive, before, design, ident, model, step_before, step_after)


async def run_own_tuning(
    session: Session, request: OwnTuningRequest, progress: Progress, client: str | None = None
) -> dict[str, Any]:
    """Tune the drive of ``session``; returns the TuningResult JSON (docs/tuning.md)."""
    result = await OwnTuning(SessionIO(session, client), request, progress).run()
    result.pop("_loop", None)
    return dict(json_safe(result))
