"""Shared fixtures. Tests run against simulated drives on python-can virtual buses."""

from __future__ import annotations

import itertools
import os

import pytest

# The 3D viewer binds a TCP port per app; tests that want it (tests/viewer, the viewer page)
# set their own free port, every other app in the suite runs without it.
os.environ.setdefault("SERVODESK_VIEWER_PORT", "0")

_counter = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual CAN channel no other test uses (virtual buses are shared by name)."""
    return f"test-{os.getpid()}-{next(_counter)}"
