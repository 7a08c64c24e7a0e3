"""EDS and DCF export (CiA 306 v1.3 electronic data sheets) from servodesk profiles.

Writes the INI layout CiA 306 §4 describes ([FileInfo], [DeviceInfo], [DummyUsage],
[Comments], the three object lists and one section per index and sub-index). Profile fields
that EDS has no key for (unit, scale, group, description, ...) are written as
``servodesk_<field>=<JSON>`` keys in the object sections, and profile-level data as
``servodesk_profile`` in [FileInfo]. A key is only written when the standard keys alone would
not reproduce the field on import (devdesc/eds.py), so a round trip is lossless while
third-party tools, which ignore unknown keys (CiA 306 §4.1), see an ordinary EDS.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from servodesk.devdesc._common import (
    ENTRY_FIELDS,
    EXTRA_PREFIX,
    SPEC_FIELDS,
    ascii_text,
    diff,
    dumps,
    parse_number,
    profile_meta,
    same,
)
from servodesk.devdesc.eds import entry_fields, identity_numbers, parse_param, var_fields
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, codec
from servodesk.domain.profile import (
    DeviceProfile,
    ObjectEntry,
    ObjectSpec,
    ObjectType,
    PdoMapping,
)
from servodesk.errors import ProfileError, ValidationError

__all__ = ["export_dcf", "export_eds"]

#: CiA 306 §4.6.3.2 object codes.
_OBJECT_CODES = {ObjectType.VAR: 0x7, ObjectType.ARRAY: 0x8, ObjectType.RECORD: 0x9}
#: CiA 306 §4.5.3: the bit rates [DeviceInfo] declares with BaudRate_<kbit/s>.
_BAUD_RATES = (10, 20, 50, 125, 250, 500, 800, 1000)
#: CiA 306 §4.6.2: objects every CANopen device has.
_MANDATORY = frozenset({0x1000, 0x1001, 0x1018})


# --------------------------------------------------------------------------------------------
# Export


def _fmt_number(v: int | float, dt: DataType, index: int) -> str:
    if isinstance(v, float):
        if dt.is_integer and v.is_integer():
            return str(int(v))
        return repr(v)
    if dt.is_real or dt.is_signed or v < 0:
        return str(v)
    # COB-IDs and PDO mapping entries read best in hex (CiA 301 §7.5.2.35 ff. print them so).
    if dt.bits >= 32 and 0x1000 <= index <= 0x1FFF:
        return f"0x{v:0{dt.bits // 4}X}"
    return str(v)


def _fmt_value(v: Any, dt: DataType, index: int) -> str | None:
    """The text of a DefaultValue / ParameterValue key, or None for no key."""
    if v is None:
        return None
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, bytes):
        return v.hex().upper()
    if isinstance(v, int | float):
        return _fmt_number(v, dt, index)
    text = str(v)
    if dt.is_integer and "$NODEID" in text.upper():
        return text.replace(" ", "")
    if dt.is_numeric:
        try:
            return _fmt_number(parse_number(text, dt), dt, index)
        except ValueError:
            return ascii_text(text)
    if dt in (DataType.OCTET_STRING, DataType.DOMAIN):
        return text.replace(" ", "").upper()
    return ascii_text(text)


def _var_keys(spec: ObjectSpec) -> dict[str, str]:
    """The standard CiA 306 keys of one variable (object or sub-index section)."""
    dt = spec.data_type
    keys = {
        "ParameterName": ascii_text(spec.name)[:241],  # CiA 306 §4.6.3.2: at most 241 chars.
        "ObjectType": "0x7",
        "DataType": f"0x{int(dt):04X}",
        "AccessType": spec.access.value,
    }
    default = _fmt_value(spec.default, dt, spec.index)
    if default is not None:
        keys["DefaultValue"] = default
    if dt.is_numeric:
        if spec.min is not None:
            keys["LowLimit"] = _fmt_number(spec.min, dt, spec.index)
        if spec.max is not None:
            keys["HighLimit"] = _fmt_number(spec.max, dt, spec.index)
    keys["PDOMapping"] = "1" if spec.pdo_mapping is not PdoMapping.NONE else "0"
    return keys


def _extras(
    actual: Mapping[str, Any], baseline: Mapping[str, Any], names: tuple[str, ...], model: Any
) -> dict[str, str]:
    differing = diff(actual, baseline, names)
    if not differing:
        return {}
    as_json = model.model_dump(mode="json", include=set(differing))
    return {f"{EXTRA_PREFIX}{n}": dumps(as_json[n]) for n in differing}


def spec_section(spec: ObjectSpec) -> dict[str, str]:
    keys = _var_keys(spec)
    try:
        baseline = var_fields({k.lower(): v for k, v in keys.items()}, spec.index, "<export>")
    except ProfileError:
        # A value the standard keys cannot express (e.g. a default that is not a number of
        # the object's type): leave the standard key out, the servodesk_ key carries it.
        for k in ("DefaultValue", "LowLimit", "HighLimit"):
            keys.pop(k, None)
        baseline = var_fields({k.lower(): v for k, v in keys.items()}, spec.index, "<export>")
    actual = spec.model_dump()
    keys.update(_extras(actual, baseline, SPEC_FIELDS, spec))
    return keys


def _entry_section(entry: ObjectEntry) -> dict[str, str]:
    specs = list(entry.specs())
    keys = {
        "ParameterName": ascii_text(entry.name)[:241],
        "ObjectType": f"0x{_OBJECT_CODES[entry.object_type]:X}",
        "SubNumber": f"0x{len(specs):X}",
    }
    baseline = entry_fields({k.lower(): v for k, v in keys.items()})
    keys.update(_extras(entry.model_dump(), baseline, ENTRY_FIELDS, entry))
    return keys


def section_text(name: str, keys: Mapping[str, str]) -> str:
    lines = [f"[{name}]"]
    lines.extend(f"{k}={v}" for k, v in keys.items())
    return "\n".join(lines) + "\n"


def export_eds(
    profile: DeviceProfile,
    *,
    node_id: int | None = None,
    values: Mapping[ObjectAddress, Value] | None = None,
    bitrate: int | None = None,
) -> str:
    """The profile as an EDS; with ``node_id`` or ``values`` as a DCF (see :func:`export_dcf`).

    ``bitrate`` (bit/s) goes to [DeviceComissioning] Baudrate of a DCF.
    """
    dcf = node_id is not None or values is not None
    vals = dict(values or {})
    if dcf:
        _check_values(profile, vals)
    vendor, product, revision = identity_numbers(profile)
    parts: list[str] = []
    suffix = "dcf" if dcf else "eds"
    file_info = {
        "FileName": f"{profile.id}.{suffix}",
        "FileVersion": "1",
        "FileRevision": "0",
        "EDSVersion": "4.0",
        "Description": ascii_text(profile.name)[:243],
        "CreatedBy": "servodesk",
        f"{EXTRA_PREFIX}profile": profile_meta(profile),
    }
    parts.append(section_text("FileInfo", file_info))
    can = profile.fieldbus == "canopen"
    device_info: dict[str, str] = {
        "VendorName": ascii_text(profile.vendor)[:244],
        "VendorNumber": f"0x{vendor:08X}",
        "ProductName": ascii_text(profile.name)[:243],
        "ProductNumber": f"0x{product:08X}",
        "RevisionNumber": f"0x{revision:08X}",
    }
    # The profile model has no bit-rate list: a CANopen family declares the CiA 301 §7.3.2
    # rates; other fieldbuses (an EDS of an EtherCAT CoE dictionary) declare none.
    for rate in _BAUD_RATES:
        device_info[f"BaudRate_{rate}"] = "1" if can else "0"
    device_info.update(
        {
            "SimpleBootUpMaster": "0",
            "SimpleBootUpSlave": "1",
            "Granularity": "8",
            "DynamicChannelsSupported": "0",
            "GroupMessaging": "0",
            "NrOfRXPDO": str(profile.pdo.rpdo_count),
            "NrOfTXPDO": str(profile.pdo.tpdo_count),
            "LSS_Supported": "0",
        }
    )
    parts.append(section_text("DeviceInfo", device_info))
    parts.append(section_text("DummyUsage", {f"Dummy{i:04d}": "0" for i in range(1, 8)}))
    comment_lines = _wrap(ascii_text(profile.description or ""), 200) if profile.description else []
    comments = {"Lines": str(len(comment_lines))}
    comments.update({f"Line{i + 1}": line for i, line in enumerate(comment_lines)})
    parts.append(section_text("Comments", comments))
    if dcf:
        comm = {"NodeID": str(node_id if node_id is not None else 0)}
        comm["NodeName"] = ascii_text(profile.name)[:246]
        comm["Baudrate"] = str((bitrate or 500_000) // 1000)
        comm["NetNumber"] = "1"
        comm["NetworkName"] = "servodesk"
        comm["CANopenManager"] = "0"
        parts.append(section_text("DeviceComissioning", comm))

    entries = sorted(profile.objects, key=lambda e: e.index)
    lists: dict[str, list[ObjectEntry]] = {
        "MandatoryObjects": [e for e in entries if e.index in _MANDATORY],
        "OptionalObjects": [
            e for e in entries if e.index not in _MANDATORY and not 0x2000 <= e.index <= 0x5FFF
        ],
        "ManufacturerObjects": [e for e in entries if 0x2000 <= e.index <= 0x5FFF],
    }
    for list_name, members in lists.items():
        keys = {"SupportedObjects": str(len(members))}
        keys.update({str(i + 1): f"0x{e.index:04X}" for i, e in enumerate(members)})
        parts.append(section_text(list_name, keys))
        for e in members:
            parts.extend(_object_sections(e, vals if dcf else None))
    return "\n".join(parts)


def _wrap(text: str, width: int) -> list[str]:
    words, lines, cur = text.split(), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}" if cur else w
    if cur:
        lines.append(cur)
    return lines


def value_keys(spec: ObjectSpec, value: Value) -> dict[str, str]:
    text = _fmt_value(value, spec.data_type, spec.index)
    keys = {"ParameterValue": text if text is not None else ""}
    try:
        back = parse_param(keys["ParameterValue"], spec, node_id=None, where="<export>")
    except ProfileError:
        back = None
    if not same(back, value):
        keys[f"{EXTRA_PREFIX}parameter_value"] = dumps(
            {"hex": value.hex()} if isinstance(value, bytes) else value
        )
    return keys


def _object_sections(entry: ObjectEntry, values: Mapping[ObjectAddress, Value] | None) -> list[str]:
    specs = list(entry.specs())
    name = f"{entry.index:04X}"
    if entry.object_type is ObjectType.VAR:
        keys = spec_section(specs[0])
        if values is not None and specs[0].address in values:
            keys.update(value_keys(specs[0], values[specs[0].address]))
        return [section_text(name, keys)]
    out = [section_text(name, _entry_section(entry))]
    for spec in specs:
        keys = spec_section(spec)
        if values is not None and spec.address in values:
            keys.update(value_keys(spec, values[spec.address]))
        out.append(section_text(f"{name}sub{spec.subindex:X}", keys))
    return out


def _check_values(profile: DeviceProfile, values: Mapping[ObjectAddress, Value]) -> None:
    for addr, v in values.items():
        spec = profile.spec(addr)
        if spec is None:
            raise ValidationError(
                f"{addr} is not an object of profile {profile.id}",
                field=str(addr),
                hint="a DCF holds values of the profile's own objects only",
            )
        try:
            codec(spec.data_type).encode(v)
        except ValidationError as exc:
            raise ValidationError(
                f"{addr} {spec.name}: {exc.message}",
                field=str(addr),
                hint=exc.hint or f"give a {spec.data_type.name} value",
            ) from None


def export_dcf(
    profile: DeviceProfile,
    node_id: int,
    values: Mapping[ObjectAddress, Value],
    *,
    bitrate: int | None = None,
) -> str:
    """A DCF (CiA 306 §5): the EDS plus ParameterValue per configured object and
    [DeviceComissioning] NodeID / Baudrate (kbit/s)."""
    if not 1 <= node_id <= 127:
        raise ValidationError(
            f"node id {node_id} is outside 1..127",
            field="node_id",
            hint="CANopen node ids are 1..127 (CiA 301 §7.2.1)",
        )
    return export_eds(profile, node_id=node_id, values=values, bitrate=bitrate)


# --------------------------------------------------------------------------------------------
# Import
