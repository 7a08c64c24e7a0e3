"""PROFINET IO cyclic data: the connect blocks of an IO controller's AR, the control blocks
that bring it to data exchange, and the RT_CLASS_1 frames (pure, no sockets).

An IO controller's AR (ARType IOCARSingle 0001h) is set up by one ``Connect`` carrying the
ARBlockReq, an IOCRBlockReq per direction (input: device -> controller, output: controller
-> device), the AlarmCRBlockReq and the ExpectedSubmoduleBlockReq (IEC 61158-6-10,
ConnectReq). The controller then ends its parameterisation with ``Control`` (opnum 4,
IODControlReq 0110h, ControlCommand PrmEnd); the device answers and, once its application
is ready, calls the controller back (the controller's RPC interface, opnum 4, IOXBlockReq
0112h, ControlCommand ApplicationReady), which the controller answers with Done. From then
on both sides send their IOCR's frame every SendClockFactor x ReductionRatio x 31.25 µs:
Ethertype 8892h, the FrameID of the IOCR, the C_SDU (each submodule's data and its IOPS, the
IOCS of the other direction's submodules, at the offsets the IOCR gives), padded to the
IOCR's DataLength (at least 40 bytes), then CycleCounter (31.25 µs units), DataStatus and
TransferStatus.

The submodules are a PROFIdrive drive's (PROFIdrive V4.1 device model): the access point
(slot 0, subslot 1, no IO data), the drive object's module access point (slot 1, subslot 1,
the parameter access record 0xB02E, no IO data) and its telegram (slot 1, subslot 2: the
setpoint telegram as output, the actual-value telegram as input). Manual 004 prints no
GSDML, so the ident numbers below are servodesk's (its twin checks them): a real LECSN-T's
come from its GSD file (docs/profinet.md "To confirm on a unit").
"""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass

from servodesk.domain import pnio

#: The PNIO controller interface (a device's requests to its controller: ApplicationReady).
CONTROLLER_INTERFACE = uuid.UUID("dea00002-6c97-11d1-8271-00a02442df7d")
OP_CONTROL = 4

#: ARType: IO controller AR (IOCARSingle).
AR_TYPE_IOCAR = 0x0001
#: ARProperties of servodesk's IO AR: State Active (1), ParametrizationServer = CM initiator
#: (bit 4); legacy start-up (bit 30 = 0: the device sends ApplicationReady after PrmEnd).
AR_PROPERTIES_IOCAR = 0x00000011

BLOCK_IOCR_REQ = 0x0102
BLOCK_IOCR_RES = 0x8102
BLOCK_ALARM_CR_REQ = 0x0103
BLOCK_ALARM_CR_RES = 0x8103
BLOCK_EXPECTED_SUBMODULE_REQ = 0x0104
BLOCK_MODULE_DIFF = 0x8104
BLOCK_PRM_END_REQ = 0x0110
BLOCK_PRM_END_RES = 0x8110
BLOCK_APP_READY_REQ = 0x0112
BLOCK_APP_READY_RES = 0x8112

#: ControlCommand bits (IODControlReq): PrmEnd, ApplicationReady, Release, Done.
CONTROL_PRM_END = 0x0001
CONTROL_APPLICATION_READY = 0x0002

IOCR_INPUT = 0x0001
IOCR_OUTPUT = 0x0002
#: IOCRProperties.RTClass: RT_CLASS_1 (frames on Ethernet, FrameID 8000h-BFFFh).
RT_CLASS_1 = 0x1
FRAME_ID_RT_CLASS_1 = range(0x8000, 0xC000)
ETHERTYPE = 0x8892
#: Shortest C_SDU of an RT frame (the Ethernet minimum less the headers and APDU status).
MIN_DATA_LENGTH = 40
#: The send clock unit: SendClockFactor 32 x 31.25 µs = 1 ms.
CLOCK_UNIT_S = 31.25e-6

#: ErrorCode1 of a faulty connect block (ErrorDecode PNIO, ErrorCode DBh); ErrorCode2 is the
#: field number in the block (0 BlockType, 1 BlockLength, 2/3 version, then its fields).
CODE1_IOCR = 0x02
CODE1_EXPECTED_SUBMODULE = 0x03
CODE1_ALARM_CR = 0x04
CODE1_CONTROL = 0x14
IOCR_FIELD = {"type": 4, "reference": 5, "lt": 6, "properties": 7, "data_length": 8,
              "frame_id": 9, "send_clock": 10, "reduction_ratio": 11, "watchdog": 15,
              "data_hold": 16, "apis": 20}  # fmt: skip
