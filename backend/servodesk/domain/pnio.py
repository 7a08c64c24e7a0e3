"""PROFINET IO context management (PNIO-CM) over DCE/RPC: the frames of acyclic record
access (pure, no sockets).

A PROFINET device's records (PROFIdrive parameter access 0xB02E, I&M0 0xAFF0) are read and
written over UDP port 34964 with connectionless DCE/RPC (CL-RPC, protocol version 4):
``Connect`` sets up an application relation (AR), ``Write`` / ``Read`` carry one record each,
``Release`` ends the AR (IEC 61158-6-10 §5.2 "RPC", PROFINET IO application layer protocol,
which manual 004 §20.1.1 cites; the LECSN-T's chapter prints none of it). servodesk is an IO
supervisor: its AR is a supervisor AR with device access (ARType 0006h, ARProperties
DeviceAccess = 1), which needs no IO controller, expected submodules or cyclic data, only the
ARBlockReq, and may read and write records (docs/profinet.md).

The 80-byte RPC header and the NDR head of the body follow the data representation
(``drep``) of the sender: servodesk sends little-endian (10h), as most controllers do, and
reads either. The PNIO blocks inside are big-endian whatever the ``drep``. Each block
starts with BlockType (2), BlockLength (2: the bytes after it) and version 1.0.
"""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass

from servodesk.domain.udp_channel import parse_host_port

#: The UDP port of the PNIO-CM RPC server of every PROFINET IO device.
RPC_PORT = 34964
#: Largest RPC datagram servodesk sends or accepts (one fragment; PNIO limits a CL-RPC
#: fragment to the UDP payload of one Ethernet frame).
MAX_DATAGRAM = 1464

#: DCE/RPC packet types (CL-RPC).
PTYPE_REQUEST = 0
PTYPE_RESPONSE = 2
PTYPE_FAULT = 3
PTYPE_REJECT = 6
PTYPE_FACK = 9
#: flags1: last fragment, no fragment acknowledgement wanted, idempotent.
FLAG_LASTFRAG = 0x02
#: flags1: the datagram is one fragment of a call (C706 §12.5.3.2, CL-RPC fragmentation).
FLAG_FRAG = 0x04
FLAG_NOFACK = 0x08
FLAG_IDEMPOTENT = 0x20

#: PNIO-CM operations (opnums of the PNIO device interface).
OP_CONNECT = 0
OP_RELEASE = 1
OP_READ = 2
OP_WRITE = 3

#: The PNIO device interface (requests to a device) and the object UUID's fixed part.
DEVICE_INTERFACE = uuid.UUID("dea00001-6c97-11d1-8271-00a02442df7d")
OBJECT_UUID_PREFIX = "dea00000-6c97-11d1-8271-"

#: DCE/RPC reject status codes (C706 §12 / Appendix E, nca_s_*): the body of a reject is
#: this 32-bit code in the sender's ``drep``.
NCA_OP_RANGE_ERROR = 0x1C010002
NCA_UNKNOWN_INTERFACE = 0x1C010003

#: Block types (IEC 61158-6-10 BlockType).
BLOCK_AR_REQ = 0x0101
BLOCK_AR_RES = 0x8101
BLOCK_WRITE_REQ = 0x0008
BLOCK_WRITE_RES = 0x8008
BLOCK_READ_REQ = 0x0009
BLOCK_READ_RES = 0x8009
BLOCK_RELEASE_REQ = 0x0114
BLOCK_RELEASE_RES = 0x8114
BLOCK_IM0 = 0x0020
#: I&M1-4 (tag function / location, installation date, descriptor, signature) and their
#: record indexes AFF1h-AFF4h; the data lengths of each after the block header.
BLOCK_IM = {1: 0x0021, 2: 0x0022, 3: 0x0023, 4: 0x0024}
INDEX_IM = {1: 0xAFF1, 2: 0xAFF2, 3: 0xAFF3, 4: 0xAFF4}
IM_LENGTHS = {1: 54, 2: 16, 3: 54, 4: 54}
#: Block types a connect request may carry (IEC 61158-6-10 ConnectReq); others are unknown.
CONNECT_BLOCKS = frozenset({0x0101, 0x0102, 0x0103, 0x0104, 0x0106, 0x0108, 0x0109, 0x010A,
                            0x010B, 0x0110, 0x0111, 0x0112, 0x0113})  # fmt: skip
