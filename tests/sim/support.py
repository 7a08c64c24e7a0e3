"""Helpers for the simulated-drive tests: profiles with quirks, driving the state machine."""

from __future__ import annotations

from typing import Any

from servodesk.domain.cia402 import State
from servodesk.domain.profile import DeviceProfile, Quirk
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimulatedDrive

_CATALOG = ProfileCatalog()


def generic() -> DeviceProfile:
    return _CATALOG.get("cia402-generic")


def with_quirks(profile: DeviceProfile, **quirks: Any) -> DeviceProfile:
    """The profile with these quirks (replacing its own)."""
    return profile.model_copy(
        update={"quirks": tuple(Quirk(id=k, value=v) for k, v in quirks.items())}
    )


def with_objects(profile: DeviceProfile, **changes: dict[str, Any]) -> DeviceProfile:
    """The profile with some entries changed: ``with_objects(p, x6065={"access": "wo"})``."""
    data = profile.model_dump()
    for entry in data["objects"]:
        entry.update(changes.get(f"x{entry['index']:04X}", {}))
    return DeviceProfile.model_validate(data)


def new_drive(profile: DeviceProfile | None = None, node_id: int = 5) -> SimulatedDrive:
    d = SimulatedDrive(profile or generic(), node_id)
    d.step(0.001)  # Initialisation: Not ready to switch on -> Switch on disabled.
    return d


def cw(drive: SimulatedDrive, value: int) -> None:
    drive.write(0x6040, 0, value)


def enable(drive: SimulatedDrive) -> None:
    for word in (0x06, 0x07, 0x0F):
        cw(drive, word)
    assert drive.state is State.OPERATION_ENABLED


def bring_to(drive: SimulatedDrive, state: State) -> None:
    """Walk a fresh drive (Switch on disabled) to ``state``."""
    if state is State.SWITCH_ON_DISABLED:
        return
    if state is State.FAULT:
        drive.raise_fault(0x8611)
        assert drive.state is State.FAULT
        return
    cw(drive, 0x06)
    if state is State.READY_TO_SWITCH_ON:
        return
    cw(drive, 0x07)
    if state is State.SWITCHED_ON:
        return
    cw(drive, 0x0F)
    if state is State.OPERATION_ENABLED:
        return
    assert state is State.QUICK_STOP_ACTIVE
    drive.write(0x605A, 0, 6)  # Stay in Quick stop active after stopping.
    cw(drive, 0x02)
    drive.step(0.01)
    assert drive.state is State.QUICK_STOP_ACTIVE


def run_until(drive: SimulatedDrive, cond: Any, timeout: float, dt: float = 0.001) -> float:
    """Step until ``cond()`` is true; returns the simulated time it took (fails on timeout)."""
    t = 0.0
    while not cond():
        if t >= timeout:
            raise AssertionError(f"condition not met within {timeout} s simulated")
        drive.step(dt)
        t += dt
    return t
