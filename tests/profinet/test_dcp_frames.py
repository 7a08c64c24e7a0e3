"""PROFINET DCP frames byte for byte, against scapy's independent dissector
(scapy.contrib.pnio_dcp), and the twin's answers to them without a socket.

What a commissioning engineer relies on: the Identify that every PROFINET device answers,
the Set frames that give a drive its station name and IP address (004 §20.1.3), and the
checks that refuse a name or an address the device would refuse, before anything is sent.
"""

from __future__ import annotations

import pytest
from scapy.contrib.pnio import ProfinetIO
from scapy.contrib.pnio_dcp import (
    DCPDeviceIDBlock,
    DCPIPBlock,
    DCPNameOfStationBlock,
    ProfinetDCP,
)
from scapy.layers.l2 import Dot1Q, Ether

from servodesk.domain import dcp
from servodesk.errors import ValidationError
from servodesk.sim.profinet_dcp import DcpResponder, DcpStation

TOOL = bytes.fromhex("020000000001")
DEVICE = bytes.fromhex("0030110a0b0c")


def _station(**kw: object) -> DcpStation:
    base: dict[str, object] = {
        "vendor_id": 0x010C,
        "device_id": 0x0010,
        "type_of_station": "LEC-S-NP",
        "name_of_station": "axis-1",
        "ip": "192.168.0.10",
        "netmask": "255.255.255.0",
        "gateway": "192.168.0.1",
    }
    base.update(kw)
    return DcpStation(**base)  # type: ignore[arg-type]


def test_identify_all_is_the_frame_scapy_builds() -> None:
    ours = dcp.identify_request(TOOL, 0x01020304, response_delay=50).encode()
    theirs = (
        Ether(dst="01:0e:cf:00:00:00", src="02:00:00:00:00:01")
        / ProfinetIO(frameID=0xFEFE)
        / ProfinetDCP(
            service_id=5,
            service_type=0,
            xid=0x01020304,
            reserved=50,
            dcp_data_length=4,
            option=255,
            sub_option=255,
            dcp_block_length=0,
        )
    )
    assert ours == bytes(theirs)
    assert len(ours) == 60  # padded to the shortest Ethernet frame


def test_set_ip_and_set_name_are_the_frames_scapy_builds() -> None:
    ours = dcp.set_request(
        DEVICE, TOOL, 9, (dcp.ip_block("10.0.0.5", "255.255.255.0", "10.0.0.1"),)
    ).encode()
    theirs = (
        Ether(dst="00:30:11:0a:0b:0c", src="02:00:00:00:00:01")
        / ProfinetIO(frameID=0xFEFD)
        / ProfinetDCP(
            service_id=4,
            service_type=0,
            xid=9,
            dcp_data_length=18,
            option=1,
            sub_option=2,
            dcp_block_length=14,
            block_qualifier=1,
            ip="10.0.0.5",
            netmask="255.255.255.0",
            gateway="10.0.0.1",
        )
    )
    assert ours == bytes(theirs)
    ours = dcp.set_request(DEVICE, TOOL, 9, (dcp.name_block("axis-1", permanent=False),)).encode()
    theirs = (
        Ether(dst="00:30:11:0a:0b:0c", src="02:00:00:00:00:01")
        / ProfinetIO(frameID=0xFEFD)
        / ProfinetDCP(
            service_id=4,
            service_type=0,
            xid=9,
            dcp_data_length=12,
            option=2,
            sub_option=2,
            dcp_block_length=8,
            block_qualifier=0,
            name_of_station="axis-1",
        )
    )
    assert ours == bytes(theirs)


def test_an_odd_block_is_padded_and_the_padding_counted_in_the_data_length() -> None:
    frame = dcp.set_request(DEVICE, TOOL, 1, (dcp.name_block("ax-1"), dcp.signal_block())).encode()
    # name block: 4 + 2 + 4 = 10 (even); signal: 4 + 4 = 8
    assert frame[24:26] == (18).to_bytes(2, "big")
    frame = dcp.set_request(DEVICE, TOOL, 1, (dcp.name_block("axis"), dcp.signal_block())).encode()
    assert frame[24:26] == (18).to_bytes(2, "big")
    odd = dcp.set_request(DEVICE, TOOL, 1, (dcp.name_block("ax1"), dcp.signal_block())).encode()
    assert odd[24:26] == (18).to_bytes(2, "big")  # 4 + 5 + pad, then 8
    assert odd[26 + 9] == 0  # the pad byte
    again = dcp.parse(odd)
    assert [(b.option, b.suboption) for b in again.blocks] == [(2, 2), (5, 3)]
    assert again.blocks[0].data == b"\x00\x01ax1"


