"""The travel window of servodesk's own tuning (docs/tuning.md, "Travel window").

The user confirms a window W, a total width centred on where the axis stands, and the page and
the API say "the axis stays within +- W/2" in revolutions and in counts. What the tuning must
hold to: the axis position never leaves that, whatever the excitation (the frequency response's
travel, the test moves, the verification moves, the tries of new gains on the axis) and
however the tuning ends; the drive's software position limits 607Dh hold the same bound
meanwhile, and everything the tuning changed is back afterwards.

The excursion is sampled on the simulated plant after every loop tick (the drive's encoder
reading, what 6064h reports), not polled over the bus, where a peak between two polls would
not be seen. Until the first session of 2026-12-07 the tuning took W as +- W and travelled
0.45 rev one way in a 0.5 rev window confirmed as +-0.25 rev: 0.449-0.465 rev from the start on
these plants.
"""

from __future__ import annotations

import asyncio
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from servodesk.benchmarks.tuning import (
    TORQUE_LIMIT_PCT,
    TRAVEL_WINDOW_REV,
    SimIO,
    build_drive,
    default_plants,
)
from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import Access, DeviceProfile, ObjectSpec
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.travel import TravelBound, bound_text, half_window, stop_overrun
from servodesk.errors import ServodeskError
from servodesk.model.plantfile import PlantSpec, load_plant_file
from servodesk.services.tuning.own import OwnTuning, OwnTuningRequest
from servodesk.services.tuning.travel import (
    MIN_RESERVE_SHARE,
    NEW_GAINS_SHARE,
    RESERVE_FACTOR,
    PlannedMove,
    TravelExceeded,
    TravelGuard,
)

PLANT_FILES = Path(__file__).resolve().parents[2] / "bench" / "plants"


def _plants() -> list[tuple[str, PlantSpec]]:
    """The benchmark's 26 plants (``servodesk bench tuning``) and every plant file of
    bench/plants."""
    files = [(p.stem, load_plant_file(p)) for p in sorted(PLANT_FILES.glob("*.toml"))]
    assert files, f"no plant files in {PLANT_FILES}"
    return [*default_plants(), *files]


class _Reach:
    """The largest distance from ``start`` the motor's encoder (the drive's 6064h) and the load
    reach, read after every plant sub-step (one servo loop tick) [counts]."""

    def __init__(self, drive: Any) -> None:
        self.plant = drive.plant
        self.start = float(drive.read(0x6064, 0))
        self.motor = 0.0
        self.load = 0.0
        self._scale = self.plant.counts_per_rad

    def __call__(self) -> None:
        m = abs(self.plant.encoder_counts - self.start)
        if m > self.motor:
            self.motor = m
        ld = abs(self.plant.mechanics.load_position * self._scale - self.start)
        if ld > self.load:
            self.load = ld


def _request(spec: PlantSpec, window: float = TRAVEL_WINDOW_REV) -> OwnTuningRequest:
    """As ``servodesk bench tuning`` asks (benchmarks/tuning.py ``tune``)."""
    move = 100.0 * spec.peak_torque / spec.rated_torque
    return OwnTuningRequest("high", window, TORQUE_LIMIT_PCT, move)


def _run(tuning: OwnTuning) -> dict[str, Any] | ServodeskError:
    """The tuning's result, or the error it ended with (a refusal is an end like any other:
    the bound holds either way)."""
    try:
        return asyncio.run(tuning.run())
    except ServodeskError as exc:
        return exc


