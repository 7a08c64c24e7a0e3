"""Opening, listing and closing drive sessions; scanning a bus for drives."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import asdict
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import (
    ConflictError,
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ServodeskError,
    ValidationError,
)
from servodesk.links.base import DriveIdentity, DriveLink, LinkParams
from servodesk.links.registry import LinkRegistry
from servodesk.links.registry import registry as default_registry
from servodesk.services.events import EventHub
from servodesk.services.session import Session

log = logging.getLogger(__name__)

GENERIC = "cia402-generic"
#: The fallback of an EtherCAT slave no EtherCAT profile matches: CoE has no 1400h/1800h/1017h,
#: which cia402-generic (CANopen) expects.
GENERIC_ETHERCAT = "cia402-ethercat"


def detection_fieldbus(fieldbus: str) -> str | None:
    """Which profiles may be chosen for a device found on ``fieldbus`` (None: any).

    An EtherCAT slave gets an EtherCAT profile (a shipped family or an imported ESI): a CANopen
    profile's PDO communication objects do not exist over CoE. A CANopen link also reaches the
    simulated twins of other fieldbuses' families (services/simulation.py), so it takes any.
    """
    return fieldbus if fieldbus == "ethercat" else None


def generic_for(fieldbus: str) -> str:
    """The profile used when none matches the identity read on ``fieldbus``."""
    return GENERIC_ETHERCAT if fieldbus == "ethercat" else GENERIC


#: What the UI says about a twin reached over CANopen though its family speaks another fieldbus.
_TWIN_NOTE = "{name} speaks {fieldbus}; its simulated twin runs on CANopen in this session."


class SessionManager:
    def __init__(
        self,
        catalog: ProfileCatalog,
        hub: EventHub,
        *,
        links: LinkRegistry = default_registry,
        sdo_timeout: float = 0.5,
        poll_hz: float = 20.0,
    ) -> None:
        self.catalog = catalog
        self.hub = hub
        self.links = links
        self.sdo_timeout = sdo_timeout
        self.poll_hz = poll_hz
        self._sessions: dict[str, Session] = {}
        self._lock = asyncio.Lock()

    def all(self) -> list[Session]:
        return list(self._sessions.values())

    def get(self, sid: str) -> Session:
        s = self._sessions.get(sid)
        if s is None:
            raise NotFoundError(
                f"no session {sid!r}",
                hint=f"open sessions: {', '.join(self._sessions) or 'none'}",
            )
        return s

    async def open(
        self,
        params: LinkParams,
        profile_id: str | None = None,
        *,
        fieldbus: str = "canopen",
        simulated: bool = False,
    ) -> Session:
        async with self._lock:
            for s in self._sessions.values():
                p = s.link.params
                if p.bus_key() == params.bus_key() and p.node_id == params.node_id:
                    raise ConflictError(
                        f"node {params.node_id} on {params.interface}:{params.channel} is "
                        f"already open as session {s.id}",
                        hint="use that session or close it first",
                    )
            chosen = self.catalog.get(profile_id) if profile_id else None
            link_cls = self.links.get(fieldbus)
            link = link_cls(params)
            try:
                await link.open()
            except LinkError as exc:
                # The bus itself cannot be opened: the request names a bad interface/channel.
                raise ValidationError(exc.message, field="interface", hint=exc.hint) from exc
            try:
                await self._probe(link, params)
                identity = await link.identity()
                note = None
                profile = (
                    chosen
                    or self._detect(identity, link.fieldbus)
                    or await self._detect_by_objects(link)
                )
                if profile is None:
                    profile = await self._from_sdo_info(link, identity)
                    if profile is not None:
                        note = (
                            f"No profile matches vendor 0x{identity.vendor_id or 0:08X} "
                            f"product 0x{identity.product_code or 0:08X}; {profile.id} was "
                            "built from the drive's own object list (SDO Information)."
                        )
                if profile is None:
                    profile = self.catalog.get(generic_for(link.fieldbus))
                    note = (
                        f"No profile matches vendor 0x{identity.vendor_id or 0:08X} product "
                        f"0x{identity.product_code or 0:08X}; using {profile.name}."
                    )
                if profile.fieldbus != link.fieldbus:
                    # The profile's name carries the brand ("SMC LECSN-T ..."): the vendor
                    # in front of it read "SMC SMC LECSN-T".
                    note = _TWIN_NOTE.format(name=profile.name, fieldbus=_bus_name(profile))
                sid = self._new_id(profile, params.node_id)
                session = Session(
                    sid,
                    link,
                    profile,
                    self.hub,
                    identity=identity,
                    simulated=simulated,
                    note=note,
                    poll_hz=self.poll_hz,
                )
                await session.start()
            except BaseException:
                await link.close()
                raise
            self._sessions[sid] = session
        self.publish_sessions()
        log.info("opened session %s (%s)", sid, profile.id)
        return session

    @staticmethod
    async def _probe(link: DriveLink, params: LinkParams) -> None:
        """Fail fast with 'not found' when no device answers at that node."""
        try:
            await link.read(ObjectAddress(0x1000))
        except LinkTimeoutError as exc:
            raise NotFoundError(
                f"node {params.node_id} does not answer on {params.interface} "
                f"channel {params.channel}",
                hint="scan the bus to see which nodes answer; check the node id and bitrate",
            ) from exc
        except ObjectAccessError:
            pass  # It answered (with an abort): the device is there.

    def _detect(self, ident: DriveIdentity, fieldbus: str) -> DeviceProfile | None:
        return self.catalog.match(
            ident.vendor_id,
            ident.product_code,
            ident.revision,
            ident.device_name,
            fieldbus=detection_fieldbus(fieldbus),
        )

    async def _scan_profile(self, ident: DriveIdentity, link: DriveLink) -> str | None:
        """The profile a session opened on this device would get, as far as the identity
        decides it. On EtherCAT that is the rule of :meth:`open` in full (a match among the
        EtherCAT profiles, else the profile built from the slave's SDO Information, else
        ``cia402-ethercat``: no EtherCAT profile names its identity elsewhere than 1018h); on
        CANopen a device no identity matches may still be found by a profile's own identity
        object when a session opens, so it stays None here."""
        prof = self._detect(ident, link.fieldbus)
        if prof is not None:
            return prof.id
        if link.fieldbus != "ethercat":
            return None
        built = await self._from_sdo_info(link, ident)
        return built.id if built is not None else GENERIC_ETHERCAT

    async def _from_sdo_info(self, link: DriveLink, ident: DriveIdentity) -> DeviceProfile | None:
        """An EtherCAT slave no profile matches, described by its own SDO Information
        (ETG.1000.6 §5.6.3): its objects merged over ``cia402-ethercat``
        (devdesc/sdo_info.py), added to the catalog so that backups, reports and the UI's
        profile page find it by id while servodesk runs. None where the slave offers no SDO
        Information or its answers cannot be read: ``cia402-ethercat`` as before."""
        if link.fieldbus != "ethercat":
            return None
        from servodesk.devdesc.sdo_info import BASE_PROFILE, profile_from_sdo_info

        where = f"{link.params.node_id} on {link.params.channel}"
        try:
            objects = await link.object_list()
            if objects is None:
                return None
            profile = profile_from_sdo_info(
                objects,
                self.catalog.get(BASE_PROFILE),
                vendor_id=ident.vendor_id,
                product_code=ident.product_code,
                revision=ident.revision,
                device_name=ident.device_name,
                where=where,
            )
        except ServodeskError as exc:
            log.warning("slave %s: SDO Information not used: %s", where, exc.message)
            return None
        # The same id for the same identity: the one read last stands (a session already
        # open keeps the profile object it was given).
        self.catalog.add(profile)
        log.info("slave %s: profile %s built from its SDO Information", where, profile.id)
        return profile

    async def _detect_by_objects(self, link: DriveLink) -> DeviceProfile | None:
        """Profiles whose identity lives elsewhere than 1018h name the object to read."""
        only = detection_fieldbus(link.fieldbus)
        for p in self.catalog.all():
            if only is not None and p.fieldbus != only:
                continue
            where = p.identity.vendor_id_object
            if not where or p.identity.vendor_id is None:
                continue
            try:
                raw = await link.read(ObjectAddress.parse(where))
            except ServodeskError:
                continue
            if int.from_bytes(raw[:4], "little") == p.identity.vendor_id:
                return p
        return None

    def _new_id(self, profile: DeviceProfile, node_id: int) -> str:
        base = f"{profile.id}-{node_id}"
        sid, n = base, 2
        while sid in self._sessions:
            sid, n = f"{base}-{n}", n + 1
        return sid

    async def close(self, sid: str) -> None:
        session = self.get(sid)
        del self._sessions[sid]
        await session.close()
        self.publish_sessions()

    async def close_all(self) -> None:
        for sid in list(self._sessions):
            try:
                await self.close(sid)
            except ServodeskError:
                log.exception("closing %s", sid)

    def publish_sessions(self) -> None:
        self.hub.publish({"type": "sessions", "sessions": [s.info() for s in self.all()]})

    async def scan(
        self, interface: str, channel: str, bitrate: int | None, timeout: float
    ) -> list[dict[str, Any]]:
        """Nodes on a CAN bus, or the slaves of an EtherCAT line, with their identity and the
        profile that matches them (an open session's node keeps its session's identity)."""
        from servodesk.links import canopen_link

        base = LinkParams(
            interface=interface, channel=channel, bitrate=bitrate, timeout=self.sdo_timeout
        )
        release = None
        if interface == "ethercat":
            from servodesk.links import ethercat_link

            # The line as SOEM's config_init found it, kept configured while the slaves'
            # identities are read (the links of open sessions share the same master).
            count, release = await asyncio.to_thread(ethercat_link.hold_line, channel)
            ids = list(range(1, count + 1))
            link_type: type[DriveLink] = ethercat_link.EthercatLink
        else:
            ids = await asyncio.to_thread(canopen_link.scan, base, timeout)
            link_type = canopen_link.CanopenLink
        try:
            return await self._identify_nodes(base, ids, link_type)
        finally:
            if release is not None:
                # The last user of the line closes the SOEM master: not on the event loop.
                await asyncio.to_thread(release)

    async def _identify_nodes(
        self, base: LinkParams, ids: list[int], link_type: type[DriveLink]
    ) -> list[dict[str, Any]]:
        open_nodes = {
            s.link.params.node_id: s
            for s in self.all()
            if s.link.params.bus_key() == base.bus_key()
        }
        out: list[dict[str, Any]] = []
        for node_id in ids:
            profile_id: str | None = None
            if node_id in open_nodes:
                ident = open_nodes[node_id].identity
            else:
                link = link_type(
                    LinkParams(
                        interface=base.interface,
                        channel=base.channel,
                        bitrate=base.bitrate,
                        node_id=node_id,
                        timeout=self.sdo_timeout,
                    )
                )
                try:
                    await link.open()
                    ident = await link.identity()
                    profile_id = await self._scan_profile(ident, link)
                except ServodeskError:
                    ident = DriveIdentity()
                    profile_id = GENERIC_ETHERCAT if link.fieldbus == "ethercat" else None
                finally:
                    await link.close()
            if node_id in open_nodes:
                profile_id = open_nodes[node_id].profile.id
            out.append(
                {
                    "node_id": node_id,
                    **asdict(ident),
                    "profile_id": profile_id,
                    "session_id": open_nodes[node_id].id if node_id in open_nodes else None,
                }
            )
        return out


def _bus_name(p: DeviceProfile) -> str:
    return {
        "ethercat": "EtherCAT",
        "profinet": "PROFINET",
        "cclink-ie-tsn": "CC-Link IE TSN",
        "canopen": "CANopen",
    }.get(p.fieldbus, p.fieldbus)
