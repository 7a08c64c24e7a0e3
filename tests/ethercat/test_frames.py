"""EtherCAT frames, datagrams, mailboxes, CoE SDO messages and the SII image, byte for byte
(ETG.1000.4 §5.4, ETG.1000.6 §5.6, ETG.2010), and the simulated slaves' answers to frames."""

from __future__ import annotations

import struct

import pytest

from servodesk.domain import ethercat as ec
from servodesk.domain.ethercat import Cmd, Datagram
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.ethercat_slave import EthercatSlaveSim

H = bytes.fromhex


def test_one_datagram_frame() -> None:
    d = Datagram.physical(Cmd.FPRD, 0x05, 0x1001, 0x0130, b"\x00\x00")
    raw = ec.build_datagrams([d])
    # Header: 14 bytes of datagrams, type 1; FPRD idx 5 ADP 1001h ADO 0130h len 2.
    assert raw == H("0e100405011030010200000000000000")
    (back,) = ec.parse_datagrams(raw)
    assert (back.cmd, back.idx, back.adp, back.ado, back.data, back.wkc) == (
        4,
        5,
        0x1001,
        0x0130,
        b"\x00\x00",
        0,
    )


def test_two_datagrams_carry_the_more_bit_and_ethernet_padding_is_ignored() -> None:
    first = Datagram.physical(Cmd.BRD, 1, 0, 0x0000, b"\x00\x00")
    second = Datagram.physical(Cmd.APWR, 2, 0xFFFF, 0x0010, b"\x01\x10", wkc=1)
    raw = ec.build_datagrams([first, second])
    assert raw == H("1c1007010000000002800000000000000202ffff10000200000001100100")
    frame = ec.build_ethernet(ec.BROADCAST_MAC, H("010101010101"), raw) + bytes(20)
    assert frame[:14] == H("ffffffffffff01010101010188a4")
    dst, src, payload = ec.parse_ethernet(frame)
    assert (dst, src) == (ec.BROADCAST_MAC, H("010101010101"))
    got = ec.parse_datagrams(payload)
    assert [(g.cmd, g.adp, g.ado, g.data, g.wkc) for g in got] == [
        (7, 0, 0, b"\x00\x00", 0),
        (2, 0xFFFF, 0x0010, b"\x01\x10", 1),
    ]


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        (H("0e20" + "00" * 14), "frame type 2"),
        (H("2010" + "00" * 14), "says 32 bytes"),
        (H("0e100405011030010500000000000000"), "says 5 data bytes"),
        (H("0e"), "no EtherCAT header"),
    ],
)
def test_bad_frames_are_refused(raw: bytes, message: str) -> None:
    with pytest.raises(ec.EthercatFrameError, match=message):
        ec.parse_datagrams(raw)


def test_other_ethertypes_are_refused() -> None:
    with pytest.raises(ec.EthercatFrameError, match="0800h is not EtherCAT"):
        ec.parse_ethernet(H("ffffffffffff0101010101010800") + bytes(46))


def test_mailbox_and_coe_sdo_messages() -> None:
    upload = ec.build_sdo(ec.Sdo(ec.CoeService.SDO_REQUEST, ec.SDO_UPLOAD_REQUEST, 0x1008, 0))
    assert upload == H("00204008100000000000")
    mbx = ec.build_mailbox(ec.Mailbox(ec.MailboxType.COE, upload, counter=2), size=20)
    # Length 10, address 0, channel/priority 0, type 3 + counter 2 << 4; padded to 20.
    assert mbx == H("0a0000000023") + upload + bytes(4)
    back = ec.parse_mailbox(mbx)
    assert (back.type, back.counter, back.data) == (3, 2, upload)
    assert ec.coe_service(back.data) == ec.CoeService.SDO_REQUEST
    sdo = ec.parse_sdo(back.data)
    assert (sdo.command, sdo.index, sdo.subindex) == (0x40, 0x1008, 0)

    # An abort travels as an SDO request (ETG.1000.6 §5.6.2.7), the code little-endian.
    assert ec.build_sdo(ec.sdo_abort(0x6041, 0, 0x06010002)) == H("00208041600002000106")
    # A last segment of 2 bytes, toggle set: padded to 7, 5 unused in bits 1-3.
    assert ec.sdo_segment(0x10 | 0x01, b"ab") == H("00301b61620000000000")
    assert ec.sdo_segment(0x00, b"abcdefgh") == H("0030006162636465666768")
    assert ec.build_mailbox(ec.mailbox_error(ec.MBXERR_UNSUPPORTED_PROTOCOL)) == H(
        "04000000000001000200"
    )
    with pytest.raises(ec.EthercatFrameError, match="exceeds"):
        ec.parse_mailbox(H("200000000003") + bytes(4))