def test_the_twins_identify_answer_reads_in_scapy_block_by_block() -> None:
    twin = DcpResponder(_station(), DEVICE)
    answer = twin.answer(dcp.identify_request(TOOL, 7).encode())
    assert answer is not None
    pkt = Ether(answer)
    assert pkt.dst == "02:00:00:00:00:01" and pkt.src == "00:30:11:0a:0b:0c"
    assert pkt[ProfinetIO].frameID == 0xFEFF
    d = pkt[ProfinetDCP]
    assert (d.service_id, d.service_type, d.xid) == (5, 1, 7)
    assert bytes(pkt[DCPNameOfStationBlock].name_of_station) == b"axis-1"
    ip = pkt[DCPIPBlock]
    assert (ip.block_info, ip.ip, ip.netmask, ip.gateway) == (
        1,
        "192.168.0.10",
        "255.255.255.0",
        "192.168.0.1",
    )
    ids = pkt[DCPDeviceIDBlock]
    assert (ids.vendor_id, ids.device_id) == (0x010C, 0x0010)


def test_an_identify_answer_scapy_builds_with_a_vlan_tag_is_read() -> None:
    # scapy's block builder pads even-length blocks too (one byte more than the standard's
    # padding), so the answer it builds here holds an odd-length name only; the twin's
    # answers with every block are read by scapy above.
    pkt = (
        Ether(dst="02:00:00:00:00:01", src="00:30:11:0a:0b:0c")
        / Dot1Q(vlan=0, prio=6)
        / ProfinetIO(frameID=0xFEFF)
        / ProfinetDCP(
            service_id=5,
            service_type=1,
            xid=3,
            dcp_data_length=16,  # scapy leaves it 0 unless given
            dcp_blocks=[DCPNameOfStationBlock(name_of_station="press-lft", block_info=0)],
        )
    )
    packet = dcp.parse(bytes(pkt))
    assert (packet.frame_id, packet.xid) == (dcp.FRAME_IDENTIFY_RESPONSE, 3)
    dev = dcp.device_from(packet)
    assert (dev.mac, dev.name_of_station, dev.ip) == ("00:30:11:0a:0b:0c", "press-lft", None)


def test_an_address_from_dhcp_in_conflict_is_reported_so() -> None:
    suite = bytes((10, 1, 2, 3, 255, 0, 0, 0, 0, 0, 0, 0))
    answer = dcp.Packet(
        TOOL,
        DEVICE,
        dcp.FRAME_IDENTIFY_RESPONSE,
        dcp.SERVICE_IDENTIFY,
        dcp.TYPE_SUCCESS,
        3,
        blocks=(
            dcp.response_block(dcp.OPT_IP, dcp.SUB_IP, 0x82, suite),
            dcp.response_block(dcp.OPT_DEVICE, dcp.SUB_DEVICE_ID, 0, bytes((0, 0x2A, 4, 1))),
        ),
    ).encode()
    assert Ether(answer)[DCPIPBlock].ip == "10.1.2.3"  # scapy reads it too
    dev = dcp.device_from(dcp.parse(answer))
    assert (dev.ip, dev.netmask, dev.gateway) == ("10.1.2.3", "255.0.0.0", "0.0.0.0")
    assert dev.ip_origin == "dhcp" and dev.ip_conflict
    assert (dev.vendor_id, dev.device_id) == (0x002A, 0x0401)


@pytest.mark.parametrize(
    ("frame", "why"),
    [
        (b"\x01\x02", "shorter than an Ethernet header"),
        (bytes(12) + b"\x08\x00" + bytes(46), "not DCP's 8892h"),
        (bytes(12) + b"\x88\x92\xfe\xfe\x05", "inside the DCP header"),
        (bytes(12) + b"\x88\x92\x80\x00" + bytes(10), "not a DCP frame"),
        (
            bytes(12) + b"\x88\x92\xfe\xfe\x05\x00" + bytes(6) + b"\x00\x40" + bytes(8),
            "past the end",
        ),
        (
            bytes(12) + b"\x88\x92\xfe\xff\x05\x01" + bytes(6) + b"\x00\x06\x02\x02\x00\x08ab",
            "runs past DCPDataLength",
        ),
    ],
)
def test_a_malformed_frame_is_refused_with_its_reason(frame: bytes, why: str) -> None:
    with pytest.raises(dcp.MalformedFrame, match=why):
        dcp.parse(frame)


