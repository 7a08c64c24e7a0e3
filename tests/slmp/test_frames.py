"""SLMP 4E binary frames and the 4020h object access in them, byte for byte (domain/slmp.py).

The layouts are MR-J4-GF's / MR-JE-C's SLMP chapter (§3.4, command 4020h), which the
CTMM04x's transient text (003 §4-2) follows; docs/slmp.md.
"""

from __future__ import annotations

import pytest

from servodesk.domain import slmp
from servodesk.errors import ValidationError

AXIS_Y = slmp.Route(multidrop=1)


def test_upload_request_of_an_axis_is_the_documented_frame() -> None:
    frame = slmp.build_request(
        0x1234, AXIS_Y, slmp.CMD_OBJECT, slmp.SUB_UPLOAD, slmp.upload_data(0x6041, 0)
    )
    assert frame == bytes.fromhex(
        "5400 3412 0000"  # 4E subheader, serial, fixed
        "00 ff ff03 01"  # network 0, station FFh, module I/O 03FFh, multidrop 1 (axis Y)
        "0c00 0400"  # 12 bytes follow; monitoring timer 4 x 0.25 s
        "2040 0100"  # command 4020h, sub-command 0001h (SDO Upload)
        "4160 00 00 0000"  # index 6041h, sub-index 0, reserved, number of data 0
    )


def test_download_request_carries_the_value_and_its_size() -> None:
    data = slmp.download_data(0x607A, 0, (0x12345).to_bytes(4, "little"))
    frame = slmp.build_request(1, slmp.Route(), slmp.CMD_OBJECT, slmp.SUB_DOWNLOAD, data, timer=8)
    assert frame == bytes.fromhex(
        "5400 0100 0000 00 ff ff03 00 1000 0800 2040 0200 7a60 00 00 0400 45230100"
    )
    req = slmp.parse_request(frame)
    assert (req.serial, req.route, req.timer) == (1, slmp.Route(), 8)
    assert (req.command, req.subcommand) == (0x4020, 0x0002)
    obj = slmp.parse_object_data(req.data, with_value=True)
    assert (obj.index, obj.subindex, obj.data) == (0x607A, 0, bytes.fromhex("45230100"))


def test_upload_answer_round_trip() -> None:
    frame = slmp.build_response(
        0x1234, AXIS_Y, 0, slmp.download_data(0x6041, 0, bytes.fromhex("4002"))
    )
    assert frame == bytes.fromhex("d400 3412 0000 00 ff ff03 01 0a00 0000 4160 00 00 0200 4002")
    answer = slmp.parse_response(frame)
    assert (answer.serial, answer.route.multidrop, answer.end_code) == (0x1234, 1, 0)
    assert slmp.parse_object_data(answer.data, with_value=True).data == bytes.fromhex("4002")


def test_an_upload_answer_with_number_of_data_zero_is_read() -> None:
    # MR-J4-GF §3.4.1 fixes "number of data" to 00h for read data: a unit may answer so.
    data = bytes.fromhex("4160 00 00 0000 4002")
    assert slmp.parse_object_data(data, with_value=True).data == bytes.fromhex("4002")


def test_refused_sdo_carries_the_abort_code_after_the_error_information() -> None:
    info = slmp.error_info(AXIS_Y, 0x4020, 0x0002)
    assert info == bytes.fromhex("00 ff ff03 01 2040 0200")
    frame = slmp.build_response(7, AXIS_Y, 0xC05C, info + (0x06090030).to_bytes(4, "little"))
    answer = slmp.parse_response(frame)
    assert answer.end_code == 0xC05C
    assert slmp.refused_abort_code(answer.data) == 0x06090030
    # The error information alone (a plain SLMP refusal) carries no abort code.
    assert slmp.refused_abort_code(info) is None
    assert "does not exist" in slmp.end_code_text(0xCF10)
    assert slmp.end_code_text(0xC0DE) == "SLMP end code C0DEh (not in servodesk's list)"


@pytest.mark.parametrize(
    ("frame", "why"),
    [
        (bytes.fromhex("5400 0100"), "too short"),
        (bytes.fromhex("5000 0100 0000 00 ff ff03 00 0600 0400 2040 0100"), "subheader 5000"),
        (bytes.fromhex("5400 0100 0100 00 ff ff03 00 0600 0400 2040 0100"), "fixed field"),
        (bytes.fromhex("5400 0100 0000 00 ff ff03 00 0800 0400 2040 0100"), "says 8 data bytes"),
        (bytes.fromhex("5400 0100 0000 00 ff ff03 00 0200 0400"), "no monitoring timer"),
    ],
)
def test_a_malformed_request_is_refused_with_the_reason(frame: bytes, why: str) -> None:
    with pytest.raises(slmp.SlmpFrameError, match=why):
        slmp.parse_request(frame)


def test_object_data_whose_lengths_disagree_is_refused() -> None:
    with pytest.raises(slmp.SlmpFrameError, match="number of data is 4 and 2 bytes follow"):
        slmp.parse_object_data(bytes.fromhex("7a60 00 00 0400 4523"), with_value=True)
    with pytest.raises(slmp.SlmpFrameError, match="2 bytes follow where none are expected"):
        slmp.parse_object_data(bytes.fromhex("7a60 00 00 0000 4523"), with_value=False)
    with pytest.raises(slmp.SlmpFrameError, match="too short"):
        slmp.parse_object_data(bytes.fromhex("7a60 00"), with_value=False)


def test_channel_names_host_and_port() -> None:
    assert slmp.parse_channel("192.168.0.250:5010") == ("192.168.0.250", 5010)
    assert slmp.parse_channel("192.168.0.250") == ("192.168.0.250", slmp.DEFAULT_PORT)
    assert slmp.parse_channel("127.0.0.1:0", server=True) == ("127.0.0.1", 0)
    for bad in ("127.0.0.1:0", "127.0.0.1:x", ":5010", "host:70000"):
        with pytest.raises(ValidationError) as err:
            slmp.parse_channel(bad)
        assert err.value.field == "channel" and "host:port" in (err.value.hint or "")
