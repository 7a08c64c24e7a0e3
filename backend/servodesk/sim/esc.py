"""The ESC side of simulated EtherCAT slaves: registers, SII, AL states, mailbox and process
data.

An :class:`EscSlave` is what the EtherCAT slave controller of a drive answers on the wire
(ESC datasheet section II register names; ETG.1000.4 / ETG.1000.6 / ETG.2010): its memory
with the registers SOEM's ``ecx_config_init`` uses, the distributed clocks' system time and
SYNC0 registers (``ecx_configdc``, ``ecx_dcsync0``; the SYNC0 cycle checked at SAFE-OP), the
EEPROM interface to an SII image,
the AL state machine (INIT, PRE-OPERATIONAL, SAFE-OPERATIONAL, OPERATIONAL; BOOT refused with
an AL status code), the mailbox on SM0 (master -> slave) / SM1 (slave -> master) and the
process data on SM2 (outputs) / SM3 (inputs), reached by logical datagrams (LRD / LWR / LRW)
through the FMMUs the master programs (ESC datasheet section I, "FMMU"). CoE requests are
handed to a CoE server (:class:`servodesk.sim.ethercat_slave.CoeServer`, the drive's
firmware) and its answers loaded into SM1. Each process data exchange is handed to
:attr:`EscSlave.on_cycle` with the outputs (in OPERATIONAL), and the firmware puts the next
inputs into SM3 with :meth:`EscSlave.set_inputs` (ETG.1000.6 §5.3: SM3 is read by the
master, written by the PDI). An :class:`EscLine` passes each datagram of a frame along the
slaves and answers frames from a raw socket, in a thread or in a process of its own
(:func:`child_main`). Nothing here imports the drive simulation, so that process starts
light.

Over 700 lines: the ESC's register map, SII, AL state machine, mailbox and FMMU process data are
one memory that SOEM reads and writes by address; :class:`EscLine` is the datagram router over
it.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import logging
import selectors
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection

from servodesk.domain import ethercat as ec
from servodesk.domain.ethercat import AlState, Cmd, Reg
from servodesk.errors import LinkError, NotFoundError
from servodesk.nic import open_raw

log = logging.getLogger(__name__)

#: ESC type this slave reports: the ET1100 (11h), whose register map it follows.
ESC_TYPE = 0x11
#: RAM size in KByte, FMMUs and SyncManagers reported in 0x0004-0x0006.
FMMUS, SYNCMANAGERS, RAM_KB = 3, 4, 8
#: Port descriptor (0x0007): ports 0 and 1 MII (11b), 2 and 3 not implemented.
PORT_DESCRIPTOR = 0x0F
#: PDI control (0x0140): 05h, SPI slave (the "microcontroller" behind it is the CoE server).
PDI_TYPE = 0x05

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


#: The DC registers only the ESC writes (receive times, system time, processing unit's
#: receive time): a master's write there is not stored.
_DC_LATCHED = frozenset(range(Reg.DC_RECEIVE_TIME, Reg.DC_SYSTEM_TIME_OFFSET))


def _or(a: bytes, b: bytes) -> bytes:
    return bytes(x | y for x, y in zip(a, b, strict=True))


@dataclass(frozen=True)
class EscBehaviour:
    """What a real slave's ESC and firmware do that the plain twin's do not (the ESI twin's
    options, sim/esi_twin.py ``TwinOptions``; picklable for the ESC process)."""

    #: Seconds after power-on during which the firmware is not ready: a request of PRE-OP
    #: leaves the slave in INIT without an error, as a slave whose PDI has not started yet.
    boot_delay_s: float = 0.0
    #: False: the SyncManager watchdog is never enforced (a slave whose firmware switches it
    #: off, whatever 0400h / 0420h say).
    watchdog: bool = True


class EscSlave:
    """One slave's ESC: memory and registers, SII EEPROM, AL state machine and the mailbox.

    CoE requests go to :attr:`coe` (the drive's SDO server, the "firmware" behind the PDI),
    whose answers come back by :meth:`answer`, at once or later.
    """

    def __init__(
        self, sii: ec.SiiInfo, *, last: bool = True, behaviour: EscBehaviour = EscBehaviour()
    ) -> None:
        self.behaviour = behaviour
        for _, size in (sii.mailbox_out, sii.mailbox_in):
            if not 32 <= size <= 1024:
                raise ValueError(f"mailbox size {size} is outside 32..1024")
        self.sii = sii
        self.eeprom = bytearray(ec.sii_image(self.sii))
        self.mem = bytearray(0x10000)
        m = self.mem
        m[Reg.TYPE] = ESC_TYPE
        m[Reg.FMMUS], m[Reg.SYNCMANAGERS], m[Reg.RAM_SIZE] = FMMUS, SYNCMANAGERS, RAM_KB
        m[Reg.PORT_DESCRIPTOR] = PORT_DESCRIPTOR
        # ESC features (0x0008): distributed clocks, 64 bit (bits 2 and 3), where the slave
        # takes a SYNC0 cycle; otherwise none, and SOEM sets hasdc 0.
        if sii.dc_cycle_ns is not None:
            struct.pack_into("<H", m, Reg.FEATURES, ec.FEATURE_DC | ec.FEATURE_DC64)
        self._last = last
        #: The local clock's zero (monotonic ns): the DC local time counts from power-on.
        self._clock0 = time.monotonic_ns()
        # DL status (0x0110): PDI operational (bit 0), link on port 0 (bit 4) with
        # communication (bits 8-9 = 10b: loop open, communication established); port 1 the
        # same when another slave follows, else closed (loop, bits 10-11 = 01b); ports 2 and
        # 3 closed. SOEM counts the open ports for the topology (ecx_config_init).
        dl = 0x0001 | 0x0010 | 0x0200 | 0x1000 | 0x4000
        dl |= 0x0400 if last else 0x0020 | 0x0800
        struct.pack_into("<H", m, Reg.DL_STATUS, dl)
        m[Reg.PDI_CONTROL] = PDI_TYPE
        # The ESC's reset values: divider 2498 (100 µs) and 1000 of them, a 100 ms SyncManager
        # watchdog (ESC datasheet 0x0400 / 0x0420), which the master may change or switch off
        # (0).
        struct.pack_into("<H", m, Reg.WATCHDOG_DIVIDER, 2498)
        struct.pack_into("<H", m, Reg.WATCHDOG_PROCESS_DATA, 1000)
        #: When the outputs (SM2) were last written, for the watchdog (monotonic seconds).
        self._outputs_at: float | None = None
        #: Mailbox responses waiting for SM1 (the oldest is in SM1 while it is full).
        self._outbox: deque[bytes] = deque()
        self._last_response: bytes | None = None
        self._counter = 0
        #: Mailbox requests taken (tests).
        self.mailbox_requests = 0
        #: Where a CoE request goes; the answer comes back by answer().
        self.coe: Callable[[bytes], None] = lambda data: None
        #: Called when the mailbox is reset (INIT, SM1 disabled): transfers in progress end.
        self.on_reset: Callable[[], None] = lambda: None
        #: Called with the outputs (SM2) after each process data exchange that reached this
        #: slave (None outside OPERATIONAL, where the outputs are not taken: ETG.1000.6
        #: §6.4.1); the firmware answers with set_inputs.
        self.on_cycle: Callable[[bytes | None], None] = lambda outputs: None
        #: Called with the new AL state and the AL status code after a transition.
        self.on_state: Callable[[int, int], None] = lambda state, code: None
        #: Called on entering SAFE-OP with the synchronisation the master configured: (0, 0)
        #: FreeRun, (2, SYNC0 cycle in ns) DC (the values of 1C32h:01 / :02, ETG.1020).
        self.on_sync: Callable[[int, int], None] = lambda mode, cycle_ns: None
        #: Process data exchanges that reached this slave (tests).
        self.cycles = 0
        #: The PDO configuration the firmware mirrors here (key index << 8 | sub: value),
        #: answered to SDO uploads at once (see cached_upload).
        self.od_cache: dict[int, bytes] = {}
        self._set_al(AlState.INIT, 0)

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
        if (
            self.sii.dc_cycle_ns is not None
            and ado < Reg.DC_SYSTEM_TIME + 8
            and end > Reg.DC_SYSTEM_TIME
        ):
            struct.pack_into("<Q", self.mem, Reg.DC_SYSTEM_TIME, self.system_time_ns())
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
        if self.sii.dc_cycle_ns is not None:
            # The receive times and the system time are the ESC's: a write to 0x0900 latches
            # the receive times, one to the system time is the master's drift control (ESC
            # datasheet section I, "Distributed clocks"), neither is stored.
            kept.update({a: self.mem[a] for a in _DC_LATCHED if ado <= a < end})
        old_repeat = self.mem[Reg.SM0 + ec.SM_SIZE + ec.SM_ACTIVATE] & ec.SM_ACTIVATE_REPEAT
        self.mem[ado:end] = data
        for a, v in kept.items():
            self.mem[a] = v
        if self.sii.dc_cycle_ns is not None and ado <= Reg.DC_RECEIVE_TIME < end:
            self._latch_receive_times()
        if ado <= Reg.AL_CONTROL < end:
            self._al_control(self.mem[Reg.AL_CONTROL])
        if ado <= Reg.EEPROM_CONTROL + 1 and end > Reg.EEPROM_CONTROL:
            self._eeprom_command()
        if ado < Reg.SM0 + 2 * ec.SM_SIZE and end > Reg.SM0:
            self._sm_changed(old_repeat)
        return True

    # Distributed clocks (ESC datasheet section I, "Distributed clocks") -----------------

    def local_time_ns(self) -> int:
        """The ESC's local clock: ns since power-on."""
        return time.monotonic_ns() - self._clock0

    def system_time_ns(self) -> int:
        """The DC system time: the local time plus the offset the master wrote (0x0920),
        modulo 2^64."""
        offset = int(struct.unpack_from("<Q", self.mem, Reg.DC_SYSTEM_TIME_OFFSET)[0])
        return (self.local_time_ns() + offset) & 0xFFFF_FFFF_FFFF_FFFF

    def _latch_receive_times(self) -> None:
        """The frame that wrote 0x0900 arrived now at port 0; it came back through port 1
        from the slaves behind (a fixed 500 ns here) where there are any. SOEM's
        ``ecx_configdc`` computes the offsets and propagation delays from these."""
        t = self.local_time_ns()
        struct.pack_into("<I", self.mem, Reg.DC_RECEIVE_TIME, t & 0xFFFFFFFF)
        back = 0 if self._last else (t + 500) & 0xFFFFFFFF
        struct.pack_into("<I", self.mem, Reg.DC_RECEIVE_TIME + 4, back)
        struct.pack_into("<Q", self.mem, Reg.DC_RECEIVE_TIME_PU, t)

    def _sync_code(self) -> tuple[int, int, int]:
        """(AL status code, sync mode, SYNC0 cycle ns) of the DC configuration at the
        request of SAFE-OP (ETG.1020, 1C32h): FreeRun when cyclic operation is off; SYNC0
        alone, at a cycle the slave takes, for DC mode; otherwise 0030h (invalid DC SYNC
        configuration) or 0035h (invalid sync cycle time)."""
        act = self.mem[Reg.DC_ACTIVATION]
        if not act & 0x01:
            return 0, 0, 0
        dc = self.sii.dc_cycle_ns
        if dc is None or act & 0x07 != ec.DC_ACTIVATE_SYNC0:
            return 0x0030, 0, 0
        cycle = int(struct.unpack_from("<I", self.mem, Reg.DC_SYNC0_CYCLE)[0])
        low, high, step = dc
        if not low <= cycle <= high or cycle % step:
            return 0x0035, 0, 0
        return 0, 2, cycle

    # AL state machine (ETG.1000.6 §6.4) -----------------------------------------------

    def _set_al(self, state: int, code: int) -> None:
        before = self.mem[Reg.AL_STATUS] & 0x0F
        struct.pack_into("<H", self.mem, Reg.AL_STATUS, state | (ec.AL_ERROR if code else 0))
        struct.pack_into("<H", self.mem, Reg.AL_STATUS_CODE, code)
        if state != before:
            self.on_state(state, code)

    def _al_control(self, control: int) -> None:
        requested, ack = control & 0x0F, control & ec.AL_ACK
        state = self.al_state
        if self.mem[Reg.AL_STATUS] & ec.AL_ERROR and not ack:
            return  # An error indication stays until the master acknowledges it.
        if requested == AlState.INIT:
            self._set_al(AlState.INIT, 0)
            self._reset_mailbox()
        elif requested == AlState.PREOP:
            if self.local_time_ns() < self.behaviour.boot_delay_s * 1e9:
                return  # The firmware is still booting: the request waits (INIT, no error).
            if self._mailbox_config_ok():
                self._set_al(AlState.PREOP, 0)
            else:
                self._set_al(state, 0x0016)  # Invalid mailbox configuration
        elif requested == AlState.BOOT:
            self._set_al(state, 0x0013)  # Bootstrap not supported
        elif requested == AlState.SAFEOP:
            # ETG.1000.6 §6.4.1: SAFE-OP from PRE-OP (or back from OP), with the process
            # data SyncManagers programmed as the SII offers them.
            if state not in (AlState.PREOP, AlState.SAFEOP, AlState.OP):
                self._set_al(state, 0x0011)  # Invalid requested state change
            elif not self._process_data_config_ok():
                self._set_al(state, 0x001D)  # Invalid output configuration
            elif state == AlState.PREOP:
                code, mode, cycle = self._sync_code()
                if code:
                    self._set_al(state, code)
                else:
                    self.on_sync(mode, cycle)
                    self._set_al(AlState.SAFEOP, 0)
            else:
                self._set_al(AlState.SAFEOP, 0)
        elif requested == AlState.OP:
            if state not in (AlState.SAFEOP, AlState.OP):
                self._set_al(state, 0x0011)  # OP only from SAFE-OP
            else:
                self._set_al(AlState.OP, 0)
        elif requested == 0 and ack:
            self._set_al(state, 0)  # Acknowledge only: the error indication is cleared.
        else:
            self._set_al(state, 0x0012)  # Unknown requested state

    def _process_data_config_ok(self) -> bool:
        """SM2 / SM3, where programmed, at the SII's start addresses and directions."""
        for n, start, control in (
            (2, self.sii.outputs_start, ec.SM_CONTROL_OUTPUTS),
            (3, self.sii.inputs_start, ec.SM_CONTROL_INPUTS),
        ):
            s_, length, on = self._sm(n)
            if not on or not length:
                continue  # Not used by this mapping.
            base = Reg.SM0 + ec.SM_SIZE * n
            if start is None or s_ != start or self.mem[base + 4] & 0x0C != control & 0x0C:
                return False
        return True

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
        self.on_reset()
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
        info = service == ec.CoeService.SDO_INFO and self.sii.coe_details & ec.COE_DETAILS_SDO_INFO
        if service != ec.CoeService.SDO_REQUEST and not info:
            self._reply(ec.mailbox_error(ec.MBXERR_SERVICE_NOT_SUPPORTED))
            return
        self.coe(mbx.data)  # SDO, or SDO Information where the SII offers it (sim/coe_info.py)

    # Process data (FMMUs, SM2 / SM3) --------------------------------------------------

    def fmmus(self) -> list[tuple[int, int, int, int]]:
        """The active FMMUs: (logical start, length, physical start, type: 1 read, 2 write).
        Byte granularity: SOEM maps whole bytes (start bit 0, stop bit 7)."""
        out: list[tuple[int, int, int, int]] = []
        for n in range(FMMUS):
            base = Reg.FMMU0 + 16 * n
            log_start, length, _, _, phys, _, kind, active = struct.unpack_from(
                "<IHBBHBBB", self.mem, base
            )
            if active & 1 and length:
                out.append((log_start, length, phys, kind))
        return out

    def logical(self, cmd: int, start: int, data: bytearray) -> int:
        """A logical datagram at ``start`` through this slave's FMMUs: inputs copied into
        ``data`` (LRD, LRW), outputs taken from it (LWR, LRW); the working counter's
        increment (ETG.1000.4 §5.4.3: read 1, write 1, LRW write 2)."""
        n = len(data)
        read = wrote = False
        for lstart, length, phys, kind in self.fmmus():
            lo, hi = max(start, lstart), min(start + n, lstart + length)
            if lo >= hi or phys + (hi - lstart) > len(self.mem):
                continue
            at, p = lo - start, phys + (lo - lstart)
            if kind & 1 and cmd in (Cmd.LRD, Cmd.LRW):
                data[at : at + hi - lo] = self.mem[p : p + hi - lo]
                read = True
            if kind & 2 and cmd in (Cmd.LWR, Cmd.LRW):
                self.mem[p : p + hi - lo] = data[at : at + hi - lo]
                wrote = True
        if not (read or wrote):
            return 0
        self.cycles += 1
        if wrote:
            self._outputs_at = time.monotonic()
        s2, l2, on2 = self._sm(2)
        outputs = (
            bytes(self.mem[s2 : s2 + l2]) if on2 and l2 and self.al_state == AlState.OP else None
        )
        self.on_cycle(outputs)
        return (1 if read else 0) + ((2 if cmd == Cmd.LRW else 1) if wrote else 0)

    def watchdog_s(self) -> float:
        """The SyncManager watchdog time in seconds (0: off)."""
        divider, count = (
            struct.unpack_from("<H", self.mem, Reg.WATCHDOG_DIVIDER)[0],
            struct.unpack_from("<H", self.mem, Reg.WATCHDOG_PROCESS_DATA)[0],
        )
        return float(count * (divider + 2) * 40e-9)

    def check_watchdog(self, now: float) -> bool:
        """In OP with outputs mapped: when no process data wrote them for the watchdog time,
        the slave falls back to SAFE-OP with the error flag and AL status code 001Bh
        (SyncManager watchdog; HIWIN 000 §2.10 table 2.10.1: "O, S -> S + E"); True then."""
        if self.al_state != AlState.OP:
            self._outputs_at = None
            return False
        _, l2, on2 = self._sm(2)
        limit = self.watchdog_s()
        if not (on2 and l2) or limit <= 0 or not self.behaviour.watchdog:
            return False
        if self._outputs_at is None:
            self._outputs_at = now  # Watched from the first check in OP on.
            return False
        if now - self._outputs_at <= limit:
            return False
        self._outputs_at = None
        self._set_al(AlState.SAFEOP, 0x001B)
        return True

    def set_inputs(self, data: bytes) -> None:
        """The firmware's inputs into SM3 (cut or zero-padded to its length)."""
        s3, l3, on3 = self._sm(3)
        if on3 and l3:
            self.mem[s3 : s3 + l3] = data[:l3].ljust(l3, b"\x00")

    def answer(self, data: bytes | None) -> None:
        """The CoE server's answer to a request (None: it sends none, as after an abort from
        the master); dropped when the mailbox was switched off meanwhile."""
        if data is not None and self._mailbox_on():
            self._reply(ec.Mailbox(ec.MailboxType.COE, data))


class EscLine:
    """Slaves in a line: each datagram of a frame passes slave 1, 2, ... in order."""

    def __init__(self, slaves: Sequence[EscSlave]) -> None:
        if not slaves:
            raise ValueError("an EtherCAT line needs at least one slave")
        self.slaves = list(slaves)
        #: Frames answered and dropped (tests and logs).
        self.frames = 0
        self.dropped = 0

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
        if cmd in (Cmd.LRD, Cmd.LWR, Cmd.LRW):
            data_l = bytearray(d.data)
            wkc_l = d.wkc
            for slave in self.slaves:
                wkc_l += slave.logical(cmd, d.address, data_l)
            d.data = bytes(data_l)
            d.wkc = wkc_l & 0xFFFF
            return
        if cmd == Cmd.NOP or cmd > Cmd.FRMW:
            return
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

    def serve(
        self,
        sock: socket.socket,
        ifname: str,
        stop: threading.Event,
        pdi: Connection | None = None,
    ) -> None:
        """Answer the frames arriving on ``sock`` until ``stop`` is set (or ``pdi``, the
        connection to the CoE servers of another process, closes). Answers from ``pdi``
        are (``"coe"``, slave index, data) tuples."""
        sel = selectors.DefaultSelector()
        sel.register(sock, selectors.EVENT_READ, "ethernet")
        if pdi is not None:
            sel.register(pdi.fileno(), selectors.EVENT_READ, "pdi")
        try:
            while not stop.is_set():
                now = time.monotonic()
                for slave in self.slaves:
                    slave.check_watchdog(now)
                for key, _ in sel.select(0.01):
                    if key.data == "pdi":
                        assert pdi is not None
                        try:
                            kind, index, data = pdi.recv()
                        except (EOFError, OSError):
                            return
                        if kind == "coe":
                            self.slaves[index].answer(data)
                        elif kind == "inputs":
                            self.slaves[index].set_inputs(data)
                        elif kind == "od":
                            self.slaves[index].od_cache = data
                    elif not self._receive(sock, ifname, stop):
                        return
        finally:
            sel.close()

    def _receive(self, sock: socket.socket, ifname: str, stop: threading.Event) -> bool:
        """Answer one frame; False when the socket is gone for good."""
        try:
            frame, addr = sock.recvfrom(2048)
        except BlockingIOError:
            return True
        except OSError as exc:
            if stop.is_set() or exc.errno in (errno.EBADF, errno.ENODEV, errno.ENXIO):
                if not stop.is_set():
                    log.warning("EtherCAT slaves on %s stop: %s", ifname, exc)
                return False
            # The link is down for a moment (ENETDOWN): a cable pulled, not an end.
            log.debug("EtherCAT slaves on %s: %s", ifname, exc)
            stop.wait(0.1)
            return True
        if addr[2] == socket.PACKET_OUTGOING:
            return True
        answer = self.process(frame)
        if answer is None:
            self.dropped += 1
            return True
        try:
            sock.send(answer)
            self.frames += 1
        except OSError as exc:
            log.warning("EtherCAT slave on %s cannot send: %s", ifname, exc)
        return True


def open_socket(ifname: str) -> socket.socket:
    """A raw AF_PACKET socket for EtherType 88A4h on ``ifname`` (non-blocking); LinkError
    when the interface is missing or the process may not (root or CAP_NET_RAW)."""
    try:
        sock = open_raw(
            ifname,
            ec.ETHERTYPE,
            what="EtherCAT",
            permission_hint="the simulated EtherCAT slave needs root or CAP_NET_RAW",
        )
    except NotFoundError as exc:
        raise LinkError(
            exc.message, hint="give the slave end of a veth pair (servodesk.sim.veth) or a NIC"
        ) from exc
    sock.setblocking(False)
    return sock


def child_main(fd: int) -> None:
    """The ESCs of a line in a process of their own (``EthercatSlaveProcess``): their
    registers answer SOEM at once, whatever the parent process holds (pysoem keeps the GIL
    while it waits in its state calls); CoE requests go to the parent over the connection on
    ``fd``, whose first message is (interface name, the slaves' SII)."""
    pdi = Connection(fd)
    try:
        ifname, siis, behaviours = pdi.recv()
    except (EOFError, OSError):
        return
    try:
        sock = open_socket(ifname)
    except LinkError as exc:
        pdi.send(("error", exc.message, exc.hint))
        return
    line = EscLine(
        [
            EscSlave(s, last=i == len(siis) - 1, behaviour=b)
            for i, (s, b) in enumerate(zip(siis, behaviours, strict=True))
        ]
    )
    for i, slave in enumerate(line.slaves):
        slave.coe = functools.partial(_coe, pdi, i, slave)
        slave.on_reset = functools.partial(_forward, pdi, "reset", i, None)
        slave.on_cycle = functools.partial(_forward, pdi, "cycle", i)
        slave.on_state = functools.partial(_forward_state, pdi, i)
        slave.on_sync = functools.partial(_forward_sync, pdi, i)
    pdi.send(("ready", None, None))
    try:
        line.serve(sock, ifname, threading.Event(), pdi)
    finally:
        sock.close()
        pdi.close()


def cached_upload(cache: dict[int, bytes], data: bytes) -> bytes | None:
    """The CoE answer to an SDO upload of a value of at most 4 bytes that ``cache`` holds,
    or None (forward the request to the firmware).

    SOEM reads the PDO configuration (1C00h, 1C12h / 1C13h, the assigned PDOs' entries) by
    SDO inside ``ecx_config_map_group``, and pysoem's ``config_map`` holds the GIL while it
    runs: a CoE server in the master's process cannot answer it. The drive's firmware
    therefore mirrors those objects into the ESC process whenever they change, as a slave's
    firmware keeps its object dictionary next to its mailbox."""
    if len(data) < 10 or data[2] >> 5 != 2:
        return None
    try:
        sdo = ec.parse_sdo(data)
    except ec.EthercatFrameError:
        return None
    if data[2] & ec.SDO_COMPLETE_ACCESS:
        # The firmware offers no complete access (CoeServer): its abort, given here, where
        # SOEM's config_map waits for it (a slave whose SII claims complete access anyway).
        return ec.build_sdo(ec.sdo_abort(sdo.index, sdo.subindex, 0x06010000))
    value = cache.get(sdo.index << 8 | sdo.subindex)
    if value is None or len(value) > 4:
        return None
    command = ec.SDO_UPLOAD_EXPEDITED | ((4 - len(value)) << 2)
    response = ec.Sdo(
        ec.CoeService.SDO_RESPONSE, command, sdo.index, sdo.subindex, value.ljust(4, b"\x00")
    )
    return ec.build_sdo(response)


def _coe(pdi: Connection, index: int, slave: EscSlave, data: bytes) -> None:
    answer = cached_upload(slave.od_cache, data)
    if answer is not None:
        slave.answer(answer)
    else:
        _forward(pdi, "coe", index, data)


def _forward_state(pdi: Connection, index: int, state: int, code: int) -> None:
    with contextlib.suppress(OSError):
        pdi.send(("state", index, (state, code)))


def _forward_sync(pdi: Connection, index: int, mode: int, cycle_ns: int) -> None:
    with contextlib.suppress(OSError):
        pdi.send(("sync", index, (mode, cycle_ns)))


def _forward(pdi: Connection, kind: str, index: int, data: bytes | None) -> None:
    # The parent gone: the serve loop ends on the closed connection.
    with contextlib.suppress(OSError):
        pdi.send((kind, index, data))
