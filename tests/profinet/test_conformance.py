"""The LECSN-T twin refuses what a real PNIO-CM / PROFIdrive stack refuses (issue 47).

Every test talks to the twin's RPC server over a real UDP socket. Frames are built with
servodesk's own encoder (domain/pnio.py) and, where it fits, with scapy's independent
PROFINET / DCE-RPC layers (scapy.contrib.pnio_rpc, scapy.layers.dcerpc), so that a mistake
shared by the encoder and the twin cannot hide. Each test names the clause it checks;
docs/profinet.md has the conformance table.
"""

from __future__ import annotations

import dataclasses
import json
import os
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from scapy.contrib.pnio_rpc import ARBlockReq, PNIOServiceResPDU
from scapy.layers.dcerpc import DceRpc4

from servodesk.domain import pnio
from servodesk.domain import profidrive as pd
from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.links.profinet_link import ProfinetLink, interface_mac_for
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.profinet_device import ProfinetDevice

pytestmark = pytest.mark.timeout(120)

MAC_A = bytes.fromhex("02aa00000001")
MAC_B = bytes.fromhex("02bb00000002")


@pytest.fixture(scope="module")
def catalog() -> ProfileCatalog:
    return ProfileCatalog()


@pytest.fixture
def device(catalog: ProfileCatalog) -> Iterator[ProfinetDevice]:
    with ProfinetDevice(SimulatedDrive(catalog.get("lecsn-t"), 1)) as dev:
        yield dev


class Client:
    """A bare PNIO-CM client on one UDP socket: one activity, explicit sequence numbers."""

    def __init__(self, dev: ProfinetDevice) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(1.0)
        self.sock.connect(dev.address)
        self.activity = uuid.uuid4()
        self.seq = 0

    def datagram(
        self, opnum: int, args: bytes, *, seq: int | None = None, interface: uuid.UUID | None = None
    ) -> bytes:
        if seq is None:
            self.seq += 1
            seq = self.seq
        return pnio.build_rpc(
            pnio.RpcPacket(
                ptype=pnio.PTYPE_REQUEST,
                opnum=opnum,
                object_uuid=pnio.object_uuid(0x021C, 0x0010),
                interface=interface or pnio.DEVICE_INTERFACE,
                activity=self.activity,
                seqnum=seq,
                body=pnio.request_body(args, pnio.MAX_DATAGRAM),
            )
        )

    def send(self, datagram: bytes) -> pnio.RpcPacket:
        self.sock.send(datagram)
        return pnio.parse_rpc(self.sock.recv(65535))

    def call(self, opnum: int, args: bytes, **kw: object) -> tuple[int, bytes]:
        packet = self.send(self.datagram(opnum, args, **kw))  # type: ignore[arg-type]
        assert packet.ptype == pnio.PTYPE_RESPONSE, packet
        return pnio.parse_response_body(packet.body)

    def connect(self, ar: uuid.UUID, key: int = 1, mac: bytes = MAC_A, name: str = "tool-a") -> int:
        req = pnio.ArRequest(
            ar_uuid=ar,
            session_key=key,
            initiator_mac=mac,
            initiator_object=pnio.object_uuid(0, 0),
            station_name=name,
        )
        status, _ = self.call(pnio.OP_CONNECT, pnio.ar_block_req(req))
        return status

    def write(self, ar: uuid.UUID, index: int, data: bytes, slot: int = 1) -> tuple[int, bytes]:
        head = pnio.RecordHeader(1, ar, pnio.RecordAddress(slot, 1, index), len(data))
        return self.call(pnio.OP_WRITE, pnio.record_request(pnio.BLOCK_WRITE_REQ, head) + data)

    def read(self, ar: uuid.UUID, index: int, slot: int = 1) -> tuple[int, bytes]:
        head = pnio.RecordHeader(1, ar, pnio.RecordAddress(slot, 1, index), 1024)
        status, blocks = self.call(pnio.OP_READ, pnio.record_request(pnio.BLOCK_READ_REQ, head))
        if status:
            return status, b""
        _h, record = pnio.parse_record_header(blocks, pnio.BLOCK_READ_RES)
        return 0, record

    def parameters(self, ar: uuid.UUID, request: pd.Request) -> pd.Response:
        status, _ = self.write(ar, pnio.INDEX_PARAMETER_ACCESS, pd.build_request(request))
        assert status == 0
        status, record = self.read(ar, pnio.INDEX_PARAMETER_ACCESS)
        assert status == 0
        return pd.parse_response(record)

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def client(device: ProfinetDevice) -> Iterator[Client]:
    c = Client(device)
    yield c
    c.close()