def test_sii_image_layout() -> None:
    info = ec.SiiInfo(0x0000AAAA, 0x00000005, 0x00010002, 0x12345678, "AB")
    img = ec.sii_image(info)
    assert img[14] == ec.crc8_sii(img[:14])  # Word 7: the checksum of words 0-6
    assert img[0x10:0x20] == H("aaaa0000050000000200010078563412")
    # Standard mailboxes: receive 1000h / 128, send 1080h / 128; protocols: CoE.
    assert img[0x30:0x3A] == H("00108000801080000400")
    assert img[0x7E:0x80] == H("0100")  # SII version 1
    assert img[0x80:0x88] == H("0a00020001024142")  # Strings: 1 string, "AB"
    general = img[0x88 : 0x88 + 4 + 32]
    assert general[:4] == H("1e001000")
    assert general[4 + 3] == 1 and general[4 + 5] == ec.COE_DETAILS_SDO  # Name 1; SDO
    syncm = img[0xAC : 0xAC + 4 + 32]
    # SM0 / SM1 the mailboxes; SM2 / SM3 the process data at 1100h / 1400h, length 0 (the
    # master sizes them from 1C12h / 1C13h), control 64h / 20h, types 3 / 4.
    assert syncm == H("290010000010800026000101801080002200010200110000640001030014000020000104")
    assert img[0xD0:] == H("ffff")
    assert struct.unpack_from("<H", img, 0x7C)[0] == 1  # 210 bytes: 2 KBit - 1
    # A slave without process data offers the mailbox SMs only.
    bare = ec.sii_image(ec.SiiInfo(1, 2, 3, 4, "AB", outputs_start=None, inputs_start=None))
    assert bare[0xAC : 0xAC + 4 + 16] == H("2900080000108000260001018010800022000102")


def test_crc8_of_the_configuration_area() -> None:
    # CRC-8, polynomial x^8 + x^2 + x + 1, initial value FFh, not reflected (ETG.2010): the
    # initial value XORs into the first byte, and the CRC is the remainder of M(x) * x^8
    # divided by the polynomial, computed here by long division of integers.
    def reference(data: bytes) -> int:
        if not data:
            return 0xFF
        value = int.from_bytes(bytes([data[0] ^ 0xFF]) + data[1:], "big") << 8
        for i in range(value.bit_length() - 1, 7, -1):
            if value >> i & 1:
                value ^= 0x107 << (i - 8)
        return value

    for data in (b"", b"\x00" * 14, b"123456789", bytes(range(14))):
        assert ec.crc8_sii(data) == reference(data)
    assert ec.crc8_sii(b"123456789") == 0xFB


# The simulated slaves, frame by frame (no socket) -------------------------------------


@pytest.fixture(scope="module")
def line() -> EthercatSlaveSim:
    cat = ProfileCatalog()
    drives = [SimulatedDrive(cat.get("hiwin-e"), n, 100 + n) for n in (1, 2)]
    return EthercatSlaveSim(drives, "unused")


