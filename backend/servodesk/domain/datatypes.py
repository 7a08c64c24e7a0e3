"""CiA 301 data types (§7.1.2 basic, §7.4.7 table 44) and their little-endian codecs.

A codec turns a typed Python value into the bytes the device holds and back. Size is in
bits; variable-length types (strings, domains) have size 0.
"""

from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass

from servodesk.errors import ValidationError

Value = int | float | bool | str | bytes


class DataType(enum.IntEnum):
    """Data type numbers as used in EDS files (CiA 306 ``DataType=0x0007``)."""

    BOOLEAN = 0x0001
    INTEGER8 = 0x0002
    INTEGER16 = 0x0003
    INTEGER32 = 0x0004
    UNSIGNED8 = 0x0005
    UNSIGNED16 = 0x0006
    UNSIGNED32 = 0x0007
    REAL32 = 0x0008
    VISIBLE_STRING = 0x0009
    OCTET_STRING = 0x000A
    UNICODE_STRING = 0x000B
    DOMAIN = 0x000F
    REAL64 = 0x0011
    INTEGER24 = 0x0010
    INTEGER40 = 0x0012
    INTEGER48 = 0x0013
    INTEGER56 = 0x0014
    INTEGER64 = 0x0015
    UNSIGNED24 = 0x0016
    UNSIGNED40 = 0x0018
    UNSIGNED48 = 0x0019
    UNSIGNED56 = 0x001A
    UNSIGNED64 = 0x001B

    @property
    def bits(self) -> int:
        return _BITS.get(self, 0)

    @property
    def is_integer(self) -> bool:
        return self.name.startswith(("INTEGER", "UNSIGNED")) or self is DataType.BOOLEAN

    @property
    def is_signed(self) -> bool:
        return self.name.startswith("INTEGER")

    @property
    def is_real(self) -> bool:
        return self in (DataType.REAL32, DataType.REAL64)

    @property
    def is_numeric(self) -> bool:
        return self.is_integer or self.is_real

    @property
    def is_string(self) -> bool:
        return self in (DataType.VISIBLE_STRING, DataType.UNICODE_STRING)

    @property
    def range(self) -> tuple[int, int] | None:
        """The integer range the type can hold, or None for non-integers."""
        if not self.is_integer:
            return None
        if self is DataType.BOOLEAN:
            return (0, 1)
        b = self.bits
        if self.is_signed:
            return (-(1 << (b - 1)), (1 << (b - 1)) - 1)
        return (0, (1 << b) - 1)

    @classmethod
    def from_name(cls, name: str) -> DataType:
        key = name.strip().upper()
        key = _ALIASES.get(key, key)
        try:
            return cls[key]
        except KeyError:
            raise ValidationError(
                f"unknown data type {name!r}",
                hint="use a CiA 301 name such as UNSIGNED16, INTEGER32, REAL32, VISIBLE_STRING",
            ) from None


_BITS: dict[DataType, int] = {
    DataType.BOOLEAN: 8,  # Transmitted as one byte over SDO (CiA 301 §7.1.4.1 note).
    DataType.INTEGER8: 8,
    DataType.INTEGER16: 16,
    DataType.INTEGER24: 24,
    DataType.INTEGER32: 32,
    DataType.INTEGER40: 40,
    DataType.INTEGER48: 48,
    DataType.INTEGER56: 56,
    DataType.INTEGER64: 64,
    DataType.UNSIGNED8: 8,
    DataType.UNSIGNED16: 16,
    DataType.UNSIGNED24: 24,
    DataType.UNSIGNED32: 32,
    DataType.UNSIGNED40: 40,
    DataType.UNSIGNED48: 48,
    DataType.UNSIGNED56: 56,
    DataType.UNSIGNED64: 64,
    DataType.REAL32: 32,
    DataType.REAL64: 64,
}

