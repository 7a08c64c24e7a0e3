"""PROFINET DCP routes: find the devices on a network interface, set a station name or IP
address, flash a device's LED, reset it to factory settings (docs/profinet.md, "DCP").

DCP is layer 2: the calls open a raw socket on the interface (root or CAP_NET_RAW) and block
for their time-out, so they run in a thread. A name, an address or a reset the device
acknowledged goes to the audit log (``GET /audit``, and with old and new value
``GET /audit/writes``), with the X-Servodesk-Client header.
"""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import asdict

from fastapi import APIRouter

from servodesk.api.control_deps import ClientHeader
from servodesk.api.deps import StateDep
from servodesk.api.schemas import (
    ERROR_RESPONSES,
    DcpDeviceOut,
    DcpDeviceRequest,
    DcpDone,
    DcpIdentifyOut,
    DcpIdentifyRequest,
    DcpResetRequest,
    DcpSetRequest,
)
from servodesk.domain import dcp
from servodesk.domain.pnio import RPC_PORT
from servodesk.domain.udp_channel import parse_host_port
from servodesk.errors import ObjectAccessError, ServodeskError, ValidationError
from servodesk.links.profinet_dcp import DcpClient

router = APIRouter(prefix="/dcp", tags=["profinet"], responses=ERROR_RESPONSES)
log = logging.getLogger(__name__)


def _sessions_by_address(state: StateDep) -> dict[tuple[str, int], str]:
    """(host, port) -> the open PROFINET session there."""
    out: dict[tuple[str, int], str] = {}
    for s in state.manager.all():
        if s.link.params.interface != "profinet":
            continue
        try:
            where = parse_host_port(s.link.params.channel, default_port=RPC_PORT, hint="")
        except ServodeskError:
            continue
        out.setdefault(where, s.id)
    return out


def _simulated_ports(state: StateDep) -> dict[str, int]:
    """MAC -> PNIO-CM port of the PROFINET twins ``serve --sim`` runs: they answer on a free
    port, not on 34964, so the channel to open names it."""
    out: dict[str, int] = {}
    for pn in getattr(state.sim, "profinet", ()):
        mac, port = pn.dcp_mac, pn.port
        if mac is not None and port is not None:
            out[dcp.mac_text(mac)] = port
    return out


def _channel(ip: str | None, port: int | None) -> str | None:
    if not ip or ip == "0.0.0.0":
        return None
    return ip if port is None or port == RPC_PORT else f"{ip}:{port}"


@router.post("/identify", operation_id="dcp_identify")
async def dcp_identify(body: DcpIdentifyRequest, state: StateDep) -> DcpIdentifyOut:
    """Every PROFINET device on ``nic`` that answers a DCP Identify within ``timeout``."""
    name = body.name_of_station
    if name is not None:
        dcp.check_name_of_station(name)

    def run() -> tuple[list[dcp.Device], int]:
        with DcpClient(body.nic) as client:
            scan = client.identify(body.timeout, name=name)
        return scan.devices, scan.malformed

    devices, malformed = await asyncio.to_thread(run)
    sessions = _sessions_by_address(state)
    ports = _simulated_ports(state)
    for d in devices:
        state.dcp_seen[d.mac] = (d.vendor_id, d.device_id)
    return DcpIdentifyOut(
        nic=body.nic,
        devices=[
            DcpDeviceOut.model_validate(
                {
                    **asdict(d),
                    "session_id": sessions.get((d.ip or "", ports.get(d.mac, RPC_PORT))),
                    "roles": list(d.roles),
                    "channel": _channel(d.ip, ports.get(d.mac)),
                    "profile_id": _profile_id(state, d.vendor_id, d.device_id),
                }
            )
            for d in devices
        ],
        malformed=malformed,
    )


def _profile_id(state: StateDep, vendor_id: int | None, device_id: int | None) -> str | None:
    p = state.catalog.match_dcp(vendor_id, device_id)
    return p.id if p is not None else None


def _with_profile_hint(state: StateDep, mac: str, exc: ObjectAccessError) -> ObjectAccessError:
    """A device's DCP refusal (BlockError) with what its profile says to do about it
    (the ``dcp`` quirk's ``refusals``), where the last Identify matched the MAC to one."""
    ids = state.dcp_seen.get(mac)
    hint = state.catalog.dcp_refusal_hint(*ids, exc.code) if ids is not None else None
    if hint is not None:
        exc.hint = hint
    return exc


