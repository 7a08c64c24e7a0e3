"""CiA 301 codecs: byte-exact little-endian encodings and range checks."""

import math

import pytest

from servodesk.domain.datatypes import DataType, codec, coerce_int
from servodesk.errors import ValidationError


@pytest.mark.parametrize(
    ("dt", "value", "raw"),
    [
        (DataType.BOOLEAN, True, "01"),
        (DataType.INTEGER8, -1, "ff"),
        (DataType.INTEGER16, -2, "feff"),
        (DataType.INTEGER24, -8388608, "000080"),
        (DataType.INTEGER32, -2147483648, "00000080"),
        (DataType.INTEGER64, -1, "ffffffffffffffff"),
        (DataType.UNSIGNED8, 255, "ff"),
        (DataType.UNSIGNED16, 0x6040, "4060"),
        (DataType.UNSIGNED24, 0x123456, "563412"),
        (DataType.UNSIGNED32, 0x65766173, "73617665"),  # "save", CiA 301 §7.5.2.13
        (DataType.UNSIGNED48, 0x0102030405, "050403020100"),
        (DataType.UNSIGNED64, 2**64 - 1, "ffffffffffffffff"),
        (DataType.REAL32, 1.5, "0000c03f"),
        (DataType.REAL64, -2.0, "00000000000000c0"),
        (DataType.VISIBLE_STRING, "E1", "4531"),
        (DataType.OCTET_STRING, b"\x01\x02", "0102"),
    ],
)
def test_round_trip_is_byte_exact(dt: DataType, value: object, raw: str) -> None:
    c = codec(dt)
    assert c.encode(value).hex() == raw  # type: ignore[arg-type]
    assert c.decode(bytes.fromhex(raw)) == value


@pytest.mark.parametrize(
    ("dt", "value"),
    [
        (DataType.UNSIGNED8, 256),
        (DataType.UNSIGNED16, -1),
        (DataType.INTEGER8, 128),
        (DataType.INTEGER32, 2**31),
        (DataType.UNSIGNED32, 2**32),
    ],
)
def test_out_of_type_range_is_refused_with_the_range(dt: DataType, value: int) -> None:
    with pytest.raises(ValidationError, match=r"does not fit"):
        codec(dt).encode(value)


def test_integer_text_forms_a_user_types() -> None:
    assert coerce_int("0x1F") == 31
    assert coerce_int("1Fh") == 31
    assert coerce_int("0b101") == 5
    assert coerce_int("1_000") == 1000
    assert coerce_int(12.0) == 12
    with pytest.raises(ValidationError):
        coerce_int(1.5)
    with pytest.raises(ValidationError):
        coerce_int("twelve")


def test_too_few_bytes_is_an_error_not_garbage() -> None:
    with pytest.raises(ValidationError, match="too few"):
        codec(DataType.UNSIGNED32).decode(b"\x01\x02")


def test_visible_string_stops_at_nul_and_real32_nan_survives() -> None:
    assert codec(DataType.VISIBLE_STRING).decode(b"ab\x00cd") == "ab"
    v = codec(DataType.REAL32).decode(codec(DataType.REAL32).encode(float("nan")))
    assert isinstance(v, float) and math.isnan(v)


def test_type_names_and_aliases() -> None:
    assert DataType.from_name("uint16") is DataType.UNSIGNED16
    assert DataType.from_name("DINT") is DataType.INTEGER32
    assert DataType.UNSIGNED16.range == (0, 65535)
    with pytest.raises(ValidationError, match="unknown data type"):
        DataType.from_name("UINT17")
