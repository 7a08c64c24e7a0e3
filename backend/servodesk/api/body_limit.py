"""Request body limits, enforced before a route reads a body whole (docs/security.md).

A Content-Length past the route's limit is answered 413 before a byte of the body is read;
a body that streams without one (chunked) is counted as it arrives and cut at the limit,
whichever part of the app was reading it.
"""

from __future__ import annotations

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from servodesk.api.errors import send_error
from servodesk.api.uploads import body_limit, too_large


class BodyLimit:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit, told = body_limit(scope["path"])
        for name, value in scope.get("headers", []):
            # h11 and httptools have already refused a malformed or repeated Content-Length.
            declared = value.strip()
            if name.lower() == b"content-length" and declared.isdigit() and int(declared) > limit:
                await send_error(send, too_large(told))
                return
        received = 0
        cut = False
        started = False

        async def counted() -> Message:
            nonlocal received, cut
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    cut = True
                    raise too_large(told)
            return message

        async def guarded(message: Message) -> None:
            nonlocal started
            # Whatever the app makes of the error from counted() (FastAPI turns an error
            # while parsing a body into its own 400), the answer is the 413 below.
            if cut:
                return
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counted, guarded)
        except Exception:
            if not cut:
                raise
        if cut and not started:
            await send_error(send, too_large(told))
