"""EDS and DCF import (CiA 306 v1.3 electronic data sheets) into servodesk profiles.

Parses with :mod:`configparser` the way the ``canopen`` package does (``;`` starts an inline
comment, option names are matched without regard to case) and turns every problem in the
user's file into a :class:`~servodesk.errors.ProfileError` that names the section and key.
The ``servodesk_<field>`` keys the export writes (devdesc/eds_export.py) bring back what EDS
has no key for, so an exported profile imports unchanged.

About 700 lines: the CiA 306 reader, one object's sections (VAR, ARRAY, RECORD, compact sub-
objects) and a DCF's ParameterValue parsing share the reader's error places; the export is
devdesc/eds_export.py.
"""

from __future__ import annotations

import configparser
import contextlib
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    EXTRA_PREFIX,
    SPEC_FIELDS,
    ParsedObject,
    area_group,
    build_entry,
    entry_default,
    loads,
    make_profile,
    parse_int,
    parse_number,
    slug,
    spec_default,
    warn,
)
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value
from servodesk.domain.profile import (
    Access,
    DeviceProfile,
    ObjectSpec,
    ObjectType,
    PdoMapping,
    resolve_value,
)
from servodesk.errors import ProfileError, ServodeskError

__all__ = [
    "DcfContents",
    "import_dcf",
    "import_eds",
    "read_dcf",
]

_CODE_TYPES = {
    0x7: ObjectType.VAR,
    0x2: ObjectType.VAR,
    0x8: ObjectType.ARRAY,
    0x9: ObjectType.RECORD,
}
#: TIME_OF_DAY / TIME_DIFFERENCE (CiA 301 §7.1.6.5/6) have no servodesk codec: read as bytes.
_BYTES_TYPES = {0x000C: "TIME_OF_DAY", 0x000D: "TIME_DIFFERENCE"}
_PERSIST_STORAGE = re.compile(r"PERSIST|EEPROM|FLASH|NVM|ROM", re.I)
_SUB_SECTION = re.compile(r"([0-9a-f]{4})sub([0-9a-f]{1,2})")


def _where(section: str, key: str | None = None) -> str:
    return f"[{section}] {key}" if key else f"[{section}]"


def _data_type(keys: Mapping[str, str], where: str) -> tuple[DataType, str | None]:
    raw = keys.get("datatype")
    if raw is None:
        raise ProfileError(
            f"{where}: the key DataType is missing",
            hint="add DataType=0x0007 (the CiA 306 number of the object's type, e.g. "
            "0x0006 UNSIGNED16, 0x0007 UNSIGNED32)",
        )
    try:
        num = parse_int(raw)
    except ValueError:
        raise ProfileError(
            f"{where} DataType={raw!r}: not a number",
            hint="write the CiA 306 data type number in hex, e.g. DataType=0x0007",
        ) from None
    if num in _BYTES_TYPES:
        return DataType.DOMAIN, f"(EDS data type {_BYTES_TYPES[num]}, read as bytes)"
    try:
        return DataType(num), None
    except ValueError:
        if 0x0020 <= num <= 0x025F:
            # CiA 301 table 44: 0020h-025Fh are complex and manufacturer/profile-defined types
            # (DEFTYPE/DEFSTRUCT); servodesk moves their bytes without knowing the layout.
            warn(f"{where} DataType={raw.strip()}: a defined (complex) type; read as DOMAIN")
            return DataType.DOMAIN, f"(EDS data type 0x{num:04X}, read as bytes)"
        raise ProfileError(
            f"{where} DataType={raw}: 0x{num:04X} is not a CiA 301 basic data type",
            hint="servodesk reads the basic types 0x0001-0x001B (BOOLEAN .. UNSIGNED64); "
            "complex or user-defined types (0x0020 and up) are not supported",
        ) from None


