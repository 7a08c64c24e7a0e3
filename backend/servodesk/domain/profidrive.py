"""PROFIdrive base mode parameter access: requests, responses and the PNU <-> object
mapping (pure, no sockets).

The LECSN-T's acyclic data is PROFIdrive parameter access, at most 240 bytes each way
(004 §20.4.1). A request is written to record 0xB02E and its response read back from it
(:mod:`servodesk.domain.pnio`)::

    request:  reference (1) | request ID (1: 01h read, 02h change) | axis / DO-ID (1)
              | number of parameters n (1) | n x address: attribute (1), number of
              elements (1), PNU (2), subindex (2) | change only: n x values
    response: reference (1) | response ID (1: 01h / 02h, 81h / 82h negative) | axis (1)
              | number of parameters (1) | read or negative: n x values
    values:   format (1) | number of values (1) | values, big-endian; an odd length is
              padded to a whole word

Format 44h carries a PROFIdrive error number (004 §20.4.2) instead of values; in a negative
change response a parameter that was changed answers format 40h with no values.

PNU <-> object (004 §20.1.5, the profile's ``pnu_subindex_offset`` quirk): the PNU is the
CoE index read as a number. For objects from 1000h, an array / record element CoE sub n is
PNU subindex n - 1, and CoE sub 0 (the number of entries) is the parameter's description
element 2 ("number of array elements"); a VAR is PNU subindex 0. Below 1000h (P922-P980,
native PROFIdrive arrays) the subindex is the PNU subindex.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from servodesk.domain.datatypes import DataType

#: Largest request or response (004 §20.1.2, §20.4.1).
MAX_BYTES = 240
#: Parameters per request such that a read of 4-byte values still fits 240 bytes:
#: 4 + 6 n <= 240 for the request, 4 + 6 n for the response.
MAX_PARAMETERS = 39

REQUEST_READ = 0x01
REQUEST_CHANGE = 0x02
NEGATIVE = 0x80

ATTR_VALUE = 0x10
ATTR_DESCRIPTION = 0x20
ATTR_TEXT = 0x30

#: Description elements (PROFIdrive V4.1, parameter description): the identifier and the
#: number of array elements (or a string's length).
DESC_ID = 1
DESC_ELEMENTS = 2
#: Identifier bits: the data type in the low byte; bit 14: the parameter is an array.
ID_ARRAY = 0x4000

#: Formats (the PROFIdrive data type numbers, and the response formats).
FMT_BOOLEAN = 0x01
FMT_INT8 = 0x02
FMT_INT16 = 0x03
FMT_INT32 = 0x04
FMT_UINT8 = 0x05
FMT_UINT16 = 0x06
FMT_UINT32 = 0x07
FMT_FLOAT = 0x08
FMT_VISIBLE_STRING = 0x09
FMT_OCTET_STRING = 0x0A
FMT_ZERO = 0x40
FMT_BYTE = 0x41
FMT_WORD = 0x42
FMT_DWORD = 0x43
FMT_ERROR = 0x44

#: Bytes per value of each format (strings: one per character).
FORMAT_SIZES: dict[int, int] = {
    FMT_BOOLEAN: 1,
    FMT_INT8: 1,
    FMT_INT16: 2,
    FMT_INT32: 4,
    FMT_UINT8: 1,
    FMT_UINT16: 2,
    FMT_UINT32: 4,
    FMT_FLOAT: 4,
    FMT_VISIBLE_STRING: 1,
    FMT_OCTET_STRING: 1,
    FMT_BYTE: 1,
    FMT_WORD: 2,
    FMT_DWORD: 4,
    FMT_ERROR: 2,
    FMT_ZERO: 0,
}
#: Formats whose values are bytes in order (no byte swap between PROFIdrive and CoE).
BYTE_STRINGS = frozenset({FMT_VISIBLE_STRING, FMT_OCTET_STRING})

#: CiA 301 data type -> PROFIdrive format.
FORMAT_OF: dict[DataType, int] = {
    DataType.BOOLEAN: FMT_BOOLEAN,
    DataType.INTEGER8: FMT_INT8,
    DataType.INTEGER16: FMT_INT16,
    DataType.INTEGER32: FMT_INT32,
    DataType.UNSIGNED8: FMT_UINT8,
    DataType.UNSIGNED16: FMT_UINT16,
    DataType.UNSIGNED32: FMT_UINT32,
    DataType.REAL32: FMT_FLOAT,
    DataType.VISIBLE_STRING: FMT_VISIBLE_STRING,
    DataType.OCTET_STRING: FMT_OCTET_STRING,
    DataType.DOMAIN: FMT_OCTET_STRING,
}

#: PROFIdrive error numbers (PROFIdrive V4.1; the LECSN-T's are 004 §20.4.2).
ERRORS: dict[int, str] = {
    0x00: "Impermissible parameter number",
    0x01: "Parameter value cannot be changed",
    0x02: "Low or high limit exceeded",
    0x03: "Faulty subindex",
    0x04: "No array",
    0x05: "Incorrect data type",
    0x06: "Setting not permitted (may only be reset)",
    0x07: "Description element cannot be changed",
    0x09: "No description data available",
    0x0B: "No operation priority",
    0x0F: "No text array available",
    0x11: "Request cannot be executed because of operating state",
    0x14: "Value impermissible",
    0x15: "Response too long",
    0x16: "Parameter address impermissible",
    0x17: "Illegal format",
    0x18: "Number of values inconsistent",
    0x19: "Axis/DO nonexistent",
    0x20: "Parameter text element cannot be changed",
    0x21: "Service not supported",
    0xFF: "Read of a write-only parameter",
}

#: Error numbers that mean "no such parameter / element / drive object" (404) and "not in
#: this state" (409), as the API answers them.
MISSING = frozenset({0x00, 0x03, 0x04, 0x19})
STATE = frozenset({0x11})


class ProfidriveFrameError(ValueError):
    """A parameter request or response that is not well formed; the message says what."""


@dataclass(frozen=True, slots=True)
class ParameterAddress:
    pnu: int
    subindex: int = 0
    attribute: int = ATTR_VALUE
    elements: int = 1


@dataclass(frozen=True, slots=True)
class Values:
    """One parameter's values as carried: format, count and the big-endian bytes."""

    format: int
    count: int
    data: bytes = b""

    @property
    def error(self) -> int | None:
        """The error number of a format-44h block, else None."""
        if self.format != FMT_ERROR:
            return None
        return int.from_bytes(self.data[:2], "big")


