"""Simulated drives of every family on one virtual bus, with sessions and backup services."""

from __future__ import annotations

import functools
import itertools
import os
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest_asyncio

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.services.backup import BackupService
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.services.restore import RestoreService
from servodesk.services.session import Session
from servodesk.services.store import Store
from servodesk.sim.bus import SimulatedBus

FAMILIES = ["cia402-generic", "hiwin-e", "smartris", "ctmm04x", "lecsn-t"]
_n = itertools.count()


@functools.cache
def catalog() -> ProfileCatalog:
    """One catalog for all tests here: parsing the profiles takes seconds."""
    return ProfileCatalog()


@dataclass
class Rig:
    bus: SimulatedBus
    manager: SessionManager
    backups: BackupService
    restores: RestoreService
    data_dir: Path
    channel: str
    first: dict[str, Session] = field(default_factory=dict)
    second: dict[str, Session] = field(default_factory=dict)


async def make_rig(
    data_dir: Path, families: list[str], *, second: bool, timeout: float = 0.3, url: str = ""
) -> Rig:
    """The drives of ``families`` and their sessions; the store in ``data_dir`` (``url``:
    on that store instead, a PostgreSQL of tests/store/conftest.py)."""
    channel = f"backup-{os.getpid()}-{next(_n)}"
    drives = [(pid, i + 1) for i, pid in enumerate(families)]
    serials: list[int | None] = [1001 + i for i in range(len(families))]
    if second:
        # A replacement drive of every family: same profile, another serial.
        drives += [(pid, i + 21) for i, pid in enumerate(families)]
        serials += [2001 + i for i in range(len(families))]
    cat = catalog()
    bus = SimulatedBus.start(drives, channel=channel, serials=serials, catalog=cat)
    hub = EventHub()
    manager = SessionManager(cat, hub, sdo_timeout=timeout, poll_hz=1.0)
    backups = BackupService(Store(data_dir, url), cat)
    backups.attach(hub)
    rig = Rig(bus, manager, backups, RestoreService(backups), data_dir, channel)
    for pid, node in drives:
        params = LinkParams(interface="virtual", channel=channel, node_id=node, timeout=timeout)
        s = await manager.open(params, pid)
        (rig.first if node < 21 else rig.second)[pid] = s
    return rig


async def close_rig(rig: Rig) -> None:
    await rig.manager.close_all()
    rig.bus.stop()
    rig.backups.store.close()


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rig(tmp_path_factory) -> AsyncIterator[Rig]:  # type: ignore[no-untyped-def]
    r = await make_rig(tmp_path_factory.mktemp("store"), FAMILIES, second=True)
    try:
        yield r
    finally:
        await close_rig(r)
