"""The CiA 402 state machine of the simulated drive, against the cia402 tables."""

from __future__ import annotations

import itertools

import pytest

from servodesk.domain.cia402 import STATE_BITS, State, decode_state, device_transition
from servodesk.sim.engine import SimAbort

from .support import (
    bring_to,
    cw,
    enable,
    generic,
    new_drive,
    run_until,
    with_objects,
    with_quirks,
)

STATES = [
    State.SWITCH_ON_DISABLED,
    State.READY_TO_SWITCH_ON,
    State.SWITCHED_ON,
    State.OPERATION_ENABLED,
    State.QUICK_STOP_ACTIVE,
    State.FAULT,
]
# Every combination of the command bits 0-3 and 7 (CiA 402-2 table 28).
WORDS = [
    sum(bit for bit, on in zip((0x01, 0x02, 0x04, 0x08, 0x80), combo, strict=True) if on)
    for combo in itertools.product((0, 1), repeat=5)
]


@pytest.mark.parametrize("state", STATES, ids=lambda s: s.name)
def test_every_controlword_in_every_state_follows_the_table(state: State) -> None:
    for word in WORDS:
        d = new_drive()
        # Immediate transitions: free-wheel disable (605Bh, 605Ch = 0); quick stop option
        # 6 so that Quick stop active is a state that stays.
        d.write(0x605B, 0, 0)
        d.write(0x605C, 0, 0)
        d.write(0x605A, 0, 6)
        bring_to(d, state)
        previous = d.read(0x6040, 0)
        assert isinstance(previous, int)
        expected = device_transition(state, word, previous, quick_stop_option=6)
        cw(d, word)
        d.step(0.005)
        want = expected.target if expected else state
        assert d.state is want, f"{state.name} + 0x{word:02X}: {d.state.name}"
        assert decode_state(d.statusword) is want


def test_statusword_state_bits_and_voltage_enabled() -> None:
    for state in STATES:
        d = new_drive()
        d.write(0x605A, 0, 6)
        bring_to(d, state)
        sw = d.statusword
        assert sw & 0x6F & STATE_BITS[state] == STATE_BITS[state]
        voltage = state not in (State.SWITCH_ON_DISABLED, State.FAULT)
        assert bool(sw & 0x10) is voltage, state
        assert sw & 0x200  # Remote.


def test_fault_reset_needs_a_rising_edge_of_bit_7() -> None:
    d = new_drive()
    cw(d, 0x80)
    d.raise_fault(0x8611)
    cw(d, 0x80)  # Bit 7 already high: no edge.
    assert d.state is State.FAULT
    cw(d, 0x00)
    cw(d, 0x80)
    assert d.state is State.SWITCH_ON_DISABLED


def test_no_fault_reset_bit7_quirk_leaves_the_fault_until_node_reset() -> None:
    d = new_drive(with_quirks(generic(), no_fault_reset_bit7=True))
    d.raise_fault(0x8611)
    cw(d, 0x00)
    cw(d, 0x80)
    assert d.state is State.FAULT
    d.reset_node()
    d.step(0.001)
    assert d.state is State.SWITCH_ON_DISABLED
    assert d.read(0x603F, 0) == 0


def test_controlword_min_interval_quirk_drops_early_controlwords() -> None:
    d = new_drive(with_quirks(generic(), controlword_min_interval_ms=40))
    cw(d, 0x06)
    assert d.state is State.READY_TO_SWITCH_ON
    d.step(0.010)
    cw(d, 0x07)  # 10 ms later: dropped, and 6040h keeps the accepted value.
    assert d.state is State.READY_TO_SWITCH_ON
    assert d.read(0x6040, 0) == 0x06
    d.step(0.030)
    cw(d, 0x07)
    assert d.state is State.SWITCHED_ON


def test_quick_stop_statusword_quirk() -> None:
    d = new_drive(with_quirks(generic(), quick_stop_statusword=0x0217))
    d.write(0x605A, 0, 6)
    enable(d)
    cw(d, 0x02)
    assert d.state is State.QUICK_STOP_ACTIVE
    assert d.statusword == 0x0217


def test_not_ready_to_switch_on_until_the_first_cycle() -> None:
    from servodesk.sim.engine import SimulatedDrive

    d = SimulatedDrive(generic(), 3)
    assert d.state is State.NOT_READY_TO_SWITCH_ON
    cw(d, 0x06)
    assert d.state is State.NOT_READY_TO_SWITCH_ON
    d.step(0.001)
    assert d.state is State.SWITCH_ON_DISABLED