def error_values(number: int) -> Values:
    return Values(FMT_ERROR, 1, number.to_bytes(2, "big"))


@dataclass(frozen=True, slots=True)
class Request:
    reference: int
    request_id: int
    axis: int
    addresses: tuple[ParameterAddress, ...]
    values: tuple[Values, ...] = ()


@dataclass(frozen=True, slots=True)
class Response:
    reference: int
    response_id: int
    axis: int
    count: int
    values: tuple[Values, ...] = ()

    @property
    def negative(self) -> bool:
        return bool(self.response_id & NEGATIVE)


def _values_bytes(v: Values) -> bytes:
    out = bytes((v.format, v.count)) + v.data
    return out + b"\0" if len(out) % 2 else out


def _parse_values(data: bytes, pos: int) -> tuple[Values, int]:
    if len(data) - pos < 2:
        raise ProfidriveFrameError(f"a value block at byte {pos} is cut short")
    fmt, count = data[pos], data[pos + 1]
    size = FORMAT_SIZES.get(fmt)
    if size is None:
        raise ProfidriveFrameError(f"format {fmt:02X}h at byte {pos} is unknown")
    end = pos + 2 + size * count
    if end > len(data):
        raise ProfidriveFrameError(
            f"{count} values of format {fmt:02X}h at byte {pos} run past the end"
        )
    v = Values(fmt, count, bytes(data[pos + 2 : end]))
    return v, end + ((end - pos) % 2)


