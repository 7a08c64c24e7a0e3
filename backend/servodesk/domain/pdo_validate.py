"""PDO validation: every reason a configuration breaks its family's rules.

:func:`validate` checks the mapping entries against the profile (mappable direction, length,
duplicates, dummy and Reserved entries), the sizes, the CANopen communication parameters (COB-ID
ranges of CiA 301 §7.3.5, transmission types, timers), the EtherCAT assignment, a fixed mapping
and a PROFIdrive telegram's layout, and returns the :class:`PdoProblem` list the UI shows next to
the fields (docs/pdo.md).
"""

from __future__ import annotations

from collections.abc import Iterable

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.pdo_model import _DUMMY, Direction, MapEntry, Pdo, PdoConfig, PdoProblem
from servodesk.domain.pdo_objects import (
    _ASSIGN,
    _count,
    _entry_subs,
    _has,
    _map_index,
    _subs,
    _telegram_entries,
    default_config,
    rules_of,
)
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import NotFoundError

_CIA_COMM = "CiA 301 §7.5.2.35"
_CIA_MAP = "CiA 301 §7.5.2.36"
_CIA_IDS = "CiA 301 §7.3.5"


#: CAN ids a PDO must not use (CiA 301 §7.3.5 restricted ids, plus the ids of the
#: predefined connection set's broadcast services that a PDO would collide with).
_RESTRICTED: tuple[tuple[int, int, str], ...] = (
    (0x000, 0x000, "000h is NMT"),
    (0x001, 0x07F, "001h-07Fh are reserved"),
    (0x080, 0x080, "080h is SYNC"),
    (0x081, 0x0FF, "081h-0FFh are the EMCY ids of nodes 1-127"),
    (0x100, 0x100, "100h is TIME"),
    (0x101, 0x180, "101h-180h are reserved"),
    (0x580, 0x5FF, "580h-5FFh are the SDO server -> client ids"),
    (0x600, 0x67F, "600h-67Fh are the SDO client -> server ids"),
    (0x6E0, 0x6FF, "6E0h-6FFh are reserved"),
    (0x700, 0x7FF, "700h-7FFh are NMT error control (heartbeat, boot-up) and reserved"),
)


def _cob_problem(cob_id: int) -> str | None:
    if cob_id > 0x7FF:
        return (
            f"COB-ID 0x{cob_id:X} does not fit 11 bits (at most 7FFh); use an id in "
            "181h-57Fh or 680h-6DFh"
        )
    for lo, hi, why in _RESTRICTED:
        if lo <= cob_id <= hi:
            return (
                f"COB-ID 0x{cob_id:03X} is not allowed: {why}; use an id in 181h-57Fh "
                "(e.g. the default 180h/200h/280h... + node id)"
            )
    return None


def _spec_name(profile: DeviceProfile, e: MapEntry) -> str:
    spec = profile.spec(ObjectAddress(e.index, e.subindex)) if not e.is_padding else None
    return f"{e} {spec.name}" if spec is not None else str(e)


