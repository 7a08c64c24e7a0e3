"""The own tuning's identification (services/tuning/own): the frequency response, then test
moves back and forth for the inertia and friction (least squares, in the design worker; a
compliant axis's double integral and gravity from its moves), and which of the estimates the
tuning takes (:meth:`Identification._identify_axis`; domain/tuning/identify.py; the
measurements behind each rule: docs/tuning.md)."""

from __future__ import annotations

import contextlib
import functools
import logging
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import lfilter  # type: ignore[import-untyped]

from servodesk.domain.cia402 import FOLLOWING_ERROR, POSITION
from servodesk.domain.tuning.identify import (
    Frf,
    InertiaEstimate,
    Resonance,
    demand_spans,
    identify_rigid,
    inertia_from_moves,
    moves_gravity,
    plant_from_identification,
    with_hidden_anti_resonance,
)
from servodesk.domain.tuning.model import PlantModel
from servodesk.services.tuning.own.base import (
    SIG_TORQUE,
    VERIFY_SETTLE_S,
    Drive,
    TuningFailed,
)
from servodesk.services.tuning.own.frf import BAND_LOW_HZ, FrequencyResponse, lowest_anti

log = logging.getLogger(__name__)

#: The identification moves' distance at most: this share of the window's width, and
#: IDENT_REV; they run from the verification move's rest position (base.py
#: VERIFY_WINDOW_SHARE, ``Drive.home``).
IDENT_REV = 0.2
IDENT_WINDOW_SHARE = 0.4
#: The identification moves must keep this share of their distance (_identify).
MIN_IDENT_SHARE = 0.5
#: Identification moves: inertial torque as a share of the tuning torque limit.
MOVE_TORQUE_SHARE = 0.35
#: Acceleration phases last at least this many periods of the lowest anti-resonance.
MOVE_AR_PERIODS = 3.0
#: Friction fit window of a compliant axis: short, so that the torque step at each reversal is not
#: smeared into the viscous term; the shaft's oscillation averages out (measured: docs/tuning.md).
FRICTION_WINDOW_S = 0.004
#: The identification moves of a compliant axis start this long after the last one's profile
#: ended, so that the load moves with the motor when the moves' double integral begins
#: (:meth:`OwnTuning._moves_inertia`; measured: docs/tuning.md). Rest is not axis time.
COMPLIANT_MOVES_REST_S = 0.1
#: The moves' double integral is taken for a compliant axis's inertia where friction is less
#: than this share of it on every move ...
MOVES_INERTIAL_SHARE_MIN = 0.6
#: ... and its moves agree within this (relative standard deviation; measured: docs/tuning.md).
MOVES_SPREAD_MAX = 0.015
#: The moves' inertia fitted with a viscous friction (``MovesInertia.with_viscous``) is taken
#: where it parts from the plain one by more than this: viscous friction makes the plain value
#: come out high by its share (measured: docs/tuning.md).
MOVES_VISCOUS_PART = 0.03
#: An axis without a resonance in its frequency response must fit the rigid-body equation
#: within this share of the torque's spread unexplained (measured: docs/tuning.md).
RIGID_RESIDUAL_MAX = 0.3
#: Below this anti-resonance the tuning takes the record fit's whole-axis inertia,
#: J_M (f_r / f_ar)^2 (``RecordFit.total_inertia``): the response's rigid-body band then holds
#: three or fewer of its 7.8 Hz bins (measured: docs/tuning.md).
RECORD_INERTIA_BELOW_HZ = 65.0
#: From there up to this anti-resonance, where the test moves' double integral is not taken, the
#: inertia is the geometric mean of the response's rigid-body band and the record fit's
#: J_M (f_r / f_ar)^2 when they agree within :data:`RECORD_BLEND_AGREE`: their errors are
#: independent (measured: docs/tuning.md).
RECORD_BLEND_BELOW_HZ = 150.0
#: How far apart the two estimates may be for :data:`RECORD_BLEND_BELOW_HZ` (a fit further
#: off fitted something else).
RECORD_BLEND_AGREE = 0.1