def test_an_identify_answer_with_a_short_ip_block_is_malformed() -> None:
    bad = dcp.Packet(
        TOOL,
        DEVICE,
        dcp.FRAME_IDENTIFY_RESPONSE,
        dcp.SERVICE_IDENTIFY,
        dcp.TYPE_SUCCESS,
        1,
        blocks=(dcp.response_block(dcp.OPT_IP, dcp.SUB_IP, 1, bytes(8)),),
    )
    with pytest.raises(dcp.MalformedFrame, match="IP parameter block of 8 bytes"):
        dcp.device_from(dcp.parse(bad.encode()))


@pytest.mark.parametrize(
    "name", ["axis-1", "lecsn-t.line2.plant-a", "a", "x" * 63, "port-1x2", "1-press"]
)
def test_valid_station_names(name: str) -> None:
    assert dcp.check_name_of_station(name) == name


@pytest.mark.parametrize(
    ("name", "why"),
    [
        ("", "is empty"),
        ("Axis-1", "capital letters"),
        ("axis_1", "has the part"),
        ("-axis", "has the part"),
        ("axis-", "has the part"),
        ("a..b", "has the part ''"),
        ("x" * 64, "has the part"),
        ("port-001", "port name"),
        ("port-001-00002.cell", "port name"),
        ("192.168.0.1", "is an IP address"),
        ("achse-ü", "has the part"),
        ("a." * 121, "characters"),
    ],
)
def test_invalid_station_names_are_refused_with_the_rule(name: str, why: str) -> None:
    with pytest.raises(ValidationError, match=why) as info:
        dcp.check_name_of_station(name)
    assert info.value.field == "name_of_station" and info.value.hint


@pytest.mark.parametrize(
    ("suite", "field", "why"),
    [
        (("192.168.0.300", "255.255.255.0", "0.0.0.0"), "ip", "not an IPv4 address"),
        (("192.168.0.10", "255.0.255.0", "0.0.0.0"), "netmask", "not contiguous"),
        (("192.168.0.10", "255.255.255.255", "0.0.0.0"), "netmask", "no room"),
        (("192.168.0.0", "255.255.255.0", "0.0.0.0"), "ip", "network address"),
        (("192.168.0.255", "255.255.255.0", "0.0.0.0"), "ip", "broadcast address"),
        (("127.0.0.5", "255.0.0.0", "0.0.0.0"), "ip", "not a device address"),
        (("224.0.0.5", "255.255.255.0", "0.0.0.0"), "ip", "not a device address"),
        (("192.168.0.10", "255.255.255.0", "192.168.1.1"), "gateway", "not another host"),
    ],
)
def test_a_bad_ip_suite_is_refused_naming_the_field(
    suite: tuple[str, str, str], field: str, why: str
) -> None:
    with pytest.raises(ValidationError, match=why) as info:
        dcp.check_ip_suite(*suite)
    assert info.value.field == field


def test_good_ip_suites_and_the_deleted_address() -> None:
    assert dcp.check_ip_suite(" 192.168.0.10", "255.255.255.0", "192.168.0.1") == (
        "192.168.0.10",
        "255.255.255.0",
        "192.168.0.1",
    )
    # "No router" written as the device's own address, as engineering tools do.
    assert dcp.check_ip_suite("10.0.0.2", "255.0.0.0", "10.0.0.2")[2] == "10.0.0.2"
    assert dcp.check_ip_suite("0.0.0.0", "0.0.0.0", "0.0.0.0") == ("0.0.0.0",) * 3


def test_mac_addresses() -> None:
    assert dcp.mac_bytes("00-30-11-0A-0B-0C") == DEVICE
    for bad in ("00:30:11:0a:0b", "00:30:11:0a:0b:zz", "01:0e:cf:00:00:00"):
        with pytest.raises(ValidationError) as info:
            dcp.mac_bytes(bad)
        assert info.value.field == "mac"