#: ErrorCode2 of the ExpectedSubmoduleBlockReq servodesk's twin names: the slot's module
#: ident, a submodule's ident, its data description (length).
EXPECTED_FIELD = {"module_ident": 6, "submodule_ident": 9, "data_length": 12}
#: CMRPC ErrorCode2 04h: the device has no room for the AR (its IO AR is another's).
CMRPC_NO_AR_RESOURCES = 0x04

#: IOxS: DataState good (bit 7), instance 0 (subslot), no extension.
IOXS_GOOD = 0x80
IOXS_BAD = 0x00
#: APDU DataStatus bits: State primary (0), DataValid (2), ProviderState run (4),
#: StationProblemIndicator no problem (5).
DS_PRIMARY = 0x01
DS_VALID = 0x04
DS_RUN = 0x10
DS_NO_PROBLEM = 0x20
DATA_STATUS_OK = DS_PRIMARY | DS_VALID | DS_RUN | DS_NO_PROBLEM  # 35h

#: The PROFIdrive device model's submodules (see the module docstring).
DAP = (0, 1)
MAP = (1, 1)
TELEGRAM = (1, 2)
#: Ident numbers servodesk and its twin use (004 prints no GSDML): the access point, the
#: drive object module and its parameter access point; the telegram submodule's ident is the
#: telegram number (1, 100, 102, 103).
DAP_MODULE_IDENT = 0x00000001
DAP_SUBMODULE_IDENT = 0x00000001
DRIVE_MODULE_IDENT = 0x00000002
MAP_SUBMODULE_IDENT = 0x00000001


def frame_ident_ok(frame_id: int) -> bool:
    return frame_id in FRAME_ID_RT_CLASS_1


# Cycle -----------------------------------------------------------------------------------


def cycle_s(send_clock_factor: int, reduction_ratio: int) -> float:
    """The IOCR's cycle: SendClockFactor x ReductionRatio x 31.25 µs."""
    return send_clock_factor * reduction_ratio * CLOCK_UNIT_S


# Submodules and the frame layout ---------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Submodule:
    slot: int
    subslot: int
    module_ident: int
    ident: int
    #: IO data bytes: input (device -> controller) and output (controller -> device).
    inputs: int = 0
    outputs: int = 0

    @property
    def kind(self) -> int:
        """SubmoduleProperties.Type: 0 no IO, 1 input, 2 output, 3 input and output."""
        return (1 if self.inputs else 0) | (2 if self.outputs else 0)


def drive_submodules(telegram: int, rx_bytes: int, tx_bytes: int) -> list[Submodule]:
    """A PROFIdrive drive with one telegram: rx (setpoint) is the output, tx the input."""
    return [
        Submodule(*DAP, DAP_MODULE_IDENT, DAP_SUBMODULE_IDENT),
        Submodule(*MAP, DRIVE_MODULE_IDENT, MAP_SUBMODULE_IDENT),
        Submodule(*TELEGRAM, DRIVE_MODULE_IDENT, telegram, inputs=tx_bytes, outputs=rx_bytes),
    ]


@dataclass(frozen=True, slots=True)
class FrameLayout:
    """Where each submodule's data, IOPS and IOCS are in one IOCR's C_SDU."""

    #: (slot, subslot, offset of the data, data bytes); the IOPS follows the data.
    data: tuple[tuple[int, int, int, int], ...]
    #: (slot, subslot, offset of the IOCS) of the other direction's submodules.
    iocs: tuple[tuple[int, int, int], ...]
    length: int

    def offset(self, slot: int, subslot: int) -> tuple[int, int]:
        for s, ss, off, n in self.data:
            if (s, ss) == (slot, subslot):
                return off, n
        raise KeyError((slot, subslot))


def layouts(subs: list[Submodule]) -> tuple[FrameLayout, FrameLayout]:
    """(input CR, output CR). The input CR carries every submodule's input data (0 bytes for
    one without IO data: only its IOPS) and the IOCS of the output submodules; the output CR
    the output data and the IOCS of every submodule of the input CR (IEC 61158-6-10)."""

    def build(mine: list[tuple[Submodule, int]], other: list[Submodule]) -> FrameLayout:
        pos = 0
        data = []
        for s, n in mine:
            data.append((s.slot, s.subslot, pos, n))
            pos += n + 1
        iocs = []
        for s in other:
            iocs.append((s.slot, s.subslot, pos))
            pos += 1
        return FrameLayout(tuple(data), tuple(iocs), max(MIN_DATA_LENGTH, pos))

    in_subs = [s for s in subs if s.kind in (0, 1, 3)]
    out_subs = [s for s in subs if s.kind in (2, 3)]
    return (
        build([(s, s.inputs) for s in in_subs], out_subs),
        build([(s, s.outputs) for s in out_subs], in_subs),
    )


