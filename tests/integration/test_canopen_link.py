"""servodesk's CANopen link against the simulated drive (an independent canopen LocalNode)."""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator

import pytest
import pytest_asyncio

from servodesk.domain.address import ObjectAddress
from servodesk.errors import LinkTimeoutError, NotFoundError, ObjectAccessError, ValidationError
from servodesk.links.base import LinkEvent, LinkParams
from servodesk.links.canopen_link import CanopenLink, pool, scan
from servodesk.sim.bus import SimulatedBus

A = ObjectAddress


@pytest.fixture
def sim(channel: str):  # type: ignore[no-untyped-def]
    bus = SimulatedBus.start(
        drives=[("cia402-generic", 5), ("cia402-generic", 6)], interface="virtual", channel=channel
    )
    yield bus
    bus.stop()


@pytest_asyncio.fixture
async def link(sim: SimulatedBus, channel: str) -> AsyncIterator[CanopenLink]:
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=5, timeout=0.3))
    await link.open()
    yield link
    await link.close()


async def test_expedited_and_segmented_reads(link: CanopenLink) -> None:
    assert await link.read(A(0x1000)) == bytes.fromhex("92010200")
    assert await link.read(A(0x1008)) == b"servodesk simulated CiA 402 drive"  # 33 bytes
    ident = await link.identity()
    assert ident.vendor_id == 0x5344534B and ident.product_code == 0x402
    assert ident.device_name == "servodesk simulated CiA 402 drive"


async def test_writes_read_back_and_reach_the_drive(link: CanopenLink, sim: SimulatedBus) -> None:
    await link.write(A(0x6081), (250000).to_bytes(4, "little"))
    assert await link.read(A(0x6081)) == (250000).to_bytes(4, "little")
    assert sim.drives[0].read(0x6081, 0) == 250000


@pytest.mark.parametrize(
    ("op", "address", "data", "code"),
    [
        ("write", A(0x6041), b"\x01\x00", 0x06010002),  # read-only
        ("read", A(0x2FFF), b"", 0x06020000),  # no object
        ("read", A(0x1018, 9), b"", 0x06090011),  # no subindex
        ("write", A(0x6081), b"\x01\x00\x00\x00\x00", 0x06070012),  # too long
        ("write", A(0x6081), b"\x01", 0x06070013),  # too short
        ("write", A(0x6072), (5000).to_bytes(2, "little"), 0x06090031),  # above 6072h max
        ("write", A(0x6060), b"\x08", 0x06090030),  # mode the drive does not have
    ],
)
async def test_abort_codes_come_back_with_their_cia301_text(
    link: CanopenLink, op: str, address: ObjectAddress, data: bytes, code: int
) -> None:
    with pytest.raises(ObjectAccessError) as info:
        if op == "read":
            await link.read(address)
        else:
            await link.write(address, data)
    assert info.value.code == code
    assert info.value.protocol == "sdo" and info.value.address == str(address)
    assert info.value.meaning in info.value.message
    # The link stays usable after an abort.
    assert await link.read(A(0x1000)) == bytes.fromhex("92010200")


async def test_concurrent_requests_to_one_node_are_serialised(link: CanopenLink) -> None:
    addrs = [A(0x1000), A(0x1018, 1), A(0x1018, 2), A(0x1008), A(0x6502)] * 6
    results = await asyncio.gather(*(link.read(a) for a in addrs))
    expected = {
        A(0x1000): bytes.fromhex("92010200"),
        A(0x1018, 1): bytes.fromhex("4b534453"),
        A(0x1018, 2): bytes.fromhex("02040000"),
        A(0x1008): b"servodesk simulated CiA 402 drive",
        A(0x6502): bytes.fromhex("2d000000"),
    }
    assert results == [expected[a] for a in addrs]


async def test_two_nodes_share_one_bus(link: CanopenLink, channel: str) -> None:
    other = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=6))
    await other.open()
    try:
        await other.write(A(0x6081), (111).to_bytes(4, "little"))
        a, b = await asyncio.gather(link.read(A(0x6081)), other.read(A(0x6081)))
        assert int.from_bytes(b, "little") == 111 and int.from_bytes(a, "little") != 111
    finally:
        await other.close()


async def test_absent_node_times_out_with_a_hint(sim: SimulatedBus, channel: str) -> None:
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=42, timeout=0.1))
    await link.open()
    try:
        t0 = time.monotonic()
        with pytest.raises(LinkTimeoutError) as info:
            await link.read(A(0x1000))
        assert time.monotonic() - t0 < 1.0
        assert "node id" in (info.value.hint or "")
    finally:
        await link.close()


async def test_emcy_and_nmt_events_reach_subscribers(link: CanopenLink, sim: SimulatedBus) -> None:
    events: list[LinkEvent] = []
    link.add_event_callback(events.append)
    await link.write(A(0x1017), (50).to_bytes(2, "little"))  # Heartbeat every 50 ms.
    sim.drives[0].raise_fault(0x8611)
    for _ in range(100):  # Up to 2 s for the EMCY and a heartbeat to arrive.
        if any(e.kind == "emcy" for e in events) and any(e.kind == "nmt" for e in events):
            break
        await asyncio.sleep(0.02)
    emcy = [e for e in events if e.kind == "emcy"]
    assert emcy and emcy[0].data["code"] == 0x8611
    assert any(e.kind == "nmt" for e in events)
    assert link.last_heartbeat is not None


async def test_nmt_commands_change_the_heartbeat_state(link: CanopenLink) -> None:
    await link.write(A(0x1017), (20).to_bytes(2, "little"))
    await link.nmt("start")
    await asyncio.sleep(0.15)
    assert await link.network_state() == "operational"
    await link.nmt("preop")
    await asyncio.sleep(0.15)
    assert await link.network_state() == "preop"
    with pytest.raises(ValidationError):
        await link.nmt("explode")


def test_scan_finds_exactly_the_simulated_nodes(sim: SimulatedBus, channel: str) -> None:
    assert scan(LinkParams(interface="virtual", channel=channel), timeout=0.3) == [5, 6]


def test_bad_node_ids_and_buses_are_refused() -> None:
    with pytest.raises(ValidationError, match=r"1\.\.127"):
        CanopenLink(LinkParams(node_id=0))
    with pytest.raises(ValidationError, match="unknown CAN interface"):
        pool.acquire(LinkParams(interface="nocan"))
    with pytest.raises(NotFoundError, match="cannot open CAN interface"):
        pool.acquire(LinkParams(interface="socketcan", channel="nosuchcan9"))
