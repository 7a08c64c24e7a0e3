"""PNIO-CM frames and PROFIdrive parameter requests, byte for byte.

The RPC datagrams and PNIO blocks servodesk builds are checked against scapy's independent
PROFINET dissector (scapy.contrib.pnio_rpc), field by field and byte for byte where both
build the same block; the PROFIdrive requests against the layout of 004 §20.4.1.
"""

from __future__ import annotations

import uuid

import pytest
from scapy.contrib import pnio_rpc
from scapy.layers.dcerpc import DceRpc4

from servodesk.domain import pnio
from servodesk.domain import profidrive as pd
from servodesk.domain.profile_loader import ProfileCatalog

AR = uuid.UUID("12345678-9abc-def0-1122-334455667788")
ACT = uuid.UUID("0f1e2d3c-4b5a-6978-8796-a5b4c3d2e1f0")


def test_an_rpc_request_reads_back_in_scapy_with_every_header_field() -> None:
    body = pnio.request_body(b"\x01\x02\x03", 1464)
    frame = pnio.build_rpc(
        pnio.RpcPacket(
            ptype=pnio.PTYPE_REQUEST,
            opnum=pnio.OP_WRITE,
            object_uuid=pnio.object_uuid(0x021C, 0x0302),
            interface=pnio.DEVICE_INTERFACE,
            activity=ACT,
            seqnum=7,
            body=body,
        )
    )
    assert len(frame) == 80 + 20 + 3
    assert frame[:4] == bytes((4, 0, 0x20, 0)) and frame[4] == 0x10  # CL-RPC, little-endian
    rpc = DceRpc4(frame)
    assert rpc.ptype == 0 and rpc.opnum == 3 and rpc.seqnum == 7 and rpc.len == 23
    assert rpc.if_id == pnio.DEVICE_INTERFACE
    assert rpc.act_id == ACT
    assert str(rpc.object) == "dea00000-6c97-11d1-8271-00010302021c"
    pdu = rpc.payload
    assert isinstance(pdu, pnio_rpc.PNIOServiceReqPDU)
    assert (pdu.args_max, pdu.args_length, pdu.max_count, pdu.offset, pdu.actual_count) == (
        1464,
        3,
        1464,
        0,
        3,
    )
    # And back: ours parses what scapy built.
    again = pnio.parse_rpc(bytes(rpc))
    assert (again.opnum, again.seqnum, again.activity) == (3, 7, ACT)
    assert pnio.parse_request_body(again.body) == (1464, b"\x01\x02\x03")


def test_a_big_endian_rpc_datagram_is_read_as_well() -> None:
    packet = pnio.RpcPacket(
        ptype=pnio.PTYPE_RESPONSE,
        opnum=pnio.OP_READ,
        object_uuid=pnio.object_uuid(1, 2),
        interface=pnio.DEVICE_INTERFACE,
        activity=ACT,
        seqnum=0x01020304,
        body=pnio.response_body(0, b"", 0, little=False),
        little=False,
    )
    frame = pnio.build_rpc(packet)
    assert frame[4] == 0x00 and frame[64:68] == bytes((1, 2, 3, 4))  # seqnum, big-endian
    assert DceRpc4(frame).seqnum == 0x01020304
    assert pnio.parse_rpc(frame) == packet


