"""servodesk's CANopen link against the simulated drive (an independent canopen LocalNode)."""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
import threading
import time
from collections.abc import AsyncIterator, Iterator

import can
import canopen
import pytest
import pytest_asyncio
from tests.conftest import StartSims

from servodesk.domain.address import ObjectAddress
from servodesk.errors import (
    LinkClosedError,
    LinkError,
    LinkTimeoutError,
    NotFoundError,
    ObjectAccessError,
    ValidationError,
)
from servodesk.links import canopen_link
from servodesk.links.base import LinkEvent, LinkParams
from servodesk.links.canopen_link import CanopenLink, pool, scan
from servodesk.sim.bus import SimulatedBus

A = ObjectAddress


@pytest.fixture
def sim(sim_bus: StartSims) -> SimulatedBus:
    return sim_bus(("cia402-generic", 5), ("cia402-generic", 6))


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


async def test_a_short_timeout_is_kept_after_a_long_one(link: CanopenLink) -> None:
    # One response timer serves every request of a link; a request with a shorter time-out
    # than the one before must still end on its own time.
    assert await link.read(A(0x1000), timeout=5.0) == bytes.fromhex("92010200")
    await link.nmt("stop")  # CiA 301 §7.3.2.2.1: no SDO in Stopped.
    await asyncio.sleep(0.05)
    t0 = time.monotonic()
    with pytest.raises(LinkTimeoutError):
        await link.read(A(0x1000), timeout=0.1)
    assert time.monotonic() - t0 < 1.0  # Two attempts of 0.1 s, not the earlier 5 s.
    await link.nmt("preop")
    await asyncio.sleep(0.05)
    assert await link.read(A(0x1000)) == bytes.fromhex("92010200")


async def test_closing_ends_the_request_in_flight_and_the_queued_ones(
    sim: SimulatedBus, channel: str
) -> None:
    # Node 42 is absent: without the close the first read would wait 2 x 5 s.
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=42, timeout=5.0))
    await link.open()
    requests, failures = link.requests, link.failures
    in_flight = asyncio.create_task(link.read(A(0x1000)))
    queued = asyncio.create_task(link.read(A(0x1008)))
    await asyncio.sleep(0.05)
    ended: list[float] = []
    t0 = time.monotonic()
    for task in (in_flight, queued):
        task.add_done_callback(lambda _: ended.append(time.monotonic() - t0))
    await link.close()
    for task in (in_flight, queued):
        with pytest.raises(LinkClosedError):
            await task
    assert max(ended) < 0.5
    # The read in flight failed; the queued one never reached the bus.
    assert (link.requests - requests, link.failures - failures) == (1, 1)
    with pytest.raises(LinkClosedError):
        await link.read(A(0x1000))


async def test_network_is_the_shared_canopen_network_while_open(
    sim: SimulatedBus, channel: str
) -> None:
    first = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=5))
    second = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=6))
    with pytest.raises(LinkError, match="not open"):
        _ = first.network
    await first.open()
    await second.open()
    try:
        assert isinstance(first.network, canopen.Network)
        assert first.network is second.network  # One bus per interface and channel.
        assert first.network.bus is not None
    finally:
        await second.close()
        await first.close()
    with pytest.raises(LinkError, match="not open"):
        _ = first.network


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


async def test_a_heartbeat_older_than_the_nmt_command_does_not_undo_it(link: CanopenLink) -> None:
    # A heartbeat every millisecond: one the drive sent just before a command can be read just
    # after it. The state servodesk reports after a command (what a cyclic start or a PDO
    # change decides on) must stay the commanded one, not flip back for a heartbeat period.
    await link.write(A(0x1017), (1).to_bytes(2, "little"))
    await asyncio.sleep(0.05)
    events: list[LinkEvent] = []
    link.add_event_callback(events.append)
    flips: list[tuple[int, list[str]]] = []
    for i in range(100):
        command, expected = ("start", "operational") if i % 2 == 0 else ("preop", "preop")
        events.clear()
        await link.nmt(command)
        await asyncio.sleep(0.01)
        states = [str(e.data["state"]) for e in list(events) if e.kind == "nmt"]
        if states != [expected] or await link.network_state() != expected:
            flips.append((i, states))
    assert not flips, flips


