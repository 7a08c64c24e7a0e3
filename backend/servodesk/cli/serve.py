"""``servodesk serve``: the backend, the UI and (with ``--sim``) simulated drives."""

from __future__ import annotations

import argparse
import secrets
import sys
from typing import Any

from servodesk.settings import Settings


def register(sub: Any) -> None:
    p = sub.add_parser("serve", help="run the backend and the browser UI")
    p.add_argument("--sim", action="store_true", help="start one simulated drive per family")
    p.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=None, help="port (default 8000)")
    p.add_argument("--token", default=None, help="token required when binding beyond loopback")
    p.add_argument("--log-level", default=None, choices=["debug", "info", "warning", "error"])
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import uvicorn

    from servodesk.api.app import create_app

    overrides: dict[str, Any] = {}
    if args.sim:
        overrides["sim"] = True
    if args.host:
        overrides["host"] = args.host
    if args.port is not None:
        if not 1 <= args.port <= 65535:
            print(f"servodesk: error: port {args.port} is outside 1..65535", file=sys.stderr)
            return 2
        overrides["port"] = args.port
    if args.token:
        overrides["token"] = args.token
    if args.log_level:
        overrides["log_level"] = args.log_level
    settings = Settings(**overrides)
    if not settings.is_loopback and not settings.token:
        # DESIGN: binding beyond loopback requires a token; make one and say it.
        settings = settings.model_copy(update={"token": secrets.token_urlsafe(24)})
    shown = "127.0.0.1" if settings.host in ("0.0.0.0", "::") else settings.host
    url = f"http://{shown}:{settings.port}/"
    if settings.token and not settings.is_loopback:
        url += f"?token={settings.token}"
    print(
        f"servodesk: serving on {url}" + ("  (simulated drives)" if settings.sim else ""),
        flush=True,
    )
    app = create_app(settings)
    uvicorn.run(
        app,
        host=settings.host,
        port=settings.port,
        log_level=settings.log_level,
        # uvloop (a dependency on Linux and macOS) when installed: an SDO round trip costs the
        # event loop a third less than on asyncio's own loop (bench/bench_sdo.py --loop).
        loop="auto",
        ws="websockets-sansio" if _has_sansio() else "auto",
    )
    return 0


def _has_sansio() -> bool:
    try:
        import websockets  # noqa: F401
        from uvicorn.protocols.websockets import websockets_sansio_impl  # noqa: F401
    except ImportError:
        return False
    return True