def _one(line: EthercatSlaveSim, d: Datagram) -> Datagram:
    frame = ec.build_ethernet(ec.BROADCAST_MAC, H("010101010101"), ec.build_datagrams([d]))
    out = line.process(frame)
    assert out is not None
    assert out[6] == 0x03  # The locally administered bit of the source MAC is set.
    (back,) = ec.parse_datagrams(ec.parse_ethernet(out)[2])
    return back


def test_position_broadcast_and_configured_addressing(line: EthercatSlaveSim) -> None:
    # BRD: both slaves answer (working counter 2), each increments ADP.
    got = _one(line, Datagram.physical(Cmd.BRD, 1, 0, ec.Reg.TYPE, b"\x00"))
    assert (got.data, got.wkc, got.adp) == (b"\x11", 2, 2)
    # APRD ADP -1 (FFFFh) reaches the second slave: DL status says its port 1 is closed.
    got = _one(line, Datagram.physical(Cmd.APRD, 2, 0xFFFF, ec.Reg.DL_STATUS, bytes(2)))
    assert got.wkc == 1 and got.adp == 1
    assert struct.unpack("<H", got.data)[0] & 0x0F00 == 0x0600  # port 0 open, port 1 closed
    got = _one(line, Datagram.physical(Cmd.APRD, 3, 0, ec.Reg.DL_STATUS, bytes(2)))
    assert struct.unpack("<H", got.data)[0] & 0x0F00 == 0x0A00  # ports 0 and 1 open
    # APWR the station address of slave 2, then FPRD its AL status at that address.
    got = _one(line, Datagram.physical(Cmd.APWR, 4, 0xFFFF, ec.Reg.STATION_ADDRESS, H("0210")))
    assert got.wkc == 1
    got = _one(line, Datagram.physical(Cmd.FPRD, 5, 0x1002, ec.Reg.AL_STATUS, bytes(6)))
    assert (got.data, got.wkc) == (H("010000000000"), 1)  # INIT, no status code
    got = _one(line, Datagram.physical(Cmd.FPRD, 6, 0x1003, ec.Reg.AL_STATUS, bytes(2)))
    assert got.wkc == 0  # Nobody has that address.
    # FPRW: read (1) and write (2); the answer carries the old value.
    got = _one(line, Datagram.physical(Cmd.FPRW, 7, 0x1002, 0x0F80, H("abcd")))
    assert (got.data, got.wkc) == (bytes(2), 3)
    # The type register is read-only for the master.
    _one(line, Datagram.physical(Cmd.BWR, 8, 0, ec.Reg.TYPE, b"\x99"))
    assert _one(line, Datagram.physical(Cmd.BRD, 9, 0, ec.Reg.TYPE, b"\x00")).data == b"\x11"
    # Logical commands map through FMMUs, which this slave has not: nobody counts.
    assert _one(line, Datagram(Cmd.LRD, 10, 0x10000, bytes(4))).wkc == 0