@pytest.mark.parametrize(("name", "spec"), _plants(), ids=[n for n, _s in _plants()])
def test_the_axis_never_leaves_the_window_it_was_confirmed(name: str, spec: PlantSpec) -> None:
    drive = build_drive(spec)
    cpr = spec.encoder_counts
    # The bound the Tuning page and the API confirm for this window: +- half of it.
    half = half_window(TRAVEL_WINDOW_REV, cpr)
    before = [drive.read(0x607D, 1), drive.read(0x607D, 2), drive.read(0x6085, 0)]
    reach = _Reach(drive)
    drive.on_substep(reach)
    out = _run(OwnTuning(SimIO(drive), _request(spec), offload=False))
    drive.remove_substep_hook(reach)
    assert reach.motor <= half, (
        f"{name}: the axis went {reach.motor / cpr:.4f} rev ({reach.motor:.0f} counts) from the "
        f"start, {(reach.motor - half) / cpr:.4f} rev past the confirmed ±{half / cpr:g} rev "
        f"(the load {reach.load / cpr:.4f} rev); the tuning ended "
        f"{out if isinstance(out, Exception) else 'done'}"
    )
    # Everything the tuning set for the run is back: the software limits and the quick stop.
    assert [drive.read(0x607D, 1), drive.read(0x607D, 2), drive.read(0x6085, 0)] == before
    if isinstance(out, dict):
        # The result says the bound and what was reached, within what the plant saw (the
        # recorder samples at the loop rate, or a divider of it on long records).
        travel = out["travel"]
        assert travel["half"] == half and travel["start"] == round(reach.start)
        assert travel["max_excursion"] <= reach.motor + 1
        assert travel["software_limits"] is True
        # And the axis is back where it stood (within a few counts of creep).
        assert abs(drive.read(0x6064, 0) - reach.start) < 0.005 * cpr


# ----------------------------------------------------------------------------- the pieces


def test_half_the_window_is_rounded_down_so_the_bound_is_never_wider_than_confirmed() -> None:
    assert half_window(0.5, 1 << 20) == 262144
    assert half_window(0.5, 131072) == 32768
    # 0.3 rev of 100001 units is 30000.3: 15000 either side, not 15000.15 rounded up.
    assert half_window(0.3, 100001) == 15000
    assert half_window(1e-9, 1000) == 1  # At least one unit.
    b = TravelBound(1000, half_window(0.5, 131072))
    assert (b.low, b.high) == (1000 - 32768, 1000 + 32768)
    assert b.contains(b.low, b.high) and not b.contains(b.low - 1, b.high)


def test_the_bound_is_said_in_revolutions_and_counts_side_by_side() -> None:
    b = TravelBound(1000, 32768)
    text = bound_text(b, 131072, "inc", unit="deg", scale=360.0 / 131072)
    assert text == "±0.25 rev (±90 deg) = ±32768 inc around 1000: -31768 … 33768 inc"
    assert bound_text(b, 131072, None) == "±0.25 rev = ±32768 around 1000: -31768 … 33768"


def test_a_stop_gentler_than_the_move_runs_past_its_target() -> None:
    # 11 rev/s braked at 38 rev/s² instead of the move's 1700: 1.6 rev further (the generic
    # profile's 6085h against an identification move of a light axis).
    assert stop_overrun(11.0, 1700.0, 38.0) == pytest.approx(0.5 * 121.0 * (1 / 38 - 1 / 1700))
    assert stop_overrun(11.0, 1700.0, 1700.0) == 0.0
    assert stop_overrun(11.0, 1700.0, None) == 0.0  # At the torque limit: no gentler.
    assert stop_overrun(11.0, 1700.0, 0.0) == math.inf


def test_a_moves_reserve_covers_what_its_gains_showed_and_what_fresh_gains_may_do() -> None:
    guard = TravelGuard(TravelBound(0, 100_000))
    g = ServoGains(kp_pos=100.0, kp_vel=0.01)
    there = PlannedMove(0.0, 20_000.0, 50_000.0, 1e6, g)
    # Gains that never moved the axis: a share of the distance.
    assert guard.reserve(there) == pytest.approx(NEW_GAINS_SHARE * 20_000)
    assert guard.envelope(there) == (0.0, 20_000 + NEW_GAINS_SHARE * 20_000)
    # They ran on 2000 counts past a move at 50000 counts/s: 40 ms at that speed.
    run = np.concatenate([np.linspace(0.0, 20_000.0, 50), [22_000.0, 21_000.0, 20_000.0]])
    guard.observe(guard.require(there), run)
    assert guard.run_on[g] == pytest.approx(0.04)
    back = PlannedMove(20_000.0, 0.0, 50_000.0, 1e6, g)
    assert guard.reserve(back) == pytest.approx(RESERVE_FACTOR * 2000.0)
    # Faster than they have run: the share again, unless the measured run-on needs more.
    fast = PlannedMove(0.0, 20_000.0, 100_000.0, 1e6, g)
    assert guard.reserve(fast) == pytest.approx(NEW_GAINS_SHARE * 20_000)
    # Never less than 1 % of the half-window, the noise's scatter.
    still = PlannedMove(0.0, 20_000.0, 50_000.0, 1e6, ServoGains(kp_pos=1.0))
    guard.fastest[still.gains] = 1e9
    assert guard.reserve(still) == pytest.approx(MIN_RESERVE_SHARE * 100_000)
    # What the model foretells, 1.5 x.
    guard.learn_model([back], [3000.0])
    assert guard.reserve(back) == pytest.approx(RESERVE_FACTOR * 3000.0)
    # A move whose envelope leaves the bound is refused, naming it.
    far = PlannedMove(60_000.0, 98_000.0, 50_000.0, 1e6, g)  # 3000 past its target: 101000.
    with pytest.raises(TravelExceeded, match=r"outside the travel window -100000 \.\. 100000"):
        guard.require(far)


