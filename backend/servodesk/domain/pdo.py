"""PDO mapping as pure data: read, validate, plan, lay out, pack and export process data.

The contract is docs/pdo.md. Four families map process data differently (``profile.pdo.kind``):

- ``canopen``: RPDO/TPDO communication (1400h/1800h+) and mapping (1600h/1A00h+) objects,
  remapped by the procedure of CiA 301 §7.5.2.35/36 in NMT pre-operational.
- ``ethercat``: mapping objects 1600h+/1A00h+ assigned to the sync managers by 1C12h/1C13h
  (ETG.1000.6; HIWIN 000 §3.1.2 gives the order of the writes).
- ``fixed``: a pre-assigned mapping that is shown and exported, never written.
- ``telegram``: a PROFIdrive telegram chosen by P922; telegrams with variable mapping are
  re-mapped on the twin through 1600h/1A00h (LECSN 004 §20.3).

Nothing here does I/O: the session service reads :func:`config_addresses`, hands the values to
:func:`parse_config`, and executes the :class:`Plan` that :func:`plan` returns.

This module is the public API (docs/pdo.md "Domain API"); the code lives in sibling modules:
``pdo_model`` (the dataclasses), ``pdo_objects`` (object dictionary: addresses, reading,
defaults, mappable objects), ``pdo_validate``, ``pdo_plan``, ``pdo_codec`` (layout, pack,
unpack), ``pdo_json`` (JSON and templates). Exporting a configuration (JSON, CSV, DCF, ESI) writes
device-description formats: devdesc/pdo_export.py.
"""

from __future__ import annotations

from servodesk.domain.pdo_codec import FD_LENGTHS, bus_cob_id, frame_length, layout, pack, unpack
from servodesk.domain.pdo_json import apply_template, config_from_json, config_to_json, templates
from servodesk.domain.pdo_model import COB_EXTENDED as COB_EXTENDED
from servodesk.domain.pdo_model import COB_INVALID as COB_INVALID
from servodesk.domain.pdo_model import COB_NO_RTR as COB_NO_RTR
from servodesk.domain.pdo_model import (
    Direction,
    MapEntry,
    Pdo,
    PdoComm,
    PdoConfig,
    PdoProblem,
    PdoStep,
    Plan,
    Slot,
    Template,
)
from servodesk.domain.pdo_objects import (
    config_addresses,
    config_values,
    default_config,
    default_values,
    mappable,
    parse_config,
)
from servodesk.domain.pdo_plan import full_plan, plan
from servodesk.domain.pdo_validate import validate

__all__ = [
    "FD_LENGTHS",
    "Direction",
    "MapEntry",
    "Pdo",
    "PdoComm",
    "PdoConfig",
    "PdoProblem",
    "PdoStep",
    "Plan",
    "Slot",
    "Template",
    "apply_template",
    "bus_cob_id",
    "config_addresses",
    "config_from_json",
    "config_to_json",
    "config_values",
    "default_config",
    "default_values",
    "frame_length",
    "full_plan",
    "layout",
    "mappable",
    "pack",
    "parse_config",
    "plan",
    "templates",
    "unpack",
    "validate",
]
