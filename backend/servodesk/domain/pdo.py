"""PDO mapping as pure data: read, validate, plan, lay out, pack and export process data.

The contract is docs/pdo.md. Four families map process data differently (``profile.pdo.kind``):

- ``canopen``: RPDO/TPDO communication (1400h/1800h+) and mapping (1600h/1A00h+) objects,
  remapped by the procedure of CiA 301 §7.5.2.35/36 in NMT pre-operational.
- ``ethercat``: mapping objects 1600h+/1A00h+ assigned to the sync managers by 1C12h/1C13h
  (ETG.1000.6; HIWIN 000 §3.1.2 gives the order of the writes).
- ``fixed``: a pre-assigned mapping that is shown and exported, never written.
- ``telegram``: a PROFIdrive telegram chosen by P922; telegrams with variable mapping are
  re-mapped on the twin through 1600h/1A00h (LECSN 004 §20.3).

Nothing here does I/O: the session service reads :func:`config_addresses`, hands the values to
:func:`parse_config`, and executes the :class:`Plan` that :func:`plan` returns.
"""

from __future__ import annotations

import csv
import enum
import io
import json
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, codec, coerce_int
from servodesk.domain.profile import (
    DeviceProfile,
    ObjectSpec,
    PdoRules,
    PdoTelegram,
    PdoTemplate,
    PdoWord,
    resolve_value,
)
from servodesk.errors import NotFoundError, PdoRefused, ServodeskError, ValidationError

#: The templates of a profile are its :class:`~servodesk.domain.profile.PdoTemplate` entries.
Template = PdoTemplate

COB_INVALID = 0x80000000  # CiA 301 §7.5.2.35: bit 31 = 1, the PDO does not exist.
COB_NO_RTR = 0x40000000  # bit 30 = 1: no RTR allowed on this TPDO.
COB_EXTENDED = 0x20000000  # bit 29 = 1: 29-bit CAN id.

_RPDO_COMM, _RPDO_MAP, _TPDO_COMM, _TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00
_ASSIGN = {"rx": 0x1C12, "tx": 0x1C13}  # ETG.1000.6: sync manager 2 / 3 PDO assignment.
#: CAN FD data lengths (ISO 11898-1): a PDO is padded to the next one.
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
#: CiA 301 §7.4.7.1: dummy mapping uses the data type indexes 0002h..0007h.
_DUMMY = range(0x0002, 0x0008)
_CIA_COMM = "CiA 301 §7.5.2.35"
_CIA_MAP = "CiA 301 §7.5.2.36"
_CIA_IDS = "CiA 301 §7.3.5"


class Direction(enum.StrEnum):
    """rx: master -> drive (RPDO, RxPDO, setpoint telegram); tx: drive -> master."""

    RX = "rx"
    TX = "tx"


# --------------------------------------------------------------------------------------------
# Data


@dataclass(frozen=True)
class MapEntry:
    """One CiA 301 mapping entry: object index, subindex and length in bits."""

    index: int
    subindex: int
    bits: int

    @property
    def raw(self) -> int:
        return (self.index & 0xFFFF) << 16 | (self.subindex & 0xFF) << 8 | (self.bits & 0xFF)

    @classmethod
    def from_raw(cls, raw: int) -> MapEntry:
        return cls(raw >> 16 & 0xFFFF, raw >> 8 & 0xFF, raw & 0xFF)

    @classmethod
    def reserved(cls, bits: int) -> MapEntry:
        """LECSN Reserved padding: PNU 0, the subindex gives the length (004 §20.3 note)."""
        return cls(0, bits, bits)

    @property
    def is_padding(self) -> bool:
        return self.index == 0 or self.index in _DUMMY

    @property
    def address(self) -> ObjectAddress | None:
        return None if self.is_padding else ObjectAddress(self.index, self.subindex)

    def __str__(self) -> str:
        if self.index == 0:
            return f"reserved:{self.bits}"
        return f"0x{self.index:04X}:{self.subindex:02X}"


@dataclass(frozen=True)
class PdoComm:
    """Communication parameters of a CANopen PDO (CiA 301 §7.5.2.35)."""

    cob_id: int
    enabled: bool
    rtr_allowed: bool = True
    transmission_type: int = 255
    inhibit_time: int = 0
    event_timer: int = 0
    sync_start: int = 0

    def cob_raw(self, direction: Direction) -> int:
        """The value of sub 1: the CAN id with bits 31 (invalid) and 30 (no RTR)."""
        raw = self.cob_id
        if not self.enabled:
            raw |= COB_INVALID
        if direction is Direction.TX and not self.rtr_allowed:
            raw |= COB_NO_RTR
        return raw


@dataclass(frozen=True)
class Pdo:
    """One PDO: where it is configured, how it is sent and what it carries."""

    direction: Direction
    number: int
    mapping_index: int
    comm_index: int | None
    comm: PdoComm | None
    entries: tuple[MapEntry, ...]
    #: The family's kind (profile.pdo.kind); it decides the name.
    kind: str = "canopen"

    @property
    def name(self) -> str:
        rx = self.direction is Direction.RX
        if self.kind == "canopen":
            return f"{'RPDO' if rx else 'TPDO'}{self.number}"
        if self.kind == "telegram":
            return "setpoint telegram" if rx else "actual-value telegram"
        return f"{'RxPDO' if rx else 'TxPDO'} {self.mapping_index:04X}h"

    @property
    def bits(self) -> int:
        return sum(e.bits for e in self.entries)

    @property
    def bytes(self) -> int:
        return (self.bits + 7) // 8


@dataclass(frozen=True)
class PdoConfig:
    """Every PDO of the family (RX first), the EtherCAT assignment, the PROFINET telegram."""

    pdos: tuple[Pdo, ...]
    assignment: dict[Direction, tuple[int, ...]] | None = None
    telegram: int | None = None

    def pdo(self, direction: Direction | str, number: int) -> Pdo:
        d = Direction(direction)
        for p in self.pdos:
            if p.direction is d and p.number == number:
                return p
        raise NotFoundError(
            f"there is no {d.value} PDO {number}",
            hint=f"numbers 1..{sum(1 for p in self.pdos if p.direction is d)}",
        )

    def of(self, direction: Direction | str) -> list[Pdo]:
        d = Direction(direction)
        return [p for p in self.pdos if p.direction is d]

    def active(self, direction: Direction | str) -> list[Pdo]:
        """The PDOs that go on the bus, in the order they are sent."""
        d = Direction(direction)
        mine = self.of(d)
        if not mine:
            return []
        kind = mine[0].kind
        if kind == "canopen":
            return [p for p in mine if p.comm is not None and p.comm.enabled and p.entries]
        if kind == "ethercat":
            by_index = {p.mapping_index: p for p in mine}
            assigned = (self.assignment or {}).get(d, ())
            return [by_index[i] for i in assigned if i in by_index]
        return mine

    def replace_pdo(self, pdo: Pdo) -> PdoConfig:
        pdos = tuple(
            pdo if (p.direction, p.number) == (pdo.direction, pdo.number) else p for p in self.pdos
        )
        return replace(self, pdos=pdos)