#: Field numbers of the ARBlockReq (PNIO ErrorCode2 under ErrorCode1 01h, faulty ARBlockReq):
#: 2/3 block version, 4 ARType, 5 ARUUID, 9 ARProperties, 11 InitiatorUDPRTPort, 12
#: StationNameLength, 13 CMInitiatorStationName.
AR_FIELD = {"version_high": 2, "version_low": 3, "ar_type": 4, "ar_uuid": 5, "properties": 9,
            "udp_rt_port": 11, "name_length": 12, "station_name": 13}  # fmt: skip
#: ErrorCode1 of a faulty release block (IODReleaseReq), and its SessionKey field.
CODE1_RELEASE_BLOCK = 0x28
RELEASE_FIELD_SESSION_KEY = 6

#: ARType: supervisor AR (IOSAR).
AR_TYPE_SUPERVISOR = 0x0006
#: ARProperties: State Active (1), ParametrizationServer = CM initiator (bit 4), DeviceAccess
#: (bit 8: the AR reaches the device's records without expected submodules).
AR_PROPERTIES_DEVICE_ACCESS = 0x00000111
#: ControlCommand bits of the release block.
CONTROL_RELEASE = 0x0004
CONTROL_DONE = 0x0008

#: Record indexes servodesk uses: PROFIdrive base mode parameter access, local (PROFIdrive
#: V4.1: the request is written, then the response read, at this index) and I&M0.
INDEX_PARAMETER_ACCESS = 0xB02E
INDEX_IM0 = 0xAFF0

#: PNIOStatus ErrorCode / ErrorDecode values (IEC 61158-6-10, PNIOStatus).
ERROR_CODE_CONNECT = 0xDB
ERROR_CODE_RELEASE = 0xDC
ERROR_CODE_READ = 0xDE
ERROR_CODE_WRITE = 0xDF
DECODE_PNIORW = 0x80
DECODE_PNIO = 0x81
#: ErrorCode1 under PNIORW (record access) and the ones servodesk names.
RW_CODES: dict[int, str] = {
    0xA0: "application: read error",
    0xA1: "application: write error",
    0xA9: "application: feature not supported",
    0xB0: "access: invalid index (the record does not exist)",
    0xB1: "access: write length error",
    0xB2: "access: invalid slot / subslot",
    0xB5: "access: state conflict (no parameter response to read yet)",
    0xB6: "access: access denied",
    0xB8: "access: invalid parameter",
    0xC2: "resource: busy",
    0xC3: "resource: unavailable",
}
#: ErrorCode1 0x40 (CMRPC) under PNIO, with its ErrorCode2 values servodesk names.
CMRPC = 0x40
CMRPC_CODES: dict[int, str] = {
    0x00: "arguments length invalid",
    0x01: "unknown blocks",
    0x04: "no AR resources (the device has no room for another AR)",
    0x05: "AR UUID unknown (the AR has ended)",
    0x06: "state conflict",
}

_RPC = struct.Struct("<BBBB3sB16s16s16sIIIHHHHHBB")  # the little-endian form
_RPC_BE = struct.Struct(">BBBB3sB16s16s16sIIIHHHHHBB")
RPC_HEADER_LEN = _RPC.size  # 80
_RW_HEAD = struct.Struct(">H16sIHH2sHI")  # seq, ARUUID, API, slot, subslot, pad, index, length