def _access(keys: Mapping[str, str], where: str) -> Access:
    raw = keys.get("accesstype")
    if raw is None:
        raise ProfileError(
            f"{where}: the key AccessType is missing",
            hint="add AccessType=ro, wo, rw, rwr, rww or const (CiA 306 §4.6.3.2)",
        )
    try:
        return Access(raw.strip().lower())
    except ValueError:
        raise ProfileError(
            f"{where} AccessType={raw!r}: unknown access type",
            hint="use ro, wo, rw, rwr, rww or const (CiA 306 §4.6.3.2)",
        ) from None


def _parse_default(text: str, dt: DataType, where: str) -> Any:
    t = text.strip()
    if dt.is_string:
        return text
    if t == "":
        return None
    if "$NODEID" in t.upper():
        if dt.is_integer:
            try:
                resolve_value(t, dt, 1)
            except (ValueError, ServodeskError):
                raise ProfileError(
                    f"{where}={t!r}: not a $NODEID expression servodesk can read",
                    hint="write $NODEID+0x180 (CiA 306 §4.6.3.2)",
                ) from None
        return t
    if dt.is_numeric:
        try:
            return parse_number(t, dt)
        except ValueError:
            raise ProfileError(
                f"{where}={t!r}: not a {dt.name} number",
                hint="write decimal (100), hex (0x64) or $NODEID+0x180 (CiA 306 §4.6.3.2)",
            ) from None
    if dt is DataType.OCTET_STRING:
        try:
            bytes.fromhex(t)
        except ValueError:
            raise ProfileError(
                f"{where}={t!r}: not hex bytes",
                hint="write an OCTET_STRING value as hex digits, e.g. 0A1B2C",
            ) from None
        return t
    try:  # DOMAIN: only hex content is a value; anything else (a file name) is dropped.
        bytes.fromhex(t)
    except ValueError:
        return None
    return t


def _parse_limit(text: str | None, dt: DataType, where: str) -> int | float | None:
    if text is None or not dt.is_numeric:
        return None
    t = text.strip()
    if t == "" or "$NODEID" in t.upper():
        return None  # A node-relative limit cannot be a fixed min/max.
    try:
        return parse_number(t, dt)
    except ValueError:
        raise ProfileError(
            f"{where}={t!r}: not a {dt.name} number",
            hint="write decimal or 0x hex, or remove the key for no limit",
        ) from None


def var_fields(
    keys: Mapping[str, str], index: int, section: str, where: str | None = None
) -> dict[str, Any]:
    """ObjectSpec fields from the (lower-cased) keys of a variable's section.

    ``where`` names the place in messages (default ``[section]``).
    """
    where = where or _where(section)
    name = keys.get("parametername")
    if name is None:
        raise ProfileError(
            f"{where}: the key ParameterName is missing",
            hint="every object and sub-index section needs ParameterName= (CiA 306 §4.6.3.2)",
        )
    dt, note = _data_type(keys, where)
    access = _access(keys, where)
    mappable_raw = keys.get("pdomapping", "0").strip() or "0"
    try:
        mappable = bool(parse_int(mappable_raw))
    except ValueError:
        raise ProfileError(
            f"{where} PDOMapping={mappable_raw!r}: not 0 or 1",
            hint="write PDOMapping=1 for a mappable object, 0 otherwise",
        ) from None
    pdo = PdoMapping.NONE
    if mappable:
        # EDS says only "mappable"; the direction follows the access type (CiA 306 §4.6.3.2:
        # rww = written by RPDO, rwr = read by TPDO); a plain rw can go either way.
        if access in (Access.RO, Access.CONST, Access.RWR):
            pdo = PdoMapping.TX
        elif access in (Access.WO, Access.RWW):
            pdo = PdoMapping.RX
        else:
            pdo = PdoMapping.BOTH
    fields: dict[str, Any] = {n: spec_default(n) for n in SPEC_FIELDS}
    fields.update(
        name=name.strip(),
        data_type=dt,
        access=access,
        pdo_mapping=pdo,
        group=area_group(index),
        # Mappable and read-only or PDO-only-writable (rww/rwr) is process data (setpoints,
        # actual values): never part of a parameter backup.
        process=mappable and access in (Access.RO, Access.RWR, Access.RWW),
    )
    if "defaultvalue" in keys:
        fields["default"] = _parse_default(keys["defaultvalue"], dt, f"{where} DefaultValue")
    fields["min"] = _parse_limit(keys.get("lowlimit"), dt, f"{where} LowLimit")
    fields["max"] = _parse_limit(keys.get("highlimit"), dt, f"{where} HighLimit")
    # Keys some tools add (canopen's Description/Unit/Factor, CANopenNode's StorageLocation).
    if keys.get("description"):
        fields["description"] = keys["description"].strip()
    if note:
        fields["description"] = f"{fields['description'] or ''} {note}".strip()
    if keys.get("unit"):
        fields["unit"] = keys["unit"].strip()
    if keys.get("factor"):
        with contextlib.suppress(ValueError):
            fields["scale"] = float(keys["factor"])
    if _PERSIST_STORAGE.search(keys.get("storagelocation", "")):
        fields["persist"] = True
    return fields


