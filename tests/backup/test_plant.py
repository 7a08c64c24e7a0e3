"""A plant's backup (issue 50): every drive read at once, each saved on its own.

``POST /backups/plant`` and ``BackupService.backup_many``: requests to different nodes of one
CAN bus interleave (each node answers on its own SDO channel, CiA 301 §7.2.4.1), so the bus is
watched with a plain python-can tap for a request to one node sent while another node's
transfer is still open; a drive that does not answer is its own failed item, the others are
saved; each drive's backup holds what a backup of it alone holds.
"""

from __future__ import annotations

from collections.abc import AsyncIterator

import can
import httpx
import pytest
import pytest_asyncio

from servodesk.errors import LinkError
from servodesk.sim.canopen_device import NMT_PRE_OPERATIONAL, NMT_STOPPED
from tests.backup.conftest import Rig, close_rig, make_rig
from tests.sim_app import sim_client

pytestmark = pytest.mark.asyncio(loop_scope="module")
FAMILIES = ["cia402-generic", "hiwin-e", "smartris"]


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def rig(tmp_path_factory) -> AsyncIterator[Rig]:  # type: ignore[no-untyped-def]
    r = await make_rig(tmp_path_factory.mktemp("store"), FAMILIES, second=False)
    try:
        yield r
    finally:
        await close_rig(r)


def _interleaved(frames: list[can.Message]) -> int:
    """How often a request to one node went out while another node's transfer was open (its
    last request not yet answered): 0 when the drives were read one after the other."""
    open_: set[int] = set()
    overlaps = 0
    for m in frames:
        if 0x601 <= m.arbitration_id <= 0x67F:
            node = m.arbitration_id - 0x600
            if open_ - {node}:
                overlaps += 1
            open_.add(node)
        elif 0x581 <= m.arbitration_id <= 0x5FF:
            open_.discard(m.arbitration_id - 0x580)
    return overlaps


async def test_the_drives_are_read_at_once_and_each_backup_is_whole(rig: Rig) -> None:
    sessions = [rig.first[f] for f in FAMILIES]
    alone = [await rig.backups.backup(s) for s in sessions]
    tap = can.Bus(interface="virtual", channel=rig.channel)
    try:
        results = await rig.backups.backup_many(sessions, label="plant")
        frames = []
        while (m := tap.recv(0)) is not None:
            frames.append(m)
    finally:
        tap.shutdown()
    assert all(isinstance(r, dict) for r in results), results
    overlaps = _interleaved(frames)
    assert overlaps > 100, f"only {overlaps} requests went out beside another node's transfer"
    for s, one, many in zip(sessions, alone, results, strict=True):
        assert isinstance(many, dict)
        assert many["label"] == "plant" and many["drive_key"] == one["drive_key"]
        a, b = rig.backups.load(one["id"]), rig.backups.load(many["id"])
        assert [(e.address, e.raw) for e in a.entries] == [(e.address, e.raw) for e in b.entries]
        assert not b.unreadable, (s.id, b.unreadable)


async def test_a_silent_drive_is_its_own_failure_and_the_others_are_saved(rig: Rig) -> None:
    sessions = [rig.first[f] for f in FAMILIES]
    dev = rig.bus.devices[1]  # hiwin-e, node 2
    dev.set_nmt_state(NMT_STOPPED)  # CiA 301 §7.3.2.2.1: no SDO in STOPPED.
    try:
        before = {s.id: len(rig.backups.store.list_backups(None, s.profile.id)) for s in sessions}
        results = await rig.backups.backup_many(sessions)
    finally:
        dev.set_nmt_state(NMT_PRE_OPERATIONAL)
    assert isinstance(results[1], LinkError), results[1]
    assert isinstance(results[0], dict) and isinstance(results[2], dict)
    after = {s.id: len(rig.backups.store.list_backups(None, s.profile.id)) for s in sessions}
    assert [after[s.id] - before[s.id] for s in sessions] == [1, 0, 1]


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def api(tmp_path_factory) -> AsyncIterator[httpx.AsyncClient]:  # type: ignore[no-untyped-def]
    data = tmp_path_factory.mktemp("data")
    async with sim_client(data, "cia402-generic,smartris,lecsn-t", sdo_timeout=0.5) as c:
        yield c


async def test_the_api_backs_up_every_open_drive_and_refuses_what_it_cannot(
    api: httpx.AsyncClient,
) -> None:
    ids = [s["id"] for s in (await api.get("/sessions")).json()]
    assert len(ids) == 3
    r = await api.post("/backups/plant", json={"label": "line 3", "note": "before the change"})
    assert r.status_code == 200, r.text
    rep = r.json()
    assert rep["saved"] == 3 and rep["failed"] == 0 and rep["duration_s"] > 0
    assert [i["session"] for i in rep["items"]] == ids
    for i in rep["items"]:
        assert i["ok"] and i["backup"]["label"] == "line 3" and i["backup"]["entries"] > 20
        listed = (await api.get("/backups", params={"drive": i["backup"]["drive_key"]})).json()
        assert listed[0]["id"] == i["backup"]["id"]
    # Named sessions only; bad names are refused before anything is read.
    r = await api.post("/backups/plant", json={"sessions": [ids[2]]})
    assert r.status_code == 200 and [i["session"] for i in r.json()["items"]] == [ids[2]]
    r = await api.post("/backups/plant", json={"sessions": [ids[0], "no-such-drive"]})
    assert r.status_code == 404 and "no-such-drive" in r.json()["message"], r.text
    r = await api.post("/backups/plant", json={"sessions": [ids[1], ids[0], ids[1]]})
    assert r.status_code == 200 and [i["session"] for i in r.json()["items"]] == ids[1::-1]
    r = await api.post("/backups/plant", json={"sessions": []})
    assert r.status_code == 422 and "sessions" in r.text, r.text
    r = await api.post("/backups/plant", json={"label": "x" * 201})
    assert r.status_code == 422, r.text
