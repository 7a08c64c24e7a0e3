"""The profiles' ``network:`` section (the Network configuration page, docs/profiles.md): refused
when it names an object the profile lacks or a key the schema does not know; every shipped
family has one that loads, cites its manual and names only objects a drive can be asked for."""

from __future__ import annotations

import json
import re
from typing import Any

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog, check_profile, parse_profile
from servodesk.errors import ProfileError

CATALOG = ProfileCatalog()
SHIPPED = ["cia402-generic", "ctmm04x", "hiwin-e", "lecsn-t", "smartris"]


def _profile(network: dict[str, Any]) -> dict[str, Any]:
    return {
        "id": "x",
        "name": "X",
        "vendor": "v",
        "fieldbus": "canopen",
        "objects": [
            {"index": 0x1017, "name": "Heartbeat", "data_type": "UNSIGNED16", "access": "rw"},
            {"index": 0x1010, "name": "Store", "data_type": "UNSIGNED32", "access": "wo"},
            {
                "index": 0x5F00,
                "name": "Twin only",
                "data_type": "UNSIGNED8",
                "access": "ro",
                "sim_only": True,
            },
        ],
        "network": {"summary": "How it is addressed.", "section": "m §1", **network},
    }


def _obj(address: str) -> dict[str, str]:
    return {"object": address, "note": "n", "section": "m §2"}


def test_an_object_the_profile_lacks_is_refused_by_name() -> None:
    p = parse_profile(_profile({"objects": [_obj("0x1017:00"), _obj("0x1018:01")]}))
    assert check_profile(p) == [
        "network.objects.1: 0x1018:01 is not an object of the profile",
    ]


def test_write_only_twin_only_and_repeated_objects_are_refused() -> None:
    p = parse_profile(
        _profile({"objects": [_obj("0x1010"), _obj("0x5F00:00"), _obj("0x1017"), _obj("1017h")]})
    )
    problems = check_profile(p)
    assert "network.objects.0: 0x1010 Store is write-only: the Network page reads it" in problems
    assert any(m.startswith("network.objects.1: 0x5F00:00 Twin only is") for m in problems)
    assert "network.objects.3: 1017h is listed twice" in problems
    assert len(problems) == 3


def test_unknown_keys_and_bad_addresses_are_refused_with_their_place() -> None:
    with pytest.raises(ProfileError, match=r"network\.colour: Extra inputs"):
        parse_profile(_profile({"colour": "red"}))
    with pytest.raises(ProfileError, match=r"network\.leds\.0\.blink: Extra inputs"):
        parse_profile(
            _profile(
                {"leds": [{"led": "NS", "state": "on", "meaning": "m", "section": "s", "blink": 2}]}
            )
        )
    with pytest.raises(ProfileError, match=r"network\.objects\.0\.object: .*'P9x'"):
        parse_profile(_profile({"objects": [_obj("P9x")]}))
    # A rule without its manual section is refused: the page cites every rule.
    with pytest.raises(ProfileError, match=r"network\.addressing\.0\.section"):
        parse_profile(_profile({"addressing": [{"text": "DIP switch 1-254"}]}))


@pytest.mark.parametrize("profile_id", SHIPPED)
def test_every_shipped_family_has_a_network_section_that_loads(profile_id: str) -> None:
    p = CATALOG.get(profile_id)
    assert check_profile(p) == []
    net = p.network
    assert net is not None, f"{profile_id} has no network section"
    assert net.summary and net.section and net.objects and net.addressing
    for o in net.objects:
        spec = p.spec(o.address)
        assert spec is not None and spec.access.readable and not spec.sim_only
    # Every entry cites the family's manual; servodesk's own simulated drive may cite servodesk.
    cited = {m.id for m in p.manuals} | ({"servodesk"} if p.vendor == "servodesk" else set())
    sections = [
        net.section,
        *(o.section for o in net.objects),
        *(r.section for r in net.addressing),
    ]
    for where in sections:
        assert any(where.startswith(m) for m in cited), f"{where!r} cites no manual of {p.id}"


@pytest.mark.parametrize("profile_id", ["ctmm04x", "hiwin-e", "lecsn-t", "smartris"])
def test_the_families_decode_their_leds_from_the_manual(profile_id: str) -> None:
    p = CATALOG.get(profile_id)
    assert p.network is not None
    leds = p.network.leds
    assert len(leds) >= 8
    manual = p.manuals[0].id
    assert all(led.section.startswith(manual) for led in leds)


def test_the_lecsn_network_section_has_the_telegram_and_the_rotary_switch_rule() -> None:
    p = CATALOG.get("lecsn-t")
    assert p.network is not None
    telegram = ObjectAddress.parse(p.pdo.telegram_object or "")
    assert p.spec(telegram) is not None and p.spec(telegram).pnu == 922  # type: ignore[union-attr]
    assert telegram in [o.address for o in p.network.objects]
    rules = " ".join(r.text for r in p.network.addressing)
    assert "SW2/SW3 = FFh: DHCP enabled" in rules
    states = {(led.led, led.state): led.meaning for led in p.network.leds}
    assert states[("Network Status", "red single flash")] == "Station name not set"
    assert states[("Network Status", "red double flash")] == "IP address not set"


def test_an_extending_profile_does_not_inherit_the_base_network_section(tmp_path: Any) -> None:
    d = tmp_path / "my-drive"
    d.mkdir()
    (d / "profile.yaml").write_text(
        "id: my-drive\nname: Mine\nvendor: me\nfieldbus: canopen\nextends: cia402-generic\n"
    )
    p = ProfileCatalog([tmp_path, *CATALOG.dirs]).get("my-drive")
    assert p.network is None and check_profile(p) == []


@pytest.mark.parametrize("pid", SHIPPED)
def test_network_texts_cite_manuals_not_source_files(pid: str) -> None:
    """The Network page shows every text and section to the engineer: a servodesk source file
    (cli/sim.py, sim/canopen_device.py) is nothing a user can open (issue 48)."""
    net = CATALOG.get(pid).network
    assert net is not None
    text = json.dumps(net.model_dump())
    assert not re.findall(r"[\w/]+\.py\b", text)