def build_request(r: Request) -> bytes:
    if not 1 <= len(r.addresses) <= 255:
        raise ValueError("a request has 1 to 255 parameters")
    out = bytearray((r.reference & 0xFF, r.request_id, r.axis, len(r.addresses)))
    for a in r.addresses:
        out += struct.pack(">BBHH", a.attribute, a.elements, a.pnu, a.subindex)
    if r.request_id == REQUEST_CHANGE:
        if len(r.values) != len(r.addresses):
            raise ValueError("a change request has one value block per parameter")
        for v in r.values:
            out += _values_bytes(v)
    if len(out) > MAX_BYTES:
        raise ValueError(f"the request has {len(out)} bytes, more than {MAX_BYTES}")
    return bytes(out)


def parse_request(data: bytes) -> Request:
    if len(data) < 4:
        raise ProfidriveFrameError(f"{len(data)} bytes are no parameter request header")
    ref, rid, axis, n = data[0], data[1], data[2], data[3]
    if n == 0:
        raise ProfidriveFrameError("the request names no parameter")
    if len(data) < 4 + 6 * n:
        raise ProfidriveFrameError(f"the request announces {n} parameters, its addresses are cut")
    addresses = tuple(
        ParameterAddress(pnu, sub, attr, elements)
        for attr, elements, pnu, sub in struct.iter_unpack(">BBHH", data[4 : 4 + 6 * n])
    )
    values: list[Values] = []
    pos = 4 + 6 * n
    if rid == REQUEST_CHANGE:
        for _ in range(n):
            v, pos = _parse_values(data, pos)
            values.append(v)
    return Request(ref, rid, axis, addresses, tuple(values))


def build_response(r: Response) -> bytes:
    out = bytearray((r.reference & 0xFF, r.response_id, r.axis, r.count))
    for v in r.values:
        out += _values_bytes(v)
    return bytes(out)


def parse_response(data: bytes) -> Response:
    """The response; a positive change response has no value blocks, every other one has
    one per parameter."""
    if len(data) < 4:
        raise ProfidriveFrameError(f"{len(data)} bytes are no parameter response header")
    ref, rid, axis, n = data[0], data[1], data[2], data[3]
    values: list[Values] = []
    if rid != REQUEST_CHANGE:
        pos = 4
        for _ in range(n):
            v, pos = _parse_values(data, pos)
            values.append(v)
    return Response(ref, rid, axis, n, tuple(values))


def error_text(number: int) -> str:
    return ERRORS.get(number, f"PROFIdrive error {number:02X}h")


# Values between CoE byte order (little-endian, as every servodesk link returns them) and
# PROFIdrive's big-endian -----------------------------------------------------------------


def to_coe(v: Values) -> bytes:
    """The value bytes in CoE order: each element byte-swapped, strings as they are."""
    if v.format in BYTE_STRINGS:
        return v.data
    size = FORMAT_SIZES[v.format]
    if size <= 1:
        return v.data
    return b"".join(v.data[i : i + size][::-1] for i in range(0, len(v.data), size))


def from_coe(fmt: int, data: bytes) -> Values:
    """CoE bytes as a value block of ``fmt``; raises ValueError when the length does not
    fit the format."""
    if fmt in BYTE_STRINGS:
        return Values(fmt, len(data), bytes(data))
    size = FORMAT_SIZES.get(fmt, 0)
    if size == 0 or len(data) % size:
        raise ValueError(f"{len(data)} bytes are no whole number of format {fmt:02X}h values")
    swapped = b"".join(data[i : i + size][::-1] for i in range(0, len(data), size))
    return Values(fmt, len(data) // size, swapped)


# Object address <-> parameter address ----------------------------------------------------

#: Objects below this index are native PROFIdrive parameters (P900-P999): no subindex offset.
COE_FROM = 0x1000


def parameter_for(index: int, subindex: int, *, array: bool) -> ParameterAddress:
    """The parameter address that reads or writes object ``index:subindex``; ``array`` says
    whether the object is an array / record (its identifier's bit 14)."""
    if index < COE_FROM:
        return ParameterAddress(index, subindex)
    if subindex >= 1:
        return ParameterAddress(index, subindex - 1)
    if array:
        return ParameterAddress(index, DESC_ELEMENTS, ATTR_DESCRIPTION)
    return ParameterAddress(index, 0)


def needs_shape(index: int, subindex: int) -> bool:
    """Whether :func:`parameter_for` depends on ``array`` for this object."""
    return index >= COE_FROM and subindex == 0