def test_scan_finds_exactly_the_simulated_nodes(sim: SimulatedBus, channel: str) -> None:
    assert scan(LinkParams(interface="virtual", channel=channel), timeout=0.3) == [5, 6]


def test_bad_node_ids_and_buses_are_refused() -> None:
    with pytest.raises(ValidationError, match=r"1\.\.127"):
        CanopenLink(LinkParams(node_id=0))
    with pytest.raises(ValidationError, match="unknown CAN interface"):
        pool.acquire(LinkParams(interface="nocan"))
    with pytest.raises(NotFoundError, match="cannot open CAN interface"):
        pool.acquire(LinkParams(interface="socketcan", channel="nosuchcan9"))


async def test_cancelled_requests_leave_the_link_usable(link: CanopenLink) -> None:
    tasks = [asyncio.create_task(link.read(a)) for a in (A(0x1000), A(0x1008), A(0x1018, 2))]
    await asyncio.sleep(0)  # The first is on the bus, the other two wait for their turn.
    tasks[1].cancel()
    first, second, third = await asyncio.gather(*tasks, return_exceptions=True)
    assert first == bytes.fromhex("92010200")
    assert isinstance(second, asyncio.CancelledError)
    assert third == bytes.fromhex("02040000")
    assert await link.read(A(0x1008)) == b"servodesk simulated CiA 402 drive"


@pytest.mark.skipif(sys.platform != "linux", reason="counts /proc/self/fd")
async def test_opening_and_closing_leaves_no_descriptor_behind(
    sim: SimulatedBus, channel: str
) -> None:
    params = LinkParams(interface="virtual", channel=channel, node_id=5)
    before = len(os.listdir("/proc/self/fd"))
    for _ in range(5):
        link = CanopenLink(params)
        await link.open()
        assert await link.read(A(0x1000)) == bytes.fromhex("92010200")
        await link.close()
    assert len(os.listdir("/proc/self/fd")) == before


async def test_answers_also_arrive_where_the_loop_cannot_watch_an_eventfd(
    sim: SimulatedBus, channel: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Windows' proactor loop has no add_reader and other systems no eventfd: the link then
    # hands answers over with call_soon_threadsafe.
    monkeypatch.setattr(canopen_link._Doorbell, "attach", classmethod(lambda *_: None))
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=5, timeout=5.0))
    await link.open()
    try:
        assert link._doorbell is None
        assert await link.read(A(0x1008)) == b"servodesk simulated CiA 402 drive"
        with pytest.raises(ObjectAccessError) as info:
            await link.write(A(0x6041), b"\x01\x00")
        assert info.value.code == 0x06010002
        await link.nmt("stop")
        await asyncio.sleep(0.05)
        waiting = asyncio.create_task(link.read(A(0x1000)))
        await asyncio.sleep(0.05)
    finally:
        await link.close()
    with pytest.raises(LinkClosedError):
        await waiting


