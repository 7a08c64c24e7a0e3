"""A profile's increment scales, rescaled to the encoder a drive reports in 608Fh.

A profile writes the engineering scale of every object counted in encoder increments
(6064h in deg, 606Ch in rpm, 6083h in rpm/s, ...) for one encoder: the one its simulation
section names (``simulation.counts_per_rev``; ``check_profile`` holds the deg scales to it).
A drive with another encoder, a real motor or a twin on a plant file at 2^20 counts, says
so in 608Fh (CiA 402-2 §6.9.4: sub 1 encoder increments per sub 2 motor revolutions). A
session on such a drive works with a copy of the profile whose increment scales are
multiplied by ``profile counts / drive counts`` (services/session.py), so that every page,
export and tuning shows the axis's own degrees and rpm. The raw values are the drive's and
are never touched.
"""

from __future__ import annotations

from typing import Any

from servodesk.domain.profile import DeviceProfile, ObjectEntry

#: CiA 402-2 §6.9.4 position encoder resolution: increments (sub 1) per revolutions (sub 2).
INCREMENT_UNITS = frozenset({"inc", "inc/s", "inc/s²", "inc/s^2"})


def counts_per_rev_from(increments: int, revolutions: int) -> float | None:
    """Counts per motor revolution from 608Fh:01 / 608Fh:02; None when the drive does not
    say (a 0 in either: smartris documents 608Fh as not usable, 001 Table 3-2)."""
    if increments <= 0 or revolutions <= 0:
        return None
    return increments / revolutions


def rescaled(profile: DeviceProfile, counts_per_rev: float) -> DeviceProfile:
    """``profile`` with the scales of its objects counted in increments, and its simulation
    section's ``counts_per_rev``, for an encoder of ``counts_per_rev`` counts per revolution.

    Only objects with an engineering unit change (a raw-only increment object has nothing to
    convert). The copy keeps the profile's id: it is the same family, on another motor.
    """
    f = profile.simulation.counts_per_rev / counts_per_rev
    objects = tuple(_entry(e, f) for e in profile.objects)
    sim = profile.simulation.model_copy(update={"counts_per_rev": round(counts_per_rev)})
    # A new model (not model_copy): the copy would carry the cached ``variables`` along.
    fields: dict[str, Any] = {name: getattr(profile, name) for name in type(profile).model_fields}
    fields.update(objects=objects, simulation=sim)
    return type(profile)(**fields)


def _entry(e: ObjectEntry, f: float) -> ObjectEntry:
    own = e.raw_unit in INCREMENT_UNITS and e.unit is not None
    subs = []
    for s in e.subs:
        raw = s.raw_unit if s.raw_unit is not None else e.raw_unit
        unit = s.unit if s.unit is not None else e.unit
        # A sub's scale of 1.0 means "the entry's" (ObjectEntry.specs), which changes with it.
        if s.scale != 1.0 and raw in INCREMENT_UNITS and unit is not None:
            s = s.model_copy(update={"scale": s.scale * f})
        subs.append(s)
    update: dict[str, Any] = {"subs": tuple(subs)}
    if own:
        update["scale"] = e.scale * f
    return e.model_copy(update=update)
