"""ESI XML (EtherCAT Slave Information, ETG.2000) from a servodesk profile.

Export writes ``EtherCATInfo/Vendor`` and one ``Descriptions/Devices/Device`` with the CoE
object dictionary (``Profile/Dictionary``: ``DataTypes`` and ``Objects``), the default process
data (``RxPdo``/``TxPdo`` from the mapping objects 1600h../1A00h.. and their sync-manager
assignment from 1C12h/1C13h) and a CoE mailbox. Default and limit values are written as
``DefaultData``/``MinData``/``MaxData``: hex of the little-endian bytes the device holds.
Fields ESI has no element for (unit, scale, group, ...) travel in the device's
``VendorSpecific`` element as JSON under the ``urn:servodesk:devdesc:1`` namespace, which
EtherCAT tools skip (ETG.2000: VendorSpecific content is vendor defined); import
(:mod:`servodesk.devdesc.esi`) reads them back.
"""

from __future__ import annotations

import contextlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    SPEC_FIELDS,
    diff,
    dumps,
    entry_default,
    json_fields,
    profile_meta,
)
from servodesk.devdesc.esi_common import STATES, EsiVar, esi_hex, spec_fields, type_of
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.profile import (
    Access,
    DeviceProfile,
    ObjectEntry,
    ObjectSpec,
    ObjectType,
    PdoMapping,
    SyncManagerSpec,
    resolve_value,
)
from servodesk.errors import ServodeskError

__all__ = ["NS", "export_esi"]

#: Namespace of servodesk's own data inside ``VendorSpecific``.
NS = "urn:servodesk:devdesc:1"
ET.register_namespace("sd", NS)


def _to_var(spec: ObjectSpec) -> EsiVar:
    dt = spec.data_type
    type_name, bits = type_of(dt, spec.default)
    v = EsiVar(name=spec.name, data_type=dt, type_name=type_name, bit_size=bits)
    v.access = {Access.RO: "ro", Access.CONST: "ro", Access.WO: "wo"}.get(spec.access, "rw")
    if spec.writable_in and set(spec.writable_in) <= set(STATES):
        v.write_restrictions = "_".join(STATES[s] for s in STATES if s in spec.writable_in)
    v.pdo = {PdoMapping.RX: "R", PdoMapping.TX: "T", PdoMapping.BOTH: "RT"}.get(spec.pdo_mapping)
    v.backup = spec.persist
    v.values = spec.values
    d = spec.default
    if d is not None and not (isinstance(d, str) and "$NODEID" in d.upper()):
        try:
            val = resolve_value(d, dt)
            if dt.is_string:
                v.default_string = str(val)
            elif val is not None:
                v.default_data = codec(dt).encode(val)
        except (ValueError, ServodeskError):
            pass  # Not expressible: the servodesk extras carry it.
    if dt.is_numeric:
        for key in ("min", "max"):
            lim = getattr(spec, key)
            if lim is None:
                continue
            with contextlib.suppress(ServodeskError):  # Out of range: the extras carry it.
                setattr(v, f"{key}_data", codec(dt).encode(lim))
    return v


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrs: str) -> ET.Element:
    el = ET.SubElement(parent, tag, attrs)
    if text is not None:
        el.text = text
    return el


def _flags(parent: ET.Element, v: EsiVar, category: str | None = None) -> None:
    flags = _sub(parent, "Flags")
    attrs = {"WriteRestrictions": v.write_restrictions} if v.write_restrictions else {}
    _sub(flags, "Access", v.access, **attrs)
    if category:
        _sub(flags, "Category", category)
    if v.pdo:
        _sub(flags, "PdoMapping", v.pdo)
    if v.backup:
        _sub(flags, "Backup", "1")


def _info_values(info: ET.Element, v: EsiVar) -> None:
    # ETG.2000 ObjectInfoType: MinData, MaxData, DefaultData (or DefaultString).
    if v.default_string is not None:
        _sub(info, "DefaultString", v.default_string)
    if v.min_data is not None:
        _sub(info, "MinData", v.min_data.hex().upper())
    if v.max_data is not None:
        _sub(info, "MaxData", v.max_data.hex().upper())
    if v.default_data is not None:
        _sub(info, "DefaultData", v.default_data.hex().upper())


def _enum_type(types: ET.Element, name: str, v: EsiVar) -> None:
    el = _sub(types, "DataType")
    _sub(el, "Name", name)
    _sub(el, "BaseType", v.type_name)
    _sub(el, "BitSize", str(v.bit_size))
    for value, text in sorted((v.values or {}).items()):
        ei = _sub(el, "EnumInfo")
        _sub(ei, "Text", text)
        _sub(ei, "Enum", str(value))


