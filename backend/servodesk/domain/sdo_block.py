"""SDO block upload of CiA 301 §7.2.4.3.9-§7.2.4.3.12, built and parsed; its CRC.

Pure functions on 8-byte frames, for both ends (the link is the client, the simulated
drive's SDO server the server), and :class:`BlockReceiver`, the client's bookkeeping of a
sub-block (which segments are good, what to acknowledge). Command byte layouts
(ccs 5 = client block upload, scs 6 = server block upload; ``x`` reserved, sent as 0):

- initiate block upload request:  ``101x xc00`` (cc: the client does CRC), 1..3 multiplexor,
  4 blksize (1..127 segments per sub-block), 5 pst (protocol switch threshold), 6..7 x
- initiate block upload response: ``110x xcs0`` (sc: the server does CRC, s: size in 4..7),
  1..3 multiplexor; or, with a size <= pst != 0, the server may switch to the normal upload
  and answer an initiate upload response (scs 2, §7.2.4.3.6) instead (§7.2.4.3.9)
- start upload:                   ``101x xx11``, nothing else
- upload sub-block segment:       ``cnnn nnnn`` (c: no more segments, n: seqno 1..blksize),
  1..7 segment data (7 bytes; the last segment's unused ones are counted in the end frame)
- block upload response (ack):    ``101x xx10``, 1 ackseq (the last seqno received in order,
  0: none), 2 blksize of the next sub-block
- end block upload request:       ``110n nnx1`` (n: bytes of the last segment without data),
  1..2 CRC of the whole data (when both sides do CRC), 3..7 x
- end block upload response:      ``101x xx01``

A segment's command byte cannot be 80h (seqno 0 does not exist, §7.2.4.3.11), so 80h while
segments are due is an abort (§7.2.4.3.17), as anywhere else.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from servodesk.domain.sdo import (
    ABORT,
    ABORT_COMMAND,
    SdoProtocolError,
    UploadStart,
    _check_abort,
    _check_address,
    _frame,
    parse_initiate_upload,
)

#: Most segments per sub-block (the seqno has 7 bits, 0 is not used).
MAX_BLKSIZE = 127
#: Abort codes of block transfers (CiA 301 table 22).
ABORT_BLKSIZE = 0x05040002
ABORT_SEQNO = 0x05040003
ABORT_CRC = 0x05040004

_CCS = 0xA0  # ccs 5 in bits 7..5
_SCS = 0xC0  # scs 6
_CRC_FLAG = 0x04  # cc / sc (bit 2)
_SIZE_FLAG = 0x02  # s (bit 1)
_LAST = 0x80  # c of a segment


# CRC (§7.2.4.3.16: x^16 + x^12 + x^5 + 1, initial value 0; the XModem variant, no final
# XOR, bits in from the most significant one). One table lookup per byte.
def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = (crc << 1) ^ 0x1021 if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16 CCITT of ``data``, continued from ``crc`` (``crc16(b"123456789") == 0x31C3``)."""
    table = _CRC_TABLE
    for b in data:
        crc = (crc << 8 & 0xFF00) ^ table[(crc >> 8) ^ b]
    return crc


# Client side ----------------------------------------------------------------------------


def initiate_upload(index: int, subindex: int, blksize: int, pst: int, crc: bool = True) -> bytes:
    """§7.2.4.3.9: ask for ``blksize`` segments per sub-block; a server may answer objects of
    at most ``pst`` bytes (0: never) with the normal upload instead."""
    if not 1 <= blksize <= MAX_BLKSIZE:
        raise ValueError(f"blksize {blksize} is outside 1..{MAX_BLKSIZE}")
    if not 0 <= pst <= 0xFF:
        raise ValueError(f"pst {pst} is outside 0..255")
    return _frame(_CCS | (_CRC_FLAG if crc else 0), index, subindex, bytes([blksize, pst]))


