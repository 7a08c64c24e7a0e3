"""``servodesk backup | restore | diff`` in-process against simulated drives."""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.services.store import Store
from servodesk.sim.bus import SimulatedBus

_n = itertools.count()


@pytest.fixture(scope="module")
def sim() -> Iterator[tuple[SimulatedBus, list[str]]]:
    channel = f"cli-backup-{os.getpid()}-{next(_n)}"
    bus = SimulatedBus.start([("cia402-generic", 3), ("smartris", 4)], channel=channel)
    try:
        yield bus, ["--interface", "virtual", "--channel", channel, "--timeout", "0.3"]
    finally:
        bus.stop()


@pytest.fixture(autouse=True)
def data_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "data"
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(d))
    return d


def test_backup_diff_restore(
    sim: tuple[SimulatedBus, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bus, opts = sim
    node = [*opts, "--node-id", "3"]
    out = tmp_path / "a.json"
    assert main(["backup", "-o", str(out), *node, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert out.is_file() and info["entries"] > 50
    # -o never replaces a file.
    assert main(["backup", "-o", str(out), *node]) == 2
    assert "never overwritten" in capsys.readouterr().err

    assert main(["diff", str(out), "drive", *node]) == 0
    capsys.readouterr()
    bus.drives[0].write(0x6081, 0, 4321)  # Someone changes the drive.
    assert main(["diff", str(out), "drive", *node, "--json"]) == 1
    cmp = json.loads(capsys.readouterr().out)
    assert [d["address"] for d in cmp["differences"]] == ["0x6081:00"]

    assert main(["restore", str(out), *node, "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "0x6081:00 <- " in text and bus.drives[0].read(0x6081) == 4321
    assert main(["restore", str(out), *node, "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["counts"]["written"] == 1 and rep["stored"]
    assert bus.drives[0].read(0x6081) != 4321
    assert main(["diff", str(out), "drive", *node]) == 0

    dcf = tmp_path / "a.dcf"
    assert main(["backup", "-o", str(dcf), *node]) == 0
    capsys.readouterr()
    assert main(["diff", str(out), str(dcf)]) == 0


def test_a_json_file_restored_is_kept_byte_for_byte_in_the_store(
    sim: tuple[SimulatedBus, list[str]],
    tmp_path: Path,
    data_dir: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # The store's copy of a file the user restores is the user's file, not servodesk's
    # rewrite of it: its SHA-256 is the one the user can compare.
    _, opts = sim
    node = [*opts, "--node-id", "3"]
    taken = tmp_path / "taken.json"
    assert main(["backup", "-o", str(taken), *node]) == 0
    # Re-indented by an editor: still intact (the checksum is of the canonical JSON).
    edited = tmp_path / "edited.json"
    edited.write_text(json.dumps(json.loads(taken.read_bytes()), indent=4), encoding="utf-8")
    assert main(["restore", str(edited), *node, "--dry-run"]) == 0
    capsys.readouterr()

    store = Store(data_dir)
    try:
        digest = hashlib.sha256(edited.read_bytes()).hexdigest()
        [row] = [b for b in store.list_backups() if b["sha256"] == digest]
        assert store.backup_file(row["file"]).read_bytes() == edited.read_bytes()
        assert row["source"] == "upload"
    finally:
        store.close()


def test_bad_input_exits_2(
    sim: tuple[SimulatedBus, list[str]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, opts = sim
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "servodesk-backup", "schema_version": 1, "entr')
    assert main(["restore", str(bad), *opts, "--node-id", "3"]) == 2
    assert "truncated or corrupt" in capsys.readouterr().err
    assert main(["diff", str(tmp_path / "missing.json"), "drive", *opts]) == 2
    assert main(["backup", "-o", str(tmp_path / "x.txt"), *opts]) == 2
    # Another family: refused with the reason, nothing written.
    a = tmp_path / "generic.json"
    assert main(["backup", "-o", str(a), *opts, "--node-id", "3"]) == 0
    capsys.readouterr()
    assert main(["restore", str(a), *opts, "--node-id", "4"]) == 2
    assert "another drive family" in capsys.readouterr().err
