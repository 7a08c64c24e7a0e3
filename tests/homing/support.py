"""Helpers for the homing tests: run a simulated drive unbound (no bus, simulated time)."""

from __future__ import annotations

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimulatedDrive

CATALOG = ProfileCatalog()
FAMILIES = ("cia402-generic", "hiwin-e", "ctmm04x", "lecsn-t", "smartris")

SW_REACHED, SW_ATTAINED, SW_ERROR = 0x0400, 0x1000, 0x2000


def speeds(profile: DeviceProfile) -> tuple[int, int, int]:
    """Switch-search speed, zero-search speed, acceleration for a quick homing run.

    3 rev/s (or 80 % of the simulated maximum), a sixth of it for the zero search, and an
    acceleration that stops within 0.15 revolution.
    """
    rev = profile.simulation.counts_per_rev
    fast = int(min(3 * rev, 0.8 * profile.simulation.max_velocity))
    acc = fast * fast / (0.3 * rev)
    rr = profile.quirk("ramp_rate_registers")
    if isinstance(rr, dict):
        # 003 §5-3-1: 609Ah is a rate register; ramp = Fclk/8 / register (multiplier 1).
        return fast, fast // 6, max(1, min(8191, int(rr["fclk_hz"] / 8 / acc)))
    speed = profile.spec(ObjectAddress(0x6099, 1))
    if speed is not None and speed.unit == "r/min":
        # 004 §20.9.3.11: speeds in 0.01 r/min, 609Ah in ms from 0 to the rated speed.
        rpm = round(fast / rev * 60 / speed.scale)
        rated = profile.simulation.rated_speed or profile.simulation.max_velocity
        return rpm, rpm // 6, round(rated / acc * 1000)
    return fast, fast // 6, int(acc)


def enable(d: SimulatedDrive) -> None:
    for word in (0x06, 0x07, 0x0F):
        d.write(0x6040, 0, word)
        d.step(0.05)  # Some families need time between controlwords (smartris 40 ms).


def start_homing(
    profile: DeviceProfile, method: int, start_revs: float, *, offset: int | None = 1000
) -> SimulatedDrive:
    d = SimulatedDrive(profile, 5)
    d.step(0.001)
    rev = profile.simulation.counts_per_rev
    d.plant.set_position_counts(start_revs * rev)
    fast, slow, acc = speeds(profile)
    d.write(0x6099, 1, fast)
    d.write(0x6099, 2, slow)
    d.write(0x609A, 0, acc)
    if offset is not None and d.spec(0x607C).access.writable:
        d.write(0x607C, 0, offset)
    d.write(0x6060, 0, 6)
    d.write(0x6098, 0, method)
    enable(d)
    d.write(0x6040, 0, 0x1F)
    return d


def run_homing(d: SimulatedDrive, timeout: float = 30.0) -> None:
    """Step until homing is attained with target reached, or a homing error at standstill."""
    t = 0.0
    while True:
        sw = d.statusword
        if sw & SW_REACHED and sw & (SW_ATTAINED | SW_ERROR):
            return
        if t > timeout:
            raise AssertionError(f"homing did not finish in {timeout} s (statusword {sw:04X})")
        d.step(0.01)
        t += 0.01
