"""Restore planning (docs/backup.md "Restore"): the preflight that checks a parameter set
against a drive before anything is written (identity, profile, state, every value's type and
range, writability now), and the order of the writes the profile and CiA 301 require (PDO
procedures, factor group and limits first).

Pure functions over :mod:`servodesk.domain.paramset`'s sets and the facts a service read from
the drive (:class:`DriveFacts`): nothing here touches a bus, a file or a database."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import codec
from servodesk.domain.encoder_units import INCREMENT_UNITS
from servodesk.domain.paramset import (
    Entry,
    ParameterSet,
    Unreadable,
    command_addresses,
    quirk_addresses,
    unreadable_dicts,
)
from servodesk.domain.paramset_compare import MapRow, map_by_name
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.domain.values import check_value
from servodesk.errors import ValidationError

#: CiA 301 §7.5.2.35-38: PDO communication (RPDO 1400h-15FFh, TPDO 1800h-19FFh) and mapping
#: (RPDO 1600h-17FFh, TPDO 1A00h-1BFFh) parameters; the mapping is at comm index + 200h.
_COMM_RANGES = ((0x1400, 0x15FF), (0x1800, 0x19FF))
_MAP_RANGES = ((0x1600, 0x17FF), (0x1A00, 0x1BFF))
#: ETG.1000.6 (CoE): sync manager PDO assignment 1C10h-1C2Fh, a count-first array like a
#: mapping (HIWIN 000 §3.1.2 re-mapping sequence: assignment off, mapping, assignment on).
_ASSIGN_RANGE = (0x1C10, 0x1C2F)
_COB_INVALID = 0x80000000

#: CiA 402-2 objects that scale or bound other objects (factor group 6089h-6097h, limits):
#: written before the objects that depend on them, so the drive checks new values against
#: the new limits (smartris 001 §11-1 shows the failure otherwise: aborts 0609 0031h).
_MASTERS = frozenset(
    {
        *range(0x6089, 0x6098),
        0x607B,  # position range limit
        0x607D,  # software position limit
        0x607E,  # polarity
        0x607F,  # max profile velocity
        0x6080,  # max motor speed
        0x6072,  # max torque
        0x6073,  # max current
        0x6075,  # motor rated current
        0x6076,  # motor rated torque
        0x60C5,  # max acceleration
        0x60C6,  # max deceleration
    }
)

#: CiA 402 states in which a restore is refused: the drive is enabled (power on the motor).
_ENABLED_STATES = frozenset({"operation_enabled", "quick_stop_active", "fault_reaction_active"})
_NMT_ALIASES = {
    "preop": "preop",
    "pre_operational": "preop",
    "preoperational": "preop",
    "op": "operational",
    "operational": "operational",
    "stopped": "stopped",
    "safeop": "safeop",
    "init": "initialising",
    "initialising": "initialising",
}


# ------------------------------------------------------------------------------ preflight


@dataclass(frozen=True, slots=True)
class RestoreProblem:
    address: ObjectAddress | None
    name: str | None
    message: str
    hint: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "address": str(self.address) if self.address else None,
            "name": self.name,
            "message": self.message,
            "hint": self.hint,
        }


@dataclass(frozen=True, slots=True)
class PlanItem:
    """One entry of a restore: where it goes, what it does and why."""

    address: ObjectAddress  # in the drive's profile (after mapping)
    source: ObjectAddress  # in the backup
    name: str
    #: would_write, unchanged, skipped_read_only, failed (unmapped)
    status: str
    new_raw: bytes | None
    old_raw: bytes | None
    message: str | None = None


@dataclass(frozen=True)
class Preflight:
    ok: bool
    problems: list[RestoreProblem]
    warnings: list[str]
    items: list[PlanItem]
    mapping: list[MapRow] | None
    #: What the backup lacks (unreadable when it was taken): a restore cannot set these.
    unreadable: tuple[Unreadable, ...] = ()

    def counts(self) -> dict[str, int]:
        out = {"to_write": 0, "unchanged": 0, "read_only_skipped": 0, "unmapped": 0}
        for it in self.items:
            if it.status == "would_write":
                out["to_write"] += 1
            elif it.status == "unchanged":
                out["unchanged"] += 1
            elif it.status == "skipped_read_only":
                out["read_only_skipped"] += 1
            else:
                out["unmapped"] += 1
        return out

    def to_dict(self) -> dict[str, Any]:
        c = self.counts()
        return {
            "ok": self.ok,
            "problems": [p.to_dict() for p in self.problems],
            "warnings": self.warnings,
            "to_write": c["to_write"],
            "unchanged": c["unchanged"],
            "read_only_skipped": c["read_only_skipped"],
            "mapping": [m.to_dict() for m in self.mapping] if self.mapping is not None else None,
            "unreadable": unreadable_dicts(self.unreadable),
        }


@dataclass(frozen=True, slots=True)
class DriveFacts:
    """What preflight needs to know about the drive, read just before."""

    profile: DeviceProfile
    identity: Mapping[str, Any]
    firmware: str | None
    #: CiA 402 state id (``operation_enabled``) or None when the drive has no statusword.
    state: str | None
    #: NMT / ESM state: preop, operational, stopped, unknown.
    nmt: str
    #: Current raw values of the objects the set touches (None: could not be read).
    current: Mapping[ObjectAddress, bytes | None]
    #: The drive's encoder (608Fh, else the profile's) and the one the profile's scales are
    #: for [counts/rev]; None: not known (no check).
    counts_per_rev: float | None = None
    profile_counts_per_rev: float | None = None


def state_allows(allowed: Iterable[str], state: str | None, nmt: str) -> bool | None:
    """Whether ``writable_in`` allows a write now; None when the state is not known."""
    names = [_NMT_ALIASES.get(n.lower(), n.lower()) for n in allowed]
    if not names:
        return True
    here: set[str] = {_NMT_ALIASES.get(nmt.lower(), nmt.lower())}
    if state:
        here.add(state)
        if state not in _ENABLED_STATES:
            here.update(("disabled", "servo_off"))
    if any(n in here for n in names):
        return True
    nmt_names = set(_NMT_ALIASES.values())
    if nmt.lower() in ("unknown", "") and any(n in nmt_names for n in names):
        return None
    if state is None and any(n not in nmt_names for n in names):
        return None
    return False


def preflight(ps: ParameterSet, drive: DriveFacts, *, map_names: bool = False) -> Preflight:
    """Check a set against a drive before any write; list every problem at once."""
    profile = drive.profile
    problems: list[RestoreProblem] = []
    warnings: list[str] = []
    mapping: list[MapRow] | None = None
    entries: list[tuple[Entry, ObjectAddress | None, str | None]]
    if ps.profile_id != profile.id:
        if not map_names:
            problems.append(
                RestoreProblem(
                    None,
                    None,
                    f"the backup is of profile {ps.profile_id!r}, the drive is {profile.id!r} "
                    f"({profile.name}): another drive family",
                    "restore it by object name (map_by_name / --map-by-name) after checking "
                    "what maps in the preflight",
                )
            )
            entries = [(e, e.address, None) for e in ps.entries]
        else:
            mapping = map_by_name(ps.entries, profile)
            entries = [(e, m.target, m.reason) for e, m in zip(ps.entries, mapping, strict=True)]
    else:
        entries = [(e, e.address, None) for e in ps.entries]
        _identity_checks(ps, drive, problems, warnings, map_names)
    if ps.profile_id == profile.id:
        warnings.extend(_encoder_warning(ps, drive))
    if ps.firmware and drive.firmware and ps.firmware != drive.firmware:
        warnings.append(
            f"firmware differs: backup {ps.firmware}, drive {drive.firmware}; "
            "values are checked against the drive's profile"
        )
    if drive.state in _ENABLED_STATES:
        problems.append(
            RestoreProblem(
                None,
                None,
                f"the drive is in {drive.state.replace('_', ' ')}; a restore needs the "
                "drive not enabled",
                "disable the drive (servo off) and run the restore again",
            )
        )
    commands = command_addresses(profile)
    items: list[PlanItem] = []
    for e, target, reason in entries:
        if target is None:
            items.append(
                PlanItem(
                    e.address, e.address, e.name, "failed", e.raw, None, f"not mapped: {reason}"
                )
            )
            continue
        spec = profile.spec(target)
        old = drive.current.get(target)
        if spec is None:
            problems.append(
                RestoreProblem(
                    target,
                    e.name,
                    f"{target} {e.name} is not an object of profile {profile.id}",
                    "the backup does not fit this drive; choose a backup of this family",
                )
            )
            continue
        base = PlanItem(target, e.address, spec.name, "would_write", e.raw, old)
        if target in commands:
            items.append(
                replace(
                    base, status="skipped_read_only", message="a command object, not a parameter"
                )
            )
            continue
        if not spec.access.writable:
            items.append(
                replace(
                    base, status="skipped_read_only", message=f"{spec.access.value} in the profile"
                )
            )
            continue
        problem = _value_problem(e, spec)
        if problem is not None:
            problems.append(problem)
            continue
        if old is not None and old == e.raw:
            items.append(replace(base, status="unchanged"))
            continue
        allowed = state_allows(spec.writable_in, drive.state, drive.nmt)
        if allowed is False:
            where = ", ".join(x for x in (drive.state, drive.nmt) if x)
            problems.append(
                RestoreProblem(
                    target,
                    spec.name,
                    f"{target} {spec.name} is writable only in {', '.join(spec.writable_in)}; "
                    f"the drive is in {where}",
                    "bring the drive into that state (NMT pre-operational / servo off) first",
                )
            )
            continue
        if allowed is None:
            warnings.append(
                f"{target} {spec.name}: writable only in {', '.join(spec.writable_in)}; the "
                "drive's state is not known, the drive decides"
            )
        items.append(base)
    if ps.unreadable:
        warnings.append(incomplete_warning(ps.unreadable))
    return Preflight(not problems, problems, warnings, items, mapping, ps.unreadable)


def incomplete_warning(unreadable: Sequence[Unreadable]) -> str:
    """What restoring a set with unreadable objects cannot do, in one sentence."""
    n = len(unreadable)
    shown = ", ".join(f"{u.address} {u.name}".strip() for u in unreadable[:5])
    more = f" and {n - 5} more" if n > 5 else ""
    return (
        f"the backup is incomplete: {n} object{'s' if n != 1 else ''} could not be read when it "
        f"was taken ({shown}{more}); a restore cannot set {'them' if n != 1 else 'it'}, the "
        "drive keeps its present values there"
    )


def _encoder_warning(ps: ParameterSet, drive: DriveFacts) -> list[str]:
    """A set read on another encoder than the drive's: its raw counts mean other angles and
    speeds here (a set without ``counts_per_rev`` was read on the profile's encoder)."""
    here, base = drive.counts_per_rev, drive.profile_counts_per_rev
    backup = ps.counts_per_rev or base
    if here is None or backup is None or math.isclose(backup, here, rel_tol=1e-9):
        return []
    counted = sum(
        1
        for e in ps.entries
        if (spec := drive.profile.spec(e.address)) is not None and spec.raw_unit in INCREMENT_UNITS
    )

    def n(x: float) -> str:
        return f"{x:.0f}" if x == round(x) else f"{x:.6g}"

    return [
        f"the backup was read on an encoder of {n(backup)} counts/rev, this drive has {n(here)} "
        f"(608Fh): its {counted} values counted in increments (positions, speeds, windows) are "
        f"written as raw counts and mean {backup / here:.3g} x those angles and speeds here"
    ]


def _identity_checks(
    ps: ParameterSet,
    drive: DriveFacts,
    problems: list[RestoreProblem],
    warnings: list[str],
    map_names: bool,
) -> None:
    bi, di = ps.identity, drive.identity
    for key, label in (("vendor_id", "vendor id"), ("product_code", "product code")):
        a, b = bi.get(key), di.get(key)
        if a is not None and b is not None and a != b:
            problems.append(
                RestoreProblem(
                    None,
                    None,
                    f"{label} differs: backup 0x{int(a):08X}, drive 0x{int(b):08X} "
                    "(another product with the same profile)",
                    "choose a backup of this product",
                )
            )
    a, b = bi.get("serial"), di.get("serial")
    if a is not None and b is not None and a != b:
        warnings.append(
            f"another drive of the same family: backup serial {a}, drive serial {b} "
            "(a replacement drive)"
        )
    if ps.profile_version and ps.profile_version != drive.profile.version:
        warnings.append(
            f"profile version differs: backup {ps.profile_version}, now {drive.profile.version}"
        )


def _value_problem(e: Entry, spec: ObjectSpec) -> RestoreProblem | None:
    if spec.data_type != e.data_type:
        return RestoreProblem(
            spec.address,
            spec.name,
            f"{spec.address} {spec.name} is {spec.data_type.name}, the backup holds "
            f"{e.data_type.name}",
            "the backup does not fit this drive's profile",
        )
    n = spec.bits // 8
    if n and len(e.raw) != n:
        return RestoreProblem(
            spec.address,
            spec.name,
            f"{spec.address} {spec.name}: {len(e.raw)} bytes for a {n}-byte {spec.data_type.name}",
        )
    if not spec.data_type.is_numeric:
        return None
    try:
        v = codec(spec.data_type).decode(e.raw)
        check_value(spec, v)
    except ValidationError as exc:
        return RestoreProblem(spec.address, spec.name, exc.message, exc.hint)
    return None


# ------------------------------------------------------------------------------ planning


@dataclass(frozen=True, slots=True)
class RestoreStep:
    """One write of a restore. ``entry`` is the item this write sets to its final value;
    None for the intermediate writes of a procedure (PDO disable, mapping count 0)."""

    address: ObjectAddress
    raw: bytes
    entry: ObjectAddress | None
    why: str = ""
    #: Steps of one procedure share a group: after a failure the rest of the group is
    #: not attempted (a half-written PDO mapping must not be validated).
    group: str = ""


def _in(index: int, ranges: Iterable[tuple[int, int]]) -> bool:
    return any(lo <= index <= hi for lo, hi in ranges)


def is_pdo_object(index: int) -> bool:
    """PDO communication, mapping (CiA 301) or assignment (CoE) object."""
    return _in(index, (*_COMM_RANGES, *_MAP_RANGES, _ASSIGN_RANGE))


def write_order(profile: DeviceProfile, addresses: Iterable[ObjectAddress]) -> list[ObjectAddress]:
    """The order plain parameters are written in.

    First the profile's ``unit_change_sequence`` (in its order), then the CiA 402 factor and
    limit objects the others depend on, then everything else by address.
    """
    seq = quirk_addresses(profile, "unit_change_sequence")
    rank = {a: i for i, a in enumerate(seq)}

    def key(a: ObjectAddress) -> tuple[int, int, ObjectAddress]:
        if a in rank:
            return (0, rank[a], a)
        if a.index in _MASTERS:
            return (1, 0, a)
        return (2, 0, a)

    return sorted(addresses, key=key)


def _u32(raw: bytes | None) -> int | None:
    return int.from_bytes(raw[:4], "little") if raw is not None and len(raw) >= 4 else None


def plan_writes(
    profile: DeviceProfile,
    to_write: Mapping[ObjectAddress, bytes],
    targets: Mapping[ObjectAddress, bytes],
    current: Mapping[ObjectAddress, bytes | None],
) -> list[RestoreStep]:
    """The ordered writes that take the drive from ``current`` to ``targets``.

    ``to_write``: the entries that differ (address -> bytes); ``targets``: every entry of
    the set (also the unchanged ones, needed to put a PDO back as it was).

    Plain parameters come first (:func:`write_order`). Then the PDOs by the CiA 301
    §7.5.2.35-38 procedure, one group per PDO: COB-ID bit 31 set (PDO invalid), the other
    communication parameters, mapping sub 0 = 0, the entries, sub 0 = n, and the COB-ID as
    in the set. CoE sync-manager assignments (1C10h-1C2Fh) are switched off before the
    mappings change and set after them (HIWIN 000 §3.1.2).
    """
    plain = [a for a in to_write if not is_pdo_object(a.index)]
    steps = [
        RestoreStep(a, to_write[a], a, "parameter", str(a)) for a in write_order(profile, plain)
    ]

    pdo = [a for a in to_write if is_pdo_object(a.index)]
    if not pdo:
        return steps
    groups: dict[int, list[ObjectAddress]] = {}
    assigns: dict[int, list[ObjectAddress]] = {}
    for a in pdo:
        if _in(a.index, (_ASSIGN_RANGE,)):
            assigns.setdefault(a.index, []).append(a)
        else:
            comm = a.index - 0x200 if _in(a.index, _MAP_RANGES) else a.index
            groups.setdefault(comm, []).append(a)
    mapping_changes = any(_in(a.index, _MAP_RANGES) for a in pdo)
    assign_objs = sorted(
        {a.index for a in targets if _in(a.index, (_ASSIGN_RANGE,))} if mapping_changes else set()
    )
    assign_objs = sorted(set(assign_objs) | set(assigns))
    for idx in assign_objs:
        count = ObjectAddress(idx, 0)
        if _u32(_pad(current.get(count))) != 0 and count in targets:
            steps.append(
                RestoreStep(
                    count, bytes(len(targets[count])), None, "assignment off", f"assign {idx:04X}"
                )
            )
    for comm in sorted(groups):
        steps.extend(_pdo_group(comm, groups[comm], to_write, targets, current))
    for idx in assign_objs:
        gname = f"assign {idx:04X}"
        count = ObjectAddress(idx, 0)
        for a in sorted(assigns.get(idx, [])):
            if a.subindex:
                steps.append(RestoreStep(a, to_write[a], a, "assignment entry", gname))
        if count in targets:
            steps.append(
                RestoreStep(
                    count,
                    targets[count],
                    count if count in to_write else None,
                    "assignment on",
                    gname,
                )
            )
    return steps


def _pad(raw: bytes | None) -> bytes | None:
    return raw + bytes(4 - len(raw)) if raw is not None and len(raw) < 4 else raw


def _pdo_group(
    comm: int,
    changed: list[ObjectAddress],
    to_write: Mapping[ObjectAddress, bytes],
    targets: Mapping[ObjectAddress, bytes],
    current: Mapping[ObjectAddress, bytes | None],
) -> list[RestoreStep]:
    gname = f"PDO {comm:04X}"
    mapping = comm + 0x200
    cob = ObjectAddress(comm, 1)
    steps: list[RestoreStep] = []
    cur_cob = _u32(current.get(cob))
    disabled = False
    has_comm = _in(comm, _COMM_RANGES) and cob in targets
    if has_comm and cur_cob is not None:
        if not cur_cob & _COB_INVALID:
            steps.append(
                RestoreStep(
                    cob,
                    (cur_cob | _COB_INVALID).to_bytes(4, "little"),
                    None,
                    "PDO invalid (COB-ID bit 31) before changing it",
                    gname,
                )
            )
        disabled = True
    for a in sorted(x for x in changed if x.index == comm and x.subindex != 1):
        steps.append(RestoreStep(a, to_write[a], a, "PDO communication parameter", gname))
    entries = sorted(x for x in changed if x.index == mapping and x.subindex != 0)
    count = ObjectAddress(mapping, 0)
    if entries or count in to_write:
        cur_n = current.get(count)
        if cur_n is None or any(cur_n):
            size = len(targets[count]) if count in targets else 1
            steps.append(RestoreStep(count, bytes(size), None, "mapping sub 0 = 0", gname))
        for a in entries:
            steps.append(RestoreStep(a, to_write[a], a, "mapping entry", gname))
        final_n = targets.get(count, cur_n)
        if final_n is not None:
            steps.append(
                RestoreStep(
                    count, final_n, count if count in to_write else None, "mapping sub 0 = n", gname
                )
            )
    if has_comm and (disabled or cob in to_write):
        final = targets[cob]
        steps.append(
            RestoreStep(cob, final, cob if cob in to_write else None, "COB-ID as in the set", gname)
        )
    return steps
