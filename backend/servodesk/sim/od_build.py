"""Build a python-canopen ``ObjectDictionary`` from a servodesk device profile.

The simulated CANopen device needs one for its ``LocalNode``; a master may use the same
dictionary for a ``RemoteNode``. Data type numbers are CiA 301's in both libraries, so they
carry over as they are; ``$NODEID`` defaults are resolved for the given node id.
"""

from __future__ import annotations

from typing import Any

from canopen import objectdictionary as od

from servodesk.domain.profile import DeviceProfile, ObjectSpec, ObjectType


def build_object_dictionary(profile: DeviceProfile, node_id: int) -> Any:
    """A ``canopen.ObjectDictionary`` holding every object of ``profile``."""
    d = od.ObjectDictionary()
    d.node_id = node_id
    specs_by_index: dict[int, list[ObjectSpec]] = {}
    for spec in profile.variables.values():
        specs_by_index.setdefault(spec.index, []).append(spec)
    for entry in profile.objects:
        specs = specs_by_index.get(entry.index, [])
        if entry.object_type is ObjectType.VAR:
            d.add_object(_variable(specs[0], node_id))
            continue
        group: Any = (
            od.ODArray(entry.name, entry.index)
            if entry.object_type is ObjectType.ARRAY
            else od.ODRecord(entry.name, entry.index)
        )
        group.description = entry.description or ""
        for spec in specs:
            group.add_member(_variable(spec, node_id))
        d.add_object(group)
    return d


def _variable(spec: ObjectSpec, node_id: int) -> Any:
    var = od.ODVariable(spec.name, spec.index, spec.subindex)
    var.data_type = int(spec.data_type)
    var.access_type = spec.access.value
    var.pdo_mappable = spec.pdo_mapping.value != "none"
    var.description = spec.description or ""
    var.unit = spec.unit or ""
    if spec.data_type.is_integer:
        var.min = int(spec.min) if spec.min is not None else None
        var.max = int(spec.max) if spec.max is not None else None
    default: Any = spec.default_value(node_id)
    if isinstance(default, bool):
        default = int(default)
    var.default = default
    var.value = default
    if spec.values:
        for value, text in spec.values.items():
            var.add_value_description(value, text)
    return var
