"""PROFINET DCP for the API: find the devices on a network interface, set a station name or IP
address, flash a device's LED, reset it to factory settings (docs/profinet.md, "DCP").

DCP is layer 2: the calls open a raw socket on the interface (root or CAP_NET_RAW) and block
for their time-out, so they run in a thread. A name, an address or a reset the device
acknowledged goes to the audit log (``GET /audit``, and with old and new value
``GET /audit/writes``), with the client's label. One :class:`DcpService` belongs to the
application (api/state.py builds it); ``servodesk dcp`` talks to the devices itself and
audits nothing.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from servodesk.domain import dcp
from servodesk.domain.pnio import RPC_PORT
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.domain.udp_channel import parse_host_port
from servodesk.errors import ObjectAccessError, ServodeskError, ValidationError
from servodesk.links.profinet_dcp import DcpClient
from servodesk.services.audit import AuditLog
from servodesk.services.manager import SessionManager
from servodesk.services.store import Store

log = logging.getLogger(__name__)

#: What an acknowledged block did, as the API answers it and the audit log's address names it.
DONE = {
    (dcp.OPT_IP, dcp.SUB_IP): "ip",
    (dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION): "name_of_station",
    (dcp.OPT_CONTROL, dcp.SUB_SIGNAL): "signal",
    (dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY): "reset_to_factory",
}


@dataclass(frozen=True)
class FoundDevice:
    """A device that answered an Identify, and what servodesk knows about it."""

    device: dcp.Device
    #: The open PROFINET session at the device's address (None: none).
    session_id: str | None
    #: The channel a session opens it on (None: the device has no address yet).
    channel: str | None
    #: The profile whose ``dcp`` quirk names its vendor and device ID.
    profile_id: str | None


@dataclass(frozen=True)
class Found:
    """An Identify's answers: the devices, and how many answers could not be read."""

    devices: list[FoundDevice]
    malformed: int


