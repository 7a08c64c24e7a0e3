"""ESI XML (EtherCAT Slave Information, ETG.2000) to a servodesk profile.

Import reads real vendor files: any namespace, ``#x`` hex, ``BitSize``, RECORD and ARRAY types
built from ``DataTypes``/``SubItem``/``ArrayInfo`` (byte arrays and arrays longer than 255
elements as one octet string, nested structures as DOMAIN), enumerations (``EnumInfo``),
values as ``DefaultData`` or ``DefaultValue``; an ESI without a dictionary gets its objects
from the PDO entries. One of several devices is picked (``device=``), each slot's default
module is placed (``Slots``), and the profile is an EtherCAT one: PDO kind ``ethercat``, the
``Sm`` sync managers, the ``Dc/OpMode`` modes, the default assignment as a template (the PDO,
sync-manager, DC and module part is :mod:`servodesk.devdesc.esi_pdo`). What the model cannot
hold is reported with :func:`~servodesk.devdesc._common.warn`, not refused. servodesk's own
extras in ``VendorSpecific`` (written by :mod:`servodesk.devdesc.esi_export`) are read back.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    SPEC_FIELDS,
    ParsedObject,
    build_entry,
    entry_default,
    loads,
    make_profile,
    parse_int,
    slug,
    warn,
)
from servodesk.devdesc.esi_common import (
    EsiTypes,
    EsiVar,
    english_name,
    esi_hex,
    kid,
    kid_text,
    kids,
    local_name,
    spec_fields,
)
from servodesk.devdesc.esi_pdo import (
    direction_from_pdos,
    mapped_entries,
    pdo_objects,
    pdo_rules,
    slot_notes,
    template_ok,
    with_default_modules,
)
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import DeviceProfile, ObjectType
from servodesk.errors import ProfileError

__all__ = ["EsiDevice", "esi_devices", "import_esi"]


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


def _data_or_decimal(v: EsiVar, key: str, text: str | None, where: str) -> None:
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


def _flags_of(el: ET.Element | None, inherit: EsiVar | None = None) -> dict[str, Any]:
    flags = kid(el, "Flags")
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
    acc = kid(flags, "Access")
    if acc is not None and acc.text:
        out["access"] = acc.text.strip()
        out["write_restrictions"] = acc.get("WriteRestrictions")
    pdo = kid_text(flags, "PdoMapping")
    if pdo is not None:
        out["pdo"] = pdo
    backup = kid_text(flags, "Backup")
    if backup is not None:
        out["backup"] = backup.strip() in ("1", "true")
    return out


def _apply_info(v: EsiVar, info: ET.Element | None, where: str) -> None:
    if info is None:
        return
    ds = kid(info, "DefaultString")
    v.default_string = (ds.text or "") if ds is not None else None
    for key in ("default", "min", "max"):
        tag = f"{key.capitalize()}Data"
        _data_or_decimal(v, key, kid_text(info, tag), f"{where} {tag}")
    v.default_value = v.default_value or kid_text(info, "DefaultValue")
    v.min_value = v.min_value or kid_text(info, "MinValue")
    v.max_value = v.max_value or kid_text(info, "MaxValue")
    if v.default_string is not None and not v.data_type.is_string:
        # Some files put a number into DefaultString; read it as the value text.
        v.default_value, v.default_string = v.default_string, None


def _bit_size(el: ET.Element, where: str) -> int:
    raw = kid_text(el, "BitSize")
    if raw is None:
        return 0
    try:
        return parse_int(raw)
    except ValueError:
        raise ProfileError(
            f"{where}: BitSize {raw!r} is not a number", hint="BitSize is the size in bits, e.g. 16"
        ) from None


def _var(
    types: EsiTypes,
    type_name: str,
    name: str,
    bit_size: int,
    flags: Mapping[str, Any],
    info: ET.Element | None,
    where: str,
) -> EsiVar:
    dt, enums = types.basic(type_name, bit_size, where)
    v = EsiVar(name=name, data_type=dt, type_name=type_name, bit_size=bit_size, values=enums)
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
    types: EsiTypes, el: ET.Element, where_file: str
) -> tuple[ParsedObject, dict[int, EsiVar]]:
    raw_index = kid_text(el, "Index")
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
    where = f"{where_file}: Object {esi_hex(index, 4)}"
    if not 0 <= index <= 0xFFFF:
        raise ProfileError(f"{where}: index outside 0..0xFFFF", hint="check the Index element")
    name = english_name(el)
    type_name = kid_text(el, "Type")
    if type_name is None:
        raise ProfileError(
            f"{where} ({name}): no Type", hint="every Object needs <Type> (e.g. UINT or DT1018)"
        )
    info = kid(el, "Info")
    obj_flags = _flags_of(el)
    cplx = types.complex(type_name)
    arr_type = types.array(type_name) if cplx is None else None
    if cplx is None and (arr_type is None or types.byte_array(type_name)):
        # A VAR; an object whose type is ARRAY [0..n] OF BYTE is one octet string.
        if arr_type is not None:
            type_name = _octets(_bit_size(arr_type, where))
        v = _var(types, type_name, name, _bit_size(el, where), obj_flags, info, where)
        return ParsedObject(index=index, object_type=ObjectType.VAR, where=where), {0: v}
    info_items = list(kids(info, "SubItem"))
    items: list[tuple[int, str, str, int, dict[str, Any]]] = []  # sub, name, type, bits, flags
    is_array = False
    # A sub-item without its own Flags has the object's access (ETG.2000 ObjectType/Flags).
    inherit = EsiVar(
        name="",
        data_type=DataType.UNSIGNED8,
        type_name="",
        bit_size=0,
        access=obj_flags.get("access", "ro"),
    )
    dt_items = list(kids(cplx, "SubItem")) if cplx is not None else []
    if cplx is None:  # The object's type is itself an array type: elements only.
        assert arr_type is not None
        lb, n = _array_info(arr_type, where)
        base = kid_text(arr_type, "BaseType") or "USINT"
        bits = _bit_size(arr_type, where) // max(n, 1)
        if lb + n - 1 > 0xFF:
            warn(f"{where}: {n} array elements do not fit sub-indices 1..255; kept as one DOMAIN")
            v = _var(types, "DOMAIN", name, 0, obj_flags, info, where)
            return ParsedObject(index=index, object_type=ObjectType.VAR, where=where), {0: v}
        items.extend((lb + k, f"{name} {lb + k}", base, bits, _flags_of(el)) for k in range(n))
        is_array = True
    next_sub = 0
    for it in dt_items:
        it_type = kid_text(it, "Type") or ""
        it_name = english_name(it)
        arr = types.array(it_type)
        flags = _flags_of(it, inherit)
        raw_sub = kid_text(it, "SubIdx")
        if arr is not None and raw_sub is None:
            # ETG.2000 ARRAY object: sub 0 then a SubItem "Elements" of an array type whose
            # elements are sub-indices LBound.. (one sub-index each, CiA 301 §7.4.3).
            lb, n = _array_info(arr, where)
            base = kid_text(arr, "BaseType") or "USINT"
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
            hit = next((x for x in unused if english_name(x) == it_name), None)
            if hit is None and pos < len(info_items) and info_items[pos] in unused:
                hit = info_items[pos]
            if hit is not None:
                matched[sub] = hit
                unused.remove(hit)
    else:
        for pos, (sub, *_rest) in enumerate(items):
            if pos < len(info_items):
                matched[sub] = info_items[pos]
    vars_: dict[int, EsiVar] = {}
    for sub, it_name, it_type, bits, flags in items:
        hit = matched.get(sub)
        sub_name = english_name(hit) if hit is not None and english_name(hit) else it_name
        vars_[sub] = _var(
            types,
            it_type,
            sub_name,
            bits,
            flags,
            kid(hit, "Info") if hit is not None else None,
            f"{where} sub {sub}",
        )
    otype = ObjectType.ARRAY if is_array else ObjectType.RECORD
    obj = ParsedObject(index=index, object_type=otype, where=where)
    obj.entry = {n: entry_default(n) for n in ENTRY_FIELDS}
    obj.entry["name"] = name
    return obj, vars_


def _array_info(arr: ET.Element, where: str) -> tuple[int, int]:
    ai = kid(arr, "ArrayInfo")
    try:
        lb = parse_int(kid_text(ai, "LBound") or "1")
        n = parse_int(kid_text(ai, "Elements") or "0")
    except ValueError:
        raise ProfileError(
            f"{where}: ArrayInfo LBound/Elements are not numbers",
            hint="write <LBound>1</LBound><Elements>8</Elements>",
        ) from None
    return lb, n


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
    if local_name(root.tag) not in ("EtherCATInfo", "EtherCATModule"):
        raise ProfileError(
            f"the root element is <{local_name(root.tag)}>, not <EtherCATInfo>",
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
    if local_name(root.tag) == "EtherCATModule":
        return list(kids(kid(root, "Modules"), "Module"))
    return list(kids(kid(kid(root, "Descriptions"), "Devices"), "Device"))


def esi_devices(text: str, *, source: str = "<esi>") -> list[EsiDevice]:
    """The devices of an ESI file, numbered from 1 (for ``--device N``)."""
    root = _parse_root(text, source)
    out = []
    for n, d in enumerate(_devices(root), start=1):
        t = kid(d, "Type")
        out.append(
            EsiDevice(
                number=n,
                name=english_name(d) or ((t.text or "").strip() if t is not None else ""),
                product_code=_code(t, "ProductCode", source),
                revision=_code(t, "RevisionNo", source),
            )
        )
    return out


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
            if _code(kid(d, "Type"), "ProductCode", source) == product_code:
                return n, d
        raise ProfileError(
            f"no device with product code {esi_hex(product_code)}",
            path=source,
            hint="leave the product code out to import the first device",
        )
    return 1, devices[0]


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
    is_module_file = local_name(root.tag) == "EtherCATModule"
    vendor = kid(root, "Vendor")
    std: dict[str, Any] = {"fieldbus": "ethercat"}
    ident: dict[str, Any] = {}
    if vendor is not None:
        vid = kid_text(vendor, "Id")
        if vid:
            try:
                ident["vendor_id"] = parse_int(vid)
            except ValueError:
                raise ProfileError(
                    f"Vendor/Id {vid!r} is not a number",
                    path=source,
                    hint="write the vendor id as #x0000015A or decimal",
                ) from None
        vname = english_name(vendor)
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
    t = kid(dev, "Type")
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
        same_code = [d for d in devices if _code(kid(d, "Type"), "ProductCode", source) == code]
        if len(same_code) > 1 and revision is not None:
            # Several revisions of one product: detection tells them apart by revision.
            ident["revision_min"] = ident["revision_max"] = revision
    if ident:
        std["identity"] = ident
    dev_name = english_name(dev) or ((t.text or "").strip() if t is not None else "")
    if dev_name:
        std["name"] = dev_name
    others = sorted(
        {
            (n.text or "").strip()
            for n in kids(dev, "Name")
            if n.get("LcId") not in (None, "1033") and n.text and n.text.strip() != dev_name
        }
    )
    what = "module" if is_module_file else "device"
    desc = f"Imported from {source.rsplit('/', 1)[-1]}, {what} {number} of {len(devices)}"
    if code is not None:
        desc += f" (product code {esi_hex(code)}"
        desc += f", revision {esi_hex(revision)})" if revision is not None else ")"
    if others:
        desc += ". Other names: " + "; ".join(others)
    std["description"] = desc + "."
    if not is_module_file:
        shared_modules = kid(kid(root, "Descriptions"), "Modules")
        slot_notes(dev, shared_modules)
        dev = with_default_modules(dev, shared_modules)
    dictionary = None
    for prof in kids(dev, "Profile"):
        dictionary = kid(prof, "Dictionary")
        if dictionary is not None:
            break
    types = EsiTypes({english_name(d): d for d in kids(kid(dictionary, "DataTypes"), "DataType")})
    parsed: list[ParsedObject] = []
    esi_vars: dict[int, dict[int, EsiVar]] = {}
    mapped = mapped_entries(dev)
    for el in kids(kid(dictionary, "Objects"), "Object"):
        obj, vars_ = _read_object(types, el, source)
        for sub, v in vars_.items():
            obj.subs[sub] = spec_fields(v, obj.index, f"{obj.where} sub {sub}")
            direction_from_pdos(obj.subs[sub], (obj.index, sub), mapped, obj.where)
        parsed.append(obj)
        esi_vars[obj.index] = vars_
    # servodesk's own extras (only in files servodesk wrote).
    meta: dict[str, Any] | None = None
    sd = None
    for vs in kids(dev, "VendorSpecific"):
        sd = kid(vs, "Servodesk")
        if sd is not None:
            break
    if sd is not None:
        prof_el = kid(sd, "Profile")
        if prof_el is not None and prof_el.text:
            m = loads(prof_el.text, "VendorSpecific/Servodesk/Profile")
            meta = m if isinstance(m, dict) else None
        by_index = {o.index: o for o in parsed}
        for el in sd:
            kind = local_name(el.tag) if isinstance(el.tag, str) else ""
            if kind not in ("Var", "Entry") or not el.text:
                continue
            try:
                idx = parse_int(el.get("Index") or "")
                sub = parse_int(el.get("SubIdx") or "0")
            except ValueError:
                continue
            o = by_index.get(idx)
            data = loads(el.text, f"VendorSpecific/Servodesk/{kind} {esi_hex(idx, 4)}")
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
                            f"VendorSpecific/Servodesk/Entry {esi_hex(idx, 4)}: object_type "
                            f"{data['object_type']!r} is not var, array or record",
                            path=source,
                            hint="remove the Servodesk element to drop the extras",
                        ) from None
                o.entry.update({k: v for k, v in data.items() if k in ENTRY_FIELDS})
    known = {o.index for o in parsed}
    have = {(o.index, s) for o in parsed for s in o.subs}
    parsed.extend(pdo_objects(dev, known, have, source))
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
        std["pdo"], template = pdo_rules(dev, source)
    pid = profile_id or slug(std.get("name") or "imported")
    if meta is not None:
        std.pop("identity", None)
        std.pop("fieldbus", None)
        std.pop("description", None)
    profile = make_profile(profile_id=pid, meta=meta, standard=std, objects=objects, where=source)
    if template is not None:
        why = template_ok(profile, template)
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
