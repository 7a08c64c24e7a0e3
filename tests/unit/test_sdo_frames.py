"""SDO frames byte for byte (CiA 301 §7.2.4.3)."""

import pytest

from servodesk.domain import sdo


def test_requests_are_byte_exact() -> None:
    assert sdo.initiate_upload(0x1018, 1).hex() == "4018100100000000"
    assert sdo.upload_segment(0).hex() == "6000000000000000"
    assert sdo.upload_segment(1).hex() == "7000000000000000"
    # Expedited download with size indicated: 0x2F (1 byte), 0x2B (2), 0x27 (3), 0x23 (4).
    assert sdo.initiate_download(0x6040, 0, b"\x06\x00").hex() == "2b40600006000000"
    assert sdo.initiate_download(0x6060, 0, b"\x01").hex() == "2f60600001000000"
    assert sdo.initiate_download(0x1010, 1, b"save").hex() == "2310100173617665"
    # Segmented download announces the size.
    assert sdo.initiate_download(0x1008, 0, b"abcdefghij").hex() == "210810000a000000"
    assert sdo.download_segment(0, b"abcdefg", last=False).hex() == "00" + b"abcdefg".hex()
    assert sdo.download_segment(1, b"hij", last=True).hex() == "19" + b"hij".hex() + "00000000"
    assert sdo.abort(0x6040, 0, 0x05040000).hex() == "8040600000000405"


def test_expedited_upload_answers_give_exactly_the_indicated_bytes() -> None:
    r = sdo.parse_initiate_upload(bytes.fromhex("4b41600037020000"), 0x6041, 0)
    assert r.data == b"\x37\x02" and r.size == 2
    r = sdo.parse_initiate_upload(bytes.fromhex("4300100092010200"), 0x1000, 0)
    assert r.data == bytes.fromhex("92010200")
    # Expedited without size: all four bytes.
    r = sdo.parse_initiate_upload(bytes.fromhex("4200100092010200"), 0x1000, 0)
    assert r.data == bytes.fromhex("92010200")


def test_segmented_upload() -> None:
    start = sdo.parse_initiate_upload(bytes.fromhex("4108100021000000"), 0x1008, 0)
    assert start.data is None and start.size == 33
    seg = sdo.parse_upload_segment(bytes.fromhex("00") + b"servode", 0, 0x1008, 0)
    assert seg == sdo.Segment(b"servode", False)
    seg = sdo.parse_upload_segment(bytes.fromhex("19") + b"ive" + bytes(4), 1, 0x1008, 0)
    assert seg == sdo.Segment(b"ive", True)
    with pytest.raises(sdo.SdoProtocolError, match="toggle") as info:
        sdo.parse_upload_segment(bytes.fromhex("10") + bytes(7), 0, 0x1008, 0)
    assert info.value.abort_code == 0x05030000


def test_abort_frames_carry_the_code() -> None:
    with pytest.raises(sdo.SdoAbort) as info:
        sdo.parse_initiate_download(bytes.fromhex("8041600002000106"), 0x6041, 0)
    assert info.value.code == 0x06010002


def test_answers_for_another_object_or_command_are_refused() -> None:
    with pytest.raises(sdo.SdoProtocolError, match="not 0x6041:00"):
        sdo.parse_initiate_upload(bytes.fromhex("4b40600037020000"), 0x6041, 0)
    with pytest.raises(sdo.SdoProtocolError, match="unexpected command"):
        sdo.parse_initiate_download(bytes.fromhex("4b41600037020000"), 0x6041, 0)
    sdo.parse_download_segment(bytes.fromhex("3000000000000000"), 1, 0x1008, 0)
    with pytest.raises(sdo.SdoProtocolError, match="8"):
        sdo.parse_initiate_download(b"\x60", 0x6041, 0)
