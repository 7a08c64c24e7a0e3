"""``servodesk serve``: the backend, the UI and (with ``--sim``) simulated drives."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from servodesk.errors import ServodeskError
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
    p.add_argument(
        "--single-user",
        action="store_true",
        help="on loopback: no login even when accounts exist (docs/security.md, Users)",
    )
    p.add_argument("--log-level", default=None, choices=["debug", "info", "warning", "error"])
    tls = p.add_argument_group("HTTPS (docs/security.md, TLS)")
    tls.add_argument("--tls-cert", default=None, metavar="FILE", help="certificate (PEM)")
    tls.add_argument("--tls-key", default=None, metavar="FILE", help="its private key (PEM)")
    tls.add_argument(
        "--insecure-http",
        action="store_true",
        help="beyond loopback: plain HTTP instead of HTTPS (logins cross the network in clear)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import uvicorn

    from servodesk.api.app import create_app

    overrides: dict[str, Any] = {}
    if args.sim:
        overrides["sim"] = True
    if args.plant:
        from servodesk.errors import ServodeskError
        from servodesk.model.plantfile import load_plant_file

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
    if args.single_user:
        overrides["single_user"] = True
    if args.log_level:
        overrides["log_level"] = args.log_level
    settings = Settings(**overrides)
    refused = _needs_accounts(settings)
    if refused:
        print(refused, file=sys.stderr)
        return 2
    with_tls = _tls_or_refuse(settings, args)
    if with_tls is None:
        return 2
    settings = with_tls
    shown = "127.0.0.1" if settings.host in ("0.0.0.0", "::") else settings.host
    url = f"{'https' if settings.https else 'http'}://{shown}:{settings.port}/"
    print(
        f"servodesk: serving on {url}" + ("  (simulated drives)" if settings.sim else ""),
        flush=True,
    )
    if args.single_user and not settings.is_loopback:
        print("servodesk: --single-user is ignored beyond loopback", flush=True)
    app = create_app(settings)
    # Say which mode it runs in (docs/security.md, Users): a login page is no surprise.
    print(f"servodesk: {app.state.servodesk.auth.describe()}", flush=True)
    uvicorn.run(
        app,
        host=settings.host,
        port=settings.port,
        log_level=settings.log_level,
        # uvloop (a dependency on Linux and macOS) when installed: an SDO round trip costs the
        # event loop a third less than on asyncio's own loop (bench/bench_sdo.py --loop).
        loop="auto",
        ssl_certfile=str(settings.tls_cert) if settings.tls_cert else None,
        ssl_keyfile=str(settings.tls_key) if settings.tls_key else None,
        **ws_options(),
    )
    return 0


def _needs_accounts(settings: Settings) -> str | None:
    """Beyond loopback every request needs a login, so an account must exist first.

    No default password and no first-come setup page (docs/security.md, "First start"): the
    first person to reach an open port must not become the administrator."""
    if settings.is_loopback:
        return None
    from servodesk.services.users import UserStore

    users = UserStore(settings.data_dir, settings.store_url)
    try:
        if users.has_accounts():
            return None
    finally:
        users.close()
    return (
        f"servodesk: error: serving on {settings.host} needs a login, and there is no account "
        f"in {settings.data_dir}\n"
        "  hint: create the administrator first: servodesk users add admin --role administrator"
    )


def _tls_or_refuse(settings: Settings, args: argparse.Namespace) -> Settings | None:
    """:func:`_with_tls`, or None after printing why the certificate cannot be used."""
    try:
        return _with_tls(settings, args)
    except ServodeskError as exc:
        print(f"servodesk: error: {exc.message}", file=sys.stderr)
        if exc.hint:
            print(f"  hint: {exc.hint}", file=sys.stderr)
        return None


def _with_tls(settings: Settings, args: argparse.Namespace) -> Settings:
    """HTTPS beyond loopback: the user's pair, else a self-signed one (servodesk/tls.py)."""
    from servodesk import tls

    cert = args.tls_cert or settings.tls_cert
    key = args.tls_key or settings.tls_key
    insecure = args.insecure_http or settings.insecure_http
    if bool(cert) != bool(key):
        raise tls.TlsError(
            "--tls-cert and --tls-key go together", hint="give the certificate and its key"
        )
    if cert and insecure:
        raise tls.TlsError(
            "--insecure-http and --tls-cert contradict each other", hint="drop one of them"
        )
    if cert and key:
        files = tls.user_files(cert, key)
    elif settings.is_loopback:
        return settings  # Only this machine reaches it: plain HTTP (make demo).
    elif insecure:
        print(
            f"servodesk: WARNING: plain HTTP on {settings.host} (--insecure-http): logins, "
            "session cookies and API tokens cross the network in clear text",
            file=sys.stderr,
            flush=True,
        )
        return settings
    else:
        files = tls.self_signed(settings.data_dir, settings.host)
    what = f"self-signed, {files.note}, {files.cert}" if files.generated else str(files.cert)
    print(f"servodesk: TLS certificate ({what})", flush=True)
    print(f"servodesk: SHA-256 fingerprint {files.fingerprint}", flush=True)
    if files.generated:
        print(
            "servodesk: your browser warns about this certificate once: accept it only if "
            "the fingerprint it shows is this one",
            flush=True,
        )
    return settings.model_copy(update={"tls_cert": files.cert, "tls_key": files.key})


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
