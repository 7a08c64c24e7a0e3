"""What ESI (EtherCAT Slave Information, ETG.2000) export and import share.

The standard part of one variable (:class:`EsiVar`: ETG.2000 ``Flags``, ``Info`` and type)
and the ObjectSpec fields it stands for (:func:`spec_fields`; export compares a profile
against them to know which fields travel as servodesk's extras), the ESI names of the CiA 301
types both ways (:func:`type_of`, :class:`EsiTypes` resolving ``DataTypes`` by name), the
``#x`` hex notation, and the namespace-blind element lookups import and its PDO and module
part read vendor files with. Export is :mod:`servodesk.devdesc.esi_export`, import
:mod:`servodesk.devdesc.esi` with :mod:`servodesk.devdesc.esi_pdo`.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from servodesk.devdesc._common import (
    SPEC_FIELDS,
    area_group,
    parse_int,
    parse_number,
    spec_default,
    warn,
)
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.profile import Access, PdoMapping
from servodesk.errors import ProfileError, ServodeskError

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
STATES = {"preop": "PreOP", "safeop": "SafeOP", "op": "OP"}


@dataclass
class EsiVar:
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


def spec_fields(v: EsiVar, index: int, where: str) -> dict[str, Any]:
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
        if set(states) != set(STATES):
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


def type_of(dt: DataType, default: Any) -> tuple[str, int]:
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


def esi_hex(v: int, width: int = 8) -> str:
    """A number in ESI's hex notation (``#x1A00``; ETG.2000 HexDecValue)."""
    return f"#x{v:0{width}X}"


# Element lookups by local name: vendor files use any namespace (or none).


def local_name(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def kids(el: ET.Element | None, name: str) -> Iterator[ET.Element]:
    if el is None:
        return
    for c in el:
        if isinstance(c.tag, str) and local_name(c.tag) == name:
            yield c


def kid(el: ET.Element | None, name: str) -> ET.Element | None:
    return next(kids(el, name), None)


def kid_text(el: ET.Element | None, name: str) -> str | None:
    c = kid(el, name)
    if c is None or c.text is None:
        return None
    return c.text.strip()


def english_name(el: ET.Element) -> str:
    """The English name of an element with several ``Name LcId=..`` children."""
    names = list(kids(el, "Name"))
    for n in names:
        if n.get("LcId") in (None, "1033") and n.text:
            return n.text.strip()
    return (names[0].text or "").strip() if names else ""


_BIT_TYPE = re.compile(r"^BIT([2-7])$")


@dataclass
class EsiTypes:
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
            base = kid_text(el, "BaseType")
            if kid(el, "ArrayInfo") is not None:
                # An array used as one value (a sub-item with its own SubIdx): its bytes.
                if self.byte_array(name):
                    return DataType.OCTET_STRING, None
                warn(f"{where}: array type {name!r} kept as one DOMAIN value")
                return DataType.DOMAIN, None
            if any(True for _ in kids(el, "SubItem")):
                # A structure nested in a structure (ETG.2000 allows it; CiA 301 has no
                # sub-sub-index): the whole nested record is one DOMAIN value.
                warn(f"{where}: nested structure {name!r} kept as one DOMAIN value")
                return DataType.DOMAIN, None
            if base:
                dt, _ = self.basic(base, bit_size, where, depth + 1)
                enums: dict[int, str] = {}
                for ei in kids(el, "EnumInfo"):
                    enum_text, enum_val = kid_text(ei, "Text"), kid_text(ei, "Enum")
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
        if el is not None and any(True for _ in kids(el, "SubItem")):
            return el
        return None

    def array(self, name: str) -> ET.Element | None:
        el = self.defs.get(name.strip())
        if el is not None and kid(el, "ArrayInfo") is not None:
            return el
        return None

    def byte_array(self, name: str) -> bool:
        """An array of 8-bit elements (``ARRAY [0..n] OF BYTE``): one octet string."""
        if _BYTE_ARRAY.match(name.strip().upper()):
            return True
        arr = self.array(name)
        if arr is None:
            return False
        base = (kid_text(arr, "BaseType") or "").strip().upper()
        return _ESI_TYPES.get(base) in (DataType.UNSIGNED8, DataType.INTEGER8)