def test_the_blocks_are_the_ones_scapy_builds() -> None:
    ar = pnio.ArRequest(
        ar_uuid=AR,
        session_key=3,
        initiator_mac=bytes.fromhex("020000000001"),
        initiator_object=pnio.object_uuid(0, 0),
        station_name="servodesk",
    )
    theirs = pnio_rpc.ARBlockReq(
        ARType=6,
        ARUUID=AR,
        SessionKey=3,
        CMInitiatorMacAdd="02:00:00:00:00:01",
        CMInitiatorObjectUUID=pnio.object_uuid(0, 0),
        ARProperties_DeviceAccess=1,
        ARProperties_ParametrizationServer=1,
        ARProperties_State=1,
        CMInitiatorActivityTimeoutFactor=100,
        CMInitiatorStationName=b"servodesk",
    )
    assert pnio.ar_block_req(ar) == bytes(theirs)
    assert pnio.parse_ar_block_req(pnio.split_blocks(bytes(theirs))[0][1]) == ar

    res = pnio.ar_block_res(6, AR, 3, bytes.fromhex("020000000005"))
    parsed = pnio_rpc.ARBlockRes(res)
    assert (parsed.block_type, parsed.ARUUID, parsed.SessionKey) == (0x8101, AR, 3)
    assert parsed.CMResponderMacAdd == "02:00:00:00:00:05"

    where = pnio.RecordAddress(slot=1, subslot=1, index=0xB02E)
    head = pnio.RecordHeader(seq=9, ar_uuid=AR, where=where, length=10)
    write = pnio.record_request(pnio.BLOCK_WRITE_REQ, head)
    assert len(write) == 64
    assert (
        write
        == bytes(
            pnio_rpc.IODWriteReq(
                seqNum=9,
                ARUUID=AR,
                slotNumber=1,
                subslotNumber=1,
                index=0xB02E,
                recordDataLength=10,
            )
        )[:64]
    )
    read = pnio.record_request(pnio.BLOCK_READ_REQ, head)
    assert (
        read
        == bytes(
            pnio_rpc.IODReadReq(
                seqNum=9,
                ARUUID=AR,
                slotNumber=1,
                subslotNumber=1,
                index=0xB02E,
                recordDataLength=10,
            )
        )[:64]
    )
    read_res = pnio.record_response(pnio.BLOCK_READ_RES, head)
    scapy_res = pnio_rpc.IODReadRes(read_res + bytes(10))
    assert (scapy_res.block_type, scapy_res.seqNum, scapy_res.index) == (0x8009, 9, 0xB02E)
    assert scapy_res.recordDataLength == 10 and len(read_res) == 64
    write_res = pnio.record_response(
        pnio.BLOCK_WRITE_RES, pnio.RecordHeader(9, AR, where, 10, status=0xDF80B000)
    )
    scapy_wres = pnio_rpc.IODWriteRes(write_res)
    assert scapy_wres.status == 0xDF80B000 and scapy_wres.block_length == 60
    parsed_head, rest = pnio.parse_record_header(write_res, pnio.BLOCK_WRITE_RES)
    assert parsed_head.status == 0xDF80B000 and rest == b""

    release = pnio.release_block(pnio.BLOCK_RELEASE_REQ, AR, 3, pnio.CONTROL_RELEASE)
    assert release == bytes(
        pnio_rpc.IODControlReq(block_type=0x0114, ARUUID=AR, SessionKey=3, ControlCommand_Release=1)
    )


def test_a_write_request_carries_its_record_and_a_short_one_is_refused() -> None:
    where = pnio.RecordAddress(1, 1, 0xB02E)
    args = pnio.record_request(pnio.BLOCK_WRITE_REQ, pnio.RecordHeader(1, AR, where, 4)) + b"abcd"
    head, record = pnio.parse_record_header(args, pnio.BLOCK_WRITE_REQ)
    assert (head.where, record) == (where, b"abcd")
    with pytest.raises(pnio.PnioFrameError, match="announces 4 bytes"):
        pnio.parse_record_header(args[:-1], pnio.BLOCK_WRITE_REQ)
    with pytest.raises(pnio.PnioFrameError, match="expected record header block 0009h"):
        pnio.parse_record_header(args, pnio.BLOCK_READ_REQ)


def test_im0_is_the_name_plate_of_004_20_4_4() -> None:
    im = pnio.Im0(
        vendor_id=540,
        order_id="MR-J4-TM",
        serial="123",
        hardware_revision=1,
        software_revision=("V", 1, 10, 0),
        profile_id=0x3A00,
        version=(1, 1),
        supported=30,
    )
    data = pnio.im0_block(im)
    assert data[:6] == bytes.fromhex("0020 0038 0100")  # type, 56 bytes, version 1.0
    assert data[6:8] == (540).to_bytes(2, "big")
    assert data[8:28] == b"MR-J4-TM".ljust(20)
    assert data[28:44] == b"123".ljust(16) and data[44:46] == b"\0\x01"
    assert data[46:50] == b"V\x01\x0a\x00"  # software revision V1.10.0
    assert data[-2:] == (30).to_bytes(2, "big")
    assert pnio.parse_im0(data) == im
    assert im.software_version == "V1.10.0"


def test_a_pnio_status_says_what_failed() -> None:
    unknown_ar = pnio.pnio_status(pnio.ERROR_CODE_READ, pnio.DECODE_PNIO, pnio.CMRPC, 0x05)
    assert unknown_ar == 0xDE814005
    assert pnio.status_text(unknown_ar) == "record read: AR UUID unknown (the AR has ended)"
    assert "invalid index" in pnio.status_text(0xDF80B000)


@pytest.mark.parametrize(
    ("channel", "expected"),
    [("192.168.0.10", ("192.168.0.10", 34964)), ("localhost:4000", ("localhost", 4000))],
)
def test_a_channel_is_a_host_with_the_pnio_port_by_default(
    channel: str, expected: tuple[str, int]
) -> None:
    assert pnio.parse_channel(channel) == expected


