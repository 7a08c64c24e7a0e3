"""EtherCAT frames, datagrams, the SII EEPROM image and the CoE mailbox (pure, no sockets).

What the simulated EtherCAT slave (:mod:`servodesk.sim.ethercat_slave`) and its tests need of
ETG.1000.4 (data link layer), ETG.1000.6 (application layer: AL state machine, mailbox, CoE)
and ETG.2010 (SII), with the register names of the Beckhoff ESC datasheet (section II).

An EtherCAT frame is an Ethernet II frame of EtherType 88A4h whose payload is::

    EtherCAT header (2: length 11 bits, reserved 1 bit, type 4 bits = 1)
    datagram ... datagram

and each datagram (ETG.1000.4 §5.4.1.2)::

    cmd (1) | idx (1) | address (4: ADP + ADO, or a logical address)
    | len (2: length 11 bits, reserved 3, C circulating 1, M more datagrams follow 1)
    | IRQ (2) | data (len) | working counter (2)

A mailbox (ETG.1000.4 §5.6 / ETG.1000.6 §5.6)::

    length (2: after this header) | address (2) | channel 6 bits + priority 2 bits (1)
    | type 4 bits + counter 3 bits + reserved 1 bit (1) | service data

CoE (type 3) service data: the CoE header (2: number 9 bits, reserved 3, service 4 bits),
then for SDO services a CiA 301 SDO command byte, index (2), sub-index (1) and 4 data bytes;
a normal (non-expedited) transfer carries the complete size in those 4 bytes and the data
after them (ETG.1000.6 §5.6.2).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from servodesk.errors import ValidationError

#: EtherType of EtherCAT frames (ETG.1000.4 §5.3.1).
ETHERTYPE = 0x88A4
#: EtherCAT header type 1: the frame carries EtherCAT datagrams (DLPDU).
FRAME_TYPE_DATAGRAMS = 1
BROADCAST_MAC = b"\xff" * 6


class Cmd(IntEnum):
    """Datagram commands (ETG.1000.4 table 12)."""

    NOP = 0
    APRD = 1  # auto-increment physical read
    APWR = 2
    APRW = 3
    FPRD = 4  # configured-address physical read
    FPWR = 5
    FPRW = 6
    BRD = 7  # broadcast read
    BWR = 8
    BRW = 9
    LRD = 10  # logical read (through the FMMUs)
    LWR = 11
    LRW = 12
    ARMW = 13  # auto-increment read, multiple write
    FRMW = 14  # configured-address read, multiple write


class Reg(IntEnum):
    """ESC registers servodesk's slave keeps (ESC datasheet section II, table 1)."""

    TYPE = 0x0000  # Type
    REVISION = 0x0001  # Revision
    BUILD = 0x0002  # Build (2)
    FMMUS = 0x0004  # FMMUs supported
    SYNCMANAGERS = 0x0005  # SyncManagers supported
    RAM_SIZE = 0x0006  # RAM size (KByte)
    PORT_DESCRIPTOR = 0x0007  # Port descriptor
    FEATURES = 0x0008  # ESC features supported (2)
    STATION_ADDRESS = 0x0010  # Configured station address (2)
    STATION_ALIAS = 0x0012  # Configured station alias (2)
    DL_CONTROL = 0x0100  # DL control (4)
    DL_STATUS = 0x0110  # DL status (2)
    AL_CONTROL = 0x0120  # AL control (2)
    AL_STATUS = 0x0130  # AL status (2)
    AL_STATUS_CODE = 0x0134  # AL status code (2)
    PDI_CONTROL = 0x0140  # PDI control
    WATCHDOG_DIVIDER = 0x0400  # watchdog divider (2): units of 40 ns, + 2
    WATCHDOG_PROCESS_DATA = 0x0420  # SyncManager watchdog time (2), in divider units
    EEPROM_CONFIG = 0x0500  # EEPROM configuration
    EEPROM_PDI_ACCESS = 0x0501  # EEPROM PDI access state
    EEPROM_CONTROL = 0x0502  # EEPROM control/status (2)
    EEPROM_ADDRESS = 0x0504  # EEPROM address (4, in words)
    EEPROM_DATA = 0x0508  # EEPROM data (8)
    FMMU0 = 0x0600  # FMMU 0..15, 16 bytes each
    SM0 = 0x0800  # SyncManager 0..15, 8 bytes each
    DC_RECEIVE_TIME = 0x0900  # receive time port 0..3 (4 each); a write latches them
    DC_SYSTEM_TIME = 0x0910  # system time (8): local time + offset; written: drift control
    DC_RECEIVE_TIME_PU = 0x0918  # receive time of the processing unit (8)
    DC_SYSTEM_TIME_OFFSET = 0x0920  # system time offset (8)
    DC_SYSTEM_TIME_DELAY = 0x0928  # system time delay (4)
    DC_CYCLIC_UNIT_CONTROL = 0x0980  # cyclic unit control
    DC_ACTIVATION = 0x0981  # bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1
    DC_START_TIME = 0x0990  # start time of cyclic operation (8)
    DC_SYNC0_CYCLE = 0x09A0  # SYNC0 cycle time (4, ns)