class PnioFrameError(ValueError):
    """A datagram or block that is not what PNIO-CM allows; the message says what."""


@dataclass(frozen=True, slots=True)
class RpcPacket:
    """One CL-RPC datagram (one fragment): header fields servodesk uses and the body."""

    ptype: int
    opnum: int
    object_uuid: uuid.UUID
    interface: uuid.UUID
    activity: uuid.UUID
    seqnum: int
    body: bytes
    flags1: int = FLAG_IDEMPOTENT
    server_boot: int = 0
    little: bool = True
    #: Fragment number (0 for an unfragmented call).
    fragnum: int = 0

    @property
    def fmt(self) -> str:
        """The struct byte order of this packet's ``drep``."""
        return "<" if self.little else ">"


def object_uuid(vendor_id: int, device_id: int, instance: int = 1) -> uuid.UUID:
    """The PNIO object UUID of a device instance: DEA00000-6C97-11D1-8271-IIII-DDDD-VVVV."""
    return uuid.UUID(f"{OBJECT_UUID_PREFIX}{instance:04x}{device_id:04x}{vendor_id:04x}")


def build_rpc(packet: RpcPacket) -> bytes:
    """The datagram: the 80-byte header in the packet's ``drep``, then the body."""
    s = _RPC if packet.little else _RPC_BE

    def u(x: uuid.UUID) -> bytes:
        return x.bytes_le if packet.little else x.bytes

    head = s.pack(
        4,  # CL-RPC
        packet.ptype,
        packet.flags1,
        0,
        b"\x10\x00\x00" if packet.little else b"\x00\x00\x00",  # drep: integers, ASCII, IEEE
        0,  # serial high
        u(packet.object_uuid),
        u(packet.interface),
        u(packet.activity),
        packet.server_boot,
        1,  # interface version
        packet.seqnum,
        packet.opnum,
        0xFFFF,  # interface hint
        0xFFFF,  # activity hint
        len(packet.body),
        packet.fragnum,
        0,  # no authentication
        0,  # serial low
    )
    return head + packet.body


def parse_rpc(frame: bytes) -> RpcPacket:
    if len(frame) < RPC_HEADER_LEN:
        raise PnioFrameError(f"{len(frame)} bytes are shorter than a CL-RPC header (80)")
    if frame[0] != 4:
        raise PnioFrameError(f"RPC version {frame[0]} is not connectionless RPC (4)")
    little = bool(frame[4] & 0x10)
    s = _RPC if little else _RPC_BE
    f = s.unpack_from(frame)
    length, fragnum = f[15], f[16]
    if len(frame) != RPC_HEADER_LEN + length:
        raise PnioFrameError(
            f"the RPC header announces {length} body bytes, the datagram carries "
            f"{len(frame) - RPC_HEADER_LEN}"
        )

    def u(b: bytes) -> uuid.UUID:
        return uuid.UUID(bytes_le=b) if little else uuid.UUID(bytes=b)

    return RpcPacket(
        ptype=f[1],
        opnum=f[12],
        object_uuid=u(f[6]),
        interface=u(f[7]),
        activity=u(f[8]),
        seqnum=f[11],
        body=bytes(frame[RPC_HEADER_LEN:]),
        flags1=f[2],
        server_boot=f[9],
        little=little,
        fragnum=fragnum,
    )


def fragment(packet: RpcPacket, max_body: int) -> list[RpcPacket]:
    """``packet`` as one datagram, or as fragments of at most ``max_body`` body bytes each
    (C706 §12.5.3.2: FLAG_FRAG on every fragment, FLAG_LASTFRAG on the last, fragment
    numbers from 0). The fragments keep the packet's other flags (no-fack among them)."""
    body = packet.body
    if len(body) <= max_body:
        return [packet]
    parts = [body[i : i + max_body] for i in range(0, len(body), max_body)]
    base = packet.flags1 & ~FLAG_LASTFRAG
    out = []
    for n, part in enumerate(parts):
        last = n == len(parts) - 1
        flags = base | FLAG_FRAG | (FLAG_LASTFRAG if last else 0)
        out.append(
            RpcPacket(
                ptype=packet.ptype,
                opnum=packet.opnum,
                object_uuid=packet.object_uuid,
                interface=packet.interface,
                activity=packet.activity,
                seqnum=packet.seqnum,
                body=part,
                flags1=flags,
                server_boot=packet.server_boot,
                little=packet.little,
                fragnum=n,
            )
        )
    return out


