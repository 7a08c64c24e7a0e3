"""The fleet's store (services/fleet.py) on SQLite and PostgreSQL: drives from the backups
of every gateway, plant tags, approved backups, drift results, gateways, filter and paging
(issue 49, second slice)."""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

import pytest

from servodesk.errors import ConflictError, NotFoundError, ValidationError
from servodesk.services.fleet import FleetStore, SeenDrive
from servodesk.services.store import Store, write_new_file

PROFILE = "cia402-generic"


def _key(serial: int) -> str:
    return f"0000029A-00000402-{serial}"


def _backup(store: Store, serial: int, n: int, *, firmware: str = "1.0") -> dict[str, Any]:
    """A backup record of drive ``serial`` as BackupService.save makes one."""
    data = json.dumps({"serial": serial, "n": n}).encode()
    bid = f"20261207T1200{n:02d}Z-{serial:06x}"
    name = f"{bid}-{PROFILE}.json"
    write_new_file(store.backup_file(name), data)
    info = {
        "id": bid,
        "time": f"2026-12-07T12:00:{n:02d}.000Z",
        "label": "",
        "note": "",
        "profile_id": PROFILE,
        "profile_version": "1",
        "drive_key": _key(serial),
        "identity": {"vendor_id": 0x29A, "product_code": 0x402, "serial": serial},
        "firmware": firmware,
        "bus": {},
        "entries": 1,
        "file": name,
        "sha256": hashlib.sha256(data).hexdigest(),
        "unreadable": [],
    }
    store.add_backup(info)
    return info


@pytest.fixture
def store(tmp_path: Path, engine_url: str) -> Any:
    s = Store(tmp_path / "line1", engine_url)
    yield s
    s.close()


def test_drives_come_from_the_backups_of_every_gateway(
    tmp_path: Path, store: Store, engine_url: str
) -> None:
    fleet = FleetStore(store.engine)
    _backup(store, 1, 1, firmware="1.0")
    newest = _backup(store, 1, 2, firmware="1.1")
    _backup(store, 2, 3)
    page = fleet.fleet()
    assert page["total"] == 2
    one = next(d for d in page["drives"] if d["drive_key"] == _key(1))
    assert (one["last_backup"], one["firmware"], one["serial"]) == (newest["id"], "1.1", "1")
    assert one["drift"] == {"state": "unknown", "count": None, "time": None}

    # A second gateway on the same store backs up drive 3 and drive 1 again: the first
    # gateway's next query sees both (its sync reads what was made since its last look).
    other = Store(tmp_path / "line2", store.url)
    try:
        _backup(other, 3, 4)
        again = _backup(other, 1, 5, firmware="2.0")
    finally:
        other.close()
    page = fleet.fleet()
    assert page["total"] == 3
    one = next(d for d in page["drives"] if d["drive_key"] == _key(1))
    assert (one["last_backup"], one["firmware"]) == (again["id"], "2.0")


def test_plant_tags_are_validated_unique_and_name_the_drive(store: Store) -> None:
    fleet = FleetStore(store.engine)
    _backup(store, 1, 1)
    _backup(store, 2, 2)
    assert fleet.set_tag(_key(1), "L2.Press.X")["plant_tag"] == "L2.Press.X"
    # The tag names the drive wherever a drive is asked for.
    assert fleet.drive("L2.Press.X")["drive_key"] == _key(1)
    for bad in ("L2 Press", "-lead", "x/y", "ä", "a" * 65):
        with pytest.raises(ValidationError, match="not a plant tag"):
            fleet.set_tag(_key(2), bad)
    with pytest.raises(ConflictError, match=f"already drive {_key(1)}"):
        fleet.set_tag(_key(2), "L2.Press.X")
    with pytest.raises(NotFoundError, match="no drive 'nope'"):
        fleet.set_tag("nope", "L9")
    # A drive swap: the tag moves from the old drive to its replacement.
    assert fleet.set_tag("L2.Press.X", None)["plant_tag"] is None
    assert fleet.set_tag(_key(2), "L2.Press.X")["plant_tag"] == "L2.Press.X"
    # Tagged drives come first, by tag.
    assert [d["drive_key"] for d in fleet.fleet()["drives"]] == [_key(2), _key(1)]


def test_approval_needs_a_reason_and_resets_the_drift_state(store: Store) -> None:
    fleet = FleetStore(store.engine)
    first = _backup(store, 1, 1)
    second = _backup(store, 1, 2)
    with pytest.raises(ValidationError, match="needs a reason"):
        fleet.approve(_key(1), first, by="ada", reason="   ")
    drive = fleet.approve(_key(1), first, by="ada", reason="commissioned, signed off")
    assert drive["approved"]["backup"] == first["id"]
    assert drive["approved"]["by"] == "ada" and drive["approved"]["reason"].startswith("comm")
    assert fleet.approved_backup(_key(1)) == first["id"]

    result = {
        "drive_key": _key(1),
        "time": "2026-12-07T12:10:00.000Z",
        "gateway": "line-1",
        "session": "cia402-generic-1",
        "backup": first["id"],
        "state": "drifted",
        "count": 1,
        "differences": [{"address": "0x6065:00", "name": "Following error window"}],
    }
    rid = fleet.add_drift(result)
    drifted = fleet.fleet(drift="drifted")
    assert drifted["total"] == 1
    assert drifted["drives"][0]["drift"] == {
        "state": "drifted",
        "count": 1,
        "time": "2026-12-07T12:10:00.000Z",
    }
    listed = fleet.drift_results(_key(1))
    assert listed[0]["id"] == rid and listed[0]["differences"][0]["address"] == "0x6065:00"

    # Approving another backup: the old result was against the old one.
    fleet.approve(_key(1), second, by="bo", reason="new gearbox")
    assert fleet.fleet(drift="unknown")["total"] == 1
    # A check that read the drive before the new approval does not set the state.
    fleet.add_drift(result)
    assert fleet.fleet(drift="drifted")["total"] == 0
    # A backup of another family is refused.
    with pytest.raises(ConflictError, match="is of a"):
        fleet.approve(
            _key(1), {**first, "drive_key": "x", "profile_id": "hiwin-e"}, by="a", reason="r"
        )