#: ESC features (0x0008) bit 2: distributed clocks; bit 3: 64-bit DC.
FEATURE_DC = 0x0004
FEATURE_DC64 = 0x0008
#: DC activation (0x0981): cyclic operation with SYNC0, the only mode servodesk's slaves take.
DC_ACTIVATE_SYNC0 = 0x03


#: SyncManager register layout (ESC datasheet 0x0800+8n): start (2), length (2), control,
#: status, activate, PDI control.
SM_SIZE = 8
SM_STATUS = 5
SM_ACTIVATE = 6
SM_PDI_CONTROL = 7
#: SM status bit 3: mailbox full (ESC datasheet, register 0x0805+8n).
SM_STATUS_MAILBOX_FULL = 0x08
#: SM activate bit 0: enable; bit 1: repeat request (mailbox).
SM_ACTIVATE_ENABLE = 0x01
SM_ACTIVATE_REPEAT = 0x02

#: EEPROM control/status (0x0502): command bits 8..10, read size bit 6, busy bit 15.
EEPROM_CMD_MASK = 0x0700
EEPROM_CMD_READ = 0x0100
EEPROM_CMD_WRITE = 0x0200
EEPROM_CMD_RELOAD = 0x0400
EEPROM_READ_8_BYTES = 0x0040
EEPROM_BUSY = 0x8000
EEPROM_ERROR_COMMAND = 0x0800  # Checksum error / command error (bit 11..14 error bits)
EEPROM_ERROR_NACK = 0x2000


class AlState(IntEnum):
    """AL states (ETG.1000.6 §6.4.1, AL control / AL status bits 0..3)."""

    INIT = 0x01
    PREOP = 0x02
    BOOT = 0x03
    SAFEOP = 0x04
    OP = 0x08


#: AL control bit 4: error acknowledge; AL status bit 4: error indication.
AL_ACK = 0x10
AL_ERROR = 0x10

#: AL status codes this slave reports (ETG.1000.6 table 11).
AL_STATUS_CODES: dict[int, str] = {
    0x0000: "No error",
    0x0011: "Invalid requested state change",
    0x0012: "Unknown requested state",
    0x0013: "Bootstrap not supported",
    0x0016: "Invalid mailbox configuration",
}


class MailboxType(IntEnum):
    """Mailbox types (ETG.1000.4 table 29)."""

    ERROR = 0x00
    AOE = 0x01
    EOE = 0x02
    COE = 0x03
    FOE = 0x04
    SOE = 0x05
    VOE = 0x0F


#: Mailbox error reply codes (ETG.1000.4 table 30).
MBXERR_SYNTAX = 0x0001
MBXERR_UNSUPPORTED_PROTOCOL = 0x0002
MBXERR_SERVICE_NOT_SUPPORTED = 0x0004
MBXERR_INVALID_HEADER = 0x0005
MBXERR_SIZE_TOO_SHORT = 0x0006


class CoeService(IntEnum):
    """CoE header services (ETG.1000.6 table 29)."""

    EMERGENCY = 0x01
    SDO_REQUEST = 0x02
    SDO_RESPONSE = 0x03
    TXPDO = 0x04
    RXPDO = 0x05
    SDO_INFO = 0x08


