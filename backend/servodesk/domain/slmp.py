"""SLMP 4E binary frames and the CiA 402 object access carried in them (pure, no sockets).

The CTMM04x reaches its objects over CC-Link IE TSN transient transmission, which is SLMP:
"objects are read and written with the SLMP SDO Upload / SDO Download commands", and a
multi-axis unit is addressed per axis with the 4E frame's request-destination multidrop
station no. (0 = X, 1 = Y, 2 = Z, 3 = U) (003 §4-2). Manual 003 gives no command codes or
frame layout. These are the SLMP 4E binary frame and the CiA 402 object read / write command
4020h of Mitsubishi's CC-Link IE servo amplifiers (MR-J4-GF, MR-JE-C manuals §3.4), whose
transient text §4-2 follows almost word for word; to be confirmed on a unit
(docs/slmp.md).

Request (4E, binary, little-endian)::

    54 00 | serial (2) | 00 00 | network (1) | station (1) | module I/O (2) | multidrop (1)
    | length (2: monitoring timer to the end) | monitoring timer (2, 0.25 s) | command (2)
    | sub-command (2) | data

Response::

    D4 00 | serial (2) | 00 00 | network | station | module I/O | multidrop
    | length (2: end code to the end) | end code (2) | data

At an end code other than 0 the data is the error information: network, station, module
I/O, multidrop, command, sub-command of the request (9 bytes). Where the server refused an
SDO, servodesk's simulated station appends the CiA 301 abort code (4 bytes) after it; how a
real unit reports the abort is not documented (docs/slmp.md).

The 4020h data: index (2), sub-index (1), reserved 00h (1), number of data bytes (2; 0 in
an upload request), data. The answer repeats index and sub-index; an upload's answer carries
the object's bytes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from servodesk.domain.udp_channel import parse_host_port

#: 4E frame subheaders (request, response).
SUBHEADER_REQUEST = b"\x54\x00"
SUBHEADER_RESPONSE = b"\xd4\x00"
#: Connected station: network 0, station FFh, the station's own module (I/O 03FFh).
NETWORK_OWN = 0x00
STATION_OWN = 0xFF
MODULE_OWN = 0x03FF

#: CiA 402 object read / write (MR-J4-GF §3.4): command and sub-commands.
CMD_OBJECT = 0x4020
SUB_UPLOAD = 0x0001
SUB_DOWNLOAD = 0x0002

#: Serial, fixed 0000h, network, station, module I/O, multidrop, length: after the subheader.
_HEAD = struct.Struct("<HHBBHBH")
_HEAD_LEN = 2 + _HEAD.size  # 13 bytes up to and including the length field
_OBJECT = struct.Struct("<HBBH")  # index, sub-index, reserved, number of data bytes
#: Error information after a non-zero end code: network, station, module I/O, multidrop,
#: command, sub-command.
_ERROR_INFO = struct.Struct("<BBHBHH")

#: The end code servodesk's simulated station answers a refused SDO with, the abort code
#: following the error information ("request content error": the request was understood
#: but cannot be carried out). A real unit's code is not documented.
END_SDO_REFUSED = 0xC05C
#: SLMP end codes servodesk names (SLMP reference manual, common codes).
END_CODES: dict[int, str] = {
    0x0000: "normal completion",
    0xC059: "the command or sub-command is not supported by the station",
    0xC05C: "the request content is wrong or cannot be carried out",
    0xC061: "the request data length does not match the data",
    0xCEE0: "another function of the station is using it",
    0xCEE1: "the request message is too long",
    0xCEE2: "the response message would be too long",
    0xCF10: "the request destination (network, station or multidrop no.) does not exist",
}

#: The UDP port used when a channel names none: MR-J4-GF's SLMP port (003 gives none).
DEFAULT_PORT = 5010
#: Largest SLMP message servodesk sends or accepts (SLMP's request data limit is 960 words).
MAX_FRAME = 2048
#: Largest object value one 4020h download carries here: 960 words of request data, less the
#: monitoring timer, command, sub-command and the object header (servodesk sends no block
#: transfers, 4020h / 0006h).
MAX_OBJECT_BYTES = 1920 - 6 - 6


class SlmpFrameError(ValueError):
    """A frame that is not an SLMP 4E binary frame of the expected kind (its text says why)."""


@dataclass(frozen=True, slots=True)
class Route:
    """Where an SLMP request goes: network no., station no., module I/O no., multidrop no."""

    network: int = NETWORK_OWN
    station: int = STATION_OWN
    module: int = MODULE_OWN
    multidrop: int = 0


@dataclass(frozen=True, slots=True)
class Request:
    serial: int
    route: Route
    timer: int
    command: int
    subcommand: int
    data: bytes


@dataclass(frozen=True, slots=True)
class Response:
    serial: int
    route: Route
    end_code: int
    data: bytes


def end_code_text(code: int) -> str:
    return END_CODES.get(code, f"SLMP end code {code:04X}h (not in servodesk's list)")


def _head(subheader: bytes, serial: int, route: Route, length: int) -> bytes:
    return subheader + _HEAD.pack(
        serial, 0, route.network, route.station, route.module, route.multidrop, length
    )


def build_request(
    serial: int, route: Route, command: int, subcommand: int, data: bytes, timer: int = 4
) -> bytes:
    """A 4E binary request; ``timer`` is the monitoring timer in 0.25 s (4: 1 s)."""
    body = struct.pack("<HHH", timer, command, subcommand) + data
    return _head(SUBHEADER_REQUEST, serial, route, len(body)) + body


def build_response(serial: int, route: Route, end_code: int, data: bytes = b"") -> bytes:
    body = struct.pack("<H", end_code) + data
    return _head(SUBHEADER_RESPONSE, serial, route, len(body)) + body


def error_info(route: Route, command: int, subcommand: int) -> bytes:
    """The error information that follows a non-zero end code."""
    return _ERROR_INFO.pack(
        route.network, route.station, route.module, route.multidrop, command, subcommand
    )


def _split(frame: bytes, subheader: bytes, kind: str) -> tuple[int, Route, bytes]:
    if len(frame) < _HEAD_LEN:
        raise SlmpFrameError(f"{len(frame)} bytes are too short for an SLMP 4E {kind}")
    if frame[:2] != subheader:
        raise SlmpFrameError(
            f"subheader {frame[:2].hex()} is not the 4E binary {kind}'s {subheader.hex()}"
        )
    serial, fixed, network, station, module, multidrop, length = _HEAD.unpack_from(frame, 2)
    if fixed != 0:
        raise SlmpFrameError(f"the 4E {kind}'s fixed field is {fixed:04X}h, not 0000h")
    body = frame[_HEAD_LEN:]
    if len(body) != length:
        raise SlmpFrameError(f"the {kind} says {length} data bytes and carries {len(body)}")
    return serial, Route(network, station, module, multidrop), body


@dataclass(frozen=True, slots=True)
class Header:
    """The fixed part of a 4E request that a station can read even when the rest is wrong."""

    serial: int
    route: Route
    fixed: int
    length: int
    body: bytes


def read_request_header(frame: bytes) -> Header | None:
    """The 4E binary request header of ``frame`` (serial no., route, the declared length)
    when its 13 bytes are there and its subheader is 5400h; None otherwise (a frame a
    station cannot even address an answer to)."""
    if len(frame) < _HEAD_LEN or frame[:2] != SUBHEADER_REQUEST:
        return None
    serial, fixed, network, station, module, multidrop, length = _HEAD.unpack_from(frame, 2)
    route = Route(network, station, module, multidrop)
    return Header(serial, route, fixed, length, frame[_HEAD_LEN:])


def parse_request(frame: bytes) -> Request:
    serial, route, body = _split(frame, SUBHEADER_REQUEST, "request")
    if len(body) < 6:
        raise SlmpFrameError("the request has no monitoring timer, command and sub-command")
    timer, command, subcommand = struct.unpack_from("<HHH", body)
    return Request(serial, route, timer, command, subcommand, body[6:])


def parse_response(frame: bytes) -> Response:
    serial, route, body = _split(frame, SUBHEADER_RESPONSE, "response")
    if len(body) < 2:
        raise SlmpFrameError("the response has no end code")
    (end_code,) = struct.unpack_from("<H", body)
    return Response(serial, route, end_code, body[2:])


# CiA 402 object access (4020h) ------------------------------------------------------------


def upload_data(index: int, subindex: int) -> bytes:
    """The request data of an SDO Upload (4020h / 0001h)."""
    return _OBJECT.pack(index, subindex, 0, 0)


def download_data(index: int, subindex: int, value: bytes) -> bytes:
    """The request data of an SDO Download (4020h / 0002h)."""
    return _OBJECT.pack(index, subindex, 0, len(value)) + value


@dataclass(frozen=True, slots=True)
class ObjectData:
    index: int
    subindex: int
    data: bytes


def parse_object_data(data: bytes, *, with_value: bool) -> ObjectData:
    """Index, sub-index and (``with_value``) the bytes of a 4020h request or answer.

    The number of data bytes must match what follows, or be 0: MR-J4-GF §3.4.1 fixes it to
    00h for read data, and it is not clear whether that holds for the answer too. An upload
    request and a download's answer carry no bytes."""
    if len(data) < _OBJECT.size:
        raise SlmpFrameError(
            f"{len(data)} bytes are too short for index, sub-index and number of data"
        )
    index, subindex, _reserved, size = _OBJECT.unpack_from(data)
    value = data[_OBJECT.size :]
    if with_value and size not in (0, len(value)):
        raise SlmpFrameError(f"the number of data is {size} and {len(value)} bytes follow")
    if not with_value and value:
        raise SlmpFrameError(f"{len(value)} bytes follow where none are expected")
    return ObjectData(index, subindex, value)


def refused_abort_code(data: bytes) -> int | None:
    """The CiA 301 abort code after the error information of a refused SDO, if there is one."""
    n = _ERROR_INFO.size
    if len(data) == n + 4:
        code: int = struct.unpack_from("<I", data, n)[0]
        return code
    return None


def parse_channel(channel: str, *, server: bool = False) -> tuple[str, int]:
    """``host`` or ``host:port`` -> (host, port), port 5010 by default; :class:`ValidationError`
    naming the fault. A ``server`` may ask for port 0: any free port."""
    return parse_host_port(
        channel,
        default_port=DEFAULT_PORT,
        hint=f"give the station's address as host:port, e.g. 192.168.0.250:{DEFAULT_PORT}",
        server=server,
    )
