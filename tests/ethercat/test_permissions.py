"""Without root or CAP_NET_RAW: the simulated slave and the link refuse with the reason
(exit 2, the message and a hint), never a traceback. Run for real as an unprivileged user."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.ethercat.nobody import as_nobody, nobody_dir


@pytest.fixture
def tmp_path() -> Iterator[Path]:
    """A directory the unprivileged user can write (pytest's own is root's, mode 700)."""
    with nobody_dir() as d:
        yield d


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
    done = as_nobody("-m", "servodesk", *args, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and hint in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "x.json").exists()