#: SDO command bytes (CiA 301 §7.2.4.3, as CoE carries them, ETG.1000.6 §5.6.2).
SDO_DOWNLOAD_EXPEDITED = 0x23  # ccs 1, e, s; n in bits 2-3
SDO_DOWNLOAD_NORMAL = 0x21  # ccs 1, s; complete size and data follow
SDO_DOWNLOAD_RESPONSE = 0x60  # scs 3
SDO_DOWNLOAD_SEGMENT_RESPONSE = 0x20  # scs 1, toggle in bit 4
SDO_UPLOAD_REQUEST = 0x40  # ccs 2
SDO_UPLOAD_SEGMENT_REQUEST = 0x60  # ccs 3, toggle in bit 4
SDO_UPLOAD_EXPEDITED = 0x43  # scs 2, e, s; n in bits 2-3
SDO_UPLOAD_NORMAL = 0x41  # scs 2, s
SDO_ABORT = 0x80
SDO_COMPLETE_ACCESS = 0x10  # bit 4 of an initiate request
SDO_TOGGLE = 0x10
SDO_LAST_SEGMENT = 0x01
#: Bytes of the SDO part after the CoE header in an initiate: command, index, sub, 4 data.
SDO_HEADER = 8
#: Mailbox header (6) + CoE header (2) + command/index/sub (4) + size (4) before normal data.
NORMAL_DATA_OFFSET = 16
#: A segment: mailbox header (6) + CoE header (2) + command (1) before the data.
SEGMENT_DATA_OFFSET = 9
#: Least segment data: a segment is padded to 7 data bytes (CiA 301 segment layout).
SEGMENT_MIN_DATA = 7


@dataclass(frozen=True)
class OdEntryInfo:
    """One sub-index as a slave's SDO Information describes it (Get Entry Description,
    ETG.1000.6 §5.6.3.6): its name, CoE data type, bit length and object access (bits 0-2
    readable in PRE-OP / SAFE-OP / OP, 3-5 writable, 6 RxPDO-, 7 TxPDO-mappable, 8 backup,
    9 settings)."""

    subindex: int
    name: str
    data_type: int
    bit_length: int
    access: int


@dataclass(frozen=True)
class OdObjectInfo:
    """One index of a slave's object list (Get OD List, Get Object Description, ETG.1000.6
    §5.6.3.3-5): object code 7 VAR, 8 ARRAY, 9 RECORD, and its sub-indices' descriptions
    (a VAR's is sub-index 0)."""

    index: int
    name: str
    object_code: int
    data_type: int
    entries: tuple[OdEntryInfo, ...]


class EthercatFrameError(ValueError):
    """Bytes that are no EtherCAT frame, datagram or mailbox this module understands."""


_ETH = struct.Struct("!6s6sH")
_DGRAM = struct.Struct("<BBIHH")  # cmd, idx, address, len+flags, irq
_MBX = struct.Struct("<HHBB")
_SDO = struct.Struct("<HBHB")  # CoE header, command, index, sub-index


@dataclass(slots=True)
class Datagram:
    """One EtherCAT datagram; ``address`` is ADP (low 16 bits) + ADO (high 16 bits) for
    physical commands, a 32-bit logical address for LRD/LWR/LRW."""

    cmd: int
    idx: int
    address: int
    data: bytes
    wkc: int = 0
    irq: int = 0
    circulating: bool = False

    @property
    def adp(self) -> int:
        return self.address & 0xFFFF

    @property
    def ado(self) -> int:
        return (self.address >> 16) & 0xFFFF

    @staticmethod
    def physical(cmd: int, idx: int, adp: int, ado: int, data: bytes, wkc: int = 0) -> Datagram:
        return Datagram(cmd, idx, (adp & 0xFFFF) | (ado & 0xFFFF) << 16, data, wkc)


def parse_ethernet(frame: bytes) -> tuple[bytes, bytes, bytes]:
    """(destination MAC, source MAC, EtherCAT payload) of an Ethernet II EtherCAT frame."""
    if len(frame) < _ETH.size:
        raise EthercatFrameError(f"{len(frame)} bytes are no Ethernet frame")
    dst, src, ethertype = _ETH.unpack_from(frame)
    if ethertype != ETHERTYPE:
        raise EthercatFrameError(f"EtherType {ethertype:04X}h is not EtherCAT ({ETHERTYPE:04X}h)")
    return dst, src, frame[_ETH.size :]


def build_ethernet(dst: bytes, src: bytes, payload: bytes) -> bytes:
    return _ETH.pack(dst, src, ETHERTYPE) + payload