def status_of(decode: int, code1: int, code2: int, code: int = pnio.ERROR_CODE_CONNECT) -> int:
    return pnio.pnio_status(code, decode, code1, code2)


# AR management -----------------------------------------------------------------------------


def test_a_release_with_the_wrong_session_key_does_not_end_the_ar(
    client: Client, device: ProfinetDevice
) -> None:
    # IEC 61158-6-10 IODReleaseBlock: the SessionKey must be the AR's; a stranger who only
    # guessed the ARUUID ends nothing (ErrorCode1 28h "faulty release block", field 6).
    ar = uuid.uuid4()
    assert client.connect(ar, key=7) == 0
    wrong = pnio.release_block(pnio.BLOCK_RELEASE_REQ, ar, 8, pnio.CONTROL_RELEASE)
    status, _ = client.call(pnio.OP_RELEASE, wrong)
    assert status == status_of(pnio.DECODE_PNIO, 0x28, 0x06, pnio.ERROR_CODE_RELEASE)
    assert device.ars == 1
    right = pnio.release_block(pnio.BLOCK_RELEASE_REQ, ar, 7, pnio.CONTROL_RELEASE)
    assert client.call(pnio.OP_RELEASE, right)[0] == 0
    assert device.ars == 0


def test_another_station_cannot_take_over_a_live_ar(device: ProfinetDevice) -> None:
    # The CM keys an AR by ARUUID and initiator: a connect from another station (MAC, name)
    # with a live ARUUID is a faulty ARBlockReq (field 5, ARUUID), and the AR stays its
    # owner's (its session key too).
    a, b = Client(device), Client(device)
    try:
        ar = uuid.uuid4()
        assert a.connect(ar, key=1) == 0
        assert b.connect(ar, key=99, mac=MAC_B, name="tool-b") == status_of(
            pnio.DECODE_PNIO, 0x01, 0x05
        )
        release = pnio.release_block(pnio.BLOCK_RELEASE_REQ, ar, 1, pnio.CONTROL_RELEASE)
        assert a.call(pnio.OP_RELEASE, release)[0] == 0
    finally:
        a.close()
        b.close()


def test_a_delayed_duplicate_is_answered_from_the_last_reply_not_carried_out(
    client: Client, device: ProfinetDevice
) -> None:
    # CL-RPC (C706 ch. 10): one activity's calls run once each, in sequence-number order.
    # A write of 111 delayed past a write of 222 must not put 111 back.
    ar = uuid.uuid4()
    assert client.connect(ar) == 0

    def change(value: int, seq: int) -> bytes:
        req = pd.Request(
            1, pd.REQUEST_CHANGE, 1, (pd.ParameterAddress(0x6081, 0),),
            (pd.Values(pd.FMT_UINT32, 1, value.to_bytes(4, "big")),),
        )  # fmt: skip
        head = pnio.RecordHeader(1, ar, pnio.RecordAddress(1, 1, 0xB02E), 0)
        data = pd.build_request(req)
        head = pnio.RecordHeader(1, ar, pnio.RecordAddress(1, 1, 0xB02E), len(data))
        return client.datagram(
            pnio.OP_WRITE, pnio.record_request(pnio.BLOCK_WRITE_REQ, head) + data, seq=seq
        )

    old = change(111, 100)
    client.send(old)
    assert device.drive.read(0x6081) == 111
    last = client.send(change(222, 101))
    assert device.drive.read(0x6081) == 222
    replay = client.send(old)  # the delayed duplicate
    assert device.drive.read(0x6081) == 222
    assert replay.seqnum == last.seqnum == 101  # the last reply, as it was sent


