"""The process-data side of an ESI import (ETG.2000 DeviceType): ``RxPdo``/``TxPdo`` as
mapping objects and mapped variables when the dictionary lacks them, the PDO rules of an
EtherCAT profile with the ``Sm`` sync managers, the ``Dc/OpMode`` modes and the default
assignment as a template, and the ``Modules``/``Slots`` of a modular device (each slot's
default module placed with its PDOs). Called by :func:`servodesk.devdesc.esi.import_esi`.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    SPEC_FIELDS,
    ParsedObject,
    area_group,
    collecting,
    entry_default,
    parse_int,
    spec_default,
    warn,
)
from servodesk.devdesc.esi_common import EsiTypes, english_name, esi_hex, kid, kid_text, kids
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import Access, DeviceProfile, ObjectType, PdoMapping
from servodesk.errors import ProfileError

_BITS_TYPES: dict[int, DataType] = {
    1: DataType.BOOLEAN,
    8: DataType.UNSIGNED8,
    16: DataType.UNSIGNED16,
    32: DataType.UNSIGNED32,
    64: DataType.UNSIGNED64,
}


def _entry_type(ent: ET.Element, bits: int, where: str) -> DataType:
    """The data type of a PDO entry the dictionary does not describe."""
    dt_name = kid_text(ent, "DataType") or ""
    with collecting():  # The guess below is reported once, by the caller.
        try:
            dt, _ = EsiTypes({}).basic(dt_name, bits, where)
            if (dt.is_numeric and dt.bits == bits) or (dt is DataType.BOOLEAN and bits == 1):
                return dt
        except ProfileError:
            pass
    return _BITS_TYPES.get(bits, DataType.OCTET_STRING if bits % 8 == 0 else DataType.DOMAIN)


def _pdo_index(pdo: ET.Element, tag: str, where: str) -> int:
    try:
        return parse_int(kid_text(pdo, "Index") or "")
    except ValueError:
        raise ProfileError(
            f"{where}: a {tag} has no valid Index", hint="write <Index>#x1600</Index>"
        ) from None


def pdo_objects(
    device: ET.Element, known: set[int], have: set[tuple[int, int]], where: str
) -> list[ParsedObject]:
    """Mapping objects and mapped variables from RxPdo/TxPdo when the dictionary lacks them."""
    out: list[ParsedObject] = []
    base = {n: spec_default(n) for n in SPEC_FIELDS}
    # Variables the PDO entries name, by index: sub -> fields.
    made: dict[int, dict[int, dict[str, Any]]] = {}
    pdo_indices = {
        _pdo_index(pdo, tag, where) for tag in ("RxPdo", "TxPdo") for pdo in kids(device, tag)
    }
    for tag, direction in (("RxPdo", PdoMapping.RX), ("TxPdo", PdoMapping.TX)):
        for pdo in kids(device, tag):
            pidx = _pdo_index(pdo, tag, where)
            entries = list(kids(pdo, "Entry"))
            fixed = (pdo.get("Fixed") or "0").lower() in ("1", "true")
            maps: dict[int, dict[str, Any]] = {}
            maps[0] = {
                **base,
                "name": "Number of mapped objects",
                "data_type": DataType.UNSIGNED8,
                "access": Access.RO if fixed else Access.RW,
                "default": len(entries),
                "group": area_group(pidx),
            }
            for k, ent in enumerate(entries, start=1):
                try:
                    idx = parse_int(kid_text(ent, "Index") or "0")
                    sub = parse_int(kid_text(ent, "SubIndex") or "0")
                    bits = parse_int(kid_text(ent, "BitLen") or "0")
                except ValueError:
                    raise ProfileError(
                        f"{where}: {tag} {esi_hex(pidx, 4)} entry {k}: Index, "
                        "SubIndex or BitLen is not a number",
                        hint="write numbers as #x6040 or decimal",
                    ) from None
                if k > 0xFF or not (0 <= idx <= 0xFFFF and 0 <= sub <= 0xFF and bits <= 0xFF):
                    warn(f"{where}: {tag} {esi_hex(pidx, 4)} entry {k} out of range, skipped")
                    continue
                maps[k] = {
                    **base,
                    "name": f"Mapped object {k}",
                    "data_type": DataType.UNSIGNED32,
                    "access": Access.RO if fixed else Access.RW,
                    "default": (idx << 16) | (sub << 8) | bits,
                    "group": area_group(pidx),
                }
                if idx < 0x1000 or (idx, sub) in have or idx in known or idx in pdo_indices:
                    continue  # Padding (index 0, dummy types) or described by the dictionary.
                dt = _entry_type(ent, bits, where)
                pdo_ok = dt.is_numeric and (dt.bits == bits or dt is DataType.BOOLEAN)
                made.setdefault(idx, {})[sub] = {
                    **base,
                    "name": english_name(ent) or f"Object {idx:04X}:{sub:02X}",
                    "data_type": dt,
                    # ETG.2000 leaves SDO access of such entries open; RxPDO data is written.
                    "access": Access.RWW if direction is PdoMapping.RX else Access.RO,
                    "pdo_mapping": direction if pdo_ok else PdoMapping.NONE,
                    "process": True,
                    "group": area_group(idx),
                }
                if not pdo_ok:
                    warn(
                        f"{where}: {tag} {esi_hex(pidx, 4)} entry {esi_hex(idx, 4)}:{sub}: "
                        f"{bits} bits is no CiA 301 type; described, not PDO-mappable here"
                    )
            if pidx not in known:
                obj = ParsedObject(index=pidx, object_type=ObjectType.RECORD, where=where)
                obj.entry = {n: entry_default(n) for n in ENTRY_FIELDS}
                obj.entry["name"] = english_name(pdo) or f"PDO {pidx:04X}"
                obj.subs = maps
                out.append(obj)
                known.add(pidx)
    for idx, subs in sorted(made.items()):
        if set(subs) == {0}:
            v = ParsedObject(index=idx, object_type=ObjectType.VAR, where=where)
            v.subs[0] = subs[0]
        else:
            # Entries at sub-indices: a RECORD whose sub 0 is the highest sub-index (CiA 301).
            v = ParsedObject(index=idx, object_type=ObjectType.RECORD, where=where)
            v.entry = {n: entry_default(n) for n in ENTRY_FIELDS}
            v.entry["name"] = f"Object {idx:04X}"
            v.subs = {
                0: {
                    **base,
                    "name": "Highest sub-index supported",
                    "data_type": DataType.UNSIGNED8,
                    "access": Access.RO,
                    "default": max(subs),
                    "group": area_group(idx),
                },
                **{s: f for s, f in subs.items() if s},
            }
        out.append(v)
        known.add(idx)
    return out


def mapped_entries(device: ET.Element) -> dict[str, set[tuple[int, int]]]:
    """The (index, sub) the device's RxPdo / TxPdo entries map, per direction."""
    out: dict[str, set[tuple[int, int]]] = {"rx": set(), "tx": set()}
    for tag, key in (("RxPdo", "rx"), ("TxPdo", "tx")):
        for pdo in kids(device, tag):
            for ent in kids(pdo, "Entry"):
                try:
                    idx = parse_int(kid_text(ent, "Index") or "0")
                    sub = parse_int(kid_text(ent, "SubIndex") or "0")
                except ValueError:
                    continue
                out[key].add((idx, sub))
    return out


