"""A profile built on the spot from an EtherCAT slave's SDO Information (issue 46).

An EtherCAT slave whose identity no EtherCAT profile matches (no shipped family, no imported
ESI) but that offers the CoE SDO Information service (ETG.1000.6 §5.6.3) describes its own
object dictionary: every index (Get OD List), its name and object code (Get Object
Description), and each sub-index's name, data type, bit length and access (Get Entry
Description). :func:`profile_from_sdo_info` turns that list (read by
``EthercatLink.object_list``) into a profile merged over ``cia402-ethercat``:

- the objects are the slave's, exactly: an object the slave does not list is not in the
  profile (a backup would only find it unreadable), and a vendor object the generic profile
  does not know is there with the slave's name, type and access;
- where ``cia402-ethercat`` knows a sub-index, its CiA 402 knowledge is kept: unit, scale,
  group, symbol, whether it is a process value (CiA 402-2 says what 6064h means; SDO
  Information does not), and where the data type is the same also its limits, default and
  value texts;
- the rest of ``cia402-ethercat`` stays as it is: modes, homing methods, the state machine's
  objects, error codes, the EtherCAT PDO rules; a PDO template that maps an object the slave
  does not have, or cannot map, is left out.

Pure: the link reads, this builds. SDO Information gives no default, limits or unit (the
value info of Get Entry Description is optional, and SOEM does not ask for it).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from servodesk.devdesc._common import ParsedObject, area_group, build_entry
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.ethercat import OdEntryInfo, OdObjectInfo
from servodesk.domain.profile import (
    Access,
    DeviceProfile,
    FamilyIdentity,
    Group,
    ObjectEntry,
    ObjectSpec,
    ObjectType,
    PdoMapping,
)
from servodesk.errors import ServodeskError

__all__ = ["BASE_PROFILE", "SUFFIX", "profile_from_sdo_info", "sdo_info_profile_id"]

#: The profile the slave's objects are merged over: its CiA 402 knowledge stays.
BASE_PROFILE = "cia402-ethercat"
#: The end of a generated profile's id: says what it is wherever the id is shown.
SUFFIX = "-sdoinfo"
#: Object codes (ETG.1000.6 §5.6.3.5, CiA 301 §7.4.3): the ones servodesk's model holds.
_OBJECT_TYPES = {7: ObjectType.VAR, 8: ObjectType.ARRAY, 9: ObjectType.RECORD}
#: Object access bits of Get Entry Description (ETG.1000.6 §5.6.3.6): readable in PRE-OP,
#: SAFE-OP, OP (bits 0-2), writable in each (3-5), RxPDO- (6) and TxPDO-mappable (7).
_READ, _WRITE, _RX, _TX = 0x07, 0x38, 0x40, 0x80
#: What the base profile's description of an address brings along: what CiA 402 says the
#: object means, which SDO Information cannot say.
_MEANING = (
    "name_local",
    "unit",
    "scale",
    "raw_unit",
    "group",
    "persist",
    "process",
    "description",
    "section",
    "symbol",
    "writable_in",
)
#: ... and what only holds in the base's data type (a slave that gives 6064h as UNSIGNED32,
#: as the Synapticon sample ESI does, takes no INTEGER32 limits).
_ENCODED = ("default", "min", "max", "values")


def sdo_info_profile_id(vendor_id: int | None, product_code: int | None) -> str:
    """``ethercat-<vendor>-<product>-sdoinfo`` (8 hex digits each): the id of the profile
    built from the SDO Information of a slave with this identity."""
    return f"ethercat-{vendor_id or 0:08x}-{product_code or 0:08x}{SUFFIX}"


def _access(bits: int, mapping: PdoMapping) -> Access:
    readable, writable = bool(bits & _READ), bool(bits & _WRITE)
    if readable and writable:
        # CiA 306's rww / rwr: written by an RxPDO, read by a TxPDO.
        if mapping.rx:
            return Access.RWW
        return Access.RWR if mapping.tx else Access.RW
    return Access.WO if writable else Access.RO


def _mapping(bits: int) -> PdoMapping:
    rx, tx = bool(bits & _RX), bool(bits & _TX)
    if rx and tx:
        return PdoMapping.BOTH
    return PdoMapping.RX if rx else PdoMapping.TX if tx else PdoMapping.NONE


def _fields(
    index: int, e: OdEntryInfo, known: ObjectSpec | None, skipped: list[str]
) -> dict[str, Any] | None:
    """One sub-index's ObjectSpec fields: the slave's description, the base's knowledge."""
    try:
        dt = DataType(e.data_type)
    except ValueError:
        skipped.append(f"{index:04X}h:{e.subindex:02X} (data type 0x{e.data_type:04X})")
        return None
    mapping = _mapping(e.access)
    fields: dict[str, Any] = {
        "name": e.name or (known.name if known else f"{index:04X}h:{e.subindex:02X}"),
        "data_type": dt,
        "access": _access(e.access, mapping),
        "pdo_mapping": mapping,
        "group": area_group(index),
    }
    if known is not None:
        keep = _MEANING + (_ENCODED if known.data_type is dt else ())
        fields.update({k: getattr(known, k) for k in keep if getattr(known, k)})
        if not fields["access"].writable:
            fields.pop("default", None)  # Nothing to restore a read-only object to.
    elif mapping.tx and not fields["access"].writable:
        fields["process"] = True  # An actual value (a TxPDO's): never backed up.
    return fields


