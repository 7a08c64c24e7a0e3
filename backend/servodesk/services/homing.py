"""Homing: the family's methods, starting a homing run and following it (CiA 402-2 §6.8).

The method list comes from the profile (``homing_methods``) described by the shared CiA 402
table (:mod:`servodesk.domain.homing`) and, for vendor methods, by the profile's
``homing_method_equivalent`` quirk. A run is started the same way on every family: mode 6,
the homing parameters (6098h, 6099h:01/02, 609Ah, 607Ch), then a rising edge of controlword
bit 4. Progress is decoded from statusword bits 13/12/10 (the table is the same in CiA 402-2
§6.8.1, 000 §3.2.4 table 3.2.4.3, 003 §4-4-3 and 004 §20.6.6) and sent as WebSocket ``homing``
messages from the session's state poll.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import coerce_int
from servodesk.domain.homing import (
    CW_HOMING_START,
    SW_HOMING_ATTAINED,
    SW_HOMING_ERROR,
    SW_TARGET_REACHED,
    resolve_method,
)
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import DriveStateError, ValidationError
from servodesk.services.session import CONTROLWORD, STATUSWORD, DriveState, Session

MODE = ObjectAddress(0x6060)
MODE_DISPLAY = ObjectAddress(0x6061)
POSITION = ObjectAddress(0x6064)
HOME_OFFSET = ObjectAddress(0x607C)
HOMING_METHOD = ObjectAddress(0x6098)
SPEED_SWITCH = ObjectAddress(0x6099, 1)
SPEED_ZERO = ObjectAddress(0x6099, 2)
HOMING_ACC = ObjectAddress(0x609A)
HOMING_MODE = 6
CW_HALT = 0x0100


def methods(profile: DeviceProfile) -> list[dict[str, Any]]:
    """``HomingMethod`` entries for the family's documented methods, in the profile's order."""
    spec = profile.spec(HOMING_METHOD)
    texts = spec.values if spec is not None and spec.values else {}
    equiv = profile.quirk("homing_method_equivalent")
    out: list[dict[str, Any]] = []
    for m in profile.homing_methods:
        info = resolve_method(m, equiv)
        if info is None:
            out.append(
                {
                    "method": m,
                    "name": texts.get(m, f"Vendor method {m}"),
                    "description": (
                        "Documented by the family but not described well enough to simulate; "
                        "the simulated drive refuses it."
                    ),
                    "uses": [],
                    "direction": None,
                    "section": spec.section if spec is not None else None,
                    "equivalent": None,
                    "needs_enable": True,
                }
            )
            continue
        section = info.section
        if not info.vendor and spec is not None and spec.section:
            section = f"{info.section}; {spec.section}"
        out.append(
            {
                "method": m,
                "name": info.name,
                "description": info.description,
                "uses": list(info.uses),
                "direction": info.direction_name,
                "section": section,
                "equivalent": info.equivalent,
                "needs_enable": m not in _no_enable(profile),
            }
        )
    return out


def _no_enable(profile: DeviceProfile) -> frozenset[int]:
    return frozenset(coerce_int(m) for m in profile.quirk("homing_without_enable", None) or ())


def decode(statusword: int, mode: int | None) -> str:
    """idle / running / attained / error from statusword bits 13/12/10 in homing mode."""
    if mode != HOMING_MODE:
        return "idle"
    if statusword & SW_HOMING_ERROR:
        return "error"
    attained = bool(statusword & SW_HOMING_ATTAINED)
    reached = bool(statusword & SW_TARGET_REACHED)
    if attained and reached:
        return "attained"
    if reached:
        return "idle"  # Interrupted or not started.
    return "running"


def _bits(statusword: int) -> dict[str, bool]:
    return {
        "target_reached": bool(statusword & SW_TARGET_REACHED),
        "homing_attained": bool(statusword & SW_HOMING_ATTAINED),
        "homing_error": bool(statusword & SW_HOMING_ERROR),
    }


_MESSAGES = {
    "idle": "homing not started or interrupted",
    "running": "homing in progress",
    "attained": "homing attained: the position is the home offset (607Ch)",
    "error": "homing error: a required switch was not found or a limit was reached",
}


class _Tracker:
    """Sends ``homing`` WebSocket messages from the session's state poll while a run lasts."""

    def __init__(self, session: Session, method: int) -> None:
        self.session = session
        self.method = method
        self.last: str | None = None
        self.seen_running = False

    def __call__(self, st: DriveState) -> None:
        state = decode(st.statusword, st.mode)
        if state == "running":
            self.seen_running = True
        if state != self.last or state == "running":
            self.session.hub.publish(
                {
                    "type": "homing",
                    "session": self.session.id,
                    "method": self.method,
                    "state": state,
                    "position": st.position,
                    "statusword_bits": _bits(st.statusword),
                    "message": _MESSAGES[state],
                },
                session=self.session.id,
            )
        self.last = state
        if state in ("attained", "error") or (state == "idle" and self.seen_running):
            self.stop()

    def stop(self) -> None:
        if self in self.session.state_listeners:
            self.session.state_listeners.remove(self)


