"""Detection by fieldbus: an EtherCAT slave gets an EtherCAT profile, never a CANopen one.

The HIWIN E twin (vendor AAAAh, product 5) answers on a veth pair. The catalog holds a CANopen
profile with exactly that identity (cia402-generic's objects: 1400h/1800h/1017h, which CoE
does not have): it must never be chosen for the slave. Without an EtherCAT profile for the
identity, the session falls back to the generic EtherCAT profile (cia402-ethercat); with one
imported from an ESI, the import wins. Scan applies the same rule.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from servodesk import devdesc
from servodesk.domain import paramset
from servodesk.domain.profile_loader import ProfileCatalog, save_profile
from servodesk.errors import ServodeskError
from servodesk.links.base import LinkParams
from servodesk.services import pdo as pdo_service
from servodesk.services.events import EventHub
from servodesk.services.manager import SessionManager
from servodesk.sim.bus import SimulatedBus
from servodesk.sim.veth import VethPair

pytestmark = pytest.mark.asyncio

REPO = Path(__file__).resolve().parents[2]
HIWIN_VENDOR, HIWIN_PRODUCT = 0x0000AAAA, 0x00000005


def _catalog_dir(tmp: Path, *, with_esi: bool) -> Path:
    """cia402-ethercat, a CANopen look-alike of the twin's identity, and maybe an ESI import."""
    d = tmp / "profiles"
    d.mkdir()
    shutil.copytree(REPO / "profiles" / "cia402-ethercat", d / "cia402-ethercat")
    data = yaml.safe_load((REPO / "profiles" / "cia402-generic" / "profile.yaml").read_text())
    data.update(
        id="canopen-lookalike",
        identity={"vendor_id": HIWIN_VENDOR, "product_codes": [HIWIN_PRODUCT]},
    )
    (d / "canopen-lookalike").mkdir()
    (d / "canopen-lookalike" / "profile.yaml").write_text(yaml.safe_dump(data), "utf-8")
    if with_esi:
        # The HIWIN family written as an ESI by servodesk and imported back under another id:
        # what a user does with the vendor's ESI of a drive servodesk has no family for.
        hiwin = ProfileCatalog().get("hiwin-e")
        esi = devdesc.export_esi(hiwin)
        imported = devdesc.import_text(esi, "hiwin-esi.xml", "hiwin-esi")
        save_profile(imported, d)
    return d


async def _open_profile(catalog: ProfileCatalog, channel: str) -> tuple[str, str | None]:
    manager = SessionManager(catalog, EventHub(), sdo_timeout=0.5, poll_hz=2.0)
    try:
        s = await manager.open(
            LinkParams(interface="ethercat", channel=channel, node_id=1, timeout=0.5),
            fieldbus="ethercat",
        )
        # "pdo show": the EtherCAT procedure reads 1C12h/1C13h and 1600h../1A00h.., never
        # the CANopen 1400h:01 COB-ID that an EtherCAT slave does not have.
        view = await pdo_service.view(s)
        assert view["kind"] == "ethercat" and view["assignment"], view
        assert any(p["entries"] for p in view["pdos"]), view["pdos"]
        # A backup reads the configurable objects: the chosen profile's are the slave's.
        specs = paramset.configurable(s.profile)
        results = await s.read_many([x.address for x in specs])
        unreadable = {
            x.address.index
            for x, r in zip(specs, results, strict=True)
            if isinstance(r, ServodeskError)
        }
        # The PDO assignment and mapping objects every CoE slave with process data has.
        assert not unreadable & {0x1600, 0x1A00, 0x1C12, 0x1C13, 0x6040, 0x6041}, unreadable
        assert len(unreadable) <= len(specs) // 4, unreadable
        scanned = await manager.scan("ethercat", channel, None, 0.5)
        assert [n["session_id"] for n in scanned] == [s.id]
        # The twin aborts 1018h:03 (issue 46); the SII that SOEM read gives the revision.
        assert scanned[0]["revision"] is not None
        assert scanned[0]["device_name"] == "HIWIN E series EtherCAT drive"
        return s.profile.id, scanned[0]["profile_id"]
    finally:
        await manager.close_all()


@pytest.mark.parametrize(
    ("with_esi", "session_profile", "scan_profile"),
    [
        # No EtherCAT match: the generic EtherCAT profile, in the session and the scan alike
        # (the scan said null until 2026-12-07, issue 46).
        (False, "cia402-ethercat", "cia402-ethercat"),
        (True, "hiwin-esi", "hiwin-esi"),  # The imported ESI matches vendor and product.
    ],
)
async def test_ethercat_slave_never_gets_a_canopen_profile(
    veth: VethPair, tmp_path: Path, with_esi: bool, session_profile: str, scan_profile: str | None
) -> None:
    catalog = ProfileCatalog([_catalog_dir(tmp_path, with_esi=with_esi)])
    # The CANopen look-alike matches the identity: only the fieldbus rule keeps it out.
    lookalike = catalog.match(HIWIN_VENDOR, HIWIN_PRODUCT, None, fieldbus="canopen")
    assert lookalike is not None and lookalike.id == "canopen-lookalike"
    with SimulatedBus.start(drives=[("hiwin-e", 1)], interface="ethercat", channel=veth.slave):
        got = await _open_profile(catalog, veth.master)
    assert got == (session_profile, scan_profile)
    assert catalog.get(got[0]).fieldbus == "ethercat"
