"""Without root or CAP_NET_RAW: the simulated slave and the link refuse with the reason
(exit 2, the message and a hint), never a traceback. Run for real as an unprivileged user."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

BACKEND = str(Path(__file__).resolve().parents[2] / "backend")


def _as_nobody(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {
        **os.environ,
        "PYTHONPATH": BACKEND,
        "HOME": str(tmp_path),
        "SERVODESK_DATA_DIR": str(tmp_path / "data"),
    }
    return subprocess.run(
        [
            "setpriv",
            "--reuid",
            "65534",
            "--regid",
            "65534",
            "--clear-groups",
            "--inh-caps=-all",
            sys.executable,
            "-m",
            "servodesk",
            *args,
        ],
        capture_output=True,
        text=True,
        check=False,
        env=env,
        cwd=tmp_path,
        timeout=120,
    )


@pytest.fixture
def tmp_path() -> Iterator[Path]:
    """A directory the unprivileged user can write (pytest's own is root's, mode 700)."""
    with tempfile.TemporaryDirectory(prefix="sdk-ecat-") as d:
        Path(d).chmod(0o777)
        yield Path(d)


@pytest.mark.parametrize(
    ("args", "message", "hint"),
    [
        (
            ["sim", "--profile", "hiwin-e", "--interface", "ethercat", "--channel", "lo"],
            "cannot open a raw socket for EtherCAT on lo",
            "needs root or CAP_NET_RAW",
        ),
        (
            ["backup", "-o", "x.json", "--interface", "ethercat", "--channel", "lo"],
            "cannot open 'lo' for EtherCAT",
            "run as root or give CAP_NET_RAW",
        ),
    ],
)
def test_no_permission_is_a_clear_error(
    tmp_path: Path, args: list[str], message: str, hint: str
) -> None:
    done = _as_nobody(tmp_path, *args)
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and hint in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "x.json").exists()