def _check_entries(
    profile: DeviceProfile, pdo: Pdo, max_entries: int, section: str | None
) -> list[PdoProblem]:
    rules = rules_of(profile)
    kind = rules.kind
    out: list[PdoProblem] = []
    name = pdo.name
    d = pdo.direction
    seen: dict[tuple[int, int], int] = {}
    for i, e in enumerate(pdo.entries):

        def bad(msg: str, sect: str | None = section, _i: int = i) -> None:
            out.append(PdoProblem(msg, pdo=name, entry=_i, field="entries", section=sect))

        if e.index == 0:
            if kind != "telegram":
                bad(
                    f"entry {i + 1} ({e.raw:#010x}) names no object; map an object, or for a "
                    "gap a dummy entry 0002h-0007h",
                    _CIA_MAP,
                )
            elif e.bits not in (0, 8, 16) or e.subindex not in (0, e.bits):
                bad(
                    f"entry {i + 1}: a Reserved entry is 0, 8 or 16 bits long with the length "
                    f"as its subindex, not subindex {e.subindex} / {e.bits} bits; write "
                    "reserved:8 or reserved:16",
                )
            continue
        if e.index in _DUMMY:
            dt = DataType(e.index)
            if kind != "canopen":
                bad(f"entry {i + 1}: dummy entries ({e}) are not used by this drive; remove it")
            elif not _has(profile, e.index, 0):
                bad(
                    f"entry {i + 1}: this drive does not support dummy mapping of {dt.name} "
                    f"(no object 0x{e.index:04X}); remove the gap",
                    _CIA_MAP,
                )
            elif e.bits != dt.bits:
                bad(
                    f"entry {i + 1}: a {dt.name} dummy is {dt.bits} bits, not {e.bits}",
                    _CIA_MAP,
                )
            continue
        addr = ObjectAddress(e.index, e.subindex)
        spec = profile.spec(addr)
        if spec is None:
            bad(
                f"entry {i + 1}: {addr} is not an object of this drive; choose one of the "
                "mappable objects",
                _CIA_MAP,
            )
            continue
        ok = spec.pdo_mapping.rx if d is Direction.RX else spec.pdo_mapping.tx
        if not ok:
            where = "RPDO/RxPDO (master -> drive)" if d is Direction.RX else "TPDO/TxPDO"
            bad(
                f"entry {i + 1}: {addr} {spec.name} cannot be mapped into a {where}; "
                + (
                    "map it in the other direction or choose another object"
                    if spec.pdo_mapping.value != "none"
                    else "it is not PDO-mappable, read or write it by SDO"
                ),
                spec.section or section,
            )
            continue
        allowed = {spec.bits}
        if spec.data_type is DataType.BOOLEAN:
            allowed.add(1)  # CiA 301 §7.4.7.1: a BOOLEAN may be mapped as one bit.
        if e.bits not in allowed:
            bad(
                f"entry {i + 1}: {addr} {spec.name} is {spec.data_type.name} ({spec.bits} "
                f"bits); the entry says {e.bits} bits. Write {spec.bits}",
                _CIA_MAP,
            )
        key = (e.index, e.subindex)
        if key in seen and not rules.allow_duplicates:
            bad(
                f"entry {i + 1}: {addr} {spec.name} is already entry {seen[key] + 1}; this "
                "drive maps an object only once, remove one of them",
            )
        seen.setdefault(key, i)
    n = len(pdo.entries)
    if n > max_entries:
        out.append(
            PdoProblem(
                f"{n} entries: {name} holds at most {max_entries}; remove {n - max_entries}",
                pdo=name,
                field="entries",
                section=section,
            )
        )
    room = _entry_subs(profile, pdo.mapping_index)
    if room and n > room and n <= max_entries:
        out.append(
            PdoProblem(
                f"{n} entries: 0x{pdo.mapping_index:04X} has only {room} entry subindices; "
                f"remove {n - room}",
                pdo=name,
                field="entries",
                section=section,
            )
        )
    return out


def validate(profile: DeviceProfile, config: PdoConfig) -> list[PdoProblem]:
    """Every reason the configuration breaks the family's rules; [] when it is valid."""
    rules = rules_of(profile)
    kind = rules.kind
    section = rules.section
    out: list[PdoProblem] = []
    if kind == "fixed":
        return _validate_fixed(profile, config)
    if kind == "telegram":
        return _validate_telegram(profile, config)
    for p in config.pdos:
        out.extend(_check_entries(profile, p, rules.max_entries, section))
        if p.bits > rules.max_bits:
            out.append(
                PdoProblem(
                    f"{p.bits} bits mapped: {p.name} carries at most {rules.max_bits} bits "
                    f"({rules.max_bits // 8} bytes); remove {p.bits - rules.max_bits} bits",
                    pdo=p.name,
                    field="entries",
                    section=section if kind != "canopen" else f"{_CIA_MAP}; {section}",
                )
            )
    if kind == "canopen":
        out.extend(_validate_comm(profile, config))
    if kind == "ethercat":
        out.extend(_validate_assignment(profile, config))
    if rules.max_bytes is not None:
        for d in Direction:
            active = config.active(d)
            total = sum(p.bits for p in active)
            nbytes = (total + 7) // 8
            if nbytes > rules.max_bytes:
                out.append(
                    PdoProblem(
                        f"{nbytes} bytes of {d.value.upper()} process data: this drive takes at "
                        f"most {rules.max_bytes} bytes per direction; remove "
                        f"{nbytes - rules.max_bytes} bytes",
                        pdo=active[0].name if len(active) == 1 else None,
                        field="entries",
                        section=section,
                    )
                )
    if not rules.allow_duplicates:
        for d in Direction:
            active = config.active(d)
            if len(active) < 2:
                continue
            seen: dict[tuple[int, int], str] = {}
            for p in active:
                for i, e in enumerate(p.entries):
                    if e.is_padding:
                        continue
                    key = (e.index, e.subindex)
                    if key in seen and seen[key] != p.name:
                        out.append(
                            PdoProblem(
                                f"{e} is already mapped in {seen[key]}; this drive maps an "
                                "object only once per direction, remove one",
                                pdo=p.name,
                                entry=i,
                                field="entries",
                                section=section,
                            )
                        )
                    seen.setdefault(key, p.name)
    return out


