"""The own tuning's frequency response and what it shows (services/tuning/own): a PRBS torque
from the drive's test signal generator while the axis travels at a constant speed, the
resonances over its rigid-body line, each two-mass mode refined on the whole record (in the
design worker), an anti-resonance below the band, the inertia of its rigid-body band
(domain/tuning/identify.py; docs/tuning.md)."""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import replace

import numpy as np

from servodesk.domain.cia402 import POSITION, VELOCITY
from servodesk.domain.tuning.identify import (
    Frf,
    RecordFit,
    Resonance,
    find_resonances,
    frequency_response,
    inertia_from_frf,
    resonance_from_record,
    travel_load_torque,
)
from servodesk.services.tuning.io import DriveRecorder, Recording
from servodesk.services.tuning.own.base import (
    SIG_AMPLITUDE,
    SIG_CONTROL,
    SIG_DURATION,
    SIG_F0,
    SIG_F1,
    SIG_KIND,
    SIG_PRBS,
    SIG_TORQUE,
    SIG_VALUE,
    Drive,
    TuningFailed,
    quietly,
)
from servodesk.services.tuning.own.moves import SHRINK, SHRINK_STEPS, Moves, move_time

log = logging.getLogger(__name__)

#: Chirp: from this frequency, for this long, at this share of the tuning torque limit.
CHIRP_F0_HZ = 10.0
CHIRP_S = 1.0
CHIRP_SHARE = 0.12
#: The lowest frequency the response is read at, twice the chirp's start: where the search for
#: resonances and dips and the rigid-body band begin.
BAND_LOW_HZ = 2.0 * CHIRP_F0_HZ
#: The frequency response is measured travelling this far (anchors-tuning.md §3.5: at most +-0.25
#: rev per frequency response) ...
FRF_TRAVEL_REV = 0.45
#: ... centred on the start, each end at most this share of the half-window from it: its way up, the
#: first move, keeps the rest in reserve for run-on nothing yet foretells (measured:
#: docs/tuning.md).
FRF_HALF_SHARE = 0.9
#: The way up to the travel's start accelerates and brakes over this long, and the axis rests there
#: this long before the travel, so that a soft load has stopped swinging (measured: docs/tuning.md).
#: Resting is not axis time.
FRF_PRE_RAMP_S = 0.25
FRF_REST_S = 1.0
#: The recording of the frequency response's travel goes on this long after its profile ends, with
#: the position, so that what the travel ran on past its end is measured, not guessed.
FRF_TAIL_S = 0.15
#: An anti-resonance the record fit finds below the band is taken when its motor inertia is
#: within this fraction of the frequency response's (OwnTuning._anti_below_band) ...
BELOW_BAND_MOTOR_TOL = 0.25
#: ... and its anti-resonance lies below this multiple of the band's lower edge: the peak
#: finder needs bins on both sides of a dip (8 Hz apart), so one within a bin of the edge
#: does not show either (a load 8 x the motor on a 60 Hz shaft: 20.0 Hz).
BELOW_BAND_EDGE = 1.25


