"""ETG.1020 diagnosis messages: an EtherCAT drive's diagnosis history (10F3h, sub 06h on).

A message is 16 bytes, little endian as every CoE value: the diagnosis code (UNSIGNED32; E800h
in bits 0-15 marks an emergency error code, CiA 301 / the drive profile's 603Fh code, in bits
16-31), flags (UNSIGNED16; bits 0-3: 0 info, 1 warning, 2 error), a text id (UNSIGNED16) and a
time stamp (UNSIGNED64, ns of the DC system time, which counts from 2000-01-01 00:00 UTC,
ETG.1000.4). HIWIN 000 §2.7 sends its faults as emergency messages, kept in 10F3h.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass

_DIAG = struct.Struct("<IHHQ")
#: Bits 0-15 of a diagnosis code that carries an emergency error code in bits 16-31.
EMCY_DIAG = 0xE800
#: Flags bits 0-3: an error message.
ERROR_FLAG = 0x0002
#: The DC system time's epoch (2000-01-01 00:00 UTC) in ns since the Unix epoch.
DC_EPOCH_NS = 946_684_800 * 1_000_000_000
SIZE = _DIAG.size


@dataclass(frozen=True, slots=True)
class DiagnosisMessage:
    diag_code: int
    flags: int
    text_id: int
    #: ns since 2000-01-01 00:00 UTC (DC system time).
    stamp: int

    @property
    def emergency_code(self) -> int | None:
        """The emergency error code it carries, None for another kind of message."""
        return self.diag_code >> 16 if self.diag_code & 0xFFFF == EMCY_DIAG else None


def emergency_message(code: int, now_ns: int | None = None) -> bytes:
    """The error message of emergency error code ``code``, stamped now (or ``now_ns``)."""
    stamp = (time.time_ns() if now_ns is None else now_ns) - DC_EPOCH_NS
    return _DIAG.pack(EMCY_DIAG | (code & 0xFFFF) << 16, ERROR_FLAG, 0, max(0, stamp))


def parse(data: bytes) -> DiagnosisMessage | None:
    """The message in ``data`` (None when it is shorter than one; parameters after it ignored)."""
    if len(data) < SIZE:
        return None
    return DiagnosisMessage(*_DIAG.unpack_from(data))
