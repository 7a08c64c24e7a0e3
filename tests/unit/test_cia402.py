"""The CiA 402 state machine tables, exhaustively (CiA 402-2 §6.2)."""

import itertools

import pytest

from servodesk.domain import cia402
from servodesk.domain.cia402 import Command, State

COMMANDED = [s for s in State if s not in (State.UNKNOWN,)]


@pytest.mark.parametrize(
    ("sw", "state"),
    [
        (0x0000, State.NOT_READY_TO_SWITCH_ON),
        (0x0250, State.SWITCH_ON_DISABLED),
        (0x0231, State.READY_TO_SWITCH_ON),
        (0x0233, State.SWITCHED_ON),
        (0x0237, State.OPERATION_ENABLED),
        (0x1637, State.OPERATION_ENABLED),
        (0x0217, State.QUICK_STOP_ACTIVE),
        (0x021F, State.FAULT_REACTION_ACTIVE),
        (0x0218, State.FAULT),
        (0x0238, State.FAULT),
    ],
)
def test_decode_state(sw: int, state: State) -> None:
    assert cia402.decode_state(sw) is state


def test_every_statusword_decodes_to_exactly_one_state() -> None:
    for sw in range(0x80):
        hits = [s for s, m, v in cia402.STATUSWORD_PATTERNS if sw & m == v]
        assert len(hits) <= 1, hex(sw)
        assert cia402.decode_state(sw) is (hits[0] if hits else State.UNKNOWN)


def test_state_bits_decode_back_to_their_state() -> None:
    for state, bits in cia402.STATE_BITS.items():
        assert cia402.decode_state(bits | 0x10) is state


def test_device_follows_the_transition_table_for_every_command_in_every_state() -> None:
    # The controlword each command uses, sent to a device in each state, must land in the
    # state the table says (or stay), and nothing else.
    for state, command in itertools.product(COMMANDED, Command):
        cw = cia402.command_word(command)
        t = cia402.device_transition(state, cw, previous=0, quick_stop_option=2)
        expected = [
            tr
            for tr in cia402.TRANSITIONS
            if tr.source is state
            and tr.number != 16
            and any(cia402.matches(c, cw) for c in tr.commands)
        ]
        if command is Command.FAULT_RESET:
            expected = [cia402.transition(15)] if state is State.FAULT else []
        if state in (State.NOT_READY_TO_SWITCH_ON, State.FAULT_REACTION_ACTIVE):
            expected = []
        if state is State.FAULT and command is not Command.FAULT_RESET:
            expected = []
        assert (t.target if t else None) == (expected[0].target if expected else None), (
            state,
            command,
        )


@pytest.mark.parametrize(
    ("state", "cw", "target"),
    [
        (State.SWITCH_ON_DISABLED, 0x06, State.READY_TO_SWITCH_ON),  # 2
        (State.READY_TO_SWITCH_ON, 0x07, State.SWITCHED_ON),  # 3
        (State.READY_TO_SWITCH_ON, 0x0F, State.OPERATION_ENABLED),  # 3+4
        (State.SWITCHED_ON, 0x0F, State.OPERATION_ENABLED),  # 4
        (State.OPERATION_ENABLED, 0x07, State.SWITCHED_ON),  # 5
        (State.SWITCHED_ON, 0x06, State.READY_TO_SWITCH_ON),  # 6
        (State.READY_TO_SWITCH_ON, 0x00, State.SWITCH_ON_DISABLED),  # 7
        (State.READY_TO_SWITCH_ON, 0x02, State.SWITCH_ON_DISABLED),  # 7
        (State.OPERATION_ENABLED, 0x06, State.READY_TO_SWITCH_ON),  # 8
        (State.OPERATION_ENABLED, 0x00, State.SWITCH_ON_DISABLED),  # 9
        (State.SWITCHED_ON, 0x02, State.SWITCH_ON_DISABLED),  # 10
        (State.OPERATION_ENABLED, 0x02, State.QUICK_STOP_ACTIVE),  # 11
        (State.QUICK_STOP_ACTIVE, 0x00, State.SWITCH_ON_DISABLED),  # 12
    ],
)
def test_numbered_transitions(state: State, cw: int, target: State) -> None:
    t = cia402.device_transition(state, cw, previous=0)
    assert t is not None and t.target is target


def test_fault_reset_needs_a_rising_edge_of_bit_7() -> None:
    assert cia402.device_transition(State.FAULT, 0x80, previous=0x00).target is (  # type: ignore[union-attr]
        State.SWITCH_ON_DISABLED
    )
    assert cia402.device_transition(State.FAULT, 0x80, previous=0x80) is None


def test_transition_16_only_with_quick_stop_options_5_to_8() -> None:
    assert cia402.device_transition(State.QUICK_STOP_ACTIVE, 0x0F, 0, quick_stop_option=2) is None
    t = cia402.device_transition(State.QUICK_STOP_ACTIVE, 0x0F, 0, quick_stop_option=6)
    assert t is not None and t.number == 16


def test_command_paths_reach_every_commandable_state_from_every_other() -> None:
    reachable = [
        State.SWITCH_ON_DISABLED,
        State.READY_TO_SWITCH_ON,
        State.SWITCHED_ON,
        State.OPERATION_ENABLED,
    ]
    for src in [*reachable, State.FAULT, State.QUICK_STOP_ACTIVE]:
        for dst in reachable:
            state = src
            prev = 0
            for cmd in cia402.command_path(src, dst):
                cw = cia402.command_word(cmd)
                t = cia402.device_transition(state, cw, prev)
                assert t is not None, (src, dst, cmd)
                state, prev = t.target, cw
            assert state is dst


def test_enable_path_is_the_usual_sequence() -> None:
    assert cia402.command_path(State.SWITCH_ON_DISABLED, State.OPERATION_ENABLED) == [
        Command.SHUTDOWN,
        Command.SWITCH_ON_ENABLE,
    ]
    assert cia402.command_path(State.FAULT, State.SWITCH_ON_DISABLED) == [Command.FAULT_RESET]
    with pytest.raises(ValueError):
        cia402.command_path(State.SWITCH_ON_DISABLED, State.FAULT)


def test_statusword_bits_use_mode_specific_names() -> None:
    bits = cia402.decode_statusword(0x1437, mode=1)
    assert bits[12] == {"bit": 12, "name": "Set-point acknowledge", "set": True}
    assert bits[10]["name"] == "Target reached" and bits[10]["set"]
    assert cia402.decode_statusword(0, mode=6)[13]["name"] == "Homing error"
