"""CiA 402 homing methods as data: what each standard method searches and where it ends.

One :class:`HomingMethodInfo` per standard method of CiA 402-2 §6.8 (methods 1-14 with index
pulse, 17-30 without, 33/34 index pulse only, 35/37 current position). The same table drives
the simulated drive (``sim/homing.py``) and the API's method list, so the description the user
reads and the motion the simulation makes cannot drift apart.

Geometry used by the descriptions (CiA 402-2 §6.8, figures of methods 1-35):

- the negative limit switch is active at and below one position, the positive limit switch at
  and above another;
- the home switch is active between a lower and an upper edge (a "dog"); methods 3/4 and 19/20
  use only its lower edge (a "positive home switch", active above it), methods 5/6 and 21/22 only
  its upper edge (a "negative home switch", active below it);
- the index pulse comes once per motor revolution.

Each method ends at one edge (``edge``) reached while moving in ``approach`` direction; with
``index`` it ends instead at the first index pulse after that edge, further in the approach
direction (e.g. method 7: "home at the first index pulse to the left of the lower home switch
edge", which is the edge met while moving negative).

Vendor-specific (negative) methods are not in this table: a profile maps each to the standard
method whose end point it shares, with its manual section (quirk ``homing_method_equivalent``),
and :func:`resolve_method` follows that mapping.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

from servodesk.domain.cia402 import (
    CW_NEW_SETPOINT,
    SW_HOMING_ATTAINED,
    SW_HOMING_ERROR,
    SW_TARGET_REACHED,
)
from servodesk.domain.datatypes import coerce_int
from servodesk.domain.profile import SimSettings

Signal = Literal["home_switch", "limit_negative", "limit_positive", "index"]
Edge = Literal["limit_negative", "limit_positive", "home_low", "home_high"]

#: Controlword bit 4 in homing mode: homing operation start (rising edge starts, 0
#: interrupts; CiA 402-2 §6.8.1). The statusword's bits are domain/cia402.py's.
CW_HOMING_START = CW_NEW_SETPOINT


@dataclass(frozen=True, slots=True)
class HomingMethodInfo:
    """A homing method: what it uses, which way it starts and where the home position is."""

    method: int
    name: str
    description: str
    uses: tuple[Signal, ...]
    #: Initial direction when no switch is active at the start: -1, +1, or 0 (no motion).
    direction: int
    section: str
    #: The edge the method ends on (None: index pulse only, or current position).
    edge: Edge | None = None
    #: Direction of motion in which the edge is met (and the index searched after it).
    approach: int = 0
    index: bool = False
    #: Methods 7-14 and 23-30 reverse at the limit switch in the initial direction; others
    #: stop with a homing error when they reach a limit switch they do not search.
    reverse_at_limit: bool = False
    #: The method needs no motion: the current position becomes the home position.
    current_position: bool = False
    vendor: bool = False
    equivalent: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def direction_name(self) -> str | None:
        return {-1: "negative", 1: "positive"}.get(self.direction)


_S = "CiA 402-2 §6.8.1"
_LIMIT_N: tuple[Signal, ...] = ("limit_negative",)
_LIMIT_P: tuple[Signal, ...] = ("limit_positive",)


def _edge_text(edge: Edge, approach: int) -> str:
    where = {
        "limit_negative": "where the negative limit switch becomes inactive",
        "limit_positive": "where the positive limit switch becomes inactive",
        "home_low": "the lower (negative-side) edge of the home switch",
        "home_high": "the upper (positive-side) edge of the home switch",
    }[edge]
    return f"{where}, met moving {'positive' if approach > 0 else 'negative'}"


def _method(
    n: int,
    name: str,
    uses: tuple[Signal, ...],
    direction: int,
    edge: Edge | None,
    approach: int,
    index: bool,
    reverse: bool = False,
) -> HomingMethodInfo:
    if edge is None:
        desc = (
            f"Moves {'negative' if direction < 0 else 'positive'} at the zero-search speed "
            "(6099h:02); home is the first index pulse."
        )
    else:
        side = "right" if approach > 0 else "left"
        at = _edge_text(edge, approach)
        desc = f"Searches {at} at the switch-search speed (6099h:01)"
        if index:
            desc += f"; home is the first index pulse to the {side} of it (6099h:02)."
        else:
            desc += "; home is that edge (approached at 6099h:02)."
        if reverse:
            desc += " Reverses at the limit switch in the initial direction."
        elif edge.startswith("home"):
            desc += " Reaching a limit switch first is a homing error."
    return HomingMethodInfo(
        method=n,
        name=name,
        description=desc,
        uses=uses + (("index",) if index else ()),
        direction=direction,
        section=_S,
        edge=edge,
        approach=approach,
        index=index,
        reverse_at_limit=reverse,
    )


_CURRENT_NOTE = {
    35: "CiA 402-2 V4.0 numbering; V4.1 renumbered it 37",
    37: "CiA 402-2 V4.1",
}


def _table() -> dict[int, HomingMethodInfo]:
    t: dict[int, HomingMethodInfo] = {}
    hs_p: tuple[Signal, ...] = ("home_switch", "limit_positive")
    hs_n: tuple[Signal, ...] = ("home_switch", "limit_negative")
    hs: tuple[Signal, ...] = ("home_switch",)
    # (number, name, uses, initial direction, edge, approach, reverse at limit)
    rows: list[tuple[int, str, tuple[Signal, ...], int, Edge, int, bool]] = [
        (1, "Negative limit switch", _LIMIT_N, -1, "limit_negative", 1, False),
        (2, "Positive limit switch", _LIMIT_P, 1, "limit_positive", -1, False),
        (3, "Positive home switch", hs, 1, "home_low", -1, False),
        (4, "Positive home switch", hs, 1, "home_low", 1, False),
        (5, "Negative home switch", hs, -1, "home_high", 1, False),
        (6, "Negative home switch", hs, -1, "home_high", -1, False),
        (7, "Home switch, positive initial direction", hs_p, 1, "home_low", -1, True),
        (8, "Home switch, positive initial direction", hs_p, 1, "home_low", 1, True),
        (9, "Home switch, positive initial direction", hs_p, 1, "home_high", -1, True),
        (10, "Home switch, positive initial direction", hs_p, 1, "home_high", 1, True),
        (11, "Home switch, negative initial direction", hs_n, -1, "home_high", 1, True),
        (12, "Home switch, negative initial direction", hs_n, -1, "home_high", -1, True),
        (13, "Home switch, negative initial direction", hs_n, -1, "home_low", 1, True),
        (14, "Home switch, negative initial direction", hs_n, -1, "home_low", -1, True),
    ]
    for base, idx in ((0, True), (16, False)):
        suffix = " and index pulse" if idx else " (no index pulse)"
        for k, name, uses, direction, edge, approach, reverse in rows:
            n = k + base
            t[n] = _method(n, name + suffix, uses, direction, edge, approach, idx, reverse)
    t[33] = _method(33, "Index pulse, negative direction", (), -1, None, -1, True)
    t[34] = _method(34, "Index pulse, positive direction", (), 1, None, 1, True)
    for n in (35, 37):
        t[n] = HomingMethodInfo(
            method=n,
            name="Current position",
            description=(
                "The current position becomes the home position: 6064h = 607Ch, no motion "
                f"({_CURRENT_NOTE[n]})."
            ),
            uses=(),
            direction=0,
            section=_S,
            current_position=True,
        )
    return t


#: The standard methods by number.
CIA402_METHODS: dict[int, HomingMethodInfo] = _table()


def equivalents(quirk_value: Any) -> dict[int, dict[str, Any]]:
    """The profile's ``homing_method_equivalent`` quirk as {method: {"method": n, ...}}.

    Each entry is either a plain standard method number or a mapping with ``method`` (the
    standard method), ``name``, ``description``, ``section``, ``direction`` and
    ``needs_enable`` (the vendor method needs Operation enabled even when the standard one
    does not).
    """
    out: dict[int, dict[str, Any]] = {}
    if not isinstance(quirk_value, dict):
        return out
    for k, v in quirk_value.items():
        entry = dict(v) if isinstance(v, dict) else {"method": v}
        entry["method"] = coerce_int(entry["method"])
        out[coerce_int(k)] = entry
    return out


def resolve_method(method: int, quirk_value: Any = None) -> HomingMethodInfo | None:
    """The behaviour of a method: the standard one, or a vendor method's mapped equivalent.

    None when neither the standard table nor the profile's mapping describes it.
    """
    std = CIA402_METHODS.get(method)
    if method > 0:
        return std
    entry = equivalents(quirk_value).get(method)
    if entry is None:
        return None
    base = CIA402_METHODS.get(entry["method"])
    if base is None:
        return None
    direction = entry.get("direction")
    d = base.direction if direction is None else {"negative": -1, "positive": 1}[direction]
    return HomingMethodInfo(
        method=method,
        name=str(entry.get("name") or base.name),
        description=str(entry.get("description") or base.description)
        + f" Simulated as method {base.method}.",
        uses=base.uses,
        direction=d,
        section=str(entry.get("section") or base.section),
        edge=base.edge,
        approach=base.approach,
        index=base.index,
        reverse_at_limit=base.reverse_at_limit,
        current_position=base.current_position,
        vendor=True,
        equivalent=base.method,
        extra={k: v for k, v in entry.items() if k not in ("method", "name", "description")},
    )


# Duration estimate and time-out ---------------------------------------------------------------
#
# A homing run has no target the user can see: it searches. What it will cover is bounded by the
# travel of the axis (the span between its ends), and what it takes by the two homing speeds and
# the homing acceleration (CiA 402-2 §6.8.2: 6099h:01 while searching a switch, 6099h:02 while
# searching the zero, 609Ah for every speed change). The estimate below is the longest a normal
# run takes from any start inside that travel, phase by phase, so that the user sees before the
# start what a slow zero-search speed costs (CTMM04x: 6099h:02 defaults to 10 pps, 003 §4-4-8,
# and the index search after the switch then covers up to one motor revolution at 10 pps), and
# so that a run that goes on much longer than that is stopped (the time-out).

#: The time-out when no estimate can be made (the travel or a speed is not known).
DEFAULT_TIMEOUT_S = 300.0
#: The time-out by default: this many times the estimate, plus MARGIN_S, within these bounds.
#: The upper bound keeps a run that would crawl for hours from being watched for hours: the
#: user who means it sets a longer time-out (``timeout_s``, up to MAX_TIMEOUT_S).
TIMEOUT_FACTOR = 2.0
TIMEOUT_MARGIN_S = 30.0
MIN_TIMEOUT_S = 60.0
MAX_DEFAULT_TIMEOUT_S = 3600.0
MAX_TIMEOUT_S = 86400.0
#: A phase at one speed that takes longer than this is worth a word in the panel.
SLOW_PHASE_S = 60.0


@dataclass(frozen=True, slots=True)
class HomingGeometry:
    """The distances a run may cover, in position units (6064h's).

    ``travel``: the span between the ends of the axis the searches may reach (a user's maximum
    travel, the software limit range 607Dh, or the twin's switch layout); ``index_spacing``: the
    distance between two index pulses (one motor revolution), None when not known;
    ``switch_width``: the width of the home switch (the dog), None when not known.
    """

    travel: float
    travel_source: str
    index_spacing: float | None = None
    switch_width: float | None = None


@dataclass(frozen=True, slots=True)
class HomingPhase:
    """One part of a run at one speed: what it does, how far, how fast and how long."""

    name: str
    distance: float
    speed: float
    seconds: float
    #: The speed object that sets it ("6099h:01" or "6099h:02").
    speed_object: str


@dataclass(frozen=True, slots=True)
class HomingEstimate:
    """The longest a normal run takes from any start within the travel (worst case)."""

    seconds: float
    phases: tuple[HomingPhase, ...]
    #: What the estimate leaves out or assumes, in the user's words.
    assumptions: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        return {
            "seconds": round(self.seconds, 3),
            "phases": [
                {
                    "name": p.name,
                    "distance": round(p.distance, 1),
                    "speed": round(p.speed, 3),
                    "seconds": round(p.seconds, 3),
                    "speed_object": p.speed_object,
                }
                for p in self.phases
            ],
            "assumptions": list(self.assumptions),
        }


def move_time(distance: float, speed: float, acceleration: float | None) -> float:
    """Seconds to cover ``distance`` from rest to rest at up to ``speed`` with ``acceleration``
    for every speed change (a trapezoid, or a triangle when the distance is short); without an
    acceleration the ramps take no time."""
    d, v = abs(distance), abs(speed)
    if d == 0.0:
        return 0.0
    if acceleration is None or acceleration <= 0.0 or not math.isfinite(acceleration):
        return d / v
    if d >= v * v / acceleration:
        return d / v + v / acceleration
    return 2.0 * math.sqrt(d / acceleration)


def estimate_duration(
    info: HomingMethodInfo,
    geometry: HomingGeometry,
    switch_speed: float,
    zero_speed: float,
    acceleration: float | None,
) -> HomingEstimate | None:
    """The worst-case duration of a run of ``info`` (CiA 402-2 §6.8.1 method figures).

    Speeds in position units per s, the acceleration in position units per s² (None: not
    known, the ramps are left out). None when a speed the method uses is 0 (it never ends).
    The phases follow the method figures: the search for the switch at 6099h:01 over the whole
    travel (twice for methods 7-14 and 23-30, which may run to the limit switch, reverse and
    come back), the way back over the braking distance after the switch and, for a home
    switch, across the switch at 6099h:02, then the search for the index pulse at 6099h:02,
    at most one index spacing.
    """
    if info.current_position:
        return HomingEstimate(0.0, (), ("no motion: the current position becomes home",))
    v1, v2 = abs(switch_speed), abs(zero_speed)
    if v2 <= 0.0 or (info.edge is not None and v1 <= 0.0):
        return None
    acc = acceleration if acceleration is not None and acceleration > 0.0 else None
    phases: list[HomingPhase] = []
    notes: list[str] = []
    if acc is None:
        notes.append("the homing acceleration (609Ah) is not known here: ramps not counted")
    if info.edge is not None:
        switch = "limit switch" if info.edge.startswith("limit") else "home switch"
        searches = 2 if info.reverse_at_limit else 1
        name = f"search the {switch} at the switch-search speed"
        if searches == 2:
            name += " (to the limit switch and back)"
        t = searches * move_time(geometry.travel, v1, acc)
        phases.append(HomingPhase(name, searches * geometry.travel, v1, t, "6099h:01"))
        # After the switch the axis brakes past the edge at 609Ah and comes back to it at the
        # zero-search speed (CTMM04x 003 §4-4-7 method 1: "-EL ON: decelerate and stop, then
        # run positive at the zero-search speed"); on a home switch it may also cross the dog.
        back = v1 * v1 / (2.0 * acc) if acc is not None else 0.0
        if switch == "home switch":
            if geometry.switch_width is not None:
                back += geometry.switch_width
            else:
                notes.append("the home switch's width is not known: crossing it not counted")
        if back > 0.0:
            phases.append(
                HomingPhase(
                    "find the edge at the zero-search speed",
                    back,
                    v2,
                    move_time(back, v2, acc),
                    "6099h:02",
                )
            )
    if info.index:
        if geometry.index_spacing is not None:
            d = geometry.index_spacing
            phases.append(
                HomingPhase(
                    "search the index pulse at the zero-search speed (up to one revolution)",
                    d,
                    v2,
                    move_time(d, v2, acc),
                    "6099h:02",
                )
            )
        else:
            notes.append(
                "one motor revolution is not known here: the index search (up to one "
                "revolution at 6099h:02) is not counted"
            )
    return HomingEstimate(sum(p.seconds for p in phases), tuple(phases), tuple(notes))


def default_timeout(estimate_s: float | None) -> float:
    """The time-out a run gets when the user sets none: twice the estimate plus a margin,
    within MIN_TIMEOUT_S .. MAX_DEFAULT_TIMEOUT_S; DEFAULT_TIMEOUT_S without an estimate."""
    if estimate_s is None:
        return DEFAULT_TIMEOUT_S
    t = TIMEOUT_FACTOR * estimate_s + TIMEOUT_MARGIN_S
    return min(max(t, MIN_TIMEOUT_S), MAX_DEFAULT_TIMEOUT_S)


def speed_multiplier(table: Any, max_velocity: int | None) -> int:
    """The PMC842SR speed multiplier for 607Fh = ``max_velocity`` (CTMM04x quirk
    ``speed_multiplier``: rows ``[highest 607Fh in pps, multiplier, RANGE_DATA]``, 003 §5-3-1
    table 5-3-1-2); 1 without a table or a value."""
    if max_velocity is None or not isinstance(table, list | tuple):
        return 1
    for row in table:
        if isinstance(row, list | tuple) and len(row) >= 2 and max_velocity <= coerce_int(row[0]):
            return coerce_int(row[1])
    last = table[-1] if table else None
    return coerce_int(last[1]) if isinstance(last, list | tuple) and len(last) >= 2 else 1


def register_acceleration(fclk_hz: float, register: int, multiplier: int = 1) -> float | None:
    """A PMC842SR rate register (CTMM04x 6083h, 6084h, 609Ah) as pulses per s².

    003 §5-3-1: linear ramp register = t_ramp[ms] x (Fclk / 8000) / (FH_reg - FL_reg), with the
    speed registers FH_reg, FL_reg = speed[pps] / multiplier. The speed changes by
    (FH_reg - FL_reg) x multiplier pps in t_ramp, so the rate is multiplier x Fclk / 8 /
    register, whatever the speeds. None for a register of 0 or less.
    """
    if register <= 0 or fclk_hz <= 0:
        return None
    return multiplier * fclk_hz / 8.0 / register


#: Statusword bits 13/12/10 in homing mode (CiA 402-2 §6.8.1 table; CTMM04x 003 §4-4-3 table
#: 4-4-3-4, HIWIN 000 §3.2.4 table 3.2.4.3, LECSN-T 004 §20.6.6): what they say of the run.
_PHASES: dict[tuple[bool, bool, bool], str] = {
    (False, False, False): "in progress",
    (False, False, True): "interrupted or not started",
    (False, True, False): "attained, target not reached yet",
    (False, True, True): "attained",
    (True, False, False): "error, the axis still moves",
    (True, False, True): "error, the axis stands",
    (True, True, False): "error, the axis still moves",
    (True, True, True): "error, the axis stands",
}


def phase_from_statusword(statusword: int) -> str:
    """What statusword bits 13/12/10 say of a homing run (only meaningful in mode 6)."""
    key = (
        bool(statusword & SW_HOMING_ERROR),
        bool(statusword & SW_HOMING_ATTAINED),
        bool(statusword & SW_TARGET_REACHED),
    )
    return _PHASES[key]


def format_seconds(seconds: float) -> str:
    """A duration for a message: "42 s", "3 min 20 s", "3 h 43 min"."""
    s = max(0.0, seconds)
    if s < 100.0:
        return f"{s:.3g} s" if s < 10.0 else f"{s:.0f} s"
    r = round(s)
    m = r // 60
    if m < 60:
        return f"{m} min {r % 60} s"
    return f"{m // 60} h {m % 60} min"


#: The twin's switch layout when the profile gives no positions, in motor revolutions from the
#: power-on position (sim/homing.py ``SwitchLayout``; not from any manual).
TWIN_LIMIT_NEGATIVE_REVS = -1.7
TWIN_LIMIT_POSITIVE_REVS = 3.7
TWIN_HOME_LOW_REVS = 1.3
TWIN_HOME_HIGH_REVS = 1.7


def twin_geometry(
    sim: SimSettings, counts_per_rev: float, profile_counts_per_rev: float
) -> HomingGeometry | None:
    """The simulated twin's travel (limit switch to limit switch), home switch width and index
    spacing, in the counts of an encoder of ``counts_per_rev`` (the session's, from 608Fh);
    the profile's switch positions are counts of its own ``profile_counts_per_rev`` encoder.
    None when the twin has no switches."""
    if not sim.homing_switches:
        return None
    f = counts_per_rev / profile_counts_per_rev if profile_counts_per_rev > 0 else 1.0

    def at(value: int | None, revs: float) -> float:
        return value * f if value is not None else revs * counts_per_rev

    lo = at(sim.limit_negative, TWIN_LIMIT_NEGATIVE_REVS)
    hi = at(sim.limit_positive, TWIN_LIMIT_POSITIVE_REVS)
    width = at(sim.home_switch_high, TWIN_HOME_HIGH_REVS) - at(
        sim.home_switch_low, TWIN_HOME_LOW_REVS
    )
    return HomingGeometry(
        travel=hi - lo,
        travel_source="the simulated twin's limit switches",
        index_spacing=counts_per_rev,
        switch_width=width,
    )
