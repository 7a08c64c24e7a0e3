"""Strict-Transport-Security on a server that speaks HTTPS (RFC 6797).

Once a browser has reached servodesk over HTTPS by a host name, it keeps using HTTPS for that
name (a plant network's man in the middle cannot downgrade it to HTTP). Not sent for an IP
address (RFC 6797 §8.1.1: a browser ignores it there) nor for a loopback name: HSTS holds
for the name on every port, and ``make demo`` serves plain HTTP on localhost.
"""

from __future__ import annotations

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from servodesk.hosts import ip_literal, is_loopback, split_host

#: One year (RFC 6797 §11.2 suggests long); no includeSubDomains: other servers share names.
HEADER = (b"strict-transport-security", b"max-age=31536000")


class Hsts:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not _named(scope):
            await self.app(scope, receive, send)
            return

        async def add(message: Message) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), HEADER]}
            await send(message)

        await self.app(scope, receive, add)


def _named(scope: Scope) -> bool:
    """The request came by a host name that is not loopback's."""
    for name, value in scope.get("headers", []):
        if name.lower() == b"host":
            host = split_host(value)
            return host is not None and ip_literal(host[0]) is None and not is_loopback(host[0])
    return False
