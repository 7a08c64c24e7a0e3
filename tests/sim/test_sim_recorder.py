"""The simulated drive's drive-side recorder (sim/recorder.py, docs/scope.md).

The recordings are checked against the simulation's own values: a hook on every plant
sub-step (``SimulatedDrive.on_substep``) keeps what the plant was at each step, and every
recorded sample must be that value at that step.
"""

from __future__ import annotations

import itertools
import struct
from typing import Any

import pytest

from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.profile import DeviceProfile, RecorderSpec
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.services.manager import GENERIC_ETHERCAT
from servodesk.sim.engine import SimAbort, SimulatedDrive
from servodesk.sim.recorder import recorder_objects
from tests.sim.support import enable, generic, new_drive

CATALOG = ProfileCatalog()
REV = 131072
POS, VEL, TORQUE, FE = 0x60640020, 0x606C0020, 0x60770010, 0x60F40020
B = 0x2F00  # The generic twin's recorder (docs/scope.md).


class PlantLog:
    """What the plant was after every sub-step: step number -> values."""

    def __init__(self, drive: SimulatedDrive) -> None:
        self.drive = drive
        self.pos: dict[int, int] = {}
        self.vel: dict[int, int] = {}
        self.torque: dict[int, int] = {}
        drive.on_substep(self._on_step)

    def _on_step(self) -> None:
        d = self.drive
        k = d.plant_steps
        self.pos[k] = d.position
        self.vel[k] = round(d.velocity)
        self.torque[k] = round(d.plant.torque / d.plant_params.rated_torque * 1000.0)

    def first_crossing(self, level: int, rising: bool = True) -> int:
        steps = sorted(self.pos)
        for a, b in itertools.pairwise(steps):
            p, v = self.pos[a], self.pos[b]
            if (p < level <= v) if rising else (p > level >= v):
                return b
        raise AssertionError(f"the position never crossed {level}")


def words(drive: SimulatedDrive, channels: int, index: int = B + 7) -> list[tuple[int, ...]]:
    """The uploaded data as rows of signed INTEGER32 words."""
    data = drive.read_bytes(index)
    n = len(data) // 4
    flat = struct.unpack(f"<{n}i", data)
    return [flat[i : i + channels] for i in range(0, n, channels)]


def configure(drive: SimulatedDrive, *channels: int, **objects: int) -> None:
    names = {"divider": 1, "depth": 2, "trigger": 3, "level": 4, "pre": 5}
    for n, entry in enumerate(channels, 1):
        drive.write(B, n, entry)
    for name, value in objects.items():
        drive.write(B + names[name], 0, value)


def move(drive: SimulatedDrive, target: int) -> None:
    drive.write(0x607A, 0, target)
    drive.write(0x6040, 0, 0x3F)  # New set-point, change immediately, absolute.
    drive.step(0.001)
    drive.write(0x6040, 0, 0x0F)


def abort_code(fn: Any, *args: Any) -> int:
    with pytest.raises(SimAbort) as info:
        fn(*args)
    return info.value.code


# ---------------------------------------------------------------------- profiles


# cia402-ethercat is the detection fallback for unknown EtherCAT slaves, not a family: no twin.
@pytest.mark.parametrize("profile_id", [i for i in CATALOG.ids() if i != GENERIC_ETHERCAT])
def test_every_family_has_a_recorder_in_a_free_index_range(profile_id: str) -> None:
    p = CATALOG.get(profile_id)
    spec = p.recorder
    assert spec is not None and spec.sim_only
    assert recorder_objects(p) == []
    lo, hi = spec.index, spec.index + RecorderSpec.TRIGGER_INDEX
    # The range holds the recorder's objects only, all sim_only, inside the manufacturer area.
    assert lo >= 0x2000 and hi <= 0x5FFF
    inside = [e for e in p.objects if lo <= e.index <= hi]
    assert len(inside) == 10 and all(e.sim_only and e.group == "recorder" for e in inside)
    if profile_id == "lecsn-t":
        # 004 §20.1.5.1 PNU areas: 2000h-27FFh, 2800h-29FFh, 2A00h-2FFFh, 6000h-6FFFh.
        assert not 0x2000 <= lo <= 0x2FFF and all(e.pnu == e.index for e in inside)
    if profile_id == "hiwin-e":
        # 000 §3.3: 2XXXh Pt parameters, 3000h-3217h objects, 4XXXh Ut monitors.
        assert lo >= 0x5000
    # What the profile advertises is what the twin samples at.
    drive = SimulatedDrive(p, 1)
    assert drive.recorder is not None
    assert drive.recorder.rate_hz == pytest.approx(spec.rate_hz)
    # The generic twin holds 1.5 s of 3 channels at a plant file's 16 kHz (docs/tuning.md).
    assert spec.max_channels == 8
    assert spec.max_depth == (32768 if profile_id == "cia402-generic" else 8192)
    depth = p.variables[A(spec.object_index(RecorderSpec.DEPTH))]
    assert depth.max == spec.max_depth


