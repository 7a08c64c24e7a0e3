"""The tuning's tests run OwnTuning without an application, so no AppState.aclose ends the
search worker (services/tuning/worker.py) they started: each module ends it, as a server's
shutdown does, so that the worker's threads do not outlive the module (tests/conftest.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest


@pytest.fixture(scope="module", autouse=True)
def _end_the_search_worker() -> Iterator[None]:
    yield
    from servodesk.services.tuning import worker

    worker.shutdown()