def direction_from_pdos(
    f: dict[str, Any], key: tuple[int, int], mapped: Mapping[str, set[tuple[int, int]]], where: str
) -> None:
    """A read-only object flagged ``PdoMapping R`` that the file maps only in a TxPdo: the
    flag is the vendor's slip (Elmo Gold: 603Fh error code), the PDOs say T."""
    if (
        f.get("access") is Access.RO
        and f.get("pdo_mapping") is PdoMapping.RX
        and key in mapped["tx"]
        and key not in mapped["rx"]
    ):
        warn(f"{where} sub {key[1]}: read-only, PdoMapping R but mapped in a TxPdo; taken as T")
        f["pdo_mapping"] = PdoMapping.TX
        f["process"] = True


def _sync_managers(device: ET.Element) -> list[dict[str, Any]]:
    """``Sm`` elements (ETG.2000 DeviceType/Sm): number by order, kind from the text."""
    out: list[dict[str, Any]] = []
    for n, sm in enumerate(kids(device, "Sm")):
        if n > 15:
            warn(f"more than 16 Sm elements; Sm {n} and later skipped")
            break
        entry: dict[str, Any] = {"number": n, "kind": (sm.text or "").strip() or "unused"}
        for attr, key in (
            ("StartAddress", "start_address"),
            ("DefaultSize", "default_size"),
            ("ControlByte", "control_byte"),
        ):
            raw = sm.get(attr)
            if raw:
                try:
                    entry[key] = parse_int(raw)
                except ValueError:
                    warn(f"Sm {n} {attr}={raw!r} is not a number; left out")
        enable = (sm.get("Enable") or "1").strip().lower()
        entry["enabled"] = enable not in ("0", "false")
        out.append(entry)
    return out