async def test_a_frame_the_adapter_refuses_is_a_link_error(
    link: CanopenLink, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A real adapter refuses frames in bus-off or with a full transmit queue; python-can
    # raises CanOperationError, which is not an OSError. The API must see a LinkError (502),
    # not an unmapped exception (500).
    def refuse(can_id: int, data: bytes, remote: bool = False) -> None:
        raise can.CanOperationError("Transmit buffer full")

    failures = link.failures
    with monkeypatch.context() as patch:
        patch.setattr(link.network, "send_message", refuse)
        with pytest.raises(LinkError, match="could not be sent: Transmit buffer full"):
            await link.read(A(0x1000))
    assert link.failures == failures + 1
    assert await link.read(A(0x1000)) == bytes.fromhex("92010200")


@pytest.mark.skipif(sys.platform == "win32", reason="uvloop is not on Windows")
def test_time_outs_on_uvloop_even_when_the_timer_is_re_armed_late(
    sim: SimulatedBus, channel: str
) -> None:
    """servodesk serve runs on uvloop, whose call_at of a time already past gives a handle
    without when(): the watchdog must not depend on it (it once raised in the timer callback,
    the request then waited forever: a session opened on an absent node hung the API)."""
    import uvloop

    async def main() -> None:
        link = CanopenLink(
            LinkParams(interface="virtual", channel=channel, node_id=42, timeout=0.05)
        )
        await link.open()
        try:
            loop = asyncio.get_running_loop()
            # Re-armed for a deadline the loop has already passed (a late timer on a busy
            # machine): the callback then gets a plain Handle.
            link._watchdog_at = loop.time() - 1.0
            link._watchdog = loop.call_at(loop.time() - 0.5, link._on_watchdog)
            for _ in range(3):
                t0 = time.monotonic()
                with pytest.raises(LinkTimeoutError):
                    await link.read(A(0x1000))
                assert time.monotonic() - t0 < 1.0
        finally:
            await link.close()

    with asyncio.Runner(loop_factory=uvloop.new_event_loop) as runner:
        runner.run(asyncio.wait_for(main(), 10.0))


async def test_an_answer_behind_a_stale_one_is_not_lost(link: CanopenLink) -> None:
    # A request cancelled on the bus (a motion's monitor, ended by a dead-man stop) still gets
    # its answer, which arrives as the next request's first one. When both answers reach the
    # loop together, the second used to be dropped and the request waited out its time-out
    # (0.5 s before the halt at shutdown, CI 2026-11-27).
    cancelled = asyncio.create_task(link.read(A(0x1018, 1)))
    await asyncio.sleep(0)  # On the bus.
    cancelled.cancel()
    await asyncio.gather(cancelled, return_exceptions=True)
    t0 = time.monotonic()
    nxt = asyncio.create_task(link.read(A(0x1000)))
    await asyncio.sleep(0)  # On the bus too.
    time.sleep(0.05)  # noqa: ASYNC251 -- holds the loop: both answers wait in the doorbell.
    assert await nxt == bytes.fromhex("92010200")
    assert time.monotonic() - t0 < 0.2  # The link's time-out is 0.3 s.


async def test_a_stale_read_answer_is_not_taken_for_a_write_of_the_same_object(
    link: CanopenLink, sim: SimulatedBus
) -> None:
    cancelled = asyncio.create_task(link.read(A(0x6081)))
    await asyncio.sleep(0)
    cancelled.cancel()
    await asyncio.gather(cancelled, return_exceptions=True)
    write = asyncio.create_task(link.write(A(0x6081), (123456).to_bytes(4, "little")))
    await asyncio.sleep(0)
    time.sleep(0.05)  # noqa: ASYNC251 -- holds the loop: both answers wait in the doorbell.
    await write  # Not "unexpected answer": the read's answer is dropped, the write's taken.
    assert sim.drives[0].read(0x6081, 0) == 123456


async def test_a_refused_write_is_not_hidden_by_the_answer_to_a_cancelled_one(
    link: CanopenLink, sim: SimulatedBus
) -> None:
    # CiA 301 SDO frames carry no transaction id: the confirmation of a cancelled write of
    # 6060h looks like the answer to the next write of 6060h. It used to be taken for it, and
    # the drive's refusal of that next write (an abort) went unseen: the caller was told a
    # mode was set that the drive had refused.
    cancelled = asyncio.create_task(link.write(A(0x6060), bytes([1])))
    await asyncio.sleep(0)  # On the bus.
    cancelled.cancel()
    await asyncio.gather(cancelled, return_exceptions=True)
    refused = asyncio.create_task(link.write(A(0x6060), bytes([0x55])))
    await asyncio.sleep(0)
    time.sleep(0.05)  # noqa: ASYNC251 -- holds the loop: both answers wait in the doorbell.
    with pytest.raises(ObjectAccessError) as info:
        await refused
    assert info.value.code == 0x06090030
    assert sim.drives[0].read(0x6060, 0) == 1


async def test_a_late_answer_that_arrives_between_requests_settles_what_was_owed(
    link: CanopenLink,
) -> None:
    # The cancelled write's answer arrives while no request waits: it is dropped, and the
    # next request of the same object takes its own answer at once (the link's time-out is
    # 0.3 s; waiting it out would show).
    cancelled = asyncio.create_task(link.write(A(0x6060), bytes([1])))
    await asyncio.sleep(0)
    cancelled.cancel()
    await asyncio.gather(cancelled, return_exceptions=True)
    await asyncio.sleep(0.05)
    t0 = time.monotonic()
    with pytest.raises(ObjectAccessError):
        await link.write(A(0x6060), bytes([0x55]))
    assert await link.read(A(0x6060)) == bytes([1])
    assert time.monotonic() - t0 < 0.2


async def test_after_a_time_out_the_same_object_is_read_right_and_then_at_full_speed(
    link: CanopenLink,
) -> None:
    # A stopped node does not answer SDO (CiA 301 §7.3.2.2.2), so the read times out and its
    # answer is owed, although it never comes. The next read of that object then drops its
    # own answer once (taken for the owed one) and waits out one time-out before its retry:
    # slower, never stale. Once the debt has lapsed (a time-out later), reads are fast again.
    await link.nmt("stop")
    await asyncio.sleep(0.05)
    with pytest.raises(LinkTimeoutError):
        await link.read(A(0x1000))
    await link.nmt("start")
    await asyncio.sleep(0.05)
    assert await link.read(A(0x1000)) == bytes.fromhex("92010200")
    await asyncio.sleep(0.3)
    t0 = time.monotonic()
    for _ in range(3):
        assert await link.read(A(0x1000)) == bytes.fromhex("92010200")
    assert time.monotonic() - t0 < 0.2


@contextlib.contextmanager
def slow_node(channel: str, node: int, delays: list[float | None]) -> Iterator[None]:
    """A node that answers its SDO requests after ``delays`` (one per request, in order;
    None: no answer; 0.05 s once they run out): confirmations, and an abort (06090030h) for a
    write of 55h to 6060h. Raw python-can on the bus, so the link's timing can be set."""
    responder = can.Bus(interface="virtual", channel=channel)
    stop = threading.Event()
    pending = iter(delays)

    def reply(request: bytes) -> None:
        index = int.from_bytes(request[1:3], "little")
        if request[0] & 0xE0 == 0x20 and index == 0x6060 and request[4] == 0x55:
            data = bytes([0x80]) + request[1:4] + (0x06090030).to_bytes(4, "little")
        elif request[0] & 0xE0 == 0x40:
            data = bytes([0x4F]) + request[1:4] + bytes([7, 0, 0, 0])  # 1 byte: 7
        else:
            data = bytes([0x60]) + request[1:4] + bytes(4)
        responder.send(can.Message(arbitration_id=0x580 + node, data=data, is_extended_id=False))

    def serve() -> None:
        while not stop.is_set():
            msg = responder.recv(0.05)
            if msg is not None and msg.arbitration_id == 0x600 + node:
                delay = next(pending, 0.05)
                if delay is not None:
                    threading.Timer(delay, reply, (bytes(msg.data),)).start()

    server = threading.Thread(target=serve, daemon=True)
    server.start()
    try:
        yield
    finally:
        stop.set()
        server.join(1.0)
        responder.shutdown()


async def test_a_refused_write_is_not_hidden_by_the_late_answer_to_a_retried_one(
    channel: str,
) -> None:
    # A drive busy for a moment (an EEPROM save, say) answers the first write of 6060h late,
    # after the link's time-out: the link sends it again, and the late answer to the first
    # send answers the retry. The answer to the second send is still to come; the next write
    # of 6060h used to take it for its own, and the drive's refusal of that write (an abort,
    # which arrives after it) went unseen.
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=9, timeout=0.3))
    with slow_node(channel, 9, [0.4, 0.05, 0.15]):
        await link.open()
        try:
            await link.write(A(0x6060), bytes([1]))  # answered on its retry
            with pytest.raises(ObjectAccessError) as info:
                await link.write(A(0x6060), bytes([0x55]))
            assert info.value.code == 0x06090030
        finally:
            await link.close()


async def test_where_the_first_send_was_lost_the_next_write_is_done_one_time_out_later(
    channel: str,
) -> None:
    # The other case of an answer on the retry: the first send never reached the drive. What
    # the link owes then never comes, and the next write of that object within a time-out
    # drops its own answer once and waits for its retry: done, one time-out slower. Reads
    # (another kind of answer) and other objects are not held up.
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=9, timeout=0.3))
    with slow_node(channel, 9, [None]):
        await link.open()
        try:
            await link.write(A(0x6060), bytes([1]))  # answered on its retry
            t0 = time.monotonic()
            assert await link.read(A(0x6060)) == bytes([7])
            await link.write(A(0x6061), bytes([1]))
            assert time.monotonic() - t0 < 0.2
            t0 = time.monotonic()
            await link.write(A(0x6060), bytes([3]))
            assert 0.25 < time.monotonic() - t0 < 0.6
        finally:
            await link.close()
