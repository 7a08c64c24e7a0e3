"""The own tuning's design (services/tuning/own): the friction the ranking takes, the gain
search on the identified model handed to the design worker (domain/tuning/search.py
``tune_on_model``: the highest gains meeting the margins, their variations ranked by what they
do to the machine's move on the model), and the search again on the model with the inertias
the tries' recordings fit (services/tuning/calibrate.py)."""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any, NamedTuple

from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.model import PlantModel
from servodesk.domain.tuning.promise import RESONANCE_TOL, RESONANCE_TOL_PEAK
from servodesk.domain.tuning.search import (
    ALTERNATIVE_SETTLING_FACTOR,
    LOW_ANTI_RESONANCE_HZ,
    RIGID_VARIATIONS,
    VARIATIONS,
    SearchResult,
    tune_on_model,
)
from servodesk.model.replay import ModelMoves, OwnMove, RecordedMove, WorstOf
from servodesk.services.tuning.calibrate import fit_inertias, fit_split
from servodesk.services.tuning.own.base import Drive
from servodesk.services.tuning.own.identify import Identification, Identified

log = logging.getLogger(__name__)

#: A runner-up tried on the axis replaces the pick so far only where it settles clearly sooner: in
#: less than this share of the pick's time; a smaller lead is within what the two moves of one try
#: disagree by (measured: docs/tuning.md). Not where the response did not show the anti-resonance.
#: The search again on the tries' fit (:meth:`Design._redesign`) is held to the same lead.
TRY_CLEAR_SHARE = 0.7
#: The search again with the inertias the tries' recordings fit (services/tuning/calibrate.py)
#: only where one of them moved by at least this share and the fit's output error is at most
#: this share of the model's: a model already within the noise is not searched again.
CALIBRATE_MIN_CHANGE = 0.005
CALIBRATE_ERROR_SHARE = 0.5
#: Runs of the oracle's structure search (oracle.py; search.tune_on_model ``structure_runs``)
#: on the model of a compliant axis whose anti-resonance the response shows, ranked with the
#: variations (measured: docs/tuning.md).
STRUCTURE_RUNS = 100
#: A rigid axis whose inertia the drive's position demand instrumented (identify_rigid) is ranked on
#: the identified axis and on it this much lighter and heavier (``WorstOf``): the instrumented fit's
#: error on the benchmark's rigid axes, with a margin (measured: docs/tuning.md) ...
RIGID_INERTIA_TOLERANCE = 0.0065
#: ... and on it this much lighter too: a machine's load changes a little, and an inertia
#: feed-forward above the axis's inertia overshoots and sticks (measured: docs/tuning.md).
RIGID_LIGHTER = 0.015
#: A compliant axis's first candidates are re-ranked by their worst move over the model and
#: the model with its Coulomb friction this much lower and higher (search.confirmed): what the
#: moves measure is a few percent off (measured: docs/tuning.md).
FRICTION_CONFIRM = 0.02
#: The least inertia change (a share of it) the same confirmation takes where the moves'
#: double integral gave the inertia (measured: docs/tuning.md).
INERTIA_CONFIRM_MIN = 0.002
#: A mode the record fit placed may be this much less damped than the fit says (the margins
#: hold there too, search.identification_set): the fit cannot say itself how far off its
#: damping is (measured: docs/tuning.md).
LIGHT_DAMPING_FACTOR = 0.25


class Redesign(NamedTuple):
    """The gain search again on the model with the inertias the tries' recordings fit."""

    design: SearchResult
    model: PlantModel


