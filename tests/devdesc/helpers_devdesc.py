"""Comparison helpers shared by the device-description tests."""

from __future__ import annotations

from functools import cache
from typing import Any

from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.domain.profile_loader import ProfileCatalog, parse_profile


def profile_ids() -> list[str]:
    """Every profile of the checkout, read at test time (families are being added)."""
    return ProfileCatalog().ids()


@cache
def load(profile_id: str) -> DeviceProfile:
    """A shipped profile, loaded once per test session (profiles are immutable)."""
    return ProfileCatalog().get(profile_id)


def strict_equal(a: Any, b: Any) -> bool:
    """Equal and of the same type, recursively (1 != 1.0 != True here)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(strict_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(strict_equal(a[k], b[k]) for k in a)
    return bool(a == b)


def variable_differences(a: DeviceProfile, b: DeviceProfile) -> list[str]:
    """Field-by-field differences of the flattened variables of two profiles."""
    out: list[str] = []
    missing = set(a.variables) ^ set(b.variables)
    out.extend(f"{addr}: only in one profile" for addr in sorted(missing))
    for addr, sa in a.variables.items():
        sb = b.variables.get(addr)
        if sb is None:
            continue
        for name in ObjectSpec.model_fields:
            va, vb = getattr(sa, name), getattr(sb, name)
            if not strict_equal(va, vb):
                out.append(f"{addr} {name}: {va!r} != {vb!r}")
    return out


def entry_differences(a: DeviceProfile, b: DeviceProfile) -> list[str]:
    """Differences of the per-index fields (name, object type, group, ...) except subs."""
    out: list[str] = []
    for idx, ea in a.entries.items():
        eb = b.entries.get(idx)
        if eb is None:
            out.append(f"0x{idx:04X}: missing")
            continue
        for name in type(ea).model_fields:
            if name != "subs" and not strict_equal(getattr(ea, name), getattr(eb, name)):
                out.append(f"0x{idx:04X} {name}: {getattr(ea, name)!r} != {getattr(eb, name)!r}")
    return out


def profile_level_differences(a: DeviceProfile, b: DeviceProfile) -> list[str]:
    da = a.model_dump(exclude={"objects"})
    db = b.model_dump(exclude={"objects"})
    return [f"{k}: {da[k]!r} != {db.get(k)!r}" for k in da if not strict_equal(da[k], db.get(k))]


def edge_profile() -> DeviceProfile:
    """A profile with every awkward value the EDS writer must carry losslessly."""
    return parse_profile(
        {
            "id": "edge-case",
            "name": "Edge; case drive ünïcode",
            "vendor": "servodesk tests",
            "fieldbus": "canopen",
            "description": "Line one;\nline two with = and : and # and % signs.",
            "groups": [{"id": "g", "name": "G"}],
            "objects": [
                {
                    "index": 0x1000,
                    "name": "Device type",
                    "data_type": "UNSIGNED32",
                    "access": "ro",
                    "default": 0x20192,
                    "group": "g",
                },
                {
                    "index": 0x2000,
                    "name": "Gain ; with comment start",
                    "name_local": "ゲイン",
                    "data_type": "REAL32",
                    "access": "rw",
                    "default": 0,
                    "min": -1.5,
                    "max": 100,
                    "unit": "1/s",
                    "scale": 0.001,
                    "raw_unit": "0.001/s",
                    "group": "g",
                    "persist": True,
                    "description": "  leading spaces\nand a newline",
                    "section": "manual §1.2",
                    "pnu": 8192,
                    "symbol": "PA01",
                    "writable_in": ["switch_on_disabled", "preop"],
                },
                {
                    "index": 0x2001,
                    "name": "Float default",
                    "data_type": "REAL64",
                    "access": "rw",
                    "default": 1e-7,
                    "group": "g",
                },
                {
                    "index": 0x2002,
                    "name": "Hex text default",
                    "data_type": "UNSIGNED16",
                    "access": "rw",
                    "default": "0x10",
                    "values": {0: "off", 16: "on"},
                },
                {
                    "index": 0x2003,
                    "name": "Text",
                    "data_type": "VISIBLE_STRING",
                    "access": "rw",
                    "default": "  spaced ; text  ",
                },
                {
                    "index": 0x2004,
                    "name": "Bytes",
                    "data_type": "OCTET_STRING",
                    "access": "rw",
                    "default": "01 02 ab",
                },
                {
                    "index": 0x2005,
                    "name": "Extremes",
                    "object_type": "record",
                    "group": "g",
                    "unit": "inc",
                    "subs": [
                        {
                            "sub": 0,
                            "name": "Count",
                            "data_type": "UNSIGNED8",
                            "access": "const",
                            "default": 3,
                        },
                        {
                            "sub": 1,
                            "name": "i64",
                            "data_type": "INTEGER64",
                            "access": "rw",
                            "default": -(1 << 63),
                            "min": -(1 << 63),
                            "max": (1 << 63) - 1,
                        },
                        {
                            "sub": 2,
                            "name": "u64",
                            "data_type": "UNSIGNED64",
                            "access": "rwr",
                            "default": (1 << 64) - 1,
                            "pdo_mapping": "tx",
                        },
                        {
                            "sub": 3,
                            "name": "bool",
                            "data_type": "BOOLEAN",
                            "access": "rww",
                            "default": 1,
                            "pdo_mapping": "rx",
                            "process": True,
                        },
                    ],
                },
                {
                    "index": 0x1800,
                    "name": "TPDO1",
                    "object_type": "record",
                    "subs": [
                        {
                            "sub": 0,
                            "name": "Highest",
                            "data_type": "UNSIGNED8",
                            "access": "const",
                            "default": 1,
                        },
                        {
                            "sub": 1,
                            "name": "COB-ID",
                            "data_type": "UNSIGNED32",
                            "access": "rw",
                            "default": "$NODEID+0x180",
                        },
                    ],
                },
            ],
        }
    )
