"""ESI XML (EtherCAT Slave Information, ETG.2000) to and from servodesk profiles.

Export writes ``EtherCATInfo/Vendor`` and one ``Descriptions/Devices/Device`` with the CoE
object dictionary (``Profile/Dictionary``: ``DataTypes`` and ``Objects``), the default process
data (``RxPdo``/``TxPdo`` from the mapping objects 1600h../1A00h.. and their sync-manager
assignment from 1C12h/1C13h) and a CoE mailbox. Default and limit values are written as
``DefaultData``/``MinData``/``MaxData``: hex of the little-endian bytes the device holds.

Import reads real vendor files: any namespace, ``#x`` hex, ``BitSize``, RECORD and ARRAY types
built from ``DataTypes``/``SubItem``/``ArrayInfo`` (byte arrays and arrays longer than 255
elements as one octet string, nested structures as DOMAIN), enumerations (``EnumInfo``),
values as ``DefaultData`` or ``DefaultValue``; an ESI without a dictionary gets its objects
from the PDO entries. One of several devices is picked (``device=``), each slot's default
module is placed (``Slots``), and the profile is an EtherCAT one: PDO kind ``ethercat``, the
``Sm`` sync managers, the ``Dc/OpMode`` modes, the default assignment as a template. What the
model cannot hold is reported with :func:`~servodesk.devdesc._common.warn`, not refused.
Fields ESI has no element for (unit, scale, group, ...) travel in the device's
``VendorSpecific`` element as JSON under the ``urn:servodesk:devdesc:1`` namespace, which
EtherCAT tools skip (ETG.2000: VendorSpecific content is vendor defined).
"""

from __future__ import annotations

import contextlib
import copy
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    SPEC_FIELDS,
    ParsedObject,
    area_group,
    build_entry,
    collecting,
    diff,
    dumps,
    entry_default,
    json_fields,
    loads,
    make_profile,
    parse_int,
    parse_number,
    profile_meta,
    slug,
    spec_default,
    warn,
)
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
from servodesk.errors import ProfileError, ServodeskError

__all__ = ["NS", "EsiDevice", "esi_devices", "export_esi", "import_esi"]

#: Namespace of servodesk's own data inside ``VendorSpecific``.
NS = "urn:servodesk:devdesc:1"
ET.register_namespace("sd", NS)

_ESI_NAMES: dict[DataType, str] = {
    DataType.BOOLEAN: "BOOL",
    DataType.INTEGER8: "SINT",
    DataType.INTEGER16: "INT",
    DataType.INTEGER24: "INT24",
    DataType.INTEGER32: "DINT",
    DataType.INTEGER40: "INT40",
    DataType.INTEGER48: "INT48",
    DataType.INTEGER56: "INT56",
    DataType.INTEGER64: "LINT",
    DataType.UNSIGNED8: "USINT",
    DataType.UNSIGNED16: "UINT",
    DataType.UNSIGNED24: "UINT24",
    DataType.UNSIGNED32: "UDINT",
    DataType.UNSIGNED40: "UINT40",
    DataType.UNSIGNED48: "UINT48",
    DataType.UNSIGNED56: "UINT56",
    DataType.UNSIGNED64: "ULINT",
    DataType.REAL32: "REAL",
    DataType.REAL64: "LREAL",
    DataType.DOMAIN: "DOMAIN",
}
_ESI_TYPES: dict[str, DataType] = {v: k for k, v in _ESI_NAMES.items()}
# Names vendor files also use (IEC 61131-3 bit strings, ETG.1020 bit arrays).
_ESI_TYPES.update(
    {
        "BYTE": DataType.UNSIGNED8,
        "WORD": DataType.UNSIGNED16,
        "DWORD": DataType.UNSIGNED32,
        "LWORD": DataType.UNSIGNED64,
        "BITARR8": DataType.UNSIGNED8,
        "BITARR16": DataType.UNSIGNED16,
        "BITARR32": DataType.UNSIGNED32,
        "BIT1": DataType.BOOLEAN,
        "FLOAT": DataType.REAL32,
        "DOUBLE": DataType.REAL64,
        "INTEGER8": DataType.INTEGER8,
        "INTEGER16": DataType.INTEGER16,
        "INTEGER32": DataType.INTEGER32,
        "INTEGER64": DataType.INTEGER64,
        "UNSIGNED8": DataType.UNSIGNED8,
        "UNSIGNED16": DataType.UNSIGNED16,
        "UNSIGNED32": DataType.UNSIGNED32,
        "UNSIGNED64": DataType.UNSIGNED64,
        "REAL32": DataType.REAL32,
        "REAL64": DataType.REAL64,
    }
)
for _n in range(2, 9):
    _ESI_TYPES[f"BIT{_n}"] = DataType.UNSIGNED8
_STRING_TYPE = re.compile(
    r"^(STRING|VISIBLE_STRING|UNICODE_STRING|WSTRING|OCTET_STRING|OSTRING)\s*(?:\((\d+)\))?$"
)
_BYTE_ARRAY = re.compile(r"^ARRAY\s*\[\s*(\d+)\s*\.\.\s*(\d+)\s*\]\s*OF\s*(BYTE|USINT)$")
_STATES = {"preop": "PreOP", "safeop": "SafeOP", "op": "OP"}


# --------------------------------------------------------------------------------------------
# The standard part of one variable, shared by export and import.


@dataclass
class _EsiVar:
    """One variable as ESI describes it (object, record sub-item or array element)."""

    name: str
    data_type: DataType
    type_name: str
    bit_size: int
    access: str = "ro"
    write_restrictions: str | None = None
    pdo: str | None = None
    backup: bool = False
    values: dict[int, str] | None = None
    default_data: bytes | None = None
    default_string: str | None = None
    default_value: str | None = None
    min_data: bytes | None = None
    max_data: bytes | None = None
    min_value: str | None = None
    max_value: str | None = None


