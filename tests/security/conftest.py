"""Fixtures of the security tests: apps as a default loopback server builds them, a valid backup
file, and one real uvicorn server with an account, shared by the tests that need a login."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi import FastAPI

from servodesk.api.app import create_app
from servodesk.domain import paramset
from servodesk.domain.paramset import ParameterSet
from servodesk.settings import Settings
from tests.security.server import LiveServer, serve


@pytest.fixture
def loopback_app(tmp_path: Path) -> FastAPI:
    """An app as ``servodesk serve`` builds it by default: loopback, port 8000, no extra host
    names (the suite's SERVODESK_ALLOWED_HOSTS is cleared), no drives."""
    return create_app(Settings(data_dir=tmp_path / "data", allowed_hosts=""))


def backup_bytes(profile_id: str = "cia402-generic") -> bytes:
    """A valid backup file (checksum included) of ``profile_id``, with no entries."""
    ps = ParameterSet(
        profile_id=profile_id, profile_version="1", time="2026-01-01T00:00:00.000Z", entries=()
    )
    return paramset.dumps(ps, "servodesk test")


@pytest.fixture(scope="package")
def token_server() -> Iterator[LiveServer]:
    """``servodesk serve`` on 127.0.0.1 with an administrator account, so that every request
    needs a login or an API token (``server.token``; uvicorn, access log at info)."""
    with serve(accounts={"admin": "administrator"}) as server:
        yield server
