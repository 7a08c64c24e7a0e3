"""XDD / XDC (CiA 311, CANopen device description in XML) import.

Reads ``ProfileBody_Device_CANopen/DeviceIdentity`` (vendor and product) and the object
dictionary of ``ProfileBody_CommunicationNetwork_CANopen/ApplicationLayers/CANopenObjectList``:
``CANopenObject`` and ``CANopenSubObject`` with the same attribute values an EDS has (CiA 311
mirrors CiA 306: ``dataType="0007"``, ``accessType``, ``defaultValue`` with ``$NODEID``,
``lowLimit``/``highLimit``), and ``PDOmapping`` in its CiA 311 spelling (no / default /
optional / RPDO / TPDO). A missing ``name`` is taken from the parameter its ``uniqueIDRef``
points at. Export is not offered: EDS carries the same dictionary for CANopen tools.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    ParsedObject,
    build_entry,
    entry_default,
    make_profile,
    parse_int,
    slug,
    warn,
)
from servodesk.devdesc.eds import var_fields
from servodesk.domain.profile import DeviceProfile, ObjectType, PdoMapping
from servodesk.errors import ProfileError

__all__ = ["import_xdd"]

_TYPES = {7: ObjectType.VAR, 2: ObjectType.VAR, 8: ObjectType.ARRAY, 9: ObjectType.RECORD}
_PDO = {"rpdo": PdoMapping.RX, "tpdo": PdoMapping.TX}


def _local(tag: object) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _find_all(root: ET.Element, name: str) -> list[ET.Element]:
    return [el for el in root.iter() if _local(el.tag) == name]


def _labels(root: ET.Element) -> dict[str, str]:
    """uniqueID -> English label of the parameters (ApplicationProcess/parameterList)."""
    out: dict[str, str] = {}
    for el in root.iter():
        uid = el.get("uniqueID")
        if not uid:
            continue
        labels = [c for c in el if _local(c.tag) == "label"]
        for lab in labels:
            lang = next((v for k, v in lab.attrib.items() if _local(k) == "lang"), "en")
            if lang.startswith("en") and lab.text:
                out[uid] = lab.text.strip()
                break
        else:
            if labels and labels[0].text:
                out[uid] = labels[0].text.strip()
    return out


#: IEC 61131-3 type elements of an ApplicationProcess parameter -> CiA 301 data type
#: (CiA 311 §6.4.4.3, table "simple data types"; BYTE/WORD/... are bit strings of that size).
_IEC_TYPES: dict[str, int] = {
    "BOOL": 0x0001,
    "SINT": 0x0002,
    "INT": 0x0003,
    "DINT": 0x0004,
    "USINT": 0x0005,
    "UINT": 0x0006,
    "UDINT": 0x0007,
    "REAL": 0x0008,
    "STRING": 0x0009,
    "WSTRING": 0x000B,
    "LREAL": 0x0011,
    "LINT": 0x0015,
    "ULINT": 0x001B,
    "BYTE": 0x0005,
    "CHAR": 0x0005,
    "WORD": 0x0006,
    "DWORD": 0x0007,
    "LWORD": 0x001B,
    "BITSTRING": 0x000A,
}
#: CiA 311 parameter ``access`` -> CiA 306 access type.
_IEC_ACCESS: dict[str, str] = {
    "const": "const",
    "read": "ro",
    "write": "wo",
    "readwrite": "rw",
    "readwriteinput": "rwr",
    "readwriteoutput": "rww",
    "noaccess": "ro",
}


def _parameters(root: ET.Element) -> dict[str, ET.Element]:
    """uniqueID -> ApplicationProcess ``parameter`` element."""
    return {
        uid: el
        for el in root.iter()
        if _local(el.tag) == "parameter" and (uid := el.get("uniqueID"))
    }


def _from_parameter(param: ET.Element | None, keys: dict[str, str], where: str) -> None:
    """Fill the keys the object leaves out from the parameter its uniqueIDRef names.

    CiA 311 §6.4.4: a CANopenObject without dataType/accessType/defaultValue takes them from
    the referenced ApplicationProcess parameter (CANopenEditor writes XDD files this way).
    """
    if param is None:
        return
    if "datatype" not in keys:
        for c in param:
            code = _IEC_TYPES.get(_local(c.tag))
            if code is not None:
                keys["datatype"] = f"0x{code:04X}"
                break
    if "accesstype" not in keys:
        keys["accesstype"] = _IEC_ACCESS.get(param.get("access", "read").lower(), "ro")
    if "defaultvalue" not in keys:
        for c in param:
            if _local(c.tag) == "defaultValue" and c.get("value") is not None:
                keys["defaultvalue"] = c.get("value", "")
                break


def _keys(
    el: ET.Element, name: str, where: str, params: dict[str, ET.Element] | None = None
) -> dict[str, str]:
    """The object's attributes as the (lower-case) EDS keys the EDS reader understands."""
    a = el.attrib
    keys: dict[str, str] = {"parametername": name}
    if "dataType" in a:
        keys["datatype"] = "0x" + a["dataType"].strip()
    if "accessType" in a:
        keys["accesstype"] = a["accessType"]
    for attr, key in (
        ("defaultValue", "defaultvalue"),
        ("lowLimit", "lowlimit"),
        ("highLimit", "highlimit"),
    ):
        if attr in a:
            keys[key] = a[attr]
    pdo = a.get("PDOmapping", "no").strip().lower()
    if pdo not in ("no", "default", "optional", "rpdo", "tpdo"):
        raise ProfileError(
            f"{where} PDOmapping={a['PDOmapping']!r}: unknown value",
            hint="CiA 311 allows no, default, optional, RPDO and TPDO",
        )
    keys["pdomapping"] = "0" if pdo == "no" else "1"
    if params is not None and ("datatype" not in keys or "accesstype" not in keys):
        _from_parameter(params.get(el.get("uniqueIDRef") or ""), keys, where)
    if "datatype" not in keys:
        warn(f"{where}: no dataType and no parameter giving one; read as DOMAIN")
        keys["datatype"] = "0x000F"
    if "accesstype" not in keys:
        keys["accesstype"] = "ro"  # CiA 311: a parameter's access defaults to read.
    return keys