@dataclass(frozen=True, slots=True)
class Identified:
    """What the identification found (:meth:`Identification._identify_axis`), as the design
    ranks on it and the result reports it."""

    frf: Frf
    #: The test moves' fit with the inertia taken (the moves', the response's or the record
    #: fit's); its gravity from the moves back and forth where they give one (design.py).
    est: InertiaEstimate
    #: The test moves' cruise speed [rad/s].
    cruise_rad_s: float
    resonances: list[Resonance]
    #: The rigid axis's moves instrumented by the drive's position demand (no tries then).
    instrumented: bool
    #: How far the moves' own inertias spread where their double integral gave the inertia;
    #: None otherwise.
    moves_spread: float | None
    #: The anti-resonance lies below the band measured: placed by the moves' inertia
    #: (``hidden``) or by the record fit (``below_band``).
    hidden: bool
    below_band: bool
    #: The record fit moved a peak (the two estimates disagreed by more than 3 %).
    refitted: bool
    #: The Coulomb friction the ranking takes and the one the frequency response's travel
    #: measured (None: none), chosen after the verification move (Design._with_friction).
    friction: float = 0.0
    travel_friction: float | None = None

    @property
    def unseen(self) -> bool:
        """The frequency response did not show the anti-resonance: the moves' inertia or the
        record fit placed it, its damping too, and the structure search's pick, as sharp as
        that model allows, overshot on the axis (a load 10 x the motor on a 60 Hz shaft,
        damping 0.01: 11 % where the factory gains overshot 6 %, and refused)."""
        return self.hidden or self.below_band

    def model(self, drive: Drive) -> PlantModel:
        """The identified axis (with its viscous friction, for the travel bound)."""
        return plant_from_identification(
            self.est.inertia,
            self.resonances,
            viscous=max(self.est.viscous, 0.0),
            current_loop_hz=drive.current_loop_hz,
        )


