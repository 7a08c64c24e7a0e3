"""Shared fixtures. Tests run against simulated drives on python-can virtual buses."""

from __future__ import annotations

import itertools
import os

import pytest

_counter = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual CAN channel no other test uses (virtual buses are shared by name)."""
    return f"test-{os.getpid()}-{next(_counter)}"