def entry_fields(keys: Mapping[str, str]) -> dict[str, Any]:
    fields: dict[str, Any] = {n: entry_default(n) for n in ENTRY_FIELDS}
    fields["name"] = keys.get("parametername", "").strip()
    return fields


def _apply_extras(
    fields: dict[str, Any], keys: Mapping[str, str], names: tuple[str, ...], section: str
) -> None:
    for k, v in keys.items():
        if not k.startswith(EXTRA_PREFIX):
            continue
        f = k[len(EXTRA_PREFIX) :]
        if f in names:
            fields[f] = loads(v, f"[{section}] {k}")


class _Reader:
    """One parsed EDS/DCF: sections by lower-cased name, keys lower-cased."""

    def __init__(self, text: str, source: str) -> None:
        self.source = source
        cp = configparser.RawConfigParser(
            inline_comment_prefixes=(";",), strict=False, interpolation=None
        )
        try:
            cp.read_string(text, source=source)
        except configparser.MissingSectionHeaderError as exc:
            raise ProfileError(
                f"line {exc.lineno}: {exc.line.strip()!r} comes before any [section]",
                path=source,
                hint="an EDS/DCF starts with a section such as [FileInfo]; is this an EDS?",
            ) from None
        except configparser.Error as exc:
            msg = str(exc).splitlines()[0]
            raise ProfileError(
                f"not a readable EDS/DCF: {msg}",
                path=source,
                hint="check the line it names (CiA 306 §4: [Section] and Key=Value lines)",
            ) from None
        self.sections: dict[str, tuple[str, dict[str, str]]] = {}
        #: index -> sub-index -> lower-cased section name of its [xxxxsubN] sections.
        self.subs: dict[int, dict[int, str]] = {}
        for name in cp.sections():
            low = name.strip().lower()
            self.sections[low] = (name, dict(cp.items(name)))
            m = _SUB_SECTION.fullmatch(low)
            if m:
                self.subs.setdefault(int(m.group(1), 16), {})[int(m.group(2), 16)] = low

    def get(self, name: str) -> dict[str, str] | None:
        found = self.sections.get(name.lower())
        return found[1] if found else None

    def name(self, name: str) -> str:
        found = self.sections.get(name.lower())
        return found[0] if found else name

    def error(self, message: str, hint: str) -> ProfileError:
        return ProfileError(message, path=self.source, hint=hint)


@dataclass(frozen=True)
class DcfContents:
    """What a DCF configures: the profile, the values, the node id and bit rate."""

    profile: DeviceProfile
    values: dict[ObjectAddress, Value]
    node_id: int | None
    bitrate: int | None