class Identification(FrequencyResponse):
    """The axis identified: its inertia, friction, gravity and resonances."""

    async def _identify_axis(self, drive: Drive) -> Identified:
        """The frequency response, the test moves, and the estimates the tuning takes
        (docs/tuning.md, "servodesk's own tuning, as built": inertia, friction)."""
        self.progress(0.05, "frequency response (PRBS torque while travelling)")
        frf = await self._measure_frf(drive)
        j_rough = self._inertia_from_frf(frf, drive, (BAND_LOW_HZ, 4.0 * BAND_LOW_HZ))
        first = self._resonances(frf, j_rough, drive)
        j_frf, frf_band_ok = self._inertia_corrected(frf, drive, first, j_rough)
        # From here the model foretells how far the factory gains overshoot a move
        # (services/tuning/travel.py), besides what the frequency response's moves showed.
        self._set_travel_model(
            plant_from_identification(j_frf, first, current_loop_hz=drive.current_loop_hz),
            drive,
        )
        self.progress(0.3, "inertia and friction (test moves)")
        # An anti-resonance below the band leaves the moves little inertial torque to fit:
        # the record fit's whole-axis inertia stands in when theirs comes out negative.
        early = (await self._anti_below_band(first, j_frf))[1]
        fallback = early.total_inertia if early is not None else None
        # A rigid axis's moves are also recorded with the drive's position demand, which
        # instruments their fit, and its ranking then trusts the model (below).
        instrumented = await self._instrumented(first)
        est, cruise_rad_s = await self._identify(
            drive, j_frf, first, fallback, instrumented=instrumented
        )
        # A compliant axis: the inertia of the frequency response's rigid-body band, with
        # the two-mass shape divided out, is the better estimate (the test moves' fit must
        # smooth over the shaft oscillation); a rigid axis: the moves' fit (friction and
        # gravity apart).
        compliant = any(r.anti_freq_hz for r in first)
        inertia = j_frf if compliant and frf_band_ok else est.inertia
        # Better still, where friction leaves the moves enough inertial torque: their
        # double integral (the benchmark's 400-800 Hz axes over seeds 1-4: |error| median
        # 0.25 %, worst 1.2 %, where the response's band was 0.94 % and 3.9 %,
        # docs/tuning.md).
        from_moves = self._moves_inertia(inertia) if compliant else None
        j_moves, moves_spread = from_moves if from_moves is not None else (None, None)
        if j_moves is not None:
            log.debug("inertia from the moves: %.4g (the response's: %.4g)", j_moves, inertia)
            inertia = j_moves
        est = replace(est, inertia=inertia)
        found = with_hidden_anti_resonance(first, j_frf, inertia, BAND_LOW_HZ)
        hidden = found != first
        if hidden:
            # The frequency response saw the motor alone: the mode's anti-resonance lies
            # below its band, and the moves' inertia places it (identify.py).
            log.debug("anti-resonance below the band measured: %s", found)
        else:
            found = self._resonances(frf, inertia, drive)
        found, below_fit = await self._anti_below_band(found, j_frf)
        below_band = below_fit is not None
        resonances, j_record = await self._sharpen(found)
        # The record fit moved a peak: the two estimates disagreed by more than 3 %.
        refitted = [r.freq_hz for r in resonances] != [r.freq_hz for r in found]
        low = lowest_anti(resonances)
        if (
            j_record is not None
            and j_moves is None
            and low is not None
            and low < RECORD_INERTIA_BELOW_HZ
            # A fit that lands far from both other estimates fitted something else; one
            # that found the anti-resonance below the band agreed with the response's
            # motor inertia instead (_anti_below_band), and there the moves saw part of
            # the load only.
            and (below_band or 0.5 < j_record / inertia < 2.0)
        ):
            # Below a low anti-resonance neither the moves (which must smooth over the
            # swinging load) nor the response's few rigid-body bins place the inertia well
            # (R30-100Hz +14 %, R30-200Hz +10 %, R3-100Hz -27 %); the record fit's
            # J_M (f_r / f_ar)^2 does, within 5 % on the benchmark's six such plants over
            # four noise seeds (docs/tuning.md).
            log.debug("inertia from the record fit: %.4g (was %.4g)", j_record, inertia)
            inertia = j_record
            est = replace(est, inertia=inertia)
        elif (
            j_record is not None
            and j_moves is None
            and frf_band_ok
            and low is not None
            and low < RECORD_BLEND_BELOW_HZ
            and abs(j_record / inertia - 1.0) < RECORD_BLEND_AGREE
        ):
            # Two estimates with independent errors: the response's few rigid-body bins
            # below 0.7 f_ar, two-mass shape divided out, and the fit of the whole record
            # (how far each was off: RECORD_BLEND_BELOW_HZ).
            blended = math.sqrt(j_record * inertia)
            log.debug(
                "inertia: %.4g, between the response's band %.4g and the record fit %.4g",
                blended,
                inertia,
                j_record,
            )
            self._notes.append(
                f"inertia {blended:.4g} kg m^2: the mean of the frequency response's "
                f"rigid-body band ({inertia:.4g}) and the fit of its whole record "
                f"({j_record:.4g})"
            )
            inertia = blended
            est = replace(est, inertia=inertia)
        return Identified(
            frf=frf,
            est=est,
            cruise_rad_s=cruise_rad_s,
            resonances=resonances,
            instrumented=instrumented,
            moves_spread=moves_spread,
            hidden=hidden,
            below_band=below_band,
            refitted=refitted,
        )

    def _moves_inertia(self, inertia: float) -> tuple[float, float] | None:
        """A compliant axis's inertia from the double integral of its identification moves
        (:func:`inertia_from_moves`) and how far the moves' own inertias spread
        (:attr:`MovesInertia.spread`), or None where that cannot be trusted. Only the moves in
        the frequency response's direction are taken: the mean torque of its constant-speed
        travel is their friction and gravity (:func:`travel_load_torque`, within 1 % on the
        benchmark's axes where the moves' fit was up to 25 % off), and the way back would need
        the gravity apart. ``inertia``: the estimate so far, for the travel's small inertial
        share. Taken when friction is a small share of every move's double integral and the
        moves agree (:data:`MOVES_INERTIAL_SHARE_MIN`, :data:`MOVES_SPREAD_MAX`); fitted with a
        viscous friction where that changes it (:data:`MOVES_VISCOUS_PART`)."""
        if self._moves_record is None:
            return None
        rate, torque, position, demand = self._moves_record
        try:
            load, speed = self._travel_load(inertia)
            way = 1.0 if speed >= 0.0 else -1.0
            spans = [(a, b) for a, b in demand_spans(demand) if (demand[b] - demand[a]) * way > 0]
            moves = inertia_from_moves(rate, torque, position, spans, load, load_speed=speed)
        except ValueError as exc:
            log.debug("no inertia from the moves' double integral: %s", exc)
            return None
        log.debug("inertia from the moves' double integral: %s", moves)
        if moves.inertial_share < MOVES_INERTIAL_SHARE_MIN or moves.spread > MOVES_SPREAD_MAX:
            return None
        j = moves.inertia
        if abs(moves.with_viscous / j - 1.0) > MOVES_VISCOUS_PART:
            j = moves.with_viscous
        return (j, moves.spread) if j > 0.0 else None

    def _moves_gravity(self, inertia: float) -> float | None:
        """A compliant axis's gravity torque [N m] from its identification moves back and
        forth (:func:`moves_gravity`), or None without their record or a move each way."""
        if self._moves_record is None:
            return None
        rate, torque, position, demand = self._moves_record
        try:
            g = moves_gravity(rate, torque, position, demand_spans(demand), inertia)
        except ValueError as exc:
            log.debug("no gravity from the moves: %s", exc)
            return None
        log.debug("gravity from the moves back and forth: %.5g N m", g)
        return g

    def _travel_friction(self, inertia: float, gravity: float) -> float | None:
        """The Coulomb friction [N m] from the frequency response's travel: its mean load
        torque (:func:`travel_load_torque`, friction and gravity at a slow constant speed)
        less the moves' ``gravity``; None without that record or where it gives none."""
        try:
            load, speed = self._travel_load(inertia)
        except ValueError as exc:
            log.debug("no friction from the travel: %s", exc)
            return None
        way = 1.0 if speed >= 0.0 else -1.0
        friction = way * (load - gravity)
        log.debug("friction from the travel: %.5g N m (load torque %.5g)", friction, load)
        return friction if friction > 0.0 else None

    def _move_profile(
        self, drive: Drive, inertia: float, resonances: list[Resonance], distance: float
    ) -> tuple[float, float]:
        """(velocity, acceleration) in counts/s and counts/s² for identification moves."""
        acc_rad = MOVE_TORQUE_SHARE * drive.limit_torque / inertia
        f_ar = lowest_anti(resonances)
        if f_ar is not None:
            # Accelerate for MOVE_AR_PERIODS periods of the lowest anti-resonance or longer:
            # t_acc = sqrt(d / a) for a triangular move.
            d_rad = distance * 2.0 * math.pi / drive.counts_per_rev
            acc_rad = min(acc_rad, d_rad * (f_ar / MOVE_AR_PERIODS) ** 2)
        acc = acc_rad * drive.counts_per_rev / (2.0 * math.pi)
        # A cruise at constant speed between the ramps: Coulomb and viscous friction show
        # there, apart from the inertia (accelerating) and the standstill (stick) samples.
        velocity = min(0.6 * math.sqrt(acc * distance), 0.95 * drive.max_velocity)
        return velocity, acc

    async def _instrumented(self, resonances: list[Resonance]) -> bool:
        """Whether the test moves' fit is instrumented by the drive's position demand
        (:func:`identify_rigid`): on a rigid axis (no resonance in the frequency response)
        of a drive that records its following error 60F4h. On a compliant axis the moves'
        fit smooths over the shaft's oscillation, and its inertia is not the one taken."""
        return not resonances and await self._has(FOLLOWING_ERROR)

    async def _identify(
        self,
        drive: Drive,
        j_frf: float,
        resonances: list[Resonance],
        fallback_inertia: float | None = None,
        *,
        instrumented: bool = False,
    ) -> tuple[InertiaEstimate, float]:
        """Inertia and friction from test moves, and the moves' cruise speed [rad/s].
        ``fallback_inertia``: the record fit's, taken when the moves' fit gives a negative
        inertia (their friction is still used). ``instrumented``: record the following error
        with the moves and instrument the fit with the position demand
        (:meth:`_instrumented`). A compliant axis's moves record it too, kept for their double
        integral (:meth:`_moves_inertia`), and rest :data:`COMPLIANT_MOVES_REST_S` apart."""
        wanted = distance = min(IDENT_REV * drive.counts_per_rev, IDENT_WINDOW_SHARE * drive.width)
        inertia = j_frf
        est: InertiaEstimate | None = None
        f_ar = lowest_anti(resonances)
        window_s = max(0.0005, 4.0 / f_ar) if f_ar is not None else 0.0005
        # A compliant axis's moves record the demand too, for their double integral
        # (_moves_inertia), and rest until the load has stopped swinging.
        with_demand = instrumented or (bool(resonances) and await self._has(FOLLOWING_ERROR))
        rest_s = COMPLIANT_MOVES_REST_S if resonances else 0.01
        for _attempt in range(2):
            # Their overshoot inside the bound (the moves go home -> home + d and back; the
            # frequency response's moves told the factory gains' run-on).
            distance, velocity, acc = await self._fit_profile(
                drive,
                functools.partial(self._move_profile, drive, inertia, resonances),
                distance,
                VERIFY_SETTLE_S,
                "the identification moves",
            )
            if distance < MIN_IDENT_SHARE * wanted:
                # Moves that short, on an axis that overshoots that far, tell neither its
                # inertia nor a compliance below the band (the rigid-body check below): a load
                # 100 x the motor behind a 3 Hz anti-resonance passed it with moves of 0.028
                # rev, and its gains never settled on the real axis.
                raise TuningFailed(
                    f"the test moves would have to be shortened to "
                    f"{distance / drive.counts_per_rev:.3g} rev (from "
                    f"{wanted / drive.counts_per_rev:.3g}) to keep the axis's overshoot inside "
                    f"the travel window: too short to identify it",
                    hint="give a wider travel window, or tune this axis by hand, starting from "
                    "low gains",
                )
            rec, _spans = await self._run_moves(
                drive,
                [drive.home + distance, drive.home] * 3,
                velocity,
                acc,
                rest_s,
                extra=[FOLLOWING_ERROR] if with_demand else None,
            )
            rad = 2.0 * math.pi / drive.counts_per_rev
            # The recorded torque command is the one reaching the current loop on that tick
            # (the compute delay is behind it); the torque at the shaft is that through the
            # current loop, a first-order lag at its bandwidth.
            torque = rec[self._signal(SIG_TORQUE)]
            if drive.current_loop_hz:
                alpha = 1.0 - math.exp(-2.0 * math.pi * drive.current_loop_hz / rec.rate_hz)
                torque = lfilter([alpha], [1.0, alpha - 1.0], torque)
            position = rec[POSITION] * rad
            # 60F4h: the demand minus the position (CiA 402-2 §6.9.2); summed in counts, as
            # radians their sum would change by rounding at rest (demand_spans).
            demand = (rec[POSITION] + rec[FOLLOWING_ERROR]) * rad if with_demand else None
            if demand is not None and resonances:
                self._moves_record = (rec.rate_hz, torque, position, demand)
            try:
                # In the worker: its Savitzky-Golay filters over the moves' record take 40-90 ms.
                est = await self._compute(
                    functools.partial(
                        identify_rigid,
                        rec.rate_hz,
                        torque,
                        position_rad=position,
                        window_s=window_s,
                        instrument_rad=demand if instrumented else None,
                    )
                )
            except ValueError as exc:
                raise TuningFailed(f"the test moves give no inertia: {exc}") from exc
            log.debug("identification pass: sized for J=%.4g, got %s", inertia, est)
            if not est.inertia > 0.0:
                if fallback_inertia is None:
                    raise TuningFailed("the test moves give a negative inertia")
                # A load 6 x the motor on a 60 Hz shaft: the moves, sized for an anti-resonance
                # at the band's edge, accelerate so gently that their inertial torque (0.015
                # N m) is a sixth of the friction, and the fit gives -9.6e-5 kg m^2.
                log.debug("negative inertia from the moves; the record fit's %g", fallback_inertia)
                est = replace(est, inertia=fallback_inertia)
                break
            if 0.7 <= est.inertia / inertia <= 1.4:
                break
            # The moves were sized for another inertia: once more, unless the anti-resonance
            # rather than the inertia set their acceleration (the same moves again).
            resized = self._move_profile(drive, est.inertia, resonances, distance)[1]
            if abs(resized / acc - 1.0) < 0.05:
                break
            inertia = est.inertia
        assert est is not None
        spread = float(np.std(torque))
        if not resonances and spread > 0.0 and est.residual_rms > RIGID_RESIDUAL_MAX * spread:
            # No resonance in the frequency response, yet the moves are no rigid body: the
            # machine has a compliance below the band measured, and a design for what the
            # moves and the response show would be for the motor alone (a load 100 x the
            # motor behind a 3 Hz anti-resonance kept 5 deg of phase margin).
            raise TuningFailed(
                f"the test moves do not fit a rigid axis (the fit leaves "
                f"{100.0 * est.residual_rms / spread:.0f} % of the torque unexplained), and the "
                f"frequency response from {BAND_LOW_HZ:.0f} Hz shows no resonance: the axis "
                f"has a compliance too low to measure (a soft belt, a very heavy or hanging "
                f"load), and gains designed for what can be seen would not be safe",
                hint="tune this axis by hand, starting from low gains",
            )
        if window_s > FRICTION_WINDOW_S:
            with contextlib.suppress(ValueError):
                fr = await self._compute(
                    functools.partial(
                        identify_rigid,
                        rec.rate_hz,
                        torque,
                        position_rad=position,
                        window_s=FRICTION_WINDOW_S,
                    )
                )
                log.debug("friction with a %g s window: %s", FRICTION_WINDOW_S, fr)
                est = replace(est, viscous=fr.viscous, coulomb=fr.coulomb, gravity=fr.gravity)
        return est, velocity * rad
