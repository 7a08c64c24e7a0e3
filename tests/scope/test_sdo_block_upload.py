"""SDO block upload (CiA 301 §7.2.4.3.9-§7.2.4.3.12) on a virtual CAN bus, checked both ways
against an independent implementation (docs/scope.md, "Block upload"):

- python-canopen's own SDO client, as a plain master, reads the twin's recording by block
  upload (its BlockUploadStream, CRC on): the twin's server is not only checked by the link
  written beside it;
- servodesk's link reads from python-canopen's own ``LocalNode`` server, which answers a block
  initiate with the normal upload, and from one that aborts it (0504 0001h): the same bytes,
  and the refusal costs one round trip once per node.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator, Callable, Iterator

import canopen
import pytest
import pytest_asyncio
from canopen.objectdictionary import DOMAIN, ODVariable
from canopen.sdo.exceptions import SdoAbortedError
from canopen.sdo.server import SdoServer

from servodesk.domain import sdo_block
from servodesk.domain.address import ObjectAddress as A
from servodesk.errors import ObjectAccessError
from servodesk.links.base import LinkParams
from servodesk.links.canopen_link import BLOCK_THRESHOLD, CanopenLink
from servodesk.sim.bus import SimulatedBus
from tests.conftest import StartSims

NODE = 5
REC = 0x2F00  # The generic twin's recorder (docs/scope.md).
DATA = A(REC + 7)
#: 8 channels: 6064h, 606Ch, 6041h, ... as ``index << 16 | sub << 8 | bits``.
CHANNELS = [0x60640020, 0x606C0020, 0x60410010, 0x60770010, 0x60F40020, 0x60610008]
DEPTH = 400  # 0.1 s at 4 kHz: 400 x 6 x 4 = 9600 bytes, 11 sub-blocks of 127 segments


@pytest.fixture
def sim(sim_bus: StartSims) -> SimulatedBus:
    return sim_bus(("cia402-generic", NODE))


@pytest_asyncio.fixture
async def link(sim: SimulatedBus, channel: str) -> AsyncIterator[CanopenLink]:
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=NODE, timeout=2.0))
    await link.open()
    yield link
    await link.close()


def _record(write: Callable[[int, int, bytes], None], read: Callable[[int, int], bytes]) -> None:
    """Configure the twin's recorder, record DEPTH samples and wait until it is done."""
    write(REC + 6, 0, b"\x00")
    for n in range(1, 9):
        entry = CHANNELS[n - 1] if n <= len(CHANNELS) else 0
        write(REC, n, entry.to_bytes(4, "little"))
    write(REC + 1, 0, (1).to_bytes(2, "little"))
    write(REC + 3, 0, b"\x00")
    write(REC + 2, 0, DEPTH.to_bytes(2, "little"))
    write(REC + 6, 0, b"\x01")
    end = time.monotonic() + 30.0
    while read(REC + 6, 0) != b"\x03":
        assert time.monotonic() < end, "the recorder did not finish"
        time.sleep(0.01)


async def _arecord(link: CanopenLink) -> None:
    async def write(i: int, s: int, d: bytes) -> None:
        await link.write(A(i, s), d)

    await link.write(A(REC + 6), b"\x00")
    for n in range(1, 9):
        entry = CHANNELS[n - 1] if n <= len(CHANNELS) else 0
        await write(REC, n, entry.to_bytes(4, "little"))
    await write(REC + 1, 0, (1).to_bytes(2, "little"))
    await write(REC + 3, 0, b"\x00")
    await write(REC + 2, 0, DEPTH.to_bytes(2, "little"))
    await write(REC + 6, 0, b"\x01")
    end = time.monotonic() + 30.0
    while await link.read(A(REC + 6)) != b"\x03":
        assert time.monotonic() < end, "the recorder did not finish"
        await asyncio.sleep(0.01)


# servodesk's link against the twin ----------------------------------------------------------


