"""Simulated EtherCAT slaves on a network interface: CoE object access to SimulatedDrives.

:class:`EthercatSlaveSim` opens a raw AF_PACKET socket for EtherType 88A4h on one interface
(the slave end of a veth pair, :mod:`servodesk.sim.veth`) and, in a thread, answers every
EtherCAT frame that arrives as a line of slaves would: each datagram of the frame, in order,
passes slave 1, slave 2, ... (:class:`EscSlave`), which read or write their ESC memory and
count the working counter, and the frame goes back out. Each slave serves one
:class:`~servodesk.sim.engine.SimulatedDrive`.

What is emulated is what SOEM's ``ecx_config_init`` and its CoE SDO services use
(docs/ethercat.md): the ESC registers (type, station address, DL status, AL control/status,
EEPROM interface, FMMU and SyncManager registers), the SII EEPROM built from the drive's
identity object 1018h and device name 1008h, the AL states INIT and PRE-OPERATIONAL, and the
CoE mailbox on SM0 (master -> slave) / SM1 (slave -> master) with SDO upload and download,
expedited, normal and segmented, and SDO abort with the drive's CiA 301 abort code. There is
no process data (no FMMU mapping, logical datagrams count no slave), no distributed clocks,
and SAFE-OPERATIONAL, OPERATIONAL and BOOTSTRAP are refused with an AL status code.
"""

from __future__ import annotations

import errno
import logging
import socket
import struct
import threading
from collections import deque
from collections.abc import Sequence

from servodesk.domain import ethercat as ec
from servodesk.domain.ethercat import AlState, Cmd, Reg
from servodesk.errors import LinkError
from servodesk.sim.engine import SimAbort, SimulatedDrive

log = logging.getLogger(__name__)

#: ESC type this slave reports: the ET1100 (11h), whose register map it follows.
ESC_TYPE = 0x11
#: RAM size in KByte, FMMUs and SyncManagers reported in 0x0004-0x0006.
FMMUS, SYNCMANAGERS, RAM_KB = 3, 4, 8
#: Port descriptor (0x0007): ports 0 and 1 MII (11b), 2 and 3 not implemented.
PORT_DESCRIPTOR = 0x0F
#: PDI control (0x0140): 05h, SPI slave (the PDI is this process, not a microcontroller).
PDI_TYPE = 0x05
#: Default mailbox offsets and sizes (SII words 18h-1Bh).
MAILBOX_OUT = (0x1000, 128)
MAILBOX_IN = (0x1080, 128)

_READ = {Cmd.APRD, Cmd.FPRD, Cmd.BRD}
_WRITE = {Cmd.APWR, Cmd.FPWR, Cmd.BWR}
_READWRITE = {Cmd.APRW, Cmd.FPRW, Cmd.BRW}
_AUTO = {Cmd.APRD, Cmd.APWR, Cmd.APRW, Cmd.ARMW}
_CONFIGURED = {Cmd.FPRD, Cmd.FPWR, Cmd.FPRW, Cmd.FRMW}
_BROADCAST = {Cmd.BRD, Cmd.BWR, Cmd.BRW}

#: Registers the master cannot write (ESC datasheet: read-only for ECAT).
_READ_ONLY = frozenset(
    [
        *range(0x0000, 0x0010),  # Type .. ESC features
        0x0110,  # DL status
        0x0111,
        *range(0x0130, 0x0136),  # AL status, AL status code
        *[0x0800 + 8 * n + ec.SM_STATUS for n in range(16)],  # SM status
        *[0x0800 + 8 * n + ec.SM_PDI_CONTROL for n in range(16)],  # SM PDI control
    ]
)


def _or(a: bytes, b: bytes) -> bytes:
    return bytes(x | y for x, y in zip(a, b, strict=True))