def _stop_trackers(session: Session) -> None:
    for cb in list(session.state_listeners):
        if isinstance(cb, _Tracker):
            cb.stop()


async def _read_int(session: Session, address: ObjectAddress) -> int | None:
    if session.profile.spec(address) is None:
        return None
    value = (await session.read_object(address)).value
    return value if isinstance(value, int) else None


async def status(session: Session) -> dict[str, Any]:
    """``HomingStatus`` read from the drive."""
    sw = await _read_int(session, STATUSWORD) or 0
    mode = await _read_int(session, MODE_DISPLAY)
    method = await _read_int(session, HOMING_METHOD)
    position = await _read_int(session, POSITION)
    state = decode(sw, mode)
    return {
        "session": session.id,
        "method": method,
        "state": state,
        "position": position,
        "statusword_bits": _bits(sw),
        "message": _MESSAGES[state],
    }


#: Sends the controlword that starts the run (the motion service checks that no stop came).
StartSender = Callable[[int], Awaitable[None]]


async def begin(
    session: Session,
    method: int,
    *,
    speed_switch: int | None = None,
    speed_zero: int | None = None,
    acceleration: int | None = None,
    offset: int | None = None,
    client: str | None = None,
    set_mode: Callable[[], Awaitable[None]] | None = None,
    go: StartSender | None = None,
) -> bool:
    """Write the homing parameters and start the run; True when the drive was enabled.

    ``set_mode`` sets 6060h = 6 (default: a plain write); the motion service passes its own,
    which follows the family's mode-change quirks. ``go`` sends the starting controlword
    (default: a plain write).
    """
    profile = session.profile
    if method not in profile.homing_methods:
        raise ValidationError(
            f"homing method {method} is not documented for {profile.name}",
            field="method",
            hint=f"use one of {list(profile.homing_methods)} (GET .../homing/methods)",
        )
    sw = await _read_int(session, STATUSWORD) or 0
    state = cia402.decode_state(sw)
    enabled = state is cia402.State.OPERATION_ENABLED
    if not enabled and method not in _no_enable(profile):
        raise DriveStateError(
            f"homing method {method} needs Operation enabled; the drive is in {state.value}",
            hint='enable the drive first (POST .../state {"command": "enable"})',
        )
    writes: list[tuple[ObjectAddress, int | None, str]] = [
        (SPEED_SWITCH, speed_switch, "speed_switch"),
        (SPEED_ZERO, speed_zero, "speed_zero"),
        (HOMING_ACC, acceleration, "acceleration"),
        (HOME_OFFSET, offset, "offset"),
    ]
    for address, value, name in writes:
        if value is None:
            continue
        spec = profile.spec(address)
        if spec is None or not spec.access.writable:
            raise ValidationError(
                f"{name} cannot be set on {profile.name}: {address} is not writable",
                field=name,
                hint="leave it out to use the drive's value",
            )
    # Bit 4 low before the mode change, so the run starts on a clean rising edge; halt (bit 8)
    # low too, or the drive would not move (CiA 402-2 §6.8.1: halt interrupts homing).
    cw = await _read_int(session, CONTROLWORD) or (0x0F if enabled else 0)
    cw &= ~(CW_HOMING_START | CW_HALT)
    await session.write_object(CONTROLWORD, cw, client=client)
    if set_mode is not None:
        await set_mode()
    else:
        await session.write_object(MODE, HOMING_MODE, client=client)
    await session.write_object(HOMING_METHOD, method, client=client)
    for address, value, _name in writes:
        if value is not None:
            await session.write_object(address, value, client=client)
    _stop_trackers(session)
    session.state_listeners.append(_Tracker(session, method))
    if go is not None:
        await go(cw | CW_HOMING_START)
    else:
        await session.write_object(CONTROLWORD, cw | CW_HOMING_START, client=client)
    return enabled


async def start(
    session: Session,
    method: int,
    *,
    speed_switch: int | None = None,
    speed_zero: int | None = None,
    acceleration: int | None = None,
    offset: int | None = None,
    client: str | None = None,
) -> dict[str, Any]:
    """Start a run without a dead-man (scripts, tests); answers the status just after.

    The API starts homing through the motion service instead (MotionService.home), which
    puts a run that moves the axis under the client's dead-man like a jog.
    """
    await begin(
        session,
        method,
        speed_switch=speed_switch,
        speed_zero=speed_zero,
        acceleration=acceleration,
        offset=offset,
        client=client,
    )
    return await status(session)
