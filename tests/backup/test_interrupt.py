"""A restore interrupted by a silent drive or a drive reset: the report names exactly what
was written, the store keeps it item by item, and resume completes it."""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable

import pytest
import pytest_asyncio

from servodesk.domain.address import ObjectAddress as A
from servodesk.sim.canopen_device import NMT_PRE_OPERATIONAL, NMT_STOPPED
from tests.backup.conftest import Rig, close_rig, make_rig
from tests.backup.helpers import change_pdo, change_plain

pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def small(tmp_path_factory) -> AsyncIterator[Rig]:  # type: ignore[no-untyped-def]
    r = await make_rig(tmp_path_factory.mktemp("store"), ["cia402-generic"], second=False)
    try:
        yield r
    finally:
        await close_rig(r)


def hook_after(rig: Rig, n: int, action: Callable[[], None]) -> list[A]:
    """Record every write the drive receives; after the n-th, run ``action`` (once)."""
    drive = rig.bus.drives[0]
    seen: list[A] = []

    def on_write(index: int, sub: int, value: object) -> None:
        seen.append(A(index, sub))
        if len(seen) == n:
            action()

    drive.on_write(on_write)
    return seen


def unhook(rig: Rig) -> None:
    rig.bus.drives[0]._write_listeners.clear()


async def test_bus_loss_mid_restore_is_reported_item_by_item_and_resumed(small: Rig) -> None:
    s = small.first["cia402-generic"]
    dev = small.bus.devices[0]
    info = await small.backups.backup(s)
    ps = small.backups.load(info["id"])
    changed = await change_plain(s, ps, 8) + await change_pdo(s)
    assert len(changed) >= 10
    # The drive stops answering SDOs (NMT stopped, CiA 301 §7.3.2.2.1) after its 4th write:
    # that write lands, its read-back gets no answer.
    seen = hook_after(small, 4, lambda: dev.set_nmt_state(NMT_STOPPED))
    try:
        rep = await small.restores.restore(s, info["id"], client="t")
    finally:
        unhook(small)
    assert rep["interrupted"] and not rep["finished"] and not rep["stored"]
    written = [i["address"] for i in rep["items"] if i["status"] == "written"]
    pending = [i for i in rep["items"] if i["status"] == "pending"]
    # Exactly the first three writes were written and verified; the fourth is pending.
    assert written == [str(a) for a in seen[:3]]
    assert pending[0]["address"] == str(seen[3]) and "interrupted" in pending[0]["message"]
    assert rep["counts"]["written"] + rep["counts"]["pending"] == len(changed)
    # The same report comes back from the store (it was persisted as it went).
    assert small.restores.report(rep["id"])["items"] == rep["items"]

    dev.set_nmt_state(NMT_PRE_OPERATIONAL)  # The drive is back.
    done = await small.restores.resume(rep["id"], s, client="t")
    assert done["finished"] and not done["interrupted"] and done["stored"]
    assert done["counts"]["written"] == len(changed) and done["counts"]["pending"] == 0
    cmp = small.backups.compare(
        ("drive", await small.backups.read_set(s, operation=None)), ("b", ps)
    )
    assert cmp["equal"], cmp["differences"]


async def test_drive_reset_mid_restore_rewrites_what_it_lost(small: Rig) -> None:
    s = small.first["cia402-generic"]
    dev = small.bus.devices[0]
    info = await small.backups.backup(s)
    ps = small.backups.load(info["id"])
    changed = await change_plain(s, ps, 6)
    await s.store()  # The changed values are now the drive's stored ones.

    def power_cycle_then_silent() -> None:
        dev.reset_node()  # Stored values come back: the writes so far are lost.
        dev.set_nmt_state(NMT_STOPPED)

    seen = hook_after(small, 3, power_cycle_then_silent)
    try:
        rep = await small.restores.restore(s, info["id"])
    finally:
        unhook(small)
    assert rep["interrupted"]
    assert [i["address"] for i in rep["items"] if i["status"] == "written"] == [
        str(a) for a in seen[:2]
    ]
    dev.set_nmt_state(NMT_PRE_OPERATIONAL)
    done = await small.restores.resume(rep["id"], s)
    assert done["finished"] and done["counts"]["written"] == len(changed)
    cmp = small.backups.compare(
        ("drive", await small.backups.read_set(s, operation=None)), ("b", ps)
    )
    assert cmp["equal"], cmp["differences"]


async def test_reset_without_silence_is_caught_by_the_final_check(small: Rig) -> None:
    s = small.first["cia402-generic"]
    dev = small.bus.devices[0]
    info = await small.backups.backup(s)
    ps = small.backups.load(info["id"])
    changed = await change_plain(s, ps, 5)
    await s.store()
    hook_after(small, 4, dev.reset_node)
    try:
        rep = await small.restores.restore(s, info["id"])
    finally:
        unhook(small)
    assert rep["interrupted"] and not rep["stored"]
    assert rep["counts"]["pending"] >= 3  # the values the reset took back
    done = await small.restores.resume(rep["id"], s)
    assert done["finished"] and done["counts"]["written"] == len(changed)
