"""SDO block upload frames byte for byte, its CRC and the client's sub-block bookkeeping
(CiA 301 §7.2.4.3.9-§7.2.4.3.16). Frames checked by hand against the bit layouts."""

import pytest

from servodesk.domain import sdo, sdo_block


def test_crc16_ccitt_is_the_xmodem_variant() -> None:
    # x^16 + x^12 + x^5 + 1, initial value 0: the published check value of "123456789".
    assert sdo_block.crc16(b"123456789") == 0x31C3
    assert sdo_block.crc16(b"") == 0
    # Continued over pieces, as a receiver would.
    assert sdo_block.crc16(b"56789", sdo_block.crc16(b"1234")) == 0x31C3
    assert sdo_block.crc16(b"A") == 0x58E5


def test_client_frames_are_byte_exact() -> None:
    # 1010 0100: ccs 5, cc 1, cs 0; 2F07h:00; blksize 127; pst 32.
    assert sdo_block.initiate_upload(0x2F07, 0, 127, 32).hex() == "a4072f007f200000"
    # Without CRC, blksize 4, pst 0 (never switch).
    assert sdo_block.initiate_upload(0x1008, 0, 4, 0, crc=False).hex() == "a00810000400" + "0000"
    assert sdo_block.START.hex() == "a300000000000000"
    assert sdo_block.ack(5, 127).hex() == "a2057f0000000000"
    assert sdo_block.END_RESPONSE.hex() == "a100000000000000"
    with pytest.raises(ValueError):
        sdo_block.initiate_upload(0x2F07, 0, 128, 0)
    with pytest.raises(ValueError):
        sdo_block.ack(0, 0)


def test_server_frames_are_byte_exact() -> None:
    # 1100 0110: scs 6, sc 1, s 1, ss 0; 12800 bytes = 0x3200.
    assert sdo_block.initiate_response(0x2F07, 0, 12800, crc=True).hex() == "c6072f0000320000"
    assert sdo_block.segment(1, b"abcdefg", last=False).hex() == "01" + b"abcdefg".hex()
    # c set, seqno 3, two data bytes and five unused.
    assert sdo_block.segment(3, b"xy", last=True).hex() == "83" + b"xy".hex() + "0000000000"
    # 110 100 0 1: scs 6, n = 4, ss 1; CRC 31C3h little-endian.
    assert sdo_block.end(4, 0x31C3).hex() == "d1c3310000000000"


def test_initiate_answers() -> None:
    start = sdo_block.parse_initiate_response(bytes.fromhex("c6072f0000320000"), 0x2F07, 0)
    assert start == sdo_block.BlockStart(12800, True)
    # The client asked without CRC: not used even though the server does it.
    start = sdo_block.parse_initiate_response(
        bytes.fromhex("c6072f0000320000"), 0x2F07, 0, crc=False
    )
    assert start == sdo_block.BlockStart(12800, False)
    # Size not indicated, no CRC.
    start = sdo_block.parse_initiate_response(bytes.fromhex("c0072f0000000000"), 0x2F07, 0)
    assert start == sdo_block.BlockStart(None, False)
    # The server switched to the normal upload (scs 2): segmented with 33 bytes announced.
    switched = sdo_block.parse_initiate_response(bytes.fromhex("4108100021000000"), 0x1008, 0)
    assert switched == sdo.UploadStart(None, 33)
    with pytest.raises(sdo.SdoAbort) as info:
        sdo_block.parse_initiate_response(bytes.fromhex("80072f0001000405"), 0x2F07, 0)
    assert info.value.code == 0x05040001
    with pytest.raises(sdo.SdoProtocolError, match="not 0x2F07:00"):
        sdo_block.parse_initiate_response(bytes.fromhex("c6082f0000320000"), 0x2F07, 0)
    # scs 6 with ss 1 is an end frame, not an answer to the initiate.
    with pytest.raises(sdo.SdoProtocolError, match="unexpected command 0xC5"):
        sdo_block.parse_initiate_response(bytes.fromhex("c5072f0000320000"), 0x2F07, 0)


def test_end_frame() -> None:
    assert sdo_block.parse_end(bytes.fromhex("d1c3310000000000"), 1, 0) == sdo_block.End(4, 0x31C3)
    with pytest.raises(sdo.SdoProtocolError, match="ending"):
        sdo_block.parse_end(bytes.fromhex("a1c3310000000000"), 1, 0)


