"""A gateway on a store as the store's, fleet's and reports' API tests run it: the app with its
simulated drives (CANopen only: no SLMP or PROFINET twin), an account and an API client per
role, on SQLite (``url`` empty: the data directory's file) or on the throw-away PostgreSQL of
tests/store/conftest.py."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

from servodesk.api.app import create_app
from servodesk.api.state import state_of
from servodesk.services.users import UserStore
from servodesk.settings import Settings

PASSWORD = "correct horse battery"


@dataclass
class Gateway:
    app: Any
    data_dir: Path
    url: str
    #: An API client per role, logged in as the account of that name.
    clients: dict[str, httpx.AsyncClient]

    @property
    def state(self) -> Any:
        return state_of(self.app)


@contextlib.asynccontextmanager
async def gateway(
    data_dir: Path, url: str, roles: Sequence[str], timeout: float = 60, **settings: Any
) -> AsyncIterator[Gateway]:
    """The running app (lifespan entered) with an account named after each of ``roles``;
    ``settings`` beside the defaults here (a sim channel and profiles, the gateway's name...)."""
    users = UserStore(data_dir, url)
    tokens: dict[str, str] = {}
    try:
        for role in roles:
            users.add(role, role, PASSWORD)
            tokens[role] = users.create_token(role, "tests")[1]
    finally:
        users.close()
    app = create_app(
        Settings(
            **{
                "sim": True,
                "sim_slmp": "",
                "sim_profinet": "",
                "data_dir": data_dir,
                "store_url": url,
                "host": "0.0.0.0",
                "allowed_hosts": "testserver",
                "viewer_port": 0,
                "sdo_timeout": 0.5,
                **settings,
            }
        )
    )
    async with app.router.lifespan_context(app):
        transport = httpx.ASGITransport(app=app)
        clients = {
            role: httpx.AsyncClient(
                transport=transport,
                base_url="http://testserver/api/v1",
                headers={"Authorization": f"Bearer {token}", "X-Servodesk-Client": role},
                timeout=timeout,
            )
            for role, token in tokens.items()
        }
        try:
            yield Gateway(app, data_dir, url, clients)
        finally:
            for c in clients.values():
                await c.aclose()