START = bytes([_CCS | 0x03]) + bytes(7)
END_RESPONSE = bytes([_CCS | 0x01]) + bytes(7)


def ack(ackseq: int, blksize: int) -> bytes:
    """§7.2.4.3.12 block upload response: segments up to ``ackseq`` arrived in order; the
    server sends the next sub-block from the one after, ``blksize`` segments at most."""
    if not 0 <= ackseq <= MAX_BLKSIZE or not 1 <= blksize <= MAX_BLKSIZE:
        raise ValueError("ackseq 0..127 and blksize 1..127")
    return bytes([_CCS | 0x02, ackseq, blksize]) + bytes(5)


@dataclass(frozen=True, slots=True)
class BlockStart:
    """The server takes the block upload: the size (None: not indicated) and whether the CRC
    is used (both sides support it)."""

    size: int | None
    crc: bool


def parse_initiate_response(
    frame: bytes, index: int, subindex: int, crc: bool = True
) -> BlockStart | UploadStart:
    """The answer to :func:`initiate_upload`: a :class:`BlockStart`, or the normal upload's
    :class:`~servodesk.domain.sdo.UploadStart` where the server switched protocol (§7.2.4.3.9,
    allowed for sizes up to pst; python-canopen's server switches for every size)."""
    _check_abort(frame, index, subindex)
    cmd = frame[0]
    if cmd & 0xE0 == 0x40:
        return parse_initiate_upload(frame, index, subindex)
    if cmd & 0xE3 not in (_SCS, _SCS | _SIZE_FLAG):  # scs 6, ss 0 (initiate)
        raise SdoProtocolError(f"unexpected command 0x{cmd:02X} answering a block upload")
    _check_address(frame, index, subindex)
    size = struct.unpack_from("<I", frame, 4)[0] if cmd & _SIZE_FLAG else None
    return BlockStart(size, crc and bool(cmd & _CRC_FLAG))


@dataclass(frozen=True, slots=True)
class End:
    """The end of a block upload: bytes of the last segment without data, the server's CRC."""

    unused: int
    crc: int


def parse_end(frame: bytes, index: int, subindex: int) -> End:
    _check_abort(frame, index, subindex)
    cmd = frame[0]
    if cmd & 0xE3 != _SCS | 0x01:  # scs 6, ss 1
        raise SdoProtocolError(f"unexpected command 0x{cmd:02X} ending a block upload")
    return End(cmd >> 2 & 0x07, struct.unpack_from("<H", frame, 1)[0])


