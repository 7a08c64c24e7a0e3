"""Defect 6, the CLI's side: files read with a bound, refused restores leave no rows, diff
of different profiles says so, temporary files never outlive a crash."""

from __future__ import annotations

import itertools
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from servodesk.cli import main
from servodesk.services.store import Store
from servodesk.sim.bus import SimulatedBus

_n = itertools.count()
#: Past every limit the CLI sets on a file it reads.
_HUGE = 64 * 1024 * 1024 + 1


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


def _sparse(path: Path, size: int = _HUGE) -> Path:
    """A file of ``size`` bytes that takes no disk space."""
    with open(path, "wb") as f:
        f.truncate(size)
    return path


def _named(endless: str, path: Path) -> str:
    """``endless`` under a name with the suffix a reader wants (a link, for /dev/zero)."""
    if endless == "/dev/zero":
        path.symlink_to("/dev/zero")
    else:
        os.replace(endless, path)
    return str(path)


@pytest.fixture(params=["sparse", "dev-zero"])
def endless(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A file larger than any limit, and one that never ends (/dev/zero)."""
    if request.param == "sparse":
        return str(_sparse(tmp_path / "big.json"))
    return "/dev/zero"


def _refused_for_size(capsys: pytest.CaptureFixture[str], code: int) -> None:
    err = capsys.readouterr().err
    assert code == 2, err
    assert "larger than" in err and "MiB" in err, err


def test_restore_and_diff_read_files_with_a_bound(
    endless: str, data_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _refused_for_size(capsys, main(["restore", endless, "--node-id", "3"]))
    _refused_for_size(capsys, main(["diff", endless, endless]))


def test_pdo_and_profile_import_read_files_with_a_bound(
    endless: str, data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _refused_for_size(capsys, main(["pdo", "apply", endless, "--node-id", "3"]))
    _refused_for_size(
        capsys, main(["profiles", "--import", _named(endless, tmp_path / "big.eds"), "--id", "x"])
    )


def test_a_plant_file_is_read_with_a_bound(
    endless: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from servodesk.errors import ValidationError
    from servodesk.model.plantfile import load_plant_file

    with pytest.raises(ValidationError) as info:
        load_plant_file(_named(endless, tmp_path / "big.toml"))
    assert "larger than" in info.value.message


def test_refused_restores_add_no_store_rows(
    sim: list[str],
    data_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Backups of the smartris drive (node 4), taken on another machine (another data
    # directory), restored into the generic drive (node 3): the preflight refuses them
    # (another profile, no --map-by-name), twice each.
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path / "elsewhere"))
    files = [tmp_path / "other.json", tmp_path / "other.dcf"]
    for f in files:
        assert main(["backup", "-o", str(f), *sim, "--node-id", "4"]) == 0
    monkeypatch.setenv("SERVODESK_DATA_DIR", str(data_dir))
    capsys.readouterr()
    for f in files * 2:
        assert main(["restore", str(f), *sim, "--node-id", "3"]) == 2
        assert "nothing was written" in capsys.readouterr().err
    store = Store(data_dir)
    assert store.list_backups() == []
    store.close()
    assert list((data_dir / "backups").iterdir()) == []


def test_diff_of_files_of_different_profiles_says_so_and_exits_2(
    sim: list[str], data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["backup", "-o", str(a), *sim, "--node-id", "3"]) == 0
    assert main(["backup", "-o", str(b), *sim, "--node-id", "4"]) == 0
    capsys.readouterr()
    assert main(["diff", str(a), str(b)]) == 2
    err = capsys.readouterr().err
    assert "different profiles" in err and "cia402-generic" in err and "smartris" in err
    # A file against a drive of another profile: the same.
    assert main(["diff", str(a), "drive", *sim, "--node-id", "4"]) == 2
    assert "different profiles" in capsys.readouterr().err
    assert json.loads(a.read_text())["profile"]["id"] == "cia402-generic"


# Temporary files ---------------------------------------------------------------------------


def test_stale_temporary_files_are_removed_when_the_store_opens(tmp_path: Path) -> None:
    backups = tmp_path / "data" / "backups"
    backups.mkdir(parents=True)
    stale = backups / ".20260101T000000Z-abcdef-x.json.k3j9_q2z.tmp"
    fresh = backups / ".20260101T000001Z-abcdef-x.json.a8d7f6e5.tmp"
    other = backups / "notes.tmp"  # Not of servodesk's pattern: never touched.
    for p in (stale, fresh, other):
        p.write_bytes(b"half a file")
    old = time.time() - 2 * 3600
    os.utime(stale, (old, old))
    os.utime(other, (old, old))
    Store(tmp_path / "data").close()
    assert not stale.exists()
    # A young one may belong to a write in progress in another process (serve and the CLI
    # share the data directory).
    assert fresh.exists() and other.exists()


def test_a_failed_profile_write_leaves_no_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from servodesk.domain.profile_loader import save_profile
    from tests.backup.conftest import catalog

    profile = catalog().get("cia402-generic")

    def crash(*_: object, **__: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(Exception):  # noqa: B017 - whichever error: the point is what is left
        save_profile(profile, tmp_path)
    monkeypatch.undo()
    assert [p.name for p in tmp_path.rglob("*") if p.is_file()] == []


def test_a_failed_profile_export_leaves_no_temporary_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def crash(*_: object, **__: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", crash)
    out = tmp_path / "x.eds"
    assert main(["profile", "cia402-generic", "--export", "eds", "-o", str(out)]) == 2
    monkeypatch.undo()
    assert "No space left" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