def test_recordable_objects() -> None:
    p = generic()
    assert RecorderSpec.recordable(p.variables[A(0x6064)])
    assert RecorderSpec.recordable(p.variables[A(0x6041)])
    assert not RecorderSpec.recordable(p.variables[A(0x1008)])  # VISIBLE_STRING.
    assert not RecorderSpec.recordable(p.variables[A(B + 7)])  # DOMAIN.


# ---------------------------------------------------------------------- recording


def test_level_trigger_records_the_plant_at_every_sub_step() -> None:
    d = new_drive()
    log = PlantLog(d)
    enable(d)
    d.step(0.01)
    start = d.position
    level = start + REV // 4
    depth, pre = 8192, 1638  # The longest recording, 20 % of it before the trigger.
    configure(d, POS, VEL, TORQUE, FE, depth=depth, trigger=1, level=level, pre=pre)
    d.write(B + 6, 0, 1)
    assert d.read(B + 6) == 1  # Waiting for the trigger.
    d.step(0.5)  # Fills the pre-trigger samples at rest.
    assert (d.read(B + 6), d.read(B + 8), d.read(B + 9)) == (1, pre, 0xFFFFFFFF)
    assert abort_code(d.read, B + 7) == 0x08000024  # No data while running.
    move(d, start + REV)
    d.step(0.3)
    assert d.read(B + 6) == 2  # Triggered, recording.
    d.step(2.0)
    assert (d.read(B + 6), d.read(B + 8), d.read(B + 9)) == (3, depth, pre)

    rows = words(d, 4)
    assert len(rows) == depth
    # The trigger sample sits at the pre-trigger index and is the first crossing of the level.
    t = log.first_crossing(level)
    rec = d.recorder
    assert rec is not None and rec.trigger_step == t and rec.data_first_step == t - pre
    assert rows[pre - 1][0] < level <= rows[pre][0]
    # One sample per plant sub-step (1/4000 s), each the plant's value at that step.
    assert d.plant_period * 4000 == pytest.approx(1.0, abs=1e-12)
    for i, (pos, vel, torque, _fe) in enumerate(rows):
        k = t - pre + i
        assert (pos, vel, torque) == (log.pos[k], log.vel[k], log.torque[k]), i
    # 60F4h at a sub-step is the servo loop's demand then (interpolated linearly across the
    # control cycle, docs/tuning.md) minus the position then: position plus following error
    # rises by the same step at each of the four sub-steps of a cycle, and the demand ends at
    # the target.
    by_cycle: dict[int, list[int]] = {}
    for i, (pos, _vel, _tq, fe) in enumerate(rows):
        by_cycle.setdefault((t - pre + i - 1) // 4, []).append(pos + fe)
    # (Within 1 per value: 60F4h rounds demand minus position, and the demand has fractions.)
    for demands in by_cycle.values():
        steps = [b - a for a, b in itertools.pairwise(demands)]
        assert not steps or max(steps) - min(steps) <= 2, demands
    assert rows[-1][0] + rows[-1][3] == start + REV
    # The move really is in the recording (not just rest): it rises through the window.
    assert rows[0][0] == start and rows[-1][0] > level and max(r[1] for r in rows) > 100_000


def test_falling_trigger_and_divider() -> None:
    d = new_drive()
    log = PlantLog(d)
    enable(d)
    d.step(0.01)
    start = d.position
    move(d, start + REV)
    d.step(1.0)
    level = start + REV // 2
    configure(d, POS, divider=4, depth=300, trigger=2, level=level, pre=60)
    d.write(B + 6, 0, 1)
    d.step(0.1)
    move(d, start)
    d.step(1.0)
    assert d.read(B + 6) == 3
    rows = words(d, 1)
    t = log.first_crossing(level, rising=False)
    # Divider 4: one sample per control cycle (1 ms); the trigger is the first sample at or
    # below the level, which the plant crossed at most 3 sub-steps earlier.
    rec = d.recorder
    assert rec is not None and rec.trigger_step is not None
    assert 0 <= rec.trigger_step - t < 4
    assert rows[59][0] > level >= rows[60][0]
    for i, (pos,) in enumerate(rows):
        assert pos == log.pos[rec.trigger_step + (i - 60) * 4]


def test_immediate_trigger_starts_at_the_next_plant_step() -> None:
    d = new_drive()
    log = PlantLog(d)
    enable(d)
    move(d, REV)
    d.step(0.05)
    configure(d, POS, VEL, depth=10, trigger=0, pre=5)  # pre is unused without a level.
    d.write(B + 6, 0, 1)
    assert d.read(B + 6) == 2  # Recording at once.
    first = d.plant_steps + 1
    d.step(0.003)
    assert (d.read(B + 6), d.read(B + 8), d.read(B + 9)) == (3, 10, 0)
    rows = words(d, 2)
    assert rows == [(log.pos[first + i], log.vel[first + i]) for i in range(10)]


def stream(drive: SimulatedDrive, channels: int) -> tuple[int, int, list[tuple[int, ...]]]:
    """One read of the stream data (B + 11): (first index, status, rows)."""
    data = drive.read_bytes(B + 11)
    first, status, nch, reserved = struct.unpack_from("<IBBH", data)
    assert (nch, reserved) == (channels, 0)
    n = (len(data) - 8) // 4
    flat = struct.unpack(f"<{n}i", data[8:])
    return first, status, [flat[i : i + channels] for i in range(0, n, channels)]


def test_stream_reads_the_filled_part_while_recording() -> None:
    """docs/scope.md "Streaming while recording": each read brings the samples recorded since
    the last one; pieced together they are the recording, with no gap and no duplicate."""
    d = new_drive()
    enable(d)
    d.step(0.01)
    start = d.position
    level = start + REV // 4
    depth, pre = 2000, 400
    configure(d, POS, VEL, depth=depth, trigger=1, level=level, pre=pre)
    d.write(B + 6, 0, 1)
    d.step(0.2)
    # Waiting for the trigger: the pre-trigger ring still turns, no samples yet.
    assert stream(d, 2) == (0, 1, [])
    assert d.read(B + 10) == 0
    move(d, start + REV)
    got: list[tuple[int, ...]] = []
    reads = 0
    while True:
        first, status, rows = stream(d, 2)
        assert first == len(got)  # The position moved past the last read's samples.
        got += rows
        reads += 1
        if status == 3:
            break
        assert status in (1, 2)
        d.step(0.02)
    assert reads > 10 and d.read(B + 10) == depth
    # Read again from an earlier sample (after a lost answer): the same samples.
    d.write(B + 10, 0, 1500)
    assert stream(d, 2) == (1500, 3, got[1500:])
    assert stream(d, 2) == (depth, 3, [])
    assert got == words(d, 2) and got[pre - 1][0] < level <= got[pre][0]


def test_a_profile_without_stream_objects_has_no_stream() -> None:
    """The stream objects are optional (a drive that uploads whole recordings only)."""
    p = generic()

    def without(*indexes: int) -> DeviceProfile:
        data = p.model_dump()
        data["objects"] = [o for o in data["objects"] if o["index"] not in indexes]
        return DeviceProfile.model_validate(data)

    d = SimulatedDrive(without(B + 10, B + 11), 1)
    assert d.recorder is not None and not d.recorder.streams
    assert abort_code(d.read, B + 11) == 0x06020000
    # Both or neither: one of them alone is a profile error.
    assert recorder_objects(without(B + 11)) == [
        f"recorder: {B + 10:04X}h without {B + 11:04X}h: streaming needs both"
    ]


def test_recording_does_not_change_the_simulation() -> None:
    a, b = new_drive(), new_drive()
    for d in (a, b):
        enable(d)
    configure(b, POS, VEL, TORQUE, FE, depth=8192, trigger=0)
    b.write(B + 6, 0, 1)
    for d in (a, b):
        move(d, 3 * REV)
    for _ in range(600):
        a.step(0.001)
        b.step(0.001)
        assert (a.position, a.velocity, a.plant.torque) == (b.position, b.velocity, b.plant.torque)
    assert b.read(B + 6) == 2


def test_unsigned_and_real32_words() -> None:
    # REAL32 objects are stored as their IEEE 754 bits, UNSIGNED32 wraps into the word.
    data = generic().model_dump()
    data["objects"] = (
        *data["objects"],
        {
            "index": 0x3000,
            "name": "Analog input",
            "data_type": "REAL32",
            "access": "rw",
            "default": 1.5,
            "section": "test",
        },
    )
    d = new_drive(DeviceProfile.model_validate(data))
    d.set_inputs(0x80000001)
    d.write(0x3000, 0, -2.25)
    configure(d, 0x60FD0020, 0x30000020, depth=3, trigger=0)
    d.write(B + 6, 0, 1)
    d.step(0.001)
    raw = d.read_bytes(B + 7)
    assert len(raw) == 3 * 2 * 4
    inputs, real = struct.unpack_from("<II", raw)
    assert inputs & 0x80000001 == 0x80000001
    assert struct.unpack("<f", struct.pack("<I", real))[0] == -2.25


# ---------------------------------------------------------------------- objects and rules


def test_configuration_is_refused_while_recording_and_the_recording_survives() -> None:
    d = new_drive()
    enable(d)
    configure(d, POS, depth=100, trigger=1, level=10**9, pre=20)
    d.nmt_state = "op"  # Written in any NMT state.
    d.write(B + 6, 0, 1)
    d.step(0.1)
    for index, sub, value in ((B, 1, VEL), (B + 2, 0, 50), (B + 4, 0, 0), (B + 1, 0, 2)):
        assert abort_code(d.write, index, sub, value) == 0x08000022
    assert abort_code(d.write, B + 6, 0, 2) == 0x06090030
    # Stop before a trigger: the pre-trigger samples are kept, no trigger index.
    d.write(B + 6, 0, 0)
    assert (d.read(B + 6), d.read(B + 8), d.read(B + 9)) == (0, 20, 0xFFFFFFFF)
    pos = d.position
    assert words(d, 1) == [(pos,)] * 20
    # The configuration may change again and the recording stays until the next start.
    d.nmt_state = "preop"
    d.write(B + 3, 0, 0)
    d.write(B + 2, 0, 5)
    d.step(0.01)
    assert d.read(B + 8) == 20 and len(words(d, 1)) == 20
    d.write(B + 6, 0, 1)
    assert abort_code(d.read, B + 7) == 0x08000024
    d.step(0.01)
    assert d.read(B + 8) == 5


def test_channel_and_start_checks() -> None:
    d = new_drive()
    # An object that does not exist, wrong bits, not recordable.
    assert abort_code(d.write, B, 1, 0x70000020) == 0x06090030
    assert abort_code(d.write, B, 1, 0x60640010) == 0x06090030
    assert abort_code(d.write, B, 1, 0x10080000) == 0x06090030
    assert abort_code(d.write, B, 1, 0x2F070000) == 0x06090030
    assert abort_code(d.write, B, 0, 3) == 0x06010002  # Sub 0 is const.
    assert abort_code(d.write, B + 7, 0, b"\x00") == 0x06010002  # Data is read-only.
    assert abort_code(d.write, B + 2, 0, 32769) == 0x06090031  # Depth <= 32768 (max_depth).
    # Start checks the configuration as a whole.
    assert abort_code(d.write, B + 6, 0, 1) == 0x08000020  # No channel.
    configure(d, 0, POS, trigger=1)
    assert abort_code(d.write, B + 6, 0, 1) == 0x08000020  # A level trigger needs channel 1.
    configure(d, POS, depth=10, pre=10)
    assert abort_code(d.write, B + 6, 0, 1) == 0x08000020  # Pre-trigger below the depth.
    d.write(B + 5, 0, 9)
    d.write(B + 6, 0, 1)
    assert d.read(B + 6) == 1
    # The data holds only the channels in use, in sub order.
    d.write(B + 6, 0, 0)
    configure(d, 0, POS, 0, VEL, trigger=0, depth=2)
    d.write(B + 6, 0, 1)
    d.step(0.001)
    assert words(d, 2) == [(d.position, 0)] * 2


def test_idle_recorder_has_no_hook_and_reset_node_loses_the_recording() -> None:
    d = new_drive()
    configure(d, POS, depth=4, trigger=0)
    d.write(B + 6, 0, 1)
    assert d._substep_hooks  # Sampling while running...
    d.step(0.001)
    assert d.read(B + 6) == 3
    assert d._substep_hooks == ()  # ...and no cost at all once done (or stopped, or idle).
    d.reset_node()
    assert (d.read(B + 6), d.read(B + 8), d.read(B, 1)) == (0, 0, 0)
    assert abort_code(d.read, B + 7) == 0x08000024
