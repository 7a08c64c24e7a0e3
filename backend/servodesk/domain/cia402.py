"""The CiA 402 drive state machine as tables (IEC 61800-7-201 / CiA 402-2 §6.2).

Used on both sides of the bus: a master decodes the statusword and picks controlword
commands (:func:`decode_state`, :func:`command_path`); a device decides the next state from
a controlword (:func:`device_transition`). Both read the same tables.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from servodesk.domain.address import ObjectAddress


class State(enum.Enum):
    """Drive states; the value is the display name used in the API and UI."""

    NOT_READY_TO_SWITCH_ON = "Not ready to switch on"
    SWITCH_ON_DISABLED = "Switch on disabled"
    READY_TO_SWITCH_ON = "Ready to switch on"
    SWITCHED_ON = "Switched on"
    OPERATION_ENABLED = "Operation enabled"
    QUICK_STOP_ACTIVE = "Quick stop active"
    FAULT_REACTION_ACTIVE = "Fault reaction active"
    FAULT = "Fault"
    UNKNOWN = "Unknown"


# CiA 402-2 table 30: statusword bit patterns (mask, value) per state.
STATUSWORD_PATTERNS: tuple[tuple[State, int, int], ...] = (
    (State.NOT_READY_TO_SWITCH_ON, 0x004F, 0x0000),
    (State.SWITCH_ON_DISABLED, 0x004F, 0x0040),
    (State.READY_TO_SWITCH_ON, 0x006F, 0x0021),
    (State.SWITCHED_ON, 0x006F, 0x0023),
    (State.OPERATION_ENABLED, 0x006F, 0x0027),
    (State.QUICK_STOP_ACTIVE, 0x006F, 0x0007),
    (State.FAULT_REACTION_ACTIVE, 0x004F, 0x000F),
    (State.FAULT, 0x004F, 0x0008),
)

# The state bits a device reports in each state (bits 0-3, 5, 6); bit 4 (voltage enabled) and
# the mode-specific bits are added by the device.
STATE_BITS: dict[State, int] = {
    State.NOT_READY_TO_SWITCH_ON: 0x0000,
    State.SWITCH_ON_DISABLED: 0x0040,
    State.READY_TO_SWITCH_ON: 0x0021,
    State.SWITCHED_ON: 0x0023,
    State.OPERATION_ENABLED: 0x0027,
    State.QUICK_STOP_ACTIVE: 0x0007,
    State.FAULT_REACTION_ACTIVE: 0x000F,
    State.FAULT: 0x0008,
}


class Command(enum.Enum):
    """Controlword device-control commands (CiA 402-2 table 28)."""

    SHUTDOWN = "shutdown"
    SWITCH_ON = "switch_on"
    SWITCH_ON_ENABLE = "switch_on_enable"
    DISABLE_VOLTAGE = "disable_voltage"
    QUICK_STOP = "quick_stop"
    DISABLE_OPERATION = "disable_operation"
    ENABLE_OPERATION = "enable_operation"
    FAULT_RESET = "fault_reset"


@dataclass(frozen=True, slots=True)
class CommandPattern:
    mask: int
    value: int
    #: The low byte a master writes for the command (bits 0-3 and 7).
    word: int


# Bits 7, 3, 2, 1, 0 of the controlword; "x" bits are outside the mask.
COMMAND_PATTERNS: dict[Command, CommandPattern] = {
    Command.SHUTDOWN: CommandPattern(0x0087, 0x0006, 0x0006),
    Command.SWITCH_ON: CommandPattern(0x008F, 0x0007, 0x0007),
    Command.SWITCH_ON_ENABLE: CommandPattern(0x008F, 0x000F, 0x000F),
    Command.DISABLE_VOLTAGE: CommandPattern(0x0082, 0x0000, 0x0000),
    Command.QUICK_STOP: CommandPattern(0x0086, 0x0002, 0x0002),
    Command.DISABLE_OPERATION: CommandPattern(0x008F, 0x0007, 0x0007),
    Command.ENABLE_OPERATION: CommandPattern(0x008F, 0x000F, 0x000F),
    # Fault reset acts on the rising edge of bit 7 (CiA 402-2 §6.2.1 note).
    Command.FAULT_RESET: CommandPattern(0x0080, 0x0080, 0x0080),
}


@dataclass(frozen=True, slots=True)
class Transition:
    number: int
    source: State
    target: State
    commands: tuple[Command, ...]


# CiA 402-2 table 29. Transitions 0, 1, 13 and 14 are internal (not commanded); 12 is also
# taken automatically when a quick stop with option code 0..4 finishes.
TRANSITIONS: tuple[Transition, ...] = (
    Transition(2, State.SWITCH_ON_DISABLED, State.READY_TO_SWITCH_ON, (Command.SHUTDOWN,)),
    Transition(3, State.READY_TO_SWITCH_ON, State.SWITCHED_ON, (Command.SWITCH_ON,)),
    # "Switch on + enable operation" from Ready to switch on passes 3 then 4 at once.
    Transition(34, State.READY_TO_SWITCH_ON, State.OPERATION_ENABLED, (Command.SWITCH_ON_ENABLE,)),
    Transition(4, State.SWITCHED_ON, State.OPERATION_ENABLED, (Command.ENABLE_OPERATION,)),
    Transition(5, State.OPERATION_ENABLED, State.SWITCHED_ON, (Command.DISABLE_OPERATION,)),
    Transition(6, State.SWITCHED_ON, State.READY_TO_SWITCH_ON, (Command.SHUTDOWN,)),
    Transition(
        7,
        State.READY_TO_SWITCH_ON,
        State.SWITCH_ON_DISABLED,
        (Command.QUICK_STOP, Command.DISABLE_VOLTAGE),
    ),
    Transition(8, State.OPERATION_ENABLED, State.READY_TO_SWITCH_ON, (Command.SHUTDOWN,)),
    Transition(9, State.OPERATION_ENABLED, State.SWITCH_ON_DISABLED, (Command.DISABLE_VOLTAGE,)),
    Transition(
        10,
        State.SWITCHED_ON,
        State.SWITCH_ON_DISABLED,
        (Command.DISABLE_VOLTAGE, Command.QUICK_STOP),
    ),
    Transition(11, State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE, (Command.QUICK_STOP,)),
    Transition(12, State.QUICK_STOP_ACTIVE, State.SWITCH_ON_DISABLED, (Command.DISABLE_VOLTAGE,)),
    Transition(15, State.FAULT, State.SWITCH_ON_DISABLED, (Command.FAULT_RESET,)),
    # Only when quick-stop option code (605Ah) is 5..8: stay in quick stop, then re-enable.
    Transition(16, State.QUICK_STOP_ACTIVE, State.OPERATION_ENABLED, (Command.ENABLE_OPERATION,)),
)

# Commands a master sends (in order) to walk from a state to a target, shortest first.
# Computed once from TRANSITIONS by breadth-first search; transition 16 is left out because
# it depends on 605Ah, and fault reset is only used from FAULT.
_COMMANDABLE = tuple(t for t in TRANSITIONS if t.number != 16)


def decode_state(statusword: int) -> State:
    """The state a statusword reports (CiA 402-2 table 30)."""
    for state, mask, value in STATUSWORD_PATTERNS:
        if statusword & mask == value:
            return state
    return State.UNKNOWN


def matches(command: Command, controlword: int) -> bool:
    p = COMMAND_PATTERNS[command]
    return controlword & p.mask == p.value


def command_word(command: Command, keep: int = 0) -> int:
    """The controlword for ``command``, keeping the non-state bits of ``keep`` (4-6, 8-15)."""
    return (keep & 0xFF70) | COMMAND_PATTERNS[command].word


def command_path(source: State, target: State) -> list[Command]:
    """Commands to send, in order, to go from ``source`` to ``target``.

    Raises ValueError when the target is not reachable by commands (e.g. FAULT).
    """
    if source == target:
        return []
    frontier: list[tuple[State, list[Command]]] = [(source, [])]
    seen = {source}
    if source in (State.FAULT, State.FAULT_REACTION_ACTIVE):
        frontier = [(State.SWITCH_ON_DISABLED, [Command.FAULT_RESET])]
        seen.add(State.SWITCH_ON_DISABLED)
        if target == State.SWITCH_ON_DISABLED:
            return [Command.FAULT_RESET]
    if source == State.NOT_READY_TO_SWITCH_ON:
        raise ValueError("the drive is still initialising (Not ready to switch on)")
    while frontier:
        nxt: list[tuple[State, list[Command]]] = []
        for state, path in frontier:
            for t in _COMMANDABLE:
                if t.source != state or t.target in seen or t.commands[0] == Command.FAULT_RESET:
                    continue
                p = [*path, t.commands[0]]
                if t.target == target:
                    return p
                seen.add(t.target)
                nxt.append((t.target, p))
        frontier = nxt
    raise ValueError(f"{target.value} cannot be reached from {source.value} by commands")


def device_transition(
    state: State, controlword: int, previous: int, quick_stop_option: int = 2
) -> Transition | None:
    """The transition a device takes for a new controlword, or None to stay.

    ``previous`` is the last controlword (fault reset acts on the 0->1 edge of bit 7).
    ``quick_stop_option`` is 605Ah: with 5..8 the drive stays in Quick stop active and can
    return to Operation enabled (transition 16).
    """
    if state in (State.FAULT,):
        if controlword & 0x80 and not previous & 0x80:
            return _BY_NUMBER[15]
        return None
    if state in (State.NOT_READY_TO_SWITCH_ON, State.FAULT_REACTION_ACTIVE, State.UNKNOWN):
        return None
    if controlword & 0x80:
        # Bit 7 set outside Fault: CiA 402 says the command bits are ignored while bit 7 is 1.
        return None
    for t in TRANSITIONS:
        if t.source != state:
            continue
        if t.number == 16 and not 5 <= quick_stop_option <= 8:
            continue
        if any(matches(c, controlword) for c in t.commands):
            return t
    return None


_BY_NUMBER = {t.number: t for t in TRANSITIONS}


def transition(number: int) -> Transition:
    return _BY_NUMBER[number]


# Statusword bits (CiA 402-2 §6.2.1, table 30 and mode-specific bits 10, 12, 13).
STATUSWORD_BITS: tuple[tuple[int, str], ...] = (
    (0, "Ready to switch on"),
    (1, "Switched on"),
    (2, "Operation enabled"),
    (3, "Fault"),
    (4, "Voltage enabled"),
    (5, "Quick stop"),
    (6, "Switch on disabled"),
    (7, "Warning"),
    (8, "Manufacturer specific"),
    (9, "Remote"),
    (10, "Target reached"),
    (11, "Internal limit active"),
    (12, "Operation mode specific 1"),
    (13, "Operation mode specific 2"),
    (14, "Manufacturer specific 14"),
    (15, "Manufacturer specific 15"),
)

# Bits 12 and 13 mean different things per mode (CiA 402-2 §6.2.1 and the mode chapters).
MODE_BIT_NAMES: dict[int, tuple[str, str]] = {
    1: ("Set-point acknowledge", "Following error"),
    3: ("Speed", "Max slippage error"),
    4: ("Reserved", "Reserved"),
    6: ("Homing attained", "Homing error"),
    7: ("IP mode active", "Reserved"),
    8: ("Target position ignored", "Following error"),
    9: ("Target velocity ignored", "Reserved"),
    10: ("Target torque ignored", "Reserved"),
}


def decode_statusword(statusword: int, mode: int | None = None) -> list[dict[str, object]]:
    """Every statusword bit with its name (mode-specific names for bits 12 and 13)."""
    out: list[dict[str, object]] = []
    names = MODE_BIT_NAMES.get(mode or 0)
    for bit, name in STATUSWORD_BITS:
        if names and bit == 12:
            name = names[0]
        elif names and bit == 13:
            name = names[1]
        out.append({"bit": bit, "name": name, "set": bool(statusword >> bit & 1)})
    return out


class Mode(enum.IntEnum):
    """Modes of operation, as written to 6060h (CiA 402-2 table 34)."""

    PROFILE_POSITION = 1
    VELOCITY = 2
    PROFILE_VELOCITY = 3
    PROFILE_TORQUE = 4
    HOMING = 6
    INTERPOLATED_POSITION = 7
    CYCLIC_SYNC_POSITION = 8
    CYCLIC_SYNC_VELOCITY = 9
    CYCLIC_SYNC_TORQUE = 10


MODE_NAMES: dict[int, str] = {
    1: "Profile position (pp)",
    2: "Velocity (vl)",
    3: "Profile velocity (pv)",
    4: "Profile torque (tq)",
    6: "Homing (hm)",
    7: "Interpolated position (ip)",
    8: "Cyclic sync position (csp)",
    9: "Cyclic sync velocity (csv)",
    10: "Cyclic sync torque (cst)",
    0: "No mode",
}


def mode_name(mode: int) -> str:
    if mode < 0:
        return f"Manufacturer-specific ({mode})"
    return MODE_NAMES.get(mode, f"Reserved ({mode})")


# --- The controlword's and statusword's bits the services set and test, one name each
# (issue 51 item 5: motion, homing and tuning each defined their own). The state machine's
# bits are Command/State above. ---

#: Controlword (6040h, CiA 402-2 §6.2.1): switch on, enable voltage, quick stop (active low)
#: and enable operation: the command "enable operation" with no mode-specific bit.
CW_ENABLE = 0x000F
#: Bit 4, mode-specific: pp "new set-point" (§6.7.1), hm "homing operation start" (§6.8.1).
CW_NEW_SETPOINT = 0x0010
#: Bit 5, pp: "change set immediately" (§6.7.1).
CW_IMMEDIATE = 0x0020
#: Bit 6, pp: the target is relative (§6.7.1).
CW_RELATIVE = 0x0040
#: Bit 8: halt (§6.2.1; the drive stops as 605Dh says).
CW_HALT = 0x0100
#: Statusword (6041h, §6.2.2) bit 3: fault.
SW_FAULT = 0x0008
#: Bit 10: target reached (pp, pv, hm; in pv the velocity, in hm the home).
SW_TARGET_REACHED = 0x0400
#: Bit 12, mode-specific: pp "set-point acknowledge" (§6.7.1), hm "homing attained" (§6.8.1).
SW_SETPOINT_ACK = 0x1000
SW_HOMING_ATTAINED = 0x1000
#: Bit 13, mode-specific: hm "homing error" (§6.8.1), pp/csp "following error".
SW_HOMING_ERROR = 0x2000


# --- The CiA 402 objects servodesk reads and writes, one name each (CiA 402-2's object
# dictionary; the sections cited are those the services cite). Services import them from
# here (issue 51 item 5: seven service modules each defined their own, 607Ah under two
# names). ---

ERROR_CODE = ObjectAddress(0x603F)  # the last fault's code (CiA 402-2 annex A)
CONTROLWORD = ObjectAddress(0x6040)  # §6.2.1
STATUSWORD = ObjectAddress(0x6041)
QUICK_STOP_OPTION = ObjectAddress(0x605A)
HALT_OPTION = ObjectAddress(0x605D)  # §6.3.4
MODE = ObjectAddress(0x6060)  # modes of operation
MODE_DISPLAY = ObjectAddress(0x6061)  # modes of operation display
POSITION = ObjectAddress(0x6064)  # position actual value
FOLLOWING_ERROR_WINDOW = ObjectAddress(0x6065)
VELOCITY = ObjectAddress(0x606C)  # velocity actual value
VELOCITY_THRESHOLD = ObjectAddress(0x606F)
TARGET_TORQUE = ObjectAddress(0x6071)  # per mille of rated torque
MAX_TORQUE = ObjectAddress(0x6072)
RATED_TORQUE = ObjectAddress(0x6076)  # mN m
TORQUE_ACTUAL = ObjectAddress(0x6077)  # per mille of rated torque
TARGET_POSITION = ObjectAddress(0x607A)
HOME_OFFSET = ObjectAddress(0x607C)
SOFT_LIMIT_MIN = ObjectAddress(0x607D, 1)  # software position limit, §6.5.4 (min = max = 0: off)
SOFT_LIMIT_MAX = ObjectAddress(0x607D, 2)
MAX_PROFILE_VELOCITY = ObjectAddress(0x607F)
PROFILE_VELOCITY = ObjectAddress(0x6081)
PROFILE_ACC = ObjectAddress(0x6083)
PROFILE_DEC = ObjectAddress(0x6084)
QUICK_STOP_DEC = ObjectAddress(0x6085)
TORQUE_SLOPE = ObjectAddress(0x6087)
ENCODER_INCREMENTS = ObjectAddress(0x608F, 1)  # position encoder resolution
ENCODER_REVOLUTIONS = ObjectAddress(0x608F, 2)
HOMING_METHOD = ObjectAddress(0x6098)
HOMING_SPEED_SWITCH = ObjectAddress(0x6099, 1)
HOMING_SPEED_ZERO = ObjectAddress(0x6099, 2)
HOMING_ACC = ObjectAddress(0x609A)
FOLLOWING_ERROR = ObjectAddress(0x60F4)  # following error actual value
TARGET_VELOCITY = ObjectAddress(0x60FF)