def _array_shape(specs: list[ObjectSpec]) -> bool:
    """An ESI ARRAY needs sub 0 (UNSIGNED8) and elements 1..n of one type, access and mapping."""
    if len(specs) < 2 or specs[0].subindex != 0 or specs[0].data_type is not DataType.UNSIGNED8:
        return False
    elems = specs[1:]
    if [s.subindex for s in elems] != list(range(1, len(elems) + 1)):
        return False
    first = _to_var(elems[0])
    if first.data_type.is_string or first.data_type is DataType.DOMAIN:
        return False
    for s in elems:
        v = _to_var(s)
        key = (v.data_type, v.access, v.write_restrictions, v.pdo, v.backup, v.values)
        if key != (
            first.data_type,
            first.access,
            first.write_restrictions,
            first.pdo,
            first.backup,
            first.values,
        ):
            return False
    return True


@dataclass
class _Export:
    types: ET.Element
    objects: ET.Element
    extras: ET.Element
    used_types: dict[str, int] = field(default_factory=dict)

    def var_extras(self, spec: ObjectSpec, v: EsiVar) -> None:
        baseline = spec_fields(v, spec.index, "<export>")
        names = diff(spec.model_dump(), baseline, SPEC_FIELDS)
        if names:
            data = json_fields(spec, names)
            el = _sub(
                self.extras,
                f"{{{NS}}}Var",
                dumps(data),
                Index=esi_hex(spec.index, 4),
                SubIdx=str(spec.subindex),
            )
            el.tail = None

    def type_name_of(self, v: EsiVar, index: int, sub: int | None) -> str:
        if v.values:
            name = f"DT{index:04X}EN" + (f"{sub:02X}" if sub is not None else "")
            _enum_type(self.types, name, v)
            return name
        self.used_types[v.type_name] = v.bit_size
        return v.type_name


def _export_entry(ex: _Export, entry: ObjectEntry) -> None:
    specs = list(entry.specs())
    obj = _sub(ex.objects, "Object")
    _sub(obj, "Index", esi_hex(entry.index, 4))
    _sub(obj, "Name", entry.name)
    if entry.object_type is ObjectType.VAR:
        spec = specs[0]
        v = _to_var(spec)
        _sub(obj, "Type", ex.type_name_of(v, entry.index, None))
        _sub(obj, "BitSize", str(v.bit_size))
        info = ET.Element("Info")
        _info_values(info, v)
        if len(info):
            obj.append(info)
        _flags(obj, v, "m" if entry.index in (0x1000, 0x1018) else "o")
        ex.var_extras(spec, v)
        return
    is_array = entry.object_type is ObjectType.ARRAY and _array_shape(specs)
    shape = ObjectType.ARRAY if is_array else ObjectType.RECORD
    entry_names = diff(
        entry.model_dump(),
        {"name": entry.name, **{n: entry_default(n) for n in ENTRY_FIELDS if n != "name"}},
        ENTRY_FIELDS,
    )
    data: dict[str, Any] = json_fields(entry, entry_names)
    if entry.object_type is not shape:
        data["object_type"] = entry.object_type.value
    if data:
        _sub(ex.extras, f"{{{NS}}}Entry", dumps(data), Index=esi_hex(entry.index, 4))
    dt_name = f"DT{entry.index:04X}"
    dtype = _sub(ex.types, "DataType")
    _sub(dtype, "Name", dt_name)
    size_el = _sub(dtype, "BitSize", "0")
    vars_ = [_to_var(s) for s in specs]
    info = ET.Element("Info")
    offset = 0
    if is_array:
        v0 = vars_[0]
        _record_item(ex, dtype, 0, v0, ex.type_name_of(v0, entry.index, 0), 0)
        offset = 16  # Sub 0 is padded to 16 bits (ETG.2000 object layout).
        elem = vars_[1]
        n = len(vars_) - 1
        arr = ET.Element("DataType")
        _sub(arr, "Name", f"{dt_name}ARR")
        _sub(arr, "BaseType", ex.type_name_of(elem, entry.index, 1))
        _sub(arr, "BitSize", str(elem.bit_size * n))
        ai = _sub(arr, "ArrayInfo")
        _sub(ai, "LBound", "1")
        _sub(ai, "Elements", str(n))
        # The array type must precede the record that uses it.
        ex.types.insert(list(ex.types).index(dtype), arr)
        item = _sub(dtype, "SubItem")
        _sub(item, "Name", "Elements")
        _sub(item, "Type", f"{dt_name}ARR")
        _sub(item, "BitSize", str(elem.bit_size * n))
        _sub(item, "BitOffs", str(offset))
        _flags(item, elem)
        offset += elem.bit_size * n
    else:
        for s, v in zip(specs, vars_, strict=True):
            if s.subindex == 0:
                _record_item(ex, dtype, 0, v, ex.type_name_of(v, entry.index, 0), 0)
                offset = 16
            else:
                _record_item(
                    ex, dtype, s.subindex, v, ex.type_name_of(v, entry.index, s.subindex), offset
                )
                offset += v.bit_size
    size_el.text = str(offset)
    for s, v in zip(specs, vars_, strict=True):
        si = _sub(info, "SubItem")
        _sub(si, "Name", v.name)
        sinfo = ET.Element("Info")
        _info_values(sinfo, v)
        if len(sinfo):
            si.append(sinfo)
        ex.var_extras(s, v)
    _sub(obj, "Type", dt_name)
    _sub(obj, "BitSize", str(offset))
    obj.append(info)
    _flags(
        obj,
        EsiVar(
            name="", data_type=DataType.UNSIGNED8, type_name="", bit_size=0, access=vars_[0].access
        ),
        "m" if entry.index == 0x1018 else "o",
    )


