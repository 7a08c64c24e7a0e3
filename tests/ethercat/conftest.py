"""A veth pair per test module: SOEM on one end, the simulated EtherCAT slaves on the other."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from servodesk.sim.veth import VethPair, create_veth


@pytest.fixture(scope="module")
def veth() -> Iterator[VethPair]:
    """Created for the module and deleted after it (creating it needs root / CAP_NET_ADMIN:
    without, the test errors with the reason rather than skipping)."""
    pair = create_veth("sdt")
    try:
        yield pair
    finally:
        pair.delete()