# Connect blocks ----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Iocr:
    """One IOCRBlockReq (the fields servodesk sets; the rest are RT_CLASS_1 defaults)."""

    iocr_type: int
    reference: int
    frame_id: int
    layout: FrameLayout
    send_clock_factor: int = 32
    reduction_ratio: int = 1
    watchdog_factor: int = 3
    data_hold_factor: int = 3
    properties: int = RT_CLASS_1
    lt: int = ETHERTYPE
    multicast_mac: bytes = bytes(6)


_IOCR = struct.Struct(">HHHIHHHHHHIHHH6sH")


def iocr_block_req(r: Iocr) -> bytes:
    # Phase 1, Sequence 0, FrameSendOffset "best effort", tag header priority 6, one API.
    head = _IOCR.pack(r.iocr_type, r.reference, r.lt, r.properties, r.layout.length,
                      r.frame_id, r.send_clock_factor, r.reduction_ratio, 1, 0, 0xFFFFFFFF,
                      r.watchdog_factor, r.data_hold_factor, 0xC000, r.multicast_mac,
                      1)  # fmt: skip
    api = struct.pack(">IH", 0, len(r.layout.data))
    api += b"".join(struct.pack(">HHH", s, ss, off) for s, ss, off, _n in r.layout.data)
    api += struct.pack(">H", len(r.layout.iocs))
    api += b"".join(struct.pack(">HHH", s, ss, off) for s, ss, off in r.layout.iocs)
    return pnio.block(BLOCK_IOCR_REQ, head + api)


def parse_iocr_block_req(content: bytes) -> Iocr:
    """The IOCRBlockReq's fields; data lengths of the layout are not in the block (0)."""
    if len(content) < _IOCR.size:
        raise pnio.PnioFrameError("the IOCRBlockReq is shorter than its fixed part")
    f = _IOCR.unpack_from(content)
    pos = _IOCR.size
    data: list[tuple[int, int, int, int]] = []
    iocs: list[tuple[int, int, int]] = []
    try:
        for _api in range(f[15]):
            _api_no, n = struct.unpack_from(">IH", content, pos)
            pos += 6
            for _ in range(n):
                s, ss, off = struct.unpack_from(">HHH", content, pos)
                data.append((s, ss, off, 0))
                pos += 6
            (m,) = struct.unpack_from(">H", content, pos)
            pos += 2
            for _ in range(m):
                iocs.append(struct.unpack_from(">HHH", content, pos))
                pos += 6
    except struct.error:
        raise pnio.PnioFrameError("the IOCRBlockReq's API list is cut short") from None
    return Iocr(
        iocr_type=f[0], reference=f[1], lt=f[2], properties=f[3],
        layout=FrameLayout(tuple(data), tuple(iocs), f[4]), frame_id=f[5],
        send_clock_factor=f[6], reduction_ratio=f[7], watchdog_factor=f[11],
        data_hold_factor=f[12], multicast_mac=f[14],
    )  # fmt: skip


def iocr_block_res(iocr_type: int, reference: int, frame_id: int) -> bytes:
    return pnio.block(BLOCK_IOCR_RES, struct.pack(">HHH", iocr_type, reference, frame_id))


def parse_iocr_block_res(content: bytes) -> tuple[int, int, int]:
    """(IOCRType, IOCRReference, FrameID)."""
    if len(content) < 6:
        raise pnio.PnioFrameError("the IOCRBlockRes is shorter than 6 bytes")
    t, ref, fid = struct.unpack_from(">HHH", content)
    return t, ref, fid


def alarm_cr_block_req(local_reference: int = 3, max_data: int = 200) -> bytes:
    """AlarmCRBlockReq: AlarmCRType 1, RTA_CLASS_1 over 8892h, RTATimeoutFactor 1 (100 ms),
    3 retries, the tag headers of priority 6 (high) and 5 (low)."""
    return pnio.block(
        BLOCK_ALARM_CR_REQ,
        struct.pack(">HHIHHHHHH", 1, ETHERTYPE, 0, 1, 3, local_reference, max_data,
                    0xC000, 0xA000),
    )  # fmt: skip


def parse_alarm_cr_block_req(content: bytes) -> tuple[int, int, int]:
    """(AlarmCRType, LT, LocalAlarmReference)."""
    if len(content) < 20:
        raise pnio.PnioFrameError("the AlarmCRBlockReq is shorter than 20 bytes")
    t, lt, _props, _tf, _retries, ref = struct.unpack_from(">HHIHHH", content)
    return t, lt, ref


