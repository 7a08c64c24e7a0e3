"""Export an imported profile again and read it back: the check that an import is lossless.

An EtherCAT profile goes out as ESI, every other one as EDS (servodesk writes no XDD; EDS
carries the same CANopen dictionary). :func:`roundtrip_difference` names the first field that
differs between the profile and its re-import, or None when they are the same.
"""

from __future__ import annotations

from typing import Any

from servodesk.devdesc.eds import import_eds
from servodesk.devdesc.eds_export import export_eds
from servodesk.devdesc.esi import import_esi
from servodesk.devdesc.esi_export import export_esi
from servodesk.domain.profile import DeviceProfile

__all__ = ["export_again", "first_difference", "roundtrip_difference"]


def export_again(profile: DeviceProfile) -> tuple[str, DeviceProfile]:
    """The profile written in its fieldbus's format, and that text read back."""
    if profile.fieldbus == "ethercat":
        text = export_esi(profile)
        return text, import_esi(text, profile_id=profile.id, source=f"{profile.id}.xml")
    text = export_eds(profile)
    return text, import_eds(text, profile_id=profile.id, source=f"{profile.id}.eds")


def first_difference(a: Any, b: Any, path: str = "") -> str | None:
    """Where two model dumps first differ (``.objects[3].default: 1 != 2``), or None."""
    if type(a) is not type(b):
        return f"{path}: {a!r} ({type(a).__name__}) != {b!r} ({type(b).__name__})"
    if isinstance(a, dict):
        for k in sorted(a.keys() | b.keys(), key=str):
            if k not in a or k not in b:
                return f"{path}.{k}: present on one side only"
            d = first_difference(a[k], b[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(a, list | tuple):
        if len(a) != len(b):
            return f"{path}: {len(a)} items != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            d = first_difference(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{path}: {a!r} != {b!r}"


def roundtrip_difference(profile: DeviceProfile) -> str | None:
    """The first difference between the profile and its export read back, or None."""
    _, back = export_again(profile)
    return first_difference(profile.model_dump(), back.model_dump())