def _entry(o: OdObjectInfo, base: DeviceProfile, skipped: list[str]) -> ObjectEntry | None:
    otype = _OBJECT_TYPES.get(o.object_code)
    if otype is None:
        skipped.append(f"{o.index:04X}h (object code {o.object_code})")
        return None
    subs: dict[int, dict[str, Any]] = {}
    for e in o.entries:
        f = _fields(o.index, e, base.spec(ObjectAddress(o.index, e.subindex)), skipped)
        if f is not None:
            subs[e.subindex] = f
    if not subs or (otype is ObjectType.VAR and 0 not in subs):
        return None
    known = base.entries.get(o.index)
    entry: dict[str, Any] = {"name": o.name or (known.name if known else f"{o.index:04X}h")}
    if otype is not ObjectType.VAR:
        entry["group"] = known.group if known and known.group else area_group(o.index)
    parsed = ParsedObject(o.index, otype, f"SDO Information {o.index:04X}h", entry, subs)
    try:
        return build_entry(parsed)
    except ServodeskError:
        skipped.append(f"{o.index:04X}h (its description does not fit the model)")
        return None


def _templates_kept(profile: DeviceProfile) -> tuple[Any, ...]:
    kept = []
    for t in profile.pdo.templates:
        ok = True
        for q in t.pdos:
            for w in q.entries or ():
                if w.address is None or w.address.startswith("reserved"):
                    continue
                spec = profile.spec(ObjectAddress.parse(w.address))
                if spec is None or not (
                    spec.pdo_mapping.rx if q.direction == "rx" else spec.pdo_mapping.tx
                ):
                    ok = False
        if ok:
            kept.append(t)
    return tuple(kept)


def profile_from_sdo_info(
    objects: Iterable[OdObjectInfo],
    base: DeviceProfile,
    *,
    vendor_id: int | None,
    product_code: int | None,
    revision: int | None,
    device_name: str | None,
    where: str,
) -> DeviceProfile:
    """The profile of the slave whose SDO Information listed ``objects`` (module doc), merged
    over ``base`` (``cia402-ethercat``). ``where`` says where it was read (interface and
    slave), for the description."""
    skipped: list[str] = []
    built = [e for o in objects if (e := _entry(o, base, skipped)) is not None]
    built.sort(key=lambda e: e.index)
    groups_used = {s.group for e in built for s in e.specs() if s.group}
    base_groups = [g for g in base.groups if g.id in groups_used]
    area = [
        Group(id=gid, name=name)
        for gid, name in (
            ("communication", "Communication (CiA 301)"),
            ("manufacturer", "Manufacturer specific"),
            ("device_profile", "Device profile (CiA 402)"),
        )
        if gid in groups_used and gid not in {g.id for g in base_groups}
    ]
    ident = f"vendor 0x{vendor_id or 0:08X}, product code 0x{product_code or 0:08X}" + (
        f", revision 0x{revision:08X}" if revision is not None else ""
    )
    description = (
        f"Built by servodesk from the SDO Information (ETG.1000.6 §5.6.3) of the EtherCAT "
        f"slave {where} ({ident}): its {len(built)} objects with their names, data types, "
        f"access and sub-indices, merged over {base.id} ({base.name}), whose CiA 402 "
        "knowledge stays (modes, state machine, units and limits of the objects it knows). "
        "Kept in memory only; import the drive's ESI for its defaults, limits and PDOs."
    )
    if skipped:
        description += " Not taken (no place in servodesk's model): " + ", ".join(skipped) + "."
    data = base.model_dump()
    data.update(
        id=sdo_info_profile_id(vendor_id, product_code),
        name=f"{device_name or 'EtherCAT slave'} (SDO Information)",
        vendor=f"vendor 0x{vendor_id or 0:08X}",
        description=description,
        extends=None,
        # No identity: detection chooses it only by this rule (services/manager.py), never
        # over a profile imported later for the same identity (docs/ethercat.md).
        identity=FamilyIdentity().model_dump(),
        objects=[e.model_dump() for e in built],
        groups=[g.model_dump() for g in base_groups + area],
    )
    profile = DeviceProfile.model_validate(data)
    kept = _templates_kept(profile)
    if len(kept) == len(profile.pdo.templates):
        return profile
    data["pdo"]["templates"] = [t.model_dump() for t in kept]
    return DeviceProfile.model_validate(data)