def test_an_unknown_operation_or_interface_gets_a_dce_rpc_reject(client: Client) -> None:
    # C706 §12.5.3 / nca_s_*: a reject PDU (ptype 6) with nca_s_op_rng_error for an opnum the
    # interface does not have, nca_s_unk_if for an interface the server does not export;
    # dissected with scapy's DceRpc4, not servodesk's parser.
    for datagram, code in (
        (client.datagram(9, b""), pnio.NCA_OP_RANGE_ERROR),
        (client.datagram(0, b"", interface=uuid.uuid4()), pnio.NCA_UNKNOWN_INTERFACE),
    ):
        client.sock.send(datagram)
        reply = DceRpc4(client.sock.recv(65535))
        assert reply.ptype == 6, reply.show(dump=True)
        assert int.from_bytes(bytes(reply.payload)[:4], "little") == code


@pytest.mark.parametrize(
    ("change", "code1", "code2"),
    [
        ({"block_version_low": 1}, 0x01, 0x03),  # BlockVersionLow must be 0
        ({"ARType": 1}, 0x01, 0x04),  # an IOCAR without IOCR / expected submodules
        ({"ARProperties_DeviceAccess": 0}, 0x01, 0x09),  # no DeviceAccess
        ({"ARProperties_reserved_2": 1}, 0x01, 0x09),  # reserved bits
        ({"ARProperties_State": 2}, 0x01, 0x09),  # State other than Active
        ({"CMInitiatorUDPRTPort": 0x8894}, 0x01, 0x0B),
        ({"CMInitiatorStationName": b"Bad_Name"}, 0x01, 0x0D),
        ({"CMInitiatorActivityTimeoutFactor": 0}, 0x01, 0x0A),
    ],
)
def test_arblockreq_checks(
    client: Client, change: dict[str, object], code1: int, code2: int
) -> None:
    # IEC 61158-6-10 ARBlockReq: ErrorCode1 01h (faulty ARBlockReq), ErrorCode2 the field.
    fields: dict[str, object] = {
        "ARType": 6,
        "ARUUID": str(uuid.uuid4()),
        "SessionKey": 1,
        "CMInitiatorMacAdd": "02:aa:00:00:00:01",
        "CMInitiatorObjectUUID": str(pnio.object_uuid(0, 0)),
        "ARProperties_DeviceAccess": 1,
        "ARProperties_ParametrizationServer": 1,
        "CMInitiatorActivityTimeoutFactor": 100,
        "CMInitiatorUDPRTPort": 0x8892,
        "CMInitiatorStationName": b"scapy-tool",
    }
    good = bytes(ARBlockReq(**fields))  # type: ignore[arg-type]
    assert client.call(pnio.OP_CONNECT, good)[0] == 0  # scapy's frame as such is accepted
    fields["ARUUID"] = str(uuid.uuid4())
    bad = bytes(ARBlockReq(**{**fields, **change}))  # type: ignore[arg-type]
    assert client.call(pnio.OP_CONNECT, bad)[0] == status_of(pnio.DECODE_PNIO, code1, code2)


def test_unknown_and_unexpected_blocks_are_refused(client: Client) -> None:
    # ConnectReq: a block type PNIO-CM does not know is "unknown blocks" (CMRPC 40h / 01h);
    # an IOCR block has no place in a supervisor AR with device access.
    ar = pnio.ar_block_req(pnio.ArRequest(uuid.uuid4(), 1, MAC_A, pnio.object_uuid(0, 0), "tool-a"))
    for extra in (pnio.block(0x7777, bytes(8)), pnio.block(0x0102, bytes(40))):
        status, _ = client.call(pnio.OP_CONNECT, ar + extra)
        assert status == status_of(pnio.DECODE_PNIO, pnio.CMRPC, 0x01)


