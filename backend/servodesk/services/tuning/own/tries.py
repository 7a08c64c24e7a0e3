"""The own tuning on the axis itself (services/tuning/own): the verification move before and
after, the model's winner and runners-up tried there and back with a brisk move within the
axis-time budget, and what each try showed (docs/tuning.md)."""

from __future__ import annotations

import logging
import math
from collections.abc import Awaitable, Callable
from typing import Any

import numpy as np

from servodesk.domain.cia402 import FOLLOWING_ERROR, POSITION
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.metrics import move_metrics, smoothed_settling
from servodesk.domain.tuning.model import PlantModel
from servodesk.domain.tuning.search import REF_HOLD_PERIODS, SearchResult
from servodesk.model.replay import RecordedMove
from servodesk.services.tuning.calibrate import recorded_move
from servodesk.services.tuning.io import Recording
from servodesk.services.tuning.own.base import SIG_TORQUE, VERIFY_SETTLE_S, Drive
from servodesk.services.tuning.own.design import TRY_CLEAR_SHARE, Design, Redesign
from servodesk.services.tuning.own.identify import Identified
from servodesk.services.tuning.own.moves import as_written, move_time
from servodesk.services.tuning.travel import UNSEEN_SHARE

log = logging.getLogger(__name__)

#: A try of a runner-up on a slow axis is watched up to this long after its profile
#: (:func:`watch_for`; measured: docs/tuning.md).
TRY_WATCH_MAX_S = 1.0
#: A try's move has settled only where the 5 ms mean of its error then stays inside +-10 counts for
#: at least this long before the watch ends (``_try_key``); one that did not counts as the watch: a
#: last crossing just before the watch ends is torque noise (measured: docs/tuning.md).
TRY_SETTLED_HOLD_S = 0.1
#: Axis time a tuning may spend moving (issue 8: at most 5 s); runners-up are tried only while
#: one more try, the verification move after it and the way back to the start fit, with 0.1 s to
#: spare for what the count of a profile's time misses (measured: docs/tuning.md).
AXIS_BUDGET_S = 4.9
#: Torque share of the move runners-up are compared with (search.py's reference move: 0.7).
RANK_TORQUE_SHARE = 0.7