def test_the_response_delay_spreads_answers_over_half_the_wait() -> None:
    assert dcp.response_delay_factor(1.0) == 50  # up to 0.49 s of 1 s
    assert dcp.response_delay_factor(0.01) == 1
    assert dcp.response_delay_factor(1000) == dcp.RESPONSE_DELAY_FACTOR_MAX
    twin = DcpResponder(_station(), DEVICE)
    frame = dcp.identify_request(TOOL, 1, response_delay=50).encode()
    assert 0 <= twin.response_delay(frame) <= 0.49
    assert twin.response_delay(dcp.identify_request(TOOL, 1).encode()) == 0


def test_the_twin_answers_only_what_is_for_it() -> None:
    twin = DcpResponder(_station(), DEVICE)
    other = bytes.fromhex("0030110a0b0d")
    assert twin.answer(dcp.identify_request(TOOL, 1, name="axis-2").encode()) is None
    assert twin.answer(dcp.identify_request(TOOL, 1, name="axis-1").encode()) is not None
    assert twin.answer(dcp.set_request(other, TOOL, 1, (dcp.signal_block(),)).encode()) is None
    assert twin.answer(b"\x00" * 60) is None
    # Its own answers (a response, not a request) are not answered again.
    answer = twin.answer(dcp.identify_request(TOOL, 1).encode())
    assert answer is not None and twin.answer(answer) is None


def _set(twin: DcpResponder, *blocks: dcp.Block) -> list[dcp.Ack]:
    answer = twin.answer(dcp.set_request(DEVICE, TOOL, 5, blocks).encode())
    assert answer is not None
    packet = dcp.parse(answer)
    assert (packet.service_id, packet.service_type, packet.xid) == (4, 1, 5)
    return dcp.acks(packet)


def test_the_twin_sets_name_and_address_and_refuses_them_in_operation() -> None:
    busy = False
    taken: list[str] = []
    twin = DcpResponder(
        _station(),
        DEVICE,
        busy=lambda: busy,
        on_ip=lambda ip: taken.append(ip) or True,  # type: ignore[func-returns-value]
    )
    acks = _set(twin, dcp.name_block("press-2"), dcp.ip_block("10.0.0.7", "255.0.0.0", "0.0.0.0"))
    assert [(a.option, a.suboption, a.error) for a in acks] == [(2, 2, 0), (1, 2, 0)]
    assert (twin.station.name_of_station, twin.station.ip, taken) == (
        "press-2",
        "10.0.0.7",
        ["10.0.0.7"],
    )
    busy = True
    acks = _set(twin, dcp.name_block("press-3"), dcp.signal_block())
    assert [(a.error, a.meaning) for a in acks] == [
        (6, "in operation, set not possible"),
        (0, "no error"),
    ]
    assert twin.station.name_of_station == "press-2" and twin.station.flashes == 1


def test_the_twin_refuses_what_it_does_not_support() -> None:
    twin = DcpResponder(_station(), DEVICE, on_ip=lambda ip: False)
    acks = _set(
        twin,
        dcp.Block(dcp.OPT_DHCP, 61, b"\x00\x01x"),
        dcp.Block(dcp.OPT_DEVICE, dcp.SUB_ALIAS, b"\x00\x01x"),
        dcp.Block(dcp.OPT_CONTROL, dcp.SUB_RESET_TO_FACTORY, (3 << 1).to_bytes(2, "big")),
        dcp.ip_block("10.0.0.7", "255.0.0.0", "0.0.0.0"),
        dcp.Block(dcp.OPT_DEVICE, dcp.SUB_NAME_OF_STATION, b"\x00\x01Bad_Name"),
    )
    assert [a.error for a in acks] == [1, 2, 2, 5, 5]
    assert twin.station.ip == "192.168.0.10"  # on_ip said no: the address is kept


def test_reset_to_factory_clears_name_and_address() -> None:
    modes: list[int] = []
    twin = DcpResponder(_station(), DEVICE, on_factory=modes.append)
    assert [a.error for a in _set(twin, dcp.reset_to_factory_block(8))] == [0]
    s = twin.station
    assert (s.name_of_station, s.ip, s.netmask, s.gateway, modes) == (
        "",
        "0.0.0.0",
        "0.0.0.0",
        "0.0.0.0",
        [8],
    )
    answer = twin.answer(dcp.identify_request(TOOL, 2).encode())
    assert answer is not None
    dev = dcp.device_from(dcp.parse(answer))
    assert (dev.name_of_station, dev.ip, dev.ip_origin) == ("", "0.0.0.0", "not set")
    with pytest.raises(ValidationError, match=r"mode 3 is not offered: 2 .* or 8"):
        dcp.reset_to_factory_block(3)
