"""Every shipped profile loads, validates and is consistent (docs/profiles.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog, check_profile, parse_profile
from servodesk.errors import NotFoundError, ProfileError

CATALOG = ProfileCatalog()
IDS = CATALOG.ids()


def test_the_five_families_are_shipped() -> None:
    assert "cia402-generic" in IDS


@pytest.mark.parametrize("profile_id", IDS)
def test_profile_loads_and_is_consistent(profile_id: str) -> None:
    p = CATALOG.get(profile_id)
    assert check_profile(p) == []
    assert p.variables, "a profile without objects"
    # Every CiA 402 axis has a statusword and controlword with the standard types.
    sw, cw = p.spec(ObjectAddress(0x6041)), p.spec(ObjectAddress(0x6040))
    assert sw is not None and sw.data_type.name == "UNSIGNED16"
    assert cw is not None and cw.data_type.name == "UNSIGNED16" and cw.access.writable
    for spec in p.variables.values():
        assert spec.section, f"{spec.address} {spec.name} has no manual section"


@pytest.mark.parametrize("profile_id", IDS)
def test_modes_and_homing_methods_match_the_enumerations(profile_id: str) -> None:
    p = CATALOG.get(profile_id)
    homing = p.spec(ObjectAddress(0x6098))
    if p.homing_methods:
        assert homing is not None
    for m in p.modes:
        assert -128 <= m <= 127


def test_the_generic_profile_has_the_standard_objects() -> None:
    p = CATALOG.get("cia402-generic")
    required = [
        0x1000,
        0x1001,
        0x1003,
        0x1008,
        0x1009,
        0x100A,
        0x1010,
        0x1011,
        0x1017,
        0x1018,
        *range(0x1400, 0x1404),
        *range(0x1600, 0x1604),
        *range(0x1800, 0x1804),
        *range(0x1A00, 0x1A04),
        0x603F,
        0x6040,
        0x6041,
        *range(0x605A, 0x605F),
        0x6060,
        0x6061,
        *range(0x6064, 0x6068),
        0x606C,
        0x6071,
        0x6077,
        0x607A,
        0x607C,
        0x607D,
        0x607F,
        0x6081,
        *range(0x6083, 0x6086),
        0x6098,
        0x6099,
        0x609A,
        0x60F4,
        0x60FD,
        0x60FE,
        0x60FF,
        0x6502,
    ]
    missing = [f"{i:04X}h" for i in required if i not in p.entries]
    assert missing == []
    assert p.spec(ObjectAddress(0x1800, 1)).default == "$NODEID+0x180"  # type: ignore[union-attr]
    assert p.spec(ObjectAddress(0x1800, 1)).default_value(5) == 0x185  # type: ignore[union-attr]
    assert p.modes == (1, 3, 4, 6) and p.homing_methods == (35, 37)


def test_unknown_keys_and_bad_values_are_refused_with_the_place() -> None:
    base = {"id": "x", "name": "X", "vendor": "v", "fieldbus": "canopen"}
    with pytest.raises(ProfileError, match="colour"):
        parse_profile({**base, "colour": "red"})
    with pytest.raises(ProfileError, match=r"objects\.0"):
        parse_profile({**base, "objects": [{"index": 0x6040, "name": "cw"}]})
    with pytest.raises(ProfileError, match="unknown data type"):
        parse_profile(
            {
                **base,
                "objects": [{"index": 0x6040, "name": "cw", "data_type": "UINT17", "access": "rw"}],
            }
        )


def test_consistency_check_finds_planted_problems() -> None:
    p = parse_profile(
        {
            "id": "x",
            "name": "X",
            "vendor": "v",
            "fieldbus": "canopen",
            "objects": [
                {
                    "index": 0x2000,
                    "name": "a",
                    "data_type": "UNSIGNED8",
                    "access": "rw",
                    "default": 300,
                    "section": "s",
                },
                {
                    "index": 0x2001,
                    "name": "b",
                    "data_type": "UNSIGNED16",
                    "access": "rw",
                    "min": 10,
                    "max": 5,
                    "section": "s",
                },
                {
                    "index": 0x2002,
                    "name": "c",
                    "data_type": "VISIBLE_STRING",
                    "access": "ro",
                    "pdo_mapping": "tx",
                    "section": "s",
                },
                {
                    "index": 0x2003,
                    "name": "d",
                    "data_type": "UNSIGNED8",
                    "access": "ro",
                    "pdo_mapping": "rx",
                    "section": "s",
                },
                {
                    "index": 0x2000,
                    "name": "again",
                    "data_type": "UNSIGNED8",
                    "access": "rw",
                    "section": "s",
                },
            ],
            "errors": [
                {"table": "emcy", "code": 0x1000, "name": "a"},
                {"table": "emcy", "code": 0x1000, "name": "b"},
            ],
        }
    )
    problems = "\n".join(check_profile(p))
    assert "default 300 is above max 255" in problems
    assert "min 10 is above max 5" in problems
    assert "PDO-mappable but VISIBLE_STRING has no size" in problems
    assert "RPDO-mappable but not writable" in problems
    assert "0x2000: defined 2 times" in problems
    assert "code 0x1000 defined 2 times" in problems


def test_unknown_profile_lists_the_known_ones(tmp_path: Path) -> None:
    with pytest.raises(NotFoundError) as info:
        CATALOG.get("no-such-drive")
    assert "cia402-generic" in (info.value.hint or "")


def test_a_user_directory_shadows_and_extends(tmp_path: Path) -> None:
    d = tmp_path / "my-drive"
    d.mkdir()
    (d / "profile.yaml").write_text(
        "id: my-drive\nname: Mine\nvendor: me\nfieldbus: canopen\nextends: cia402-generic\n"
        "objects:\n  - {index: 0x2000, name: Gain, data_type: UNSIGNED16, access: rw,"
        " default: 5, section: 'my manual 1.2'}\n"
    )
    cat = ProfileCatalog([tmp_path, *CATALOG.dirs])
    p = cat.get("my-drive")
    assert p.spec(ObjectAddress(0x2000)) is not None
    assert p.spec(ObjectAddress(0x6041)) is not None  # From the generic profile.
    assert check_profile(p) == []
