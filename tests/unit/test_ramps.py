"""Which kind of ramp a family's 6083h / 6084h hold, from the profile's raw unit."""

from __future__ import annotations

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.domain.ramps import ramp_kind


@pytest.mark.parametrize(
    ("profile", "kind"),
    [
        ("cia402-generic", "rate"),  # CiA 402-2 §6.5: units per s²
        ("hiwin-e", "rate"),
        ("lecsn-t", "time"),  # 004 §20.9.3.10 (7): ms to the rated speed
        ("ctmm04x", "register"),  # 003 §5-3-1: PMC842SR rate data
    ],
)
def test_each_familys_ramp_objects(profile: str, kind: str) -> None:
    catalog = ProfileCatalog()
    for index in (0x6083, 0x6084):
        spec = catalog.get(profile).spec(ObjectAddress(index))
        assert spec is not None
        assert ramp_kind(spec.raw_unit) == kind, (profile, spec.raw_unit)


def test_units_written_every_way() -> None:
    assert ramp_kind(None) == "rate"  # An object without a unit: CiA 402's default.
    assert ramp_kind("inc/s^2") == ramp_kind("inc / s2") == ramp_kind("u.u./s²") == "rate"
    assert ramp_kind(" ms ") == "time"
    assert ramp_kind("PMC842SR RATE DATA") == "register"
