"""``servodesk dcp``: find PROFINET devices on a network interface and set their station
name and IP address (PROFINET DCP, layer 2: root or CAP_NET_RAW; docs/profinet.md).

    servodesk dcp identify --nic eth1 [--timeout 1.0] [--name NAME] [--json]
    servodesk dcp set --nic eth1 --mac 00:30:11:aa:bb:cc [--name NAME]
                      [--ip 192.168.0.10 --netmask 255.255.255.0 [--gateway 0.0.0.0]] [--temporary]
    servodesk dcp signal --nic eth1 --mac 00:30:11:aa:bb:cc
    servodesk dcp reset --nic eth1 --mac 00:30:11:aa:bb:cc --mode 2|8 --yes

Exit codes: 0 done, 2 bad input, a device that does not answer or refuses (the message says
which and why).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from typing import Any

from servodesk.cli.backup import settings_catalog
from servodesk.domain import dcp
from servodesk.errors import ObjectAccessError, ValidationError
from servodesk.links.profinet_dcp import DcpClient


def register(sub: Any) -> None:
    p = sub.add_parser("dcp", help="PROFINET DCP: find devices, set station name and IP address")
    cmds = p.add_subparsers(dest="dcp_command", metavar="DCP_COMMAND")

    i = cmds.add_parser("identify", help="list the PROFINET devices on a network interface")
    _nic(i)
    i.add_argument("--timeout", type=float, default=1.0, help="seconds to wait (0.1-10)")
    i.add_argument("--name", help="only the device with this station name")
    i.add_argument("--json", action="store_true", help="print JSON")
    i.set_defaults(func=run_identify)

    s = cmds.add_parser("set", help="set a device's station name and / or IP address")
    _device(s)
    s.add_argument("--name", help="the station name (lower case, e.g. lecsn-t-axis1)")
    s.add_argument("--ip", help="the IP address")
    s.add_argument("--netmask", help="the subnet mask (with --ip)")
    s.add_argument("--gateway", default="0.0.0.0", help="the gateway (default: none)")
    s.add_argument("--temporary", action="store_true", help="until the next power cycle only")
    s.set_defaults(func=run_set)

    g = cmds.add_parser("signal", help="flash a device's LED")
    _device(g)
    g.set_defaults(func=run_signal)

    r = cmds.add_parser("reset", help="reset a device to factory settings (004 §20.4.5)")
    _device(r)
    r.add_argument(
        "--mode",
        type=int,
        choices=sorted(dcp.RESET_MODES),
        required=True,
        help="2: station name and IP; 8: also the drive's parameters",
    )
    r.add_argument("--yes", action="store_true", help="confirm: the device loses its address")
    r.set_defaults(func=run_reset)
    p.set_defaults(func=lambda args: _usage(p))


def _usage(p: argparse.ArgumentParser) -> int:
    p.print_help(sys.stderr)
    return 2


def _nic(p: argparse.ArgumentParser) -> None:
    p.add_argument("--nic", required=True, help="the network interface (`ip link`), e.g. eth1")


def _device(p: argparse.ArgumentParser) -> None:
    _nic(p)
    p.add_argument("--mac", required=True, help="the device's MAC address (from identify)")


def run_identify(args: argparse.Namespace) -> int:
    if not 0.1 <= args.timeout <= 10:
        raise ValidationError(f"--timeout {args.timeout} is outside 0.1-10 s", field="timeout")
    if args.name is not None:
        dcp.check_name_of_station(args.name)
    with DcpClient(args.nic) as client:
        scan = client.identify(args.timeout, name=args.name)
    profiles = _profiles(scan.devices)
    if args.json:
        out = {
            "nic": args.nic,
            "devices": [{**asdict(d), "profile_id": profiles.get(d.mac)} for d in scan.devices],
        }
        out["malformed"] = scan.malformed
        print(json.dumps(out, indent=2))
        return 0
    if not scan.devices:
        print(f"no PROFINET device answered on {args.nic} within {args.timeout} s")
    for d in scan.devices:
        ids = (
            f"{d.vendor_id:04X}h/{d.device_id:04X}h"
            if d.vendor_id is not None and d.device_id is not None
            else "-"
        )
        print(
            f"{d.mac}  {d.name_of_station or '(no name)':24}  "
            f"{d.ip or '-'}/{d.netmask or '-'} gw {d.gateway or '-'} ({d.ip_origin or '-'})  "
            f"vendor/device {ids}  {d.type_of_station or ''}"
            + (f"  profile {profiles[d.mac]}" if d.mac in profiles else "")
        )
    if scan.malformed:
        print(f"{scan.malformed} answer(s) could not be read", file=sys.stderr)
    return 0


def _profiles(devices: list[dcp.Device]) -> dict[str, str]:
    """MAC -> the profile whose ``dcp`` quirk names the device's vendor and device ID (the
    profiles are loaded only when some device answered with them)."""
    if not any(d.vendor_id is not None for d in devices):
        return {}
    catalog = settings_catalog()
    out: dict[str, str] = {}
    for d in devices:
        p = catalog.match_dcp(d.vendor_id, d.device_id)
        if p is not None:
            out[d.mac] = p.id
    return out


#: How long a refused Set waits for the device's Identify answer, which names its vendor and
#: device ID and so the profile whose hint the refusal gets [s].
REFUSAL_IDENTIFY_S = 0.3


def _send(args: argparse.Namespace, blocks: tuple[dcp.Block, ...], what: str) -> int:
    mac = dcp.mac_bytes(args.mac)
    with DcpClient(args.nic) as client:
        try:
            client.set(mac, blocks)
        except ObjectAccessError as exc:
            if exc.protocol != "dcp":
                raise
            # What to do about a refusal is the device's (its profile's ``dcp`` quirk): the
            # LECSN-T refuses an address its rotary switches set (004 §20.1.3(4)).
            seen = client.identify(REFUSAL_IDENTIFY_S).devices
            found = [d for d in seen if d.mac == dcp.mac_text(mac)]
            if found:
                hint = settings_catalog().dcp_refusal_hint(
                    found[0].vendor_id, found[0].device_id, exc.code
                )
                if hint is not None:
                    exc.hint = hint
            raise
    print(f"{dcp.mac_text(mac)}: {what}")
    return 0


def run_set(args: argparse.Namespace) -> int:
    blocks: list[dcp.Block] = []
    done: list[str] = []
    if args.name is not None:
        name = dcp.check_name_of_station(args.name)
        blocks.append(dcp.name_block(name, permanent=not args.temporary))
        done.append(f"station name {name}")
    if args.ip is not None or args.netmask is not None:
        if args.ip is None or args.netmask is None:
            raise ValidationError(
                "--ip and --netmask go together", field="ip", hint="give both (and --gateway)"
            )
        ip, mask, gw = dcp.check_ip_suite(args.ip, args.netmask, args.gateway)
        blocks.append(dcp.ip_block(ip, mask, gw, permanent=not args.temporary))
        done.append(f"IP {ip}/{mask} gateway {gw}")
    if not blocks:
        raise ValidationError("nothing to set", hint="give --name, --ip with --netmask, or both")
    return _send(args, tuple(blocks), "set " + ", ".join(done))


def run_signal(args: argparse.Namespace) -> int:
    return _send(args, (dcp.signal_block(),), "LED flashing")


def run_reset(args: argparse.Namespace) -> int:
    if not args.yes:
        raise ValidationError(
            "a reset to factory clears the station name and the IP address",
            hint="add --yes to confirm",
        )
    return _send(
        args,
        (dcp.reset_to_factory_block(args.mode),),
        f"reset to factory, mode {args.mode}: {dcp.RESET_MODES[args.mode]}",
    )