def parse_param(text: str, spec: ObjectSpec, node_id: int | None, where: str) -> Value | None:
    dt = spec.data_type
    t = text.strip()
    if "$NODEID" in t.upper() and dt.is_integer:
        if node_id is None:
            # A DCF written as a template for any node: the expression stays the object's
            # default (resolved per node); no configured value is taken from it.
            warn(
                f"{where}={t!r} uses $NODEID but [DeviceComissioning] has no NodeID; "
                "value not taken (the default resolves it per node)"
            )
            return None
        try:
            v = resolve_value(t, dt, node_id)
        except (ValueError, ServodeskError):
            raise ProfileError(
                f"{where}={t!r}: not a $NODEID expression servodesk can read",
                hint="write $NODEID+0x180 (CiA 306 §4.6.3.2)",
            ) from None
        return int(v) if isinstance(v, int | float) else 0
    if dt.is_integer:
        try:
            iv = int(parse_number(t, dt))
        except ValueError:
            raise ProfileError(
                f"{where}={t!r}: not a {dt.name} number",
                hint="write decimal or 0x hex (CiA 306 §4.6.3.2)",
            ) from None
        return bool(iv) if dt is DataType.BOOLEAN else iv
    if dt.is_real:
        try:
            return float(parse_number(t, dt))
        except ValueError:
            raise ProfileError(
                f"{where}={t!r}: not a number", hint="write a decimal number such as 1.5"
            ) from None
    if dt.is_string:
        return text
    try:
        return bytes.fromhex(t)
    except ValueError:
        raise ProfileError(
            f"{where}={t!r}: not hex bytes", hint="write OCTET_STRING/DOMAIN values as hex"
        ) from None


def _read_objects(r: _Reader) -> list[ParsedObject]:
    listed: list[tuple[str, int]] = []
    have_list = False
    for list_name in ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects"):
        keys = r.get(list_name)
        if keys is None:
            continue
        have_list = True
        sect = r.name(list_name)
        raw_n = keys.get("supportedobjects")
        if raw_n is None:
            raise r.error(
                f"[{sect}]: the key SupportedObjects is missing",
                "add SupportedObjects=<count> and 1=0x1000, 2=0x1001, ... (CiA 306 §4.6.2)",
            )
        try:
            n = parse_int(raw_n)
        except ValueError:
            raise r.error(
                f"[{sect}] SupportedObjects={raw_n!r}: not a number",
                "write the number of listed objects, e.g. SupportedObjects=3",
            ) from None
        numbered = sorted(int(k) for k in keys if k.isdigit())
        if numbered != list(range(1, n + 1)):
            # CiA 306 §4.6.2: SupportedObjects counts the entries 1..n. Vendor tools get the
            # count wrong; the entries that are there are the list.
            warn(
                f"{r.source}: [{sect}] SupportedObjects={n} but the entries are "
                f"{_ranges_text(numbered)}; read the entries that are there"
            )
        for i in numbered:
            raw = keys[str(i)]
            try:
                listed.append((f"[{sect}] {i}={raw}", parse_int(raw)))
            except ValueError:
                raise r.error(
                    f"[{sect}] {i}={raw!r}: not an object index",
                    "write the index in hex, e.g. 0x6040",
                ) from None
    index_sections = sorted(int(k, 16) for k in r.sections if re.fullmatch(r"[0-9a-f]{4}", k))
    for where, idx in listed:
        if r.get(f"{idx:04X}") is None:
            # Listed but not described: nothing to import for it (a vendor file that lists
            # objects of another variant, or a truncated file).
            warn(f"{r.source}: {where}: there is no section [{idx:04X}]; object skipped")
    if not have_list and not index_sections:
        raise r.error(
            "no object dictionary: neither [MandatoryObjects]/[OptionalObjects]/"
            "[ManufacturerObjects] nor any [xxxx] object section",
            "is the file complete? An EDS lists its objects in [MandatoryObjects] etc.",
        )
    objects = [_read_object(r, idx) for idx in index_sections]
    return [o for o in objects if o is not None]


