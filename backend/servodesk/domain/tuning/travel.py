"""The travel window of a tuning: what the user confirms, and the bound servodesk enforces.

The window the user types (``travel_window_rev``, the Tuning page, ``servodesk tune --travel``)
is a total width centred on where the axis stands when the tuning starts: the axis stays
within +- half of it. Until the first session of 2026-12-05 the page and the API said that,
while servodesk's own tuning took the window as +- the whole of it and travelled 0.45 rev one
way in a 0.5 rev window (docs/tuning.md, "Travel window").

The half-width in position units is rounded down, so that the bound is never wider than what
was confirmed; the Tuning page computes it with the same rule and the same floating-point
operations (frontend/src/components/tuning/tuningModel.ts ``windowInUnits``), so the counts it
shows are the ones the drive's software position limits (607Dh, CiA 402-2 §6.5.4) get.

Pure standard library: services/tuning/ imports it at start-up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


def half_window(window_rev: float, units_per_rev: float) -> int:
    """Half the travel window in position units: ``floor(window * units / 2)``, at least 1."""
    return max(1, math.floor(window_rev * units_per_rev / 2.0))


@dataclass(frozen=True, slots=True)
class TravelBound:
    """The positions a tuning keeps the axis within: ``start`` +- ``half`` [position units]."""

    start: int
    half: int

    @property
    def low(self) -> int:
        return self.start - self.half

    @property
    def high(self) -> int:
        return self.start + self.half

    def contains(self, low: float, high: float) -> bool:
        """Whether ``low`` .. ``high`` (positions, or a predicted envelope) lies inside."""
        return self.low <= low and high <= self.high

    def as_dict(self, units_per_rev: float, raw_unit: str | None = None) -> dict[str, object]:
        """The bound for the API: start, low and high in position units, the half-width in
        units and in revolutions."""
        return {
            "start": self.start,
            "low": self.low,
            "high": self.high,
            "half": self.half,
            "half_rev": self.half / units_per_rev if units_per_rev > 0.0 else None,
            "raw_unit": raw_unit,
        }


def bound_text(
    bound: TravelBound,
    units_per_rev: float,
    raw_unit: str | None,
    *,
    unit: str | None = None,
    scale: float | None = None,
) -> str:
    """The bound in words, engineering units and raw counts side by side: "+-0.25 rev (+-90
    deg) = +-32768 inc around 1000: -31768 .. 33768 inc". ``unit`` and ``scale``: the position's own
    engineering unit (6064h), shown where it is not revolutions."""
    raw = f" {raw_unit}" if raw_unit else ""
    parts = [f"±{_g(bound.half / units_per_rev)} rev"]
    if unit and scale and unit not in ("rev", "r"):
        parts.append(f"(±{_g(bound.half * scale)} {unit})")
    return (
        f"{' '.join(parts)} = ±{bound.half}{raw} around {bound.start}: "
        f"{bound.low} … {bound.high}{raw}"
    )


def _g(x: float) -> str:
    """A figure as the page shows it: up to 6 significant digits, no trailing zeros."""
    return f"{x:.6g}"


def stop_overrun(velocity: float, deceleration: float, stop_deceleration: float | None) -> float:
    """How far a stop from ``velocity`` runs past the move's own braking [units].

    A halt or quick stop ramps the position demand down from where it is at its own
    deceleration (CiA 402-2 §6.3.4: 605Ah/605Dh options 1 and 2, 6084h and 6085h); a move whose
    profile brakes at ``deceleration`` would have stopped ``v^2 / 2a`` further on, so a stop
    ramp at least as steep ends inside the move's set-points, and a gentler one runs
    ``v^2 / 2 (1 / a_stop - 1 / a)`` beyond them. ``stop_deceleration`` None: a stop at the
    torque limit (options 3, 4), no gentler than any move of the tuning."""
    if stop_deceleration is None or velocity <= 0.0 or deceleration <= 0.0:
        return 0.0
    if stop_deceleration <= 0.0:
        return math.inf
    return max(0.0, 0.5 * velocity * velocity * (1.0 / stop_deceleration - 1.0 / deceleration))
