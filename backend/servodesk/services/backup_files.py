"""A stored backup as plain data, and the pure parts of using one.

:class:`StoredFile` is what the store knows of a backup's file (its path and SHA-256), small
enough to hand to the documents' worker process (api/backup_documents.py), which opens the
file itself rather than have a large set pickled across. :func:`read_checked`,
:func:`units_profile` and :func:`comparison` are the same code whether they run there or in
:class:`servodesk.services.backup.BackupService`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from typing import Any

from servodesk.domain import paramset, paramset_compare
from servodesk.domain.address import ObjectAddress
from servodesk.domain.encoder_units import rescaled
from servodesk.domain.paramset import ParameterSet
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import NotFoundError, ValidationError


@dataclass(frozen=True)
class StoredFile:
    """A backup's file as the store records it: ``label``/``note`` are the store's (editable;
    the file keeps the ones it was written with)."""

    bid: str
    path: str
    name: str
    sha256: str
    profile_id: str
    directory: str
    label: str
    note: str

    def labelled(self, ps: ParameterSet) -> ParameterSet:
        return replace(ps, label=self.label, note=self.note)


def read_checked(f: StoredFile) -> bytes:
    """The file's bytes, refused when missing or changed since the store recorded it."""
    try:
        with open(f.path, "rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        raise NotFoundError(
            f"the file of backup {f.bid} ({f.name}) is missing",
            hint=f"it belongs in {f.directory}",
        ) from None
    if hashlib.sha256(data).hexdigest() != f.sha256:
        raise ValidationError(
            f"the file of backup {f.bid} ({f.name}) was changed after it was written "
            "(SHA-256 differs from the store)",
            field="backup",
            hint="restore the file from a copy; servodesk never edits backup files",
        )
    return data


def restore_targets(
    ps: ParameterSet, profile: DeviceProfile, map_names: bool
) -> list[ObjectAddress]:
    """The drive objects a restore of ``ps`` into a drive of ``profile`` touches: by name
    where asked and the profiles differ, else the set's own addresses."""
    if ps.profile_id != profile.id and map_names:
        rows = paramset_compare.map_by_name(ps.entries, profile)
        return [r.target for r in rows if r.target is not None]
    return [e.address for e in ps.entries]


def units_profile(ps: ParameterSet, profiles: dict[str, DeviceProfile]) -> DeviceProfile | None:
    """The profile whose scales give the set's engineering values: ``profiles``' entry,
    rescaled to the set's encoder when the drive's was not the profile's (None: unknown)."""
    profile = profiles.get(ps.profile_id)
    if profile is None:
        return None
    cpr = ps.counts_per_rev
    if cpr and cpr != profile.simulation.counts_per_rev:
        return rescaled(profile, cpr)
    return profile


def comparison(
    a: tuple[str, ParameterSet],
    b: tuple[str, ParameterSet],
    profile: DeviceProfile | None,
    *,
    include_same: bool = False,
) -> dict[str, Any]:
    """A Comparison (docs/api.md) of two labelled sets, in ``profile``'s units."""
    diffs, same = paramset_compare.compare(
        a[1].entries, b[1].entries, profile, include_same=include_same
    )
    equal = all(d["kind"] == "same" for d in diffs)
    # What a side lacks because the drive refused it is not compared: say so, or "N equal"
    # reads as the whole drive (issue 48).
    return {
        "a": a[0],
        "b": b[0],
        "equal": equal,
        "differences": diffs,
        "same": same,
        "a_unreadable": paramset.unreadable_dicts(a[1].unreadable),
        "b_unreadable": paramset.unreadable_dicts(b[1].unreadable),
    }