def parse_datagrams(payload: bytes) -> list[Datagram]:
    """The datagrams of an EtherCAT payload (after the Ethernet header), in order.

    The EtherCAT header's length covers the datagrams; Ethernet padding after them is
    ignored. The M bit of each datagram says whether another follows (ETG.1000.4 §5.4.1.2).
    """
    if len(payload) < 2:
        raise EthercatFrameError("no EtherCAT header")
    header = int.from_bytes(payload[:2], "little")
    length, ftype = header & 0x07FF, header >> 12
    if ftype != FRAME_TYPE_DATAGRAMS:
        raise EthercatFrameError(f"EtherCAT frame type {ftype} carries no datagrams")
    if length > len(payload) - 2:
        raise EthercatFrameError(f"EtherCAT header says {length} bytes, {len(payload) - 2} follow")
    body = payload[2 : 2 + length]
    out: list[Datagram] = []
    pos = 0
    while True:
        if pos + _DGRAM.size + 2 > len(body):
            raise EthercatFrameError(f"datagram {len(out) + 1} is cut short")
        cmd, idx, address, lenflags, irq = _DGRAM.unpack_from(body, pos)
        n = lenflags & 0x07FF
        start = pos + _DGRAM.size
        end = start + n
        if end + 2 > len(body):
            raise EthercatFrameError(f"datagram {len(out) + 1} says {n} data bytes; fewer follow")
        wkc = int.from_bytes(body[end : end + 2], "little")
        out.append(
            Datagram(cmd, idx, address, bytes(body[start:end]), wkc, irq, bool(lenflags & 0x4000))
        )
        pos = end + 2
        if not lenflags & 0x8000:
            return out


def build_datagrams(datagrams: list[Datagram]) -> bytes:
    """An EtherCAT payload (header and datagrams, no Ethernet header) of ``datagrams``."""
    if not datagrams:
        raise EthercatFrameError("a frame carries at least one datagram")
    parts: list[bytes] = []
    for i, d in enumerate(datagrams):
        if len(d.data) > 0x07FF:
            raise EthercatFrameError(f"{len(d.data)} data bytes do not fit one datagram")
        lenflags = len(d.data) | (0x4000 if d.circulating else 0)
        if i < len(datagrams) - 1:
            lenflags |= 0x8000
        parts.append(_DGRAM.pack(d.cmd, d.idx, d.address, lenflags, d.irq))
        parts.append(d.data)
        parts.append((d.wkc & 0xFFFF).to_bytes(2, "little"))
    body = b"".join(parts)
    if len(body) > 0x07FF:
        raise EthercatFrameError(f"{len(body)} bytes of datagrams do not fit one frame")
    return (len(body) | FRAME_TYPE_DATAGRAMS << 12).to_bytes(2, "little") + body


# Mailbox and CoE ------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Mailbox:
    """A mailbox message: its type, counter (1..7; 0 = not used) and service data."""

    type: int
    data: bytes
    counter: int = 0
    address: int = 0
    channel: int = 0
    priority: int = 0


def build_mailbox(mbx: Mailbox, size: int | None = None) -> bytes:
    """The mailbox bytes, padded with zeros to ``size`` (the SyncManager's length)."""
    head = _MBX.pack(
        len(mbx.data),
        mbx.address,
        (mbx.channel & 0x3F) | (mbx.priority & 0x03) << 6,
        (mbx.type & 0x0F) | (mbx.counter & 0x07) << 4,
    )
    raw = head + mbx.data
    if size is not None:
        if len(raw) > size:
            raise EthercatFrameError(f"{len(raw)} mailbox bytes do not fit {size}")
        raw = raw.ljust(size, b"\x00")
    return raw


def parse_mailbox(raw: bytes) -> Mailbox:
    """The message in a mailbox buffer (its length field says where it ends)."""
    if len(raw) < _MBX.size:
        raise EthercatFrameError(f"{len(raw)} bytes are no mailbox header")
    length, address, chprio, typecnt = _MBX.unpack_from(raw)
    if _MBX.size + length > len(raw):
        raise EthercatFrameError(f"mailbox length {length} exceeds the {len(raw)}-byte buffer")
    return Mailbox(
        typecnt & 0x0F,
        bytes(raw[_MBX.size : _MBX.size + length]),
        (typecnt >> 4) & 0x07,
        address,
        chprio & 0x3F,
        chprio >> 6,
    )


def mailbox_error(detail: int, counter: int = 0) -> Mailbox:
    """A mailbox error reply (type 0): type 01h (command) and the detail (ETG.1000.4 §5.6)."""
    return Mailbox(MailboxType.ERROR, struct.pack("<HH", 0x0001, detail), counter)


@dataclass(frozen=True, slots=True)
class Sdo:
    """A CoE SDO message: CoE service, SDO command byte, index, sub-index, and the bytes
    after the sub-index (4 bytes in an initiate: data or complete size, then more data)."""

    service: int
    command: int
    index: int
    subindex: int
    payload: bytes = b"\x00\x00\x00\x00"


