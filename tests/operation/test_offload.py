"""The documents' worker process (api/offload.py): a worker that dies is one 503, not a
server that refuses every later document."""

from __future__ import annotations

import os

import pytest

from servodesk.api import offload
from servodesk.api.errors import status_for
from servodesk.errors import WorkerFailed

pytestmark = pytest.mark.asyncio


async def test_a_dead_worker_fails_its_request_and_the_next_one_works() -> None:
    try:
        with pytest.raises(WorkerFailed) as info:
            await offload.in_process(os._exit, 3)  # The worker dies as if killed for memory.
        assert status_for(info.value) == 503
        assert "try again" in (info.value.hint or "")
        # A new worker answers the next request (a broken pool refused them all before).
        assert await offload.in_process(pow, 2, 10) == 1024
    finally:
        offload.shutdown()