class Reassembly:
    """The fragments of one call (one activity and sequence number) as they come in; the
    whole body once the last fragment and every one before it are there."""

    def __init__(self) -> None:
        self._parts: dict[int, bytes] = {}
        self._last: int | None = None

    def add(self, packet: RpcPacket) -> bytes | None:
        self._parts[packet.fragnum] = packet.body
        if packet.flags1 & FLAG_LASTFRAG:
            self._last = packet.fragnum
        if self._last is None or len(self._parts) < self._last + 1:
            return None
        if any(n not in self._parts for n in range(self._last + 1)):
            return None
        return b"".join(self._parts[n] for n in range(self._last + 1))


def fack(packet: RpcPacket, *, window: int = 8, max_frag: int = MAX_DATAGRAM) -> RpcPacket:
    """The fragment acknowledgement of ``packet`` (C706 §12.5.3.6, fack body version 0:
    window size, max TSDU, max fragment size, the serial no., no selective acks)."""
    fmt = "<" if packet.little else ">"
    body = struct.pack(f"{fmt}BBHIIHH", 0, 0, window, max_frag, max_frag, packet.fragnum, 0)
    return RpcPacket(
        ptype=PTYPE_FACK,
        opnum=packet.opnum,
        object_uuid=packet.object_uuid,
        interface=packet.interface,
        activity=packet.activity,
        seqnum=packet.seqnum,
        body=body,
        flags1=0,
        little=packet.little,
        fragnum=packet.fragnum,
    )


# NDR heads of the PNIO request and response bodies ---------------------------------------


def _ndr(first: int, args: bytes, args_maximum: int, little: bool) -> bytes:
    """The NDR head (``first``, ArgsLength, conformant array: maximum count, offset 0, actual
    count) and the blocks. ``first`` is ArgsMaximum in a request, PNIOStatus in a response."""
    n = len(args)
    return struct.pack(f"{'<' if little else '>'}IIIII", first, n, args_maximum, 0, n) + args


def _parse_ndr(body: bytes, what: str, little: bool) -> tuple[int, bytes]:
    if len(body) < 20:
        raise PnioFrameError(f"the PNIO {what} body is shorter than its NDR head (20 bytes)")
    first, n, _maxc, offset, actual = struct.unpack_from(f"{'<' if little else '>'}IIIII", body)
    if actual != n or offset != 0 or len(body) < 20 + n:
        raise PnioFrameError(f"the NDR head announces {n} argument bytes, {len(body) - 20} follow")
    return first, body[20 : 20 + n]


def request_body(args: bytes, args_maximum: int, *, little: bool = True) -> bytes:
    """ArgsMaximum, ArgsLength, then the conformant array head and the blocks."""
    return _ndr(args_maximum, args, args_maximum, little)


def parse_request_body(body: bytes, *, little: bool = True) -> tuple[int, bytes]:
    """(ArgsMaximum, the blocks)."""
    return _parse_ndr(body, "request", little)


def pnio_status(code: int = 0, decode: int = 0, code1: int = 0, code2: int = 0) -> int:
    """PNIOStatus as the 32-bit number the NDR head carries (ErrorCode in the top byte)."""
    return (code << 24) | (decode << 16) | (code1 << 8) | code2


def response_body(status: int, args: bytes, args_maximum: int, *, little: bool = True) -> bytes:
    return _ndr(status, args, args_maximum, little)


