"""Defect 1: ids that become file names are checked; nothing is written outside the data
directory, and a refused file leaves no file and no store row behind."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from servodesk.cli import main
from servodesk.errors import ValidationError
from servodesk.services.backup import BackupService
from servodesk.services.store import Store
from servodesk.sim.bus import SimulatedBus
from tests.backup.conftest import catalog
from tests.security.conftest import backup_bytes

_n = itertools.count()


def _evil_id(target: Path) -> str:
    """A profile id that climbs out of <data>/backups to ``target`` (without its .json)."""
    return "x/../../../../../../../../.." + str(target)


def _files(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob("*") if p.is_file())


def test_upload_of_a_climbing_profile_id_is_refused_and_writes_nothing(
    loopback_app: FastAPI, tmp_path: Path
) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    data = backup_bytes(_evil_id(outside / "anything"))
    with TestClient(loopback_app, base_url="http://127.0.0.1:8000") as c:
        r = c.post(
            "/api/v1/backups/upload",
            params={"filename": "evil.json"},
            content=data,
            headers={"Content-Type": "application/json"},
        )
        assert r.status_code in (400, 422), r.text
        body = r.json()
        assert body["error"] == "ValidationError"
        assert "profile.id" in body["message"] and body.get("hint")
        assert c.get("/api/v1/backups").json() == []  # No store row either.
    assert _files(outside) == []
    assert not (outside / "anything.json").exists()


@pytest.mark.parametrize(
    "bad",
    ["../x", "a/b", "..", "a..b", ".hidden", "UPPER", "x" * 65, "é", "a\\b", "a\x00b", ""],
)
def test_the_allow_list_refuses_ids_that_could_name_another_file(bad: str) -> None:
    from servodesk.domain.ids import check_id

    with pytest.raises(ValidationError) as info:
        check_id(bad, "profile.id")
    assert info.value.field == "profile.id" and info.value.hint


@pytest.mark.parametrize("good", ["cia402-generic", "hiwin-e", "lecsn-t", "my_drive.v2", "a"])
def test_the_allow_list_takes_the_ids_servodesk_makes(good: str) -> None:
    from servodesk.domain.ids import check_id

    assert check_id(good, "profile.id") == good


def test_the_store_never_writes_or_reads_outside_its_directory(tmp_path: Path) -> None:
    from servodesk.domain.paramset import ParameterSet

    store = Store(tmp_path / "data")
    service = BackupService(store, catalog())
    ps = ParameterSet(
        profile_id=_evil_id(tmp_path / "out"), profile_version="1", time="t", entries=()
    )
    with pytest.raises(ValidationError):
        service.save(ps)
    assert not (tmp_path / "out.json").exists()
    # A record naming a file outside (as a store written before the check could hold) is
    # refused, not followed.
    store.add_backup(
        {
            "id": "old",
            "time": "t",
            "label": "",
            "note": "",
            "profile_id": "x",
            "profile_version": "",
            "drive_key": "",
            "identity": {},
            "firmware": None,
            "bus": {},
            "entries": 0,
            "file": "../../secret.json",
            "sha256": "0" * 64,
        }
    )
    (tmp_path / "secret.json").write_text("{}")
    with pytest.raises(ValidationError) as info:
        service.file_bytes("old")
    assert "outside" in info.value.message
    store.close()


# The CLI -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sim() -> Iterator[list[str]]:
    channel = f"security-cli-{os.getpid()}-{next(_n)}"
    bus = SimulatedBus.start([("cia402-generic", 3), ("smartris", 4)], channel=channel)
    try:
        yield ["--interface", "virtual", "--channel", channel, "--timeout", "0.3"]
    finally:
        bus.stop()


@pytest.fixture
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(d))
    return d


def test_cli_restore_of_a_climbing_profile_id_exits_2_and_writes_nothing(
    sim: list[str], data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    evil = tmp_path / "evil.json"
    evil.write_bytes(backup_bytes(_evil_id(outside / "anything")))
    assert main(["restore", str(evil), *sim, "--node-id", "3"]) == 2
    err = capsys.readouterr().err
    assert "profile.id" in err
    assert _files(outside) == []
    backups = data_dir / "backups"
    assert not backups.exists() or _files(backups) == []
