"""Homing errors, interruption and homing without Operation enabled (unbound simulation)."""

from __future__ import annotations

from servodesk.domain.cia402 import State
from servodesk.sim.engine import SimulatedDrive

from .support import CATALOG, SW_ATTAINED, SW_ERROR, SW_REACHED, run_homing, start_homing


def test_missing_home_switch_is_a_homing_error_with_bits_13_and_10() -> None:
    p = CATALOG.get("hiwin-e")
    no_switches = p.model_copy(
        update={"simulation": p.simulation.model_copy(update={"homing_switches": False})}
    )
    d = start_homing(no_switches, 24, 0)
    d.step(0.1)
    assert d.statusword & (SW_ERROR | SW_ATTAINED | SW_REACHED) == 0  # In progress.
    run_homing(d, timeout=30)
    # 000 §3.2.4 table 3.2.4.3: error with velocity 0 = bits 13 and 10, no bit 12.
    assert d.statusword & (SW_ERROR | SW_ATTAINED | SW_REACHED) == SW_ERROR | SW_REACHED
    assert abs(d.velocity) < 1000
    assert d.state is State.OPERATION_ENABLED


def test_stroke_end_without_reversal_is_a_homing_error() -> None:
    # Method 3 (positive home switch) started above the dog runs into the positive limit
    # switch: methods 3-6 do not reverse (004 §20.6.6(4): stroke end -> AL 90).
    d = start_homing(CATALOG.get("lecsn-t"), 3, 2.5)
    run_homing(d)
    assert d.statusword & SW_ERROR
    rev = d.profile.simulation.counts_per_rev
    assert d.plant.encoder_counts >= 3.7 * rev  # It stopped at/after the limit switch.


def test_limit_switches_and_home_switch_show_in_60fd() -> None:
    d = SimulatedDrive(CATALOG.get("ctmm04x"), 5)
    d.step(0.001)
    rev = d.profile.simulation.counts_per_rev
    for revs, bits in ((0, 0), (-2, 0x01), (4, 0x02), (1.5, 0x04)):
        d.plant.set_position_counts(revs * rev)
        assert d.read(0x60FD, 0) & 0x07 == bits


def test_clearing_bit_4_interrupts_homing() -> None:
    d = start_homing(
        CATALOG.get("cia402-generic").model_copy(update={"homing_methods": (1, 37)}), 1, 0
    )
    d.step(0.2)
    assert d.velocity < -1000
    d.write(0x6040, 0, 0x0F)
    d.step(0.5)  # Decelerates at 609Ah and stays stopped.
    assert abs(d.velocity) < 100
    # Interrupted: bit 10 only (CiA 402-2 §6.8.1).
    assert d.statusword & (SW_ERROR | SW_ATTAINED | SW_REACHED) == SW_REACHED


def test_hiwin_37_and_minus_3_home_without_operation_enabled() -> None:
    p = CATALOG.get("hiwin-e")
    for method in (37, -3):
        d = SimulatedDrive(p, 5)
        d.step(0.001)
        d.plant.set_position_counts(123456)
        d.write(0x607C, 0, 500)
        d.write(0x6060, 0, 6)
        d.write(0x6098, 0, method)
        d.write(0x6040, 0, 0x06)
        d.write(0x6040, 0, 0x16)  # Ready to switch on + bit 4.
        d.step(0.01)
        assert d.state is State.READY_TO_SWITCH_ON
        assert d.read(0x6064, 0) == 500
        assert d.statusword & SW_ATTAINED


def test_lecsn_minus_3_needs_servo_on() -> None:
    d = SimulatedDrive(CATALOG.get("lecsn-t"), 5)
    d.step(0.001)
    d.write(0x6060, 0, 6)
    d.write(0x6098, 0, -3)
    d.write(0x6040, 0, 0x06)
    d.write(0x6040, 0, 0x16)
    d.step(0.01)
    assert not d.statusword & SW_ATTAINED  # 004 §20.6.6(4): "not at servo-off".
