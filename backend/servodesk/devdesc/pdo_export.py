"""PDO export: the final layout for the PLC programmer.

:func:`export` writes a configuration as JSON (the PdoLayout body plus every active PDO's
layout), CSV (one row per slot), a CiA 306 DCF with the PDO objects' ParameterValue, or an
ETG.2000 ESI ``<RxPdo>``/``<TxPdo>`` fragment.
"""

from __future__ import annotations

import csv
import io
import json
from typing import Any, Literal

from servodesk.devdesc.eds_export import section_text, spec_section, value_keys
from servodesk.devdesc.esi_common import type_of
from servodesk.domain.datatypes import DataType
from servodesk.domain.pdo_codec import layout
from servodesk.domain.pdo_json import config_to_json
from servodesk.domain.pdo_model import Direction, PdoConfig
from servodesk.domain.pdo_objects import config_values, rules_of
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import ValidationError


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
        section_text("DeviceComissioning", {"NodeID": f"0x{node_id:02X}"}),
    ]
    indexes = sorted({a.index for a in values})
    for idx in indexes:
        entry = profile.entries.get(idx)
        if entry is not None and entry.subs:
            subs = [a for a in profile.variables if a.index == idx]
            parts.append(
                section_text(
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
            keys = spec_section(spec)
            keys = {k: v for k, v in keys.items() if not k.startswith("servodesk_")}
            keys.update(value_keys(spec, values[addr]))
            name = (
                f"{idx:04X}"
                if entry is not None and not entry.subs
                else f"{idx:04X}sub{addr.subindex:X}"
            )
            parts.append(section_text(name, keys))
    return "\n".join(parts)


def _export_esi(profile: DeviceProfile, config: PdoConfig) -> str:
    import xml.etree.ElementTree as ET

    chunks: list[str] = []
    for d, tag, sm in ((Direction.RX, "RxPdo", "2"), (Direction.TX, "TxPdo", "3")):
        active = {p.mapping_index for p in config.active(d)}
        for p in config.of(d):
            attrs = {"Fixed": "1" if rules_of(profile).kind == "fixed" else "0"}
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
                        tn = type_of(s.data_type, spec.default if spec else None)[0]
                        ET.SubElement(ent, "DataType").text = "BOOL" if s.bits == 1 else tn
            ET.indent(el, space="  ")
            chunks.append(ET.tostring(el, encoding="unicode"))
    return "\n".join(chunks) + "\n"