def test_the_reply_ndr_head_is_consistent(client: Client) -> None:
    # PNIO response body: ArgsMaximum echoes the request's, ActualCount = ArgsLength.
    ar = uuid.uuid4()
    assert client.connect(ar) == 0
    head = pnio.RecordHeader(1, ar, pnio.RecordAddress(0, 1, pnio.INDEX_IM0), 1024)
    datagram = client.datagram(pnio.OP_READ, pnio.record_request(pnio.BLOCK_READ_REQ, head))
    client.sock.send(datagram)
    rpc = DceRpc4(client.sock.recv(65535))  # scapy takes the byte order from the drep
    reply = rpc[PNIOServiceResPDU]
    assert reply.status == 0
    assert reply.max_count == pnio.MAX_DATAGRAM
    assert reply.args_length == reply.actual_count == 64 + reply.blocks[0].recordDataLength


# I&M ---------------------------------------------------------------------------------------


def test_im0_advertises_im1_to_4_and_serves_them(client: Client) -> None:
    # 004 §20.4.4: IM supported 30 (001Eh = I&M1-4). Each is read and written (records
    # AFF1h-AFF4h, blocks 0021h-0024h of IEC 61158-6-10).
    ar = uuid.uuid4()
    assert client.connect(ar) == 0
    status, record = client.read(ar, pnio.INDEX_IM0, slot=0)
    assert status == 0 and pnio.parse_im0(record).supported == 0x001E
    for n in range(1, 5):
        status, record = client.read(ar, pnio.INDEX_IM[n], slot=0)
        assert status == 0
        assert len(pnio.one_block(record, pnio.BLOCK_IM[n])) == pnio.IM_LENGTHS[n]
    tag = b"axis-1 feed".ljust(32) + b"cabinet 3".ljust(22)
    assert client.write(ar, pnio.INDEX_IM[1], pnio.block(0x0021, tag), slot=0)[0] == 0
    assert pnio.one_block(client.read(ar, pnio.INDEX_IM[1], slot=0)[1], 0x0021) == tag
    # A wrong length is a write length error (PNIORW B1h).
    status, _ = client.write(ar, pnio.INDEX_IM[1], pnio.block(0x0021, b"x"), slot=0)
    assert status >> 8 & 0xFFFF == (pnio.DECODE_PNIORW << 8) | 0xB1


# PROFIdrive (004 §20.4) ---------------------------------------------------------------------


def _read(client: Client, ar: uuid.UUID, *addresses: pd.ParameterAddress) -> pd.Response:
    return client.parameters(ar, pd.Request(1, pd.REQUEST_READ, 1, addresses))


def test_profidrive_rules(client: Client, device: ProfinetDevice) -> None:
    ar = uuid.uuid4()
    assert client.connect(ar) == 0
    # Multi-element reads of arrays (004 §20.4.3.5, §20.4.3.7): P964 x5, P975 x8.
    r = _read(client, ar, pd.ParameterAddress(964, 0, elements=5))
    (v,) = r.values
    assert (v.format, v.count) == (pd.FMT_UINT16, 5)
    assert int.from_bytes(v.data[:2], "big") == 540
    r = _read(client, ar, pd.ParameterAddress(975, 0, elements=8))
    (v,) = r.values
    assert v.count == 8 and int.from_bytes(v.data[14:16], "big") == 1  # .7 DO-ID
    # P922 is R (004 §20.4.3.1): a change is error 01h.
    change = pd.Request(
        2, pd.REQUEST_CHANGE, 1, (pd.ParameterAddress(922, 0),),
        (pd.Values(pd.FMT_UINT16, 1, (102).to_bytes(2, "big")),),
    )  # fmt: skip
    (v,) = client.parameters(ar, change).values
    assert v.error == 0x01
    # Identifier bit 9: read-only (PROFIdrive description element 1).
    ro, rw = (
        int.from_bytes(
            _read(client, ar, pd.ParameterAddress(p, pd.DESC_ID, pd.ATTR_DESCRIPTION))
            .values[0]
            .data,
            "big",
        )
        for p in (0x6041, 0x607A)
    )
    assert ro & 0x0200 and not rw & 0x0200
    # A subindex on a parameter without subindexes: 04h "no array" (004 §20.4.2).
    for pnu in (922, 0x607A):
        (v,) = _read(client, ar, pd.ParameterAddress(pnu, 1)).values
        assert v.error == 0x04, pnu


