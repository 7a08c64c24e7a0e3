"""An in-process servodesk app on ``serve --sim``'s twins, and an httpx client on it.

The shape every API test file had written out for itself (tests/api/conftest.py,
tests/backup/test_api_backups.py, ...): settings with a CAN channel of its own, the app's
lifespan, an ASGI transport. New tests take it from here.
"""

from __future__ import annotations

import contextlib
import itertools
import os
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import httpx

from servodesk.api.app import create_app
from servodesk.settings import Settings

_n = itertools.count()


@contextlib.asynccontextmanager
async def sim_client(
    data_dir: Path, profiles: str, *, base_url: str = "http://t/api/v1", **settings: Any
) -> AsyncIterator[httpx.AsyncClient]:
    """A client of an app whose twins are ``profiles`` (comma-separated profile ids), its
    data in ``data_dir``; ``settings`` are further Settings fields."""
    app = create_app(
        Settings(
            sim=True,
            sim_channel=f"sim-app-{os.getpid()}-{next(_n)}",
            sim_profiles=profiles,
            data_dir=data_dir,
            **settings,
        )
    )
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url=base_url) as c:
            yield c
