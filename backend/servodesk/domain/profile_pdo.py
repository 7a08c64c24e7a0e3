"""A profile's process-data rules (docs/pdo.md "Families"): which objects may be mapped,
the PROFIdrive telegrams, the EtherCAT sync managers and DC modes, and the start templates.

Part of the device profile model (domain/profile.py): :class:`PdoRules` is ``pdo:`` in
profile.yaml."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

from servodesk.domain.datatypes import DataType
from servodesk.domain.profile_base import STRICT, parse_data_type


def parse_type_ranges(text: str) -> frozenset[int]:
    """``"0-240,254-255"`` -> the set of numbers (transmission types of a PDO rule)."""
    out: set[int] = set()
    for part in text.replace(" ", "").split(","):
        if not part:
            continue
        lo, _, hi = part.partition("-")
        a, b = int(lo, 0), int(hi or lo, 0)
        if not 0 <= a <= b <= 255:
            raise ValueError(f"{part!r} is not a range inside 0..255")
        out.update(range(a, b + 1))
    return frozenset(out)


def _check_ranges(v: str) -> str:
    parse_type_ranges(v)
    return v


class PdoWord(BaseModel):
    """One entry of a telegram layout or template: an object address, or a word that is no
    object (telegram 1's STW1), or Reserved padding (``reserved:8``)."""

    model_config = STRICT

    #: ``"0x6040:00"``, ``"reserved:16"``; None for a word that is no object.
    address: str | None = None
    #: Length in bits when it is not the object's own (words that are no object, BOOLEAN).
    bits: int | None = Field(default=None, ge=0, le=64)
    name: str | None = None
    data_type: DataType | None = None
    note: str | None = None

    _dt = field_validator("data_type", mode="before")(parse_data_type)

    @model_validator(mode="before")
    @classmethod
    def _from_text(cls, v: Any) -> Any:
        return {"address": v} if isinstance(v, str) else v


class PdoTelegram(BaseModel):
    """A PROFIdrive telegram of the family (004 §20.3): its size and its layouts."""

    model_config = STRICT

    number: int = Field(ge=1, le=65535)
    name: str
    #: Size of each direction's IO data in bytes; a variable mapping must total exactly this.
    bytes: int = Field(ge=0, le=1440)
    max_entries: int = Field(ge=0, le=255)
    #: False: the layout is fixed and cannot be changed (telegrams 1 and 100).
    variable: bool = False
    #: The layout (fixed telegrams) or the default mapping (variable ones), per direction.
    rx: tuple[PdoWord, ...] = ()
    tx: tuple[PdoWord, ...] = ()
    section: str | None = None
    description: str | None = None


class PdoTemplatePdo(BaseModel):
    """One PDO of a template; fields left out keep the current value."""

    model_config = STRICT

    direction: Literal["rx", "tx"]
    number: int = Field(ge=1, le=512)
    #: Entries as addresses (``"0x6040:00"``, ``"reserved:8"``); None keeps the current ones.
    entries: tuple[PdoWord, ...] | None = None
    enabled: bool | None = None
    #: An 11-bit CAN id; text may be ``$NODEID+0x180``.
    cob_id: int | str | None = None
    rtr_allowed: bool | None = None
    transmission_type: int | None = Field(default=None, ge=0, le=255)
    inhibit_time: int | None = Field(default=None, ge=0, le=0xFFFF)
    event_timer: int | None = Field(default=None, ge=0, le=0xFFFF)
    sync_start: int | None = Field(default=None, ge=0, le=0xFF)


class PdoTemplate(BaseModel):
    """A ready-made PDO configuration of the family (a documented default or a useful set)."""

    model_config = STRICT

    id: str = Field(pattern=r"^[a-z0-9][a-z0-9-]*$")
    name: str
    description: str
    section: str | None = None
    pdos: tuple[PdoTemplatePdo, ...] = ()
    #: EtherCAT: the mapping objects assigned to the sync managers (1C12h/1C13h).
    assignment: dict[Literal["rx", "tx"], tuple[int, ...]] | None = None
    #: PROFINET: the telegram (P922).
    telegram: int | None = None


class SyncManagerSpec(BaseModel):
    """One EtherCAT sync manager as the ESI describes it (ETG.2000 DeviceType/Sm)."""

    model_config = STRICT

    #: SM number (the order of the ``Sm`` elements: 0 = first).
    number: int = Field(ge=0, le=15)
    #: What it carries: MBoxOut, MBoxIn, Outputs, Inputs (the Sm element's text).
    kind: str
    start_address: int | None = Field(default=None, ge=0, le=0xFFFF)
    default_size: int | None = Field(default=None, ge=0, le=0xFFFF)
    control_byte: int | None = Field(default=None, ge=0, le=0xFF)
    enabled: bool = True


class DcOpMode(BaseModel):
    """One distributed-clock operation mode of an EtherCAT slave (ETG.2000 Dc/OpMode)."""

    model_config = STRICT

    name: str
    description: str | None = None
    #: Value of the AssignActivate register 0x0980 (0x0300: SYNC0 active, 0: free run).
    assign_activate: int = Field(ge=0, le=0xFFFF)
    #: CycleTimeSync0/ShiftTimeSync0/CycleTimeSync1 as the file states them (ns; the cycle
    #: factor of the file is kept in ``cycle_factor_sync0``).
    cycle_time_sync0: int | None = None
    cycle_factor_sync0: int | None = None
    shift_time_sync0: int | None = None
    cycle_time_sync1: int | None = None
    cycle_factor_sync1: int | None = None


class PdoRules(BaseModel):
    """Process-data limits and procedure of the family (see docs/pdo.md)."""

    model_config = STRICT

    #: Which procedure maps process data: "canopen" (CiA 301 §7.5.2.35/36), "ethercat"
    #: (mapping objects + 1C12h/1C13h assignment), "fixed" (never written), "telegram"
    #: (PROFIdrive telegram chosen by P922, variable mapping of telegrams 102/103).
    kind: Literal["canopen", "ethercat", "fixed", "telegram"] = "canopen"
    #: Byte order of the process data on the wire.
    byte_order: Literal["little", "big"] = "little"
    rpdo_count: int = 4
    tpdo_count: int = 4
    max_entries: int = 8
    max_bits: int = 64
    #: Most bytes of process data per direction (all active PDOs together); None: no limit
    #: beyond max_bits per PDO.
    max_bytes: int | None = None
    #: False: an object may be mapped only once per direction (e.g. HIWIN 000 §3.1).
    allow_duplicates: bool = True
    #: Transmission types the drive accepts (CiA 301 §7.5.2.35 table 72 by default).
    rx_transmission_types: str = "0-240,254-255"
    tx_transmission_types: str = "0-240,252-255"
    #: Transmission types for which the event timer applies; with any other type it must
    #: be 0 (CiA 301 §7.5.2.35: TPDO event timer only for the event-driven types 254/255).
    rx_timer_types: str = "0-255"
    tx_timer_types: str = "254-255"
    #: Where the telegram number is selected (PROFIdrive P922), e.g. "0x039A:00".
    telegram_object: str | None = None
    #: When mapping may be changed: "preop" (NMT/ESM pre-operational), "safeop", "any", or
    #: "fixed" (the mapping cannot be changed at all).
    mapping_state: str = "preop"
    section: str | None = None
    telegrams: tuple[PdoTelegram, ...] = ()
    templates: tuple[PdoTemplate, ...] = ()
    #: EtherCAT: the sync managers and distributed-clock modes from the ESI (empty: unknown).
    sync_managers: tuple[SyncManagerSpec, ...] = ()
    dc_modes: tuple[DcOpMode, ...] = ()

    _ranges = field_validator(
        "rx_transmission_types", "tx_transmission_types", "rx_timer_types", "tx_timer_types"
    )(_check_ranges)

    def transmission_types(self, direction: str) -> frozenset[int]:
        return parse_type_ranges(
            self.rx_transmission_types if direction == "rx" else self.tx_transmission_types
        )

    def timer_types(self, direction: str) -> frozenset[int]:
        return parse_type_ranges(self.rx_timer_types if direction == "rx" else self.tx_timer_types)

    def telegram(self, number: int) -> PdoTelegram | None:
        return next((t for t in self.telegrams if t.number == number), None)
