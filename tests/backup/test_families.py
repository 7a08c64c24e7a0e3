"""Backup, change, restore, compare against the simulated drive of every family; restore into
a replacement drive of the same family; refusals that write nothing."""

from __future__ import annotations

import json

import pytest

from servodesk.domain.address import ObjectAddress as A
from servodesk.services.restore import PreflightFailed, PreflightStateConflict
from tests.backup.conftest import FAMILIES, Rig
from tests.backup.helpers import change_pdo, change_plain

pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest.mark.parametrize("pid", FAMILIES)
async def test_backup_change_restore_compare(rig: Rig, pid: str) -> None:
    s = rig.first[pid]
    info = await rig.backups.backup(s, label="commissioned", note="")
    ps = rig.backups.load(info["id"])
    assert info["entries"] == len(ps.entries) > 20
    assert ps.identity["serial"] == s.identity.serial
    assert (rig.data_dir / "backups" / info["file"]).is_file()

    changed = await change_plain(s, ps, 5) + await change_pdo(s)
    assert len(changed) >= 5
    before = rig.backups.compare(
        ("drive", await rig.backups.read_set(s, operation=None)), ("b", ps)
    )
    assert not before["equal"]
    assert {d["address"] for d in before["differences"]} == {str(a) for a in changed}

    rep = await rig.restores.restore(s, info["id"], client="test-restore")
    assert rep["finished"] and not rep["interrupted"], rep["message"]
    assert rep["counts"]["failed"] == 0 and rep["counts"]["pending"] == 0
    assert {i["address"] for i in rep["items"] if i["status"] == "written"} == {
        str(a) for a in changed
    }
    assert rep["stored"] is True
    assert rep["pre_backup"] and rig.backups.info(rep["pre_backup"])["source"] == "pre-restore"

    after = rig.backups.compare(("drive", await rig.backups.read_set(s, operation=None)), ("b", ps))
    assert after["equal"], after["differences"]

    audit = rig.backups.store.list_audit(s.id, limit=1000)
    clients = {a["client"] for a in audit}
    assert {"test-user", "test-restore"} <= clients
    assert any(a["address"] == str(changed[0]) and a["old_raw_hex"] for a in audit)


@pytest.mark.parametrize("pid", FAMILIES)
async def test_restore_into_a_replacement_drive_of_the_same_family(rig: Rig, pid: str) -> None:
    src, dst = rig.first[pid], rig.second[pid]
    ps0 = await rig.backups.read_set(src, operation=None)
    await change_plain(src, ps0, 3)  # The source differs from the factory state of dst.
    info = await rig.backups.backup(src, label="source")
    ps = rig.backups.load(info["id"])
    pf, _ = await rig.restores.preflight(dst, ps)
    assert pf.ok, pf.problems
    if src.identity.serial is not None:
        assert any("replacement" in w for w in pf.warnings)
    rep = await rig.restores.restore(dst, info["id"], store=False)
    assert rep["finished"] and rep["counts"]["failed"] == 0 and not rep["stored"]
    assert rep["counts"]["written"] >= 3
    cmp = rig.backups.compare(("dst", await rig.backups.read_set(dst, operation=None)), ("b", ps))
    assert cmp["equal"], cmp["differences"]


async def test_another_family_is_refused_unless_mapped_by_name(rig: Rig) -> None:
    info = await rig.backups.backup(rig.first["cia402-generic"])
    dst = rig.second["smartris"]
    audit_before = len(rig.backups.store.list_audit(dst.id))
    with pytest.raises(PreflightFailed) as err:
        await rig.restores.restore(dst, info["id"])
    assert "another drive family" in err.value.message
    assert len(rig.backups.store.list_audit(dst.id)) == audit_before  # nothing written
    pf, _ = await rig.restores.preflight(dst, rig.backups.load(info["id"]), map_names=True)
    assert pf.mapping is not None
    mapped = {str(m.address): m for m in pf.mapping}
    assert mapped["0x6083:00"].target == A(0x6083)  # Profile acceleration
    assert any(m.target is None and m.reason for m in pf.mapping)  # and what does not map


async def test_enabled_drive_is_refused_and_nothing_is_written(rig: Rig) -> None:
    s = rig.first["cia402-generic"]
    info = await rig.backups.backup(s)
    ps = rig.backups.load(info["id"])
    await change_plain(s, ps, 2)
    await s.command("enable")
    try:
        n = len(rig.backups.store.list_audit(s.id, limit=10_000))
        with pytest.raises(PreflightStateConflict) as err:
            await rig.restores.restore(s, info["id"])
        assert "drive not enabled" in err.value.message
        assert len(rig.backups.store.list_audit(s.id, limit=10_000)) == n
    finally:
        await s.command("disable")
    rep = await rig.restores.restore(s, info["id"], store=False)
    assert rep["counts"]["written"] == 2


async def test_dry_run_shows_exactly_what_would_be_written(rig: Rig) -> None:
    s = rig.first["smartris"]
    info = await rig.backups.backup(s)
    ps = rig.backups.load(info["id"])
    changed = await change_plain(s, ps, 3) + await change_pdo(s)
    n = len(rig.backups.store.list_audit(s.id, limit=10_000))
    rep = await rig.restores.restore(s, info["id"], dry_run=True)
    assert len(rig.backups.store.list_audit(s.id, limit=10_000)) == n  # wrote nothing
    assert rep["dry_run"] and rep["pre_backup"] is None
    assert {i["address"] for i in rep["items"] if i["status"] == "would_write"} == {
        str(a) for a in changed
    }
    steps = [(st["address"], st["why"]) for st in rep["steps"]]
    # The PDO goes last, by the CiA 301 procedure, and the COB-ID is restored at the end.
    assert steps[-1][0] == "0x1400:01"
    assert ("0x1600:00", "mapping sub 0 = n") in steps
    assert rig.restores.report(rep["id"]) == rep
    real = await rig.restores.restore(s, info["id"], store=False)
    assert real["counts"]["written"] == len(changed)
    assert json.dumps(real)  # JSON-ready


async def test_compare_drive_against_profile_defaults(rig: Rig) -> None:
    s = rig.second["cia402-generic"]
    drive = await rig.backups.read_set(s, operation=None)
    cmp = rig.backups.compare(
        ("drive", drive), ("defaults", rig.backups.defaults(s.profile.id, 21))
    )
    assert cmp["same"] > 10
    for d in cmp["differences"]:
        assert d["kind"] in ("changed", "only_a", "only_b")
        assert d["a_raw_hex"] != d["b_raw_hex"]
