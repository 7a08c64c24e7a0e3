"""An API client on an app serving a simulated drive (real CANopen on a virtual bus)."""

from __future__ import annotations

import itertools
import os
from collections.abc import AsyncIterator

import httpx
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.settings import Settings

_n = itertools.count()


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def client(tmp_path_factory) -> AsyncIterator[httpx.AsyncClient]:  # type: ignore[no-untyped-def]
    settings = Settings(
        sim=True,
        sim_channel=f"api-{os.getpid()}-{next(_n)}",
        sim_profiles="cia402-generic",
        data_dir=tmp_path_factory.mktemp("data"),
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as c:
            yield c
