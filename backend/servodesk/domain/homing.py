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

from dataclasses import dataclass, field
from typing import Any, Literal

from servodesk.domain.datatypes import coerce_int

Signal = Literal["home_switch", "limit_negative", "limit_positive", "index"]
Edge = Literal["limit_negative", "limit_positive", "home_low", "home_high"]

#: Statusword bits of homing mode (CiA 402-2 §6.8.1, table of bits 13/12/10).
SW_TARGET_REACHED = 0x0400
SW_HOMING_ATTAINED = 0x1000
SW_HOMING_ERROR = 0x2000
#: Controlword bit 4: homing operation start (rising edge starts, 0 interrupts).
CW_HOMING_START = 0x0010


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
