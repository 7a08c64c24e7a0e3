"""A session recognises every family's twin from its identity and picks its profile."""

from __future__ import annotations

import pytest
from tests.conftest import StartSims

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager

FAMILIES = ["cia402-generic", "hiwin-e", "smartris", "ctmm04x", "lecsn-t"]


async def test_each_family_is_detected_and_non_canopen_twins_say_so(
    channel: str, sim_bus: StartSims
) -> None:
    catalog = ProfileCatalog()
    sim_bus(*((p, n + 1) for n, p in enumerate(FAMILIES)), catalog=catalog)
    manager = SessionManager(catalog, EventHub())
    try:
        for n, expected in enumerate(FAMILIES):
            s = await manager.open(LinkParams(interface="virtual", channel=channel, node_id=n + 1))
            assert s.profile.id == expected
            fieldbus = catalog.get(expected).fieldbus
            if fieldbus == "canopen":
                assert s.note is None
            else:
                assert s.note and "runs on CANopen" in s.note
    finally:
        await manager.close_all()


async def test_the_user_can_override_the_detected_profile(channel: str, sim_bus: StartSims) -> None:
    sim_bus(("smartris", 3))
    manager = SessionManager(ProfileCatalog(), EventHub())
    try:
        s = await manager.open(
            LinkParams(interface="virtual", channel=channel, node_id=3), "cia402-generic"
        )
        assert s.profile.id == "cia402-generic"
    finally:
        await manager.close_all()


@pytest.mark.parametrize("vendor", [None, 0x1234])
def test_an_unknown_identity_matches_no_profile(vendor: int | None) -> None:
    assert ProfileCatalog().match(vendor, 99, 1, None) is None