@pytest.mark.parametrize("channel", ["", ":34964", "host:x", "host:70000", "host:0"])
def test_a_bad_channel_names_what_is_wrong(channel: str) -> None:
    with pytest.raises(Exception, match="channel") as info:
        pnio.parse_channel(channel)
    assert info.value.hint  # type: ignore[attr-defined]


# PROFIdrive ---------------------------------------------------------------------------


def test_a_read_request_is_the_layout_of_004_20_4_1() -> None:
    req = pd.Request(
        7,
        pd.REQUEST_READ,
        1,
        (pd.ParameterAddress(24698), pd.ParameterAddress(24729, 1)),
    )
    data = pd.build_request(req)
    assert data == bytes.fromhex("07 01 01 02  10 01 607A 0000  10 01 6099 0001")
    assert pd.parse_request(data) == req


def test_a_change_request_pads_odd_values_to_a_word() -> None:
    req = pd.Request(
        1,
        pd.REQUEST_CHANGE,
        1,
        (pd.ParameterAddress(0x2001), pd.ParameterAddress(0x6060)),
        (pd.from_coe(pd.FMT_INT32, (-2).to_bytes(4, "little", signed=True)),
         pd.from_coe(pd.FMT_INT8, b"\x01")),
    )  # fmt: skip
    data = pd.build_request(req)
    values = data[4 + 12 :]
    assert values == bytes.fromhex("04 01 FFFFFFFE  02 01 01 00")
    assert pd.parse_request(data) == req


def test_a_negative_response_carries_an_error_number_per_parameter() -> None:
    data = bytes.fromhex("07 81 01 02  44 01 0000  06 01 0220")
    resp = pd.parse_response(data)
    assert resp.negative and resp.count == 2
    assert resp.values[0].error == 0x00
    assert resp.values[1].error is None and pd.to_coe(resp.values[1]) == b"\x20\x02"
    assert pd.build_response(resp) == data
    assert pd.parse_response(bytes.fromhex("01 02 01 01")).values == ()  # changed


def test_a_cut_response_is_refused_with_where() -> None:
    with pytest.raises(pd.ProfidriveFrameError, match="run past the end"):
        pd.parse_response(bytes.fromhex("07 01 01 01  07 01 0000"))
    with pytest.raises(pd.ProfidriveFrameError, match="format 99h"):
        pd.parse_response(bytes.fromhex("07 01 01 01  99 01 0000"))


def test_values_swap_between_coe_and_profidrive_byte_order() -> None:
    v = pd.from_coe(pd.FMT_UINT32, bytes.fromhex("78563412"))
    assert v == pd.Values(pd.FMT_UINT32, 1, bytes.fromhex("12345678"))
    assert pd.to_coe(v) == bytes.fromhex("78563412")
    text = pd.from_coe(pd.FMT_VISIBLE_STRING, b"LECSN")
    assert (text.count, pd.to_coe(text)) == (5, b"LECSN")
    with pytest.raises(ValueError, match="no whole number"):
        pd.from_coe(pd.FMT_INT32, b"\x01\x02")


@pytest.mark.parametrize(
    ("index", "sub", "array", "expected"),
    [
        (0x607A, 0, False, pd.ParameterAddress(0x607A, 0)),  # a VAR: PNU subindex 0
        (0x6099, 1, True, pd.ParameterAddress(0x6099, 0)),  # P24729.0 = 6099h:01
        (0x6099, 2, True, pd.ParameterAddress(0x6099, 1)),
        (0x6099, 0, True, pd.ParameterAddress(0x6099, 2, pd.ATTR_DESCRIPTION)),  # entries
        (0x1010, 1, True, pd.ParameterAddress(0x1010, 0)),  # P4112.0 = 1010h:01
        (0x03C4, 2, True, pd.ParameterAddress(0x03C4, 2)),  # P964.2: native, no offset
    ],
)
def test_objects_map_to_parameters_by_004_20_1_5(
    index: int, sub: int, array: bool, expected: pd.ParameterAddress
) -> None:
    assert pd.parameter_for(index, sub, array=array) == expected


def test_the_error_numbers_are_the_ones_the_lecsn_manual_lists() -> None:
    table = {
        e.code: e.name for e in ProfileCatalog().get("lecsn-t").errors if e.table == "profidrive"
    }
    assert table, "the LECSN-T profile lists the PROFIdrive error numbers (004 §20.4.2)"
    for code, name in table.items():
        assert pd.error_text(code).lower() == name.lower(), hex(code)
