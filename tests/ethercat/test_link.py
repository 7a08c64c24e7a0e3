"""EthercatLink (pysoem) against the simulated slaves on a veth pair: identity, object
reads and writes, refusals with their CiA 301 abort codes, and the errors of a wrong
address."""

from __future__ import annotations

import time

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import (
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links.base import LinkParams
from servodesk.links.ethercat_link import EthercatLink
from servodesk.links.registry import link_for_interface, registry
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.ethercat_slave import EthercatSlaveSim
from servodesk.sim.veth import VethPair

pytestmark = pytest.mark.asyncio


def _drives(n: int) -> list[SimulatedDrive]:
    cat = ProfileCatalog()
    return [SimulatedDrive(cat.get("hiwin-e"), i + 1, 0x7000 + i) for i in range(n)]


def _link(channel: str, node_id: int = 1, timeout: float = 0.5) -> EthercatLink:
    cls = registry.get(link_for_interface("ethercat"))
    assert cls is EthercatLink
    link = cls(LinkParams(interface="ethercat", channel=channel, node_id=node_id, timeout=timeout))
    assert isinstance(link, EthercatLink)
    return link


async def test_identity_reads_writes_and_refusals(veth: VethPair) -> None:
    drives = _drives(2)
    with EthercatSlaveSim(drives, veth.slave):
        async with _link(veth.master, 2) as link:
            ident = await link.identity()
            assert (ident.vendor_id, ident.product_code, ident.serial) == (0xAAAA, 5, 0x7001)
            assert ident.device_name == "HIWIN E series EtherCAT drive"  # 29 bytes: normal
            assert ident.software_version == "1.7"

            await link.write(ObjectAddress(0x6081), (2500).to_bytes(4, "little"))
            assert drives[1].read(0x6081) == 2500  # the second slave's drive, not the first
            assert drives[0].read(0x6081) != 2500
            assert await link.read(ObjectAddress(0x6081)) == (2500).to_bytes(4, "little")

            failures = link.failures
            with pytest.raises(ObjectAccessError) as info:
                await link.read(ObjectAddress(0x5FFF))
            assert info.value.code == 0x06020000
            assert "Object does not exist in the object dictionary" in info.value.message
            with pytest.raises(ObjectAccessError) as info:
                await link.write(ObjectAddress(0x6041), b"\x00\x00")
            assert info.value.code == 0x06010002
            assert "Attempt to write a read only object" in info.value.message
            assert link.failures == failures + 2


async def test_links_to_two_slaves_share_the_master(veth: VethPair) -> None:
    drives = _drives(2)
    with EthercatSlaveSim(drives, veth.slave) as line:
        first, second = _link(veth.master, 1), _link(veth.master, 2)
        await first.open()
        await second.open()
        frames = line.frames
        await first.close()  # The master stays open for the second link.
        serial = await second.read(ObjectAddress(0x1018, 4))
        assert int.from_bytes(serial, "little") == 0x7001
        assert line.frames > frames
        await second.close()


async def test_round_trip(veth: VethPair) -> None:
    with EthercatSlaveSim(_drives(1), veth.slave):
        async with _link(veth.master) as link:
            n = 200
            start = time.perf_counter()
            for _ in range(n):
                await link.read(ObjectAddress(0x6041))
            per = (time.perf_counter() - start) / n
            assert per < 0.005, f"{per * 1e3:.3f} ms per SDO read"


async def test_wrong_addresses_and_a_silent_line(veth: VethPair) -> None:
    with EthercatSlaveSim(_drives(1), veth.slave) as line:
        with pytest.raises(NotFoundError, match="no EtherCAT slave at position 2"):
            await _link(veth.master, 2).open()
        link = _link(veth.master, 1, timeout=0.2)
        await link.open()
        line.stop()  # The slave goes away under an open link: a time-out, not a hang.
        with pytest.raises(LinkTimeoutError, match="no CoE answer"):
            await link.read(ObjectAddress(0x6041))
        await link.close()
    with pytest.raises(NotFoundError, match="no EtherCAT slave answers"):
        await _link(veth.master).open()
    with pytest.raises(NotFoundError, match="no network interface 'sdnothere0'"):
        await _link("sdnothere0").open()
    for bad in ("..", "eth0:1", "a/b", "x" * 16, ""):
        with pytest.raises(ValidationError, match="is no network interface name"):
            await _link(bad).open()
    with pytest.raises(ValidationError):
        _link(veth.master, 0)
    with pytest.raises(ValidationError, match="does not carry EtherCAT"):
        EthercatLink(LinkParams(interface="virtual", channel=veth.master))


async def test_a_closed_soem_interface_is_a_link_error(veth: VethPair) -> None:
    with EthercatSlaveSim(_drives(1), veth.slave):
        async with _link(veth.master) as link:
            assert link._shared is not None
            link._shared.master.close()  # SOEM's interface gone under the link
            with pytest.raises(LinkError, match="NetworkInterfaceNotOpenError"):
                await link.read(ObjectAddress(0x6041))
