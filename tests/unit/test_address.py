"""Object addresses as users type them."""

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.errors import ValidationError


@pytest.mark.parametrize(
    ("text", "index", "sub"),
    [
        ("0x6040", 0x6040, 0),
        ("0x6040:00", 0x6040, 0),
        ("0x1018:4", 0x1018, 4),
        ("6040h", 0x6040, 0),
        ("1018h.2", 0x1018, 2),
        ("607D:02", 0x607D, 2),
        ("P24640", 24640, 0),
        ("P24640[1]", 24640, 1),
        (" 0x60ff ", 0x60FF, 0),
    ],
)
def test_parse(text: str, index: int, sub: int) -> None:
    assert ObjectAddress.parse(text) == ObjectAddress(index, sub)


@pytest.mark.parametrize("text", ["", "0x", "0x12345", "6040:100", "hello", "P"])
def test_bad_addresses_say_how_to_write_one(text: str) -> None:
    with pytest.raises(ValidationError) as info:
        ObjectAddress.parse(text)
    assert info.value.hint is None or "0x6040" in info.value.hint


def test_printed_form_and_pnu() -> None:
    a = ObjectAddress(0x6040, 0)
    assert str(a) == "0x6040:00"
    assert a.pnu == 24640  # LECSN manual: PNU = CiA index in decimal.
