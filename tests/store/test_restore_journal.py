"""A restore's group commit (services/restore.py, issue 50): the journal and the audit chain
get each batch's intent before its writes and its results after them. A restore stopped
mid-batch, by a lost bus or a crash, resumes to a drive equal to the backup, with every item
of the journal done and one audit record per written parameter whose old value is the
automatic backup's; on SQLite and on PostgreSQL."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio
import sqlalchemy as sa

from servodesk.domain.address import ObjectAddress as A
from servodesk.services import db, restore
from servodesk.services.audit import AuditLog
from servodesk.services.store import Store, StoreError
from servodesk.sim.canopen_device import NMT_PRE_OPERATIONAL, NMT_STOPPED
from tests.backup.conftest import Rig, close_rig, make_rig
from tests.backup.helpers import change_pdo, change_plain
from tests.backup.test_interrupt import hook_after, unhook

pytestmark = pytest.mark.asyncio


@pytest_asyncio.fixture
async def rig(tmp_path: Path, engine_url: str) -> AsyncIterator[tuple[Rig, AuditLog]]:
    r = await make_rig(tmp_path / "data", ["cia402-generic"], second=False, url=engine_url)
    audit = AuditLog(r.backups.store.url)
    r.backups.audit = audit
    try:
        yield r, audit
    finally:
        audit.close()
        await close_rig(r)


def _writes(audit: AuditLog, rid: str) -> list[dict[str, Any]]:
    """The restore's ``write.object`` records, oldest first."""
    rows = audit.query(event="write.object", limit=10_000)
    return [r for r in reversed(rows) if r["details"].get("restore") == rid]


async def _check_complete(rig: Rig, audit: AuditLog, rid: str, backup: str) -> None:
    """The drive equals the backup, the journal has nothing left to do, and the audit has
    one write per written item with the automatic backup's old value."""
    s = rig.first["cia402-generic"]
    ps = rig.backups.load(backup)
    drive = await rig.backups.read_set(s, operation=None)
    cmp = rig.backups.compare(("drive", drive), ("b", ps))
    assert cmp["equal"], cmp["differences"]
    rep = rig.restores.report(rid)
    assert rep["finished"] and not rep["interrupted"] and rep["stored"]
    assert rep["counts"]["pending"] == 0 and rep["counts"]["failed"] == 0
    written = {i["address"] for i in rep["items"] if i["status"] == "written"}
    # The automatic backup holds each object's value before the restore.
    before = {str(e.address): e.raw.hex() for e in rig.backups.load(rep["pre_backup"]).entries}
    target = {str(e.address): e.raw.hex() for e in ps.entries}
    records = _writes(audit, rid)
    by_address: dict[str, list[dict[str, Any]]] = {}
    for rec in records:
        by_address.setdefault(rec["details"]["address"], []).append(rec["details"])
        assert rec["details"]["client"] == "t" and rec["result"] == "success"
    # A record per written parameter (a PDO procedure writes a COB-ID twice: invalid, then
    # its value): the first replaced the automatic backup's value, the last set the target.
    assert written <= set(by_address)
    for address in written:
        first, last = by_address[address][0], by_address[address][-1]
        assert first["old_raw_hex"] == before[address], first
        assert last["new_raw_hex"] == target[address], last
        if not address.startswith(("0x14", "0x16", "0x18", "0x1A")):
            assert len(by_address[address]) == 1, by_address[address]
    # Every batch's intent precedes its writes in the chain, and the chain is intact.
    intents = [
        r
        for r in audit.query(event="restore.batch", limit=10_000)
        if r["details"]["restore"] == rid
    ]
    assert intents and min(i["seq"] for i in intents) < min(r["seq"] for r in records)
    for i in intents:
        for w in i["details"]["writes"]:
            assert w["new_raw_hex"] and "address" in w
    assert audit.verify().ok