def _decode(data: bytes, dt: DataType, where: str) -> Any:
    if dt.is_string:
        return codec(dt).decode(data)
    if dt.is_numeric:
        size = max(dt.bits // 8, 1)
        if len(data) < size:
            # Vendor files shorten DefaultData of wide types; the missing bytes are zero.
            data = data + bytes(size - len(data))
        elif len(data) > size:
            extra = data[size:]
            if any(extra):
                warn(f"{where}: {len(data)} bytes for a {dt.name}; value left out")
                return None
            data = data[:size]  # Zero padding beyond the type (BOOL written as 2 bytes).
        try:
            v = codec(dt).decode(data)
        except ServodeskError as exc:
            raise ProfileError(f"{where}: {exc.message}") from None
        return int(v) if isinstance(v, bool) else v
    return data.hex().upper()


def _fields(v: _EsiVar, index: int, where: str) -> dict[str, Any]:
    """ObjectSpec fields from the standard ESI description of one variable."""
    access = {"ro": Access.RO, "rw": Access.RW, "wo": Access.WO}.get(v.access.lower())
    if access is None:
        raise ProfileError(
            f"{where}: Access {v.access!r} is not ro, rw or wo",
            hint="ETG.2000 Flags/Access is ro, rw or wo",
        )
    pdo_text = (v.pdo or "").upper()
    pdo = {
        "": PdoMapping.NONE,
        "R": PdoMapping.RX,
        "T": PdoMapping.TX,
        "RT": PdoMapping.BOTH,
        "TR": PdoMapping.BOTH,
    }.get(pdo_text)
    if pdo is None:
        raise ProfileError(
            f"{where}: PdoMapping {v.pdo!r} is not R, T or RT",
            hint="ETG.2000 Flags/PdoMapping is R (RxPDO), T (TxPDO) or RT",
        )
    writable_in: tuple[str, ...] = ()
    if v.write_restrictions:
        states = tuple(s.lower() for s in re.split(r"[_\s]+", v.write_restrictions) if s)
        if set(states) != set(_STATES):
            writable_in = states
    f: dict[str, Any] = {n: spec_default(n) for n in SPEC_FIELDS}
    f.update(
        name=v.name,
        data_type=v.data_type,
        access=access,
        pdo_mapping=pdo,
        persist=v.backup,
        # Read-only and mappable to a TxPDO is an actual value, never backed up.
        process=access is Access.RO and pdo is PdoMapping.TX,
        writable_in=writable_in,
        group=area_group(index),
        values=v.values,
    )
    dt = v.data_type
    if v.default_string is not None:
        f["default"] = v.default_string
    elif v.default_data is not None:
        f["default"] = _decode(v.default_data, dt, f"{where} DefaultData")
    elif v.default_value is not None and v.default_value.strip():
        f["default"] = _number(v.default_value, dt, f"{where} DefaultValue")
    if dt.is_numeric:
        for key, data, text in (
            ("min", v.min_data, v.min_value),
            ("max", v.max_data, v.max_value),
        ):
            if data is not None:
                f[key] = _decode(data, dt, f"{where} {key.capitalize()}Data")
            elif text is not None and text.strip():
                f[key] = _number(text, dt, f"{where} {key.capitalize()}Value")
    return f


def _number(text: str, dt: DataType, where: str) -> Any:
    if not dt.is_numeric:
        return text
    try:
        return parse_number(text, dt)
    except ValueError:
        raise ProfileError(
            f"{where}={text!r}: not a {dt.name} number",
            hint="write decimal, or hex as #x1F",
        ) from None


# --------------------------------------------------------------------------------------------
# Export


def _type_of(dt: DataType, default: Any) -> tuple[str, int]:
    """ESI type name and bit size; strings take their length from the default value."""
    if dt in (DataType.VISIBLE_STRING, DataType.OCTET_STRING, DataType.UNICODE_STRING):
        n = 0
        if isinstance(default, str) and "$NODEID" not in default.upper():
            try:
                n = len(codec(dt).encode(default))
            except ServodeskError:
                n = 0
        n = max(n, 1)
        if dt is DataType.VISIBLE_STRING:
            return f"STRING({n})", n * 8
        if dt is DataType.UNICODE_STRING:
            return f"UNICODE_STRING({n // 2 or 1})", n * 8
        return f"OCTET_STRING({n})", n * 8
    return _ESI_NAMES[dt], 1 if dt is DataType.BOOLEAN else dt.bits


def _to_var(spec: ObjectSpec) -> _EsiVar:
    dt = spec.data_type
    type_name, bits = _type_of(dt, spec.default)
    v = _EsiVar(name=spec.name, data_type=dt, type_name=type_name, bit_size=bits)
    v.access = {Access.RO: "ro", Access.CONST: "ro", Access.WO: "wo"}.get(spec.access, "rw")
    if spec.writable_in and set(spec.writable_in) <= set(_STATES):
        v.write_restrictions = "_".join(_STATES[s] for s in _STATES if s in spec.writable_in)
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


def _hex(v: int, width: int = 8) -> str:
    return f"#x{v:0{width}X}"


def _flags(parent: ET.Element, v: _EsiVar, category: str | None = None) -> None:
    flags = _sub(parent, "Flags")
    attrs = {"WriteRestrictions": v.write_restrictions} if v.write_restrictions else {}
    _sub(flags, "Access", v.access, **attrs)
    if category:
        _sub(flags, "Category", category)
    if v.pdo:
        _sub(flags, "PdoMapping", v.pdo)
    if v.backup:
        _sub(flags, "Backup", "1")


def _info_values(info: ET.Element, v: _EsiVar) -> None:
    # ETG.2000 ObjectInfoType: MinData, MaxData, DefaultData (or DefaultString).
    if v.default_string is not None:
        _sub(info, "DefaultString", v.default_string)
    if v.min_data is not None:
        _sub(info, "MinData", v.min_data.hex().upper())
    if v.max_data is not None:
        _sub(info, "MaxData", v.max_data.hex().upper())
    if v.default_data is not None:
        _sub(info, "DefaultData", v.default_data.hex().upper())


def _enum_type(types: ET.Element, name: str, v: _EsiVar) -> None:
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

    def var_extras(self, spec: ObjectSpec, v: _EsiVar) -> None:
        baseline = _fields(v, spec.index, "<export>")
        names = diff(spec.model_dump(), baseline, SPEC_FIELDS)
        if names:
            data = json_fields(spec, names)
            el = _sub(
                self.extras,
                f"{{{NS}}}Var",
                dumps(data),
                Index=_hex(spec.index, 4),
                SubIdx=str(spec.subindex),
            )
            el.tail = None

    def type_name_of(self, v: _EsiVar, index: int, sub: int | None) -> str:
        if v.values:
            name = f"DT{index:04X}EN" + (f"{sub:02X}" if sub is not None else "")
            _enum_type(self.types, name, v)
            return name
        self.used_types[v.type_name] = v.bit_size
        return v.type_name


def _export_entry(ex: _Export, entry: ObjectEntry) -> None:
    specs = list(entry.specs())
    obj = _sub(ex.objects, "Object")
    _sub(obj, "Index", _hex(entry.index, 4))
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
        _sub(ex.extras, f"{{{NS}}}Entry", dumps(data), Index=_hex(entry.index, 4))
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
        _EsiVar(
            name="", data_type=DataType.UNSIGNED8, type_name="", bit_size=0, access=vars_[0].access
        ),
        "m" if entry.index == 0x1018 else "o",
    )