def _dc_modes(device: ET.Element) -> list[dict[str, Any]]:
    """``Dc/OpMode`` (ETG.2000 DeviceType/Dc): AssignActivate and the SYNC0/1 times."""
    out: list[dict[str, Any]] = []
    for om in kids(kid(device, "Dc"), "OpMode"):
        name = kid_text(om, "Name") or ""
        try:
            mode: dict[str, Any] = {
                "name": name,
                "description": kid_text(om, "Desc"),
                "assign_activate": parse_int(kid_text(om, "AssignActivate") or "0"),
            }
            for tag, key, factor_key in (
                ("CycleTimeSync0", "cycle_time_sync0", "cycle_factor_sync0"),
                ("ShiftTimeSync0", "shift_time_sync0", None),
                ("CycleTimeSync1", "cycle_time_sync1", "cycle_factor_sync1"),
            ):
                el = kid(om, tag)
                if el is not None and el.text and el.text.strip():
                    mode[key] = parse_int(el.text)
                    if factor_key and el.get("Factor"):
                        mode[factor_key] = parse_int(el.get("Factor") or "")
        except ValueError:
            warn(f"Dc/OpMode {name!r}: a value is not a number; mode skipped")
            continue
        out.append(mode)
    return out


def pdo_rules(device: ET.Element, source: str) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The PDO section of an EtherCAT profile, and the default-assignment template (or None).

    ETG.2000 RxPdo/TxPdo: ``Fixed`` (the content cannot change), ``Sm`` (assigned to that
    sync manager by default, i.e. listed in 1C12h/1C13h), ``Mandatory``.
    """
    counts = {"rx": 0, "tx": 0}
    most_entries, most_bits, all_fixed = 8, 64, True
    pdos: list[dict[str, Any]] = []
    assignment: dict[str, list[int]] = {"rx": [], "tx": []}
    for tag, direction, lo in (("RxPdo", "rx", 0x1600), ("TxPdo", "tx", 0x1A00)):
        for pos, pdo in enumerate(kids(device, tag), start=1):
            pidx = _pdo_index(pdo, tag, source)
            number = pidx - lo + 1 if lo <= pidx < lo + 0x200 else pos
            counts[direction] = max(counts[direction], number)
            entries = list(kids(pdo, "Entry"))
            most_entries = max(most_entries, len(entries))
            bits = 0
            words: list[str] = []
            for ent in entries:
                try:
                    idx = parse_int(kid_text(ent, "Index") or "0")
                    sub = parse_int(kid_text(ent, "SubIndex") or "0")
                    n = parse_int(kid_text(ent, "BitLen") or "0")
                except ValueError:
                    continue
                bits += n
                words.append(f"reserved:{n}" if idx == 0 else f"0x{idx:04X}:{sub:02X}")
            most_bits = max(most_bits, bits)
            all_fixed = all_fixed and (pdo.get("Fixed") or "0").lower() in ("1", "true")
            if pdo.get("Sm") is not None and 0 < number <= 512:
                assignment[direction].append(pidx)
                pdos.append({"direction": direction, "number": number, "entries": words})
    has_pdos = bool(counts["rx"] or counts["tx"])
    rules: dict[str, Any] = {
        "kind": "ethercat",
        "rpdo_count": counts["rx"],
        "tpdo_count": counts["tx"],
        "max_entries": min(most_entries, 255),
        "max_bits": most_bits,
        # ETG.1000.6 §5.6.7.4: PDO mapping and assignment change in PreOP only.
        "mapping_state": "fixed" if has_pdos and all_fixed else "preop",
        "sync_managers": _sync_managers(device),
        "dc_modes": _dc_modes(device),
    }
    template = None
    if pdos:
        template = {
            "id": "esi-default",
            "name": "Default assignment (ESI)",
            "description": "The PDOs the ESI assigns to the sync managers by default "
            "(RxPdo/TxPdo with an Sm attribute), with their default entries.",
            "section": "ETG.2000 RxPdo/TxPdo Sm",
            "pdos": pdos,
            "assignment": {k: v for k, v in assignment.items() if v},
        }
    return rules, template


def template_ok(profile: DeviceProfile, template: Mapping[str, Any]) -> str | None:
    """Why the default template cannot be kept (an entry not mappable), or None."""
    for q in template["pdos"]:
        for w in q["entries"]:
            if w.startswith("reserved"):
                continue
            addr = ObjectAddress.parse(w)
            spec = profile.spec(addr)
            if spec is None:
                return f"{w} is not in the dictionary"
            ok = spec.pdo_mapping.rx if q["direction"] == "rx" else spec.pdo_mapping.tx
            if not ok:
                return f"{w} {spec.name} is not mappable in {q['direction']}"
    return None


def _is_true(text: str | None) -> bool:
    return (text or "").strip().lower() in ("1", "true")


def _shift_slot(pdo: ET.Element, pdo_offset: int, index_offset: int) -> None:
    """Move the ``DependOnSlot`` indices of a module's PDO to its slot (ETG.2000 Slots:
    SlotPdoIncrement for the PDO's index, SlotIndexIncrement for the objects it maps)."""
    for el, offset in [(kid(pdo, "Index"), pdo_offset)] + [
        (kid(ent, "Index"), index_offset) for ent in kids(pdo, "Entry")
    ]:
        if el is None or not _is_true(el.get("DependOnSlot")) or not el.text:
            continue
        try:
            el.text = esi_hex(parse_int(el.text) + offset, 4)
        except ValueError:
            continue  # Reported where the entry is read.


