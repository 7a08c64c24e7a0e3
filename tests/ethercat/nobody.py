"""Run Python as an unprivileged user (uid/gid 65534, no capabilities), for the tests that
check what servodesk says without root: no veth pair, no raw socket."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

BACKEND = str(Path(__file__).resolve().parents[2] / "backend")


def as_nobody(*argv: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``python *argv`` as user nobody, with servodesk importable from this checkout; HOME and
    SERVODESK_DATA_DIR in ``cwd`` (which nobody must be able to write) when given."""
    env = {**os.environ, "PYTHONPATH": BACKEND}
    if cwd is not None:
        env.update(HOME=str(cwd), SERVODESK_DATA_DIR=str(cwd / "data"))
    return subprocess.run(
        ["setpriv", "--reuid", "65534", "--regid", "65534", "--clear-groups",
         "--inh-caps=-all", sys.executable, *argv],
        capture_output=True, text=True, check=False, env=env, cwd=cwd, timeout=120,
    )  # fmt: skip


@contextmanager
def nobody_dir() -> Iterator[Path]:
    """A directory the unprivileged user can write (pytest's own is root's, mode 700)."""
    with tempfile.TemporaryDirectory(prefix="sdk-ecat-") as d:
        Path(d).chmod(0o777)
        yield Path(d)