async def test_the_recording_comes_by_block_upload_byte_equal(
    link: CanopenLink, sim: SimulatedBus
) -> None:
    await _arecord(link)
    expected = sim.drives[0].read_bytes(DATA.index, 0)
    assert len(expected) == DEPTH * len(CHANNELS) * 4
    tx0, rx0 = link.sdo_frames_tx, link.sdo_frames_rx
    data = await link.read_large(DATA)
    assert data == expected
    assert sim.devices[0].sdo.block_uploads == 1
    segments = -(-len(data) // 7)
    # Block: initiate, start, one ack per 127 segments, end response from the link; a
    # segmented upload would send one request per segment (1372 here).
    assert link.sdo_frames_tx - tx0 == 3 + -(-segments // 127)
    assert link.sdo_frames_rx - rx0 == 2 + segments
    assert not link.block_refused


async def test_lost_and_late_segments_are_sent_again(link: CanopenLink, sim: SimulatedBus) -> None:
    await _arecord(link)
    expected = sim.drives[0].read_bytes(DATA.index, 0)
    server = sim.devices[0].sdo
    # Segment 5 lost, 40 one place late, and the last segment of the second sub-block lost
    # (the link ends that sub-block by its time-out), as a bus could.
    server.drop_segments = {5, 254}
    server.late_segments = {40}
    try:
        assert await link.read_large(DATA) == expected
    finally:
        server.drop_segments, server.late_segments = set(), set()
    assert link.block_resent > 0
    # The link is in step with the server afterwards.
    assert await link.read(A(0x1000)) == bytes.fromhex("92010200")


async def test_a_cancelled_block_upload_leaves_the_node_ready(
    link: CanopenLink, sim: SimulatedBus
) -> None:
    """The scope stops during an upload: the link aborts the transfer, so the twin's server
    (strict: a wrong command in a transfer is refused) takes the next request as new."""
    await _arecord(link)
    expected = sim.drives[0].read_bytes(DATA.index, 0)
    server = sim.devices[0].sdo
    server.drop_segments = {127}  # the first sub-block's last: the link waits for it
    rx0 = link.sdo_frames_rx
    task = asyncio.create_task(link.read_large(DATA))
    end = time.monotonic() + 20.0
    while link.sdo_frames_rx - rx0 < 127:  # the initiate's answer and 126 segments
        assert time.monotonic() < end and not task.done()
        await asyncio.sleep(0.005)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    server.drop_segments = set()
    tx = link.sdo_frames_tx
    await link.write(A(0x6081), (1234).to_bytes(4, "little"))
    assert sim.drives[0].read(0x6081, 0) == 1234
    # Answered at the first send: not refused and retried after a time-out.
    assert link.sdo_frames_tx == tx + 1
    assert await link.read_large(DATA) == expected


async def test_a_large_object_read_once_is_read_by_block_upload_afterwards(
    link: CanopenLink, sim: SimulatedBus
) -> None:
    name = b"servodesk simulated CiA 402 drive"
    assert len(name) > BLOCK_THRESHOLD
    assert await link.read(A(0x1008)) == name  # segmented: the size is learnt
    assert sim.devices[0].sdo.block_uploads == 0
    assert await link.read(A(0x1008)) == name
    assert sim.devices[0].sdo.block_uploads == 1
    # Small objects stay on the expedited upload even through read_large (pst).
    assert await link.read_large(A(0x1000)) == bytes.fromhex("92010200")
    assert sim.devices[0].sdo.block_uploads == 1


async def test_errors_of_the_object_come_back_as_aborts(link: CanopenLink) -> None:
    # While nothing is recorded the data is not available (0800 0024h): not a refusal of
    # block transfers, raised as it is.
    with pytest.raises(ObjectAccessError) as info:
        await link.read_large(DATA)
    assert info.value.code == 0x08000024
    with pytest.raises(ObjectAccessError) as missing:
        await link.read_large(A(0x2FFF))
    assert missing.value.code == 0x06020000
    assert not link.block_refused


async def test_segmented_only_when_block_upload_is_switched_off(
    link: CanopenLink, sim: SimulatedBus
) -> None:
    await _arecord(link)
    link.block_upload = False
    tx0 = link.sdo_frames_tx
    assert await link.read_large(DATA) == sim.drives[0].read_bytes(DATA.index, 0)
    assert sim.devices[0].sdo.block_uploads == 0
    assert link.sdo_frames_tx - tx0 == 1 + -(-DEPTH * len(CHANNELS) * 4 // 7)


# python-canopen's client against the twin ---------------------------------------------------


@pytest.fixture
def master(sim: SimulatedBus, channel: str) -> Iterator[canopen.RemoteNode]:
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    node = canopen.RemoteNode(NODE, canopen.ObjectDictionary())  # type: ignore[no-untyped-call]
    node.sdo.RESPONSE_TIMEOUT = 2.0
    network.add_node(node)
    yield node
    network.disconnect()


@pytest.mark.parametrize("crc", [True, False])
def test_canopen_client_reads_the_twin_by_block_upload(
    master: canopen.RemoteNode, sim: SimulatedBus, crc: bool
) -> None:
    _record(master.sdo.download, master.sdo.upload)
    with master.sdo.open(
        DATA.index, 0, "rb", block_transfer=True, request_crc_support=crc
    ) as stream:
        data = stream.read()
    assert data == sim.drives[0].read_bytes(DATA.index, 0)
    assert len(data) == DEPTH * len(CHANNELS) * 4
    assert sim.devices[0].sdo.block_uploads == 1
    # The twin is ready for the next transfer: the end response closed this one.
    assert master.sdo.upload(0x1000, 0) == bytes.fromhex("92010200")


def test_the_twin_is_strict_about_the_block_protocol(master: canopen.RemoteNode) -> None:
    """Wrong commands in a block upload abort it with CiA 301's codes (§7.2.4.3.17)."""
    sdo_client = master.sdo

    def ask(frame: bytes) -> bytes:
        return bytes(sdo_client.request_response(frame))

    def code(frame: bytes) -> int:
        with pytest.raises(SdoAbortedError) as info:
            ask(frame)
        return int(info.value.code)

    # Block size 0 (0504 0002h).
    assert code(bytes.fromhex("a4081000" + "00000000")) == 0x05040002
    # An upload segment request inside a block upload (0504 0001h).
    answer = ask(sdo_block.initiate_upload(0x1008, 0, 4, 0))
    assert answer[0] == 0xC6
    assert code(bytes.fromhex("6000000000000000")) == 0x05040001
    # An ack beyond the segments sent (0504 0003h): 33 bytes in sub-blocks of 4 segments.
    ask(sdo_block.initiate_upload(0x1008, 0, 4, 0))
    sdo_client.send_request(sdo_block.START)
    for _ in range(4):
        sdo_client.read_response()
    assert code(sdo_block.ack(5, 4)) == 0x05040003
    # A start with no transfer (0504 0001h).
    assert code(sdo_block.START) == 0x05040001
    # pst: 4 bytes <= 8, the server switches to the normal upload (expedited answer).
    assert ask(sdo_block.initiate_upload(0x1000, 0, 127, 8))[0] == 0x43


# servodesk's link against python-canopen's server ------------------------------------------

BIG = bytes((i * 7 + 3) & 0xFF for i in range(3000))


class _Refusing(SdoServer):
    """python-canopen's SDO server with block upload refused by an abort, as some drives do."""

    initiates = 0

    def block_upload(self, data: bytearray) -> None:
        type(self).initiates += 1
        self._index, self._subindex = int.from_bytes(data[1:3], "little"), data[3]
        self.abort(0x05040001)  # type: ignore[no-untyped-call]


def _local(channel: str, refuse: bool) -> tuple[canopen.Network, canopen.LocalNode]:
    od = canopen.ObjectDictionary()  # type: ignore[no-untyped-call]
    var = ODVariable("Big domain", 0x2000, 0)
    var.data_type = DOMAIN
    var.access_type = "rw"
    od.add_object(var)
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    node = canopen.LocalNode(NODE, od)
    if refuse:
        _Refusing.initiates = 0
        node.sdo = _Refusing(0x600 + NODE, 0x580 + NODE, node)  # type: ignore[no-untyped-call]
    network.add_node(node)
    node.set_data(0x2000, 0, BIG)
    return network, node


@pytest.mark.parametrize("refuse", [False, True], ids=["switches", "aborts"])
async def test_link_reads_canopen_local_node_by_falling_back(channel: str, refuse: bool) -> None:
    network, _node = _local(channel, refuse)
    link = CanopenLink(LinkParams(interface="virtual", channel=channel, node_id=NODE, timeout=2.0))
    await link.open()
    try:
        assert await link.read_large(A(0x2000)) == BIG
        assert link.block_refused is refuse
        tx = link.sdo_frames_tx
        assert await link.read_large(A(0x2000)) == BIG
        # The second read goes straight to its segmented upload: initiate + one per segment.
        assert link.sdo_frames_tx - tx == 1 + -(-len(BIG) // 7)
        assert await link.read(A(0x2000)) == BIG
        if refuse:
            assert _Refusing.initiates == 1
    finally:
        await link.close()
        network.disconnect()