class BlockReceiver:
    """The client's side of the sub-blocks (§7.2.4.3.11-§7.2.4.3.12).

    Segments count only in order: seqno 1, 2, ... of the sub-block. After a gap (a segment
    lost, or one out of order) the rest of the sub-block is dropped, and the acknowledgement
    names the last good seqno, so the server sends the rest again in the next sub-block
    (§7.2.4.3.12: "the server shall continue with the next segment after ackseq"). The last
    segment (c set) ends the data only when it arrived in order.
    """

    def __init__(self, index: int, subindex: int, blksize: int, limit: int) -> None:
        self.index = index
        self.subindex = subindex
        self.blksize = blksize
        self.limit = limit
        self.data = bytearray()
        #: The last seqno received in order in this sub-block.
        self.ackseq = 0
        #: The c segment arrived in order: after the ack, the end frame is due.
        self.complete = False
        #: Segments dropped (out of order, or after a gap), for the link's counters.
        self.dropped = 0
        self._pending = bytearray()

    def segment(self, frame: bytes) -> bool:
        """Take one frame of the sub-block; True when the sub-block is over (ack due): its
        last seqno or the c segment arrived, in order or not."""
        if len(frame) != 8:
            raise SdoProtocolError(f"SDO segment has {len(frame)} bytes, not 8")
        cmd = frame[0]
        if cmd == ABORT:
            _check_abort(frame, self.index, self.subindex)
        seqno, last = cmd & 0x7F, bool(cmd & _LAST)
        if seqno == 0:
            raise SdoProtocolError("block segment with sequence number 0", ABORT_SEQNO)
        if seqno == self.ackseq + 1 and not self.complete:
            self.ackseq = seqno
            self._pending += frame[1:8]
            self.complete = last
            if len(self.data) + len(self._pending) > self.limit + 7:
                raise SdoProtocolError("upload longer than servodesk accepts", ABORT_COMMAND)
        else:
            self.dropped += 1
        return last or seqno >= self.blksize

    def ack(self) -> bytes:
        """The acknowledgement of the sub-block; its good segments become data."""
        frame = ack(self.ackseq, self.blksize)
        self.data += self._pending
        self._pending.clear()
        self.ackseq = 0
        return frame

    def finish(self, end: End, crc: bool, size: int | None) -> bytes:
        """The data, checked against the end frame: the unused bytes, the size, the CRC."""
        if not self.complete:
            raise SdoProtocolError("block upload ended before its last segment")
        if len(self.data) < end.unused or (end.unused == 7 and len(self.data) > 7):
            raise SdoProtocolError(f"end frame gives {end.unused} unused bytes", ABORT_COMMAND)
        data = bytes(self.data[: len(self.data) - end.unused])
        if size is not None and len(data) != size:
            raise SdoProtocolError(f"announced {size} bytes, sent {len(data)}")
        if crc and crc16(data) != end.crc:
            raise SdoProtocolError("block upload CRC does not match", ABORT_CRC)
        return data


# Server side ----------------------------------------------------------------------------

#: The client's block upload commands by their cs bits (byte 0, bits 1..0).
CS_INITIATE, CS_END, CS_ACK, CS_START = 0, 1, 2, 3


def client_cs(frame: bytes) -> int | None:
    """The cs of a client block upload frame (ccs 5), None for any other command."""
    return frame[0] & 0x03 if frame[0] & 0xE0 == _CCS else None


@dataclass(frozen=True, slots=True)
class BlockRequest:
    """A parsed initiate block upload request."""

    index: int
    subindex: int
    blksize: int
    pst: int
    crc: bool


def parse_initiate_request(frame: bytes) -> BlockRequest:
    cmd, index, subindex = struct.unpack_from("<BHB", frame)
    blksize, pst = frame[4], frame[5]
    if not 1 <= blksize <= MAX_BLKSIZE:
        raise SdoProtocolError(f"block size {blksize} is outside 1..127", ABORT_BLKSIZE)
    return BlockRequest(index, subindex, blksize, pst, bool(cmd & _CRC_FLAG))


def parse_ack(frame: bytes) -> tuple[int, int]:
    """(ackseq, blksize) of a block upload response; a blksize outside 1..127 is refused."""
    ackseq, blksize = frame[1], frame[2]
    if not 1 <= blksize <= MAX_BLKSIZE:
        raise SdoProtocolError(f"block size {blksize} is outside 1..127", ABORT_BLKSIZE)
    return ackseq, blksize


def initiate_response(index: int, subindex: int, size: int, crc: bool) -> bytes:
    """scs 6 with the size indicated; ``crc``: this server does CRC."""
    cmd = _SCS | (_CRC_FLAG if crc else 0) | _SIZE_FLAG
    return _frame(cmd, index, subindex, struct.pack("<I", size))


def segment(seqno: int, chunk: bytes, last: bool) -> bytes:
    if not 1 <= seqno <= MAX_BLKSIZE or len(chunk) > 7:
        raise ValueError("seqno 1..127, 0..7 bytes")
    return bytes([(_LAST if last else 0) | seqno]) + chunk.ljust(7, b"\x00")


def end(unused: int, crc: int) -> bytes:
    if not 0 <= unused <= 7:
        raise ValueError("0..7 unused bytes")
    return bytes([_SCS | unused << 2 | 0x01]) + struct.pack("<H", crc & 0xFFFF) + bytes(5)