def test_filter_and_paging(store: Store) -> None:
    fleet = FleetStore(store.engine)
    for serial in range(1, 26):
        _backup(store, serial, serial % 60)
    fleet.set_tag(_key(7), "L1.Saw_7")
    page = fleet.fleet(offset=20, limit=10)
    assert page["total"] == 25 and len(page["drives"]) == 5
    everything = [
        d["drive_key"] for p in (0, 10, 20) for d in fleet.fleet(offset=p, limit=10)["drives"]
    ]
    assert len(set(everything)) == 25 and everything[0] == _key(7)
    # Text search: tag, serial, profile; LIKE's wildcards are taken literally.
    assert [d["drive_key"] for d in fleet.fleet(q="saw_7")["drives"]] == [_key(7)]
    assert fleet.fleet(q="s_w")["total"] == 0
    assert fleet.fleet(q="-25")["drives"][0]["drive_key"] == _key(25)
    assert fleet.fleet(q="CIA402")["total"] == 25
    assert fleet.fleet(q="%")["total"] == 0


def test_gateways_register_and_note_their_drives(store: Store) -> None:
    fleet = FleetStore(store.engine)
    fleet.register_gateway("line-1", "https://pc1:8000", ["virtual:a"], "1", started=True)
    fleet.register_gateway("line-2", "https://pc2:8000", ["can0", "can0"], "1", started=True)
    seen = SeenDrive(_key(9), PROFILE, "3.0", "9", "cia402-generic-1", 0)
    fleet.see("line-2", [seen])
    gateways = {g["name"]: g for g in fleet.gateways()}
    assert gateways["line-2"]["buses"] == ["can0"] and gateways["line-2"]["alive"]
    drive = fleet.drive(_key(9))
    assert drive["gateway"] == "line-2" and drive["alarms"] == 0
    assert drive["link"] == "https://pc2:8000/#/overview/cia402-generic-1"
    assert fleet.fleet(gateway="line-1")["total"] == 0
    # Its first backup keeps what the gateway noted.
    _backup(store, 9, 1, firmware="3.0")
    drive = fleet.drive(_key(9))
    assert drive["gateway"] == "line-2" and drive["last_backup"] is not None
    time.sleep(0.01)
    fleet.register_gateway("line-1", "https://pc1b:8000", [], "2")
    gateways = {g["name"]: g for g in fleet.gateways()}
    assert gateways["line-1"]["url"] == "https://pc1b:8000" and gateways["line-1"]["version"] == "2"


def test_fleet_tables_move_between_engines_and_ids_continue(tmp_path: Path, pg_url: str) -> None:
    """``servodesk store export/import`` carries the fleet (tags, approvals, drift results,
    gateways) from SQLite to PostgreSQL unchanged, and the next drift result there takes the
    next id (the sequence continues after the imported ones)."""
    from servodesk.cli import main

    laptop = Store(tmp_path / "laptop")
    try:
        fleet = FleetStore(laptop.engine)
        first = _backup(laptop, 1, 1)
        fleet.register_gateway("laptop", "http://127.0.0.1:8000", ["virtual:x"], "1")
        fleet.set_tag(_key(1), "L2.Press.X")
        fleet.approve(_key(1), first, by="ada", reason="signed off")
        result = {
            "drive_key": _key(1),
            "time": "2026-12-07T12:10:00.000Z",
            "gateway": "laptop",
            "session": "s",
            "backup": first["id"],
            "state": "drifted",
            "count": 1,
            "differences": [{"address": "0x6065:00"}],
        }
        assert [fleet.add_drift(result) for _ in range(3)] == [1, 2, 3]
    finally:
        laptop.close()
    export, again = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    assert main(["store", "export", str(export), "--data-dir", str(tmp_path / "laptop")]) == 0
    assert main(["store", "import", str(export), "--url", pg_url]) == 0
    assert main(["store", "export", str(again), "--url", pg_url]) == 0
    rows = sorted(export.read_text().splitlines()[1:-1])
    assert rows == sorted(again.read_text().splitlines()[1:-1])
    assert any('"t": "drift_results"' in r or '"t":"drift_results"' in r for r in rows)

    central = Store(tmp_path / "line1", pg_url)
    try:
        fleet = FleetStore(central.engine)
        drive = fleet.drive("L2.Press.X")
        assert drive["approved"]["by"] == "ada" and drive["drift"]["state"] == "drifted"
        assert fleet.add_drift(result) == 4
    finally:
        central.close()


def test_a_restarted_gateway_reads_only_the_newest_backups(store: Store) -> None:
    """The first sync of a new process starts at the newest backup the fleet table holds
    (less the margin), not at the first backup ever: a gateway's restart does not read the
    plant's whole history again."""
    import sqlalchemy as sa

    from servodesk.services import db

    _backup(store, 1, 1)
    _backup(store, 2, 2)
    day = 86400.0
    with db.write(store.engine) as conn:
        for serial, age in ((1, 2 * day), (2, day)):
            conn.execute(
                sa.update(db.backups)
                .where(db.backups.c.drive_key == _key(serial))
                .values(created=time.time() - age)
            )
    assert FleetStore(store.engine).sync() == 2  # A new table: every backup once.
    assert FleetStore(store.engine).sync() == 1  # Only what is inside the margin.
