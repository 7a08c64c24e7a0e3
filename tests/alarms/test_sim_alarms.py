"""Family fault codes in the simulation: following error, limit switch, I²t overload, alarm
objects and each family's reset procedure (unbound simulation, plain object access)."""

from __future__ import annotations

import pytest

from servodesk.domain.cia402 import State
from servodesk.domain.datatypes import coerce_int
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimAbort, SimulatedDrive

CATALOG = ProfileCatalog()
FAMILIES = ("cia402-generic", "hiwin-e", "ctmm04x", "lecsn-t", "smartris")


def _drive(profile: DeviceProfile) -> SimulatedDrive:
    d = SimulatedDrive(profile, 5)
    d.step(0.001)
    return d


def _enable(d: SimulatedDrive) -> None:
    for word in (0x06, 0x07, 0x0F):
        d.write(0x6040, 0, word)
        d.step(0.05)
    assert d.state is State.OPERATION_ENABLED


def _bit7_reset(d: SimulatedDrive) -> None:
    for word in (0x00, 0x80, 0x00):
        d.write(0x6040, 0, word)
        d.step(0.05)


@pytest.mark.parametrize("family", FAMILIES)
def test_mapped_codes_are_in_the_family_tables(family: str) -> None:
    p = CATALOG.get(family)
    codes = p.quirk("sim_fault_codes")
    assert isinstance(codes, dict), "every family declares its simulated fault codes"
    for condition, code in codes.items():
        assert condition in ("following_error", "limit_switch", "overload")
        if code is not None:
            c = coerce_int(code)
            assert any(p.error(t, c) for t in ("error_code", "emcy", "alarm")), (condition, c)


@pytest.mark.parametrize(
    ("family", "code", "name"),
    [
        ("cia402-generic", 0x8611, "Following error"),
        ("hiwin-e", 0xFF3E, "Position error too big"),  # AL.d00, 000 §3.2 table 3.2.1
        ("ctmm04x", 0x8611, "Excessive position deviation"),  # 003 §6-1
    ],
)
def test_following_error_raises_the_family_code_and_bit7_resets(
    family: str, code: int, name: str
) -> None:
    d = _drive(CATALOG.get(family))
    d.write(0x6060, 0, 1)
    _enable(d)
    rev = d.profile.simulation.counts_per_rev
    d.write(0x6065, 0, 0)  # No following error allowed...
    d.write(0x6066, 0, 0)
    d.write(0x607A, 0, 2 * rev)  # ...and a move: the lag exceeds it at once.
    d.write(0x6040, 0, 0x1F)
    d.step(0.3)
    assert d.state is State.FAULT
    assert d.read(0x603F, 0) == code
    assert d.error_text() == name
    _bit7_reset(d)
    assert d.state is State.SWITCH_ON_DISABLED
    assert d.read(0x603F, 0) == 0


def test_lecsn_following_error_sets_bit_13_without_an_alarm() -> None:
    d = _drive(CATALOG.get("lecsn-t"))
    d.write(0x6060, 0, 1)
    _enable(d)
    d.write(0x6065, 0, 0)
    d.write(0x6066, 0, 0)
    d.write(0x6081, 0, 100_000)
    d.write(0x6083, 0, 100)
    d.write(0x607A, 0, 262144)
    d.write(0x6040, 0, 0x1F)
    d.step(0.05)
    assert d.state is State.OPERATION_ENABLED  # Chapter 20 cites no alarm for it.
    assert d.statusword & 0x2000


def _fast(profile: DeviceProfile) -> DeviceProfile:
    sim = profile.simulation.model_copy(update={"i2t_time_constant": 0.5})
    return profile.model_copy(update={"simulation": sim})


@pytest.mark.parametrize(
    ("family", "code"),
    [("cia402-generic", 0x2310), ("hiwin-e", 0xFF19), ("smartris", 0x2350)],
)
def test_i2t_overload_raises_the_family_code(family: str, code: int) -> None:
    d = _drive(_fast(CATALOG.get(family)))
    d.write(0x6060, 0, 4)
    _enable(d)
    d.write(0x6072, 0, 3000)  # 300 % torque limit,
    if d.has_object(0x6087):
        d.write(0x6087, 0, 10_000_000)  # a steep torque slope (‰/s),
    if d.has_object(0x607F):
        d.write(0x607F, 0, int(d.profile.simulation.max_velocity))  # no extra speed limit.
    t = 0.0
    sign = 1
    while d.state is not State.FAULT and t < 3.0:
        # 250 % torque back and forth: the motor current stays far above rated.
        d.write(0x6071, 0, sign * 2500)
        sign = -sign
        d.step(0.01)
        t += 0.01
    assert d.state is State.FAULT, "the I²t model trips"
    assert d.read(0x603F, 0) == code
    assert 0.1 < t < 3.0  # Not at once: the thermal model integrates.


def test_smartris_fault_needs_a_node_reset_not_bit_7() -> None:
    d = _drive(CATALOG.get("smartris"))
    d.raise_fault(0x2350)
    assert d.state is State.FAULT
    assert d.error_text() == "Load level fault (I²t)"
    _bit7_reset(d)
    assert d.state is State.FAULT  # 001 §5-4: bit 7 "not usable".
    d.reset_node()
    d.step(0.01)
    assert d.state is State.SWITCH_ON_DISABLED


def test_generic_limit_switch_fault_and_moving_back_out() -> None:
    d = _drive(CATALOG.get("cia402-generic"))
    d.write(0x6060, 0, 3)
    _enable(d)
    d.write(0x60FF, 0, 400_000)
    t = 0.0
    while d.state is not State.FAULT and t < 3.0:
        d.step(0.01)
        t += 0.01
    assert d.read(0x603F, 0) == 0xFF01
    assert d.read(0x60FD, 0) & 0x02  # Positive limit switch input.
    _bit7_reset(d)
    d.write(0x60FF, 0, -100_000)
    _enable(d)  # Standing on the switch is not a new limit event.
    d.step(0.5)
    assert d.state is State.OPERATION_ENABLED
    assert not d.read(0x60FD, 0) & 0x02


def test_lecsn_alarm_objects_history_and_clear() -> None:
    d = _drive(CATALOG.get("lecsn-t"))
    d.raise_fault(0x00250000)  # [AL 25] absolute position erased
    assert d.state is State.FAULT
    assert d.read(0x2A41, 0) == 0x00250000  # 004 §20.9.3.3(4) current alarm
    assert d.read(0x2A00, 1) == 0x00250000  # latest alarm history
    assert d.error_text(0x00250000) == "Absolute position erased"
    _bit7_reset(d)
    assert d.state is State.SWITCH_ON_DISABLED
    assert d.read(0x2A41, 0) == 0
    d.raise_fault(0x00370000)
    assert [d.read(0x2A00, 1), d.read(0x2A01, 1)] == [0x00370000, 0x00250000]
    with pytest.raises(SimAbort) as exc:
        d.write(0x2A40, 0, 1)
    assert exc.value.code == 0x06090030
    d.write(0x2A40, 0, 0x1EA5)  # 004 §20.9.3.3(3)
    assert d.read(0x2A00, 1) == 0 and d.read(0x2A01, 1) == 0