def parse_response_body(body: bytes, *, little: bool = True) -> tuple[int, bytes]:
    """(PNIOStatus, the blocks)."""
    return _parse_ndr(body, "response", little)


def status_text(status: int) -> str:
    """What a PNIOStatus means, as far as servodesk knows its codes."""
    code, decode, code1, code2 = status.to_bytes(4, "big")
    where = {
        ERROR_CODE_CONNECT: "connect",
        ERROR_CODE_RELEASE: "release",
        ERROR_CODE_READ: "record read",
        ERROR_CODE_WRITE: "record write",
    }.get(code, f"error code {code:02X}h")
    if decode == DECODE_PNIORW:
        return f"{where}: {RW_CODES.get(code1, f'PNIORW error {code1:02X}h')}"
    if decode == DECODE_PNIO and code1 == CMRPC:
        return f"{where}: {CMRPC_CODES.get(code2, f'CMRPC error {code2:02X}h')}"
    return f"{where}: PNIO error {code1:02X}h / {code2:02X}h (decode {decode:02X}h)"


# Blocks ---------------------------------------------------------------------------------


def block(block_type: int, content: bytes) -> bytes:
    """BlockHeader (type, length of what follows it, version 1.0) and the content."""
    return struct.pack(">HHBB", block_type, len(content) + 2, 1, 0) + content


def split_blocks(data: bytes) -> list[tuple[int, bytes]]:
    """Each block's (type, content after the header)."""
    out: list[tuple[int, bytes]] = []
    pos = 0
    while pos < len(data):
        if len(data) - pos < 6:
            raise PnioFrameError(f"{len(data) - pos} bytes left are no block header")
        block_type, length = struct.unpack_from(">HH", data, pos)
        end = pos + 4 + length
        if length < 2 or end > len(data):
            raise PnioFrameError(f"block {block_type:04X}h announces {length} bytes, too many")
        out.append((block_type, bytes(data[pos + 6 : end])))
        pos = end
    return out


def block_versions(data: bytes) -> list[tuple[int, int, int]]:
    """Each block's (type, BlockVersionHigh, BlockVersionLow) (after :func:`split_blocks`
    accepted the data)."""
    out: list[tuple[int, int, int]] = []
    pos = 0
    while pos + 6 <= len(data):
        block_type, length, high, low = struct.unpack_from(">HHBB", data, pos)
        out.append((block_type, high, low))
        pos += 4 + length
    return out


def one_block(data: bytes, expected: int) -> bytes:
    blocks = split_blocks(data)
    if not blocks or blocks[0][0] != expected:
        got = f"{blocks[0][0]:04X}h" if blocks else "none"
        raise PnioFrameError(f"expected block {expected:04X}h, got {got}")
    return blocks[0][1]


@dataclass(frozen=True, slots=True)
class ArRequest:
    ar_uuid: uuid.UUID
    session_key: int
    initiator_mac: bytes
    initiator_object: uuid.UUID
    station_name: str
    ar_type: int = AR_TYPE_SUPERVISOR
    properties: int = AR_PROPERTIES_DEVICE_ACCESS
    #: Activity time-out of the AR, in 100 ms.
    timeout_factor: int = 100
    #: InitiatorUDPRTPort: 8892h (RT over Ethernet, no UDP RT) is the only value in use.
    udp_rt_port: int = 0x8892


def ar_block_req(r: ArRequest) -> bytes:
    name = r.station_name.encode("ascii")
    return block(
        BLOCK_AR_REQ,
        struct.pack(">H16sH6s16sIHHH", r.ar_type, r.ar_uuid.bytes, r.session_key,
                    r.initiator_mac, r.initiator_object.bytes, r.properties,
                    r.timeout_factor, r.udp_rt_port, len(name))
        + name,
    )  # fmt: skip


