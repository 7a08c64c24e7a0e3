"""SDO frames of CiA 301 §7.2.4.3 (expedited and segmented transfer), built and parsed.

Pure functions on 8-byte frames; the link sends and awaits them. Command byte layouts:

- initiate download request: ``001x nnes`` (ccs 1), response ``0110 0000`` (scs 3)
- download segment request:  ``000t nnnc`` (ccs 0), response ``001t 0000`` (scs 1)
- initiate upload request:   ``0100 0000`` (ccs 2), response ``010x nnes`` (scs 2)
- upload segment request:    ``011t 0000`` (ccs 3), response ``000t nnnc`` (scs 0)
- abort transfer:            ``1000 0000`` with the abort code in bytes 4..7
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

_HEAD = struct.Struct("<BHB")
ABORT = 0x80

#: Abort codes the client itself sends (CiA 301 table 22).
ABORT_TIMEOUT = 0x05040000
ABORT_TOGGLE = 0x05030000
ABORT_COMMAND = 0x05040001


class SdoProtocolError(Exception):
    """The server's answer does not fit the transfer (wrong command, toggle, address)."""

    def __init__(self, message: str, abort_code: int = ABORT_COMMAND) -> None:
        super().__init__(message)
        self.abort_code = abort_code


class SdoAbort(Exception):
    """The server aborted the transfer with ``code``."""

    def __init__(self, code: int, index: int, subindex: int) -> None:
        super().__init__(f"SDO abort 0x{code:08X} for 0x{index:04X}:{subindex:02X}")
        self.code = code
        self.index = index
        self.subindex = subindex


def _frame(command: int, index: int, subindex: int, payload: bytes = b"") -> bytes:
    return _HEAD.pack(command, index, subindex) + payload.ljust(4, b"\x00")


def initiate_upload(index: int, subindex: int) -> bytes:
    return _frame(0x40, index, subindex)


def upload_segment(toggle: int) -> bytes:
    return bytes([0x60 | (toggle & 1) << 4]) + bytes(7)


def initiate_download(index: int, subindex: int, data: bytes) -> bytes:
    """Expedited for 1..4 bytes (size indicated), else segmented with the size."""
    n = len(data)
    if 0 < n <= 4:
        return _frame(0x23 | (4 - n) << 2, index, subindex, data)
    return _frame(0x21, index, subindex, struct.pack("<I", n))


def download_segment(toggle: int, chunk: bytes, last: bool) -> bytes:
    if not 0 <= len(chunk) <= 7:
        raise ValueError("a segment carries 0..7 bytes")
    cmd = (toggle & 1) << 4 | (7 - len(chunk)) << 1 | int(last)
    return bytes([cmd]) + chunk.ljust(7, b"\x00")


def abort(index: int, subindex: int, code: int) -> bytes:
    return _frame(ABORT, index, subindex, struct.pack("<I", code))


def _check_abort(frame: bytes, index: int, subindex: int) -> None:
    if len(frame) != 8:
        raise SdoProtocolError(f"SDO response has {len(frame)} bytes, not 8")
    if frame[0] == ABORT:
        raise SdoAbort(struct.unpack_from("<I", frame, 4)[0], index, subindex)


def _check_address(frame: bytes, index: int, subindex: int) -> None:
    _, idx, sub = _HEAD.unpack_from(frame)
    if (idx, sub) != (index, subindex):
        raise SdoProtocolError(
            f"response is for 0x{idx:04X}:{sub:02X}, not 0x{index:04X}:{subindex:02X}"
        )


@dataclass(frozen=True, slots=True)
class UploadStart:
    """The answer to an initiate-upload: the data (expedited) or the announced size."""

    data: bytes | None
    size: int | None


def parse_initiate_upload(frame: bytes, index: int, subindex: int) -> UploadStart:
    _check_abort(frame, index, subindex)
    cmd = frame[0]
    if cmd >> 5 != 2:
        raise SdoProtocolError(f"unexpected command 0x{cmd:02X} answering an upload")
    _check_address(frame, index, subindex)
    expedited, sized = bool(cmd & 0x02), bool(cmd & 0x01)
    if expedited:
        n = 4 - (cmd >> 2 & 0x03) if sized else 4
        return UploadStart(bytes(frame[4 : 4 + n]), n)
    return UploadStart(None, struct.unpack_from("<I", frame, 4)[0] if sized else None)


@dataclass(frozen=True, slots=True)
class Segment:
    data: bytes
    last: bool


def parse_upload_segment(frame: bytes, toggle: int, index: int, subindex: int) -> Segment:
    _check_abort(frame, index, subindex)
    cmd = frame[0]
    if cmd >> 5 != 0:
        raise SdoProtocolError(f"unexpected command 0x{cmd:02X} in an upload segment")
    if (cmd >> 4 & 1) != (toggle & 1):
        raise SdoProtocolError("toggle bit not alternated", ABORT_TOGGLE)
    n = 7 - (cmd >> 1 & 0x07)
    return Segment(bytes(frame[1 : 1 + n]), bool(cmd & 0x01))


def parse_initiate_download(frame: bytes, index: int, subindex: int) -> None:
    _check_abort(frame, index, subindex)
    if frame[0] != 0x60:
        raise SdoProtocolError(f"unexpected command 0x{frame[0]:02X} answering a download")
    _check_address(frame, index, subindex)


def parse_download_segment(frame: bytes, toggle: int, index: int, subindex: int) -> None:
    _check_abort(frame, index, subindex)
    cmd = frame[0]
    if cmd & 0xE0 != 0x20:
        raise SdoProtocolError(f"unexpected command 0x{cmd:02X} answering a segment")
    if (cmd >> 4 & 1) != (toggle & 1):
        raise SdoProtocolError("toggle bit not alternated", ABORT_TOGGLE)
