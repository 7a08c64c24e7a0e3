"""Files: refused when corrupt, truncated, foreign or out of range (nothing written); written
atomically and never overwritten; a crash while writing leaves everything intact; DCF/CSV."""

from __future__ import annotations

import csv
import errno
import io
import json
import os
from collections.abc import AsyncIterator
from pathlib import Path

import pytest
import pytest_asyncio

from servodesk.domain import paramset
from servodesk.errors import ConflictError, ValidationError
from servodesk.services import store as store_mod
from servodesk.services.restore import PreflightFailed
from servodesk.services.store import StoreError, write_new_file
from tests.backup.conftest import Rig, close_rig, make_rig
from tests.backup.helpers import change_plain

pytestmark = pytest.mark.asyncio(loop_scope="module")


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def one(tmp_path_factory) -> AsyncIterator[Rig]:  # type: ignore[no-untyped-def]
    r = await make_rig(tmp_path_factory.mktemp("store"), ["cia402-generic"], second=False)
    try:
        yield r
    finally:
        await close_rig(r)


def _resealed(data: bytes, change: object) -> bytes:
    doc = json.loads(data)
    change(doc)  # type: ignore[operator]
    doc["checksum"] = paramset.checksum(doc)
    return json.dumps(doc).encode()


def _set_entry(address: str, raw_hex: str, value: object) -> object:
    def change(doc: dict) -> None:  # type: ignore[type-arg]
        for e in doc["entries"]:
            if e["address"] == address:
                e["raw_hex"], e["value"] = raw_hex, value

    return change


async def test_bad_files_are_refused_and_nothing_is_written(one: Rig) -> None:
    s = one.first["cia402-generic"]
    info = await one.backups.backup(s)
    good = one.backups.file_bytes(info["id"])
    n_audit = len(one.backups.store.list_audit(limit=10_000))
    n_backups = len(one.backups.store.list_backups())
    bad = {
        "truncated.json": good[: len(good) * 2 // 3],
        "corrupt.json": good.replace(b'"raw_hex": "', b'"raw_hex": "0', 1),
        "foreign.json": _resealed(good, lambda d: d.update(schema_version=2)),
        "other.json": json.dumps({"hello": "world"}).encode(),
    }
    for name, data in bad.items():
        with pytest.raises(ValidationError) as err:
            one.backups.import_bytes(data, name)
        assert err.value.message.startswith(name), err.value.message
    assert len(one.backups.store.list_backups()) == n_backups

    # Max torque (6072h) far above the profile's maximum: stored, but the restore refuses it.
    spec = s.profile.spec(paramset.ObjectAddress(0x6072))
    assert spec is not None and spec.max is not None
    too_big = int(spec.max) + 1
    data = _resealed(good, _set_entry("0x6072:00", too_big.to_bytes(2, "little").hex(), too_big))
    up = one.backups.import_bytes(data, "range.json")
    with pytest.raises(PreflightFailed) as err2:
        await one.restores.restore(s, up["id"])
    assert "0x6072:00" in err2.value.message and "above the maximum" in err2.value.message
    assert [p.address for p in err2.value.problems] == [paramset.ObjectAddress(0x6072)]
    assert len(one.backups.store.list_audit(limit=10_000)) == n_audit  # not one write


async def test_a_file_changed_on_disk_is_refused(one: Rig) -> None:
    info = await one.backups.backup(one.first["cia402-generic"])
    path = one.data_dir / "backups" / info["file"]
    os.chmod(path, 0o644)
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))
    with pytest.raises(ValidationError) as err:
        one.backups.load(info["id"])
    assert "changed after it was written" in err.value.message


async def test_crash_while_writing_a_backup_leaves_files_and_store_intact(
    one: Rig, monkeypatch: pytest.MonkeyPatch
) -> None:
    s = one.first["cia402-generic"]
    first = await one.backups.backup(s, label="keep me")
    files_before = {p.name: p.read_bytes() for p in (one.data_dir / "backups").iterdir()}
    rows_before = one.backups.store.list_backups()

    def crash(src: str, dst: str) -> None:
        raise OSError(errno.EIO, "simulated crash at the final link")

    monkeypatch.setattr(store_mod.os, "link", crash)
    with pytest.raises(StoreError):
        await one.backups.backup(s, label="lost")
    monkeypatch.undo()
    files_after = {p.name: p.read_bytes() for p in (one.data_dir / "backups").iterdir()}
    assert files_after == files_before  # no partial file, no temp file left
    assert one.backups.store.list_backups() == rows_before
    assert one.backups.load(first["id"]).label == "keep me"
    # And the store still works afterwards.
    again = await one.backups.backup(s, label="after")
    assert one.backups.store.list_backups()[0]["id"] == again["id"]


async def test_write_new_file_never_replaces(tmp_path: Path) -> None:
    p = tmp_path / "b.json"
    write_new_file(p, b"first")
    with pytest.raises(ConflictError):
        write_new_file(p, b"second")
    assert p.read_bytes() == b"first"
    assert os.listdir(tmp_path) == ["b.json"]


async def test_dcf_and_csv_export_and_dcf_import(one: Rig) -> None:
    s = one.first["cia402-generic"]
    info = await one.backups.backup(s)
    ps = one.backups.load(info["id"])
    dcf, _media, suffix = one.backups.export(ps, "dcf")
    assert suffix == "dcf" and b"ParameterValue" in dcf and b"[DeviceComissioning]" in dcf
    imported = one.backups.import_bytes(dcf, "drive.dcf")
    back = one.backups.load(imported["id"])
    assert back.profile_id == "cia402-generic"
    cmp = one.backups.compare(("dcf", back), ("json", ps))
    assert cmp["equal"], cmp["differences"]
    text, _, _ = one.backups.export(ps, "csv")
    rows = list(csv.DictReader(io.StringIO(text.decode())))
    assert len(rows) == len(ps.entries)
    r = next(x for x in rows if x["address"] == "0x6081:00")
    assert r["raw_hex"] == ps.by_address()[paramset.ObjectAddress(0x6081)].raw.hex()


async def test_labels_change_in_the_store_not_in_the_file(one: Rig) -> None:
    s = one.first["cia402-generic"]
    await change_plain(s, await one.backups.read_set(s, operation=None), 1)
    info = await one.backups.backup(s, label="a")
    before = one.backups.file_bytes(info["id"])
    one.backups.store.update_backup(info["id"], "renamed", "a note")
    assert one.backups.file_bytes(info["id"]) == before
    assert one.backups.load(info["id"]).label == "renamed"