def _read_object(r: _Reader, index: int) -> ParsedObject | None:
    sect = r.name(f"{index:04X}")
    keys = r.get(sect) or {}
    raw_type = keys.get("objecttype", "0x7")
    try:
        code = parse_int(raw_type)
        otype = _CODE_TYPES[code]
    except (ValueError, KeyError):
        raise r.error(
            f"[{sect}] ObjectType={raw_type!r}: not a supported object code",
            "use 0x7 (VAR), 0x8 (ARRAY) or 0x9 (RECORD); DEFTYPE/DEFSTRUCT are not supported",
        ) from None
    obj = ParsedObject(index=index, object_type=otype, where=f"{r.source}: [{sect}]")
    if otype is ObjectType.VAR:
        fields = var_fields(keys, index, sect)
        _apply_extras(fields, keys, SPEC_FIELDS, sect)
        obj.subs[0] = fields
        return obj
    obj.entry = entry_fields(keys)
    if not obj.entry["name"]:
        raise r.error(
            f"[{sect}]: the key ParameterName is missing",
            "every object section needs ParameterName= (CiA 306 §4.6.3.2)",
        )
    _apply_extras(obj.entry, keys, ENTRY_FIELDS, sect)
    compact = keys.get("compactsubobj", "").strip()
    if compact and otype is ObjectType.ARRAY and parse_int_or(compact, r, sect) > 0:
        _read_compact(r, obj, keys, sect, parse_int_or(compact, r, sect))
        return obj
    for sub, low in sorted(r.subs.get(index, {}).items()):
        sname = r.name(low)
        skeys = r.get(low) or {}
        fields = var_fields(skeys, index, sname)
        _apply_extras(fields, skeys, SPEC_FIELDS, sname)
        obj.subs[sub] = fields
    raw_n = keys.get("subnumber")
    if raw_n is not None:
        n = parse_int_or(raw_n, r, sect, key="SubNumber")
        if len(obj.subs) != n:
            # CiA 306 §4.6.3.2: SubNumber counts the [xxxxsubN] sections; files count
            # sub-indices the device has but the file does not describe (1003h sub 1..n).
            warn(
                f"{r.source}: [{sect}] SubNumber={n} but {len(obj.subs)} sub-index sections "
                f"[{index:04X}subN] exist; imported those"
            )
    if not obj.subs:
        # Nothing describes its sub-indices (no [xxxxsubN], no CompactSubObj): an object
        # servodesk cannot address; reported and left out.
        warn(
            f"{r.source}: [{sect}]: {otype.value.upper()} without sub-index sections "
            "or CompactSubObj; object skipped"
        )
        return None
    return obj


def _ranges_text(numbers: list[int]) -> str:
    """1..3, 5 for [1, 2, 3, 5] (what a list's entries are, for a warning)."""
    if not numbers:
        return "none"
    parts: list[str] = []
    start = prev = numbers[0]
    for n in [*numbers[1:], None]:
        if n is not None and n == prev + 1:
            prev = n
            continue
        parts.append(f"{start}..{prev}" if prev > start else str(start))
        if n is not None:
            start = prev = n
    return ", ".join(parts)


def parse_int_or(raw: str, r: _Reader, sect: str, key: str = "CompactSubObj") -> int:
    try:
        return parse_int(raw)
    except ValueError:
        raise r.error(f"[{sect}] {key}={raw!r}: not a number", f"write {key} as a number") from None


def _read_compact(
    r: _Reader, obj: ParsedObject, keys: Mapping[str, str], sect: str, n: int
) -> None:
    """CiA 306 §4.6.3.3 compact storage: one section describes elements 1..n."""
    base = var_fields(keys, obj.index, sect)
    _apply_extras(base, keys, SPEC_FIELDS, sect)
    sub0 = {f: spec_default(f) for f in SPEC_FIELDS}
    sub0.update(
        name="Number of entries",
        data_type=DataType.UNSIGNED8,
        access=Access.RO,
        default=n,
        group=base["group"],
    )
    obj.subs[0] = sub0
    names = r.get(f"{obj.index:04X}Name") or {}
    for i in range(1, n + 1):
        f = dict(base)
        f["name"] = names.get(str(i), f"{base['name']} {i}").strip()
        obj.subs[i] = f