def parse_ar_block_req(content: bytes) -> ArRequest:
    if len(content) < 52:
        raise PnioFrameError("the ARBlockReq is shorter than its fixed part (52 bytes)")
    f = struct.unpack_from(">H16sH6s16sIHHH", content)
    name = content[52 : 52 + f[8]]
    if len(name) != f[8]:
        raise PnioFrameError("the ARBlockReq's station name is cut short")
    return ArRequest(
        udp_rt_port=f[7],
        ar_type=f[0],
        ar_uuid=uuid.UUID(bytes=f[1]),
        session_key=f[2],
        initiator_mac=f[3],
        initiator_object=uuid.UUID(bytes=f[4]),
        properties=f[5],
        timeout_factor=f[6],
        station_name=name.decode("ascii", "replace"),
    )


def ar_block_res(ar_type: int, ar_uuid: uuid.UUID, session_key: int, mac: bytes) -> bytes:
    return block(
        BLOCK_AR_RES, struct.pack(">H16sH6sH", ar_type, ar_uuid.bytes, session_key, mac, 0x8892)
    )


def parse_ar_block_res(content: bytes) -> tuple[uuid.UUID, int]:
    """(ARUUID, SessionKey) of an ARBlockRes."""
    if len(content) < 28:
        raise PnioFrameError("the ARBlockRes is shorter than 28 bytes")
    _t, ar, key = struct.unpack_from(">H16sH", content)
    return uuid.UUID(bytes=ar), key


def release_block(block_type: int, ar_uuid: uuid.UUID, session_key: int, command: int) -> bytes:
    """IODReleaseBlock (request 0114h: command Release; response 8114h: Done)."""
    return block(
        block_type, struct.pack(">2s16sHHHH", b"\0\0", ar_uuid.bytes, session_key, 0, command, 0)
    )


def parse_release_block(content: bytes) -> tuple[uuid.UUID, int, int]:
    """(ARUUID, SessionKey, ControlCommand)."""
    if len(content) < 26:
        raise PnioFrameError("the release block is shorter than 26 bytes")
    _pad, ar, key, _alarm, command, _props = struct.unpack_from(">2s16sHHHH", content)
    return uuid.UUID(bytes=ar), key, command


@dataclass(frozen=True, slots=True)
class RecordAddress:
    """Where a record is: API, slot, subslot, index."""

    slot: int
    subslot: int
    index: int
    api: int = 0


@dataclass(frozen=True, slots=True)
class RecordHeader:
    """The fields of an IODRead / IODWrite request or response header servodesk uses."""

    seq: int
    ar_uuid: uuid.UUID
    where: RecordAddress
    length: int
    #: Responses: AdditionalValue1 / 2 and (write) the PNIOStatus of the record access.
    add1: int = 0
    add2: int = 0
    status: int = 0


def record_request(block_type: int, h: RecordHeader) -> bytes:
    """IODReadReqHeader (0009h) or IODWriteReqHeader (0008h), 64 bytes; a read's record
    length is the most it takes back, a write's the record that follows."""
    w = h.where
    head = _RW_HEAD.pack(h.seq, h.ar_uuid.bytes, w.api, w.slot, w.subslot, b"\0\0", w.index,
                         h.length)  # fmt: skip
    return block(block_type, head + bytes(24))


def record_response(block_type: int, h: RecordHeader) -> bytes:
    """IODReadResHeader (8009h) or IODWriteResHeader (8008h, with the PNIOStatus), 64 bytes."""
    w = h.where
    head = _RW_HEAD.pack(h.seq, h.ar_uuid.bytes, w.api, w.slot, w.subslot, b"\0\0", w.index,
                         h.length)  # fmt: skip
    tail = struct.pack(">HH", h.add1, h.add2)
    if block_type == BLOCK_WRITE_RES:
        tail += struct.pack(">I", h.status)
    return block(block_type, head + tail + bytes(58 - len(head) - len(tail)))


