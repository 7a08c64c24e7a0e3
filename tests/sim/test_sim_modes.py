"""Operation modes of the simulated drive: pp, pv, tq, homing, halt; following error."""

from __future__ import annotations

import pytest

from servodesk.domain.cia402 import State
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimAbort

from .support import cw, enable, new_drive, run_until

_CATALOG = ProfileCatalog()

REV = 131072


def new_setpoint(d, word: int = 0x1F) -> None:  # type: ignore[no-untyped-def]
    cw(d, word)
    assert d.statusword & 0x1000, "set-point acknowledge (bit 12) after bit 4"
    cw(d, word & ~0x10)
    d.step(0.001)
    assert not d.statusword & 0x1000, "bit 12 clears after bit 4 is cleared"


def test_profile_position_move_reaches_target_with_bit_10_and_handshake() -> None:
    d = new_drive()
    d.write(0x6060, 0, 1)
    enable(d)
    target = 3 * REV
    d.write(0x607A, 0, target)
    new_setpoint(d)
    assert not d.statusword & 0x400  # Moving: target not reached.
    t = run_until(d, lambda: d.statusword & 0x400, 5.0)
    # Trapezoid: 200 000 counts/s, 1e6 counts/s² -> 0.2 s ramps; 393 216 counts.
    assert t == pytest.approx(target / 200_000 + 0.2, abs=0.05)
    assert abs(d.read(0x6064, 0) - target) <= d.read(0x6067, 0)
    assert abs(d.read(0x60F4, 0)) <= 100


