"""DCP on a real network interface: servodesk's client on one end of a veth pair, the
LECSN-T twin answering on the other (raw Ethernet frames, EtherType 8892h; needs root or
CAP_NET_RAW, as the EtherCAT tests do).

What an engineer does with a new drive: find it, give it a station name and an IP address,
then open a session at that address; flash its LED to find it in the cabinet; reset it to
factory settings. And what goes wrong: a drive in data exchange refuses a new address, a MAC
that is not there, an interface that does not exist, no permission.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from pathlib import Path

import pytest

from servodesk.domain import dcp
from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import LinkError, NotFoundError, ObjectAccessError, ValidationError
from servodesk.links import profinet_dcp, profinet_link
from servodesk.links.base import LinkParams
from servodesk.links.profinet_dcp import DcpClient
from servodesk.links.profinet_link import ProfinetLink
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.profinet_device import ProfinetDevice
from servodesk.sim.veth import VethPair, create_veth
from tests.ethercat.nobody import as_nobody

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def pair() -> Iterator[VethPair]:
    with create_veth("sdd") as p:
        yield p


@pytest.fixture
def device(pair: VethPair) -> Iterator[ProfinetDevice]:
    dev = ProfinetDevice(SimulatedDrive(ProfileCatalog().get("lecsn-t"), 1)).start()
    dev.serve_dcp(pair.slave, manage_addresses=True)
    try:
        yield dev
    finally:
        dev.stop()


def _params(channel: str) -> LinkParams:
    return LinkParams(interface="profinet", channel=channel, node_id=1, timeout=0.5)


def test_identify_finds_the_drive_with_its_name_address_and_ids(
    pair: VethPair, device: ProfinetDevice
) -> None:
    with DcpClient(pair.master) as client:
        scan = client.identify(0.3)
    assert scan.malformed == 0
    [dev] = scan.devices
    mac = Path(f"/sys/class/net/{pair.slave}/address").read_text().strip()
    assert dev.mac == mac
    # The twin's station name, and the address its PNIO-CM server answers at.
    assert (dev.name_of_station, dev.ip, dev.ip_origin) == ("lecsn-t-1", "127.0.0.1", "static")
    # One vendor ID for DCP and I&M0: 021Ch (540, Mitsubishi Electric, 004 §20.4.4 and
    # P964.0, §20.4.3.5), the one servodesk matches profiles by (issue 47).
    assert (dev.vendor_id, dev.device_id, dev.roles) == (0x021C, 0x0010, ("IO device",))
    assert dev.vendor_id == device.drive.read(0x03C4, 0) == 540
    assert dev.type_of_station == "LEC-S-NP (MR-J4-TM)"


def test_identify_by_name_finds_only_that_station(pair: VethPair, device: ProfinetDevice) -> None:
    with DcpClient(pair.master) as client:
        assert [d.name_of_station for d in client.identify(0.2, name="lecsn-t-1").devices] == [
            "lecsn-t-1"
        ]
        assert client.identify(0.2, name="lecsn-t-9").devices == []


async def test_a_new_name_and_address_then_a_session_there(
    pair: VethPair, device: ProfinetDevice
) -> None:
    port = device.address[1]
    with DcpClient(pair.master) as client:
        mac = dcp.mac_bytes(client.identify(0.2).devices[0].mac)
        acks = client.set(
            mac,
            (
                dcp.name_block("press-2-axis1"),
                dcp.ip_block("10.77.0.5", "255.255.255.0", "0.0.0.0"),
            ),
        )
        assert [a.error for a in acks] == [0, 0]
        [dev] = client.identify(0.2).devices
    assert (dev.name_of_station, dev.ip, dev.netmask) == (
        "press-2-axis1",
        "10.77.0.5",
        "255.255.255.0",
    )
    # The drive answers PNIO-CM at its new address, on the same port.
    assert device.channel == f"10.77.0.5:{port}"
    link = ProfinetLink(_params(f"10.77.0.5:{port}"))
    await link.open()
    try:
        assert (await link.identity()).device_name == "MR-J4-TM"
    finally:
        await link.close()
    # And no longer at the old one.
    old = ProfinetLink(_params(f"127.0.0.1:{port}"))
    with pytest.raises(NotFoundError):
        await old.open()


async def test_a_drive_with_an_open_session_refuses_a_new_address(
    pair: VethPair, device: ProfinetDevice
) -> None:
    link = ProfinetLink(_params(device.channel))
    await link.open()
    try:
        with DcpClient(pair.master) as client:
            mac = dcp.mac_bytes(client.identify(0.2).devices[0].mac)
            with pytest.raises(ObjectAccessError) as info:
                await asyncio.to_thread(
                    client.set, mac, (dcp.ip_block("10.77.0.6", "255.255.255.0", "0.0.0.0"),)
                )
            assert (info.value.protocol, info.value.code) == ("dcp", 6)
            assert "in operation" in info.value.message and info.value.hint
            assert "close servodesk's session" in info.value.hint
            # Flashing the LED is fine in operation (the engineer looks for the drive).
            assert [a.error for a in client.set(mac, (dcp.signal_block(),))] == [0]
        assert device.station.flashes == 1
        # The session goes on where it was.
        assert await link.read(A(0x6041)) is not None
        assert device.station.ip == "127.0.0.1"
    finally:
        await link.close()


async def test_a_client_that_died_without_release_blocks_dcp_only_until_its_ar_times_out(
    pair: VethPair, device: ProfinetDevice, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A supervisor whose process was killed leaves its AR open; the device drops it after
    # the AR's activity time-out (here 1 s), and a new address is then accepted.
    monkeypatch.setattr(profinet_link, "ACTIVITY_TIMEOUT_FACTOR", 10)
    crashed = ProfinetLink(_params(device.channel))
    await crashed.open()  # and never closed: no Release reaches the device
    new_ip = (dcp.ip_block("10.77.0.7", "255.255.255.0", "0.0.0.0"),)
    with DcpClient(pair.master) as client:
        mac = dcp.mac_bytes(client.identify(0.2).devices[0].mac)
        with pytest.raises(ObjectAccessError) as info:
            await asyncio.to_thread(client.set, mac, new_ip)
        assert (info.value.protocol, info.value.code) == ("dcp", 6)
        await asyncio.sleep(1.1)
        assert [a.error for a in await asyncio.to_thread(client.set, mac, new_ip)] == [0]
    assert device.station.ip == "10.77.0.7" and device.ars == 0


async def test_reset_to_factory_leaves_the_drive_without_an_address_until_one_is_set(
    pair: VethPair, device: ProfinetDevice
) -> None:
    port = device.address[1]
    drive = device.drive
    drive.write(0x2088, 0, 500)  # PB08, position loop gain: stored by P4112 (1010h:01)
    drive.write(0x1010, 1, 0x65766173)
    with DcpClient(pair.master) as client:
        mac = dcp.mac_bytes(client.identify(0.2).devices[0].mac)
        # Mode 2: the communication parameters only; the stored gain survives the reset.
        client.set(mac, (dcp.reset_to_factory_block(2),))
        [dev] = client.identify(0.2).devices
        assert (dev.name_of_station, dev.ip, dev.ip_origin) == ("", "0.0.0.0", "not set")
        assert drive.read(0x2088) == 500
        # Mode 8: the drive's parameters too (004 §20.4.5).
        client.set(mac, (dcp.reset_to_factory_block(8),))
        assert drive.read(0x2088) == 370
        with pytest.raises(NotFoundError):
            await ProfinetLink(_params(f"127.0.0.1:{port}")).open()
        client.set(mac, (dcp.ip_block("10.77.0.7", "255.255.255.0", "0.0.0.0"),))
    link = ProfinetLink(_params(f"10.77.0.7:{port}"))
    await link.open()
    await link.close()
    assert device.station.resets == [2, 8]


def test_a_mac_that_is_not_there_is_not_found(
    pair: VethPair, device: ProfinetDevice, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(profinet_dcp, "SET_TIMEOUT_S", 0.1)
    with DcpClient(pair.master) as client, pytest.raises(NotFoundError) as info:
        client.set(bytes.fromhex("0030110a0b0c"), (dcp.signal_block(),))
    assert "no device with MAC 00:30:11:0a:0b:0c answers DCP" in info.value.message


def test_an_interface_that_does_not_exist() -> None:
    with pytest.raises(NotFoundError, match="no network interface 'nope0'"):
        DcpClient("nope0")
    with pytest.raises(ValidationError):
        DcpClient("../eth0")


def test_a_down_interface_says_so(pair: VethPair) -> None:
    import subprocess

    subprocess.run(["ip", "link", "set", pair.master, "down"], check=True)
    with DcpClient(pair.master) as client, pytest.raises(LinkError, match="is down"):
        client.identify(0.1)


def test_without_permission_the_cli_says_what_is_needed() -> None:
    done = as_nobody("-m", "servodesk", "dcp", "identify", "--nic", "lo", "--timeout", "0.1")
    assert done.returncode == 2, done.stderr
    assert "cannot open a raw socket for PROFINET DCP on lo" in done.stderr
    assert "run as root or give CAP_NET_RAW" in done.stderr
    assert "Traceback" not in done.stderr