def alarm_cr_block_res(local_reference: int, max_data: int = 200) -> bytes:
    return pnio.block(BLOCK_ALARM_CR_RES, struct.pack(">HHH", 1, local_reference, max_data))


def expected_submodule_block_req(subs: list[Submodule]) -> bytes:
    """One ExpectedSubmoduleBlockReq with an API entry per slot (API 0)."""
    slots: dict[int, list[Submodule]] = {}
    for s in subs:
        slots.setdefault(s.slot, []).append(s)
    body = struct.pack(">H", len(slots))
    for slot, members in slots.items():
        body += struct.pack(">IHIHH", 0, slot, members[0].module_ident, 0, len(members))
        for s in members:
            body += struct.pack(">HIH", s.subslot, s.ident, s.kind)
            if s.kind in (0, 1, 3):
                # Input data description; a submodule without IO data describes 0 input bytes.
                body += struct.pack(">HHBB", 1, s.inputs, 1, 1)
            if s.kind in (2, 3):
                body += struct.pack(">HHBB", 2, s.outputs, 1, 1)
    return pnio.block(BLOCK_EXPECTED_SUBMODULE_REQ, body)


def parse_expected_submodule_block_req(content: bytes) -> list[Submodule]:
    out: list[Submodule] = []
    try:
        (n_api,) = struct.unpack_from(">H", content)
        pos = 2
        for _ in range(n_api):
            _api, slot, module, _props, n = struct.unpack_from(">IHIHH", content, pos)
            pos += 14
            for _ in range(n):
                subslot, ident, props = struct.unpack_from(">HIH", content, pos)
                pos += 8
                kind = props & 0x3
                lengths = {1: 0, 2: 0}
                for _d in range(2 if kind == 3 else 1):
                    desc, length, _iocs, _iops = struct.unpack_from(">HHBB", content, pos)
                    pos += 6
                    lengths[desc] = length
                out.append(Submodule(slot, subslot, module, ident, lengths.get(1, 0),
                                     lengths.get(2, 0)))  # fmt: skip
    except struct.error:
        raise pnio.PnioFrameError("the ExpectedSubmoduleBlockReq is cut short") from None
    return out


def control_block(block_type: int, ar_uuid: uuid.UUID, session_key: int, command: int) -> bytes:
    """IODControlReq / IOXBlockReq and their responses (the layout of the release block)."""
    return pnio.release_block(block_type, ar_uuid, session_key, command)


def parse_control_block(content: bytes) -> tuple[uuid.UUID, int, int]:
    """(ARUUID, SessionKey, ControlCommand)."""
    return pnio.parse_release_block(content)


# RT frames ---------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RtFrame:
    dst: bytes
    src: bytes
    frame_id: int
    data: bytes
    cycle_counter: int
    data_status: int
    transfer_status: int = 0


_ETH = struct.Struct(">6s6sHH")


def build_rt(f: RtFrame) -> bytes:
    return (
        _ETH.pack(f.dst, f.src, ETHERTYPE, f.frame_id)
        + f.data
        + struct.pack(">HBB", f.cycle_counter & 0xFFFF, f.data_status, f.transfer_status)
    )


def parse_rt(frame: bytes, data_length: int) -> RtFrame | None:
    """An RT frame of an IOCR whose C_SDU is ``data_length`` bytes; None for any other
    frame (another Ethertype or VLAN-tagged frame, too short)."""
    pos = 12
    (etype,) = struct.unpack_from(">H", frame, pos) if len(frame) >= 14 else (0,)
    if etype == 0x8100 and len(frame) >= 18:  # priority tag (IEC 61158-6-10: VLAN 0, prio 6)
        pos += 4
        (etype,) = struct.unpack_from(">H", frame, pos)
    if etype != ETHERTYPE or len(frame) < pos + 4 + data_length + 4:
        return None
    (frame_id,) = struct.unpack_from(">H", frame, pos + 2)
    start = pos + 4
    data = frame[start : start + data_length]
    cc, ds, ts = struct.unpack_from(">HBB", frame, start + data_length)
    return RtFrame(frame[0:6], frame[6:12], frame_id, bytes(data), cc, ds, ts)


def pack_c_sdu(layout: FrameLayout, data: dict[tuple[int, int], bytes], iops: int,
               iocs: int) -> bytes:  # fmt: skip
    """A C_SDU: each submodule's data (zeros where ``data`` has none) and IOPS, the IOCS."""
    out = bytearray(layout.length)
    for s, ss, off, n in layout.data:
        out[off : off + n] = data.get((s, ss), b"")[:n].ljust(n, b"\0")
        out[off + n] = iops
    for _s, _ss, off in layout.iocs:
        out[off] = iocs
    return bytes(out)