def test_parameter_activation_reads_0_while_busy_and_1_when_done(client: Client) -> None:
    # 004 §20.8.14.1: P11572 <- 1EA5h; it reads 0 while the drive activates (about 100 ms)
    # and 1 when it is done.
    ar = uuid.uuid4()
    assert client.connect(ar) == 0
    change = pd.Request(
        3, pd.REQUEST_CHANGE, 1, (pd.ParameterAddress(11572, 0),),
        (pd.Values(pd.FMT_UINT16, 1, (0x1EA5).to_bytes(2, "big")),),
    )  # fmt: skip
    assert not client.parameters(ar, change).negative
    (busy,) = _read(client, ar, pd.ParameterAddress(11572, 0)).values
    assert int.from_bytes(busy.data, "big") == 0
    time.sleep(0.15)
    (done,) = _read(client, ar, pd.ParameterAddress(11572, 0)).values
    assert int.from_bytes(done.data, "big") == 1


# Every parameter has a value -----------------------------------------------------------------


def test_a_backup_of_the_twin_has_no_unreadable_parameter(
    device: ProfinetDevice, tmp_path: Path
) -> None:
    # Issue 47: every parameter the manual marks readable holds the manual's default or a
    # documented plausible value (profiles/lecsn-t/NOTES.md), so servodesk's own backup over
    # PROFINET has no unreadable entry.
    out = tmp_path / "lecsn.json"
    env = {**os.environ, "SERVODESK_DATA_DIR": str(tmp_path / "data")}
    done = subprocess.run(
        [sys.executable, "-m", "servodesk", "backup", "-o", str(out), "--interface",
         "profinet", "--channel", device.channel, "--node-id", "1"],
        capture_output=True, text=True, env=env, timeout=100,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    doc = json.loads(out.read_text())
    assert doc["unreadable"] == []
    profile = device.drive.profile
    readable = {
        str(s.address)
        for e in profile.entries.values()
        for s in e.specs()
        if s.access.readable and s.index != 0x5F07  # the twin's recorder data (sim only)
    }
    backed_up = {e["address"] for e in doc["entries"]}
    # What a backup takes (the configurable parameters) all came back.
    assert backed_up and backed_up <= readable
    assert len(backed_up) > 2000


# Link side ---------------------------------------------------------------------------------


async def test_the_link_sends_its_nic_mac_and_the_device_ids(device: ProfinetDevice) -> None:
    # IEC 61158-6-10: CMInitiatorMacAdd is the initiator's MAC; the RPC object UUID
    # DEA00000-6C97-11D1-8271-IIII-DDDD-VVVV names the device's vendor and device ID.
    seen: list[pnio.RpcPacket] = []
    answers = device.answers

    def spy(frame: bytes) -> list[bytes]:
        seen.append(pnio.parse_rpc(frame))
        return answers(frame)

    device.answers = spy  # type: ignore[method-assign]
    params = LinkParams(
        interface="profinet",
        channel=device.channel,
        node_id=1,
        timeout=0.5,
        extra={"vendor_id": 0x021C, "device_id": 0x0010},
    )
    link = ProfinetLink(params)
    await link.open()
    try:
        await link.identity()
    finally:
        await link.close()
    connect = seen[0]
    assert connect.opnum == pnio.OP_CONNECT
    assert str(connect.object_uuid).endswith("0001" + "0010" + "021c")
    _max, args = pnio.parse_request_body(connect.body)
    ar = pnio.parse_ar_block_req(pnio.one_block(args, pnio.BLOCK_AR_REQ))
    assert ar.initiator_mac == interface_mac_for("127.0.0.1")  # lo: 00:00:00:00:00:00
    assert {str(p.object_uuid) for p in seen} == {str(connect.object_uuid)}


def test_the_initiator_mac_is_the_nic_that_holds_the_address() -> None:
    # A real NIC's MAC from its address (not zeros): any interface with an IPv4 address.
    import fcntl
    import struct

    for _i, name in socket.if_nameindex():
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            req = struct.pack("256s", name.encode()[:15])
            try:
                ip = socket.inet_ntoa(fcntl.ioctl(probe.fileno(), 0x8915, req)[20:24])
            except OSError:
                continue
        finally:
            probe.close()
        mac = Path(f"/sys/class/net/{name}/address").read_text().strip()
        assert interface_mac_for(ip) == bytes.fromhex(mac.replace(":", ""))
    assert interface_mac_for("203.0.113.77") == bytes(6)  # held by no interface


# DCE/RPC fragments -------------------------------------------------------------------------


@pytest.mark.parametrize("acks", [False, True])
async def test_fragmented_requests_and_replies_work_both_ways(
    device: ProfinetDevice, acks: bool
) -> None:
    # C706 §12.5.3.2: a call longer than one datagram goes in fragments (FRAG, fragment
    # numbers, LASTFRAG on the last); without "no fack" the receiver acknowledges each
    # fragment but the last (fack, §12.5.3.6). Both sides here send 64-byte fragments.
    requests: list[pnio.RpcPacket] = []
    replies: list[pnio.RpcPacket] = []
    answers = device.answers

    def spy(frame: bytes) -> list[bytes]:
        requests.append(pnio.parse_rpc(frame))
        out = answers(frame)
        replies.extend(pnio.parse_rpc(d) for d in out)
        return out

    device.answers = spy  # type: ignore[method-assign]
    device.max_fragment_body = 64
    link = ProfinetLink(LinkParams(interface="profinet", channel=device.channel, node_id=1))
    link.max_fragment_body = 64
    link.fragment_acks = acks
    await link.open()
    try:
        await link.write(A(0x607A), (-4242).to_bytes(4, "little", signed=True))
        assert device.drive.read(0x607A) == -4242
        values = await link.read_many([A(0x6081), A(0x607A), A(0x2D30), A(0x03C4, 0)])
        assert values[1] == (-4242).to_bytes(4, "little", signed=True)
        assert values[2] == b"MR-J4-TM"
        assert (await link.identity()).vendor_id == 540
    finally:
        await link.close()
    fragments_in = [r for r in requests if r.flags1 & pnio.FLAG_FRAG]
    fragments_out = [r for r in replies if r.flags1 & pnio.FLAG_FRAG]
    facks = [r for r in replies if r.ptype == pnio.PTYPE_FACK]
    assert fragments_in and fragments_out
    assert {f.fragnum for f in fragments_out} >= {0, 1, 2}
    if acks:
        # One fack per request fragment but the last of each call.
        assert len(facks) == len(fragments_in) - sum(
            1 for f in fragments_in if f.flags1 & pnio.FLAG_LASTFRAG
        )
    else:
        assert not facks and all(f.flags1 & pnio.FLAG_NOFACK for f in fragments_in)


def test_a_call_missing_a_fragment_is_not_carried_out(
    client: Client, device: ProfinetDevice
) -> None:
    ar = uuid.uuid4()
    assert client.connect(ar) == 0
    req = pd.Request(
        1, pd.REQUEST_CHANGE, 1, (pd.ParameterAddress(0x6081, 0),),
        (pd.Values(pd.FMT_UINT32, 1, (777).to_bytes(4, "big")),),
    )  # fmt: skip
    data = pd.build_request(req)
    head = pnio.RecordHeader(1, ar, pnio.RecordAddress(1, 1, 0xB02E), len(data))
    packet = pnio.parse_rpc(
        client.datagram(pnio.OP_WRITE, pnio.record_request(pnio.BLOCK_WRITE_REQ, head) + data)
    )
    packet = dataclasses.replace(packet, flags1=pnio.FLAG_NOFACK)
    first, *rest = pnio.fragment(packet, 40)
    before = device.drive.read(0x6081)
    for f in rest:  # the first fragment is lost
        client.sock.send(pnio.build_rpc(f))
    client.sock.settimeout(0.2)
    with pytest.raises(TimeoutError):
        client.sock.recv(65535)
    assert device.drive.read(0x6081) == before
    reply = client.send(pnio.build_rpc(first))  # the resend of the lost fragment completes it
    assert reply.ptype == pnio.PTYPE_RESPONSE and device.drive.read(0x6081) == 777