def _record_item(
    ex: _Export, dtype: ET.Element, sub: int, v: _EsiVar, type_name: str, offset: int
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
            _sub(pdo, "Index", _hex(e.index, 4))
            _sub(pdo, "Name", e.name)
            for k in range(1, count + 1):
                raw = _int_default(profile, e.index, k) or 0
                idx, sub, bits = raw >> 16, (raw >> 8) & 0xFF, raw & 0xFF
                ent = _sub(pdo, "Entry")
                _sub(ent, "Index", _hex(idx, 4))
                _sub(ent, "SubIndex", str(sub))
                _sub(ent, "BitLen", str(bits))
                target = profile.spec(ObjectAddress(idx, sub)) if idx else None
                if target is not None:
                    _sub(ent, "Name", target.name)
                    _sub(ent, "DataType", _type_of(target.data_type, target.default)[0])


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
    _sub(vendor, "Id", _hex(vendor_id))
    _sub(vendor, "Name", profile.vendor)
    desc = _sub(root, "Descriptions")
    groups = _sub(desc, "Groups")
    group = _sub(groups, "Group")
    _sub(group, "Type", "Drive")
    _sub(group, "Name", "Drives")
    devices = _sub(desc, "Devices")
    device = _sub(devices, "Device", Physics="YY")
    _sub(device, "Type", profile.id, ProductCode=_hex(product), RevisionNo=_hex(revision))
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
            attrs["StartAddress"] = _hex(sm.start_address, 4)
        if sm.control_byte is not None:
            attrs["ControlByte"] = _hex(sm.control_byte, 2)
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
            _sub(om, "AssignActivate", _hex(mode.assign_activate, 4))
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


# --------------------------------------------------------------------------------------------
# Import


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _kids(el: ET.Element | None, name: str) -> Iterator[ET.Element]:
    if el is None:
        return
    for c in el:
        if isinstance(c.tag, str) and _local(c.tag) == name:
            yield c


def _kid(el: ET.Element | None, name: str) -> ET.Element | None:
    return next(_kids(el, name), None)


def _text(el: ET.Element | None, name: str) -> str | None:
    c = _kid(el, name)
    if c is None or c.text is None:
        return None
    return c.text.strip()


def _name(el: ET.Element) -> str:
    """The English name of an element with several ``Name LcId=..`` children."""
    names = list(_kids(el, "Name"))
    for n in names:
        if n.get("LcId") in (None, "1033") and n.text:
            return n.text.strip()
    return (names[0].text or "").strip() if names else ""


def _hexbytes(text: str | None, where: str) -> bytes | None:
    if text is None:
        return None
    t = re.sub(r"\s+", "", text)
    if t.lower().startswith("#x"):
        t = t[2:]
    try:
        return bytes.fromhex(t)
    except ValueError:
        raise ProfileError(
            f"{where}={text!r}: not hex bytes",
            hint="DefaultData/MinData/MaxData hold the value's little-endian bytes in hex",
        ) from None


_DECIMAL = re.compile(r"^[+-]?\d+$")


def _data_or_decimal(v: _EsiVar, key: str, text: str | None, where: str) -> None:
    """``DefaultData``/``MinData``/``MaxData`` (ETG.2000: hex of the little-endian bytes).

    Some vendor tools write a decimal number there instead; text that cannot be hex bytes
    (odd length, a sign) but is a decimal integer is read as the number, with a warning.
    """
    if text is None:
        return
    t = re.sub(r"\s+", "", text)
    bare = t[2:] if t.lower().startswith("#x") else t
    if _DECIMAL.match(t) and (len(bare) % 2 == 1 or t[0] in "+-") and v.data_type.is_numeric:
        warn(f"{where}={text!r}: decimal, not hex bytes (ETG.2000); read as the number {t}")
        setattr(v, f"{key}_value", t)
        return
    setattr(v, f"{key}_data", _hexbytes(text, where))


_BIT_TYPE = re.compile(r"^BIT([2-7])$")


@dataclass
class _Types:
    """The DataTypes of a dictionary, resolved by name."""

    defs: dict[str, ET.Element]

    def basic(
        self, name: str, bit_size: int | None, where: str, depth: int = 0
    ) -> tuple[DataType, dict[int, str] | None]:
        key = name.strip().upper()
        m_bits = _BIT_TYPE.match(key)
        if m_bits:
            # ETG.2000 BIT2..BIT7 have no CiA 301 type; SDO access moves one whole byte.
            warn(f"{where}: {name} ({m_bits.group(1)} bits) read as UNSIGNED8")
            return DataType.UNSIGNED8, None
        if key in _ESI_TYPES:
            return _ESI_TYPES[key], None
        m = _STRING_TYPE.match(key)
        if m:
            kind = m.group(1)
            if kind in ("STRING", "VISIBLE_STRING"):
                return DataType.VISIBLE_STRING, None
            if kind in ("UNICODE_STRING", "WSTRING"):
                return DataType.UNICODE_STRING, None
            return DataType.OCTET_STRING, None
        if _BYTE_ARRAY.match(key):
            return DataType.OCTET_STRING, None
        el = self.defs.get(name.strip())
        if el is not None and depth < 8:
            base = _text(el, "BaseType")
            if _kid(el, "ArrayInfo") is not None:
                # An array used as one value (a sub-item with its own SubIdx): its bytes.
                if self.byte_array(name):
                    return DataType.OCTET_STRING, None
                warn(f"{where}: array type {name!r} kept as one DOMAIN value")
                return DataType.DOMAIN, None
            if any(True for _ in _kids(el, "SubItem")):
                # A structure nested in a structure (ETG.2000 allows it; CiA 301 has no
                # sub-sub-index): the whole nested record is one DOMAIN value.
                warn(f"{where}: nested structure {name!r} kept as one DOMAIN value")
                return DataType.DOMAIN, None
            if base:
                dt, _ = self.basic(base, bit_size, where, depth + 1)
                enums: dict[int, str] = {}
                for ei in _kids(el, "EnumInfo"):
                    enum_text, enum_val = _text(ei, "Text"), _text(ei, "Enum")
                    if enum_val is not None:
                        try:
                            enums[parse_int(enum_val)] = enum_text or ""
                        except ValueError:
                            continue
                return dt, enums or None
        raise ProfileError(
            f"{where}: unknown data type {name!r}",
            hint="use an ETG.2000 base type (BOOL, SINT, INT, DINT, USINT, UINT, UDINT, REAL, "
            "STRING(n), ...) or define it under Dictionary/DataTypes",
        )

    def complex(self, name: str) -> ET.Element | None:
        el = self.defs.get(name.strip())
        if el is not None and any(True for _ in _kids(el, "SubItem")):
            return el
        return None

    def array(self, name: str) -> ET.Element | None:
        el = self.defs.get(name.strip())
        if el is not None and _kid(el, "ArrayInfo") is not None:
            return el
        return None

    def byte_array(self, name: str) -> bool:
        """An array of 8-bit elements (``ARRAY [0..n] OF BYTE``): one octet string."""
        if _BYTE_ARRAY.match(name.strip().upper()):
            return True
        arr = self.array(name)
        if arr is None:
            return False
        base = (_text(arr, "BaseType") or "").strip().upper()
        return _ESI_TYPES.get(base) in (DataType.UNSIGNED8, DataType.INTEGER8)


def _flags_of(el: ET.Element | None, inherit: _EsiVar | None = None) -> dict[str, Any]:
    flags = _kid(el, "Flags")
    out: dict[str, Any] = {}
    if inherit is not None:
        out.update(
            access=inherit.access,
            write_restrictions=inherit.write_restrictions,
            pdo=inherit.pdo,
            backup=inherit.backup,
        )
    if flags is None:
        return out
    acc = _kid(flags, "Access")
    if acc is not None and acc.text:
        out["access"] = acc.text.strip()
        out["write_restrictions"] = acc.get("WriteRestrictions")
    pdo = _text(flags, "PdoMapping")
    if pdo is not None:
        out["pdo"] = pdo
    backup = _text(flags, "Backup")
    if backup is not None:
        out["backup"] = backup.strip() in ("1", "true")
    return out


def _apply_info(v: _EsiVar, info: ET.Element | None, where: str) -> None:
    if info is None:
        return
    ds = _kid(info, "DefaultString")
    v.default_string = (ds.text or "") if ds is not None else None
    for key in ("default", "min", "max"):
        tag = f"{key.capitalize()}Data"
        _data_or_decimal(v, key, _text(info, tag), f"{where} {tag}")
    v.default_value = v.default_value or _text(info, "DefaultValue")
    v.min_value = v.min_value or _text(info, "MinValue")
    v.max_value = v.max_value or _text(info, "MaxValue")
    if v.default_string is not None and not v.data_type.is_string:
        # Some files put a number into DefaultString; read it as the value text.
        v.default_value, v.default_string = v.default_string, None


def _bit_size(el: ET.Element, where: str) -> int:
    raw = _text(el, "BitSize")
    if raw is None:
        return 0
    try:
        return parse_int(raw)
    except ValueError:
        raise ProfileError(
            f"{where}: BitSize {raw!r} is not a number", hint="BitSize is the size in bits, e.g. 16"
        ) from None


def _var(
    types: _Types,
    type_name: str,
    name: str,
    bit_size: int,
    flags: Mapping[str, Any],
    info: ET.Element | None,
    where: str,
) -> _EsiVar:
    dt, enums = types.basic(type_name, bit_size, where)
    v = _EsiVar(name=name, data_type=dt, type_name=type_name, bit_size=bit_size, values=enums)
    for k, val in flags.items():
        setattr(v, k, val)
    if (
        v.pdo
        and dt.is_integer
        and dt is not DataType.BOOLEAN
        and 0 < bit_size < dt.bits
        and not v.data_type.is_string
    ):
        # A bit-sized value (BIT2, an enum of 3 bits): servodesk maps whole CiA 301 types.
        warn(f"{where}: {bit_size}-bit value of type {type_name!r} is not PDO-mappable here")
        v.pdo = None
    _apply_info(v, info, where)
    return v


def _octets(bits: int) -> str:
    """The type name of a byte array kept as one OCTET_STRING value (not a sub per byte)."""
    return f"OCTET_STRING({max(bits // 8, 1)})"


def _read_object(
    types: _Types, el: ET.Element, where_file: str
) -> tuple[ParsedObject, dict[int, _EsiVar]]:
    raw_index = _text(el, "Index")
    if raw_index is None:
        raise ProfileError(
            f"{where_file}: an Object has no Index",
            hint="every Dictionary/Objects/Object needs <Index>#x6040</Index>",
        )
    try:
        index = parse_int(raw_index)
    except ValueError:
        raise ProfileError(
            f"{where_file}: Object Index {raw_index!r} is not a number",
            hint="write the index as #x6040",
        ) from None
    where = f"{where_file}: Object {_hex(index, 4)}"
    if not 0 <= index <= 0xFFFF:
        raise ProfileError(f"{where}: index outside 0..0xFFFF", hint="check the Index element")
    name = _name(el)
    type_name = _text(el, "Type")
    if type_name is None:
        raise ProfileError(
            f"{where} ({name}): no Type", hint="every Object needs <Type> (e.g. UINT or DT1018)"
        )
    info = _kid(el, "Info")
    obj_flags = _flags_of(el)
    cplx = types.complex(type_name)
    arr_type = types.array(type_name) if cplx is None else None
    if cplx is None and (arr_type is None or types.byte_array(type_name)):
        # A VAR; an object whose type is ARRAY [0..n] OF BYTE is one octet string.
        if arr_type is not None:
            type_name = _octets(_bit_size(arr_type, where))
        v = _var(types, type_name, name, _bit_size(el, where), obj_flags, info, where)
        return ParsedObject(index=index, object_type=ObjectType.VAR, where=where), {0: v}
    info_items = list(_kids(info, "SubItem"))
    items: list[tuple[int, str, str, int, dict[str, Any]]] = []  # sub, name, type, bits, flags
    is_array = False
    # A sub-item without its own Flags has the object's access (ETG.2000 ObjectType/Flags).
    inherit = _EsiVar(
        name="",
        data_type=DataType.UNSIGNED8,
        type_name="",
        bit_size=0,
        access=obj_flags.get("access", "ro"),
    )
    dt_items = list(_kids(cplx, "SubItem")) if cplx is not None else []
    if cplx is None:  # The object's type is itself an array type: elements only.
        assert arr_type is not None
        lb, n = _array_info(arr_type, where)
        base = _text(arr_type, "BaseType") or "USINT"
        bits = _bit_size(arr_type, where) // max(n, 1)
        if lb + n - 1 > 0xFF:
            warn(f"{where}: {n} array elements do not fit sub-indices 1..255; kept as one DOMAIN")
            v = _var(types, "DOMAIN", name, 0, obj_flags, info, where)
            return ParsedObject(index=index, object_type=ObjectType.VAR, where=where), {0: v}
        items.extend((lb + k, f"{name} {lb + k}", base, bits, _flags_of(el)) for k in range(n))
        is_array = True
    next_sub = 0
    for it in dt_items:
        it_type = _text(it, "Type") or ""
        it_name = _name(it)
        arr = types.array(it_type)
        flags = _flags_of(it, inherit)
        raw_sub = _text(it, "SubIdx")
        if arr is not None and raw_sub is None:
            # ETG.2000 ARRAY object: sub 0 then a SubItem "Elements" of an array type whose
            # elements are sub-indices LBound.. (one sub-index each, CiA 301 §7.4.3).
            lb, n = _array_info(arr, where)
            base = _text(arr, "BaseType") or "USINT"
            start = max(lb, next_sub, 1)
            if start + n - 1 > 0xFF:
                # ARRAY [0..511] OF BYTE and the like: more elements than sub-indices exist.
                kind = "OCTET_STRING" if types.byte_array(it_type) else "DOMAIN"
                warn(
                    f"{where}: {n} elements of {it_type!r} do not fit sub-indices "
                    f"{start}..255; kept as one {kind} sub-index {start}"
                )
                dt_name = _octets(_bit_size(arr, where)) if kind == "OCTET_STRING" else "DOMAIN"
                items.append((start, it_name or name, dt_name, 0, flags))
                next_sub = start + 1
                continue
            is_array = True
            bits = _bit_size(arr, where) // max(n, 1)
            items.extend((start + k, f"{name} {start + k}", base, bits, flags) for k in range(n))
            next_sub = start + n
            continue
        try:
            sub = parse_int(raw_sub) if raw_sub is not None else next_sub
        except ValueError:
            raise ProfileError(
                f"{where}: SubIdx {raw_sub!r} is not a number",
                hint="SubIdx is the sub-index, e.g. 1",
            ) from None
        if not 0 <= sub <= 0xFF:
            warn(f"{where}: SubIdx {sub} outside 0..255 skipped")
            next_sub = sub + 1
            continue
        if arr is not None and types.byte_array(it_type):
            # A sub-item with its own SubIdx whose type is a byte array: one value, its bytes.
            it_type = _octets(_bit_size(arr, where))
        items.append((sub, it_name, it_type, _bit_size(it, where), flags))
        next_sub = sub + 1
    # Object/Info/SubItem carry names and values; match by name, else by position.
    matched: dict[int, ET.Element] = {}
    unused = list(info_items)
    if not is_array:
        for pos, (sub, it_name, *_rest) in enumerate(items):
            hit = next((x for x in unused if _name(x) == it_name), None)
            if hit is None and pos < len(info_items) and info_items[pos] in unused:
                hit = info_items[pos]
            if hit is not None:
                matched[sub] = hit
                unused.remove(hit)
    else:
        for pos, (sub, *_rest) in enumerate(items):
            if pos < len(info_items):
                matched[sub] = info_items[pos]
    vars_: dict[int, _EsiVar] = {}
    for sub, it_name, it_type, bits, flags in items:
        hit = matched.get(sub)
        sub_name = _name(hit) if hit is not None and _name(hit) else it_name
        vars_[sub] = _var(
            types,
            it_type,
            sub_name,
            bits,
            flags,
            _kid(hit, "Info") if hit is not None else None,
            f"{where} sub {sub}",
        )
    otype = ObjectType.ARRAY if is_array else ObjectType.RECORD
    obj = ParsedObject(index=index, object_type=otype, where=where)
    obj.entry = {n: entry_default(n) for n in ENTRY_FIELDS}
    obj.entry["name"] = name
    return obj, vars_


def _array_info(arr: ET.Element, where: str) -> tuple[int, int]:
    ai = _kid(arr, "ArrayInfo")
    try:
        lb = parse_int(_text(ai, "LBound") or "1")
        n = parse_int(_text(ai, "Elements") or "0")
    except ValueError:
        raise ProfileError(
            f"{where}: ArrayInfo LBound/Elements are not numbers",
            hint="write <LBound>1</LBound><Elements>8</Elements>",
        ) from None
    return lb, n


_BITS_TYPES: dict[int, DataType] = {
    1: DataType.BOOLEAN,
    8: DataType.UNSIGNED8,
    16: DataType.UNSIGNED16,
    32: DataType.UNSIGNED32,
    64: DataType.UNSIGNED64,
}


def _entry_type(ent: ET.Element, bits: int, where: str) -> DataType:
    """The data type of a PDO entry the dictionary does not describe."""
    dt_name = _text(ent, "DataType") or ""
    with collecting():  # The guess below is reported once, by the caller.
        try:
            dt, _ = _Types({}).basic(dt_name, bits, where)
            if (dt.is_numeric and dt.bits == bits) or (dt is DataType.BOOLEAN and bits == 1):
                return dt
        except ProfileError:
            pass
    return _BITS_TYPES.get(bits, DataType.OCTET_STRING if bits % 8 == 0 else DataType.DOMAIN)


def _pdo_index(pdo: ET.Element, tag: str, where: str) -> int:
    try:
        return parse_int(_text(pdo, "Index") or "")
    except ValueError:
        raise ProfileError(
            f"{where}: a {tag} has no valid Index", hint="write <Index>#x1600</Index>"
        ) from None


def _pdo_objects(
    device: ET.Element, known: set[int], have: set[tuple[int, int]], where: str
) -> list[ParsedObject]:
    """Mapping objects and mapped variables from RxPdo/TxPdo when the dictionary lacks them."""
    out: list[ParsedObject] = []
    base = {n: spec_default(n) for n in SPEC_FIELDS}
    # Variables the PDO entries name, by index: sub -> fields.
    made: dict[int, dict[int, dict[str, Any]]] = {}
    pdo_indices = {
        _pdo_index(pdo, tag, where) for tag in ("RxPdo", "TxPdo") for pdo in _kids(device, tag)
    }
    for tag, direction in (("RxPdo", PdoMapping.RX), ("TxPdo", PdoMapping.TX)):
        for pdo in _kids(device, tag):
            pidx = _pdo_index(pdo, tag, where)
            entries = list(_kids(pdo, "Entry"))
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
                    idx = parse_int(_text(ent, "Index") or "0")
                    sub = parse_int(_text(ent, "SubIndex") or "0")
                    bits = parse_int(_text(ent, "BitLen") or "0")
                except ValueError:
                    raise ProfileError(
                        f"{where}: {tag} {_hex(pidx, 4)} entry {k}: Index, "
                        "SubIndex or BitLen is not a number",
                        hint="write numbers as #x6040 or decimal",
                    ) from None
                if k > 0xFF or not (0 <= idx <= 0xFFFF and 0 <= sub <= 0xFF and bits <= 0xFF):
                    warn(f"{where}: {tag} {_hex(pidx, 4)} entry {k} out of range, skipped")
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
                    "name": _name(ent) or f"Object {idx:04X}:{sub:02X}",
                    "data_type": dt,
                    # ETG.2000 leaves SDO access of such entries open; RxPDO data is written.
                    "access": Access.RWW if direction is PdoMapping.RX else Access.RO,
                    "pdo_mapping": direction if pdo_ok else PdoMapping.NONE,
                    "process": True,
                    "group": area_group(idx),
                }
                if not pdo_ok:
                    warn(
                        f"{where}: {tag} {_hex(pidx, 4)} entry {_hex(idx, 4)}:{sub}: "
                        f"{bits} bits is no CiA 301 type; described, not PDO-mappable here"
                    )
            if pidx not in known:
                obj = ParsedObject(index=pidx, object_type=ObjectType.RECORD, where=where)
                obj.entry = {n: entry_default(n) for n in ENTRY_FIELDS}
                obj.entry["name"] = _name(pdo) or f"PDO {pidx:04X}"
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