def _device_standard(r: _Reader) -> dict[str, Any]:
    info = r.get("DeviceInfo")
    if info is None:
        raise r.error(
            "the section [DeviceInfo] is missing",
            "an EDS needs [DeviceInfo] with VendorName, ProductName, ... (CiA 306 §4.5)",
        )
    std: dict[str, Any] = {}
    if info.get("productname"):
        std["name"] = info["productname"].strip()
    if info.get("vendorname"):
        std["vendor"] = info["vendorname"].strip()
    ident: dict[str, Any] = {}
    for key, field_name in (("vendornumber", "vendor_id"), ("productnumber", "product_codes")):
        raw = info.get(key)
        if raw is None or not raw.strip():
            continue
        try:
            v = parse_int(raw)
        except ValueError:
            raise r.error(
                f"[{r.name('DeviceInfo')}] {key}={raw!r}: not a number",
                "write the number in hex, e.g. 0x000001A5",
            ) from None
        ident[field_name] = [v] if field_name == "product_codes" else v
    if ident:
        std["identity"] = ident
    pdo: dict[str, Any] = {}
    for key, field_name in (("nrofrxpdo", "rpdo_count"), ("nroftxpdo", "tpdo_count")):
        raw = info.get(key)
        if raw is not None and raw.strip():
            try:
                pdo[field_name] = parse_int(raw)
            except ValueError:
                raise r.error(
                    f"[{r.name('DeviceInfo')}] {key}={raw!r}: not a number",
                    "write the number of PDOs, e.g. NrOfRXPDO=4",
                ) from None
    if pdo:
        std["pdo"] = pdo
    comments = r.get("Comments")
    if comments:
        lines = [comments.get(f"line{i}", "") for i in range(1, len(comments) + 1)]
        text = " ".join(x.strip() for x in lines if x.strip())
        if text:
            std["description"] = text
    return std


def _meta(r: _Reader) -> dict[str, Any] | None:
    fi = r.get("FileInfo") or {}
    raw = fi.get(f"{EXTRA_PREFIX}profile")
    if raw is None:
        return None
    meta = loads(raw, f"[{r.name('FileInfo')}] {EXTRA_PREFIX}profile")
    if not isinstance(meta, dict):
        raise r.error(
            f"[{r.name('FileInfo')}] {EXTRA_PREFIX}profile: not a JSON object",
            "remove the key to import the standard keys only",
        )
    return meta


def identity_numbers(profile: DeviceProfile) -> tuple[int, int, int]:
    """Vendor, product and revision number: profile identity, else the 1018h defaults."""
    vars_ = profile.variables

    def default_of(sub: int) -> int:
        spec = vars_.get(ObjectAddress(0x1018, sub))
        if spec is None:
            return 0
        try:
            v = spec.default_value()
        except (ValueError, ServodeskError):
            return 0
        return v if isinstance(v, int) and not isinstance(v, bool) else 0

    ident = profile.identity
    vendor = ident.vendor_id if ident.vendor_id is not None else default_of(1)
    product = ident.product_codes[0] if ident.product_codes else default_of(2)
    revision = default_of(3) or (ident.revision_min or 0)
    return vendor, product, revision


def _import(
    text: str, profile_id: str | None, name: str | None, source: str
) -> tuple[_Reader, DeviceProfile]:
    r = _Reader(text, source)
    std = _device_standard(r)
    try:
        objects = [build_entry(o) for o in _read_objects(r)]
    except ProfileError as exc:
        if exc.path is not None or exc.message.startswith(source):
            raise
        raise ProfileError(exc.message, path=source, hint=exc.hint) from None
    meta = _meta(r)
    pid = profile_id or slug(name or std.get("name") or "imported")
    if meta is None:
        std.setdefault("fieldbus", "canopen")
        profile = make_profile(
            profile_id=pid, meta=None, standard=std, objects=objects, where=source
        )
    else:
        # The extras hold the exact profile; the standard identity and PDO counts win only
        # where someone edited them after export (they differ from what export writes).
        ident, pdo = std.pop("identity", None), std.pop("pdo", None)
        profile = make_profile(
            profile_id=pid, meta=meta, standard=std, objects=objects, where=source
        )
        vendor, product, _ = identity_numbers(profile)
        if ident and (
            ident.get("vendor_id", vendor) != vendor
            or ident.get("product_codes", [product])[0] != product
        ):
            profile = make_profile(
                profile_id=pid,
                meta=meta,
                standard={**std, "identity": ident},
                objects=objects,
                where=source,
            )
        if pdo and any(getattr(profile.pdo, k) != v for k, v in pdo.items()):
            profile = profile.model_copy(update={"pdo": profile.pdo.model_copy(update=pdo)})
    if name:
        profile = profile.model_copy(update={"name": name})
    return r, profile


