"""Validation of writes against the profile, and the value views of a read."""

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.domain.values import describe, encode_write
from servodesk.errors import ObjectAccessError, ValidationError

P = ProfileCatalog().get("cia402-generic")


def spec(index: int, sub: int = 0):  # type: ignore[no-untyped-def]
    return P.spec(ObjectAddress(index, sub))


def test_read_only_objects_are_refused_before_the_bus_with_the_abort_code() -> None:
    with pytest.raises(ObjectAccessError, match="nothing was sent") as info:
        encode_write(ObjectAddress(0x6041), spec(0x6041), 1)
    assert info.value.code == 0x06010002
    assert info.value.meaning == "Attempt to write a read only object"


def test_range_from_the_profile_with_units() -> None:
    with pytest.raises(ValidationError, match=r"above the maximum 3000") as info:
        encode_write(ObjectAddress(0x6072), spec(0x6072), 5000)
    assert "0.1 %" in info.value.message
    assert encode_write(ObjectAddress(0x6072), spec(0x6072), 1000) == b"\xe8\x03"
    # A number in hex goes as the bytes (raw_hex); text is no number (docs/api.md, PUT objects).
    assert encode_write(ObjectAddress(0x6072), spec(0x6072), raw_hex="e803") == b"\xe8\x03"
    with pytest.raises(ValidationError, match="UNSIGNED16: it takes a number"):
        encode_write(ObjectAddress(0x6072), spec(0x6072), "0x3E8")


def test_modes_outside_the_list_are_refused() -> None:
    with pytest.raises(ValidationError, match="not an allowed value") as info:
        encode_write(ObjectAddress(0x6060), spec(0x6060), 8)
    assert "1 (Profile position)" in (info.value.hint or "")


def test_raw_hex_is_checked_for_size_and_range() -> None:
    assert encode_write(
        ObjectAddress(0x6081), spec(0x6081), raw_hex="40 0d 03 00"
    ) == bytes.fromhex("400d0300")
    with pytest.raises(ValidationError, match="4 bytes"):
        encode_write(ObjectAddress(0x6081), spec(0x6081), raw_hex="400d")
    with pytest.raises(ValidationError, match="not hex"):
        encode_write(ObjectAddress(0x6081), spec(0x6081), raw_hex="zz")
    with pytest.raises(ValidationError, match="either a value or raw_hex"):
        encode_write(ObjectAddress(0x6081), spec(0x6081), 1, "00")


def test_unknown_objects_take_raw_bytes_only() -> None:
    a = ObjectAddress(0x2345, 1)
    assert encode_write(a, None, raw_hex="0102") == b"\x01\x02"
    with pytest.raises(ValidationError, match="not in the session's profile"):
        encode_write(a, None, 5)


def test_describe_gives_raw_and_engineering_side_by_side() -> None:
    v = describe(ObjectAddress(0x6064), spec(0x6064), (131072).to_bytes(4, "little", signed=True))
    assert v.value == 131072 and v.raw_hex == "00000200"
    assert v.engineering == pytest.approx(360.0) and v.unit == "deg" and v.raw_unit == "inc"
    m = describe(ObjectAddress(0x6061), spec(0x6061), b"\x03")
    assert m.value == 3 and m.value_text == "Profile velocity"