def _mapped_entries(device: ET.Element) -> dict[str, set[tuple[int, int]]]:
    """The (index, sub) the device's RxPdo / TxPdo entries map, per direction."""
    out: dict[str, set[tuple[int, int]]] = {"rx": set(), "tx": set()}
    for tag, key in (("RxPdo", "rx"), ("TxPdo", "tx")):
        for pdo in _kids(device, tag):
            for ent in _kids(pdo, "Entry"):
                try:
                    idx = parse_int(_text(ent, "Index") or "0")
                    sub = parse_int(_text(ent, "SubIndex") or "0")
                except ValueError:
                    continue
                out[key].add((idx, sub))
    return out


def _direction_from_pdos(
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


def _parse_root(text: str, source: str) -> ET.Element:
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        line, col = exc.position
        raise ProfileError(
            f"not well-formed XML (line {line}, column {col}): {exc}",
            path=source,
            hint="an ESI file is XML starting with <EtherCATInfo>; is the file complete?",
        ) from None
    if _local(root.tag) not in ("EtherCATInfo", "EtherCATModule"):
        raise ProfileError(
            f"the root element is <{_local(root.tag)}>, not <EtherCATInfo>",
            path=source,
            hint="this is not an ESI (ETG.2000) file; XDD files end in .xdd",
        )
    return root


@dataclass(frozen=True)
class EsiDevice:
    """One device (or, in an ``EtherCATModule`` file, one module) an ESI file describes."""

    number: int
    name: str
    product_code: int | None
    revision: int | None


def _code(el: ET.Element | None, attr: str, source: str) -> int | None:
    raw = el.get(attr) if el is not None else None
    if not raw:
        return None
    try:
        return parse_int(raw)
    except ValueError:
        raise ProfileError(
            f"Device Type {attr} {raw!r} is not a number",
            path=source,
            hint="write it as #x00000001",
        ) from None


def _devices(root: ET.Element) -> list[ET.Element]:
    if _local(root.tag) == "EtherCATModule":
        return list(_kids(_kid(root, "Modules"), "Module"))
    return list(_kids(_kid(_kid(root, "Descriptions"), "Devices"), "Device"))


def esi_devices(text: str, *, source: str = "<esi>") -> list[EsiDevice]:
    """The devices of an ESI file, numbered from 1 (for ``--device N``)."""
    root = _parse_root(text, source)
    out = []
    for n, d in enumerate(_devices(root), start=1):
        t = _kid(d, "Type")
        out.append(
            EsiDevice(
                number=n,
                name=_name(d) or ((t.text or "").strip() if t is not None else ""),
                product_code=_code(t, "ProductCode", source),
                revision=_code(t, "RevisionNo", source),
            )
        )
    return out


def _sync_managers(device: ET.Element) -> list[dict[str, Any]]:
    """``Sm`` elements (ETG.2000 DeviceType/Sm): number by order, kind from the text."""
    out: list[dict[str, Any]] = []
    for n, sm in enumerate(_kids(device, "Sm")):
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
    for om in _kids(_kid(device, "Dc"), "OpMode"):
        name = _text(om, "Name") or ""
        try:
            mode: dict[str, Any] = {
                "name": name,
                "description": _text(om, "Desc"),
                "assign_activate": parse_int(_text(om, "AssignActivate") or "0"),
            }
            for tag, key, factor_key in (
                ("CycleTimeSync0", "cycle_time_sync0", "cycle_factor_sync0"),
                ("ShiftTimeSync0", "shift_time_sync0", None),
                ("CycleTimeSync1", "cycle_time_sync1", "cycle_factor_sync1"),
            ):
                el = _kid(om, tag)
                if el is not None and el.text and el.text.strip():
                    mode[key] = parse_int(el.text)
                    if factor_key and el.get("Factor"):
                        mode[factor_key] = parse_int(el.get("Factor") or "")
        except ValueError:
            warn(f"Dc/OpMode {name!r}: a value is not a number; mode skipped")
            continue
        out.append(mode)
    return out


def _pdo_rules(device: ET.Element, source: str) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The PDO section of an EtherCAT profile, and the default-assignment template (or None).

    ETG.2000 RxPdo/TxPdo: ``Fixed`` (the content cannot change), ``Sm`` (assigned to that
    sync manager by default, i.e. listed in 1C12h/1C13h), ``Mandatory``.
    """
    counts = {"rx": 0, "tx": 0}
    most_entries, most_bits, all_fixed = 8, 64, True
    pdos: list[dict[str, Any]] = []
    assignment: dict[str, list[int]] = {"rx": [], "tx": []}
    for tag, direction, lo in (("RxPdo", "rx", 0x1600), ("TxPdo", "tx", 0x1A00)):
        for pos, pdo in enumerate(_kids(device, tag), start=1):
            pidx = _pdo_index(pdo, tag, source)
            number = pidx - lo + 1 if lo <= pidx < lo + 0x200 else pos
            counts[direction] = max(counts[direction], number)
            entries = list(_kids(pdo, "Entry"))
            most_entries = max(most_entries, len(entries))
            bits = 0
            words: list[str] = []
            for ent in entries:
                try:
                    idx = parse_int(_text(ent, "Index") or "0")
                    sub = parse_int(_text(ent, "SubIndex") or "0")
                    n = parse_int(_text(ent, "BitLen") or "0")
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


def _template_ok(profile: DeviceProfile, template: Mapping[str, Any]) -> str | None:
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


def _pick_device(
    devices: list[ET.Element],
    device: int | None,
    product_code: int | None,
    source: str,
) -> tuple[int, ET.Element]:
    if device is not None:
        if not 1 <= device <= len(devices):
            raise ProfileError(
                f"no device {device}: the file describes {len(devices)}",
                path=source,
                hint=f"choose --device 1..{len(devices)} "
                "(servodesk profiles --import FILE --list-devices lists them)",
            )
        return device, devices[device - 1]
    if product_code is not None:
        for n, d in enumerate(devices, start=1):
            if _code(_kid(d, "Type"), "ProductCode", source) == product_code:
                return n, d
        raise ProfileError(
            f"no device with product code {_hex(product_code)}",
            path=source,
            hint="leave the product code out to import the first device",
        )
    return 1, devices[0]


def _is_true(text: str | None) -> bool:
    return (text or "").strip().lower() in ("1", "true")


def _shift_slot(pdo: ET.Element, pdo_offset: int, index_offset: int) -> None:
    """Move the ``DependOnSlot`` indices of a module's PDO to its slot (ETG.2000 Slots:
    SlotPdoIncrement for the PDO's index, SlotIndexIncrement for the objects it maps)."""
    for el, offset in [(_kid(pdo, "Index"), pdo_offset)] + [
        (_kid(ent, "Index"), index_offset) for ent in _kids(pdo, "Entry")
    ]:
        if el is None or not _is_true(el.get("DependOnSlot")) or not el.text:
            continue
        try:
            el.text = _hex(parse_int(el.text) + offset, 4)
        except ValueError:
            continue  # Reported where the entry is read.


def _with_default_modules(device: ET.Element, shared: ET.Element | None) -> ET.Element:
    """The device as delivered: each slot's default module (``ModuleIdent Default="1"``)
    adds its PDOs and dictionary objects, moved to the slot (slot n: n x the increments).
    The device element itself is left as parsed; a copy is returned when a slot adds any."""
    slots = _kid(device, "Slots")
    if slots is None:
        return device
    modules: dict[int, ET.Element] = {}
    for m in [*_kids(_kid(device, "Modules"), "Module"), *_kids(shared, "Module")]:
        t = _kid(m, "Type")
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
    for n, slot in enumerate(_kids(slots, "Slot")):
        default = next((m for m in _kids(slot, "ModuleIdent") if _is_true(m.get("Default"))), None)
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
            for pdo in _kids(module, tag):
                moved = copy.deepcopy(pdo)
                _shift_slot(moved, n * pdo_inc, n * idx_inc)
                out.append(moved)
        mdict = next(
            (d for d in (_kid(p, "Dictionary") for p in _kids(module, "Profile")) if d is not None),
            None,
        )
        if mdict is not None and any(True for _ in _kids(_kid(mdict, "Objects"), "Object")):
            warn(
                f"slot {n + 1}: the dictionary objects of module {_text(module, 'Type')!r} "
                "are not imported (only its PDOs)"
            )
        placed.append(f"slot {n + 1}: {_text(module, 'Type') or default.text.strip()}")
    if placed:
        warn("default modules imported with their PDOs: " + "; ".join(placed))
    return out if out is not None else device


def _slot_notes(device: ET.Element, shared: ET.Element | None) -> None:
    """Modules and slots (ETG.2000 Modules/Slots): reported, their objects not imported.

    Modules are listed in the device or, shared by all devices, in Descriptions/Modules.
    """
    slots = list(_kids(_kid(device, "Slots"), "Slot"))
    modules = list(_kids(_kid(device, "Modules"), "Module"))
    if slots and not modules:
        modules = list(_kids(shared, "Module"))
    if modules or slots:
        names = ", ".join(_text(m, "Type") or "?" for m in modules[:8])
        more = f" and {len(modules) - 8} more" if len(modules) > 8 else ""
        warn(
            f"{len(modules)} module(s) ({names}{more}) and {len(slots)} slot(s): the device's "
            "own objects and PDOs and the slots' default modules are imported, no other module"
        )


def import_esi(
    text: str,
    *,
    profile_id: str | None = None,
    product_code: int | None = None,
    device: int | None = None,
    source: str = "<esi>",
) -> DeviceProfile:
    """A profile from an ESI file: the first device, device number ``device`` (from 1), or
    the one with ``product_code``. Whatever is not imported is reported with
    :func:`~servodesk.devdesc._common.warn`."""
    root = _parse_root(text, source)
    is_module_file = _local(root.tag) == "EtherCATModule"
    vendor = _kid(root, "Vendor")
    std: dict[str, Any] = {"fieldbus": "ethercat"}
    ident: dict[str, Any] = {}
    if vendor is not None:
        vid = _text(vendor, "Id")
        if vid:
            try:
                ident["vendor_id"] = parse_int(vid)
            except ValueError:
                raise ProfileError(
                    f"Vendor/Id {vid!r} is not a number",
                    path=source,
                    hint="write the vendor id as #x0000015A or decimal",
                ) from None
        vname = _name(vendor)
        if vname:
            std["vendor"] = vname
    devices = _devices(root)
    if not devices:
        raise ProfileError(
            "no Descriptions/Devices/Device element",
            path=source,
            hint="the ESI must describe at least one device",
        )
    number, dev = _pick_device(devices, device, product_code, source)
    t = _kid(dev, "Type")
    code = _code(t, "ProductCode", source)
    revision = _code(t, "RevisionNo", source)
    if is_module_file:
        # A module (ETG.2000 EtherCATModule) is part of a modular slave, never a slave: no
        # identity, so detection never picks it for a device on the line.
        ident = {}
        warn(
            f"an EtherCATModule file: imported module {number} of {len(devices)}; a module is "
            "part of a modular slave, so the profile has no identity"
        )
    elif code is not None:
        ident["product_codes"] = [code]
        same_code = [d for d in devices if _code(_kid(d, "Type"), "ProductCode", source) == code]
        if len(same_code) > 1 and revision is not None:
            # Several revisions of one product: detection tells them apart by revision.
            ident["revision_min"] = ident["revision_max"] = revision
    if ident:
        std["identity"] = ident
    dev_name = _name(dev) or ((t.text or "").strip() if t is not None else "")
    if dev_name:
        std["name"] = dev_name
    others = sorted(
        {
            (n.text or "").strip()
            for n in _kids(dev, "Name")
            if n.get("LcId") not in (None, "1033") and n.text and n.text.strip() != dev_name
        }
    )
    what = "module" if is_module_file else "device"
    desc = f"Imported from {source.rsplit('/', 1)[-1]}, {what} {number} of {len(devices)}"
    if code is not None:
        desc += f" (product code {_hex(code)}"
        desc += f", revision {_hex(revision)})" if revision is not None else ")"
    if others:
        desc += ". Other names: " + "; ".join(others)
    std["description"] = desc + "."
    if not is_module_file:
        shared_modules = _kid(_kid(root, "Descriptions"), "Modules")
        _slot_notes(dev, shared_modules)
        dev = _with_default_modules(dev, shared_modules)
    dictionary = None
    for prof in _kids(dev, "Profile"):
        dictionary = _kid(prof, "Dictionary")
        if dictionary is not None:
            break
    types = _Types({_name(d): d for d in _kids(_kid(dictionary, "DataTypes"), "DataType")})
    parsed: list[ParsedObject] = []
    esi_vars: dict[int, dict[int, _EsiVar]] = {}
    mapped = _mapped_entries(dev)
    for el in _kids(_kid(dictionary, "Objects"), "Object"):
        obj, vars_ = _read_object(types, el, source)
        for sub, v in vars_.items():
            obj.subs[sub] = _fields(v, obj.index, f"{obj.where} sub {sub}")
            _direction_from_pdos(obj.subs[sub], (obj.index, sub), mapped, obj.where)
        parsed.append(obj)
        esi_vars[obj.index] = vars_
    # servodesk's own extras (only in files servodesk wrote).
    meta: dict[str, Any] | None = None
    sd = None
    for vs in _kids(dev, "VendorSpecific"):
        sd = _kid(vs, "Servodesk")
        if sd is not None:
            break
    if sd is not None:
        prof_el = _kid(sd, "Profile")
        if prof_el is not None and prof_el.text:
            m = loads(prof_el.text, "VendorSpecific/Servodesk/Profile")
            meta = m if isinstance(m, dict) else None
        by_index = {o.index: o for o in parsed}
        for el in sd:
            kind = _local(el.tag) if isinstance(el.tag, str) else ""
            if kind not in ("Var", "Entry") or not el.text:
                continue
            try:
                idx = parse_int(el.get("Index") or "")
                sub = parse_int(el.get("SubIdx") or "0")
            except ValueError:
                continue
            o = by_index.get(idx)
            data = loads(el.text, f"VendorSpecific/Servodesk/{kind} {_hex(idx, 4)}")
            if o is None or not isinstance(data, dict):
                continue
            if kind == "Var" and sub in o.subs:
                o.subs[sub].update({k: v for k, v in data.items() if k in SPEC_FIELDS})
            elif kind == "Entry":
                if "object_type" in data:
                    try:
                        o.object_type = ObjectType(data["object_type"])
                    except ValueError:
                        raise ProfileError(
                            f"VendorSpecific/Servodesk/Entry {_hex(idx, 4)}: object_type "
                            f"{data['object_type']!r} is not var, array or record",
                            path=source,
                            hint="remove the Servodesk element to drop the extras",
                        ) from None
                o.entry.update({k: v for k, v in data.items() if k in ENTRY_FIELDS})
    known = {o.index for o in parsed}
    have = {(o.index, s) for o in parsed for s in o.subs}
    parsed.extend(_pdo_objects(dev, known, have, source))
    if not parsed:
        # An I/O coupler (Beckhoff EK1100) has no mailbox, no dictionary and no process data
        # of its own: the profile is its identity only.
        warn(
            f"{what} {dev_name or number} has neither a Profile/Dictionary nor RxPdo/TxPdo: "
            "the profile holds its identity only"
        )
    parsed.sort(key=lambda o: o.index)
    objects = [build_entry(o) for o in parsed]
    template = None
    if meta is None:
        std["pdo"], template = _pdo_rules(dev, source)
    pid = profile_id or slug(std.get("name") or "imported")
    if meta is not None:
        std.pop("identity", None)
        std.pop("fieldbus", None)
        std.pop("description", None)
    profile = make_profile(profile_id=pid, meta=meta, standard=std, objects=objects, where=source)
    if template is not None:
        why = _template_ok(profile, template)
        if why is None:
            rules = {**std["pdo"], "templates": [template]}
            profile = make_profile(
                profile_id=pid,
                meta=meta,
                standard={**std, "pdo": rules},
                objects=objects,
                where=source,
            )
        else:
            warn(f"the default PDO assignment is not offered as a template: {why}")
    return profile