class DcpService:
    """DCP on the server's network interfaces, with the sessions, profiles and audit log."""

    def __init__(
        self, manager: SessionManager, catalog: ProfileCatalog, store: Store, audit: AuditLog
    ) -> None:
        self._manager = manager
        self._catalog = catalog
        self._store = store
        self._audit = audit
        #: MAC -> PNIO-CM port of the PROFINET twins ``serve --sim`` runs: they answer on a
        #: free port, not on 34964, so the channel to open names it (late-bound: the twins
        #: start with the application).
        self.simulated_ports: Callable[[], dict[str, int]] = dict
        #: The PROFINET vendor and device ID each MAC answered the last Identify with.
        self._seen: dict[str, tuple[int | None, int | None]] = {}

    async def identify(self, nic: str, timeout: float, name: str | None = None) -> Found:
        """Every device on ``nic`` that answers a DCP Identify within ``timeout``."""
        if name is not None:
            dcp.check_name_of_station(name)

        def run() -> tuple[list[dcp.Device], int]:
            with DcpClient(nic) as client:
                scan = client.identify(timeout, name=name)
            return scan.devices, scan.malformed

        devices, malformed = await asyncio.to_thread(run)
        sessions = self._sessions_by_address()
        ports = self.simulated_ports()
        for d in devices:
            self._seen[d.mac] = (d.vendor_id, d.device_id)
        return Found(
            devices=[
                FoundDevice(
                    device=d,
                    session_id=sessions.get((d.ip or "", ports.get(d.mac, RPC_PORT))),
                    channel=_channel(d.ip, ports.get(d.mac)),
                    profile_id=self._profile_id(d.vendor_id, d.device_id),
                )
                for d in devices
            ],
            malformed=malformed,
        )

    async def set_station(
        self,
        nic: str,
        mac: str,
        *,
        name: str | None,
        ip: tuple[str, str, str] | None,
        permanent: bool,
        client: str | None,
    ) -> list[str]:
        """Set a device's station name and / or IP suite (``ip``: address, netmask, gateway),
        checked before anything is sent; what the device acknowledged (:data:`DONE`)."""
        blocks: list[dcp.Block] = []
        values: dict[tuple[int, int], str] = {}
        suffix = "" if permanent else " (until power off)"
        if name is not None:
            name = dcp.check_name_of_station(name)
            blocks.append(dcp.name_block(name, permanent=permanent))
            values[(dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION)] = name + suffix
        if ip is not None:
            addr, mask, gw = dcp.check_ip_suite(*ip)
            blocks.append(dcp.ip_block(addr, mask, gw, permanent=permanent))
            values[(dcp.OPT_IP, dcp.SUB_IP)] = f"{addr}/{mask} gateway {gw}{suffix}"
        if not blocks:
            raise ValidationError(
                "nothing to set", hint="give name_of_station, ip (ip, netmask, gateway) or both"
            )
        return await self._set(nic, mac, tuple(blocks), client, values)

    async def signal(self, nic: str, mac: str) -> list[str]:
        """Flash the device's LED (the LECSN-T's Network Status LED blinks green, 004
        §20.2.3); it changes nothing on the device, so nothing is audited."""
        return await self._set(nic, mac, (dcp.signal_block(),), None, {})

    async def reset(self, nic: str, mac: str, mode: int, client: str | None) -> list[str]:
        """Reset to factory (004 §20.4.5) with ``mode`` (:data:`dcp.RESET_MODES`)."""
        values = {(dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY): f"option {mode}"}
        return await self._set(nic, mac, (dcp.reset_to_factory_block(mode),), client, values)

    async def _set(
        self,
        nic: str,
        mac_text: str,
        blocks: tuple[dcp.Block, ...],
        client_id: str | None,
        values: dict[tuple[int, int], str],
    ) -> list[str]:
        """Send the Set; what the device acknowledged goes to the audit log (session
        ``dcp:<nic>``, drive ``profinet:<mac>``, address ``dcp:<what>``), as parameter writes
        do."""
        mac = dcp.mac_bytes(mac_text)

        def run() -> list[dcp.Ack]:
            with DcpClient(nic) as client:
                return client.set(mac, blocks)

        try:
            acks = await asyncio.to_thread(run)
        except ObjectAccessError as exc:
            if exc.protocol != "dcp":
                raise
            raise self._with_profile_hint(dcp.mac_text(mac), exc) from None
        log.info("DCP set on %s %s: %s", nic, mac_text, [(a.option, a.suboption) for a in acks])
        data = {(b.option, b.suboption): b.data for b in blocks}
        now = time.time()
        for a in acks:
            key = (a.option, a.suboption)
            if key not in values:
                continue  # The LED signal changes nothing on the device.
            self._store.add_audit(
                {
                    "time": now,
                    "client": client_id or "unknown",
                    "session": f"dcp:{nic}",
                    "drive_key": f"profinet:{dcp.mac_text(mac)}",
                    "address": f"dcp:{DONE[key]}",
                    "name": dcp.BLOCK_NAMES[key].removeprefix("the ").removeprefix("a "),
                    "new_raw_hex": data.get(key, b"").hex(),
                    "new_value": values[key],
                }
            )
        if values:  # The LED signal changes nothing on the device: not audited.
            self._audit.record(
                "config.dcp_set",
                drive=f"profinet:{dcp.mac_text(mac)}",
                details={"nic": nic, **{DONE[k]: v for k, v in values.items()}},
            )
        return _done(acks)

    def _sessions_by_address(self) -> dict[tuple[str, int], str]:
        """(host, port) -> the open PROFINET session there."""
        out: dict[tuple[str, int], str] = {}
        for s in self._manager.all():
            if s.link.params.interface != "profinet":
                continue
            try:
                where = parse_host_port(s.link.params.channel, default_port=RPC_PORT, hint="")
            except ServodeskError:
                continue
            out.setdefault(where, s.id)
        return out

    def _profile_id(self, vendor_id: int | None, device_id: int | None) -> str | None:
        p = self._catalog.match_dcp(vendor_id, device_id)
        return p.id if p is not None else None

    def _with_profile_hint(self, mac: str, exc: ObjectAccessError) -> ObjectAccessError:
        """A device's DCP refusal (BlockError) with what its profile says to do about it
        (the ``dcp`` quirk's ``refusals``), where the last Identify matched the MAC to one."""
        ids = self._seen.get(mac)
        hint = self._catalog.dcp_refusal_hint(*ids, exc.code) if ids is not None else None
        if hint is not None:
            exc.hint = hint
        return exc


def _channel(ip: str | None, port: int | None) -> str | None:
    if not ip or ip == "0.0.0.0":
        return None
    return ip if port is None or port == RPC_PORT else f"{ip}:{port}"


def _done(acks: Sequence[dcp.Ack]) -> list[str]:
    return [DONE.get((a.option, a.suboption), f"{a.option:02X}h/{a.suboption:02X}h") for a in acks]