# ----------------------------------------------------------------------------- on the drive

_LIGHT = PlantSpec(inertia_ratio=1.0)  # The fastest moves of the benchmark: up to 23 rev/s.


class _Writes:
    """Every write to the drive, in order: (index, subindex, value)."""

    def __init__(self, drive: Any) -> None:
        self.log: list[tuple[int, int, Any]] = []
        drive.on_write(lambda i, s, v: self.log.append((i, s, v)))

    def first(self, index: int, subindex: int, value: Any = None) -> int:
        return next(
            n
            for n, (i, s, v) in enumerate(self.log)
            if i == index and s == subindex and (value is None or v == value)
        )


def test_the_drives_software_limits_hold_the_bound_from_before_the_first_move() -> None:
    drive = build_drive(_LIGHT)
    writes = _Writes(drive)
    start = drive.read(0x6064, 0)
    half = half_window(TRAVEL_WINDOW_REV, _LIGHT.encoder_counts)
    limits: list[tuple[int, int]] = []

    def on_write(index: int, _sub: int, value: Any) -> None:
        # 607Dh as the drive holds it at each new set-point (CiA 402-2 §6.5: bit 4 rising).
        if index == 0x6040 and value & 0x10:
            limits.append((drive.read(0x607D, 1), drive.read(0x607D, 2)))

    drive.on_write(on_write)
    out = _run(OwnTuning(SimIO(drive), _request(_LIGHT), offload=False))
    assert isinstance(out, dict), out
    assert set(limits) == {(start - half, start + half)}  # Through every move.
    # Written before the first set-point and before the test signal's first start (its
    # control, sub 6 of the generator's object, docs/tuning.md).
    assert drive.profile.tuning.signal_index is not None
    signal = writes.first(drive.profile.tuning.signal_index, 6, 1)
    assert writes.first(0x607D, 2) < min(writes.first(0x6040, 0, 0x3F), signal)
    # Back afterwards (the generic twin's "no limit", +-2^31).
    assert (drive.read(0x607D, 1), drive.read(0x607D, 2)) == (-(2**31), 2**31 - 1)
    assert any("607Dh were" in n for n in out["notes"]), out["notes"]


@pytest.mark.parametrize("end", ["cancelled", "fault"])
def test_the_limits_are_put_back_however_the_tuning_ends(end: str) -> None:
    """A stop or the dead-man cancels the tuning (services/tuning/), a fault fails it: the
    axis comes to rest, then 607Dh, 6085h and the gains are as they were."""
    spec = PlantSpec(inertia_ratio=3.0)
    drive = build_drive(spec)
    keep = [(0x607D, 1), (0x607D, 2), (0x6085, 0), (0x6072, 0), (0x6065, 0), (0x2101, 0)]
    before = [drive.read(i, s) for i, s in keep]
    reach = _Reach(drive)
    drive.on_substep(reach)
    io = SimIO(drive)
    began = drive.time
    struck = False

    async def sleep(seconds: float) -> None:
        nonlocal struck
        drive.step(seconds)
        if not struck and drive.time - began > 2.4:  # In the identification moves.
            struck = True
            if end == "fault":
                drive.raise_fault(0x8611)
            else:
                raise asyncio.CancelledError

    io.sleep = sleep  # type: ignore[method-assign]
    with pytest.raises((asyncio.CancelledError, ServodeskError)):
        asyncio.run(OwnTuning(io, _request(spec), offload=False).run())
    assert [drive.read(i, s) for i, s in keep] == before
    assert reach.motor <= half_window(TRAVEL_WINDOW_REV, spec.encoder_counts)