@pytest.mark.parametrize(
    ("option", "stays"),
    [
        (0, False),
        (1, False),
        (2, False),
        (3, False),
        (4, False),
        (5, True),
        (6, True),
        (7, True),
        (8, True),
    ],
)
def test_quick_stop_options(option: int, stays: bool) -> None:
    d = new_drive()
    d.write(0x605A, 0, option)
    d.write(0x6060, 0, 3)
    enable(d)
    d.write(0x60FF, 0, 300_000)
    run_until(d, lambda: abs(d.velocity - 300_000) < 2000, 2.0)
    cw(d, 0x02)
    if option == 0:
        assert d.state is State.SWITCH_ON_DISABLED  # Drive function disabled at once.
        return
    assert d.state is State.QUICK_STOP_ACTIVE
    assert decode_state(d.statusword) is State.QUICK_STOP_ACTIVE
    t = run_until(
        d,
        lambda: (
            (abs(d.velocity) < 50 and d.state is not State.QUICK_STOP_ACTIVE)
            or (stays and abs(d.velocity) < 50 and d.statusword & 0x400)
        ),
        2.0,
    )
    decel = {1: 1_000_000, 2: 5_000_000}.get((option - 1) % 4 + 1)
    if decel is not None:
        # The ramp: 300 000 counts/s at decel takes 0.3 s (1, 5) or 0.06 s (2, 6).
        assert t == pytest.approx(300_000 / decel, abs=0.02)
    else:
        assert t < 0.02  # Torque-limit stop is the fastest.
    if stays:
        assert d.state is State.QUICK_STOP_ACTIVE
        cw(d, 0x0F)  # Transition 16 back to Operation enabled.
        assert d.state is State.OPERATION_ENABLED
    else:
        assert d.state is State.SWITCH_ON_DISABLED


@pytest.mark.parametrize(
    ("key", "word", "target"),
    [
        (0x605C, 0x07, State.SWITCHED_ON),  # Disable operation (transition 5).
        (0x605B, 0x06, State.READY_TO_SWITCH_ON),  # Shutdown (transition 8).
    ],
)
def test_disable_operation_and_shutdown_options(key: int, word: int, target: State) -> None:
    for option, ramps in ((0, False), (1, True)):
        d = new_drive()
        d.write(key, 0, option)
        d.write(0x6060, 0, 3)
        enable(d)
        d.write(0x60FF, 0, 200_000)
        run_until(d, lambda d=d: abs(d.velocity - 200_000) < 2000, 2.0)
        cw(d, word)
        if ramps:
            assert d.state is State.OPERATION_ENABLED  # Slowing down on 6084h.
            t = run_until(d, lambda d=d: d.state is target, 1.0)
            assert t == pytest.approx(0.2, abs=0.02)
            assert abs(d.velocity) < 5000
        else:
            assert d.state is target
            d.step(0.01)
            assert abs(d.velocity) > 100_000  # Free wheel: the axis coasts.


def test_fault_reaction_options() -> None:
    for option in (0, 1, 2):
        d = new_drive()
        d.write(0x605E, 0, option)
        d.write(0x6060, 0, 3)
        enable(d)
        d.write(0x60FF, 0, 300_000)
        run_until(d, lambda d=d: abs(d.velocity - 300_000) < 2000, 2.0)
        d.raise_fault(0x2310)
        if option == 0:
            assert d.state is State.FAULT
            continue
        assert d.state is State.FAULT_REACTION_ACTIVE
        assert decode_state(d.statusword) is State.FAULT_REACTION_ACTIVE
        t = run_until(d, lambda d=d: d.state is State.FAULT, 1.0)
        assert t == pytest.approx(300_000 / (1_000_000 if option == 1 else 5_000_000), abs=0.02)


def test_writable_in_states_refuses_with_08000022() -> None:
    p = with_objects(generic(), x6065={"writable_in": ("switch_on_disabled", "preop")})
    d = new_drive(p)
    d.nmt_state = "op"
    d.write(0x6065, 0, 1000)  # Switch on disabled: allowed.
    cw(d, 0x06)
    with pytest.raises(SimAbort) as exc:
        d.write(0x6065, 0, 2000)
    assert exc.value.code == 0x08000022
    d.nmt_state = "preop"
    d.write(0x6065, 0, 2000)