class Tries(Design):
    """The verification moves and the tries on the axis."""

    async def _verify_before(
        self, drive: Drive, ident: Identified
    ) -> tuple[tuple[float, float, float], dict[str, Any]]:
        """The verification move with the present gains: its profile (distance, velocity,
        acceleration), the same for the new gains, and its step response. Sized for the
        inertia the moves confirmed: the frequency response alone can see the motor without
        its load (below a low anti-resonance), and a move sized for that runs into the torque
        limit."""
        inertia = ident.est.inertia

        def verify_size(d: float) -> tuple[float, float]:
            return self._verify_profile(drive, inertia, d)[1:]

        # Where the frequency response did not show the anti-resonance, the new gains'
        # first moves are given a larger reserve (travel.UNSEEN_SHARE).
        if ident.hidden or ident.below_band or self._travel_params is None:
            self.guard.fresh_share = UNSEEN_SHARE
        # Shortened where the present gains' overshoot would not fit, nor the reserve of
        # gains that have not moved the axis yet (the new gains': their model's is checked
        # before their own verification move, below).
        profile = await self._fit_profile(
            drive,
            verify_size,
            drive.verify_distance,
            VERIFY_SETTLE_S,
            "the verification move",
            also_fresh=True,
        )
        step_before = await self._verify_move(drive, profile)
        if self.guard.fresh_share < UNSEEN_SHARE and not self._model_foretold(2):
            # The model did not foretell the present gains' run-on: the new gains, designed
            # on it, get the larger reserve too, and the move they are compared on is run
            # again as short as that needs (soft-8x-60hz: 0.034 rev where the model said
            # 0.004; the design's gains then ran on 0.066).
            self.guard.fresh_share = UNSEEN_SHARE
            shorter = await self._fit_profile(
                drive,
                verify_size,
                profile[0],
                VERIFY_SETTLE_S,
                "the verification move",
                also_fresh=True,
            )
            if shorter[0] < profile[0]:
                profile = shorter
                step_before = await self._verify_move(drive, profile)
        return profile, step_before

    async def _try_the_pick(
        self,
        drive: Drive,
        ident: Identified,
        profile: tuple[float, float, float],
        design: SearchResult,
        step: dict[str, Any],
        model: PlantModel,
    ) -> tuple[dict[str, Any], SearchResult, PlantModel]:
        """The design's gains, already on the drive, and its runners-up tried on the axis
        (:meth:`_try_alternatives`) with, at ``high``, the search again on what the winner's
        try fits (:meth:`_redesign`); returns the verification move of the gains kept, and the
        search result and model they came from."""
        identified = model

        async def redesign(records: list[RecordedMove], first: ServoGains) -> Redesign | None:
            return await self._redesign(drive, ident, identified, records, first)

        _, step, design, model = await self._try_alternatives(
            drive,
            profile,
            design,
            step,
            model,
            trust_model=not ident.unseen,
            # Not where the response did not show the anti-resonance (the model's shape
            # is its least certain part there, which the inertias cannot mend). Where the
            # moves' double integral gave the inertia (within 0.25 % at the median on the
            # benchmark's 400-800 Hz axes, closer than the fit, whose inertias also take
            # up what the friction and damping are off by: R3-800Hz seed 1's motor came
            # out 4.1 % heavier and its gains settled 2 x slower), only the split between
            # motor and load is fitted, the total held (_redesign). Only at
            # ``high``: the other levels rank nothing and try nothing on the axis.
            redesign=None if ident.unseen or self.request.mode != "high" else redesign,
        )
        return step, design, model

    async def _try_alternatives(
        self,
        drive: Drive,
        profile: tuple[float, float, float],
        design: SearchResult,
        step: dict[str, Any],
        model: PlantModel,
        *,
        trust_model: bool = True,
        redesign: Callable[[list[RecordedMove], ServoGains], Awaitable[Redesign | None]]
        | None = None,
    ) -> tuple[ServoGains, dict[str, Any], SearchResult, PlantModel]:
        """The model's winner and runners-up (:func:`~servodesk.domain.tuning.search.
        alternatives_of`) tried on the axis itself with a brisk move (the verification move's
        distance at :data:`RANK_TORQUE_SHARE` of the torque limit, like the reference move of
        search.py), there and back (:meth:`_try_key`: settling to +-10 counts of the error's
        5 ms mean, then the drive's following error RMS, each averaged over the two moves). The
        identified model is not the machine: its friction and damping decide between integral
        times and position gains that all meet the margins, and the axis settles that where it
        clearly can. ``trust_model``: a runner-up replaces the pick so far only where it settles
        in less than :data:`TRY_CLEAR_SHARE` of its time (a smaller lead is within what the two
        moves of one try disagree by); otherwise (the frequency response did not show the
        anti-resonance, and the model's moves are the least like the axis's) the better key
        wins, the following error breaking ties.

        ``redesign``: with the recordings of the winner's try, the search again on the model
        with the inertias they fit (:meth:`_redesign`). Where that runs, its winner is the pick
        and no runner-up is tried: the model then replays the axis's own move to 10-20 counts
        RMS, while on those axes (100-200 Hz, heavy loads) most tries do not settle within
        their watch and the rest rank against the noiseless settling at random (R1-200Hz seed
        5: tries of 0.03, 0.25 and 0.14 s for gains that settle in 22, 14 and 11 ms).
        Each try stays within the axis-time budget of a tuning. Returns the gains, their
        verification move, and the search result and model they came from (the gains' figures
        are that result's)."""
        # The winner's try also feeds the refit: it runs where the ranking offers no runner-up
        # too (R1-200Hz seed 7: none within 1.5 x the winner, so no try and no fit, and gains
        # that settle in 25.5 ms; fitted, 16.3 ms; the oracle 11.0 ms).
        if not design.alternatives and redesign is None:
            return design.gains, step, design, model
        distance, _velocity, acc = profile
        acc *= RANK_TORQUE_SHARE * 3.0  # The verification move accelerates at a third.

        def brisk_speed(d: float) -> tuple[float, float]:
            return min(0.8 * math.sqrt(acc * d), 0.95 * drive.max_velocity), acc

        # Each try's brisk move keeps its overshoot inside the bound: 1.5 x the model's, and a
        # share of the move where the gains have not moved the axis that fast
        # (travel.py); shortened where it must.
        brisk = await self._fit_profile(
            drive, brisk_speed, distance, watch_for(design), "the tries on the axis", design.gains
        )
        return await self._tries(drive, profile, brisk, design, step, model, trust_model, redesign)

    async def _tries(
        self,
        drive: Drive,
        profile: tuple[float, float, float],
        brisk: tuple[float, float, float],
        design: SearchResult,
        step: dict[str, Any],
        model: PlantModel,
        trust_model: bool,
        redesign: Callable[[list[RecordedMove], ServoGains], Awaitable[Redesign | None]] | None,
    ) -> tuple[ServoGains, dict[str, Any], SearchResult, PlantModel]:
        """:meth:`_try_alternatives` with its brisk move fitted to the bound."""
        # Axis time of one try and of the verification move that follows a change (each is
        # there and back): the winner's try, one runner-up (where there is one), that move and
        # the way back to the start must fit to start.
        try_s = 2.0 * move_time(*brisk)
        verify_s = 2.0 * move_time(*profile) + self._return_s(drive, profile)
        tries = 2.0 if design.alternatives else 1.0
        if self.axis_time_s + tries * try_s + verify_s > AXIS_BUDGET_S:
            return design.gains, step, design, model
        if not await self._fits_there_and_back(drive, brisk, design.gains, watch_for(design)):
            self._notes.append(
                "no gains tried on the axis: the brisk move of a try may overshoot past the "
                "travel window"
            )
            return design.gains, step, design, model
        best = design.gains
        watch = watch_for(design)
        records: list[RecordedMove] = []
        best_key = await self._try_key(drive, brisk, watch, best, records)
        first = last = design.gains
        redone = await redesign(records, design.gains) if redesign is not None else None
        if redone is not None:
            design, model = redone.design, redone.model
            best = design.gains
        for i, g in enumerate(design.alternatives if redone is None else ()):
            if self.axis_time_s + try_s + verify_s > AXIS_BUDGET_S:
                break
            if not await self._fits_there_and_back(drive, brisk, g, watch):
                self._notes.append(
                    f"runner-up {i + 1} not tried on the axis: its brisk move may overshoot "
                    f"past the travel window"
                )
                continue
            # After a search again (0.86) the progress goes on from there.
            self.progress(min(0.87 + 0.03 * i, 0.97), f"trying runner-up {i + 1} on the axis")
            await self.write_gains(g)
            last = g
            key = await self._try_key(drive, brisk, watch)
            await self._check_healthy()
            log.debug("runner-up %d on the axis: %s (the pick: %s)", i + 1, key, best_key)
            # Trusting the model, a clear lead only: where no try settles within the watch
            # (inf) the axis cannot tell them apart and the model's order stands, and one that
            # settles beats one that does not.
            clear = key[0] < TRY_CLEAR_SHARE * best_key[0]
            better = clear if trust_model else key < best_key
            if better:
                verdict = "taken"
            elif trust_model:
                verdict = (
                    f"not clearly ahead (under {TRY_CLEAR_SHARE:g} x the pick's time), "
                    "the pick kept"
                )
            else:
                verdict = "the pick kept"
            self._notes.append(
                f"runner-up {i + 1} tried on the axis: {_settling_text(key[0], watch)}, the pick "
                f"so far {_settling_text(best_key[0], watch)} (each the faster of a move there "
                f"and back): {verdict}"
            )
            if better:
                best, best_key = g, key
        if last != best:
            await self.write_gains(best)
        if best != first:
            step = await self._verify_move(drive, profile)
            await self._check_healthy()
        return best, step, design.with_gains(best, drive.rate_hz, model), model

    async def _try_key(
        self,
        drive: Drive,
        profile: tuple[float, float, float],
        watch: float = VERIFY_SETTLE_S,
        gains: ServoGains | None = None,
        records: list[RecordedMove] | None = None,
    ) -> tuple[float, float]:
        """How well the gains move the axis there and back: settling to +-10 counts of the
        error's 5 ms mean [s] (the plain figure is the end of the record on a noisy axis:
        :func:`smoothed_settling`; ``watch`` where a move does not settle within it, or only in
        its last :data:`TRY_SETTLED_HOLD_S`), the faster of the two moves (until the first
        session of 2026-12-04 their mean), then the drive's following error RMS [counts], the
        mean of the two moves. The way back used to be driven but not watched:
        watching it gives each try two samples of the torque noise at no extra motion. Which
        noise a try happened to see decides the pick (starting the tries a few milliseconds
        later changed 20 of the benchmark's 104 rows, docs/tuning.md).

        Not the settling to +-100 counts, which used to come between the two: where no try
        came within +-10 counts in the observation window (the slowest axes), it chose gains
        that approach sooner and then creep (R30-400Hz 2.5 -> 1.8 x the oracle on two of four
        seeds without it; docs/tuning.md).

        ``records``: each move as services/tuning/calibrate.py fits the model to it, where the
        recording shows it at the loop rate with the following error (``gains``: those the
        axis ran with)."""
        distance, velocity, acc = profile
        start = float(drive.home)
        keys = []
        for origin, target in ((start, start + distance), (start + distance, start)):
            # The way back waits for arrival too: the next try starts from rest.
            rec, span, fe_rms = await self._watched_move(
                drive, origin, target, velocity, acc, settle=target == start, watch=watch
            )
            settled = smoothed_settling(
                rec.t, target, rec[POSITION], span[1], hold_s=TRY_SETTLED_HOLD_S
            )
            # A move that did not settle within its watch took at least that long: counted
            # so (a censored time), the other move of the try still tells (TRY_SETTLED_HOLD_S).
            keys.append((min(settled, watch), math.inf if fe_rms is None else fe_rms))
            if (
                records is not None
                and gains is not None
                and fe_rms is not None
                and rec.rate_hz == drive.rate_hz
            ):
                written_v, written_acc = as_written(drive, velocity, acc)
                m = recorded_move(
                    position=rec[POSITION],
                    following_error=rec[FOLLOWING_ERROR],
                    torque=rec[self._signal(SIG_TORQUE)],
                    rate_hz=drive.rate_hz,
                    origin=round(origin),
                    target=round(target),
                    velocity=float(written_v),
                    acc=float(written_acc),
                    gains=gains,
                    torque_limit=drive.limit_torque,
                )
                if m is not None:
                    records.append(m)
        a, b = keys
        # The faster move's settling, not the mean of the two: torque noise delays the
        # settling of the error's 5 ms mean (an excursion past the band after the move has
        # come in restarts it), it can hardly advance it, so the slower of two moves of the
        # same gains is the noisier figure (R1-200Hz seed 1: the model's pick 38 ms and not
        # within its 250 ms watch, 144 ms as a mean, lost to a runner-up's 28 / 31 ms that
        # settles 2.5 x slower without noise).
        return (min(a[0], b[0]), (a[1] + b[1]) / 2.0)

    async def _watched_move(
        self,
        drive: Drive,
        origin: float,
        target: float,
        velocity: float,
        acc: float,
        *,
        settle: bool,
        watch: float = VERIFY_SETTLE_S,
    ) -> tuple[Recording, tuple[float, float], float | None]:
        """One move from ``origin`` to ``target`` [counts], watched for ``watch`` seconds
        (:data:`VERIFY_SETTLE_S` unless a try asks longer) after its profile (a try on the
        axis, the verification move): its recording (with the drive's following error 60F4h
        where it records one), its span and that following error's RMS over it [counts], None
        without 60F4h. ``settle``: wait for target reached (:meth:`_run_moves`)."""
        fe = [FOLLOWING_ERROR] if await self._has(FOLLOWING_ERROR) else []
        rec, spans = await self._run_moves(
            drive, [target], velocity, acc, watch, settle=settle, extra=fe, origin=origin
        )
        return rec, spans[0], _following_error_rms(rec, spans[0]) if fe else None

    def _verify_profile(
        self, drive: Drive, inertia: float, distance: float | None = None
    ) -> tuple[float, float, float]:
        """(distance, velocity, acceleration) of the verification move, the same before and
        after: a quarter revolution (or half a smaller window, or ``distance``) at a third of
        the limit."""
        if distance is None:
            distance = drive.verify_distance
        acc = (drive.limit_torque / 3.0) / inertia * drive.counts_per_rev / (2.0 * math.pi)
        velocity = min(0.8 * math.sqrt(acc * distance), 0.95 * drive.max_velocity)
        return distance, velocity, acc

    async def _verify_move(
        self, drive: Drive, profile: tuple[float, float, float]
    ) -> dict[str, Any]:
        distance, velocity, acc = profile
        start = float(drive.home)
        rec, span, fe_rms = await self._watched_move(
            drive, start, start + distance, velocity, acc, settle=False
        )
        # The way back counts its whole profile. Measured from the start it looked like no
        # move, and only its acceleration and braking (2 v / a) were counted: for this
        # profile 22 % short, the whole tuning's axis time 1-3 % (until 2026-11-27).
        back, _ = await self._run_moves(
            drive, [start], velocity, acc, 0.05, settle=True, origin=start + distance
        )
        del back
        pos = rec[POSITION]
        t = rec.t
        t_end = span[1]
        m = move_metrics(t, start + distance, pos, t_end)
        keep = max(1, len(t) // 800)  # The page draws about 800 points.
        return {
            "t_s": [round(float(x), 6) for x in t[::keep]],
            "position": [float(x - start) for x in pos[::keep]],
            "target": distance,
            "unit": "counts",
            "metrics": {
                # The page's figures (docs/tuning.md): settling to +-100 counts after the end
                # of the commanded profile, overshoot as a fraction of the move, the drive's
                # following error RMS during it [counts].
                "settling_s": m.settling_100_s,
                "overshoot": m.overshoot_counts / distance,
                "following_error_rms": fe_rms,
                "settling_10_s": m.settling_10_s,
                "settling_100_s": m.settling_100_s,
                "settling_10_smoothed_s": smoothed_settling(t, start + distance, pos, t_end),
                "overshoot_counts": m.overshoot_counts,
            },
        }


def watch_for(design: SearchResult) -> float:
    """How long a try on the axis is watched after its profile [s]. A slow axis is watched as
    long as the model watched its reference move (10 periods of the design's bandwidth,
    search.REF_HOLD_PERIODS), at least :data:`VERIFY_SETTLE_S`, up to :data:`TRY_WATCH_MAX_S`:
    the tries are judged by their settling, and a 10 Hz axis settles over hundreds of
    milliseconds (the oracle's gains on R30-100Hz: 195 ms). Watching is not motion: the axis
    time does not grow."""
    if design.bandwidth_hz > 0.0:
        return min(TRY_WATCH_MAX_S, max(VERIFY_SETTLE_S, REF_HOLD_PERIODS / design.bandwidth_hz))
    return VERIFY_SETTLE_S


def _settling_text(seconds: float, watch: float) -> str:
    """A try's settling (:meth:`OwnTuning._try_key`, the mean of its two moves) for the notes:
    a try whose moves did not settle counts as its watch."""
    if seconds >= watch:
        return f"not settled within its {1e3 * watch:.3g} ms watch"
    return f"settles in {1e3 * seconds:.3g} ms"


def _following_error_rms(rec: Recording, span: tuple[float, float]) -> float | None:
    """The drive's own following error (60F4h) RMS over a move's commanded profile [counts];
    None when the recording holds no sample of it."""
    t = rec.t
    during = rec[FOLLOWING_ERROR][(t >= span[0]) & (t <= span[1])]
    return float(np.sqrt(np.mean(during**2))) if len(during) else None