@pytest.mark.parametrize("halt_first", [True, False], ids=["dead-man", "quick-stop"])
def test_a_stop_at_full_speed_brakes_inside_the_window(halt_first: bool) -> None:
    """The dead-man halts the axis and then quick-stops it; the Operation page's Stop, from any
    client, quick-stops it at once (services/motion/). The generic twin's quick stop ramp
    (6085h) is 38 rev/s²: from the 13 rev/s of a light axis's verification move, where this
    stop comes, the quick stop alone ran the axis 1.2 rev from the start (6085h left as it
    was). The tuning raises 6085h to each move's own deceleration, so the stop ends inside the
    move's set-points, and puts it back once the axis stands."""
    drive = build_drive(_LIGHT)
    qs = drive.read(0x6085, 0)
    half = half_window(TRAVEL_WINDOW_REV, _LIGHT.encoder_counts)
    reach = _Reach(drive)
    drive.on_substep(reach)
    io = SimIO(drive)
    top = 12.0 * _LIGHT.encoder_counts  # Above the test moves' 11 rev/s: a verification move.
    stopped_at: list[float] = []

    async def sleep(seconds: float) -> None:
        # Stepped by the millisecond, so that the stop comes at speed.
        end = drive.time + seconds
        while drive.time < end - 1e-9:
            drive.step(min(0.001, end - drive.time))
            if not stopped_at and abs(drive.plant.velocity_counts) > top:
                stopped_at.append(drive.plant.velocity_counts / _LIGHT.encoder_counts)
                if halt_first:
                    drive.write(0x6040, 0, 0x010F)  # Halt (605Dh = 1: the move's own ramp),
                    drive.step(0.002)  # a bus round trip later ...
                drive.write(0x6040, 0, 0x0002)  # ... quick stop (605Ah = 2: 6085h).
                raise asyncio.CancelledError

    io.sleep = sleep  # type: ignore[method-assign]
    with pytest.raises(asyncio.CancelledError):
        asyncio.run(OwnTuning(io, _request(_LIGHT), offload=False).run())
    assert stopped_at, "the tuning never moved the axis that fast"
    assert reach.motor <= half, (reach.motor / _LIGHT.encoder_counts, stopped_at)
    assert abs(drive.plant.velocity_counts) < 0.01 * _LIGHT.encoder_counts
    assert drive.read(0x6085, 0) == qs


class _ReadOnlySoftLimits:
    """A family whose 607Dh the master cannot write (read-only in its profile)."""

    def __init__(self, profile: DeviceProfile) -> None:
        self._profile = profile

    def __getattr__(self, name: str) -> Any:
        return getattr(self._profile, name)

    def spec(self, address: ObjectAddress) -> ObjectSpec | None:
        s = self._profile.spec(address)
        if s is not None and address.index == 0x607D:
            return s.model_copy(update={"access": Access.RO})
        return s


def test_without_writable_software_limits_the_result_says_only_servodesks_bound_applied() -> None:
    spec = PlantSpec(inertia_ratio=3.0)
    drive = build_drive(spec)
    reach = _Reach(drive)
    drive.on_substep(reach)
    io = SimIO(drive)
    io.profile = _ReadOnlySoftLimits(drive.profile)  # type: ignore[assignment]
    out = _run(OwnTuning(io, _request(spec), offload=False))
    assert isinstance(out, dict), out
    assert any("no writable software position limits (607Dh)" in n for n in out["notes"])
    assert out["travel"]["software_limits"] is False
    assert drive.read(0x607D, 1) == -(2**31)  # Never written.
    assert reach.motor <= half_window(TRAVEL_WINDOW_REV, spec.encoder_counts)


def test_a_small_window_shrinks_every_move_into_it() -> None:
    """A 0.1 rev window (+-0.05 rev): the frequency response's travel, the test moves and the
    verification move all scale with it."""
    spec = PlantSpec(inertia_ratio=3.0, resonance_hz=400.0)
    drive = build_drive(spec)
    reach = _Reach(drive)
    drive.on_substep(reach)
    out = _run(OwnTuning(SimIO(drive), _request(spec, 0.1), offload=False))
    assert reach.motor <= half_window(0.1, spec.encoder_counts), reach.motor / spec.encoder_counts
    assert isinstance(out, dict), out
    assert out["travel"]["half_rev"] == pytest.approx(0.05, rel=1e-4)