def test_al_state_machine_refuses_what_it_does_not_support(line: EthercatSlaveSim) -> None:
    slave = line.slaves[1]
    fp = 0x1002
    # Its own address, whichever test of the module's shared line ran before.
    _one(line, Datagram.physical(Cmd.APWR, 0, 0xFFFF, ec.Reg.STATION_ADDRESS, H("0210")))
    assert slave.station_address == fp

    def control(value: int) -> None:
        _one(line, Datagram.physical(Cmd.FPWR, 1, fp, ec.Reg.AL_CONTROL, struct.pack("<H", value)))

    control(0x0002)  # PRE-OP without the mailbox SyncManagers programmed.
    assert (slave.al_state, slave.al_status_code) == (1, 0x0016)
    control(0x0004)  # Without acknowledging the error: nothing changes.
    assert slave.al_status_code == 0x0016
    control(0x0011)  # INIT + acknowledge
    assert (slave.al_state, slave.al_status_code) == (1, 0)
    sm = H("00108000260001008010800022000100")
    _one(line, Datagram.physical(Cmd.FPWR, 2, fp, ec.Reg.SM0, sm))
    control(0x0002)
    assert (slave.al_state, slave.al_status_code) == (2, 0)
    control(0x0008)  # OP straight from PRE-OP: through SAFE-OP only (ETG.1000.6 §6.4.1).
    assert (slave.al_state, slave.al_status_code) == (2, 0x0011)
    status = _one(line, Datagram.physical(Cmd.FPRD, 3, fp, ec.Reg.AL_STATUS, bytes(6))).data
    assert status == H("120000001100")  # PRE-OP with the error flag, code 0011h
    control(0x0013)  # BOOT, acknowledging the last error
    assert (slave.al_state, slave.al_status_code) == (2, 0x0013)
    control(0x0012)
    assert (slave.al_state, slave.al_status_code) == (2, 0)
    # SM2 enabled at another address than the SII's 1100h: invalid output configuration.
    _one(line, Datagram.physical(Cmd.FPWR, 4, fp, ec.Reg.SM0 + 16, H("00120400640001ff")))
    control(0x0004)
    assert (slave.al_state, slave.al_status_code) == (2, 0x001D)
    _one(line, Datagram.physical(Cmd.FPWR, 5, fp, ec.Reg.SM0 + 16, H("0011040064000000")))
    control(0x0014)  # SAFE-OP, acknowledging: SM2 off, nothing mapped, accepted.
    assert (slave.al_state, slave.al_status_code) == (4, 0)
    control(0x0008)
    assert (slave.al_state, slave.al_status_code) == (8, 0)
    control(0x0002)  # Back to PRE-OP.
    assert (slave.al_state, slave.al_status_code) == (2, 0)


def test_process_data_through_the_fmmus(line: EthercatSlaveSim) -> None:
    # What SOEM's config_map programs for a slave with 2 output and 2 input bytes: SM2 at
    # 1100h, SM3 at 1400h, FMMU0 logical 10000h -> 1100h (write), FMMU1 10002h -> 1400h (read).
    slave = line.slaves[0]
    # The second slave gets an address of its own (the module's line is shared: without it,
    # both slaves answer station address 0 when this test runs first, and both get FMMUs).
    _one(line, Datagram.physical(Cmd.APWR, 0, 0xFFFF, ec.Reg.STATION_ADDRESS, H("0210")))
    fp = slave.station_address
    seen: list[bytes | None] = []
    before = slave.on_cycle
    slave.on_cycle = seen.append
    try:
        sms = H("00110200640001000014020020000100")
        _one(line, Datagram.physical(Cmd.FPWR, 1, fp, ec.Reg.SM0 + 16, sms))
        fmmus = H("0000010002000007001100020100000002000100020000070014000101000000")
        _one(line, Datagram.physical(Cmd.FPWR, 2, fp, ec.Reg.FMMU0, fmmus))
        slave.set_inputs(b"\x34\x12\xff")  # cut to SM3's two bytes
        back = _one(line, Datagram(Cmd.LRW, 3, 0x10000, H("cdab0000")))
        # Read (inputs) counts 1, write (outputs) 2; the other slave has no FMMU.
        assert back.wkc == 3
        assert back.data == H("cdab3412")
        assert bytes(slave.mem[0x1100:0x1102]) == H("cdab")
        assert seen == [None]  # Not OP: the outputs are not handed to the firmware.
        assert _one(line, Datagram(Cmd.LRD, 4, 0x10002, bytes(2))).data == H("3412")
        assert _one(line, Datagram(Cmd.LWR, 5, 0x10000, H("0102"))).wkc == 1
        assert _one(line, Datagram(Cmd.LRD, 6, 0x20000, bytes(2))).wkc == 0  # unmapped
    finally:
        slave.on_cycle = before
        _one(line, Datagram.physical(Cmd.FPWR, 7, fp, ec.Reg.FMMU0, bytes(32)))


def test_frames_that_are_no_ethercat_are_dropped(line: EthercatSlaveSim) -> None:
    assert line.process(H("ffffffffffff0101010101010800") + bytes(46)) is None
    assert line.process(H("ffffffffffff01010101010188a40e20") + bytes(14)) is None