def _sii_from_drive(drive: SimulatedDrive, mailbox_size: int) -> ec.SiiInfo:
    """The SII identity of a drive: what its 1018h and 1008h read (0 / the profile name
    where the drive has none)."""

    def u32(index: int, sub: int) -> int:
        try:
            return int.from_bytes(drive.read_bytes(index, sub)[:4], "little")
        except SimAbort:
            return 0

    try:
        name = drive.read_bytes(0x1008, 0).decode("ascii", "replace").rstrip("\x00")
    except SimAbort:
        name = drive.profile.name
    return ec.SiiInfo(
        vendor_id=u32(0x1018, 1),
        product_code=u32(0x1018, 2),
        revision=u32(0x1018, 3),
        serial=u32(0x1018, 4),
        name=name,
        mailbox_out=(MAILBOX_OUT[0], mailbox_size),
        mailbox_in=(MAILBOX_OUT[0] + mailbox_size, mailbox_size),
    )


class EscSlave:
    """One slave: ESC memory, SII EEPROM, AL state machine and the CoE mailbox of a drive."""

    def __init__(
        self, drive: SimulatedDrive, *, last: bool = True, mailbox_size: int = MAILBOX_OUT[1]
    ) -> None:
        if not 32 <= mailbox_size <= 1024:
            raise ValueError(f"mailbox size {mailbox_size} is outside 32..1024")
        self.drive = drive
        self.sii = _sii_from_drive(drive, mailbox_size)
        self.eeprom = bytearray(ec.sii_image(self.sii))
        self.mem = bytearray(0x10000)
        m = self.mem
        m[Reg.TYPE] = ESC_TYPE
        m[Reg.FMMUS], m[Reg.SYNCMANAGERS], m[Reg.RAM_SIZE] = FMMUS, SYNCMANAGERS, RAM_KB
        m[Reg.PORT_DESCRIPTOR] = PORT_DESCRIPTOR
        # ESC features (0x0008): no distributed clocks (bit 2 clear), so SOEM sets hasdc 0.
        # DL status (0x0110): PDI operational (bit 0), link on port 0 (bit 4) with
        # communication (bits 8-9 = 10b: loop open, communication established); port 1 the
        # same when another slave follows, else closed (loop, bits 10-11 = 01b); ports 2 and
        # 3 closed. SOEM counts the open ports for the topology (ecx_config_init).
        dl = 0x0001 | 0x0010 | 0x0200 | 0x1000 | 0x4000
        dl |= 0x0400 if last else 0x0020 | 0x0800
        struct.pack_into("<H", m, Reg.DL_STATUS, dl)
        m[Reg.PDI_CONTROL] = PDI_TYPE
        self._set_al(AlState.INIT, 0)
        #: Mailbox responses waiting for SM1 (the oldest is in SM1 while it is full).
        self._outbox: deque[bytes] = deque()
        self._last_response: bytes | None = None
        self._counter = 0
        #: A segmented download in progress: index, sub, size, bytes so far, next toggle.
        self._download: tuple[int, int, int, bytearray, int] | None = None
        #: A segmented upload in progress: index, sub, bytes left, next toggle.
        self._upload: tuple[int, int, bytes, int] | None = None
        #: Mailbox requests answered (tests).
        self.mailbox_requests = 0

    # ESC memory ---------------------------------------------------------------------

    @property
    def station_address(self) -> int:
        return int(struct.unpack_from("<H", self.mem, Reg.STATION_ADDRESS)[0])

    @property
    def al_state(self) -> int:
        return self.mem[Reg.AL_STATUS] & 0x0F

    @property
    def al_status_code(self) -> int:
        return int(struct.unpack_from("<H", self.mem, Reg.AL_STATUS_CODE)[0])

    def _sm(self, n: int) -> tuple[int, int, bool]:
        """SyncManager ``n``: start, length, enabled."""
        base = Reg.SM0 + ec.SM_SIZE * n
        start, length = struct.unpack_from("<HH", self.mem, base)
        return start, length, bool(self.mem[base + ec.SM_ACTIVATE] & ec.SM_ACTIVATE_ENABLE)

    def _mailbox_on(self) -> bool:
        """The mailbox SMs work from PRE-OPERATIONAL on (ETG.1000.6 §6.4.1: INIT has no
        mailbox communication)."""
        return self.al_state != AlState.INIT

    def read(self, ado: int, n: int) -> bytes | None:
        """``n`` bytes from ``ado``; None when the access is refused (no working counter):
        the SM1 mailbox read while it is empty, as the ESC's SyncManager blocks it."""
        end = ado + n
        if end > len(self.mem):
            return None
        s1, l1, on1 = self._sm(1)
        in_mailbox = on1 and l1 and ado < s1 + l1 and end > s1
        sm1_status = Reg.SM0 + ec.SM_SIZE + ec.SM_STATUS
        if in_mailbox and not self.mem[sm1_status] & ec.SM_STATUS_MAILBOX_FULL:
            return None
        data = bytes(self.mem[ado:end])
        if in_mailbox and end >= s1 + l1:
            # Reading the buffer's last byte frees it (ESC datasheet, mailbox mode).
            self.mem[sm1_status] &= ~ec.SM_STATUS_MAILBOX_FULL & 0xFF
            self._next_response()
        return data

    def write(self, ado: int, data: bytes) -> bool:
        """Write ``data`` at ``ado``; False when refused (no working counter)."""
        end = ado + len(data)
        if end > len(self.mem):
            return False
        s0, l0, on0 = self._sm(0)
        if on0 and l0 and ado < s0 + l0 and end > s0:
            if not self._mailbox_on():
                return False  # The SM is deactivated in INIT: the ESC refuses the write.
            self.mem[ado:end] = data
            if end >= s0 + l0:  # The last byte written: the mailbox is full, process it.
                self._mailbox(bytes(self.mem[s0 : s0 + l0]))
            return True
        kept = {a: self.mem[a] for a in _READ_ONLY if ado <= a < end}
        old_repeat = self.mem[Reg.SM0 + ec.SM_SIZE + ec.SM_ACTIVATE] & ec.SM_ACTIVATE_REPEAT
        self.mem[ado:end] = data
        for a, v in kept.items():
            self.mem[a] = v
        if ado <= Reg.AL_CONTROL < end:
            self._al_control(self.mem[Reg.AL_CONTROL])
        if ado <= Reg.EEPROM_CONTROL + 1 and end > Reg.EEPROM_CONTROL:
            self._eeprom_command()
        if ado < Reg.SM0 + 2 * ec.SM_SIZE and end > Reg.SM0:
            self._sm_changed(old_repeat)
        return True

    # AL state machine (ETG.1000.6 §6.4) -----------------------------------------------

    def _set_al(self, state: int, code: int) -> None:
        struct.pack_into("<H", self.mem, Reg.AL_STATUS, state | (ec.AL_ERROR if code else 0))
        struct.pack_into("<H", self.mem, Reg.AL_STATUS_CODE, code)

    def _al_control(self, control: int) -> None:
        requested, ack = control & 0x0F, control & ec.AL_ACK
        state = self.al_state
        if self.mem[Reg.AL_STATUS] & ec.AL_ERROR and not ack:
            return  # An error indication stays until the master acknowledges it.
        if requested == AlState.INIT:
            self._set_al(AlState.INIT, 0)
            self._reset_mailbox()
        elif requested == AlState.PREOP:
            if self._mailbox_config_ok():
                self._set_al(AlState.PREOP, 0)
            else:
                self._set_al(state, 0x0016)  # Invalid mailbox configuration
        elif requested == AlState.BOOT:
            self._set_al(state, 0x0013)  # Bootstrap not supported
        elif requested in (AlState.SAFEOP, AlState.OP):
            # No process data: SAFE-OP needs SM2/SM3 and the FMMUs mapped (ETG.1000.6).
            self._set_al(state, 0x0011)  # Invalid requested state change
        elif requested == 0 and ack:
            self._set_al(state, 0)  # Acknowledge only: the error indication is cleared.
        else:
            self._set_al(state, 0x0012)  # Unknown requested state

    def _mailbox_config_ok(self) -> bool:
        s0, l0, on0 = self._sm(0)
        s1, l1, on1 = self._sm(1)
        return (
            on0
            and on1
            and (s0, l0) == self.sii.mailbox_out
            and (s1, l1) == self.sii.mailbox_in
            and self.mem[Reg.SM0 + 4] & 0x0C == 0x04  # SM0: ECAT writes
            and self.mem[Reg.SM0 + ec.SM_SIZE + 4] & 0x0C == 0x00  # SM1: ECAT reads
        )

    # EEPROM interface (ESC 0x0500-0x050F) ----------------------------------------------

    def _eeprom_command(self) -> None:
        control = int(struct.unpack_from("<H", self.mem, Reg.EEPROM_CONTROL)[0])
        command = control & ec.EEPROM_CMD_MASK
        word = int(struct.unpack_from("<I", self.mem, Reg.EEPROM_ADDRESS)[0])
        status = 0
        if command == ec.EEPROM_CMD_READ:
            # 4 bytes from the word address (bit 6 of the status clear: 4-byte reads).
            chunk = bytes(self.eeprom[word * 2 : word * 2 + 4]).ljust(4, b"\xff")
            self.mem[Reg.EEPROM_DATA : Reg.EEPROM_DATA + 4] = chunk
        elif command == ec.EEPROM_CMD_WRITE:
            if word * 2 + 2 <= len(self.eeprom):
                self.eeprom[word * 2 : word * 2 + 2] = self.mem[
                    Reg.EEPROM_DATA : Reg.EEPROM_DATA + 2
                ]
            else:
                status = ec.EEPROM_ERROR_NACK  # No such word: the EEPROM does not acknowledge.
        elif command not in (0, ec.EEPROM_CMD_RELOAD):
            status = ec.EEPROM_ERROR_COMMAND
        # The command bits clear when it is done, and never busy: done at once.
        struct.pack_into("<H", self.mem, Reg.EEPROM_CONTROL, status)

    # SyncManagers and the mailbox -------------------------------------------------------

    def _sm_changed(self, old_repeat: int) -> None:
        sm1 = Reg.SM0 + ec.SM_SIZE
        if not self.mem[sm1 + ec.SM_ACTIVATE] & ec.SM_ACTIVATE_ENABLE:
            self._reset_mailbox()
            return
        repeat = self.mem[sm1 + ec.SM_ACTIVATE] & ec.SM_ACTIVATE_REPEAT
        if repeat != old_repeat:
            # Repeat request (SM1 activate bit 1): the last response is put back in the
            # buffer, and the PDI acknowledges with bit 1 of 0x080F (ESC datasheet).
            if self._last_response is not None:
                self._load(self._last_response)
            self.mem[sm1 + ec.SM_PDI_CONTROL] = (
                self.mem[sm1 + ec.SM_PDI_CONTROL] & ~ec.SM_ACTIVATE_REPEAT & 0xFF
            ) | repeat

    def _reset_mailbox(self) -> None:
        self._outbox.clear()
        self._download = self._upload = None
        self.mem[Reg.SM0 + ec.SM_SIZE + ec.SM_STATUS] &= ~ec.SM_STATUS_MAILBOX_FULL & 0xFF

    def _load(self, raw: bytes) -> None:
        s1, l1, _ = self._sm(1)
        self.mem[s1 : s1 + l1] = raw[:l1].ljust(l1, b"\x00")
        self.mem[Reg.SM0 + ec.SM_SIZE + ec.SM_STATUS] |= ec.SM_STATUS_MAILBOX_FULL

    def _next_response(self) -> None:
        if self._outbox:
            self._last_response = self._outbox.popleft()
            self._load(self._last_response)

    def _reply(self, mbx: ec.Mailbox) -> None:
        self._counter = self._counter % 7 + 1  # Counter 1..7 (0 is "not used").
        _, l1, _ = self._sm(1)
        raw = ec.build_mailbox(
            ec.Mailbox(mbx.type, mbx.data, self._counter, mbx.address, mbx.channel), l1
        )
        full = self.mem[Reg.SM0 + ec.SM_SIZE + ec.SM_STATUS] & ec.SM_STATUS_MAILBOX_FULL
        if full:
            self._outbox.append(raw)
        else:
            self._last_response = raw
            self._load(raw)

    def _mailbox(self, raw: bytes) -> None:
        self.mailbox_requests += 1
        try:
            mbx = ec.parse_mailbox(raw)
        except ec.EthercatFrameError:
            self._reply(ec.mailbox_error(ec.MBXERR_INVALID_HEADER))
            return
        if mbx.type != ec.MailboxType.COE:
            self._reply(ec.mailbox_error(ec.MBXERR_UNSUPPORTED_PROTOCOL))
            return
        try:
            service = ec.coe_service(mbx.data)
        except ec.EthercatFrameError:
            self._reply(ec.mailbox_error(ec.MBXERR_SIZE_TOO_SHORT))
            return
        if service != ec.CoeService.SDO_REQUEST:
            self._reply(ec.mailbox_error(ec.MBXERR_SERVICE_NOT_SUPPORTED))
            return
        answer = self._sdo(mbx.data)
        if answer is not None:
            self._reply(ec.Mailbox(ec.MailboxType.COE, answer))

    # CoE SDO server (ETG.1000.6 §5.6.2) ---------------------------------------------------

    def _sdo(self, data: bytes) -> bytes | None:
        if len(data) < 3:
            return None
        command = data[2]
        ccs = command >> 5
        if ccs == 0:  # Download segment
            return self._download_segment(data)
        if ccs == 3:  # Upload segment
            return self._upload_segment(command)
        if ccs == 4:  # Abort from the master: drop any transfer in progress.
            self._download = self._upload = None
            return None
        if len(data) < 2 + ec.SDO_HEADER:
            return ec.build_sdo(ec.sdo_abort(0, 0, 0x05040001))
        sdo = ec.parse_sdo(data)
        self._download = self._upload = None
        try:
            if command & ec.SDO_COMPLETE_ACCESS:
                # Complete access is not offered (SII General CoE details bit 5 clear).
                raise SimAbort(0x06010000, "complete access is not supported")
            if ccs == 1:
                return self._download_initiate(sdo)
            if ccs == 2:
                return self._upload_initiate(sdo)
            raise SimAbort(0x05040001)
        except SimAbort as exc:
            return ec.build_sdo(ec.sdo_abort(sdo.index, sdo.subindex, exc.code))
        except Exception:  # A simulation bug must not stop the slave: a general error.
            log.exception("SDO %04X:%02X failed", sdo.index, sdo.subindex)
            return ec.build_sdo(ec.sdo_abort(sdo.index, sdo.subindex, 0x08000000))

    def _response(self, command: int, index: int, sub: int, payload: bytes = b"") -> bytes:
        sdo = ec.Sdo(ec.CoeService.SDO_RESPONSE, command, index, sub, payload.ljust(4, b"\x00"))
        return ec.build_sdo(sdo)

    def _download_initiate(self, sdo: ec.Sdo) -> bytes:
        if sdo.command & 0x02:  # Expedited: the data is in the 4 bytes (n unused if s).
            n = 4 - ((sdo.command >> 2) & 0x03) if sdo.command & 0x01 else 4
            self.drive.write_bytes(sdo.index, sdo.subindex, sdo.payload[:n])
            return self._response(ec.SDO_DOWNLOAD_RESPONSE, sdo.index, sdo.subindex)
        if len(sdo.payload) < 4:
            raise SimAbort(0x05040001, "no complete size")
        size = int.from_bytes(sdo.payload[:4], "little")
        first = sdo.payload[4:]
        if len(first) >= size:
            self.drive.write_bytes(sdo.index, sdo.subindex, first[:size])
        else:
            self.drive.check_download(sdo.index, sdo.subindex)
            self._download = (sdo.index, sdo.subindex, size, bytearray(first), 0)
        return self._response(ec.SDO_DOWNLOAD_RESPONSE, sdo.index, sdo.subindex)

    def _download_segment(self, data: bytes) -> bytes | None:
        if self._download is None:
            return ec.build_sdo(ec.sdo_abort(0, 0, 0x05040001))
        index, sub, size, buf, toggle = self._download
        command = data[2]
        if command & ec.SDO_TOGGLE != toggle:
            self._download = None
            return ec.build_sdo(ec.sdo_abort(index, sub, 0x05030000))
        seg = data[3:]
        if len(seg) == ec.SEGMENT_MIN_DATA:  # Padded: bits 1-3 say how many are unused.
            seg = seg[: ec.SEGMENT_MIN_DATA - ((command >> 1) & 0x07)]
        buf += seg
        if not command & ec.SDO_LAST_SEGMENT:
            self._download = (index, sub, size, buf, toggle ^ ec.SDO_TOGGLE)
            return self._segment_ack(toggle)
        self._download = None
        try:
            if len(buf) != size:
                raise SimAbort(0x06070010, f"{len(buf)} bytes sent, {size} announced")
            self.drive.write_bytes(index, sub, bytes(buf))
        except SimAbort as exc:
            return ec.build_sdo(ec.sdo_abort(index, sub, exc.code))
        return self._segment_ack(toggle)

    @staticmethod
    def _segment_ack(toggle: int) -> bytes:
        head = (ec.CoeService.SDO_RESPONSE << 12).to_bytes(2, "little")
        return head + bytes([ec.SDO_DOWNLOAD_SEGMENT_RESPONSE | toggle]) + bytes(7)

    def _upload_initiate(self, sdo: ec.Sdo) -> bytes:
        value = self.drive.read_bytes(sdo.index, sdo.subindex)
        if len(value) <= 4:
            command = ec.SDO_UPLOAD_EXPEDITED | ((4 - len(value)) << 2)
            return self._response(command, sdo.index, sdo.subindex, value)
        _, l1, _ = self._sm(1)
        room = l1 - ec.NORMAL_DATA_OFFSET
        size = len(value).to_bytes(4, "little")
        if len(value) > room:
            # Segmented: the first part in the initiate response, the rest on request.
            self._upload = (sdo.index, sdo.subindex, value[room:], 0)
            value = value[:room]
        return self._response(ec.SDO_UPLOAD_NORMAL, sdo.index, sdo.subindex, size + value)

    def _upload_segment(self, command: int) -> bytes:
        if self._upload is None:
            return ec.build_sdo(ec.sdo_abort(0, 0, 0x05040001))
        index, sub, rest, toggle = self._upload
        if command & ec.SDO_TOGGLE != toggle:
            self._upload = None
            return ec.build_sdo(ec.sdo_abort(index, sub, 0x05030000))
        _, l1, _ = self._sm(1)
        room = l1 - ec.SEGMENT_DATA_OFFSET
        part, rest = rest[:room], rest[room:]
        last = not rest
        self._upload = None if last else (index, sub, rest, toggle ^ ec.SDO_TOGGLE)
        return ec.sdo_segment(toggle | (ec.SDO_LAST_SEGMENT if last else 0), part)


