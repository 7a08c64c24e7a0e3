"""Defect 6: request bodies are limited before they are read whole: a Content-Length past
the limit is refused at once, and a body without one is counted while it streams (413)."""

from __future__ import annotations

import time
from collections.abc import Iterator

from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.security.server import LiveServer, raw_request, status_of

MiB = 1024 * 1024


def test_a_declared_length_past_the_limit_is_refused_before_the_body(
    token_server: LiveServer,
) -> None:
    # 1 GB announced, not one byte sent: the answer comes at once, not after a time-out.
    req = (
        f"POST /api/v1/backups/upload?filename=x.json HTTP/1.1\r\n"
        f"Host: 127.0.0.1:{token_server.port}\r\nAuthorization: Bearer {token_server.token}\r\n"
        "Content-Type: application/json\r\nContent-Length: 1000000000\r\n\r\n"
    ).encode()
    t0 = time.monotonic()
    answer = raw_request(token_server.port, req, timeout=10)
    assert status_of(answer) == 413, answer[:300]
    assert time.monotonic() - t0 < 5
    assert b"PayloadTooLarge" in answer and b"MiB" in answer


def _chunks(total: int, size: int = MiB) -> Iterator[bytes]:
    sent = 0
    while sent < total:
        yield b" " * size
        sent += size


def test_a_streamed_body_is_counted_and_cut_at_the_limit(loopback_app: FastAPI) -> None:
    with TestClient(loopback_app, base_url="http://127.0.0.1:8000") as c:
        # No Content-Length (chunked): 40 MiB of JSON whitespace to the 32 MiB upload.
        r = c.post(
            "/api/v1/backups/upload?filename=x.json",
            content=_chunks(40 * MiB),
            headers={"Content-Type": "application/json"},
        )
        assert r.status_code == 413, r.text
        assert r.json()["error"] == "PayloadTooLarge" and "32 MiB" in r.json()["message"]
        # An ordinary JSON route has a far smaller limit.
        r = c.post(
            "/api/v1/compare",
            content=b" " * (2 * MiB),
            headers={"Content-Type": "application/json"},
        )
        assert r.status_code == 413 and "1 MiB" in r.json()["message"]
