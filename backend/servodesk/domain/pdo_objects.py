"""Where a PDO configuration lives in the object dictionary, and reading it from there.

The communication (1400h/1800h+) and mapping (1600h/1A00h+) objects, the EtherCAT sync manager
assignment (1C12h/1C13h) and the PROFIdrive telegram object: :func:`config_addresses` lists what
to read, :func:`parse_config` turns the values read into a :class:`PdoConfig`,
:func:`config_values` is its inverse, :func:`default_config` is the factory configuration, and
:func:`mappable` lists the objects a direction can carry. Mapping entries written as text
(``"0x607A:00"``, ``"reserved:8"``, a dummy type index) are resolved here.
"""

from __future__ import annotations

from collections.abc import Mapping

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, coerce_int
from servodesk.domain.pdo_model import (
    _DUMMY,
    COB_EXTENDED,
    COB_INVALID,
    COB_NO_RTR,
    Direction,
    MapEntry,
    Pdo,
    PdoComm,
    PdoConfig,
)
from servodesk.domain.profile import (
    DeviceProfile,
    ObjectSpec,
    PdoRules,
    PdoTelegram,
    PdoWord,
)
from servodesk.errors import ValidationError

_RPDO_COMM, _RPDO_MAP, _TPDO_COMM, _TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00
_ASSIGN = {"rx": 0x1C12, "tx": 0x1C13}  # ETG.1000.6: sync manager 2 / 3 PDO assignment.


# --------------------------------------------------------------------------------------------
# Where the configuration lives


def rules_of(profile: DeviceProfile) -> PdoRules:
    return profile.pdo


def _count(profile: DeviceProfile, d: Direction) -> int:
    r = rules_of(profile)
    return r.rpdo_count if d is Direction.RX else r.tpdo_count


def _map_index(d: Direction, number: int) -> int:
    return (_RPDO_MAP if d is Direction.RX else _TPDO_MAP) + number - 1


def _comm_index(d: Direction, number: int) -> int:
    return (_RPDO_COMM if d is Direction.RX else _TPDO_COMM) + number - 1


def _subs(profile: DeviceProfile, index: int) -> list[int]:
    """Subindices the profile defines for ``index`` (sorted)."""
    return [a.subindex for a in profile.variables if a.index == index]


def _has(profile: DeviceProfile, index: int, sub: int) -> bool:
    return profile.spec(ObjectAddress(index, sub)) is not None


def _entry_subs(profile: DeviceProfile, index: int) -> int:
    """How many mapping entries the mapping object can hold (its subs 1..n)."""
    return len([s for s in _subs(profile, index) if s > 0])


def _telegram_address(profile: DeviceProfile) -> ObjectAddress | None:
    t = rules_of(profile).telegram_object
    return ObjectAddress.parse(t) if t else None


def _directions(profile: DeviceProfile) -> list[tuple[Direction, int]]:
    return [(d, n) for d in Direction for n in range(1, _count(profile, d) + 1)]


def config_addresses(profile: DeviceProfile) -> list[ObjectAddress]:
    """Every object to read for :func:`parse_config` (objects the profile has, in order)."""
    kind = rules_of(profile).kind
    out: list[ObjectAddress] = []
    if kind == "telegram":
        t = _telegram_address(profile)
        if t is not None and profile.spec(t) is not None:
            out.append(t)
    for d, n in _directions(profile):
        if kind == "canopen":
            ci = _comm_index(d, n)
            out.extend(ObjectAddress(ci, s) for s in _subs(profile, ci) if s > 0)
        mi = _map_index(d, n)
        out.extend(ObjectAddress(mi, s) for s in _subs(profile, mi))
    if kind == "ethercat":
        for key in ("rx", "tx"):
            out.extend(ObjectAddress(_ASSIGN[key], s) for s in _subs(profile, _ASSIGN[key]))
    return out


# --------------------------------------------------------------------------------------------
# Reading


def _int(values: Mapping[ObjectAddress, int], addr: ObjectAddress, what: str) -> int:
    if addr not in values:
        raise ValidationError(
            f"{addr} ({what}) was not read",
            field=str(addr),
            hint="read every address of config_addresses(profile) first",
        )
    try:
        return coerce_int(values[addr])
    except ValidationError:
        raise ValidationError(
            f"{addr} ({what}) holds {values[addr]!r}, not a number", field=str(addr)
        ) from None


def _opt(values: Mapping[ObjectAddress, int], addr: ObjectAddress, default: int) -> int:
    return coerce_int(values[addr]) if addr in values else default