class FrequencyResponse(Moves):
    """The frequency response measured, its resonances found and refined."""

    async def _measure_frf(self, drive: Drive) -> Frf:
        """The plant's frequency response: a PRBS torque from the drive's signal generator
        while the axis travels at a constant speed (a profile-position move across the
        window), so that Coulomb friction is a constant torque rather than stick-slip, which
        would make a small-signal response look stiffer than the machine (anchors-tuning.md
        §3.7: "use a velocity offset").

        The travel is centred on the start, downward (+-0.225 rev at 0.39 rev/s in the
        default 0.5 rev window; until the first session of 2026-12-07 it went 0.45 rev up from
        the start, in a window confirmed as +-0.25 rev). The way up to its start is the
        tuning's first move (:data:`FRF_HALF_SHARE`, :data:`FRF_PRE_RAMP_S`); what it runs on
        past its end (the factory gains' run-on, services/tuning/travel.py) sizes the travel,
        and the travel's own what follows. The way back ends at :attr:`Drive.home`, where the
        identification moves start."""
        r_addr = self._signal(SIG_VALUE)
        t_addr = self._signal(SIG_TORQUE)
        guard = self.guard
        bound = drive.bound
        start = float(drive.start_counts)
        distance = float(
            math.floor(
                min(FRF_TRAVEL_REV * drive.counts_per_rev, 2.0 * FRF_HALF_SHARE * bound.half)
            )
        )
        velocity = min(distance / (CHIRP_S + 0.15), 0.95 * drive.max_velocity)
        acc = velocity / 0.02  # At speed within 20 ms, long before the recording starts.
        # Downward: where the axis comes back to afterwards, the rest below the start
        # (:attr:`Drive.home`), is then a short way on. Upward, with the way back across the
        # window, the benchmark's settling was worse on every variant measured (seeds 1-4:
        # geometric mean 1.13 against 1.08 x the oracle, 95 against 99 rows within 2 x;
        # docs/tuning.md).
        high = start + round(distance / 2.0)
        low = high - round(distance)
        # The first move, up to where the travel starts: at the travel's speed with gentle
        # ramps, which leave a heavy load behind a soft shaft hardly swinging when the travel
        # starts (FRF_PRE_RAMP_S, FRF_REST_S; at twice the speed the benchmark's 400-800 Hz axes
        # came out worse); its reserve is what the half-window leaves past its end.
        self._slow = (velocity, velocity / FRF_PRE_RAMP_S)
        guard.fresh_reserve = bound.high - high
        try:
            await self._run_moves(drive, [high], *self._slow, FRF_REST_S, settle=True)
        finally:
            guard.fresh_reserve = None
        # The travel down: what the first move ran on past its end, at the same speed, with
        # the integral wound up against the friction over a cruise as long, sizes it (shortened
        # at its far end where it must be).
        for _ in range(SHRINK_STEPS):
            if guard.fits(self._plan(low, velocity, acc, drive)):
                break
            distance *= SHRINK
            velocity = min(distance / (CHIRP_S + 0.15), 0.95 * drive.max_velocity)
            acc = velocity / 0.02
            low = high - round(distance)
        seconds = CHIRP_S + 0.02
        rec = DriveRecorder(self.io, drive.rate_hz)
        assert rec.spec is not None
        # The position too where the recorder has a channel for it, through the travel's end.
        with_position = rec.spec.max_channels >= 4
        channels = [r_addr, t_addr, VELOCITY, *([POSITION] if with_position else [])]
        travel_s = move_time(distance, velocity, acc)
        await rec.configure(
            channels, max(seconds, travel_s + FRF_TAIL_S) if with_position else seconds
        )
        await self.io.write(self._signal(SIG_KIND), SIG_PRBS)
        await self.io.write(self._signal(SIG_AMPLITUDE), CHIRP_SHARE * drive.limit_torque)
        await self.io.write(self._signal(SIG_F0), CHIRP_F0_HZ)
        await self.io.write(self._signal(SIG_F1), min(0.25 * drive.rate_hz, 4000.0))
        await self.io.write(self._signal(SIG_DURATION), CHIRP_S)
        await self._move(drive, low, velocity, acc)
        travel = self._moves[-1]
        await self.io.sleep(0.06)
        await rec.start()
        await self.io.write(self._signal(SIG_CONTROL), 1)
        try:
            await self.io.sleep(seconds)
        finally:
            await quietly(self.io.write(self._signal(SIG_CONTROL), 0))
        whole = await rec.finish()
        await self._check_healthy()
        await self._wait_reached(1.0)
        # The travel ramps included (until the second session of 2026-11-27 counted without).
        self.axis_time_s += travel_s
        if with_position:
            self._account(drive, whole[POSITION], np.zeros(0))
            guard.observe(travel, whole[POSITION])
        else:
            self.excursion = (
                min(self.excursion[0], (low - start) / drive.counts_per_rev),
                max(self.excursion[1], (high - start) / drive.counts_per_rev),
            )
        # The response from the test signal's second only, as before the tail was recorded.
        n = min(whole.samples, round(seconds * whole.rate_hz))
        recording = Recording(whole.rate_hz, {a: x[:n] for a, x in whole.channels.items()})
        # Back up to the rest the identification moves start from, at twice the speed (since
        # the second session of 2026-11-27).
        drive.home = drive.start_counts - math.floor(drive.verify_distance / 2.0)
        await self._run_moves(drive, [drive.home], 2.0 * velocity, acc, 0.05, settle=True)
        rad = 2.0 * math.pi / drive.counts_per_rev
        velocity_rad = recording[VELOCITY] * rad
        self._account(drive, np.zeros(0), recording[t_addr])
        nperseg = 1 << max(8, round(math.log2(recording.rate_hz / 8.0)))
        self._frf_record = (recording.rate_hz, recording[r_addr], recording[t_addr], velocity_rad)
        return frequency_response(
            recording.rate_hz,
            recording[r_addr],
            recording[t_addr],
            velocity_rad,
            nperseg=min(nperseg, recording.samples),
            f_min_hz=CHIRP_F0_HZ,
        )

    def _travel_load(self, inertia: float) -> tuple[float, float]:
        """The frequency response's travel: its mean load torque [N m], friction and gravity
        (:func:`travel_load_torque`; ``inertia`` for its small inertial share), and its mean
        speed [rad/s]. ValueError without that record or where it is too short."""
        if self._frf_record is None:
            raise ValueError("no frequency response recorded")
        rate, _signal, torque, speed = self._frf_record
        return travel_load_torque(rate, torque, speed, inertia), float(np.mean(speed))

    async def _sharpen(self, resonances: list[Resonance]) -> tuple[list[Resonance], float | None]:
        """Each two-mass resonance refined from the whole record
        (:func:`resonance_from_record`): its damping and anti-resonance always (the Welch
        estimate smears a sharp mode wide, and puts a low anti-resonance where a few coarse
        bins fall: R30-100Hz's 18 Hz at 20-21 Hz, which split the inertia 45 % wrong), its
        frequency when the two estimates differ by more than 3 % (a noise bump moved the
        Welch peak). Also returns the total inertia of the lowest mode's fit (None without
        one)."""
        if self._frf_record is None:
            return resonances, None
        out = []
        total: float | None = None
        lowest = min(resonances, key=lambda r: r.freq_hz) if resonances else None
        for r in resonances:
            fit = await self._record_fit(r)
            if fit is None:
                out.append(r)
                continue
            fr = fit.freq_hz if abs(fit.freq_hz / r.freq_hz - 1.0) > 0.03 else r.freq_hz
            anti = fit.anti_freq_hz if fit.anti_freq_hz is not None else r.anti_freq_hz
            if anti is not None and anti >= fr:
                anti = r.anti_freq_hz
            out.append(replace(r, freq_hz=fr, anti_freq_hz=anti, damping_estimate=fit.damping))
            if r is lowest:
                total = fit.total_inertia
        return out, total

    async def _anti_below_band(
        self, resonances: list[Resonance], j_frf: float
    ) -> tuple[list[Resonance], RecordFit | None]:
        """The lowest resonance with its anti-resonance from the record fit when the response
        shows a peak without a dip and the test moves did not place one
        (:func:`with_hidden_anti_resonance`); (resonances, the fit when it placed one).

        A two-mass mode whose anti-resonance lies just below the band measured: a load 10 x the
        motor on a 60 Hz shaft has it at 18 Hz. The moves, sized for an anti-resonance at the band's
        edge (:func:`lowest_anti`), fit 35 % of the inertia there, which puts the anti-resonance at
        33 Hz, inside the band, so the rule above does not apply. The record fit is started with the
        anti-resonance at the band's lower edge, and both it and the motor's inertia are free
        parameters of the fit: on that axis it returns 17.9-18.1 Hz and the total inertia within 6 %
        (docs/tuning.md). It is taken only when the fitted anti-resonance lies below the band or
        within a bin of its edge (:data:`BELOW_BAND_EDGE`; further inside, the dip would have shown)
        and the fitted motor inertia agrees with the response's (:data:`BELOW_BAND_MOTOR_TOL`):
        otherwise the peak is not such a mode."""
        if self._frf_record is None or not resonances:
            return resonances, None
        i = min(range(len(resonances)), key=lambda k: resonances[k].freq_hz)
        r = resonances[i]
        if r.anti_freq_hz is not None:
            return resonances, None
        fit = await self._record_fit(replace(r, anti_freq_hz=BAND_LOW_HZ))
        if (
            fit is None
            or fit.anti_freq_hz is None
            or fit.motor_inertia is None
            or not fit.anti_freq_hz < BELOW_BAND_EDGE * BAND_LOW_HZ
            or abs(fit.motor_inertia / j_frf - 1.0) > BELOW_BAND_MOTOR_TOL
        ):
            return resonances, None
        log.debug("anti-resonance below the band from the record fit: %s", fit)
        out = list(resonances)
        out[i] = replace(r, freq_hz=fit.freq_hz, anti_freq_hz=fit.anti_freq_hz)
        return out, fit

    async def _record_fit(self, resonance: Resonance) -> RecordFit | None:
        """:func:`resonance_from_record` on the frequency response's record, in the design's
        worker process when offloading: one fit is 20-40 ms of arithmetic, a tuning runs up to
        four, and the event loop carries the operator's heartbeats meanwhile."""
        assert self._frf_record is not None
        return await self._compute(
            functools.partial(resonance_from_record, *self._frf_record, resonance)
        )

    def _resonances(self, frf: Frf, inertia: float, drive: Drive) -> list[Resonance]:
        """Resonances up to an eighth of the loop rate (plant files allow no higher), and
        below twice the current loop bandwidth: above that the measured response is the
        current loop's roll-off and quantisation, not the machine's."""
        top = drive.rate_hz / 8.0
        if drive.current_loop_hz:
            top = min(top, 2.0 * drive.current_loop_hz)
        return find_resonances(frf, inertia, min_freq_hz=BAND_LOW_HZ, max_freq_hz=top)

    def _inertia_from_frf(self, frf: Frf, drive: Drive, band: tuple[float, float]) -> float:
        try:
            return inertia_from_frf(frf, band, current_loop_hz=drive.current_loop_hz)
        except ValueError as exc:
            raise TuningFailed(
                f"the frequency response gives no inertia: {exc}",
                hint="check that the axis is free to move and the torque limit is not tiny",
            ) from exc

    def _inertia_corrected(
        self, frf: Frf, drive: Drive, resonances: list[Resonance], rough: float
    ) -> tuple[float, bool]:
        """The total inertia from the rigid-body band below the lowest anti-resonance, the
        two-mass shape divided out (identify.py); (estimate, True when the band was wide
        enough: at least 15 Hz above the lowest frequency measured)."""
        anti = [r.anti_freq_hz for r in resonances if r.anti_freq_hz]
        top = min(0.7 * min(anti), 400.0) if anti else min(400.0, 0.05 * drive.rate_hz)
        lo = BAND_LOW_HZ
        if top < lo + 15.0:
            return rough, False
        try:
            j = inertia_from_frf(
                frf, (lo, top), current_loop_hz=drive.current_loop_hz, resonances=resonances
            )
        except ValueError:
            return rough, False
        return j, True


def lowest_anti(resonances: list[Resonance]) -> float | None:
    """The lowest anti-resonance [Hz], for sizing test moves; None on a rigid axis. When the
    lowest resonance has none, it lies below the band measured (a two-mass mode always has one
    below its peak), and the lowest frequency measured stands in for it."""
    if not resonances:
        return None
    if min(resonances, key=lambda r: r.freq_hz).anti_freq_hz is None:
        return BAND_LOW_HZ
    return min(r.anti_freq_hz for r in resonances if r.anti_freq_hz)