def import_eds(
    text: str, *, profile_id: str, name: str | None = None, source: str = "<eds>"
) -> DeviceProfile:
    """A profile from the text of an EDS (or DCF: its ParameterValues are ignored)."""
    return _import(text, profile_id, name, source)[1]


def read_dcf(
    text: str, *, profile_id: str | None = None, name: str | None = None, source: str = "<dcf>"
) -> DcfContents:
    """The profile, ParameterValues, node id and bit rate (bit/s) of a DCF."""
    r, profile = _import(text, profile_id, name, source)
    comm = r.get("DeviceComissioning") or {}
    node_id = bitrate = None
    for key in ("nodeid", "baudrate"):
        raw = comm.get(key)
        if raw is None or not raw.strip():
            continue
        try:
            v = parse_int(raw)
        except ValueError:
            raise r.error(
                f"[{r.name('DeviceComissioning')}] {key}={raw!r}: not a number",
                "write NodeID as 1..127 and Baudrate in kbit/s, e.g. Baudrate=500",
            ) from None
        if key == "nodeid":
            node_id = v
        else:
            bitrate = v * 1000
    values: dict[ObjectAddress, Value] = {}
    for entry in profile.objects:
        for spec in entry.specs():
            sect = (
                f"{spec.index:04X}"
                if entry.object_type is ObjectType.VAR
                else f"{spec.index:04X}sub{spec.subindex:X}"
            )
            keys = r.get(sect)
            if keys is None:
                continue
            where = f"[{r.name(sect)}] ParameterValue"
            extra = keys.get(f"{EXTRA_PREFIX}parameter_value")
            if extra is not None:
                pv: Any = loads(extra, f"[{r.name(sect)}] {EXTRA_PREFIX}parameter_value")
                if isinstance(pv, dict) and "hex" in pv:
                    try:
                        pv = bytes.fromhex(str(pv["hex"]))
                    except ValueError:
                        raise r.error(
                            f"[{r.name(sect)}] {EXTRA_PREFIX}parameter_value: not hex bytes",
                            "remove the key and write ParameterValue as hex",
                        ) from None
                values[spec.address] = pv
            elif "parametervalue" in keys:
                raw = keys["parametervalue"]
                if raw.strip() or spec.data_type.is_string:
                    value = parse_param(raw, spec, node_id, where)
                    if value is not None:
                        values[spec.address] = value
        if entry.object_type is ObjectType.ARRAY:
            # Compact arrays carry their values in [xxxxValue] (CiA 306 §4.6.3.3).
            compact_vals = r.get(f"{entry.index:04X}Value")
            main = r.get(f"{entry.index:04X}") or {}
            if compact_vals and main.get("compactsubobj"):
                for spec in entry.specs():
                    raw = compact_vals.get(str(spec.subindex))
                    if spec.subindex and raw is not None and spec.address not in values:
                        value = parse_param(
                            raw, spec, node_id, f"[{entry.index:04X}Value] {spec.subindex}"
                        )
                        if value is not None:
                            values[spec.address] = value
    return DcfContents(profile=profile, values=values, node_id=node_id, bitrate=bitrate)


def import_dcf(
    text: str, *, profile_id: str | None = None, name: str | None = None, source: str = "<dcf>"
) -> tuple[DeviceProfile, dict[ObjectAddress, Value]]:
    """The profile and the configured values (ParameterValue) of a DCF."""
    c = read_dcf(text, profile_id=profile_id, name=name, source=source)
    return c.profile, c.values