def _validate_comm(profile: DeviceProfile, config: PdoConfig) -> list[PdoProblem]:
    rules = rules_of(profile)
    out: list[PdoProblem] = []
    ids: dict[int, str] = {}
    for p in config.pdos:
        c, ci = p.comm, p.comm_index
        if c is None or ci is None:
            continue
        name = p.name
        d = p.direction.value
        fam = rules.section

        def bad(msg: str, fld: str, sect: str | None, _name: str = name) -> None:
            out.append(PdoProblem(msg, pdo=_name, field=fld, section=sect))

        if c.cob_id > 0x7FF or c.enabled:
            why = _cob_problem(c.cob_id)
            if why:
                bad(why, "cob_id", _CIA_IDS)
        if c.enabled:
            if c.cob_id in ids:
                bad(
                    f"COB-ID 0x{c.cob_id:03X} is also used by {ids[c.cob_id]}; two PDOs on one "
                    "id collide on the bus, give each its own id or disable one",
                    "cob_id",
                    _CIA_COMM,
                )
            else:
                ids[c.cob_id] = name
        tt = c.transmission_type
        allowed = rules.transmission_types(d)
        if tt not in allowed:
            bad(
                f"transmission type {tt} is not allowed for {name}; "
                + _types_hint(allowed, p.direction),
                "transmission_type",
                f"{_CIA_COMM}; {fam}" if fam else _CIA_COMM,
            )
        if c.event_timer:
            if not _has(profile, ci, 5):
                bad(
                    f"{name} has no event timer (0x{ci:04X}:05); set it to 0",
                    "event_timer",
                    fam,
                )
            elif tt not in rules.timer_types(d):
                bad(
                    f"the event timer ({c.event_timer} ms) applies only to transmission types "
                    f"{_ranges_text(rules.timer_types(d))}, not {tt}; set it to 0 or make "
                    f"{name} event-driven (254/255)",
                    "event_timer",
                    f"{_CIA_COMM}; {fam}" if fam else _CIA_COMM,
                )
        if c.inhibit_time and not _has(profile, ci, 3):
            bad(f"{name} has no inhibit time (0x{ci:04X}:03); set it to 0", "inhibit_time", fam)
        if c.sync_start:
            if not _has(profile, ci, 6):
                bad(
                    f"{name} has no SYNC start value (0x{ci:04X}:06); set it to 0",
                    "sync_start",
                    fam,
                )
            elif not 1 <= tt <= 240:
                bad(
                    f"the SYNC start value applies only to cyclic synchronous types 1-240, "
                    f"not {tt}; set it to 0",
                    "sync_start",
                    _CIA_COMM,
                )
        if not c.rtr_allowed:
            if p.direction is Direction.RX:
                bad(
                    "COB-ID bit 30 (no RTR) is reserved for RPDOs; allow RTR",
                    "rtr_allowed",
                    _CIA_COMM,
                )
            elif tt in (252, 253):
                bad(
                    f"transmission type {tt} sends {name} only on a remote request, but RTR is "
                    "not allowed (COB-ID bit 30); allow RTR or choose another type",
                    "rtr_allowed",
                    _CIA_COMM,
                )
    return out


def _ranges_text(values: Iterable[int]) -> str:
    vs = sorted(values)
    parts: list[str] = []
    start = prev = None
    for v in vs:
        if start is None:
            start = prev = v
        elif prev is not None and v == prev + 1:
            prev = v
        else:
            parts.append(f"{start}" if start == prev else f"{start}-{prev}")
            start = prev = v
    if start is not None:
        parts.append(f"{start}" if start == prev else f"{start}-{prev}")
    return ", ".join(parts)


