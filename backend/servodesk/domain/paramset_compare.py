"""Comparing parameter sets: what differs between two backups or a backup and a drive
(docs/backup.md "Compare"), and mapping a backup's entries onto another family's objects by
name (a restore across families).

Pure functions over :mod:`servodesk.domain.paramset`'s entries, like it."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.paramset import Entry
from servodesk.domain.profile import DeviceProfile, ObjectSpec

# ------------------------------------------------------------------------------- compare


@dataclass(frozen=True, slots=True)
class Difference:
    address: ObjectAddress
    name: str
    group: str | None
    unit: str | None
    raw_unit: str | None
    a: Entry | None
    b: Entry | None
    kind: str  # "changed" | "only_a" | "only_b" | "same"

    def to_dict(self, scale: float | None) -> dict[str, Any]:
        def eng(e: Entry | None) -> float | None:
            v = e.value if e is not None else None
            if scale is None or self.unit is None or isinstance(v, bool):
                return None
            return float(v) * scale if isinstance(v, int | float) else None

        return {
            "address": str(self.address),
            "name": self.name,
            "group": self.group,
            "unit": self.unit,
            "raw_unit": self.raw_unit,
            "a_value": self.a.value if self.a else None,
            "b_value": self.b.value if self.b else None,
            "a_raw_hex": self.a.raw.hex() if self.a else None,
            "b_raw_hex": self.b.raw.hex() if self.b else None,
            "a_engineering": eng(self.a),
            "b_engineering": eng(self.b),
            "kind": self.kind,
        }


def compare(
    a: Sequence[Entry],
    b: Sequence[Entry],
    profile: DeviceProfile | None = None,
    *,
    include_same: bool = False,
) -> tuple[list[dict[str, Any]], int]:
    """What differs between two sets, by address and raw bytes; (differences, same count).

    Differences come grouped: in the profile's group order, then by address.
    """
    da = {e.address: e for e in a}
    db = {e.address: e for e in b}
    group_rank = {g.id: i for i, g in enumerate(profile.groups)} if profile else {}
    rows: list[tuple[tuple[int, ObjectAddress], dict[str, Any]]] = []
    same = 0
    for address in sorted(set(da) | set(db)):
        ea, eb = da.get(address), db.get(address)
        if ea is not None and eb is not None and ea.raw == eb.raw:
            same += 1
            if not include_same:
                continue
            kind = "same"
        else:
            kind = "changed" if ea and eb else ("only_a" if ea else "only_b")
        spec = profile.spec(address) if profile else None
        any_e = ea or eb
        assert any_e is not None
        group = spec.group if spec else None
        d = Difference(
            address=address,
            name=spec.name if spec else any_e.name,
            group=group,
            unit=spec.unit if spec else any_e.unit,
            raw_unit=spec.raw_unit if spec else None,
            a=ea,
            b=eb,
            kind=kind,
        )
        rank = group_rank.get(group or "", len(group_rank))
        rows.append(((rank, address), d.to_dict(spec.scale if spec else None)))
    rows.sort(key=lambda r: r[0])
    return [r[1] for r in rows], same


# ------------------------------------------------------------------------- name mapping


def _norm(name: str) -> str:
    return re.sub(r"[^a-z0-9]+", " ", name.lower()).strip()


@dataclass(frozen=True, slots=True)
class MapRow:
    address: ObjectAddress
    name: str
    target: ObjectAddress | None
    reason: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "address": str(self.address),
            "name": self.name,
            "target": str(self.target) if self.target else None,
            "reason": self.reason,
        }


def map_by_name(entries: Sequence[Entry], target: DeviceProfile) -> list[MapRow]:
    """Where each entry of another family's set goes in ``target``, matched by name.

    The same address with the same name wins; else the one object of that name; an
    ambiguous name is resolved by equal subindex and data type, else left unmapped. The data
    type must match (bytes of another size cannot be restored).
    """
    by_name: dict[str, list[ObjectSpec]] = {}
    for s in target.variables.values():
        by_name.setdefault(_norm(s.name), []).append(s)
    rows: list[MapRow] = []
    for e in entries:
        key = _norm(e.name)
        here = target.spec(e.address)
        chosen: ObjectSpec | None = None
        reason: str | None = None
        if here is not None and _norm(here.name) == key:
            chosen = here
        else:
            cands = by_name.get(key, [])
            if len(cands) > 1:
                cands = [
                    c
                    for c in cands
                    if c.subindex == e.address.subindex and c.data_type == e.data_type
                ]
            if len(cands) == 1:
                chosen = cands[0]
            elif cands:
                reason = f"{len(cands)} objects of {target.id} are named {e.name!r}"
            else:
                reason = f"{target.id} has no object named {e.name!r}"
        if chosen is not None and chosen.data_type != e.data_type:
            reason = (
                f"{chosen.address} {chosen.name} is {chosen.data_type.name}, "
                f"the backup holds {e.data_type.name}"
            )
            chosen = None
        rows.append(MapRow(e.address, e.name, chosen.address if chosen else None, reason))
    return rows
