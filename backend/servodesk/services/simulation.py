"""``serve --sim``: one simulated drive per family, each opened as a session.

The drives are CANopen nodes on a virtual bus, except the CC-Link IE TSN one (the CTMM04x),
which answers SLMP on a UDP port of 127.0.0.1 (``SERVODESK_SIM_SLMP``) and is opened over
the SLMP link, as a real unit would be (docs/slmp.md), and the PROFINET one (the LECSN-T),
which answers PNIO-CM record access on a UDP port of 127.0.0.1 (``SERVODESK_SIM_PROFINET``)
and is opened over the PROFINET link (docs/profinet.md). With ``SERVODESK_SIM_ETHERCAT=1`` the
EtherCAT one (the HIWIN E) is a slave of a simulated line behind a veth pair, opened with the
EtherCAT link (pysoem); where the pair cannot be made (no root) it stays a CANopen node, and
the log and its session's note say why (docs/ethercat.md). With ``SERVODESK_SIM_DCP=1`` the
PROFINET twin also answers DCP behind a veth pair, whose other end its session's note names
(docs/profinet.md, "DCP"). ``SERVODESK_SIM_WITHHOLD`` names objects the twins then hold no
value for (a refusal to show; settings.py).
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import ServodeskError
from servodesk.links.base import LinkParams
from servodesk.services.manager import GENERIC_ETHERCAT, SessionManager
from servodesk.settings import Settings, withheld

log = logging.getLogger(__name__)

#: Node ids of the simulated drives, in this order of profiles (others follow).
PREFERRED = ["cia402-generic", "hiwin-e", "smartris", "ctmm04x", "lecsn-t"]


def simulated_drives(catalog: ProfileCatalog, only: str = "") -> list[tuple[str, int]]:
    ids = catalog.ids()
    wanted = [p.strip() for p in only.split(",") if p.strip()]
    if wanted:
        for pid in wanted:
            catalog.get(pid)  # An unknown id fails here with the list of known ones.
        ids = wanted
    else:
        # The generic EtherCAT profile is a detection fallback, not a family: no twin of it.
        ids = [p for p in ids if p != GENERIC_ETHERCAT]
    ordered = [p for p in PREFERRED if p in ids] + [p for p in ids if p not in PREFERRED]
    return [(pid, n + 1) for n, pid in enumerate(ordered)]


def _add_note(session: Any, text: str) -> None:
    session.note = f"{session.note} {text}" if session.note else text


async def start_simulation(
    settings: Settings, catalog: ProfileCatalog, manager: SessionManager
) -> Any:
    from servodesk.model.plantfile import load_plant_file
    from servodesk.sim.bus import SimulatedBus
    from servodesk.sim.engine_base import SimAbort

    drives = simulated_drives(catalog, settings.sim_profiles)
    plant = load_plant_file(settings.sim_plant) if settings.sim_plant is not None else None
    veth, no_ethercat = None, None
    if settings.sim_ethercat:
        from servodesk.sim.veth import create_veth

        try:
            veth = await asyncio.to_thread(create_veth, "sdsim")
        except ServodeskError as exc:
            no_ethercat = f"{exc.message} ({exc.hint})" if exc.hint else exc.message
            log.warning("the EtherCAT twin stays on CANopen: %s", no_ethercat)
    dcp_pair, no_dcp = None, None
    if settings.sim_dcp and settings.sim_profinet:
        from servodesk.sim.veth import create_veth

        try:
            dcp_pair = await asyncio.to_thread(create_veth, "sddcp")
        except ServodeskError as exc:
            no_dcp = f"{exc.message} ({exc.hint})" if exc.hint else exc.message
            log.warning("the PROFINET twin answers no DCP: %s", no_dcp)
    sim = await asyncio.to_thread(
        SimulatedBus.start,
        drives=drives,
        interface=settings.sim_interface,
        channel=settings.sim_channel,
        catalog=catalog,
        plant=plant,
        slmp_channel=settings.sim_slmp or None,
        profinet_channel=settings.sim_profinet or None,
        ethercat=veth,
        dcp=dcp_pair,
    )
    for pid, address in withheld(settings.sim_withhold):
        for drive in sim.drives:
            if drive.profile.id != pid:
                continue
            try:
                drive.withhold(address.index, address.subindex)
            except SimAbort:
                log.warning("SERVODESK_SIM_WITHHOLD: %s has no object %s", pid, address)
    for drive in sim.drives:
        pid, node = drive.profile.id, drive.node_id
        fieldbus, interface, channel, node_id = sim.link_of(drive)
        extra: dict[str, int | str] = {}
        if fieldbus == "profinet":
            # The RPC object UUID names the device's vendor and device ID, as its DCP
            # Identify gives them (the profile's dcp quirk on the twin; docs/profinet.md).
            ids = drive.profile.quirk("dcp", None) or {}
            extra = {k: int(ids[k]) for k in ("vendor_id", "device_id") if k in ids}
            if dcp_pair is not None and sim.profinet and sim.profinet[0].io is not None:
                # The twin's RT frames are on the pair's slave end: cyclic data from the
                # master end (servodesk as its IO controller, docs/profinet.md).
                extra["nic"] = dcp_pair.master
        params = LinkParams(
            interface=interface,
            channel=channel,
            node_id=node_id,
            timeout=settings.sdo_timeout,
            extra=dict(extra),
        )
        try:
            session = await manager.open(params, pid, fieldbus=fieldbus, simulated=True)
            if no_ethercat is not None and drive.profile.fieldbus == "ethercat":
                _add_note(session, f"SERVODESK_SIM_ETHERCAT: {no_ethercat}")
            if fieldbus == "profinet" and dcp_pair is not None:
                _add_note(session, f"DCP: search network interface {dcp_pair.master}.")
            elif fieldbus == "profinet" and no_dcp is not None:
                _add_note(session, f"SERVODESK_SIM_DCP: {no_dcp}")
        except Exception:
            log.exception("could not open the simulated %s drive (node %d)", pid, node)
    return sim
