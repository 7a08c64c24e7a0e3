"""``servodesk scan``: the drives on a CAN bus or an EtherCAT line, with their identity and
the profile that matches them (what the Connect page's Scan shows).

    servodesk scan --interface socketcan --channel can0 [--bitrate 500000] [--wait 0.5] [--json]
    servodesk scan --interface ethercat --channel eth1 [--json]

A CC-Link IE TSN station is reached at its address (docs/slmp.md); PROFINET devices are found
by DCP: ``servodesk dcp identify --nic eth1``. Exit codes: 0 done (also when nothing answers),
2 bad input or a bus that cannot be opened.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from typing import Any

from servodesk.cli.backup import _dump, settings_catalog
from servodesk.errors import ValidationError


def register(sub: Any) -> None:
    p = sub.add_parser("scan", help="list the drives on a CAN bus or an EtherCAT line")
    p.add_argument(
        "--interface",
        default="virtual",
        help="python-can interface (virtual, socketcan, pcan, ...) or ethercat",
    )
    p.add_argument(
        "--channel", default="servodesk-sim", help="python-can channel, or the network interface"
    )
    p.add_argument("--bitrate", type=int, default=None, help="bit rate for real CAN interfaces")
    p.add_argument("--wait", type=float, default=0.5, help="seconds to wait for CAN nodes (0.05-3)")
    p.add_argument("--timeout", type=float, default=None, help="SDO time-out in seconds")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def _check(args: argparse.Namespace) -> None:
    from servodesk.links.registry import can_interfaces

    if args.interface in ("slmp", "profinet"):
        raise ValidationError(
            f"{args.interface} has no scan",
            field="interface",
            hint="PROFINET devices are found by DCP: servodesk dcp identify --nic NIC; a "
            "CC-Link IE TSN station is reached at its host:port",
        )
    if args.interface != "ethercat" and args.interface not in can_interfaces():
        raise ValidationError(
            f"unknown interface {args.interface!r}",
            field="interface",
            hint=f"python-can has {', '.join(can_interfaces())}; or ethercat",
        )
    if not 0.05 <= args.wait <= 3.0:
        raise ValidationError(f"--wait {args.wait} is outside 0.05-3 s", field="wait")


async def _scan(args: argparse.Namespace) -> list[dict[str, Any]]:
    """A session manager only: a scan reads identities and keeps nothing, so it opens no
    store (the other commands' _Context would create the data directory and its database)."""
    from servodesk.services.events import EventHub
    from servodesk.services.manager import SessionManager
    from servodesk.settings import Settings

    settings = Settings()
    catalog = settings_catalog(settings)
    timeout = args.timeout or settings.sdo_timeout
    manager = SessionManager(catalog, EventHub(), sdo_timeout=timeout, poll_hz=1.0)
    try:
        found: list[dict[str, Any]] = await manager.scan(
            args.interface, args.channel, args.bitrate, args.wait
        )
        return found
    finally:
        await manager.close_all()


def run(args: argparse.Namespace) -> int:
    _check(args)
    nodes = asyncio.run(_scan(args))
    if args.json:
        _dump({"interface": args.interface, "channel": args.channel, "nodes": nodes})
        print()
        return 0
    what = "slave" if args.interface == "ethercat" else "node"
    if not nodes:
        print(f"no {what} answered on {args.interface}:{args.channel}", file=sys.stderr)
    for n in nodes:
        ids = " ".join(
            f"{k} {n[k]:08X}h" if isinstance(n.get(k), int) else f"{k} -"
            for k in ("vendor_id", "product_code", "revision")
        )
        print(
            f"{what} {n['node_id']:3}  {n.get('device_name') or '(identity not readable)':32}  "
            f"{ids}  profile {n.get('profile_id') or '-'}"
        )
    return 0