@dataclass(frozen=True)
class Problem:
    """A reason a mapping is refused, shown next to the field it is about."""

    message: str
    pdo: str | None = None
    entry: int | None = None
    field: str | None = None
    section: str | None = None

    def to_dict(self) -> dict[str, object]:
        return {
            "message": self.message,
            "pdo": self.pdo,
            "entry": self.entry,
            "field": self.field,
            "section": self.section,
        }


@dataclass(frozen=True)
class Slot:
    """One mapped entry at its place in the frame."""

    entry: MapEntry
    offset_bits: int
    bits: int
    address: ObjectAddress | None
    name: str
    data_type: DataType | None
    unit: str | None

    @property
    def offset_byte(self) -> int:
        return self.offset_bits // 8

    @property
    def padding(self) -> bool:
        return self.address is None


@dataclass(frozen=True)
class Step:
    """One action of a plan, in order."""

    kind: Literal["write", "nmt"]
    address: ObjectAddress | None
    value: int
    data_type: DataType | None
    command: str | None
    why: str

    @property
    def value_hex(self) -> str | None:
        if self.kind != "write":
            return None
        bits = self.data_type.bits if self.data_type is not None else 32
        return f"0x{self.value & ((1 << bits) - 1):0{max(bits // 4, 2)}X}"

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": self.kind,
            "address": str(self.address) if self.address is not None else None,
            "value": self.value,
            "value_hex": self.value_hex,
            "command": self.command,
            "why": self.why,
        }


@dataclass(frozen=True)
class Plan:
    """The ordered steps that turn the current configuration into the desired one."""

    steps: tuple[Step, ...]
    touched: tuple[str, ...]

    def to_dict(self) -> dict[str, object]:
        return {"steps": [s.to_dict() for s in self.steps], "touched": list(self.touched)}


# --------------------------------------------------------------------------------------------
# Where the configuration lives


def _rules(profile: DeviceProfile) -> PdoRules:
    return profile.pdo


def _count(profile: DeviceProfile, d: Direction) -> int:
    r = _rules(profile)
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
    t = _rules(profile).telegram_object
    return ObjectAddress.parse(t) if t else None


def _directions(profile: DeviceProfile) -> list[tuple[Direction, int]]:
    return [(d, n) for d in Direction for n in range(1, _count(profile, d) + 1)]


def config_addresses(profile: DeviceProfile) -> list[ObjectAddress]:
    """Every object to read for :func:`parse_config` (objects the profile has, in order)."""
    kind = _rules(profile).kind
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
    rules = _rules(profile)
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
    kind = _rules(profile).kind
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


def _entry_from_json(profile: DeviceProfile, item: Any, where: str) -> MapEntry:
    if isinstance(item, str):
        return _resolve(profile, item, where)
    if isinstance(item, int) and not isinstance(item, bool):
        return MapEntry.from_raw(item)
    if isinstance(item, Mapping):
        unknown = set(item) - {"index", "subindex", "bits", "address", "raw"}
        if unknown:
            raise ValidationError(
                f"{where}: unknown key {sorted(unknown)[0]!r}",
                field=where,
                hint='an entry is "0x607A:00" or {"index", "subindex", "bits"}',
            )
        try:
            if "raw" in item:
                return MapEntry.from_raw(coerce_int(item["raw"]))
            if "address" in item:
                e = _resolve(profile, str(item["address"]), where)
                bits = item.get("bits")
                return e if bits is None else replace(e, bits=coerce_int(bits))
            index = coerce_int(item["index"])
            sub = coerce_int(item.get("subindex", 0))
            if "bits" in item:
                bits = coerce_int(item["bits"])
            else:
                bits = _resolve(profile, f"0x{index:04X}:{sub:02X}", where).bits
        except KeyError as exc:
            raise ValidationError(f"{where}: {exc.args[0]!r} is missing", field=where) from None
        except ValidationError as exc:
            raise ValidationError(
                exc.message if exc.message.startswith(where) else f"{where}: {exc.message}",
                field=where,
                hint=exc.hint,
            ) from None
        if not (0 <= index <= 0xFFFF and 0 <= sub <= 0xFF and 0 <= bits <= 0xFF):
            raise ValidationError(f"{where}: index, subindex or bits out of range", field=where)
        return MapEntry(index, sub, bits)
    raise ValidationError(
        f"{where}: {item!r} is not a mapping entry",
        field=where,
        hint='write "0x607A:00" or {"index": 24698, "subindex": 0, "bits": 32}',
    )


# --------------------------------------------------------------------------------------------
# Validation

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
) -> list[Problem]:
    rules = _rules(profile)
    kind = rules.kind
    out: list[Problem] = []
    name = pdo.name
    d = pdo.direction
    seen: dict[tuple[int, int], int] = {}
    for i, e in enumerate(pdo.entries):

        def bad(msg: str, sect: str | None = section, _i: int = i) -> None:
            out.append(Problem(msg, pdo=name, entry=_i, field="entries", section=sect))

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
            Problem(
                f"{n} entries: {name} holds at most {max_entries}; remove {n - max_entries}",
                pdo=name,
                field="entries",
                section=section,
            )
        )
    room = _entry_subs(profile, pdo.mapping_index)
    if room and n > room and n <= max_entries:
        out.append(
            Problem(
                f"{n} entries: 0x{pdo.mapping_index:04X} has only {room} entry subindices; "
                f"remove {n - room}",
                pdo=name,
                field="entries",
                section=section,
            )
        )
    return out