def with_default_modules(device: ET.Element, shared: ET.Element | None) -> ET.Element:
    """The device as delivered: each slot's default module (``ModuleIdent Default="1"``)
    adds its PDOs and dictionary objects, moved to the slot (slot n: n x the increments).
    The device element itself is left as parsed; a copy is returned when a slot adds any."""
    slots = kid(device, "Slots")
    if slots is None:
        return device
    modules: dict[int, ET.Element] = {}
    for m in [*kids(kid(device, "Modules"), "Module"), *kids(shared, "Module")]:
        t = kid(m, "Type")
        try:
            ident = parse_int((t.get("ModuleIdent") or "") if t is not None else "")
        except ValueError:
            continue
        modules.setdefault(ident, m)
    try:
        pdo_inc = parse_int(slots.get("SlotPdoIncrement") or "0")
        idx_inc = parse_int(slots.get("SlotIndexIncrement") or "0")
    except ValueError:
        warn("Slots: SlotPdoIncrement/SlotIndexIncrement is not a number; no module imported")
        return device
    out: ET.Element | None = None
    placed: list[str] = []
    for n, slot in enumerate(kids(slots, "Slot")):
        default = next((m for m in kids(slot, "ModuleIdent") if _is_true(m.get("Default"))), None)
        if default is None or not default.text:
            continue
        try:
            module = modules.get(parse_int(default.text))
        except ValueError:
            module = None
        if module is None:
            warn(f"slot {n + 1}: default module {default.text.strip()} is not described")
            continue
        if out is None:
            out = copy.deepcopy(device)
        for tag in ("RxPdo", "TxPdo"):
            for pdo in kids(module, tag):
                moved = copy.deepcopy(pdo)
                _shift_slot(moved, n * pdo_inc, n * idx_inc)
                out.append(moved)
        mdict = next(
            (d for d in (kid(p, "Dictionary") for p in kids(module, "Profile")) if d is not None),
            None,
        )
        if mdict is not None and any(True for _ in kids(kid(mdict, "Objects"), "Object")):
            warn(
                f"slot {n + 1}: the dictionary objects of module {kid_text(module, 'Type')!r} "
                "are not imported (only its PDOs)"
            )
        placed.append(f"slot {n + 1}: {kid_text(module, 'Type') or default.text.strip()}")
    if placed:
        warn("default modules imported with their PDOs: " + "; ".join(placed))
    return out if out is not None else device


def slot_notes(device: ET.Element, shared: ET.Element | None) -> None:
    """Modules and slots (ETG.2000 Modules/Slots): reported, their objects not imported.

    Modules are listed in the device or, shared by all devices, in Descriptions/Modules.
    """
    slots = list(kids(kid(device, "Slots"), "Slot"))
    modules = list(kids(kid(device, "Modules"), "Module"))
    if slots and not modules:
        modules = list(kids(shared, "Module"))
    if modules or slots:
        names = ", ".join(kid_text(m, "Type") or "?" for m in modules[:8])
        more = f" and {len(modules) - 8} more" if len(modules) > 8 else ""
        warn(
            f"{len(modules)} module(s) ({names}{more}) and {len(slots)} slot(s): the device's "
            "own objects and PDOs and the slots' default modules are imported, no other module"
        )