_ALIASES = {
    "BOOL": "BOOLEAN",
    "INT8": "INTEGER8",
    "INT16": "INTEGER16",
    "INT32": "INTEGER32",
    "INT64": "INTEGER64",
    "UINT8": "UNSIGNED8",
    "UINT16": "UNSIGNED16",
    "UINT32": "UNSIGNED32",
    "UINT64": "UNSIGNED64",
    "SINT": "INTEGER8",
    "INT": "INTEGER16",
    "DINT": "INTEGER32",
    "LINT": "INTEGER64",
    "USINT": "UNSIGNED8",
    "UINT": "UNSIGNED16",
    "UDINT": "UNSIGNED32",
    "ULINT": "UNSIGNED64",
    "REAL": "REAL32",
    "LREAL": "REAL64",
    "FLOAT32": "REAL32",
    "FLOAT64": "REAL64",
    "STRING": "VISIBLE_STRING",
    "OCTETSTRING": "OCTET_STRING",
}


@dataclass(frozen=True, slots=True)
class Codec:
    """Encodes and decodes one data type."""

    data_type: DataType

    def encode(self, value: Value) -> bytes:
        dt = self.data_type
        if dt.is_integer:
            iv = coerce_int(value, dt)
            lo, hi = dt.range or (0, 0)
            if not lo <= iv <= hi:
                raise ValidationError(f"{iv} does not fit {dt.name} ({lo}..{hi})")
            return iv.to_bytes(dt.bits // 8, "little", signed=dt.is_signed)
        if dt is DataType.REAL32:
            fv = coerce_float(value)
            if math.isfinite(fv) and abs(fv) > 3.4028234663852886e38:
                raise ValidationError(f"{fv} does not fit REAL32")
            return struct.pack("<f", fv)
        if dt is DataType.REAL64:
            return struct.pack("<d", coerce_float(value))
        if dt is DataType.VISIBLE_STRING:
            if isinstance(value, bytes):
                return value
            return str(value).encode("latin-1", errors="replace")
        if dt is DataType.UNICODE_STRING:
            return str(value).encode("utf-16-le")
        # OCTET_STRING, DOMAIN: bytes, or hex text.
        if isinstance(value, bytes):
            return value
        if isinstance(value, str):
            try:
                return bytes.fromhex(value.replace(" ", ""))
            except ValueError:
                raise ValidationError(f"{value!r} is not hex bytes") from None
        raise ValidationError(f"{dt.name} takes bytes or hex text, not {type(value).__name__}")

    def decode(self, data: bytes) -> Value:
        dt = self.data_type
        if dt.is_integer:
            n = dt.bits // 8
            if len(data) < n:
                raise ValidationError(f"{len(data)} bytes are too few for {dt.name} ({n})")
            v = int.from_bytes(data[:n], "little", signed=dt.is_signed)
            return bool(v) if dt is DataType.BOOLEAN else v
        if dt is DataType.REAL32:
            if len(data) < 4:
                raise ValidationError(f"{len(data)} bytes are too few for REAL32")
            return float(struct.unpack_from("<f", data)[0])
        if dt is DataType.REAL64:
            if len(data) < 8:
                raise ValidationError(f"{len(data)} bytes are too few for REAL64")
            return float(struct.unpack_from("<d", data)[0])
        if dt is DataType.VISIBLE_STRING:
            return data.split(b"\x00", 1)[0].decode("latin-1")
        if dt is DataType.UNICODE_STRING:
            return data.decode("utf-16-le", errors="replace")
        return bytes(data)


def coerce_int(value: Value, dt: DataType = DataType.INTEGER64) -> int:
    """Accept int, bool, integral float, or text in decimal / 0x hex / 0b binary."""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        if value.is_integer():
            return int(value)
        raise ValidationError(f"{value} is not a whole number ({dt.name})")
    if isinstance(value, str):
        text = value.strip().replace("_", "")
        try:
            return int(text, 0)
        except ValueError:
            pass
        if text.lower().endswith("h"):
            try:
                return int(text[:-1], 16)
            except ValueError:
                pass
        if text.lower() in ("true", "false"):
            return int(text.lower() == "true")
    raise ValidationError(f"{value!r} is not an integer ({dt.name})")


def coerce_float(value: Value) -> float:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value.strip())
        except ValueError:
            pass
    raise ValidationError(f"{value!r} is not a number")


def codec(dt: DataType) -> Codec:
    return _CODECS[dt]


_CODECS = {dt: Codec(dt) for dt in DataType}