class Design(Identification):
    """The gains searched for on the identified axis."""

    def _with_friction(self, ident: Identified, model: PlantModel) -> Identified:
        """``ident`` with the Coulomb friction the ranking takes, the one the frequency
        response's travel measured, and the gravity of the moves back and forth where they give
        one. The ranking's model has Coulomb friction only (its viscous term is dropped,
        :meth:`_model_moves`), and a sticking axis that stops 10 counts early or late settles
        at another time: the friction it takes matters to the percent."""
        est, inertia = ident.est, ident.est.inertia
        f_ar = model.anti_resonance_hz
        low_anti = f_ar is not None and f_ar < LOW_ANTI_RESONANCE_HZ
        # The moves' own friction: c + b v at their cruise speed. They measured it at that
        # one speed, and from one speed the fit cannot tell c from b: it lent up to half
        # of the Coulomb friction to b (R1-100Hz: c 47 % low, where b is 0; taking c + b v
        # rather than c: bench median 1.84 -> 1.76 x the oracle, docs/tuning.md). Below a
        # low anti-resonance c alone: the moves are gentle there and their b is the
        # shaft's, not friction (a load 10 x the motor behind 18 Hz: c + b v was far above
        # the friction, and the ranking's gains overshot 11 % where the factory gains
        # overshot 6 %); their c was 8-30 % low there.
        moves_friction = max(
            est.coulomb + (0.0 if low_anti else est.viscous * ident.cruise_rad_s), 0.0
        )
        # A compliant axis's moves, recorded with the drive's demand, give the gravity
        # apart from the friction (identify.moves_gravity: within 0.02 % of the peak
        # torque, where their least squares were up to 0.054 % off, 2.4 mN m, the same way
        # on every seed), and the frequency response's slow constant-speed travel less
        # that gravity is the friction: within 1.6 % on every compliant axis of the
        # benchmark over two seeds, where c + b v was -3 to +11 % off (docs/tuning.md).
        # Without the moves' gravity the travel's friction is taken below a low
        # anti-resonance only (within 1.2 % there): a 400 Hz axis's least-squares gravity
        # left it 2-3.7 % high.
        gravity = self._moves_gravity(inertia)
        if gravity is not None:
            est = replace(est, gravity=gravity)
        travel = self._travel_friction(inertia, est.gravity)
        friction = moves_friction
        if travel is not None and (gravity is not None or low_anti):
            friction = travel
            self._notes.append(
                f"Coulomb friction from the slow travel of the frequency response "
                f"({travel:.4g} N m; the test moves gave {moves_friction:.4g} N m)"
            )
        return replace(ident, est=est, friction=friction, travel_friction=travel)

    def _model_moves(
        self,
        drive: Drive,
        ident: Identified,
        model: PlantModel,
        scale: float = 1.0,
        friction_scale: float = 1.0,
    ) -> ModelMoves | None:
        """The machine's move on ``model`` (its inertias x ``scale``, its Coulomb friction the
        ranking's x ``friction_scale``), as the search ranks the gains on it. Without the
        viscous term: the moves' fit lends it friction and shaft effects the machine may not
        have (R10-100Hz: 0.0029 N m s/rad where there is none), and damping the axis lacks
        makes sluggish gains look settled. Real viscous friction only helps whatever gains win
        (bench median ratio 1.93 -> 1.60, docs/tuning.md)."""
        return ModelMoves.of(
            replace(
                model,
                viscous=0.0,
                motor_inertia=model.motor_inertia * scale,
                load_inertia=model.load_inertia * scale,
            ),
            drive.rate_hz,
            counts_per_rev=drive.counts_per_rev,
            torque_limit=drive.move_torque,
            coulomb=ident.friction * friction_scale,
            gravity=ident.est.gravity,
        )

    def _design_job(
        self,
        drive: Drive,
        ident: Identified,
        model: PlantModel,
        incumbent: ServoGains | None = None,
    ) -> tuple[Callable[[], SearchResult], bool]:
        """The gain search on ``model`` (the identified axis, or the same with the inertias
        the tries' records fitted: :meth:`_redesign`) as a job for the design worker
        (:meth:`_search`), and whether it ranks a rigid axis with the instrumented inertia
        (no tries then)."""

        def moves(scale: float, friction_scale: float = 1.0) -> ModelMoves | None:
            return self._model_moves(drive, ident, model, scale, friction_scale)

        nominal = moves(1.0)
        rerank: ModelMoves | WorstOf | None = nominal
        variations = VARIATIONS
        rigid_model = nominal is not None and ident.instrumented
        if rigid_model:
            # Its variations reach feed-forwards near the inertia: a rigid axis then
            # stops closer to the target when its profile ends (R10-rigid: 61 counts
            # of lag at 0.85 J, 30 at 1.0 J), which the oracle's gains rest on; that
            # pays only with the inertia known to well under 2 %.
            tol = RIGID_INERTIA_TOLERANCE
            members = (
                moves(1.0 - tol),
                nominal,
                moves(1.0 + tol),
                moves(1.0 - RIGID_LIGHTER),
            )
            rerank = WorstOf(tuple(m for m in members if m is not None))
            self._notes.append(
                f"ranked by the worst move on the identified axis, on it "
                f"{100.0 * tol:.2g} % lighter and heavier, and "
                f"{100.0 * RIGID_LIGHTER:.2g} % lighter (a lighter load must not "
                f"overshoot and stick)"
            )
            variations = replace(VARIATIONS, ff=RIGID_VARIATIONS.ff)
            if self.request.move_torque_pct is not None:
                # The whole rigid grid only for the machine's own move: gains ranked at
                # the hardest move stayed as fast on gentler ones (100-351 % of rated,
                # 0.25 and 0.5 rev, six rigid axes), while those ranked at the tuning's
                # limit settled many times slower on harder moves (R3-rigid 0.9 -> 19-27
                # ms), and the rigid grid's more so (R1-rigid 57 ms even on its own
                # move, docs/tuning.md).
                variations = RIGID_VARIATIONS
        # A compliant axis's first candidates must also settle with the friction a
        # little off what the moves measured (1.4-6.9 % high on the benchmark's 400 Hz
        # axes): the model's fastest were often fast only at that friction
        # (search.confirmed).
        confirm: WorstOf | None = None
        if ident.resonances and not rigid_model:
            off: list[ModelMoves | OwnMove | None] = [
                moves(1.0, 1.0 + f) for f in (-FRICTION_CONFIRM, FRICTION_CONFIRM)
            ]
            if ident.moves_spread is not None:
                # Where the moves' double integral gave the inertia, also with the
                # inertia off by as much as their moves disagree (at least
                # INERTIA_CONFIRM_MIN), each on the machine's move as that inertia makes
                # it: stress-noise4x seed 2's model, 1.2 % light, put first gains that
                # settled 10 x slower than the oracle's on the axis (docs/tuning.md).
                spread = max(ident.moves_spread, INERTIA_CONFIRM_MIN)
                log.debug("confirmed with the inertia +-%.2g %%", 100.0 * spread)
                for f in (-spread, spread):
                    m = moves(1.0 + f)
                    off.append(OwnMove(m, model.total_inertia * (1.0 + f)) if m else None)
            if all(m is not None for m in off):
                confirm = WorstOf(tuple(m for m in off if m is not None))
        job = functools.partial(
            tune_on_model,
            model,
            drive.rate_hz,
            self.request.mode,
            counts_per_rev=drive.counts_per_rev,
            torque_limit=drive.move_torque,
            coulomb=ident.friction,
            gravity=ident.est.gravity,
            rerank=rerank,
            variations=variations,
            # The oracle's structures too, where a resonance gives them something to
            # shape (a rigid axis's structures changed nothing, docs/tuning.md), unless
            # the frequency response did not show its anti-resonance (``unseen``).
            structure_runs=STRUCTURE_RUNS if ident.resonances and not ident.unseen else 0,
            # High response trusts a resonance where the response's own peak put it
            # (promise.RESONANCE_TOL_PEAK); one the record fit placed, it does not.
            resonance_tol=(
                RESONANCE_TOL_PEAK
                if self.request.mode == "high" and not (ident.unseen or ident.refitted)
                else RESONANCE_TOL
            ),
            # Where the response did not show the anti-resonance the model's moves are
            # the least like the axis's, and the tries on the axis may pick any runner-up:
            # a load 10 x the motor behind a 60 Hz shaft overshot 11 % with the model's
            # winner (the factory gains: 6 %), and a runner-up the model put slower
            # than 1.5 x the winner settled it.
            try_factor=math.inf if ident.unseen else ALTERNATIVE_SETTLING_FACTOR,
            confirm=confirm,
            # Not where the response did not show the anti-resonance: there the model's
            # moves are the least like the axis's.
            ff_sweep=not ident.unseen,
            incumbent=incumbent,
            # A mode the record fit placed is a low, sharp one whose damping the record
            # barely resolves (identify.resonance_from_record): the margins also hold
            # with it LIGHT_DAMPING_FACTOR as damped.
            light_damping=(
                model.damping * LIGHT_DAMPING_FACTOR
                if ident.resonances and (ident.unseen or ident.refitted)
                else None
            ),
        )
        return job, rigid_model

    async def _redesign(
        self,
        drive: Drive,
        ident: Identified,
        model: PlantModel,
        records: list[RecordedMove],
        first: ServoGains,
    ) -> Redesign | None:
        """The gain search again on ``model`` with the inertias the tries' ``records`` fit
        (services/tuning/calibrate.py) on the simulation the search ranks ``model`` with
        (:meth:`_model_moves`), where they clearly fit better than the model's: the output
        error at most :data:`CALIBRATE_ERROR_SHARE` of the model's and an inertia moved by at
        least :data:`CALIBRATE_MIN_CHANGE`, and where the new winner settles on that model in
        less than :data:`TRY_CLEAR_SHARE` of the time of ``first``, the pick so far, run there
        as the winner was. None otherwise. Where the moves' double integral gave the inertia
        (``ident.moves_spread``) the total is trusted and only its split between motor and load
        is fitted (:func:`~servodesk.services.tuning.calibrate.fit_split`)."""
        nominal = self._model_moves(drive, ident, model)
        split_only = ident.moves_spread is not None
        if nominal is None or not records:
            return None
        # In the worker: some 80 replays of the recorded moves, 1.3 s of arithmetic on
        # R10-200Hz, which on the event loop held every session's traffic that long.
        fit = await self._compute(
            functools.partial(
                fit_split if split_only else fit_inertias, nominal.params, records, drive.rate_hz
            )
        )
        log.debug("the tries' records fit the inertias x %s", fit)
        moved = max(abs(fit.motor - 1.0), abs(fit.load - 1.0))
        refit: dict[str, Any] = {
            "motor_inertia_factor": fit.motor,
            "load_inertia_factor": fit.load,
            # Only the split was fitted: the moves' double integral gave the total.
            "total_held": split_only,
            "error_rms_counts_before": math.sqrt(fit.error_before),
            "error_rms_counts_after": math.sqrt(fit.error_after),
            "outcome": "fit_not_used",
            "searched_settling_s": None,
            "first_settling_s": None,
        }
        self._refit = refit
        if (
            moved < CALIBRATE_MIN_CHANGE
            or fit.error_after > CALIBRATE_ERROR_SHARE * fit.error_before
        ):
            return None
        fitted = replace(
            model,
            motor_inertia=model.motor_inertia * fit.motor,
            load_inertia=model.load_inertia * fit.load,
        )
        note = (
            f"the tries' recordings fit the motor inertia {100.0 * (fit.motor - 1.0):+.2g} % and "
            f"the load's {100.0 * (fit.load - 1.0):+.2g} % off the identification"
            f"{', the total held' if split_only else ''} (position error RMS "
            f"{math.sqrt(fit.error_before):.3g} -> {math.sqrt(fit.error_after):.3g} counts): "
            "gains searched again on that"
        )
        self.progress(0.86, "searching the gains again with the inertias the tries fit")
        job, _ = self._design_job(drive, ident, fitted, first)
        found = await self._search(job)
        held = found.incumbent_metrics
        refit["searched_settling_s"] = found.metrics.settling_10_s
        refit["first_settling_s"] = held.settling_10_s if held is not None else None
        if (
            found.gains != first
            and held is not None
            and found.metrics.settling_10_s >= TRY_CLEAR_SHARE * held.settling_10_s
        ):
            # Not clearly ahead on the fitted model either: the first pick stays, and the
            # runners-up are tried on the axis as where nothing was refitted (R30-100Hz seed 1:
            # 378 ms on the fitted model against the first pick's 388, on the axis 636 ms
            # against 388, docs/tuning.md).
            self._notes.append(
                f"{note}; they settle in {1e3 * found.metrics.settling_10_s:.3g} ms on it, the "
                f"first pick in {1e3 * held.settling_10_s:.3g} ms: not clearly ahead, the first "
                "kept"
            )
            refit["outcome"] = "first_kept"
            return None
        self._notes.append(note)
        refit["outcome"] = "searched_again"
        return Redesign(found, fitted)
