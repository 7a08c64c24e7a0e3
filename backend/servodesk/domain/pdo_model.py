"""The PDO data model: directions, mapping entries, PDOs, configurations and plans.

Frozen dataclasses only (docs/pdo.md "Domain API"): a :class:`PdoConfig` holds every
:class:`Pdo` of the family with its :class:`MapEntry` list and CANopen :class:`PdoComm`
parameters, a :class:`PdoProblem` is a reason a mapping is refused, a :class:`Slot` is an entry at
its place in the frame and a :class:`Plan` is the ordered :class:`PdoStep` list that changes a
drive's mapping. The functions that build and use them live in the other ``pdo_*`` modules.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, replace
from typing import Literal

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import PdoTemplate
from servodesk.errors import NotFoundError

#: The templates of a profile are its :class:`~servodesk.domain.profile.PdoTemplate` entries.
Template = PdoTemplate

COB_INVALID = 0x80000000  # CiA 301 §7.5.2.35: bit 31 = 1, the PDO does not exist.
COB_NO_RTR = 0x40000000  # bit 30 = 1: no RTR allowed on this TPDO.
COB_EXTENDED = 0x20000000  # bit 29 = 1: 29-bit CAN id.

#: CiA 301 §7.4.7.1: dummy mapping uses the data type indexes 0002h..0007h.
_DUMMY = range(0x0002, 0x0008)


class Direction(enum.StrEnum):
    """rx: master -> drive (RPDO, RxPDO, setpoint telegram); tx: drive -> master."""

    RX = "rx"
    TX = "tx"


# --------------------------------------------------------------------------------------------
# Data


@dataclass(frozen=True)
class MapEntry:
    """One CiA 301 mapping entry: object index, subindex and length in bits."""

    index: int
    subindex: int
    bits: int

    @property
    def raw(self) -> int:
        return (self.index & 0xFFFF) << 16 | (self.subindex & 0xFF) << 8 | (self.bits & 0xFF)

    @classmethod
    def from_raw(cls, raw: int) -> MapEntry:
        return cls(raw >> 16 & 0xFFFF, raw >> 8 & 0xFF, raw & 0xFF)

    @classmethod
    def reserved(cls, bits: int) -> MapEntry:
        """LECSN Reserved padding: PNU 0, the subindex gives the length (004 §20.3 note)."""
        return cls(0, bits, bits)

    @property
    def is_padding(self) -> bool:
        return self.index == 0 or self.index in _DUMMY

    @property
    def address(self) -> ObjectAddress | None:
        return None if self.is_padding else ObjectAddress(self.index, self.subindex)

    def __str__(self) -> str:
        if self.index == 0:
            return f"reserved:{self.bits}"
        return f"0x{self.index:04X}:{self.subindex:02X}"


@dataclass(frozen=True)
class PdoComm:
    """Communication parameters of a CANopen PDO (CiA 301 §7.5.2.35)."""

    cob_id: int
    enabled: bool
    rtr_allowed: bool = True
    transmission_type: int = 255
    inhibit_time: int = 0
    event_timer: int = 0
    sync_start: int = 0

    def cob_raw(self, direction: Direction) -> int:
        """The value of sub 1: the CAN id with bits 31 (invalid) and 30 (no RTR)."""
        raw = self.cob_id
        if not self.enabled:
            raw |= COB_INVALID
        if direction is Direction.TX and not self.rtr_allowed:
            raw |= COB_NO_RTR
        return raw


@dataclass(frozen=True)
class Pdo:
    """One PDO: where it is configured, how it is sent and what it carries."""

    direction: Direction
    number: int
    mapping_index: int
    comm_index: int | None
    comm: PdoComm | None
    entries: tuple[MapEntry, ...]
    #: The family's kind (profile.pdo.kind); it decides the name.
    kind: str = "canopen"

    @property
    def name(self) -> str:
        rx = self.direction is Direction.RX
        if self.kind == "canopen":
            return f"{'RPDO' if rx else 'TPDO'}{self.number}"
        if self.kind == "telegram":
            return "setpoint telegram" if rx else "actual-value telegram"
        return f"{'RxPDO' if rx else 'TxPDO'} {self.mapping_index:04X}h"

    @property
    def bits(self) -> int:
        return sum(e.bits for e in self.entries)

    @property
    def bytes(self) -> int:
        return (self.bits + 7) // 8


@dataclass(frozen=True)
class PdoConfig:
    """Every PDO of the family (RX first), the EtherCAT assignment, the PROFINET telegram."""

    pdos: tuple[Pdo, ...]
    assignment: dict[Direction, tuple[int, ...]] | None = None
    telegram: int | None = None

    def pdo(self, direction: Direction | str, number: int) -> Pdo:
        d = Direction(direction)
        for p in self.pdos:
            if p.direction is d and p.number == number:
                return p
        raise NotFoundError(
            f"there is no {d.value} PDO {number}",
            hint=f"numbers 1..{sum(1 for p in self.pdos if p.direction is d)}",
        )

    def of(self, direction: Direction | str) -> list[Pdo]:
        d = Direction(direction)
        return [p for p in self.pdos if p.direction is d]

    def active(self, direction: Direction | str) -> list[Pdo]:
        """The PDOs that go on the bus, in the order they are sent."""
        d = Direction(direction)
        mine = self.of(d)
        if not mine:
            return []
        kind = mine[0].kind
        if kind == "canopen":
            return [p for p in mine if p.comm is not None and p.comm.enabled and p.entries]
        if kind == "ethercat":
            by_index = {p.mapping_index: p for p in mine}
            assigned = (self.assignment or {}).get(d, ())
            return [by_index[i] for i in assigned if i in by_index]
        return mine

    def replace_pdo(self, pdo: Pdo) -> PdoConfig:
        pdos = tuple(
            pdo if (p.direction, p.number) == (pdo.direction, pdo.number) else p for p in self.pdos
        )
        return replace(self, pdos=pdos)


@dataclass(frozen=True)
class PdoProblem:
    """A reason a mapping is refused, shown next to the field it is about."""

    message: str
    pdo: str | None = None
    entry: int | None = None
    field: str | None = None
    section: str | None = None

    def to_dict(self) -> dict[str, object]:
        return {
            "message": self.message,
            "pdo": self.pdo,
            "entry": self.entry,
            "field": self.field,
            "section": self.section,
        }


@dataclass(frozen=True)
class Slot:
    """One mapped entry at its place in the frame."""

    entry: MapEntry
    offset_bits: int
    bits: int
    address: ObjectAddress | None
    name: str
    data_type: DataType | None
    unit: str | None

    @property
    def offset_byte(self) -> int:
        return self.offset_bits // 8

    @property
    def padding(self) -> bool:
        return self.address is None


@dataclass(frozen=True)
class PdoStep:
    """One action of a plan, in order."""

    kind: Literal["write", "nmt"]
    address: ObjectAddress | None
    value: int
    data_type: DataType | None
    command: str | None
    why: str

    @property
    def value_hex(self) -> str | None:
        if self.kind != "write":
            return None
        bits = self.data_type.bits if self.data_type is not None else 32
        return f"0x{self.value & ((1 << bits) - 1):0{max(bits // 4, 2)}X}"

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": self.kind,
            "address": str(self.address) if self.address is not None else None,
            "value": self.value,
            "value_hex": self.value_hex,
            "command": self.command,
            "why": self.why,
        }


@dataclass(frozen=True)
class Plan:
    """The ordered steps that turn the current configuration into the desired one."""

    steps: tuple[PdoStep, ...]
    touched: tuple[str, ...]

    def to_dict(self) -> dict[str, object]:
        return {"steps": [s.to_dict() for s in self.steps], "touched": list(self.touched)}