@pytest.mark.parametrize("batch", [(64, 0.1), (3, 0.0)], ids=["one-batch", "many-batches"])
async def test_bus_lost_mid_batch_resumes_to_the_backup_with_journal_and_audit_complete(
    rig: tuple[Rig, AuditLog], batch: tuple[int, float], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Many batches of 3, and results committed after every write: the intents committed
    # ahead of their batches and the commits within one, as on a slow link.
    monkeypatch.setattr(restore, "BATCH_STEPS", batch[0])
    monkeypatch.setattr(restore, "BATCH_SECONDS", batch[1])
    r, audit = rig
    s = r.first["cia402-generic"]
    dev = r.bus.devices[0]
    info = await r.backups.backup(s)
    changed = await change_plain(s, r.backups.load(info["id"]), 8) + await change_pdo(s)
    assert len(changed) >= 10
    # After the 5th write the drive stops answering: the write lands, its read-back is lost.
    seen = hook_after(r, 5, lambda: dev.set_nmt_state(NMT_STOPPED))
    try:
        rep = await r.restores.restore(s, info["id"], client="t")
    finally:
        unhook(r)
    assert rep["interrupted"] and not rep["finished"]
    # The batch's results were committed when the bus was lost: the report knows exactly
    # which writes were verified.
    entries = {i["address"] for i in rep["items"]}
    verified = [i["address"] for i in rep["items"] if i["status"] == "written"]
    assert verified == [str(a) for a in seen[:4] if str(a) in entries]
    assert rig_item(rep, seen[4])["status"] == "pending"
    dev.set_nmt_state(NMT_PRE_OPERATIONAL)
    done = await r.restores.resume(rep["id"], s, client="t")
    assert done["counts"]["written"] == len(changed)
    await _check_complete(r, audit, rep["id"], info["id"])
    # The write the lost bus cut reached the drive: resume found it there and recorded it.
    found = [w for w in _writes(audit, rep["id"]) if w["details"].get("found_on_resume")]
    assert [w["details"]["address"] for w in found] == [str(seen[4])]


def rig_item(rep: dict[str, Any], address: A) -> dict[str, Any]:
    return next(i for i in rep["items"] if i["address"] == str(address))


async def test_a_crash_mid_batch_leaves_the_batch_pending_and_resume_reads_the_drive(
    rig: tuple[Rig, AuditLog], monkeypatch: pytest.MonkeyPatch
) -> None:
    r, audit = rig
    s = r.first["cia402-generic"]
    # One batch whatever the machine's load: the crash must fall inside it.
    monkeypatch.setattr(restore, "BATCH_SECONDS", 60.0)
    info = await r.backups.backup(s)
    changed = await change_plain(s, r.backups.load(info["id"]), 10)
    assert len(changed) == 10
    loop = asyncio.get_running_loop()
    task = asyncio.ensure_future(r.restores.restore(s, info["id"], client="t"))

    # The process dies after the drive took the 4th write: nothing after the batch's
    # intent reaches the store (a cancelled task runs no more of the restore's code).
    def crash() -> None:
        loop.call_soon_threadsafe(task.cancel)

    seen = hook_after(r, 4, crash)
    try:
        with pytest.raises(asyncio.CancelledError):
            await task
    finally:
        unhook(r)
    assert len(seen) >= 4
    rows = db.rows(
        r.backups.store.engine, sa.select(db.restores.c.id).order_by(db.restores.c.created)
    )
    rid = str(rows[-1]["id"])
    left = r.restores.report(rid)
    assert not left["finished"] and left["counts"]["written"] == 0
    pending = [i for i in left["items"] if i["status"] == "pending"]
    assert len(pending) == len(changed)
    assert all(i["message"] == restore.INTENT.format(batch=1) for i in pending)
    # The intent is in the audit chain; the writes are not (their results never committed).
    assert not _writes(audit, rid)
    intent = audit.query(event="restore.batch", limit=1)[0]["details"]
    assert intent["restore"] == rid and len(intent["writes"]) == len(changed)

    done = await r.restores.resume(rid, s, client="t")
    assert done["counts"]["written"] == len(changed)
    await _check_complete(r, audit, rid, info["id"])
    # What the crashed restore had written was found on the drive, not written again.
    found = {
        w["details"]["address"] for w in _writes(audit, rid) if w["details"].get("found_on_resume")
    }
    assert {str(a) for a in seen[:4]} <= found
    assert not [i for i in done["items"] if (i["message"] or "").startswith("in batch")]


async def test_every_write_is_audited_with_the_automatic_backups_old_value(
    rig: tuple[Rig, AuditLog],
) -> None:
    r, audit = rig
    s = r.first["cia402-generic"]
    info = await r.backups.backup(s)
    changed = await change_plain(s, r.backups.load(info["id"]), 6)
    rep = await r.restores.restore(s, info["id"], client="t")
    assert rep["finished"] and rep["counts"]["written"] == len(changed)
    await _check_complete(r, audit, rep["id"], info["id"])
    # The old table (GET /sessions/{sid}/audit) has the same writes.
    rows = r.backups.store.list_audit(s.id, limit=len(changed))
    assert sorted(x["address"] for x in rows) == sorted(str(a) for a in changed)
    for x in rows:
        assert x["client"] == "t" and x["old_raw_hex"] != x["new_raw_hex"]


async def test_a_group_commit_writes_items_audit_rows_and_the_restore_together(
    tmp_path: Path, engine_url: str
) -> None:
    store = Store(tmp_path / "data", engine_url)
    try:
        store.add_restore(
            {
                "id": "r1",
                "backup": "b1",
                "session": "s1",
                "drive_key": "d1",
                "bus": {},
                "time": "t",
                "dry_run": False,
                "options": {},
            },
            [
                {"address": f"0x6081:0{i}", "source": "b", "name": "n", "status": "pending"}
                for i in range(4)
            ],
        )
        write = {"time": 1.0, "client": "c", "session": "s1", "drive_key": "d1"}
        store.journal(
            "r1",
            {
                0: {"status": "written", "message": None},
                1: {"status": "failed", "code": 0x06090030, "message": "refused"},
                2: {"message": restore.INTENT.format(batch=2)},
                9: {"status": "written"},  # No such item: nothing happens.
            },
            [
                write | {"address": "0x6081:00", "old_raw_hex": "01", "new_raw_hex": "02"},
                write | {"address": "0x6081:01", "new_raw_hex": "03", "new_value": 3},
            ],
            {"interrupted": True, "message": "bus lost"},
        )
        rec = store.get_restore("r1")
        assert rec["interrupted"] and rec["message"] == "bus lost"
        assert [(i["status"], i["message"], i["code"]) for i in rec["items"]] == [
            ("written", None, None),
            ("failed", "refused", 0x06090030),
            ("pending", restore.INTENT.format(batch=2), None),
            ("pending", None, None),
        ]
        assert [a["address"] for a in store.list_audit("s1")] == ["0x6081:01", "0x6081:00"]
        # A failing statement rolls the whole group back: nothing of it is kept.
        with pytest.raises(StoreError):
            # new_raw_hex is NOT NULL: the audit row is refused after the item's update.
            bad = write | {"address": "0x6081:03", "new_raw_hex": None}
            store.journal("r1", {3: {"status": "written"}}, [bad], None)
        assert store.get_restore("r1")["items"][3]["status"] == "pending"
    finally:
        store.close()