def test_relative_move_and_change_immediately() -> None:
    d = new_drive()
    enable(d)
    d.write(0x607A, 0, REV)
    new_setpoint(d)
    d.step(0.2)
    d.write(0x607A, 0, -REV // 2)
    new_setpoint(d, 0x7F)  # Relative (bit 6) to the current target, change immediately.
    run_until(d, lambda: d.statusword & 0x400, 5.0)
    assert abs(d.position - REV // 2) <= 100


def test_buffered_set_point_runs_after_the_current_move() -> None:
    d = new_drive()
    enable(d)
    d.write(0x607A, 0, REV)
    new_setpoint(d)
    d.write(0x607A, 0, 0)
    cw(d, 0x1F)  # Single set-point (bit 5 = 0): buffered while moving.
    assert d.statusword & 0x1000
    cw(d, 0x0F)
    d.step(0.005)
    assert d.statusword & 0x1000, "buffer full: acknowledge stays until the buffer frees"
    seen_first = False
    for _ in range(4000):
        d.step(0.001)
        seen_first = seen_first or d.position > REV - 200
        if seen_first and d.statusword & 0x400:
            break
    assert seen_first
    assert abs(d.position) <= 100


def test_software_limits_clip_the_target_and_set_bit_11() -> None:
    d = new_drive()
    d.write(0x607D, 1, -REV)
    d.write(0x607D, 2, REV)
    enable(d)
    d.write(0x607A, 0, 5 * REV)
    cw(d, 0x1F)
    assert d.statusword & 0x800
    cw(d, 0x0F)
    run_until(d, lambda: d.statusword & 0x400, 5.0)
    assert abs(d.position - REV) <= 100


def test_profile_velocity_reaches_target_with_bit_10() -> None:
    d = new_drive()
    d.write(0x6060, 0, 3)
    enable(d)
    d.write(0x60FF, 0, -250_000)
    assert d.statusword & 0x1000  # Speed = 0 (bit 12 in pv).
    t = run_until(d, lambda: d.statusword & 0x400, 2.0)
    assert t == pytest.approx(0.25, abs=0.03)  # 6083h = 1e6 counts/s².
    assert d.read(0x606C, 0) == pytest.approx(-250_000, abs=1000)
    assert not d.statusword & 0x1000


def test_profile_velocity_stops_at_the_software_limits_with_bit_11() -> None:
    # The backstop behind servodesk's own limit monitor: a velocity command toward a software
    # limit brakes at 6084h so that the axis stops at the limit, not beyond it.
    d = new_drive()
    d.write(0x6060, 0, 3)
    enable(d)
    start = d.position
    lo, hi = start - 60_000, start + 100_000
    d.write(0x607D, 1, lo)
    d.write(0x607D, 2, hi)
    d.write(0x60FF, 0, 250_000)
    highest = start
    for _ in range(100):  # 1 s: without the wall it would end over 100000 past the limit.
        d.step(0.01)
        highest = max(highest, d.position)
    assert hi - 200 <= highest < hi, highest - hi
    assert abs(d.velocity) < 1000 and d.statusword & 0x800
    # Away from the limit it runs again, and it stops at the other one.
    d.write(0x60FF, 0, -250_000)
    d.step(0.3)
    assert d.velocity < -200_000 and not d.statusword & 0x800
    lowest = d.position
    for _ in range(100):
        d.step(0.01)
        lowest = min(lowest, d.position)
    assert lo < lowest <= lo + 200, lowest - lo
    # Limits 0/0 are off (CiA 402-2 §6.5.4): the axis passes where the limit was.
    d.write(0x607D, 1, 0)
    d.write(0x607D, 2, 0)
    d.step(0.4)
    assert d.position < lo - 20_000


def test_profile_ramps_in_family_units_become_accelerations() -> None:
    # The CTMM04x writes 6083h/6084h into PMC842SR rate registers (003 §5-3-1): the ramp is
    # Fclk / 8 / register, 32.768 MHz / 8 / 100 = 40960 pulses/s² for the default 100. The
    # LECSN-T's are time constants from 0 to the rated speed in ms (004 §20.9.3.10(7)). Both were
    # once read as counts/s²: a jog on the CTMM04x twin took 80 s to reach 8000 pulses/s.
    d = new_drive(_CATALOG.get("ctmm04x"))
    d.write(0x6060, 0, 3)
    d.write(0x60FF, 0, 0)
    enable(d)
    d.write(0x60FF, 0, 8000)
    d.step(0.1)
    assert 0.4 * 8000 < d.velocity < 0.6 * 8000  # 4096 pulses/s after 0.1 s.
    d.step(0.2)
    assert d.velocity == pytest.approx(8000, rel=0.01)

    d = new_drive(_CATALOG.get("lecsn-t"))
    rated = _CATALOG.get("lecsn-t").simulation.rated_speed
    assert rated
    d.write(0x6060, 0, 3)
    d.write(0x6083, 0, 2000)  # 2 s from 0 to the rated speed (3000 r/min).
    enable(d)
    d.write(0x60FF, 0, 400_000)
    d.step(0.05)
    assert 0.9 * 0.05 * rated / 2.0 < d.velocity < 1.1 * 0.05 * rated / 2.0
    d.step(0.15)
    assert d.velocity == pytest.approx(400_000, rel=0.01)


def test_a_lecsn_twin_runs_past_its_software_limits_in_profile_velocity() -> None:
    # 004 §20.8.3: the LECSN-T's software limit works in profile position only. Its twin must not
    # be kinder than the drive: in profile velocity it runs on past 607Dh, and only servodesk's
    # own monitor (services/motion/) stands between a jog and the end of travel.
    d = new_drive(_CATALOG.get("lecsn-t"))
    d.write(0x6060, 0, 3)
    enable(d)
    start = d.position
    d.write(0x607D, 1, start - 60_000)
    d.write(0x607D, 2, start + 30_000)
    d.write(0x60FF, 0, 300_000)
    d.step(1.0)
    assert d.position > start + 200_000 and not d.statusword & 0x800


def test_profile_torque_follows_the_target_torque() -> None:
    d = new_drive()
    d.write(0x6060, 0, 4)
    enable(d)
    d.write(0x6071, 0, 100)  # 10 % of rated torque.
    run_until(d, lambda: d.statusword & 0x400, 0.1)
    assert d.read(0x6077, 0) == pytest.approx(100, abs=2)
    d.step(0.05)
    assert d.velocity > 1000  # The free motor accelerates.
    d.write(0x6072, 0, 50)  # Max torque 5 %: the torque is limited (bit 11).
    d.step(0.01)
    assert d.read(0x6077, 0) <= 51
    assert d.statusword & 0x800


@pytest.mark.parametrize("method", [35, 37])
def test_homing_sets_position_to_home_offset(method: int) -> None:
    d = new_drive()
    d.plant.set_position_counts(12345.0)
    d.write(0x6098, 0, method)
    d.write(0x607C, 0, 1000)
    d.write(0x6060, 0, 6)
    enable(d)
    d.step(0.002)
    assert d.statusword & 0x1400 == 0x0400  # Not started: bit 10 only.
    cw(d, 0x1F)
    d.step(0.002)
    assert d.statusword & 0x1400 == 0x1400  # Homing attained + target reached.
    assert d.read(0x6064, 0) == pytest.approx(1000, abs=2)


def test_unsupported_mode_and_homing_method_are_refused() -> None:
    d = new_drive()
    for index, value in ((0x6060, 8), (0x6060, 2), (0x6098, 1)):
        with pytest.raises(SimAbort) as exc:
            d.write(index, 0, value)
        assert exc.value.code == 0x06090030
    assert d.read(0x6060, 0) == 1


def test_mode_display_follows_mode() -> None:
    d = new_drive()
    d.write(0x6060, 0, 3)
    assert d.read(0x6061, 0) == 3


def test_halt_stops_the_axis_and_resumes() -> None:
    d = new_drive()
    d.write(0x6060, 0, 3)
    enable(d)
    d.write(0x60FF, 0, 200_000)
    run_until(d, lambda: d.statusword & 0x400, 1.0)
    cw(d, 0x10F)  # Halt (bit 8): slow-down ramp 6084h.
    t = run_until(d, lambda: d.statusword & 0x400 and abs(d.velocity) < 1000, 1.0)
    assert t == pytest.approx(0.2, abs=0.03)
    assert d.state is State.OPERATION_ENABLED
    cw(d, 0x0F)
    run_until(d, lambda: abs(d.velocity - 200_000) < 1000, 1.0)


def test_halt_in_profile_position_pauses_the_move() -> None:
    d = new_drive()
    enable(d)
    d.write(0x607A, 0, 2 * REV)
    new_setpoint(d)
    d.step(0.3)
    cw(d, 0x10F)
    d.step(0.4)
    paused = d.position
    d.step(0.1)
    assert abs(d.position - paused) < 50
    cw(d, 0x0F)
    run_until(d, lambda: d.statusword & 0x400, 3.0)
    assert abs(d.position - 2 * REV) <= 100


def test_following_error_raises_8611_with_bits_history_and_emcy() -> None:
    d = new_drive()
    emcy: list[tuple[int, int, bytes]] = []
    d.on_emcy(lambda c, r, data: emcy.append((c, r, data)))
    enable(d)
    d.write(0x6072, 0, 5)  # 0.5 % torque cannot beat the Coulomb friction.
    d.write(0x607A, 0, REV)
    new_setpoint(d)
    run_until(d, lambda: d.state is State.FAULT, 1.0)
    assert d.read(0x603F, 0) == 0x8611
    assert d.error_text() == "Following error"
    assert d.read(0x1001, 0) == 0x21  # Generic + device profile specific.
    assert d.read(0x1003, 0) == 1
    assert d.read(0x1003, 1) == 0x8611
    assert d.statusword & 0x08
    assert emcy == [(0x8611, 0x21, bytes(5))]
    # Fault reset: Switch on disabled, error cleared, EMCY "error reset".
    cw(d, 0x00)
    cw(d, 0x80)
    assert d.state is State.SWITCH_ON_DISABLED
    assert d.read(0x603F, 0) == 0 and d.read(0x1001, 0) == 0
    assert emcy[-1] == (0, 0, bytes(5))
    assert d.read(0x1003, 1) == 0x8611  # The history stays.


def test_error_history_newest_first_and_clearing() -> None:
    d = new_drive()
    for code in (0x2310, 0x3210):
        d.raise_fault(code)
        cw(d, 0x00)
        cw(d, 0x80)
    assert d.read(0x1003, 0) == 2
    assert [d.read(0x1003, 1), d.read(0x1003, 2)] == [0x3210, 0x2310]
    with pytest.raises(SimAbort) as exc:
        d.write(0x1003, 0, 1)
    assert exc.value.code == 0x06090030
    d.write(0x1003, 0, 0)
    assert d.read(0x1003, 0) == 0 and d.read(0x1003, 1) == 0


def test_following_error_window_off_with_ffffffff() -> None:
    d = new_drive()
    enable(d)
    d.write(0x6065, 0, 0xFFFFFFFF)
    d.write(0x6072, 0, 5)
    d.write(0x607A, 0, REV)
    new_setpoint(d)
    d.step(0.5)
    assert d.state is State.OPERATION_ENABLED


def test_smartris_max_profile_velocity_is_in_rpm() -> None:
    # 001 §6-4: 607Fh is printed in rpm (the example: 4500 rpm), whatever the factor group,
    # while 60FFh is in inc/s (16384 inc/rev). Read as inc/s, the 4500 of its default once
    # limited profile velocity to 16 rpm.
    d = new_drive(_CATALOG.get("smartris"))
    d.write(0x6060, 0, 3)
    for word in (0x06, 0x07, 0x0F):
        cw(d, word)
        d.step(0.05)  # 001 §5-4: controlword commands at least 40 ms apart.
    assert d.state is State.OPERATION_ENABLED
    d.write(0x60FF, 0, 3000 * 16384 // 60)  # 3000 rpm
    d.step(4.0)  # 6083h: 1000 rpm/s.
    assert d.velocity == pytest.approx(3000 * 16384 / 60, rel=0.01)  # below 4500 rpm
    d.write(0x607F, 0, 1000)
    d.step(4.0)
    assert d.velocity == pytest.approx(1000 * 16384 / 60, rel=0.01)


@pytest.mark.parametrize("profile_id", ["hiwin-e", "lecsn-t", "smartris", "ctmm04x"])
def test_no_mode_is_written_back_where_the_profile_lists_it(profile_id: str) -> None:
    # A restore sets 6060h back to the twin's power-up 0 ("no mode change / no mode
    # assigned"); a real drive accepts it and keeps the mode it runs (000 §3.2).
    profile = _CATALOG.get(profile_id)
    d = new_drive(profile)
    assert d.read(0x6060, 0) == 0
    mode = profile.modes[0] if profile.modes[0] > 0 else profile.modes[1]
    d.write(0x6060, 0, mode)
    d.step(0.001)
    d.write(0x6060, 0, 0)
    d.step(0.001)
    assert d.read(0x6060, 0) == 0
    assert d.read(0x6061, 0) == mode  # No mode change.


def test_no_mode_is_refused_where_the_profile_does_not_list_it() -> None:
    d = new_drive()  # cia402-generic: 6060h lists 1, 3, 4, 6.
    with pytest.raises(SimAbort) as exc:
        d.write(0x6060, 0, 0)
    assert exc.value.code == 0x06090030  # CiA 301 §7.2.4.3.17: invalid value.
    assert d.read(0x6060, 0) == 1