def coe_service(data: bytes) -> int:
    """The CoE service of a CoE mailbox's data (ETG.1000.6 §5.6.1)."""
    if len(data) < 2:
        raise EthercatFrameError("no CoE header")
    return int.from_bytes(data[:2], "little") >> 12


def build_sdo(sdo: Sdo) -> bytes:
    return _SDO.pack(sdo.service << 12, sdo.command, sdo.index, sdo.subindex) + sdo.payload


def parse_sdo(data: bytes) -> Sdo:
    """An SDO initiate message (CoE header, command, index, sub-index, the rest)."""
    if len(data) < _SDO.size:
        raise EthercatFrameError(f"{len(data)} bytes are no CoE SDO message")
    coe, command, index, sub = _SDO.unpack_from(data)
    return Sdo(coe >> 12, command, index, sub, bytes(data[_SDO.size :]))


def sdo_segment(command: int, data: bytes) -> bytes:
    """A CoE SDO segment (CoE header, command, data): ``data`` shorter than 7 bytes is
    padded to 7 and the unused count set in bits 1-3 (CiA 301 §7.2.4.3.4)."""
    if len(data) < SEGMENT_MIN_DATA:
        command |= (SEGMENT_MIN_DATA - len(data)) << 1
        data = data.ljust(SEGMENT_MIN_DATA, b"\x00")
    return (CoeService.SDO_RESPONSE << 12).to_bytes(2, "little") + bytes([command]) + data


def sdo_abort(index: int, subindex: int, code: int) -> Sdo:
    """An SDO abort: sent with the CoE service SDO request (ETG.1000.6 §5.6.2.7), which is
    what SOEM's ecx_SDOread / ecx_SDOwrite recognise (``Command == ECT_SDO_ABORT`` outside an
    SDO response)."""
    return Sdo(CoeService.SDO_REQUEST, SDO_ABORT, index, subindex, code.to_bytes(4, "little"))


# SII EEPROM -----------------------------------------------------------------------------

#: SII word addresses (ETG.2010 table 2).
SII_VENDOR = 0x0008
SII_PRODUCT = 0x000A
SII_REVISION = 0x000C
SII_SERIAL = 0x000E
SII_RX_MAILBOX = 0x0018  # standard receive (master -> slave) mailbox offset, size
SII_TX_MAILBOX = 0x001A  # standard send (slave -> master) mailbox offset, size
SII_MAILBOX_PROTOCOL = 0x001C
SII_SIZE = 0x003E
SII_VERSION = 0x003F
SII_CATEGORIES = 0x0040
#: Category types (ETG.2010 table 3).
CAT_STRINGS = 10
CAT_GENERAL = 30
CAT_SYNCM = 41
CAT_END = 0xFFFF
#: Mailbox protocols word: bit 2 = CoE.
MBXPROTO_COE = 0x0004
#: General category CoE details: bit 0 = SDO supported, bit 1 = SDO Information, bit 5 =
#: SDO complete access.
COE_DETAILS_SDO = 0x01
COE_DETAILS_SDO_INFO = 0x02
COE_DETAILS_COMPLETE_ACCESS = 0x20
#: SyncManager types in the SyncM category.
SM_TYPE_MAILBOX_OUT = 1
SM_TYPE_MAILBOX_IN = 2
SM_TYPE_OUTPUTS = 3
SM_TYPE_INPUTS = 4
#: SM control bytes SOEM programs for mailboxes (ethercatconfig.c EC_DEFAULTMBXSM0/1):
#: mailbox mode, ECAT writes (SM0) / reads (SM1), ECAT and PDI interrupts.
SM_CONTROL_MAILBOX_OUT = 0x26
SM_CONTROL_MAILBOX_IN = 0x22
#: Process data SyncManagers: buffered (3-buffer) mode, ECAT writes SM2 (outputs) and reads
#: SM3 (inputs), with the PDI interrupt (the ESI ControlByte most slaves give: 64h / 20h).
SM_CONTROL_OUTPUTS = 0x64
SM_CONTROL_INPUTS = 0x20


def crc8_sii(data: bytes) -> int:
    """The checksum of the SII configuration area (words 0-6): CRC-8, polynomial
    x^8 + x^2 + x + 1 (07h), initial value FFh (ETG.2010 §2.1)."""
    crc = 0xFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


