"""DCP Get (IEC 61158-6-10 DCP-Get.Req / .Res) in the link and the twin (issue 47).

The link's Get goes over a real veth pair to the twin's responder; the frames a client
without servodesk's encoder sends (pnio-dcp puts a zero block length after each option) and
the twin's answers are dissected with scapy's pnio_dcp layer.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

import pytest
from scapy.contrib.pnio import ProfinetIO  # noqa: F401  (binds EtherType 8892h)
from scapy.contrib.pnio_dcp import DCPDeviceIDBlock, DCPIPBlock, DCPNameOfStationBlock
from scapy.layers.l2 import Ether

from servodesk.domain import dcp
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import ObjectAccessError
from servodesk.links.profinet_dcp import DcpClient
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.profinet_dcp import DcpResponder, DcpStation
from servodesk.sim.profinet_device import ProfinetDevice
from servodesk.sim.veth import VethPair, create_veth

pytestmark = pytest.mark.timeout(60)

DEV_MAC = bytes.fromhex("020000aa0001")
TOOL_MAC = bytes.fromhex("020000bb0002")


@pytest.fixture
def pair() -> Iterator[VethPair]:
    with create_veth("sdg") as p:
        yield p


@pytest.fixture
def device(pair: VethPair) -> Iterator[ProfinetDevice]:
    dev = ProfinetDevice(SimulatedDrive(ProfileCatalog().get("lecsn-t"), 1)).start()
    dev.serve_dcp(pair.slave, manage_addresses=True)
    try:
        yield dev
    finally:
        dev.stop()


def test_the_link_gets_name_address_and_ids_from_the_twin(
    pair: VethPair, device: ProfinetDevice
) -> None:
    mac = bytes.fromhex(
        Path(f"/sys/class/net/{pair.slave}/address").read_text().strip().replace(":", "")
    )
    with DcpClient(pair.master) as client:
        got = client.get(mac)
    assert (got.name_of_station, got.ip, got.ip_origin) == ("lecsn-t-1", "127.0.0.1", "static")
    # The same vendor ID as I&M0 and P964.0 (540 = 021Ch, 004 §20.4.4).
    assert (got.vendor_id, got.device_id) == (0x021C, 0x0010)


def test_get_of_an_option_the_device_lacks_is_refused_by_block_error(
    pair: VethPair, device: ProfinetDevice
) -> None:
    mac = bytes.fromhex(
        Path(f"/sys/class/net/{pair.slave}/address").read_text().strip().replace(":", "")
    )
    with DcpClient(pair.master) as client, pytest.raises(ObjectAccessError) as info:
        client.get(mac, ((dcp.OPT_DHCP, 61),))  # DHCP: not an option the twin has
    assert info.value.code == 1


def _responder() -> DcpResponder:
    station = DcpStation(0x021C, 0x0010, "LEC-S-NP (MR-J4-TM)", "axis-1", "10.0.0.5",
                         "255.255.255.0", "0.0.0.0")  # fmt: skip
    return DcpResponder(station, DEV_MAC)


@pytest.mark.parametrize("length_after_each", [False, True])
def test_a_get_request_is_answered_block_by_block(length_after_each: bool) -> None:
    # DCP-Get.Req lists (option, suboption) pairs; pnio-dcp sends a zero block length after
    # each, which the twin skips rather than answering "not supported" (issue 47).
    pairs = [(dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION), (dcp.OPT_IP, dcp.SUB_IP),
             (dcp.OPT_DEVICE, dcp.SUB_DEVICE_ID)]  # fmt: skip
    body = b"".join(bytes(p) + (b"\0\0" if length_after_each else b"") for p in pairs)
    frame = (
        DEV_MAC + TOOL_MAC
        + struct.pack(">HHBBIHH", 0x8892, 0xFEFD, dcp.SERVICE_GET, 0, 77, 0, len(body))
        + body
    ).ljust(60, b"\0")  # fmt: skip
    reply = _responder().answer(frame)
    assert reply is not None
    pkt = Ether(reply)  # scapy's dissector, not servodesk's
    assert bytes(pkt[DCPNameOfStationBlock].name_of_station) == b"axis-1"
    assert pkt[DCPIPBlock].ip == "10.0.0.5"
    assert (pkt[DCPDeviceIDBlock].vendor_id, pkt[DCPDeviceIDBlock].device_id) == (0x021C, 0x0010)
    parsed = dcp.parse(reply)
    assert (parsed.service_id, parsed.service_type, parsed.xid) == (dcp.SERVICE_GET, 1, 77)