def _read_entries(
    profile: DeviceProfile, values: Mapping[ObjectAddress, int], index: int
) -> tuple[MapEntry, ...]:
    n = _int(values, ObjectAddress(index, 0), "number of mapped objects")
    room = _entry_subs(profile, index)
    if n > room:
        raise ValidationError(
            f"0x{index:04X}:00 says {n} mapped objects, but the object has {room} entries",
            field=f"0x{index:04X}:00",
            hint="the drive's mapping is inconsistent: write a valid mapping",
        )
    return tuple(
        MapEntry.from_raw(_int(values, ObjectAddress(index, k), f"mapped object {k}"))
        for k in range(1, n + 1)
    )


def _word_entry(profile: DeviceProfile, word: PdoWord, where: str) -> MapEntry:
    if word.address is None:
        # A word that is no object of the dictionary (telegram 1's STW1): padding the
        # twin fills with zeros, named by the telegram layout.
        return MapEntry.reserved(word.bits or 16)
    e = _resolve(profile, word.address, where)
    if word.bits is not None and not e.is_padding:
        e = MapEntry(e.index, e.subindex, word.bits)
    return e


def _telegram_entries(
    profile: DeviceProfile, tg: PdoTelegram, d: Direction
) -> tuple[MapEntry, ...]:
    words = tg.rx if d is Direction.RX else tg.tx
    return tuple(
        _word_entry(profile, w, f"telegram {tg.number} {d.value}[{i}]") for i, w in enumerate(words)
    )


def parse_config(profile: DeviceProfile, values: Mapping[ObjectAddress, int]) -> PdoConfig:
    """The configuration the object values describe (values as read from the drive)."""
    rules = rules_of(profile)
    kind = rules.kind
    pdos: list[Pdo] = []
    assignment: dict[Direction, tuple[int, ...]] | None = None
    telegram: int | None = None
    tg: PdoTelegram | None = None
    if kind == "telegram":
        t = _telegram_address(profile)
        spec = profile.spec(t) if t is not None else None
        if t is not None and t in values:
            telegram = coerce_int(values[t])
        elif spec is not None:
            dv = spec.default_value()
            telegram = int(dv) if isinstance(dv, int) else None
        tg = rules.telegram(telegram) if telegram is not None else None
        if tg is None:
            raise ValidationError(
                f"telegram {telegram} is not one of this drive's telegrams",
                field="telegram",
                hint="known: " + ", ".join(str(x.number) for x in rules.telegrams),
            )
    for d, n in _directions(profile):
        mi = _map_index(d, n)
        if kind == "ethercat" and not _has(profile, mi, 0):
            # An ESI lists PDOs its dictionary has no mapping object for (Elmo Gold: RxPdo
            # 1609h; Inovance IS620N: 1601h): config_addresses reads none, so there is none.
            continue
        comm: PdoComm | None = None
        ci: int | None = None
        if kind == "canopen":
            ci = _comm_index(d, n)
            raw = _int(values, ObjectAddress(ci, 1), "COB-ID")
            comm = PdoComm(
                cob_id=raw & 0x1FFFFFFF if raw & COB_EXTENDED else raw & 0x7FF,
                enabled=not raw & COB_INVALID,
                rtr_allowed=d is Direction.RX or not raw & COB_NO_RTR,
                transmission_type=_opt(values, ObjectAddress(ci, 2), 255),
                inhibit_time=_opt(values, ObjectAddress(ci, 3), 0),
                event_timer=_opt(values, ObjectAddress(ci, 5), 0),
                sync_start=_opt(values, ObjectAddress(ci, 6), 0),
            )
        if tg is not None:
            if tg.variable and ObjectAddress(mi, 0) in values:
                entries = _read_entries(profile, values, mi)
            else:
                # A real LECSN has no 1600h/1A00h: its mapping is the telegram's
                # (004 §20.3); fixed telegrams always have their own layout.
                entries = _telegram_entries(profile, tg, d)
        else:
            entries = _read_entries(profile, values, mi)
        pdos.append(Pdo(d, n, mi, ci, comm, entries, kind))
    if kind == "ethercat":
        assignment = {}
        for d in Direction:
            idx = _ASSIGN[d.value]
            if not _has(profile, idx, 0):
                # The dictionary has no assignment object (the Synapticon multi-device
                # sample ESI): the assignment is fixed, ETG.2000's RxPdo/TxPdo with an Sm
                # (the default template), else every PDO of the direction.
                assignment[d] = _fixed_assignment(profile, d, pdos)
                continue
            cnt = _int(values, ObjectAddress(idx, 0), "number of assigned PDOs")
            room = len([s for s in _subs(profile, idx) if s > 0])
            if cnt > room:
                raise ValidationError(
                    f"0x{idx:04X}:00 says {cnt} assigned PDOs, but the object has {room} entries",
                    field=f"0x{idx:04X}:00",
                )
            assignment[d] = tuple(
                _int(values, ObjectAddress(idx, k), "assigned PDO") for k in range(1, cnt + 1)
            )
    return PdoConfig(tuple(pdos), assignment, telegram)