def parse_record_header(data: bytes, expected: int) -> tuple[RecordHeader, bytes]:
    """The header of a read / write request or response, and the record data after it."""
    if len(data) < 64:
        raise PnioFrameError(f"{len(data)} bytes are shorter than a record header (64)")
    block_type, length = struct.unpack_from(">HH", data)
    if block_type != expected or length != 60:
        raise PnioFrameError(
            f"expected record header block {expected:04X}h of 60 bytes, "
            f"got {block_type:04X}h of {length}"
        )
    seq, ar, api, slot, subslot, _pad, index, rec_len = _RW_HEAD.unpack_from(data, 6)
    add1 = add2 = status = 0
    if block_type in (BLOCK_READ_RES, BLOCK_WRITE_RES):
        add1, add2 = struct.unpack_from(">HH", data, 6 + _RW_HEAD.size)
        if block_type == BLOCK_WRITE_RES:
            (status,) = struct.unpack_from(">I", data, 10 + _RW_HEAD.size)
    header = RecordHeader(
        seq, uuid.UUID(bytes=ar), RecordAddress(slot, subslot, index, api), rec_len,
        add1, add2, status,
    )  # fmt: skip
    rest = bytes(data[64:])
    if block_type in (BLOCK_WRITE_REQ, BLOCK_READ_RES):
        if len(rest) < rec_len:
            raise PnioFrameError(f"the record header announces {rec_len} bytes, {len(rest)} follow")
        rest = rest[:rec_len]
    return header, rest


# I&M0 -----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Im0:
    """Identification & Maintenance 0 (the device's name plate), 004 §20.4.4."""

    vendor_id: int
    order_id: str
    serial: str
    hardware_revision: int
    software_revision: tuple[str, int, int, int]  # prefix ('V', 'R', ...), major, minor, bugfix
    revision_counter: int = 0
    profile_id: int = 0
    profile_type: int = 0
    version: tuple[int, int] = (1, 1)
    supported: int = 0

    @property
    def software_version(self) -> str:
        p, a, b, c = self.software_revision
        return f"{p}{a}.{b:02d}.{c}"


_IM0 = struct.Struct(">H20s16sHcBBBHHHBBH")


def im0_block(im: Im0) -> bytes:
    def text(s: str, n: int) -> bytes:
        return s.encode("ascii", "replace")[:n].ljust(n, b" ")

    p, a, b, c = im.software_revision
    return block(
        BLOCK_IM0,
        _IM0.pack(im.vendor_id, text(im.order_id, 20), text(im.serial, 16),
                  im.hardware_revision, p.encode("ascii")[:1], a, b, c, im.revision_counter,
                  im.profile_id, im.profile_type, im.version[0], im.version[1], im.supported),
    )  # fmt: skip


def parse_im0(data: bytes) -> Im0:
    content = one_block(data, BLOCK_IM0)
    if len(content) < _IM0.size:
        raise PnioFrameError(f"the I&M0 block has {len(content)} bytes, not {_IM0.size}")
    f = _IM0.unpack_from(content)
    return Im0(
        vendor_id=f[0],
        order_id=f[1].decode("ascii", "replace").rstrip(" \0"),
        serial=f[2].decode("ascii", "replace").rstrip(" \0"),
        hardware_revision=f[3],
        software_revision=(f[4].decode("ascii", "replace"), f[5], f[6], f[7]),
        revision_counter=f[8],
        profile_id=f[9],
        profile_type=f[10],
        version=(f[11], f[12]),
        supported=f[13],
    )


def parse_channel(channel: str, *, server: bool = False) -> tuple[str, int]:
    """``host`` or ``host:port`` -> (host, port); the port defaults to 34964. A server may
    take port 0 (any free port)."""
    return parse_host_port(
        channel,
        default_port=RPC_PORT,
        hint="give the device's address as host or host:port, e.g. 192.168.0.10 or 127.0.0.1:34964",
        server=server,
    )