def _segments(data: bytes, first: int, count: int, seq0: int = 1) -> list[bytes]:
    """Segments ``first``.. of ``data`` (7 bytes each) numbered from seq0."""
    out = []
    total = max(1, -(-len(data) // 7))
    for k in range(first, min(first + count, total)):
        out.append(
            sdo_block.segment(seq0 + k - first, data[7 * k : 7 * k + 7], last=k == total - 1)
        )
    return out


def test_receiver_two_sub_blocks_in_order() -> None:
    data = b"abcdefghijklmnopqrst"  # 20 bytes: 3 segments, the last with 1 byte unused
    rx = sdo_block.BlockReceiver(0x2F07, 0, 2, 1 << 20)
    s = _segments(data, 0, 3)
    assert rx.segment(s[0]) is False
    assert rx.segment(s[1]) is True  # seqno == blksize: the sub-block is over
    assert rx.ack().hex() == "a2020200" + "00000000"
    assert rx.segment(_segments(data, 2, 1)[0]) is True and rx.complete
    assert rx.ack().hex() == "a2010200" + "00000000"
    end = sdo_block.End(1, sdo_block.crc16(data))
    assert rx.finish(end, crc=True, size=20) == data


def test_receiver_lost_segment_is_acknowledged_before_it_and_sent_again() -> None:
    data = bytes(range(21))  # 3 full segments
    rx = sdo_block.BlockReceiver(1, 0, 3, 1 << 20)
    s = _segments(data, 0, 3)
    assert rx.segment(s[0]) is False
    # Segment 2 is lost; segment 3 (c set) arrives out of order: the sub-block is over.
    assert rx.segment(s[2]) is True and not rx.complete
    assert rx.ack()[1] == 1  # ackseq: only segment 1 counts
    # The server sends from segment 2 again, numbered from 1.
    again = _segments(data, 1, 3)
    assert rx.segment(again[0]) is False
    assert rx.segment(again[1]) is True and rx.complete
    assert rx.ack()[1] == 2
    assert rx.finish(sdo_block.End(0, sdo_block.crc16(data)), crc=True, size=21) == data
    assert rx.dropped == 1


def test_receiver_out_of_order_keeps_only_what_came_in_sequence() -> None:
    data = bytes(range(35))
    rx = sdo_block.BlockReceiver(1, 0, 5, 1 << 20)
    s = _segments(data, 0, 5)
    rx.segment(s[0])
    rx.segment(s[2])  # 3 before 2: dropped
    rx.segment(s[1])  # 2 follows 1: in sequence
    rx.segment(s[3])  # 4 without 3: dropped, and so is everything after
    assert rx.segment(s[4]) is True
    assert rx.ack()[1] == 2
    assert bytes(rx.data) == data[:14]
    assert rx.dropped == 3


def test_receiver_refuses_a_bad_crc_size_or_abort() -> None:
    data = b"0123456789"
    rx = sdo_block.BlockReceiver(1, 0, 127, 1 << 20)
    for f in _segments(data, 0, 2):
        rx.segment(f)
    rx.ack()
    with pytest.raises(sdo.SdoProtocolError, match="CRC") as info:
        rx.finish(sdo_block.End(4, sdo_block.crc16(data) ^ 1), crc=True, size=10)
    assert info.value.abort_code == 0x05040004
    with pytest.raises(sdo.SdoProtocolError, match="announced 11"):
        rx.finish(sdo_block.End(4, 0), crc=False, size=11)
    assert rx.finish(sdo_block.End(4, 0), crc=False, size=None) == data
    rx = sdo_block.BlockReceiver(1, 0, 127, 1 << 20)
    with pytest.raises(sdo.SdoAbort) as aborted:
        rx.segment(bytes.fromhex("8000000000000806"))  # 80h: an abort, never a segment
    assert aborted.value.code == 0x06080000
    with pytest.raises(sdo.SdoProtocolError, match="before its last segment"):
        rx.finish(sdo_block.End(0, 0), crc=False, size=None)


def test_empty_object_is_one_segment_of_seven_unused_bytes() -> None:
    rx = sdo_block.BlockReceiver(1, 0, 127, 1 << 20)
    assert rx.segment(sdo_block.segment(1, b"", last=True)) is True
    rx.ack()
    assert rx.finish(sdo_block.End(7, 0), crc=True, size=0) == b""


def test_server_side_parsers() -> None:
    req = sdo_block.parse_initiate_request(bytes.fromhex("a4072f007f200000"))
    assert req == sdo_block.BlockRequest(0x2F07, 0, 127, 32, True)
    with pytest.raises(sdo.SdoProtocolError) as info:
        sdo_block.parse_initiate_request(bytes.fromhex("a4072f0000200000"))
    assert info.value.abort_code == 0x05040002
    assert sdo_block.parse_ack(bytes.fromhex("a2057f0000000000")) == (5, 127)
    assert sdo_block.client_cs(sdo_block.START) == sdo_block.CS_START
    assert sdo_block.client_cs(sdo_block.END_RESPONSE) == sdo_block.CS_END
    assert sdo_block.client_cs(sdo.upload_segment(0)) is None