def _record_item(
    ex: _Export, dtype: ET.Element, sub: int, v: EsiVar, type_name: str, offset: int
) -> None:
    item = _sub(dtype, "SubItem")
    _sub(item, "SubIdx", str(sub))
    _sub(item, "Name", v.name)
    _sub(item, "Type", type_name)
    _sub(item, "BitSize", str(v.bit_size))
    _sub(item, "BitOffs", str(offset))
    _flags(item, v)


def _int_default(profile: DeviceProfile, index: int, sub: int) -> int | None:
    spec = profile.spec(ObjectAddress(index, sub))
    if spec is None:
        return None
    try:
        v = spec.default_value()
    except (ValueError, ServodeskError):
        return None
    return int(v) if isinstance(v, int) else None


def _pdo_elements(profile: DeviceProfile, device: ET.Element) -> None:
    """RxPdo/TxPdo from the default mapping objects; Sm from 1C12h/1C13h (ETG.1000.6 §5.6.7)."""
    for tag, lo, hi, assign_idx, sm in (
        ("RxPdo", 0x1600, 0x17FF, 0x1C12, "2"),
        ("TxPdo", 0x1A00, 0x1BFF, 0x1C13, "3"),
    ):
        maps = [e for e in sorted(profile.objects, key=lambda e: e.index) if lo <= e.index <= hi]
        assigned: set[int] = set()
        n_assign = _int_default(profile, assign_idx, 0)
        if n_assign is not None:
            for k in range(1, n_assign + 1):
                a = _int_default(profile, assign_idx, k)
                if a:
                    assigned.add(a)
        else:
            first = next(
                (e.index for e in maps if (_int_default(profile, e.index, 0) or 0) > 0), None
            )
            if first is not None:
                assigned.add(first)
        for e in maps:
            count = _int_default(profile, e.index, 0) or 0
            sub0 = profile.spec(ObjectAddress(e.index, 0))
            attrs = {"Fixed": "0" if sub0 is not None and sub0.access.writable else "1"}
            if e.index in assigned:
                attrs["Sm"] = sm
            pdo = _sub(device, tag, **attrs)
            _sub(pdo, "Index", esi_hex(e.index, 4))
            _sub(pdo, "Name", e.name)
            for k in range(1, count + 1):
                raw = _int_default(profile, e.index, k) or 0
                idx, sub, bits = raw >> 16, (raw >> 8) & 0xFF, raw & 0xFF
                ent = _sub(pdo, "Entry")
                _sub(ent, "Index", esi_hex(idx, 4))
                _sub(ent, "SubIndex", str(sub))
                _sub(ent, "BitLen", str(bits))
                target = profile.spec(ObjectAddress(idx, sub)) if idx else None
                if target is not None:
                    _sub(ent, "Name", target.name)
                    _sub(ent, "DataType", type_of(target.data_type, target.default)[0])