def _var(
    el: ET.Element,
    index: int,
    sub: int,
    labels: dict[str, str],
    where: str,
    params: dict[str, ET.Element] | None = None,
) -> dict[str, Any]:
    name = el.get("name") or labels.get(el.get("uniqueIDRef") or "", "")
    if not name:
        raise ProfileError(
            f"{where}: no name and no uniqueIDRef to a labelled parameter",
            hint="give the object a name= attribute",
        )
    fields = var_fields(_keys(el, name, where, params), index, where, where=where)
    direction = _PDO.get(el.get("PDOmapping", "").strip().lower())
    if direction is not None:
        fields["pdo_mapping"] = direction
    return fields


def import_xdd(text: str, *, profile_id: str | None = None, source: str = "<xdd>") -> DeviceProfile:
    """A profile from the text of an XDD (or XDC) file."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        line, col = exc.position
        raise ProfileError(
            f"not well-formed XML (line {line}, column {col}): {exc}",
            path=source,
            hint="an XDD file is XML starting with <ISO15745ProfileContainer>",
        ) from None
    if _local(root.tag) != "ISO15745ProfileContainer":
        raise ProfileError(
            f"the root element is <{_local(root.tag)}>, not <ISO15745ProfileContainer>",
            path=source,
            hint="this is not an XDD (CiA 311) file; ESI files use the suffix .xml",
        )
    lists = _find_all(root, "CANopenObjectList")
    if not lists:
        raise ProfileError(
            "no ApplicationLayers/CANopenObjectList",
            path=source,
            hint="the XDD needs the ProfileBody_CommunicationNetwork_CANopen object list",
        )
    labels = _labels(root)
    params = _parameters(root)
    parsed: list[ParsedObject] = []
    for el in (c for c in lists[0] if _local(c.tag) == "CANopenObject"):
        raw_index = el.get("index", "")
        try:
            index = int(raw_index, 16)
        except ValueError:
            raise ProfileError(
                f"CANopenObject index={raw_index!r}: not a hex index",
                path=source,
                hint='write index="6040" (hex, no prefix)',
            ) from None
        where = f"{source}: CANopenObject {index:04X}"
        raw_type = el.get("objectType", "7")
        try:
            otype = _TYPES[int(raw_type)]
        except (ValueError, KeyError):
            raise ProfileError(
                f"{where} objectType={raw_type!r}: not 7 (VAR), 8 (ARRAY) or 9 (RECORD)",
                hint="DEFTYPE/DEFSTRUCT objects are not supported",
            ) from None
        obj = ParsedObject(index=index, object_type=otype, where=where)
        if otype is ObjectType.VAR:
            obj.subs[0] = _var(el, index, 0, labels, where, params)
        else:
            obj.entry = {n: entry_default(n) for n in ENTRY_FIELDS}
            obj.entry["name"] = el.get("name") or labels.get(el.get("uniqueIDRef") or "", "")
            for sel in (c for c in el if _local(c.tag) == "CANopenSubObject"):
                raw_sub = sel.get("subIndex", "")
                try:
                    sub = int(raw_sub, 16)
                except ValueError:
                    raise ProfileError(
                        f"{where} subIndex={raw_sub!r}: not a hex sub-index",
                        hint='write subIndex="01" (hex, no prefix)',
                    ) from None
                obj.subs[sub] = _var(sel, index, sub, labels, f"{where} sub {sub:02X}", params)
        parsed.append(obj)
    std: dict[str, Any] = {"fieldbus": "canopen"}
    ident: dict[str, Any] = {}
    for di in _find_all(root, "DeviceIdentity"):
        for c in di:
            tag, val = _local(c.tag), (c.text or "").strip()
            if not val:
                continue
            if tag == "vendorName":
                std["vendor"] = val
            elif tag == "productName":
                std["name"] = val
            elif tag in ("vendorID", "productID"):
                try:
                    num = parse_int(val if val.lower().startswith(("0x", "#x")) else "0x" + val)
                except ValueError:
                    raise ProfileError(
                        f"DeviceIdentity/{tag} {val!r} is not a number",
                        path=source,
                        hint="write it in hex, e.g. 0x0000015A",
                    ) from None
                if tag == "vendorID":
                    ident["vendor_id"] = num
                else:
                    ident["product_codes"] = [num]
        break
    if ident:
        std["identity"] = ident
    objects = [build_entry(o) for o in sorted(parsed, key=lambda o: o.index)]
    pid = profile_id or slug(std.get("name") or "imported")
    return make_profile(profile_id=pid, meta=None, standard=std, objects=objects, where=source)