def _fixed_assignment(profile: DeviceProfile, d: Direction, pdos: list[Pdo]) -> tuple[int, ...]:
    """The assignment of a profile without 1C12h / 1C13h (see :func:`parse_config`)."""
    for t in rules_of(profile).templates:
        if t.id == "esi-default" and t.assignment and d.value in t.assignment:
            return tuple(t.assignment[d.value])
    return tuple(p.mapping_index for p in pdos if p.direction is d)


def default_values(profile: DeviceProfile, node_id: int) -> dict[ObjectAddress, int]:
    """The profile's default value of every configuration object."""
    out: dict[ObjectAddress, int] = {}
    for addr in config_addresses(profile):
        spec = profile.spec(addr)
        if spec is None:
            continue
        v = spec.default_value(node_id)
        if isinstance(v, int | bool):
            out[addr] = int(v)
    return out


def default_config(profile: DeviceProfile, node_id: int) -> PdoConfig:
    """The configuration a drive of the family has from the factory."""
    return parse_config(profile, default_values(profile, node_id))


def config_values(profile: DeviceProfile, config: PdoConfig) -> dict[ObjectAddress, int]:
    """The object values that hold ``config`` (the inverse of :func:`parse_config`)."""
    kind = rules_of(profile).kind
    out: dict[ObjectAddress, int] = {}
    t = _telegram_address(profile)
    if kind == "telegram" and t is not None and config.telegram is not None:
        out[t] = config.telegram
    for p in config.pdos:
        if p.comm is not None and p.comm_index is not None:
            ci = p.comm_index
            out[ObjectAddress(ci, 1)] = p.comm.cob_raw(p.direction)
            for sub, v in _comm_fields(p.comm):
                if _has(profile, ci, sub):
                    out[ObjectAddress(ci, sub)] = v
        if kind == "telegram" and not _has(profile, p.mapping_index, 0):
            continue
        out[ObjectAddress(p.mapping_index, 0)] = len(p.entries)
        for k in range(1, _entry_subs(profile, p.mapping_index) + 1):
            out[ObjectAddress(p.mapping_index, k)] = (
                p.entries[k - 1].raw if k <= len(p.entries) else 0
            )
    if kind == "ethercat":
        for d in Direction:
            idx = _ASSIGN[d.value]
            assigned = (config.assignment or {}).get(d, ())
            out[ObjectAddress(idx, 0)] = len(assigned)
            for k in range(1, len([s for s in _subs(profile, idx) if s > 0]) + 1):
                out[ObjectAddress(idx, k)] = assigned[k - 1] if k <= len(assigned) else 0
    return out


def _comm_fields(c: PdoComm) -> list[tuple[int, int]]:
    return [(2, c.transmission_type), (3, c.inhibit_time), (5, c.event_timer), (6, c.sync_start)]


# --------------------------------------------------------------------------------------------
# Mappable objects and entries


def mappable(profile: DeviceProfile, direction: Direction | str) -> list[ObjectSpec]:
    """Objects that can be mapped in ``direction``, in address order."""
    d = Direction(direction)
    return [
        s
        for s in profile.variables.values()
        if s.bits > 0 and (s.pdo_mapping.rx if d is Direction.RX else s.pdo_mapping.tx)
    ]


def _resolve(profile: DeviceProfile, text: str, where: str) -> MapEntry:
    """An entry from ``"0x607A:00"`` (length from the profile), ``"reserved:8"`` or a dummy
    data type index ``"0x0005"``."""
    t = text.strip()
    if t.lower().startswith("reserved"):
        _, _, n = t.partition(":")
        try:
            bits = int(n or "0", 10)
        except ValueError:
            raise ValidationError(
                f"{where}: {text!r} is not a Reserved entry",
                field=where,
                hint="write reserved:0, reserved:8 or reserved:16",
            ) from None
        return MapEntry.reserved(bits)
    try:
        addr = ObjectAddress.parse(t)
    except ValidationError as exc:
        raise ValidationError(f"{where}: {exc.message}", field=where, hint=exc.hint) from None
    if addr.index == 0:
        return MapEntry.reserved(addr.subindex)
    if addr.index in _DUMMY:
        return MapEntry(addr.index, 0, DataType(addr.index).bits)
    spec = profile.spec(addr)
    if spec is None:
        raise ValidationError(
            f"{where}: {addr} is not an object of {profile.name}",
            field=where,
            hint="choose one of the mappable objects (GET /pdo/mappable)",
        )
    return MapEntry(addr.index, addr.subindex, spec.bits)
