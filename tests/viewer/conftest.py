"""An app serving simulated drives with the 3D viewer on a free port (real viser server)."""

from __future__ import annotations

import itertools
import os
import socket
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest_asyncio
from fastapi import FastAPI

from servodesk.api.app import create_app
from servodesk.api.routes.viewer import viewer
from servodesk.services.viewer import ViewerService
from servodesk.settings import Settings
from tests.control_helpers import bind_in_process, take_control

_n = itertools.count()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def port_is_bound(port: int) -> bool:
    """True when something listens on 127.0.0.1:port."""
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


@dataclass
class Viewer:
    app: FastAPI
    client: httpx.AsyncClient
    service: ViewerService
    port: int


def make_app(tmp_path: Path, profiles: str, viewer_port: int) -> FastAPI:
    settings = Settings(
        sim=True,
        sim_channel=f"viewer-{os.getpid()}-{next(_n)}",
        sim_profiles=profiles,
        data_dir=tmp_path,
        viewer_port=viewer_port,
    )
    return create_app(settings)


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def twin(tmp_path_factory) -> AsyncIterator[Viewer]:  # type: ignore[no-untyped-def]
    """Two simulated drives (generic and HIWIN) and the viewer, for the whole module."""
    port = free_port()
    app = make_app(tmp_path_factory.mktemp("data"), "cia402-generic,hiwin-e", port)
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as c:
            # The tests enable and move the generic drive: the client holds its control (the
            # token on every request) with an in-process connection bound as its dead-man.
            token = await take_control(c, "cia402-generic-1", "viewer-test")
            bind_in_process(app, "cia402-generic-1", token, "viewer-test")
            yield Viewer(app, c, viewer(app), port)