def validate(profile: DeviceProfile, config: PdoConfig) -> list[Problem]:
    """Every reason the configuration breaks the family's rules; [] when it is valid."""
    rules = _rules(profile)
    kind = rules.kind
    section = rules.section
    out: list[Problem] = []
    if kind == "fixed":
        return _validate_fixed(profile, config)
    if kind == "telegram":
        return _validate_telegram(profile, config)
    for p in config.pdos:
        out.extend(_check_entries(profile, p, rules.max_entries, section))
        if p.bits > rules.max_bits:
            out.append(
                Problem(
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
                    Problem(
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
                            Problem(
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


def _validate_comm(profile: DeviceProfile, config: PdoConfig) -> list[Problem]:
    rules = _rules(profile)
    out: list[Problem] = []
    ids: dict[int, str] = {}
    for p in config.pdos:
        c, ci = p.comm, p.comm_index
        if c is None or ci is None:
            continue
        name = p.name
        d = p.direction.value
        fam = rules.section

        def bad(msg: str, fld: str, sect: str | None, _name: str = name) -> None:
            out.append(Problem(msg, pdo=_name, field=fld, section=sect))

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


def _validate_assignment(profile: DeviceProfile, config: PdoConfig) -> list[Problem]:
    rules = _rules(profile)
    out: list[Problem] = []
    for d in Direction:
        idx = _ASSIGN[d.value]
        assigned = (config.assignment or {}).get(d, ())
        room = len([s for s in _subs(profile, idx) if s > 0])
        maps = {p.mapping_index for p in config.of(d)}
        if len(assigned) > room:
            out.append(
                Problem(
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
                    Problem(
                        f"0x{a:04X} is not a {d.value.upper()} mapping object; assign one of "
                        f"0x{lo:04X}-0x{lo + _count(profile, d) - 1:04X}",
                        field="assignment",
                        section=rules.section,
                    )
                )
            elif a in assigned[:k]:
                out.append(
                    Problem(
                        f"0x{a:04X} is assigned twice to 0x{idx:04X}; assign it once",
                        field="assignment",
                        section=rules.section,
                    )
                )
    return out


def _validate_fixed(profile: DeviceProfile, config: PdoConfig) -> list[Problem]:
    base = default_config(profile, 1)
    out: list[Problem] = []
    for p in config.pdos:
        try:
            ref = base.pdo(p.direction, p.number)
        except NotFoundError:
            out.append(Problem(f"{p.name} does not exist on this drive", pdo=p.name))
            continue
        if p.entries != ref.entries:
            out.append(_fixed_problem(profile, p.name))
    return out


def _fixed_problem(profile: DeviceProfile, name: str | None) -> Problem:
    sect = _rules(profile).section
    return Problem(
        f"the PDO mapping of {profile.name} is pre-assigned and cannot be changed ({sect}); "
        "keep the fixed mapping and use the objects it carries",
        pdo=name,
        field="entries",
        section=sect,
    )


def _validate_telegram(profile: DeviceProfile, config: PdoConfig) -> list[Problem]:
    rules = _rules(profile)
    tg = rules.telegram(config.telegram) if config.telegram is not None else None
    if tg is None:
        known = ", ".join(str(t.number) for t in rules.telegrams)
        return [
            Problem(
                f"telegram {config.telegram} is not supported; choose one of {known}",
                field="telegram",
                section=rules.section,
            )
        ]
    sect = tg.section or rules.section
    out: list[Problem] = []
    for p in config.pdos:
        if not tg.variable:
            if p.entries != _telegram_entries(profile, tg, p.direction):
                out.append(
                    Problem(
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
                Problem(
                    f"{p.name}: the mapping totals {p.bits / 8:g} bytes, telegram {tg.number} "
                    f"needs exactly {tg.bytes}; {todo}",
                    pdo=p.name,
                    field="entries",
                    section=sect,
                )
            )
    return out


# --------------------------------------------------------------------------------------------
# Planning


def _norm_state(state: str | None) -> str:
    s = (state or "").strip().lower().replace("-", "").replace("_", "").replace(" ", "")
    return {
        "preop": "preop",
        "preoperational": "preop",
        "operational": "operational",
        "op": "operational",
        "started": "operational",
        "start": "operational",
        "stopped": "stopped",
        "stop": "stopped",
    }.get(s, s or "unknown")


def _write(
    profile: DeviceProfile, index: int, sub: int, value: int, why: str, fallback: DataType
) -> Step:
    addr = ObjectAddress(index, sub)
    spec = profile.spec(addr)
    return Step("write", addr, value, spec.data_type if spec else fallback, None, why)


def _nmt(command: str, why: str) -> Step:
    return Step("nmt", None, 0, None, command, why)


def _mapping_steps(profile: DeviceProfile, pdo: Pdo, cite: str) -> list[Step]:
    mi = pdo.mapping_index
    name = pdo.name
    steps = [
        _write(profile, mi, 0, 0, f"clear the mapping of {name} (sub 0 = 0) - {cite}", _U8),
    ]
    for k, e in enumerate(pdo.entries, start=1):
        steps.append(
            _write(
                profile, mi, k, e.raw, f"{name} entry {k}: {_spec_name(profile, e)} - {cite}", _U32
            )
        )
    steps.append(
        _write(
            profile,
            mi,
            0,
            len(pdo.entries),
            f"{name} maps {len(pdo.entries)} objects ({pdo.bits} bits) - {cite}",
            _U8,
        )
    )
    return steps


_U8, _U16, _U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32


def _canopen_steps(
    profile: DeviceProfile, cur: Pdo | None, pdo: Pdo, section: str | None
) -> list[Step]:
    assert pdo.comm is not None and pdo.comm_index is not None
    c, ci, name, d = pdo.comm, pdo.comm_index, pdo.name, pdo.direction
    cc = cur.comm if cur is not None else None
    map_changed = cur is None or cur.entries != pdo.entries
    comm_changed = cc is None or cc != c
    if not map_changed and not comm_changed:
        return []
    # The family's own section when it is not the standard itself (smartris 001 §2-8).
    fam = f"; {section}" if section and not section.startswith("CiA") else ""
    steps: list[Step] = []
    written: int | None = None
    if cc is None or cc.enabled:
        # CiA 301 §7.5.2.35: the PDO is made invalid (bit 31) before its id, its
        # parameters or its mapping change; its old id stays until then.
        base = cc if cc is not None else c
        written = replace(base, enabled=False).cob_raw(d)
        steps.append(
            _write(
                profile,
                ci,
                1,
                written,
                f"disable {name} (COB-ID bit 31 = 1) - {_CIA_COMM}{fam}",
                _U32,
            )
        )
    else:
        written = cc.cob_raw(d)
    if map_changed:
        steps.extend(_mapping_steps(profile, pdo, f"{_CIA_MAP}{fam}"))
    old = dict(_comm_fields(cc)) if cc is not None else {}
    fields = {2: "transmission type", 3: "inhibit time", 5: "event timer", 6: "SYNC start value"}
    changed = [
        (sub, v) for sub, v in _comm_fields(c) if _has(profile, ci, sub) and old.get(sub) != v
    ]
    # Timers going to 0 first, the type next, timers with a value last: a drive that takes
    # an event timer only with type 254/255 (smartris 001 §2-8) accepts every step.
    order = (
        [(s, v) for s, v in changed if s != 2 and v == 0]
        + [(s, v) for s, v in changed if s == 2]
        + [(s, v) for s, v in changed if s != 2 and v != 0]
    )
    for sub, v in order:
        steps.append(
            _write(
                profile,
                ci,
                sub,
                v,
                f"{name} {fields[sub]} = {v} (while the PDO is invalid) - {_CIA_COMM}{fam}",
                _U8 if sub in (2, 6) else _U16,
            )
        )
    final = c.cob_raw(d)
    if final != written:
        what = f"enable {name} on COB-ID 0x{c.cob_id:03X}" if c.enabled else f"{name} stays off"
        steps.append(
            _write(
                profile,
                ci,
                1,
                final,
                f"{what} (COB-ID bit 31 = {0 if c.enabled else 1}) - {_CIA_COMM}{fam}",
                _U32,
            )
        )
    return steps


def _body(
    profile: DeviceProfile, current: PdoConfig | None, desired: PdoConfig
) -> tuple[list[Step], list[str]]:
    rules = _rules(profile)
    kind = rules.kind
    section = rules.section
    steps: list[Step] = []
    touched: list[str] = []

    def cur_of(p: Pdo) -> Pdo | None:
        if current is None:
            return None
        try:
            return current.pdo(p.direction, p.number)
        except NotFoundError:
            return None

    if kind == "canopen":
        for p in desired.pdos:
            s = _canopen_steps(profile, cur_of(p), p, section)
            if s:
                steps.extend(s)
                touched.append(p.name)
        return steps, touched
    if kind == "ethercat":
        for d in Direction:
            idx = _ASSIGN[d.value]
            want = (desired.assignment or {}).get(d, ())
            had = (current.assignment or {}).get(d, ()) if current is not None else None
            changed_maps = [
                p for p in desired.of(d) if (c := cur_of(p)) is None or c.entries != p.entries
            ]
            if not changed_maps and had == want:
                continue
            cite = section or "ETG.1000.6"
            steps.append(
                _write(
                    profile,
                    idx,
                    0,
                    0,
                    f"unassign the {d.value.upper()} PDOs (0x{idx:04X}:00 = 0) - {cite}",
                    _U8,
                )
            )
            for p in changed_maps:
                steps.extend(_mapping_steps(profile, p, cite))
                touched.append(p.name)
            for k, a in enumerate(want, start=1):
                steps.append(
                    _write(
                        profile, idx, k, a, f"assign 0x{a:04X} (0x{idx:04X}:{k:02X}) - {cite}", _U16
                    )
                )
            if want:
                steps.append(
                    _write(
                        profile,
                        idx,
                        0,
                        len(want),
                        f"{len(want)} {d.value.upper()} PDO assigned; the drive checks the "
                        f"mapping here - {cite}",
                        _U8,
                    )
                )
            names = {p.mapping_index: p.name for p in desired.of(d)}
            for a in sorted(set(want) ^ set(had or ())):
                if a in names and names[a] not in touched:
                    touched.append(names[a])
        return steps, touched
    if kind == "telegram":
        t = _telegram_address(profile)
        tg = rules.telegram(desired.telegram) if desired.telegram is not None else None
        if tg is None or t is None:
            return steps, touched
        cite = tg.section or section or ""
        telegram_changed = current is None or current.telegram != desired.telegram
        if telegram_changed:
            steps.append(
                _write(
                    profile,
                    t.index,
                    t.subindex,
                    tg.number,
                    f"select telegram {tg.number} (P{t.index}) - {cite}",
                    _U16,
                )
            )
        if tg.variable:
            for p in desired.pdos:
                c = cur_of(p)
                if c is None or c.entries != p.entries or telegram_changed:
                    steps.extend(_mapping_steps(profile, p, cite))
                    touched.append(p.name)
        elif telegram_changed:
            touched.extend(p.name for p in desired.pdos)
        return steps, touched
    return steps, touched


def _wrap_nmt(rules: PdoRules, nmt_state: str, body: list[Step]) -> list[Step]:
    state = _norm_state(nmt_state)
    need = _norm_state(rules.mapping_state)
    if need != "preop" or state == "preop":
        return body
    cite = rules.section or "CiA 301 §7.3.2"
    if rules.kind == "ethercat":
        why = (
            f"ESM PreOp (the twin: NMT pre-operational): mapping and assignment only there - {cite}"
        )
    elif rules.kind == "telegram":
        why = (
            "NMT pre-operational: the telegram and its mapping are set only while no process "
            f"data is exchanged - {cite}"
        )
    else:
        why = f"NMT pre-operational: PDOs are remapped only there - CiA 301 §7.3.2; {cite}"
        if cite.startswith("CiA"):
            why = "NMT pre-operational: PDOs are remapped only there - CiA 301 §7.3.2"
    out = [_nmt("preop", why)]
    out.extend(body)
    if state == "operational":
        out.append(_nmt("start", "NMT operational again, as before the change - CiA 301 §7.3.2"))
    elif state == "stopped":
        out.append(_nmt("stop", "NMT stopped again, as before the change - CiA 301 §7.3.2"))
    return out


def _refuse(problems: list[Problem]) -> PdoRefused:
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    first = problems[0]
    where = f"{first.pdo}: " if first.pdo and not first.message.startswith(first.pdo) else ""
    return PdoRefused(
        f"PDO configuration refused: {where}{first.message}{more}",
        problems=list(problems),
        field=first.field,
        hint="correct the fields the problems name; nothing was written",
    )


def _same(profile: DeviceProfile, a: PdoConfig, b: PdoConfig) -> bool:
    return a == b


def plan(profile: DeviceProfile, current: PdoConfig, desired: PdoConfig, *, nmt_state: str) -> Plan:
    """The ordered writes that turn ``current`` into ``desired``; only changed PDOs are
    touched. Raises :class:`PdoRefused` when ``desired`` breaks the family's rules."""
    rules = _rules(profile)
    if rules.kind == "fixed" or rules.mapping_state == "fixed":
        if not _same(profile, current, desired):
            changed: list[str | None] = [p.name for p in desired.pdos if p not in current.pdos]
            raise _refuse([_fixed_problem(profile, n) for n in changed or [None]])
        return Plan((), ())
    problems = validate(profile, desired)
    if problems:
        raise _refuse(problems)
    body, touched = _body(profile, current, desired)
    if not body:
        return Plan((), ())
    return Plan(tuple(_wrap_nmt(rules, nmt_state, body)), tuple(touched))


def full_plan(profile: DeviceProfile, desired: PdoConfig, *, nmt_state: str) -> Plan:
    """Rewrite every PDO to ``desired`` whatever the drive holds (used for rollback).

    Not validated: it puts back a configuration the drive had before."""
    rules = _rules(profile)
    if rules.kind == "fixed" or rules.mapping_state == "fixed":
        return Plan((), ())
    body, touched = _body(profile, None, desired)
    return Plan(tuple(_wrap_nmt(rules, nmt_state, body)), tuple(touched))


# --------------------------------------------------------------------------------------------
# Layout, pack, unpack


def _telegram_words(profile: DeviceProfile, pdo: Pdo) -> tuple[PdoWord, ...] | None:
    """The word names of a fixed telegram whose layout ``pdo`` carries (telegram 1's
    STW1/NSOLL_A are no objects, so only the telegram can name them)."""
    if pdo.kind != "telegram":
        return None
    for tg in _rules(profile).telegrams:
        if tg.variable:
            continue
        words = tg.rx if pdo.direction is Direction.RX else tg.tx
        if len(words) == len(pdo.entries) and any(w.address is None for w in words):
            try:
                if _telegram_entries(profile, tg, pdo.direction) == pdo.entries:
                    return words
            except ServodeskError:
                continue
    return None


def layout(profile: DeviceProfile, pdo: Pdo) -> list[Slot]:
    """Each entry at its bit offset in the frame (CiA 301: entries follow each other)."""
    words = _telegram_words(profile, pdo)
    out: list[Slot] = []
    offset = 0
    for i, e in enumerate(pdo.entries):
        if e.is_padding:
            w = words[i] if words is not None else None
            if w is not None and w.address is None:
                name = w.name or "Reserved"
                if w.note:
                    name = f"{name} ({w.note})"
                out.append(Slot(e, offset, e.bits, None, name, w.data_type, None))
            elif e.index == 0:
                out.append(Slot(e, offset, e.bits, None, "Reserved", None, None))
            else:
                dt = DataType(e.index)
                out.append(Slot(e, offset, e.bits, None, f"dummy {dt.name}", dt, None))
        else:
            addr = ObjectAddress(e.index, e.subindex)
            spec = profile.spec(addr)
            out.append(
                Slot(
                    e,
                    offset,
                    e.bits,
                    addr,
                    spec.name if spec else f"unknown object {addr}",
                    spec.data_type if spec else None,
                    spec.unit if spec else None,
                )
            )
        offset += e.bits
    return out


def frame_length(profile: DeviceProfile, pdo: Pdo) -> int:
    """Bytes on the bus: the mapped bytes, padded to a CAN FD length except classic PDOs."""
    n = pdo.bytes
    if _rules(profile).kind == "canopen":
        return n
    for length in FD_LENGTHS:
        if length >= n:
            return length
    raise ValidationError(
        f"{pdo.name} has {n} bytes: more than a CAN FD frame (64) carries",
        hint="map fewer objects",
    )


def _raw_of(value: Value, dt: DataType | None, bits: int, where: str) -> int:
    mask = (1 << bits) - 1
    if dt is None:
        return coerce_int(value) & mask
    if dt.is_real:
        fv = float(value) if not isinstance(value, str | bytes) else float(str(value))
        fmt = "<f" if dt is DataType.REAL32 else "<d"
        return int.from_bytes(struct.pack(fmt, fv), "little") & mask
    if not dt.is_integer:
        data = codec(dt).encode(value)
        return int.from_bytes(data[: (bits + 7) // 8].ljust((bits + 7) // 8, b"\0"), "little")
    try:
        data = codec(dt).encode(value)
    except ValidationError as exc:
        raise ValidationError(f"{where}: {exc.message}", field=where) from None
    return int.from_bytes(data, "little") & mask


def _value_of(raw: int, dt: DataType | None, bits: int) -> Value:
    if dt is None:
        return raw
    if dt is DataType.BOOLEAN:
        return bool(raw & 1)
    if dt.is_real:
        n = dt.bits // 8
        fmt = "<f" if dt is DataType.REAL32 else "<d"
        return float(struct.unpack(fmt, raw.to_bytes(n, "little"))[0])
    if dt.is_integer:
        if dt.is_signed and bits == dt.bits and raw >> (bits - 1) & 1:
            return raw - (1 << bits)
        return raw
    n = (bits + 7) // 8
    return codec(dt).decode(raw.to_bytes(n, "little"))


def pack(profile: DeviceProfile, pdo: Pdo, values: Mapping[ObjectAddress, Value]) -> bytes:
    """The PDO's payload (without CAN FD padding) from object values; a missing value is 0."""
    slots = layout(profile, pdo)
    total = sum(s.bits for s in slots)
    nbytes = (total + 7) // 8
    big = _rules(profile).byte_order == "big"
    acc = 0
    for s in slots:
        if s.address is None or s.address not in values:
            continue
        raw = _raw_of(values[s.address], s.data_type, s.bits, str(s.address))
        if big:
            # Big-endian (004 §20.1.2): each value's bytes most significant first, the
            # entries in order from the first byte.
            acc |= raw << (nbytes * 8 - s.offset_bits - s.bits)
        else:
            # CiA 301 §7.5.2.36: entries fill the frame from bit 0 of byte 0 upwards.
            acc |= raw << s.offset_bits
    return acc.to_bytes(nbytes, "big" if big else "little")


def unpack(profile: DeviceProfile, pdo: Pdo, data: bytes) -> dict[ObjectAddress, Value]:
    """Object values from a received payload; bytes beyond the mapping (padding) are
    ignored, a frame shorter than the mapping is refused."""
    slots = layout(profile, pdo)
    total = sum(s.bits for s in slots)
    nbytes = (total + 7) // 8
    if len(data) < nbytes:
        raise ValidationError(
            f"{pdo.name}: {len(data)} bytes received, the mapping needs {nbytes}",
            hint="the drive's mapping differs from the one read; read the PDO configuration again",
        )
    big = _rules(profile).byte_order == "big"
    acc = int.from_bytes(data[:nbytes], "big" if big else "little")
    out: dict[ObjectAddress, Value] = {}
    for s in slots:
        if s.address is None:
            continue
        mask = (1 << s.bits) - 1
        if big:
            raw = acc >> (nbytes * 8 - s.offset_bits - s.bits) & mask
        else:
            raw = acc >> s.offset_bits & mask
        out[s.address] = _value_of(raw, s.data_type, s.bits)
    return out


# --------------------------------------------------------------------------------------------
# Templates and JSON


def templates(profile: DeviceProfile) -> list[Template]:
    return list(_rules(profile).templates)


def apply_template(profile: DeviceProfile, current: PdoConfig, template_id: str) -> PdoConfig:
    """``current`` with the template's PDOs (the others unchanged); not validated."""
    for t in _rules(profile).templates:
        if t.id == template_id:
            return config_from_json(profile, _template_json(t), current=current)
    raise NotFoundError(
        f"no PDO template {template_id!r} for {profile.name}",
        hint="templates: " + ", ".join(t.id for t in _rules(profile).templates),
    )


def _template_json(t: PdoTemplate) -> dict[str, Any]:
    pdos: list[dict[str, Any]] = []
    for p in t.pdos:
        item: dict[str, Any] = {"direction": p.direction, "number": p.number}
        if p.entries is not None:
            item["entries"] = [
                w.address if w.bits is None else {"address": w.address, "bits": w.bits}
                for w in p.entries
            ]
        for k in (
            "enabled",
            "cob_id",
            "rtr_allowed",
            "transmission_type",
            "inhibit_time",
            "event_timer",
            "sync_start",
        ):
            v = getattr(p, k)
            if v is not None:
                item[k] = v
        pdos.append(item)
    out: dict[str, Any] = {"pdos": pdos}
    if t.assignment is not None:
        out["assignment"] = {k: list(v) for k, v in t.assignment.items()}
    if t.telegram is not None:
        out["telegram"] = t.telegram
    return out


def _entry_json(profile: DeviceProfile, e: MapEntry) -> str | dict[str, int]:
    if e.index == 0 and e.subindex in (0, e.bits):
        return f"reserved:{e.bits}"
    try:
        if _resolve(profile, str(e), "entry") == e:
            return str(e)
    except ValidationError:
        pass
    return {"index": e.index, "subindex": e.subindex, "bits": e.bits}


def config_to_json(profile: DeviceProfile, config: PdoConfig) -> dict[str, Any]:
    """The configuration as a PdoLayout body (docs/pdo.md); :func:`config_from_json` reads
    it back unchanged."""
    pdos: list[dict[str, Any]] = []
    for p in config.pdos:
        item: dict[str, Any] = {
            "direction": p.direction.value,
            "number": p.number,
            "entries": [_entry_json(profile, e) for e in p.entries],
        }
        if p.comm is not None:
            c = p.comm
            item.update(
                cob_id=c.cob_id,
                enabled=c.enabled,
                rtr_allowed=c.rtr_allowed,
                transmission_type=c.transmission_type,
                inhibit_time=c.inhibit_time,
                event_timer=c.event_timer,
                sync_start=c.sync_start,
            )
        pdos.append(item)
    out: dict[str, Any] = {"pdos": pdos}
    if config.assignment is not None:
        out["assignment"] = {d.value: list(v) for d, v in config.assignment.items()}
    if config.telegram is not None:
        out["telegram"] = config.telegram
    return out


_PDO_KEYS = {
    "direction",
    "number",
    "entries",
    "cob_id",
    "enabled",
    "rtr_allowed",
    "transmission_type",
    "inhibit_time",
    "event_timer",
    "sync_start",
}
_COMM_LIMITS = {
    "transmission_type": 0xFF,
    "inhibit_time": 0xFFFF,
    "event_timer": 0xFFFF,
    "sync_start": 0xFF,
}


def _json_int(v: Any, where: str, lo: int, hi: int, node_id: int = 0) -> int:
    try:
        if isinstance(v, str) and "$NODEID" in v.upper():
            r = resolve_value(v, DataType.UNSIGNED32, node_id)
            n = int(r) if isinstance(r, int) else coerce_int(str(r))
        elif isinstance(v, bool) or not isinstance(v, int | str | float):
            raise ValidationError(f"{v!r} is not a number")
        else:
            n = coerce_int(v)
    except (ValidationError, ValueError) as exc:
        msg = exc.message if isinstance(exc, ValidationError) else str(exc)
        raise ValidationError(f"{where}: {msg}", field=where) from None
    if not lo <= n <= hi:
        raise ValidationError(f"{where}: {n} is outside {lo}..{hi}", field=where)
    return n


def _json_bool(v: Any, where: str) -> bool:
    if isinstance(v, bool):
        return v
    raise ValidationError(f"{where}: {v!r} is not true or false", field=where)


def config_from_json(
    profile: DeviceProfile,
    data: Mapping[str, Any],
    *,
    current: PdoConfig | None = None,
) -> PdoConfig:
    """A configuration from a PdoLayout body (docs/pdo.md).

    PDOs (and fields) left out keep their value in ``current``; without ``current`` every PDO
    must be given. Bad input raises :class:`ValidationError` naming the field."""
    if not isinstance(data, Mapping):
        raise ValidationError("the PDO layout must be a JSON object", field="pdos")
    unknown = set(data) - {"pdos", "assignment", "telegram"}
    if unknown:
        raise ValidationError(
            f"unknown key {sorted(unknown)[0]!r}",
            field=sorted(unknown)[0],
            hint="a PDO layout has pdos, assignment and telegram",
        )
    rules = _rules(profile)
    kind = rules.kind
    node_id = _node_id_of(current)
    telegram = current.telegram if current is not None else None
    if "telegram" in data and data["telegram"] is not None:
        if kind != "telegram":
            raise ValidationError(
                f"{profile.name} has no telegrams", field="telegram", hint="leave telegram out"
            )
        telegram = _json_int(data["telegram"], "telegram", 0, 0xFFFF)
    tg = rules.telegram(telegram) if telegram is not None else None
    if kind == "telegram" and tg is None:
        known = ", ".join(str(t.number) for t in rules.telegrams)
        raise ValidationError(
            f"telegram {telegram} is not supported", field="telegram", hint=f"choose {known}"
        )
    telegram_changed = current is not None and current.telegram != telegram
    given: dict[tuple[Direction, int], Mapping[str, Any]] = {}
    raw_pdos = data.get("pdos", [])
    if not isinstance(raw_pdos, Sequence) or isinstance(raw_pdos, str):
        raise ValidationError("pdos must be a list", field="pdos")
    for i, item in enumerate(raw_pdos):
        where = f"pdos[{i}]"
        if not isinstance(item, Mapping):
            raise ValidationError(f"{where} must be an object", field=where)
        bad = set(item) - _PDO_KEYS
        if bad:
            k = sorted(bad)[0]
            raise ValidationError(f"{where}.{k}: unknown key", field=f"{where}.{k}")
        try:
            d = Direction(str(item.get("direction", "")).lower())
        except ValueError:
            raise ValidationError(
                f"{where}.direction: {item.get('direction')!r} is not rx or tx",
                field=f"{where}.direction",
            ) from None
        n = _json_int(item.get("number"), f"{where}.number", 1, _count(profile, d) or 1)
        if n > _count(profile, d):
            raise ValidationError(
                f"{where}.number: {profile.name} has {_count(profile, d)} {d.value} PDOs",
                field=f"{where}.number",
            )
        if (d, n) in given:
            raise ValidationError(f"{where}: {d.value} PDO {n} is given twice", field=where)
        given[(d, n)] = item
    pdos: list[Pdo] = []
    for d, n in _directions(profile):
        base = _base_pdo(profile, current, d, n, tg if telegram_changed else None)
        item = given.get((d, n))
        if item is None:
            if base is None:
                raise ValidationError(
                    f"{d.value} PDO {n} is missing",
                    field="pdos",
                    hint="give every PDO, or pass the current configuration",
                )
            if tg is not None and not tg.variable:
                base = replace(base, entries=_telegram_entries(profile, tg, d))
            pdos.append(base)
            continue
        where = f"pdos[{raw_pdos.index(item)}]"
        if "entries" in item and item["entries"] is not None:
            ents = item["entries"]
            if not isinstance(ents, Sequence) or isinstance(ents, str):
                raise ValidationError(f"{where}.entries must be a list", field=f"{where}.entries")
            entries = tuple(
                _entry_from_json(profile, e, f"{where}.entries[{k}]") for k, e in enumerate(ents)
            )
        elif base is not None:
            entries = base.entries
        else:
            raise ValidationError(f"{where}.entries is missing", field=f"{where}.entries")
        if tg is not None and not tg.variable:
            # A fixed telegram always has its own layout (004 §20.3); entries sent along
            # (e.g. the previous telegram's, merged by a client) do not apply to it.
            entries = _telegram_entries(profile, tg, d)
        comm: PdoComm | None = None
        ci: int | None = None
        if kind == "canopen":
            ci = _comm_index(d, n)
            bc = base.comm if base is not None else None
            vals: dict[str, Any] = {}
            for k in ("cob_id", "enabled", "rtr_allowed", *_COMM_LIMITS):
                if k in item and item[k] is not None:
                    vals[k] = item[k]
                elif bc is not None:
                    vals[k] = getattr(bc, k)
                elif k in ("cob_id", "enabled"):
                    raise ValidationError(f"{where}.{k} is missing", field=f"{where}.{k}")
            cob = _json_int(vals["cob_id"], f"{where}.cob_id", 0, 0x1FFFFFFF, node_id)
            comm = PdoComm(
                cob_id=cob,
                enabled=_json_bool(vals["enabled"], f"{where}.enabled"),
                rtr_allowed=_json_bool(vals.get("rtr_allowed", True), f"{where}.rtr_allowed"),
                **{
                    k: _json_int(
                        vals.get(k, 255 if k == "transmission_type" else 0), f"{where}.{k}", 0, hi
                    )
                    for k, hi in _COMM_LIMITS.items()
                },
            )
        elif any(k in item for k in (*_COMM_LIMITS, "cob_id", "enabled", "rtr_allowed")):
            k = next(k for k in (*_COMM_LIMITS, "cob_id", "enabled", "rtr_allowed") if k in item)
            raise ValidationError(
                f"{where}.{k}: {profile.name} has no communication parameters ({kind} family)",
                field=f"{where}.{k}",
                hint="give only direction, number and entries",
            )
        mi = _map_index(d, n)
        pdos.append(Pdo(d, n, mi, ci, comm, entries, kind))
    assignment: dict[Direction, tuple[int, ...]] | None = None
    if kind == "ethercat":
        assignment = dict(current.assignment or {}) if current is not None else {}
        raw = data.get("assignment")
        if raw is not None:
            if not isinstance(raw, Mapping):
                raise ValidationError(
                    'assignment must be {"rx": [0x1600], "tx": [0x1A00]}', field="assignment"
                )
            for k, v in raw.items():
                try:
                    d = Direction(str(k).lower())
                except ValueError:
                    raise ValidationError(
                        f"assignment.{k}: not rx or tx", field=f"assignment.{k}"
                    ) from None
                seq = [v] if isinstance(v, int | str) else v
                if not isinstance(seq, Sequence):
                    raise ValidationError(f"assignment.{k} must be a list", field=f"assignment.{k}")
                assignment[d] = tuple(
                    _json_int(x, f"assignment.{k}[{j}]", 0, 0xFFFF) for j, x in enumerate(seq)
                )
        for d in Direction:
            if d not in assignment:
                raise ValidationError(
                    f"assignment.{d.value} is missing", field=f"assignment.{d.value}"
                )
    elif data.get("assignment") is not None:
        raise ValidationError(f"{profile.name} has no sync manager assignment", field="assignment")
    return PdoConfig(tuple(pdos), assignment, telegram)


def _node_id_of(current: PdoConfig | None) -> int:
    """The node id the current default COB-IDs imply (for ``$NODEID`` in templates)."""
    if current is None:
        return 0
    for p in current.pdos:
        if p.comm is not None and p.number == 1:
            base = 0x200 if p.direction is Direction.RX else 0x180
            if base < p.comm.cob_id <= base + 127:
                return p.comm.cob_id - base
    return 0


def _base_pdo(
    profile: DeviceProfile,
    current: PdoConfig | None,
    d: Direction,
    n: int,
    new_telegram: PdoTelegram | None,
) -> Pdo | None:
    if current is None:
        return None
    try:
        p = current.pdo(d, n)
    except NotFoundError:
        return None
    if new_telegram is not None:
        # Another telegram: its default mapping, not the old one (004 §20.3).
        return replace(p, entries=_telegram_entries(profile, new_telegram, d))
    return p


# --------------------------------------------------------------------------------------------
# Export


def _type_name(dt: DataType | None) -> str:
    return dt.name if dt is not None else ""


def export(
    profile: DeviceProfile,
    config: PdoConfig,
    fmt: Literal["json", "csv", "dcf", "esi"],
    node_id: int,
) -> str:
    """The final layout for the PLC programmer: JSON, CSV (one row per slot), a DCF with the
    PDO objects' ParameterValue (CiA 306), or an ESI <RxPdo>/<TxPdo> fragment (ETG.2000)."""
    if fmt == "json":
        body = config_to_json(profile, config)
        body["layout"] = _layout_json(profile, config, node_id)
        return json.dumps(body, indent=2) + "\n"
    if fmt == "csv":
        return _export_csv(profile, config, node_id)
    if fmt == "dcf":
        return _export_dcf(profile, config, node_id)
    if fmt == "esi":
        return _export_esi(profile, config)
    raise ValidationError(
        f"unknown export format {fmt!r}", field="format", hint="json, csv, dcf or esi"
    )


def bus_cob_id(profile: DeviceProfile, pdo: Pdo, node_id: int) -> int | None:
    """The CAN id the PDO uses on the (twin's) bus: its COB-ID, else 200h/180h + node id."""
    if pdo.comm is not None:
        return pdo.comm.cob_id
    return (0x200 if pdo.direction is Direction.RX else 0x180) + node_id


def _layout_json(profile: DeviceProfile, config: PdoConfig, node_id: int) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    for d in Direction:
        for p in config.active(d):
            out.append(
                {
                    "pdo": p.name,
                    "direction": d.value,
                    "cob_id": p.comm.cob_id if p.comm is not None else None,
                    "bytes": p.bytes,
                    "entries": [
                        {
                            "byte_offset": s.offset_byte,
                            "bit_offset": s.offset_bits % 8,
                            "bits": s.bits,
                            "address": str(s.address) if s.address else None,
                            "name": s.name,
                            "data_type": _type_name(s.data_type),
                            "unit": s.unit,
                        }
                        for s in layout(profile, p)
                    ],
                }
            )
    return out


def _export_csv(profile: DeviceProfile, config: PdoConfig, node_id: int) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["pdo", "cob_id", "byte_offset", "bit_offset", "bits", "address", "name", "type", "unit"]
    )
    for d in Direction:
        for p in config.active(d):
            cob = f"0x{p.comm.cob_id:03X}" if p.comm is not None else ""
            for s in layout(profile, p):
                w.writerow(
                    [
                        p.name,
                        cob,
                        s.offset_byte,
                        s.offset_bits % 8,
                        s.bits,
                        str(s.address) if s.address else "",
                        s.name,
                        _type_name(s.data_type),
                        s.unit or "",
                    ]
                )
    return buf.getvalue()


def _export_dcf(profile: DeviceProfile, config: PdoConfig, node_id: int) -> str:
    # Imported here: devdesc builds on the domain, not the other way round.
    from servodesk.devdesc.eds import _section_text, _spec_section, _value_keys

    if not 1 <= node_id <= 127:
        raise ValidationError(
            f"node id {node_id} is outside 1..127",
            field="node_id",
            hint="CANopen node ids are 1..127 (CiA 301 §7.2.1)",
        )
    values = config_values(profile, config)
    parts = [
        "; PDO configuration of "
        f"{profile.name} (node {node_id}), CiA 306 DCF sections with ParameterValue\n",
        _section_text("DeviceComissioning", {"NodeID": f"0x{node_id:02X}"}),
    ]
    indexes = sorted({a.index for a in values})
    for idx in indexes:
        entry = profile.entries.get(idx)
        if entry is not None and entry.subs:
            subs = [a for a in profile.variables if a.index == idx]
            parts.append(
                _section_text(
                    f"{idx:04X}",
                    {
                        "ParameterName": entry.name,
                        "ObjectType": "0x9" if entry.object_type.value == "record" else "0x8",
                        "SubNumber": f"0x{len(subs):X}",
                    },
                )
            )
        for addr in sorted(a for a in values if a.index == idx):
            spec = profile.spec(addr)
            if spec is None:
                continue
            keys = _spec_section(spec)
            keys = {k: v for k, v in keys.items() if not k.startswith("servodesk_")}
            keys.update(_value_keys(spec, values[addr]))
            name = (
                f"{idx:04X}"
                if entry is not None and not entry.subs
                else f"{idx:04X}sub{addr.subindex:X}"
            )
            parts.append(_section_text(name, keys))
    return "\n".join(parts)


def _export_esi(profile: DeviceProfile, config: PdoConfig) -> str:
    import xml.etree.ElementTree as ET

    from servodesk.devdesc.esi import _type_of

    chunks: list[str] = []
    for d, tag, sm in ((Direction.RX, "RxPdo", "2"), (Direction.TX, "TxPdo", "3")):
        active = {p.mapping_index for p in config.active(d)}
        for p in config.of(d):
            attrs = {"Fixed": "1" if _rules(profile).kind == "fixed" else "0"}
            if p.mapping_index in active:
                attrs["Sm"] = sm
            el = ET.Element(tag, attrs)
            ET.SubElement(el, "Index").text = f"#x{p.mapping_index:04X}"
            ET.SubElement(el, "Name").text = p.name
            for s in layout(profile, p):
                ent = ET.SubElement(el, "Entry")
                ET.SubElement(ent, "Index").text = f"#x{s.entry.index:04X}" if s.address else "#x0"
                if s.address is not None:
                    ET.SubElement(ent, "SubIndex").text = str(s.entry.subindex)
                ET.SubElement(ent, "BitLen").text = str(s.bits)
                if s.address is not None:
                    ET.SubElement(ent, "Name").text = s.name
                    if s.data_type is not None:
                        spec = profile.spec(s.address)
                        tn = _type_of(s.data_type, spec.default if spec else None)[0]
                        ET.SubElement(ent, "DataType").text = "BOOL" if s.bits == 1 else tn
            ET.indent(el, space="  ")
            chunks.append(ET.tostring(el, encoding="unicode"))
    return "\n".join(chunks) + "\n"


__all__ = [
    "FD_LENGTHS",
    "Direction",
    "MapEntry",
    "Pdo",
    "PdoComm",
    "PdoConfig",
    "Plan",
    "Problem",
    "Slot",
    "Step",
    "Template",
    "apply_template",
    "bus_cob_id",
    "config_addresses",
    "config_from_json",
    "config_to_json",
    "config_values",
    "default_config",
    "default_values",
    "export",
    "frame_length",
    "full_plan",
    "layout",
    "mappable",
    "pack",
    "parse_config",
    "plan",
    "templates",
    "unpack",
    "validate",
]
