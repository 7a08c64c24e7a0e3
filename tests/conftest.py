"""Shared fixtures. Tests run against simulated drives on python-can virtual buses."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import pytest

# The 3D viewer binds a TCP port per app; tests that want it (tests/viewer, the viewer page)
# set their own free port, every other app in the suite runs without it.
os.environ.setdefault("SERVODESK_VIEWER_PORT", "0")
# The server answers only to its own host names (docs/security.md): beside the loopback
# names, those the suite's clients send: Starlette's TestClient ("testserver") and the httpx
# ASGITransport clients' base URLs ("http://test", "http://t").
os.environ.setdefault("SERVODESK_ALLOWED_HOSTS", "testserver,test,t")

_counter = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual CAN channel no other test uses (virtual buses are shared by name)."""
    return f"test-{os.getpid()}-{next(_counter)}"


#: Test directories whose tests run on simulated time or none: CPU-bound computation (the
#: tuning's searches on simulated drives), nothing that waits on the wall clock. ``make test``
#: (scripts/run_tests.sh) runs these first on every core, then the rest one at a time: those
#: run drives, buses and browsers on the wall clock and must not be kept waiting for a core.
#: A test here that times something is marked ``wallclock``.
SIMTIME_DIRS = ("tests/tuning", "tests/unit")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    root = Path(config.rootpath)
    for item in items:
        rel = Path(item.path).resolve().relative_to(root).as_posix()
        if rel.startswith(tuple(d + "/" for d in SIMTIME_DIRS)) and not item.get_closest_marker(
            "wallclock"
        ):
            item.add_marker(pytest.mark.simtime)