def export_esi(profile: DeviceProfile) -> str:
    """The profile as an ESI XML document (one device)."""
    vendor_id = profile.identity.vendor_id
    if vendor_id is None:
        vendor_id = _int_default(profile, 0x1018, 1) or 0
    product = (
        profile.identity.product_codes[0]
        if profile.identity.product_codes
        else _int_default(profile, 0x1018, 2) or 0
    )
    revision = _int_default(profile, 0x1018, 3) or (profile.identity.revision_min or 0)
    device_type = _int_default(profile, 0x1000, 0) or 402

    root = ET.Element("EtherCATInfo", {"Version": "1.6"})
    vendor = _sub(root, "Vendor")
    _sub(vendor, "Id", esi_hex(vendor_id))
    _sub(vendor, "Name", profile.vendor)
    desc = _sub(root, "Descriptions")
    groups = _sub(desc, "Groups")
    group = _sub(groups, "Group")
    _sub(group, "Type", "Drive")
    _sub(group, "Name", "Drives")
    devices = _sub(desc, "Devices")
    device = _sub(devices, "Device", Physics="YY")
    _sub(device, "Type", profile.id, ProductCode=esi_hex(product), RevisionNo=esi_hex(revision))
    _sub(device, "Name", profile.name, LcId="1033")
    _sub(device, "GroupType", "Drive")
    prof = _sub(device, "Profile")
    _sub(prof, "ProfileNo", str(device_type & 0xFFFF))
    _sub(prof, "AddInfo", str(device_type >> 16))
    dictionary = _sub(prof, "Dictionary")
    types = _sub(dictionary, "DataTypes")
    objects = _sub(dictionary, "Objects")
    extras = ET.Element(f"{{{NS}}}Servodesk", {"Version": "1"})
    _sub(extras, f"{{{NS}}}Profile", profile_meta(profile))
    ex = _Export(types=types, objects=objects, extras=extras)
    for entry in sorted(profile.objects, key=lambda e: e.index):
        _export_entry(ex, entry)
    # Base types first, as ESI editors list them (ETG.2000 DataTypes).
    for i, (name, bits) in enumerate(sorted(ex.used_types.items())):
        base = ET.Element("DataType")
        _sub(base, "Name", name)
        _sub(base, "BitSize", str(bits))
        types.insert(i, base)
    for name in ("Outputs", "Inputs", "MBoxState"):
        _sub(device, "Fmmu", name)
    sms = profile.pdo.sync_managers or (
        SyncManagerSpec(
            number=0, kind="MBoxOut", start_address=0x1000, control_byte=0x26, default_size=128
        ),
        SyncManagerSpec(
            number=1, kind="MBoxIn", start_address=0x1080, control_byte=0x22, default_size=128
        ),
        SyncManagerSpec(number=2, kind="Outputs", start_address=0x1100, control_byte=0x64),
        SyncManagerSpec(number=3, kind="Inputs", start_address=0x1400, control_byte=0x20),
    )
    for sm in sorted(sms, key=lambda x: x.number):
        attrs = {"Enable": "1" if sm.enabled else "0"}
        if sm.start_address is not None:
            attrs["StartAddress"] = esi_hex(sm.start_address, 4)
        if sm.control_byte is not None:
            attrs["ControlByte"] = esi_hex(sm.control_byte, 2)
        if sm.default_size is not None:
            attrs["DefaultSize"] = str(sm.default_size)
        _sub(device, "Sm", sm.kind, **attrs)
    _pdo_elements(profile, device)
    mailbox = _sub(device, "Mailbox", DataLinkLayer="1")
    _sub(mailbox, "CoE", SdoInfo="1", PdoAssign="1", PdoConfig="1", CompleteAccess="0")
    if profile.pdo.dc_modes:
        dc = _sub(device, "Dc")
        for mode in profile.pdo.dc_modes:
            om = _sub(dc, "OpMode")
            _sub(om, "Name", mode.name)
            if mode.description is not None:
                _sub(om, "Desc", mode.description)
            _sub(om, "AssignActivate", esi_hex(mode.assign_activate, 4))
            for tag, value, factor in (
                ("CycleTimeSync0", mode.cycle_time_sync0, mode.cycle_factor_sync0),
                ("ShiftTimeSync0", mode.shift_time_sync0, None),
                ("CycleTimeSync1", mode.cycle_time_sync1, mode.cycle_factor_sync1),
            ):
                if value is not None:
                    el = _sub(om, tag, str(value))
                    if factor is not None:
                        el.set("Factor", str(factor))
    vs = _sub(device, "VendorSpecific")
    vs.append(extras)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
