"""An API client on an app serving a simulated drive (real CANopen on a virtual bus).

The client holds control of the drive (its token is on the client's default headers) and an
in-process connection is bound as its dead-man, as a browser tab's WebSocket would be: every
change of the drive needs control, servo on also the dead-man (docs/api.md "Control and
motion as built")."""

from __future__ import annotations

import itertools
import os
from collections.abc import AsyncIterator

import httpx
import pytest_asyncio

from servodesk.api.app import create_app
from servodesk.settings import Settings
from tests.control_helpers import bind_in_process, take_control

_n = itertools.count()

#: The simulated drive's session and the label the client takes control with.
SID = "cia402-generic-1"
CLIENT = "api-test"


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
            token = await take_control(c, SID, CLIENT)
            bind_in_process(app, SID, token, CLIENT)
            yield c