@dataclass(frozen=True, slots=True)
class SiiInfo:
    """What a slave's SII says of it."""

    vendor_id: int
    product_code: int
    revision: int
    serial: int
    name: str
    mailbox_out: tuple[int, int] = (0x1000, 128)  # SM0: offset, size (master -> slave)
    mailbox_in: tuple[int, int] = (0x1080, 128)  # SM1: offset, size (slave -> master)
    #: SM2 / SM3 start addresses of the process data (their lengths come from the PDO
    #: assignment the master reads over CoE, 1C12h / 1C13h); None: no process data.
    outputs_start: int | None = 0x1100
    inputs_start: int | None = 0x1400
    #: The SYNC0 cycle times the slave takes (min, max, step; ns), as its ESI's DC element
    #: offers them (not part of the SII image); None: no distributed clocks.
    dc_cycle_ns: tuple[int, int, int] | None = None
    #: The General category's CoE details (ETG.2010 table 5): what the master may use.
    coe_details: int = COE_DETAILS_SDO


def _u32(v: int, what: str) -> bytes:
    if not 0 <= v <= 0xFFFFFFFF:
        raise ValidationError(f"{what} {v} is outside 0..0xFFFFFFFF", field=what)
    return v.to_bytes(4, "little")


def sii_image(info: SiiInfo) -> bytes:
    """The SII EEPROM contents (ETG.2010): the configuration area with its checksum, the
    identity, the mailbox offsets and sizes, CoE as the mailbox protocol, then the Strings
    (the device name is string 1), General and SyncM categories and the end marker."""
    name = info.name.encode("ascii", "replace")[:255]
    head = bytearray(0x80)
    # Words 0-6: PDI control, PDI configuration, sync impulse, PDI configuration 2, alias,
    # reserved: all 0 for this slave. Word 7: the checksum of words 0-6.
    head[14] = crc8_sii(bytes(head[:14]))
    head[SII_VENDOR * 2 : SII_VENDOR * 2 + 4] = _u32(info.vendor_id, "vendor_id")
    head[SII_PRODUCT * 2 : SII_PRODUCT * 2 + 4] = _u32(info.product_code, "product_code")
    head[SII_REVISION * 2 : SII_REVISION * 2 + 4] = _u32(info.revision, "revision")
    head[SII_SERIAL * 2 : SII_SERIAL * 2 + 4] = _u32(info.serial, "serial")
    out_off, out_size = info.mailbox_out
    in_off, in_size = info.mailbox_in
    struct.pack_into(
        "<HHHHH", head, SII_RX_MAILBOX * 2, out_off, out_size, in_off, in_size, MBXPROTO_COE
    )
    struct.pack_into("<H", head, SII_VERSION * 2, 1)

    def category(kind: int, data: bytes) -> bytes:
        if len(data) % 2:
            data += b"\x00"
        return struct.pack("<HH", kind, len(data) // 2) + data

    strings = bytes([1, len(name)]) + name
    general = bytearray(32)
    general[3] = 1  # Name: string 1
    general[5] = info.coe_details
    syncm = struct.pack(
        "<HHBBBBHHBBBB",
        out_off,
        out_size,
        SM_CONTROL_MAILBOX_OUT,
        0,
        SM_ACTIVATE_ENABLE,
        SM_TYPE_MAILBOX_OUT,
        in_off,
        in_size,
        SM_CONTROL_MAILBOX_IN,
        0,
        SM_ACTIVATE_ENABLE,
        SM_TYPE_MAILBOX_IN,
    )
    if info.outputs_start is not None and info.inputs_start is not None:
        # SM2 / SM3 with length 0: the master sizes them from the PDO assignment (ETG.2010
        # SyncM category; SOEM's ecx_map_sm takes their start, control and enable from here).
        syncm += struct.pack(
            "<HHBBBBHHBBBB",
            info.outputs_start,
            0,
            SM_CONTROL_OUTPUTS,
            0,
            SM_ACTIVATE_ENABLE,
            SM_TYPE_OUTPUTS,
            info.inputs_start,
            0,
            SM_CONTROL_INPUTS,
            0,
            SM_ACTIVATE_ENABLE,
            SM_TYPE_INPUTS,
        )
    body = (
        category(CAT_STRINGS, strings)
        + category(CAT_GENERAL, bytes(general))
        + category(CAT_SYNCM, syncm)
        + struct.pack("<H", CAT_END)
    )
    image = bytearray(head + body)
    kbit = max(1, -(-len(image) * 8 // 1024))
    struct.pack_into("<H", image, SII_SIZE * 2, kbit - 1)  # size in KBit - 1 (ETG.2010)
    return bytes(image)
