"""Ids that become parts of file names: the one allow-list they must pass.

A profile id names a backup file (``<backup id>-<profile id>.json``) and a profile's folder
(``<data dir>/profiles/<id>/``). It comes from files people upload and restore, so it is
checked before any path is built from it: "x/../../../tmp/anything" must never name a file
outside the data directory (the store also confirms every resolved path is inside it,
services/store.py ``path_inside``).
"""

from __future__ import annotations

import re

from servodesk.errors import ValidationError

#: Lower-case letters and digits first, then also ".", "_" and "-"; 64 characters at most.
#: No "/" or "\\" (another directory), no leading "." (a hidden file, "..").
ID_PATTERN = re.compile(r"[a-z0-9][a-z0-9._-]{0,63}")


def check_id(value: object, field: str) -> str:
    """``value`` if it is a safe id, else a ValidationError naming ``field`` and the rule."""
    # fullmatch: "$" of re.match would also take an id followed by a newline.
    if isinstance(value, str) and ID_PATTERN.fullmatch(value) and ".." not in value:
        return value
    shown = repr(value)[:80]
    raise ValidationError(
        f"{field} {shown} is not a valid id: ids are 1-64 characters of a-z, 0-9, '.', '_' "
        "and '-', starting with a letter or digit, without '..'",
        field=field,
        hint="use a file written by servodesk, or correct the id (e.g. cia402-generic)",
    )
