"""servodesk's CANopen link and a session against ``servodesk sim`` in a second process."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator

import pytest
from tests.simproc import sim_subprocess

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import ObjectAccessError
from servodesk.links.base import LinkParams
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager

GROUP = f"239.74.164.{10 + os.getpid() % 240}"


@pytest.fixture(scope="module")
def smartris_process() -> Iterator[subprocess.Popen[str]]:
    with sim_subprocess("smartris", 7, "udp_multicast", GROUP) as proc:
        yield proc


async def test_session_over_udp_multicast_detects_and_drives_the_family(
    smartris_process: subprocess.Popen[str],
) -> None:
    manager = SessionManager(ProfileCatalog(), EventHub())
    params = LinkParams(interface="udp_multicast", channel=GROUP, node_id=7, timeout=0.5)
    session = await manager.open(params)  # Profile detected from 1018h.
    try:
        assert session.profile.id == "smartris"
        assert session.identity.device_name
        value = await session.read_object(ObjectAddress(0x6502))
        assert value.value == 0x0C  # smartris 001: pv and tq only.
        with pytest.raises(ObjectAccessError) as info:
            await session.link.read(ObjectAddress(0x2FFF))
        assert info.value.code == 0x06020000
        # smartris 001 §5: controlword commands at least 40 ms apart (quirk); the session
        # spaces them, so enabling works across processes.
        state = await session.command("enable")
        assert state.state == "Operation enabled"
        state = await session.command("disable")
        assert state.state == "Switch on disabled"
    finally:
        await manager.close_all()