class EthercatSlaveSim:
    """Slaves in a line on ``ifname``: ``start()`` opens the socket and serves frames."""

    def __init__(
        self, drives: Sequence[SimulatedDrive], ifname: str, *, mailbox_size: int = 128
    ) -> None:
        if not drives:
            raise ValueError("an EtherCAT line needs at least one slave")
        self.ifname = ifname
        self.slaves = [
            EscSlave(d, last=i == len(drives) - 1, mailbox_size=mailbox_size)
            for i, d in enumerate(drives)
        ]
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        #: Frames answered and dropped (tests and logs).
        self.frames = 0
        self.dropped = 0

    @property
    def drives(self) -> list[SimulatedDrive]:
        return [s.drive for s in self.slaves]

    def start(self) -> EthercatSlaveSim:
        """Open the raw socket; LinkError when the interface is missing or not permitted."""
        try:
            sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ec.ETHERTYPE))
        except PermissionError as exc:
            raise LinkError(
                f"cannot open a raw socket for EtherCAT on {self.ifname}: {exc}",
                hint="the simulated EtherCAT slave needs root or CAP_NET_RAW",
            ) from exc
        try:
            sock.bind((self.ifname, ec.ETHERTYPE))
        except OSError as exc:
            sock.close()
            if exc.errno == errno.ENODEV:
                raise LinkError(
                    f"no network interface {self.ifname!r}",
                    hint="give the slave end of a veth pair (servodesk.sim.veth) or a NIC",
                ) from exc
            raise LinkError(f"cannot bind to {self.ifname!r}: {exc}") from exc
        sock.settimeout(0.05)  # Wake up this often to see whether to stop.
        self._sock = sock
        self._thread = threading.Thread(target=self._serve, name="ethercat-slave", daemon=True)
        self._thread.start()
        log.info("EtherCAT slaves on %s: %d", self.ifname, len(self.slaves))
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> EthercatSlaveSim:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _serve(self) -> None:
        sock = self._sock
        assert sock is not None
        while not self._stop.is_set():
            try:
                frame, addr = sock.recvfrom(2048)
            except TimeoutError:
                continue
            except OSError as exc:
                if self._stop.is_set() or exc.errno in (errno.EBADF, errno.ENODEV, errno.ENXIO):
                    if not self._stop.is_set():
                        log.warning("EtherCAT slaves on %s stop: %s", self.ifname, exc)
                    return
                # The link is down for a moment (ENETDOWN): a cable pulled, not an end.
                log.debug("EtherCAT slaves on %s: %s", self.ifname, exc)
                self._stop.wait(0.1)
                continue
            if addr[2] == socket.PACKET_OUTGOING:
                continue
            answer = self.process(frame)
            if answer is None:
                self.dropped += 1
                continue
            try:
                sock.send(answer)
                self.frames += 1
            except OSError as exc:
                log.warning("EtherCAT slave on %s cannot send: %s", self.ifname, exc)

    def process(self, frame: bytes) -> bytes | None:
        """The frame as it comes back from the end of the line, or None when it is no
        EtherCAT frame (dropped, as an ESC drops it)."""
        try:
            dst, src, payload = ec.parse_ethernet(frame)
            datagrams = ec.parse_datagrams(payload)
        except ec.EthercatFrameError:
            return None
        for d in datagrams:
            self.datagram(d)
        # The ESC at port 0 sets bit 1 of the source MAC's first byte (the locally
        # administered bit) in frames it sends back (ESC datasheet, frame processing).
        src = bytes([src[0] | 0x02]) + src[1:]
        return ec.build_ethernet(dst, src, ec.build_datagrams(datagrams))

    def datagram(self, d: ec.Datagram) -> None:
        """Pass one datagram along the line: each slave reads, writes and counts."""
        cmd = d.cmd
        if cmd in (Cmd.NOP, Cmd.LRD, Cmd.LWR, Cmd.LRW) or cmd > Cmd.FRMW:
            return  # No FMMU maps logical addresses: no slave is addressed.
        adp, ado = d.adp, d.ado
        data = d.data
        wkc = d.wkc
        n = len(data)
        armw_source = False
        for slave in self.slaves:
            if cmd in _AUTO:
                hit = adp == 0
                adp = (adp + 1) & 0xFFFF  # Each slave increments ADP (ETG.1000.4 §5.4.1.2).
            elif cmd in _CONFIGURED:
                hit = adp == slave.station_address
            else:  # Broadcast: every slave, and each increments ADP.
                hit = True
                adp = (adp + 1) & 0xFFFF
            if cmd in (Cmd.ARMW, Cmd.FRMW):
                if hit:
                    got = slave.read(ado, n)
                    if got is not None:
                        data, wkc, armw_source = got, wkc + 1, True
                elif armw_source and slave.write(ado, data):
                    wkc += 1
                continue
            if not hit:
                continue
            if cmd in _READ:
                got = slave.read(ado, n)
                if got is not None:
                    # BRD: the data is the OR of every slave's (ESC datasheet, commands).
                    data = (
                        bytes(a | b for a, b in zip(data, got, strict=True))
                        if cmd == Cmd.BRD
                        else got
                    )
                    wkc += 1
            elif cmd in _WRITE:
                if slave.write(ado, data):
                    wkc += 1
            elif cmd in _READWRITE:
                got = slave.read(ado, n)
                if got is not None:
                    wkc += 1
                if slave.write(ado, data):
                    wkc += 2
                if got is not None:
                    data = (
                        bytes(a | b for a, b in zip(data, got, strict=True))
                        if cmd == Cmd.BRW
                        else got
                    )
        d.data = data
        d.wkc = wkc & 0xFFFF
        if cmd in _AUTO or cmd in _BROADCAST:
            d.address = adp | ado << 16
