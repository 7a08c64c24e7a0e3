"""The own tuning's moves inside the travel bound (services/tuning/own; services/tuning/travel.py):
each profile-position move planned, checked against the bound (its set-points, the overshoot
its gains may show, a stop's run-out), sent, recorded and observed; moves sized or slowed
until they fit; the way back to where the axis stood."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    CONTROLWORD,
    CW_ENABLE,
    CW_IMMEDIATE,
    CW_NEW_SETPOINT,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    PROFILE_VELOCITY,
    QUICK_STOP_DEC,
    SW_TARGET_REACHED,
    TARGET_POSITION,
    State,
    decode_state,
)
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.model import PlantModel
from servodesk.model.replay import ModelMoves
from servodesk.services.tuning.io import DriveRecorder, Recording
from servodesk.services.tuning.own.base import SIG_TORQUE, Drive
from servodesk.services.tuning.own.safety import Safety
from servodesk.services.tuning.travel import PlannedMove, model_overshoots

#: A move that does not fit is shortened by this factor until it does (at most
#: SHRINK_STEPS times).
SHRINK = 0.85
SHRINK_STEPS = 12

#: Gains no move has run and no model has foretold: what a move of gains not yet known needs
#: in reserve (TravelGuard.fresh_share; _fit_profile ``also_fresh``).
FRESH = ServoGains(kp_pos=math.nan)


class Moves(Safety):
    """Moves planned against the travel bound, sent, recorded and observed."""

    # ------------------------------------------------------------------ the travel bound

    def _set_travel_model(
        self, model: PlantModel, drive: Drive, *, coulomb: float = 0.0, gravity: float = 0.0
    ) -> None:
        """The identified axis the moves' overshoot is foretold on (travel.py
        :func:`model_overshoots`), under the tuning's own torque limit; none where the
        simulation lacks the model's modes (a second resonance): then the measured run-on and
        the new gains' share of the distance alone."""
        moves = ModelMoves.of(
            model,
            drive.rate_hz,
            counts_per_rev=drive.counts_per_rev,
            torque_limit=drive.limit_torque,
            coulomb=coulomb,
            gravity=gravity,
        )
        self._travel_params = moves.params if moves is not None else None
        self.guard.predicted.clear()  # An older model's predictions.

    async def _predict(self, drive: Drive, moves: list[PlannedMove], watch_s: float) -> None:
        """The model's overshoot for ``moves`` it has not foretold yet (in the design worker:
        the first run of the compiled tick loop takes seconds)."""
        params = self._travel_params
        todo = self.guard.needs_model(moves)
        if params is None or not todo:
            return
        job = functools.partial(
            model_overshoots,
            params,
            drive.rate_hz,
            drive.limit_torque,
            [(m.gains, m.distance, m.velocity, m.acc) for m in todo],
            watch_s,
        )
        self.guard.learn_model(todo, await self._compute(job))

    def _there_and_back(
        self, drive: Drive, profile: tuple[float, float, float], gains: ServoGains
    ) -> list[PlannedMove]:
        """A move from :attr:`Drive.home` up by the profile's distance and back, as written."""
        distance, velocity, acc = profile
        v, a = as_written(drive, velocity, acc)
        home = float(drive.home)
        far = float(round(drive.home + distance))  # As _plan rounds the target.
        return [PlannedMove(home, far, v, a, gains), PlannedMove(far, home, v, a, gains)]

    async def _fits_there_and_back(
        self,
        drive: Drive,
        profile: tuple[float, float, float],
        gains: ServoGains,
        watch_s: float,
    ) -> bool:
        moves = self._there_and_back(drive, profile, gains)
        if gains is not FRESH:  # Nothing to simulate: the reserve is its share of the move.
            await self._predict(drive, moves, watch_s)
        return all(self.guard.fits(m) for m in moves)

    async def _fit_profile(
        self,
        drive: Drive,
        size: Callable[[float], tuple[float, float]],
        distance: float,
        watch_s: float,
        what: str,
        gains: ServoGains | None = None,
        *,
        also_fresh: bool = False,
    ) -> tuple[float, float, float]:
        """(distance, velocity, acceleration): ``distance``, or shorter by :data:`SHRINK`
        steps until a move there and back from home with ``gains`` (the present ones), its
        velocity and acceleration ``size(distance)``, fits the bound with its reserve;
        ``also_fresh``: and with gains that have not moved the axis yet (the verification
        move, which the new gains run too). ``what`` names the moves in the note a shortening
        leaves."""
        wanted = distance
        velocity, acc = size(distance)
        sets = [gains or self._gains_now, *([FRESH] if also_fresh else [])]
        for _ in range(SHRINK_STEPS):
            velocity, acc = size(distance)
            fits = [
                await self._fits_there_and_back(drive, (distance, velocity, acc), g, watch_s)
                for g in sets
            ]
            if all(fits):
                break
            distance *= SHRINK
        if distance < wanted:
            self._notes.append(
                f"{what} shortened from {wanted / drive.counts_per_rev:.3g} to "
                f"{distance / drive.counts_per_rev:.3g} rev: their overshoot must stay inside "
                f"the travel window"
            )
        return distance, velocity, acc

    def _model_foretold(self, last: int) -> bool:
        """Whether the model foretold the run-on of the ``last`` moves observed (the present
        gains' verification move there and back) within the reserve it gave them."""
        g = self.guard
        return all(g.foretold(move, past) for move, past in g.log[-last:])

    def _return_s(self, drive: Drive, profile: tuple[float, float, float]) -> float:
        """The axis time of the way back to the start at the profile's speed [s]."""
        return move_time(abs(drive.start_counts - drive.home), profile[1], profile[2])

    async def _return_to_start(self, drive: Drive, velocity: float, acc: float) -> None:
        """From the rest position back to where the axis stood when the tuning began (in
        Operation enabled only; a move like any other, checked against the bound)."""
        if round(self._demand) == drive.start_counts:
            return
        if decode_state(await self._statusword()) is not State.OPERATION_ENABLED:
            return
        await self._run_moves(drive, [drive.start_counts], velocity, acc, 0.05, settle=True)

    # ------------------------------------------------------------------ motion

    def _plan(self, target: float, velocity: float, acc: float, drive: Drive) -> PlannedMove:
        """The move to ``target`` from where the demand rests, as :meth:`_move` writes it."""
        v, a = as_written(drive, velocity, acc)
        return PlannedMove(self._demand, round(target), float(v), float(a), self._gains_now)

    async def _move(self, drive: Drive, target: float, velocity: float, acc: float) -> PlannedMove:
        """An absolute profile-position move (CiA 402-2 §6.5: new set-point on the rising edge
        of bit 4, change immediately), checked against the travel bound first: its set-points,
        the overshoot past its target its gains may show and a stop's run-out
        (:class:`~servodesk.services.tuning.travel.TravelGuard`). The moves are planned to fit;
        one that does not after a move of its gains ran on further than foretold (the way
        back of a verification move or a try, whose way there showed it) is slowed, its
        velocity and acceleration by :data:`SHRINK` steps, until it fits: the run-on grows
        with the speed. Returns the move as sent."""
        planned = plan = self._plan(target, velocity, acc, drive)
        for _ in range(SHRINK_STEPS):
            if self.guard.fits(plan):
                break
            v, a = as_written(drive, plan.velocity * SHRINK, plan.acc * SHRINK)
            plan = replace(plan, velocity=float(v), acc=float(a))
        plan = self.guard.require(plan)  # Refused where even the slowest would not fit.
        if plan.velocity < planned.velocity:
            self._notes.append(
                f"a move to {plan.target:.0f} slowed to {plan.velocity / planned.velocity:.2g} "
                f"x its speed: its gains had run on further than foretold"
            )
        if self._qs_writable and (self._qs_dec is None or plan.acc > self._qs_dec):
            # A dead-man stop then brakes no gentler than the move would have (605Ah option
            # 2: the quick-stop ramp; stop_overrun): 6085h at least the move's deceleration.
            await self.io.write(QUICK_STOP_DEC, round(plan.acc))
            self._qs_dec = plan.acc
        await self.io.write(PROFILE_VELOCITY, round(plan.velocity))
        await self.io.write(PROFILE_ACC, round(plan.acc))
        await self.io.write(PROFILE_DEC, round(plan.acc))
        await self.io.write(TARGET_POSITION, round(plan.target))
        await self.io.write(CONTROLWORD, CW_ENABLE | CW_IMMEDIATE)
        await self.io.write(CONTROLWORD, CW_ENABLE | CW_IMMEDIATE | CW_NEW_SETPOINT)
        await self.io.write(CONTROLWORD, CW_ENABLE | CW_IMMEDIATE)
        self._demand = plan.target
        self._moves.append(plan)
        return plan

    async def _wait_reached(self, timeout_s: float) -> bool:
        """Until the drive reports target reached (statusword bit 10), at most ``timeout_s``
        (an untuned axis may creep into its window for long: the metrics then say so)."""
        start = self.io.now()
        while not await self._statusword() & SW_TARGET_REACHED:
            if self.io.now() - start > timeout_s:
                return False
            await self.io.sleep(0.002)
        return True

    async def _run_moves(
        self,
        drive: Drive,
        targets: list[float],
        velocity: float,
        acc: float,
        rest_s: float,
        *,
        settle: bool = False,
        extra: list[ObjectAddress] | None = None,
        origin: float | None = None,
    ) -> tuple[Recording, list[tuple[float, float]]]:
        """Moves one after the other, recorded (position, torque command) at the loop rate
        (or a divider that makes the recording fit). Returns the recording and each move's
        (start, end of its commanded profile) in recording time. ``settle``: each move waits
        for target reached (verification); otherwise the next starts ``rest_s`` after the
        profile's end, wherever the axis is (identification needs motion, not arrival).
        ``origin``: where the first move starts (default: where the demand rests); the
        moves' durations, and so the recording's length and the axis time, follow from it.
        Each move's recorded positions, until the next move starts, tell the travel guard how
        far its gains ran on past its target (TravelGuard.observe)."""
        first = self._demand if origin is None else origin
        distance = max(abs(b - a) for a, b in zip([first, *targets], targets, strict=False))
        duration = move_time(distance, velocity, acc)
        # Room for the axis to arrive late (an untuned loop lags its profile).
        total = len(targets) * (duration + rest_s) + 0.02
        rec = DriveRecorder(self.io, drive.rate_hz)
        assert rec.spec is not None
        divider = max(1, math.ceil(total * drive.rate_hz / rec.spec.max_depth))
        torque = self._signal(SIG_TORQUE)
        await rec.configure([POSITION, torque, *(extra or [])], total, divider)
        await rec.start()
        t0 = self.io.now()
        spans: list[tuple[float, float]] = []
        sent = len(self._moves)
        for target in targets:
            start = self.io.now() - t0
            plan = await self._move(drive, target, velocity, acc)
            took = duration
            if plan.velocity < as_written(drive, velocity, acc)[0]:
                # Slowed (_move): as long as it takes now.
                took = move_time(abs(plan.distance), plan.velocity, plan.acc)
            spans.append((start, start + took))
            await self.io.sleep(took)
            if settle:
                await self._wait_reached(1.0)
            await self.io.sleep(rest_s)
            await self._check_healthy()
            self.axis_time_s += took
        recording = await rec.finish()
        self._account(drive, recording[POSITION], recording[torque])
        t = recording.t
        ends = [s for s, _e in spans[1:]] + [math.inf]
        for plan, (begin, _end), until in zip(self._moves[sent:], spans, ends, strict=True):
            self.guard.observe(plan, recording[POSITION][(t >= begin) & (t < until)])
        return recording, spans

    def _account(self, drive: Drive, position: np.ndarray, torque: np.ndarray) -> None:
        if len(position):
            lo = (float(position.min()) - drive.start_counts) / drive.counts_per_rev
            hi = (float(position.max()) - drive.start_counts) / drive.counts_per_rev
            self.excursion = (min(self.excursion[0], lo), max(self.excursion[1], hi))
        if len(torque):
            self.peak_torque = max(self.peak_torque, float(np.max(np.abs(torque))))


def as_written(drive: Drive, velocity: float, acc: float) -> tuple[int, int]:
    """The profile velocity (6081h) and acceleration (6083h, 6084h) a move writes, in whole
    counts per second and per second²: within the drive's 607Fh, and within UNSIGNED32 so
    that a wild estimate does not become a refused write."""
    v = min(velocity, drive.max_velocity, 0xFFFFFFFF)
    return max(1, round(v)), max(1, round(min(acc, 0xFFFFFFFF)))


def move_time(distance: float, velocity: float, acc: float) -> float:
    """Duration of one trapezoidal profile move [s] (the drive's profile position, 6081h/6083h)."""
    cruise = max(0.0, distance / velocity - velocity / acc)
    return 2.0 * velocity / acc + cruise