async def _set(
    body: DcpDeviceRequest,
    blocks: tuple[dcp.Block, ...],
    state: StateDep,
    client_id: str | None,
    values: dict[tuple[int, int], str],
) -> list[dcp.Ack]:
    """Send the Set; what the device acknowledged goes to the audit log (session
    ``dcp:<nic>``, drive ``profinet:<mac>``, address ``dcp:<what>``), as parameter writes do."""
    mac = dcp.mac_bytes(body.mac)

    def run() -> list[dcp.Ack]:
        with DcpClient(body.nic) as client:
            return client.set(mac, blocks)

    try:
        acks = await asyncio.to_thread(run)
    except ObjectAccessError as exc:
        if exc.protocol != "dcp":
            raise
        raise _with_profile_hint(state, dcp.mac_text(mac), exc) from None
    log.info("DCP set on %s %s: %s", body.nic, body.mac, [(a.option, a.suboption) for a in acks])
    data = {(b.option, b.suboption): b.data for b in blocks}
    now = time.time()
    for a in acks:
        key = (a.option, a.suboption)
        if key not in values:
            continue  # The LED signal changes nothing on the device.
        state.backups.store.add_audit(
            {
                "time": now,
                "client": client_id or "unknown",
                "session": f"dcp:{body.nic}",
                "drive_key": f"profinet:{dcp.mac_text(mac)}",
                "address": f"dcp:{_DONE[key]}",
                "name": dcp.BLOCK_NAMES[key].removeprefix("the ").removeprefix("a "),
                "new_raw_hex": data.get(key, b"").hex(),
                "new_value": values[key],
            }
        )
    if values:  # The LED signal changes nothing on the device: not audited.
        state.audit.record(
            "config.dcp_set",
            drive=f"profinet:{dcp.mac_text(mac)}",
            details={"nic": body.nic, **{_DONE[k]: v for k, v in values.items()}},
        )
    return acks


_DONE = {
    (dcp.OPT_IP, dcp.SUB_IP): "ip",
    (dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION): "name_of_station",
    (dcp.OPT_CONTROL, dcp.SUB_SIGNAL): "signal",
    (dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY): "reset_to_factory",
}


def _done(mac: str, acks: list[dcp.Ack]) -> DcpDone:
    return DcpDone(
        mac=dcp.mac_text(dcp.mac_bytes(mac)),
        done=[
            _DONE.get((a.option, a.suboption), f"{a.option:02X}h/{a.suboption:02X}h") for a in acks
        ],
    )


@router.post("/set", operation_id="dcp_set")
async def dcp_set(
    body: DcpSetRequest, state: StateDep, x_servodesk_client: ClientHeader = None
) -> DcpDone:
    """Set a device's station name and / or IP suite (checked before anything is sent)."""
    blocks: list[dcp.Block] = []
    values: dict[tuple[int, int], str] = {}
    suffix = "" if body.permanent else " (until power off)"
    if body.name_of_station is not None:
        name = dcp.check_name_of_station(body.name_of_station)
        blocks.append(dcp.name_block(name, permanent=body.permanent))
        values[(dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION)] = name + suffix
    if body.ip is not None:
        ip, mask, gw = dcp.check_ip_suite(body.ip.ip, body.ip.netmask, body.ip.gateway)
        blocks.append(dcp.ip_block(ip, mask, gw, permanent=body.permanent))
        values[(dcp.OPT_IP, dcp.SUB_IP)] = f"{ip}/{mask} gateway {gw}{suffix}"
    if not blocks:
        raise ValidationError(
            "nothing to set", hint="give name_of_station, ip (ip, netmask, gateway) or both"
        )
    return _done(body.mac, await _set(body, tuple(blocks), state, x_servodesk_client, values))


@router.post("/signal", operation_id="dcp_signal")
async def dcp_signal(body: DcpDeviceRequest, state: StateDep) -> DcpDone:
    """Flash the device's LED (the LECSN-T's Network Status LED blinks green, 004 §20.2.3)."""
    return _done(body.mac, await _set(body, (dcp.signal_block(),), state, None, {}))


@router.post("/reset", operation_id="dcp_reset")
async def dcp_reset(
    body: DcpResetRequest, state: StateDep, x_servodesk_client: ClientHeader = None
) -> DcpDone:
    """Reset to factory (004 §20.4.5): the station name becomes "" and the IP 0.0.0.0; mode 8
    also restores the drive's parameters. The device is unreachable until it gets an
    address again."""
    values = {(dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY): f"option {body.mode}"}
    blocks = (dcp.reset_to_factory_block(body.mode),)
    return _done(body.mac, await _set(body, blocks, state, x_servodesk_client, values))