def _types_hint(allowed: frozenset[int], d: Direction) -> str:
    text = _ranges_text(allowed)
    if d is Direction.RX:
        return f"RPDOs take {text} (0-240: applied at the next SYNC, 254/255: at once)"
    return (
        f"TPDOs take {text} (0: acyclic synchronous, 1-240: every n-th SYNC, "
        "252/253: on RTR, 254/255: event-driven)"
    )


def _validate_assignment(profile: DeviceProfile, config: PdoConfig) -> list[PdoProblem]:
    rules = rules_of(profile)
    out: list[PdoProblem] = []
    for d in Direction:
        idx = _ASSIGN[d.value]
        assigned = (config.assignment or {}).get(d, ())
        room = len([s for s in _subs(profile, idx) if s > 0])
        maps = {p.mapping_index for p in config.of(d)}
        if len(assigned) > room:
            out.append(
                PdoProblem(
                    f"{len(assigned)} mapping objects assigned to 0x{idx:04X}: this drive takes "
                    f"{room} per sync manager; assign one",
                    field="assignment",
                    section=rules.section,
                )
            )
        for k, a in enumerate(assigned):
            if a not in maps:
                lo = _map_index(d, 1)
                out.append(
                    PdoProblem(
                        f"0x{a:04X} is not a {d.value.upper()} mapping object; assign one of "
                        f"0x{lo:04X}-0x{lo + _count(profile, d) - 1:04X}",
                        field="assignment",
                        section=rules.section,
                    )
                )
            elif a in assigned[:k]:
                out.append(
                    PdoProblem(
                        f"0x{a:04X} is assigned twice to 0x{idx:04X}; assign it once",
                        field="assignment",
                        section=rules.section,
                    )
                )
    return out


def _validate_fixed(profile: DeviceProfile, config: PdoConfig) -> list[PdoProblem]:
    base = default_config(profile, 1)
    out: list[PdoProblem] = []
    for p in config.pdos:
        try:
            ref = base.pdo(p.direction, p.number)
        except NotFoundError:
            out.append(PdoProblem(f"{p.name} does not exist on this drive", pdo=p.name))
            continue
        if p.entries != ref.entries:
            out.append(_fixed_problem(profile, p.name))
    return out


def _fixed_problem(profile: DeviceProfile, name: str | None) -> PdoProblem:
    sect = rules_of(profile).section
    return PdoProblem(
        f"the PDO mapping of {profile.name} is pre-assigned and cannot be changed ({sect}); "
        "keep the fixed mapping and use the objects it carries",
        pdo=name,
        field="entries",
        section=sect,
    )


def _validate_telegram(profile: DeviceProfile, config: PdoConfig) -> list[PdoProblem]:
    rules = rules_of(profile)
    tg = rules.telegram(config.telegram) if config.telegram is not None else None
    if tg is None:
        known = ", ".join(str(t.number) for t in rules.telegrams)
        return [
            PdoProblem(
                f"telegram {config.telegram} is not supported; choose one of {known}",
                field="telegram",
                section=rules.section,
            )
        ]
    sect = tg.section or rules.section
    out: list[PdoProblem] = []
    for p in config.pdos:
        if not tg.variable:
            if p.entries != _telegram_entries(profile, tg, p.direction):
                out.append(
                    PdoProblem(
                        f"telegram {tg.number} has a fixed layout; choose telegram "
                        + " or ".join(str(t.number) for t in rules.telegrams if t.variable)
                        + " to map other objects",
                        pdo=p.name,
                        field="entries",
                        section=sect,
                    )
                )
            continue
        out.extend(_check_entries(profile, p, tg.max_entries, sect))
        want = tg.bytes * 8
        if p.bits != want:
            diff = (want - p.bits) // 8 if p.bits < want else (p.bits - want + 7) // 8
            todo = (
                f"add Reserved entries (8 or 16 bits) for {diff} bytes"
                if p.bits < want
                else f"remove {diff} bytes"
            )
            out.append(
                PdoProblem(
                    f"{p.name}: the mapping totals {p.bits / 8:g} bytes, telegram {tg.number} "
                    f"needs exactly {tg.bytes}; {todo}",
                    pdo=p.name,
                    field="entries",
                    section=sect,
                )
            )
    return out
