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
    p.add_argument(
        "--plant",
        default=None,
        metavar="FILE",
        help="with --sim: the simulated drives run the axis of this TOML plant file "
        "(docs/tuning.md, Plant files)",
    )
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
    if args.plant:
        from servodesk.errors import ServodeskError
        from servodesk.sim.plantfile import load_plant_file

        if not args.sim:
            print(
                "servodesk: error: --plant needs --sim (it describes simulated drives)",
                file=sys.stderr,
            )
            return 2
        try:
            load_plant_file(args.plant)  # Refuse a bad file here, before anything starts.
        except ServodeskError as exc:
            print(f"servodesk: error: {exc.message}", file=sys.stderr)
            if exc.hint:
                print(f"  hint: {exc.hint}", file=sys.stderr)
            return 2
        overrides["sim_plant"] = args.plant
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
        **ws_options(),
    )
    return 0


def ws_options() -> dict[str, Any]:
    """uvicorn's WebSocket settings servodesk runs on (the scope bench uses them too).

    No permessage-deflate: the scope's frames are float64 samples that deflate only ~4:1 at
    ~0.15 ms of event-loop time per frame and client, and that time lands in front of the next
    frame. With 4 drives x 8 channels and 5 clients (``servodesk bench scope``) compression
    roughly doubled the latency from sample to client (p50 14-19 ms -> 9-10 ms without, p99
    50-72 ms -> 28-50 ms). Everything servodesk streams goes to a browser on the same machine
    or the machine's own network, where the bytes cost less than the delay.
    """
    return {
        "ws": "websockets-sansio" if _has_sansio() else "auto",
        "ws_per_message_deflate": False,
    }


def _has_sansio() -> bool:
    try:
        import websockets  # noqa: F401
        from uvicorn.protocols.websockets import websockets_sansio_impl  # noqa: F401
    except ImportError:
        return False
    return True
