"""What a family's ramp objects (6083h profile acceleration, 6084h deceleration) hold.

CiA 402-2 §6.5 gives them in position units per s² (a *rate*). The LECSN-T gives them as a
*time* in ms from 0 to the rated speed (004 §20.9.3.10 (7)); the CTMM04x as PMC842SR rate
*registers* (1..8191, a larger value a gentler ramp; 003 §5-3-1). The profile's raw unit says
which. The one place that decides it: motion, tuning and (through ``GET /limits``) the UI.
"""

from __future__ import annotations

from typing import Literal

RampKind = Literal["rate", "time", "register"]


def ramp_kind(raw_unit: str | None) -> RampKind:
    """``rate`` for units per s² (and an object without a raw unit, CiA 402's default),
    ``time`` for ms, ``register`` for anything else."""
    if raw_unit is None:
        return "rate"
    unit = raw_unit.replace(" ", "")
    if "/s²" in unit or "/s^2" in unit or "/s2" in unit:
        return "rate"
    if unit == "ms":
        return "time"
    return "register"
