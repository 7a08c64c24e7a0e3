"""The device profile model: what a drive family is, as data (see docs/profiles.md).

A profile is authored as ``profiles/<id>/profile.yaml`` and validated on load by these
pydantic models (unknown keys are refused). Objects are authored per index (VAR, ARRAY or
RECORD) and flattened into one :class:`ObjectSpec` per (index, subindex), which is what
every other layer uses.
"""

from __future__ import annotations

import dataclasses
import enum
import re
from collections.abc import Iterator
from functools import cached_property
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from servodesk.domain import quirks
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, coerce_int
from servodesk.domain.tuning.gains import ServoGains
from servodesk.errors import ServodeskError

Scalar = int | float | str | None


class Access(enum.StrEnum):
    """CiA 306 access types. ``rwr``/``rww``: read-write, mapped to TPDO / RPDO."""

    RO = "ro"
    WO = "wo"
    RW = "rw"
    RWR = "rwr"
    RWW = "rww"
    CONST = "const"

    @property
    def readable(self) -> bool:
        return self is not Access.WO

    @property
    def writable(self) -> bool:
        return self in (Access.WO, Access.RW, Access.RWR, Access.RWW)


class PdoMapping(enum.StrEnum):
    """Whether and in which direction an object can be mapped into process data."""

    NONE = "none"
    RX = "rx"  # master -> drive (RPDO, RxPDO, setpoint telegram)
    TX = "tx"  # drive -> master (TPDO, TxPDO, actual-value telegram)
    BOTH = "both"

    @property
    def rx(self) -> bool:
        return self in (PdoMapping.RX, PdoMapping.BOTH)

    @property
    def tx(self) -> bool:
        return self in (PdoMapping.TX, PdoMapping.BOTH)


class ObjectType(enum.StrEnum):
    VAR = "var"
    ARRAY = "array"
    RECORD = "record"


_STRICT = ConfigDict(extra="forbid", frozen=True, use_enum_values=False)


def _parse_data_type(v: Any) -> Any:
    if isinstance(v, str):
        try:
            return DataType.from_name(v)
        except ServodeskError as exc:  # pydantic reports ValueErrors with their place.
            raise ValueError(f"{exc.message} ({exc.hint})") from None
    return v


class ObjectSpec(BaseModel):
    """One variable of the object dictionary: what it is, its limits, its units."""

    model_config = _STRICT

    index: int = Field(ge=0, le=0xFFFF)
    subindex: int = Field(ge=0, le=0xFF)
    name: str
    #: The name as the manual prints it (Japanese, Chinese, ...).
    name_local: str | None = None
    data_type: DataType
    access: Access
    pdo_mapping: PdoMapping = PdoMapping.NONE
    #: Default value; text may be ``$NODEID+0x180`` (CiA 306 §4.6.3) or a string value.
    default: Scalar = None
    min: int | float | None = None
    max: int | float | None = None
    #: Engineering unit and scale: engineering value = raw * scale, in ``unit``;
    #: ``raw_unit`` names the unit of the raw value (e.g. "inc", "0.1 %").
    unit: str | None = None
    scale: float = 1.0
    raw_unit: str | None = None
    group: str | None = None
    #: Saved to non-volatile memory by "store parameters" (1010h / P4112).
    persist: bool = False
    #: A process value (actual position, statusword): never backed up or restored.
    process: bool = False
    description: str | None = None
    #: Where the manual documents it, e.g. "000 §5.3.2" (manual id and section).
    section: str | None = None
    #: Value descriptions for enumerations (value -> meaning).
    values: dict[int, str] | None = None
    #: PROFIdrive parameter number (PNU) and the drive's parameter symbol (e.g. PA01).
    pnu: int | None = None
    symbol: str | None = None
    #: Writable only in these CiA 402 states / NMT states (e.g. ["preop"]); empty: any.
    writable_in: tuple[str, ...] = ()
    #: Only the simulated twin has it; servodesk never expects it on a real drive.
    sim_only: bool = False

    _dt = field_validator("data_type", mode="before")(_parse_data_type)

    @property
    def address(self) -> ObjectAddress:
        return ObjectAddress(self.index, self.subindex)

    @property
    def bits(self) -> int:
        return self.data_type.bits

    def default_value(self, node_id: int = 0) -> Value | None:
        """The default as a typed value, resolving ``$NODEID`` expressions."""
        return resolve_value(self.default, self.data_type, node_id)

    def limits(self) -> tuple[int | float | None, int | float | None]:
        """Effective (min, max): the profile's limits, else the data type's range."""
        lo, hi = self.min, self.max
        rng = self.data_type.range
        if rng is not None:
            lo = rng[0] if lo is None else lo
            hi = rng[1] if hi is None else hi
        return lo, hi


class SubSpec(BaseModel):
    """A subindex as authored inside an ARRAY or RECORD entry (fields inherit)."""

    model_config = _STRICT

    sub: int = Field(ge=0, le=0xFF)
    #: Generate this many consecutive subindices; ``{n}`` in the name counts from 1.
    repeat: int = Field(default=1, ge=1, le=254)
    name: str
    name_local: str | None = None
    data_type: DataType
    access: Access
    pdo_mapping: PdoMapping | None = None
    default: Scalar = None
    min: int | float | None = None
    max: int | float | None = None
    unit: str | None = None
    scale: float = 1.0
    raw_unit: str | None = None
    group: str | None = None
    persist: bool | None = None
    process: bool | None = None
    description: str | None = None
    section: str | None = None
    values: dict[int, str] | None = None
    pnu: int | None = None
    symbol: str | None = None
    writable_in: tuple[str, ...] | None = None

    _dt = field_validator("data_type", mode="before")(_parse_data_type)


class ObjectEntry(BaseModel):
    """One index as authored in profile.yaml."""

    model_config = _STRICT

    index: int = Field(ge=0, le=0xFFFF)
    name: str
    name_local: str | None = None
    object_type: ObjectType = ObjectType.VAR
    # VAR fields (for ARRAY/RECORD they are the defaults the subs inherit).
    data_type: DataType | None = None
    access: Access | None = None
    pdo_mapping: PdoMapping = PdoMapping.NONE
    default: Scalar = None
    min: int | float | None = None
    max: int | float | None = None
    unit: str | None = None
    scale: float = 1.0
    raw_unit: str | None = None
    group: str | None = None
    persist: bool = False
    process: bool = False
    description: str | None = None
    section: str | None = None
    values: dict[int, str] | None = None
    pnu: int | None = None
    symbol: str | None = None
    writable_in: tuple[str, ...] = ()
    #: Only the simulated twin has it (e.g. LECSN 1600h/1A00h, docs/pdo.md).
    sim_only: bool = False
    subs: tuple[SubSpec, ...] = ()

    @field_validator("data_type", mode="before")
    @classmethod
    def _dt(cls, v: Any) -> Any:
        return _parse_data_type(v)

    @model_validator(mode="after")
    def _shape(self) -> ObjectEntry:
        if self.object_type is ObjectType.VAR:
            if self.subs:
                raise ValueError(f"0x{self.index:04X}: a VAR has no subs (use array/record)")
            if self.data_type is None or self.access is None:
                raise ValueError(f"0x{self.index:04X}: a VAR needs data_type and access")
        elif not self.subs:
            raise ValueError(f"0x{self.index:04X}: an {self.object_type.value} needs subs")
        return self

    def specs(self) -> Iterator[ObjectSpec]:
        """The flattened variables of this entry."""
        if self.object_type is ObjectType.VAR:
            assert self.data_type is not None and self.access is not None
            yield ObjectSpec(
                index=self.index,
                subindex=0,
                **_common(self),
                data_type=self.data_type,
                access=self.access,
                pdo_mapping=self.pdo_mapping,
            )
            return
        for s in self.subs:
            for k in range(s.repeat):
                n = k + 1
                name = s.name.replace("{n}", str(n)) if s.repeat > 1 or "{n}" in s.name else s.name
                yield ObjectSpec(
                    index=self.index,
                    subindex=s.sub + k,
                    name=name,
                    name_local=s.name_local,
                    data_type=s.data_type,
                    access=s.access,
                    pdo_mapping=s.pdo_mapping if s.pdo_mapping is not None else PdoMapping.NONE,
                    default=s.default,
                    min=s.min,
                    max=s.max,
                    unit=s.unit if s.unit is not None else self.unit,
                    scale=s.scale if s.scale != 1.0 else self.scale,
                    raw_unit=s.raw_unit if s.raw_unit is not None else self.raw_unit,
                    group=s.group or self.group,
                    persist=self.persist if s.persist is None else s.persist,
                    process=self.process if s.process is None else s.process,
                    description=s.description,
                    section=s.section or self.section,
                    values=s.values,
                    pnu=s.pnu if s.pnu is not None else self.pnu,
                    symbol=s.symbol,
                    writable_in=self.writable_in if s.writable_in is None else s.writable_in,
                    sim_only=self.sim_only,
                )


def _common(e: ObjectEntry) -> dict[str, Any]:
    return {
        "name": e.name,
        "name_local": e.name_local,
        "default": e.default,
        "min": e.min,
        "max": e.max,
        "unit": e.unit,
        "scale": e.scale,
        "raw_unit": e.raw_unit,
        "group": e.group,
        "persist": e.persist,
        "process": e.process,
        "description": e.description,
        "section": e.section,
        "values": e.values,
        "pnu": e.pnu,
        "symbol": e.symbol,
        "writable_in": e.writable_in,
        "sim_only": e.sim_only,
    }


class ErrorEntry(BaseModel):
    """One code of an error table: 603Fh error codes, EMCY codes, alarms, abort codes."""

    model_config = _STRICT

    #: Which table: "error_code" (603Fh), "emcy", "alarm", "sdo_abort", "profidrive",
    #: "slmp", "tuning", ... Codes are unique per table.
    table: str
    code: int
    name: str
    name_local: str | None = None
    #: Display form when it is not hex, e.g. "AL 16.1".
    display: str | None = None
    kind: Literal["fault", "warning", "info"] = "fault"
    cause: str | None = None
    remedy: str | None = None
    section: str | None = None
    #: How it is cleared: "reset" (fault reset), "power_cycle", "auto".
    clear: str | None = None
    #: Further documented attributes (LED blink code, error register bits, ...).
    extra: dict[str, Scalar] = Field(default_factory=dict)


class Quirk(BaseModel):
    """A documented deviation from the standard, as a flag shared code interprets."""

    model_config = _STRICT

    id: str
    value: Any = True
    section: str | None = None
    note: str | None = None


class Contradiction(BaseModel):
    """Two passages (or manual versions) that disagree, and which value the profile uses."""

    model_config = _STRICT

    topic: str
    chosen: str
    chosen_section: str
    other: str
    other_section: str
    note: str | None = None


class FamilyIdentity(BaseModel):
    """How a session recognises the family from 1018h (or the fieldbus's identity)."""

    model_config = _STRICT

    vendor_id: int | None = None
    product_codes: tuple[int, ...] = ()
    revision_min: int | None = None
    revision_max: int | None = None
    #: Regular expression matched against the device name (1008h), when one is read.
    device_name: str | None = None
    #: Where the vendor id is read when the device has no 1018h (e.g. PROFIdrive P964.0 as
    #: "0x03C4:00"); read only when 1018h gave nothing.
    vendor_id_object: str | None = None

    def matches(
        self,
        vendor_id: int | None,
        product_code: int | None,
        revision: int | None,
        device_name: str | None = None,
    ) -> bool:
        if self.vendor_id is None and not self.device_name:
            return False
        if self.vendor_id is not None and vendor_id != self.vendor_id:
            return False
        if self.vendor_id is None and not device_name:
            return False  # Only a name to go by, and the device gave none.
        if self.product_codes and product_code not in self.product_codes:
            return False
        if revision is not None:
            if self.revision_min is not None and revision < self.revision_min:
                return False
            if self.revision_max is not None and revision > self.revision_max:
                return False
        return not (
            self.device_name and device_name and not re.search(self.device_name, device_name)
        )


class Manual(BaseModel):
    model_config = _STRICT

    id: str
    title: str
    version: str | None = None
    language: str | None = None


class Group(BaseModel):
    """A parameter group as shown on the Parameters page (ordered)."""

    model_config = _STRICT

    id: str
    name: str
    name_local: str | None = None
    description: str | None = None


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

    model_config = _STRICT

    #: ``"0x6040:00"``, ``"reserved:16"``; None for a word that is no object.
    address: str | None = None
    #: Length in bits when it is not the object's own (words that are no object, BOOLEAN).
    bits: int | None = Field(default=None, ge=0, le=64)
    name: str | None = None
    data_type: DataType | None = None
    note: str | None = None

    _dt = field_validator("data_type", mode="before")(_parse_data_type)

    @model_validator(mode="before")
    @classmethod
    def _from_text(cls, v: Any) -> Any:
        return {"address": v} if isinstance(v, str) else v


class PdoTelegram(BaseModel):
    """A PROFIdrive telegram of the family (004 §20.3): its size and its layouts."""

    model_config = _STRICT

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

    model_config = _STRICT

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

    model_config = _STRICT

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

    model_config = _STRICT

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

    model_config = _STRICT

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

    model_config = _STRICT

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


class SimSettings(BaseModel):
    """How the simulated twin behaves beyond what the objects say."""

    model_config = _STRICT

    #: Encoder counts per motor revolution (6064h units) in the simulation.
    counts_per_rev: int = 1 << 17
    #: Rated velocity in counts/s that the simulated torque limit allows to reach.
    max_velocity: float = 5.0e5
    motor_inertia: float = 3.7e-5
    load_inertia_ratio: float = 3.0
    rated_torque: float = 1.27
    peak_torque: float = 3.8
    coulomb: float = 0.02
    viscous: float = 1.0e-4
    #: Values the simulated device reports (1018h etc.) when the profile has no default.
    serial_number: int = 1
    #: Homing switches in encoder counts from the power-on position (sim/homing.py); None:
    #: the default layout in revolutions (limits -1.7 / 3.7, home switch 1.3 to 1.7).
    limit_negative: int | None = None
    limit_positive: int | None = None
    home_switch_low: int | None = None
    home_switch_high: int | None = None
    #: Position of one index pulse; the others follow every counts_per_rev.
    index_offset: int = 0
    #: False: no switches are fitted (homing on a switch fails, 60FDh bits 0-2 stay 0).
    homing_switches: bool = True
    #: A switch search that travels this many revolutions without finding it fails.
    homing_max_travel_revs: float = 20.0
    #: I²t overload: thermal time constant [s] and the continuous current (torque) ratio to
    #: the rated value above which the overload fault trips.
    i2t_time_constant: float = 10.0
    i2t_limit_ratio: float = 1.15
    #: Speed [counts/s] that acceleration time constants in ms refer to (e.g. 609Ah of a
    #: drive whose ramps are "ms from 0 to the rated speed"); None: the maximum velocity.
    rated_speed: float | None = None
    #: The twin supervises its software position limits (607Dh:01/02) in profile velocity
    #: too, braking to stop at them (sim/engine_setpoints.py ``_limit_wall``), as servodesk's
    #: generic drive does; false where the manual confines them to profile position (LECSN-T 004
    #: §20.8.3, CTMM04x 003 §4-4-5/§4-4-6), so that the twin is no kinder than the drive.
    software_limits_in_pv: bool = True
    #: Servo loop and plant rate [Hz]: loop_rate_hz / 1000 plant sub-steps per 1 ms control
    #: cycle (docs/tuning.md; 4 kHz keeps five live twins in real time on a laptop).
    loop_rate_hz: int = Field(default=4000, ge=1000, le=32000)
    #: Integrate the plant exactly for the torque held over each step, as plant files do
    #: (model/plant.py ``PlantParams.exact``); false keeps the semi-implicit step every twin
    #: had until the third session of 2026-11-29, whose half-step phase lead damps a fast loop
    #: more than the machine would and biased what a tuning measured on the twin (the generic
    #: twin's friction at the test moves' speed 39 % high).
    exact_integration: bool = True

    @field_validator("loop_rate_hz")
    @classmethod
    def _whole_ticks(cls, v: int) -> int:
        if v % 1000:
            raise ValueError(f"{v} Hz: the loop rate must be a multiple of 1000 Hz")
        return v


#: The canonical servo gains (docs/tuning.md, "Canonical gains"): the fields of
#: :class:`~servodesk.domain.tuning.gains.ServoGains`, in order.
SERVO_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(ServoGains))

#: Gains a ``tuning.kind: gains`` profile must map: the cascade cannot run without them.
REQUIRED_GAINS: tuple[str, ...] = ("kp_pos", "kp_vel", "ti_vel")


def _check_address(v: str) -> str:
    """An object address as authored (``"0x2101:00"``, ``"P922"``); kept as written."""
    try:
        ObjectAddress.parse(v)
    except ServodeskError as exc:  # pydantic reports ValueErrors with their place.
        raise ValueError(exc.message) from exc
    return v


class GainObject(BaseModel):
    """Where one canonical gain lives: SI value = raw object value * ``scale``."""

    model_config = _STRICT

    #: The object's address, e.g. ``"0x2101:00"``.
    object: str
    scale: float = Field(default=1.0, gt=0)
    #: The SI unit of the canonical gain (docs/tuning.md), e.g. ``"N m s/rad"``.
    unit: str

    _address = field_validator("object")(_check_address)

    @property
    def address(self) -> ObjectAddress:
        return ObjectAddress.parse(self.object)


class TuningSpec(BaseModel):
    """How a family is tuned (docs/tuning.md): the drive's own built-in tuning, servodesk's
    tuning through a gain map, or nothing to tune."""

    model_config = _STRICT

    #: Sub-indexes of the test signal generator objects at ``signal_index``.
    SIGNAL_SUBS: ClassVar[int] = 8

    kind: Literal["gains", "builtin", "none"]
    #: Canonical gain name -> object and scale (kind ``gains``).
    gains: dict[str, GainObject] = Field(default_factory=dict)
    #: The read-only object reporting the servo loop rate [Hz], e.g. ``"0x2108:00"``.
    loop_rate_object: str | None = None
    #: The read-only object reporting the current loop bandwidth [Hz] (the tuning's model).
    current_loop_object: str | None = None
    #: Index of the test signal generator (subs 1-8, docs/tuning.md); simulated twins only.
    signal_index: int | None = Field(default=None, ge=0x2000, le=0x5FFF)
    section: str | None = None
    note: str | None = None

    @model_validator(mode="after")
    def _check(self) -> TuningSpec:
        unknown = sorted(set(self.gains) - set(SERVO_GAIN_NAMES))
        if unknown:
            raise ValueError(
                f"unknown gain {', '.join(unknown)}: the gains are {', '.join(SERVO_GAIN_NAMES)}"
            )
        if self.kind == "gains":
            missing = [g for g in REQUIRED_GAINS if g not in self.gains]
            if missing:
                raise ValueError(f"kind gains needs the gains {', '.join(missing)} mapped")
        for key in ("loop_rate_object", "current_loop_object"):
            text = getattr(self, key)
            if text is not None:
                try:
                    ObjectAddress.parse(text)
                except ServodeskError as exc:
                    raise ValueError(f"{key}: {exc.message}") from exc
        return self

    @property
    def loop_rate_address(self) -> ObjectAddress | None:
        if self.loop_rate_object is None:
            return None
        return ObjectAddress.parse(self.loop_rate_object)

    @property
    def current_loop_address(self) -> ObjectAddress | None:
        if self.current_loop_object is None:
            return None
        return ObjectAddress.parse(self.current_loop_object)


class RecorderSpec(BaseModel):
    """A drive-side recorder (trace function): objects sampled inside the drive at a fixed
    rate, with a trigger and pre-trigger, uploaded afterwards by SDO (docs/scope.md).

    Its objects sit at consecutive indexes from ``index`` (the offsets below). None of the
    families documents a trace function reachable over the fieldbus, so the shipped profiles
    give their simulated twin one (``sim_only``) in an index range the family leaves free.
    """

    model_config = _STRICT

    #: Offsets from ``index``: channels (ARRAY, sub n = ``index << 16 | sub << 8 | bits``),
    #: divider, depth, trigger, level, pre-trigger, control/status, data (DOMAIN), recorded
    #: count, trigger sample index.
    CHANNELS: ClassVar[int] = 0
    DIVIDER: ClassVar[int] = 1
    DEPTH: ClassVar[int] = 2
    TRIGGER: ClassVar[int] = 3
    LEVEL: ClassVar[int] = 4
    PRE_TRIGGER: ClassVar[int] = 5
    CONTROL: ClassVar[int] = 6
    DATA: ClassVar[int] = 7
    COUNT: ClassVar[int] = 8
    TRIGGER_INDEX: ClassVar[int] = 9

    #: First index of the recorder objects (manufacturer area).
    index: int = Field(ge=0x2000, le=0x5FFF - 9)
    max_channels: int = Field(default=8, ge=1, le=8)
    #: Most samples per channel (the depth object is UNSIGNED16).
    max_depth: int = Field(default=8192, ge=1, le=65535)
    #: Samples per second at divider 1: the simulated plant, ``simulation.loop_rate_hz``
    #: (a twin built from a plant file samples at that file's loop rate).
    rate_hz: float = Field(default=4000.0, gt=0)
    #: Only the simulated twin has it; a session on a real drive reports no recorder.
    sim_only: bool = True
    section: str | None = None
    note: str | None = None

    def object_index(self, offset: int) -> int:
        """The index of one recorder object, e.g. ``object_index(RecorderSpec.DATA)``."""
        return self.index + offset

    @staticmethod
    def recordable(spec: ObjectSpec) -> bool:
        """Whether the recorder can sample ``spec``: readable, and an integer of at most 32
        bits or a REAL32 (a sample is one INTEGER32 word)."""
        dt = spec.data_type
        return spec.access.readable and (
            (dt.is_integer and 0 < dt.bits <= 32) or dt is DataType.REAL32
        )


class NetworkObject(BaseModel):
    """An object that configures or reports the fieldbus connection (the Network page reads it)."""

    model_config = _STRICT

    #: The object's address, e.g. ``"0x1017:00"``; it must be an object of the profile.
    object: str
    #: What it tells the engineer about the network, in the manual's terms.
    note: str = Field(min_length=1)
    section: str = Field(min_length=1)

    _address = field_validator("object")(_check_address)

    @property
    def address(self) -> ObjectAddress:
        return ObjectAddress.parse(self.object)


class NetworkRule(BaseModel):
    """An addressing rule the engineer must know (switches, defaults, DHCP, ...)."""

    model_config = _STRICT

    text: str = Field(min_length=1)
    section: str = Field(min_length=1)


class NetworkLed(BaseModel):
    """One documented state of an LED: its colour or pattern and what it means."""

    model_config = _STRICT

    led: str = Field(min_length=1)
    state: str = Field(min_length=1)
    meaning: str = Field(min_length=1)
    section: str = Field(min_length=1)


class NetworkSpec(BaseModel):
    """How the family is addressed on its fieldbus, as its manual says (the Network
    configuration page; docs/profiles.md). Every entry cites its section."""

    model_config = _STRICT

    #: One or two sentences: how the family is found and addressed on its fieldbus.
    summary: str = Field(min_length=1)
    section: str = Field(min_length=1)
    #: The objects that configure or report the network, in the order the page lists them.
    objects: tuple[NetworkObject, ...] = ()
    addressing: tuple[NetworkRule, ...] = ()
    leds: tuple[NetworkLed, ...] = ()


class DeviceProfile(BaseModel):
    """A drive family: identity, objects, codes, modes, rules and quirks."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_version: Literal[1] = 1
    id: str = Field(pattern=r"^[a-z0-9][a-z0-9-]*$")
    version: str = "1"
    name: str
    vendor: str
    #: The fieldbus the family speaks: canopen, ethercat, cclink-ie-tsn, profinet.
    fieldbus: str
    description: str | None = None
    manuals: tuple[Manual, ...] = ()
    #: Another profile whose objects/errors this one includes (its own win by address).
    extends: str | None = None
    identity: FamilyIdentity = FamilyIdentity()
    modes: tuple[int, ...] = ()
    homing_methods: tuple[int, ...] = ()
    groups: tuple[Group, ...] = ()
    objects: tuple[ObjectEntry, ...] = ()
    errors: tuple[ErrorEntry, ...] = ()
    quirks: tuple[Quirk, ...] = ()
    contradictions: tuple[Contradiction, ...] = ()
    pdo: PdoRules = PdoRules()
    simulation: SimSettings = SimSettings()
    #: The drive-side recorder, where the drive (or its simulated twin) has one.
    recorder: RecorderSpec | None = None
    #: How the family is tuned (docs/tuning.md); None: not described.
    tuning: TuningSpec | None = None
    #: How the family is addressed on its fieldbus (the Network configuration page); None: the
    #: profile documents none.
    network: NetworkSpec | None = None

    @cached_property
    def variables(self) -> dict[ObjectAddress, ObjectSpec]:
        """Every (index, subindex) of the profile, in address order."""
        out: dict[ObjectAddress, ObjectSpec] = {}
        for entry in self.objects:
            for spec in entry.specs():
                out[spec.address] = spec
        return dict(sorted(out.items()))

    @cached_property
    def entries(self) -> dict[int, ObjectEntry]:
        return {e.index: e for e in self.objects}

    def spec(self, address: ObjectAddress) -> ObjectSpec | None:
        return self.variables.get(address)

    def quirk(self, quirk_id: str, default: Any = None) -> Any:
        """The value of quirk ``quirk_id`` (``default`` where the family has none). An id not in
        the registry (domain/quirks.py) raises: a typo must not read as "no quirk"."""
        quirks.spec(quirk_id)
        for q in self.quirks:
            if q.id == quirk_id:
                return q.value
        return default

    def dc_cycles_ns(self) -> tuple[int, int, int] | None:
        """(min, max, step) of the SYNC0 cycle the drive takes, in ns (quirk
        ``dc_cycle_time_ns``; HIWIN 000 §2.5); None where the profile names none."""
        q = self.quirk("dc_cycle_time_ns")
        if not isinstance(q, dict):
            return None
        return int(q["min"]), int(q["max"]), int(q["step"])

    def error(self, table: str, code: int) -> ErrorEntry | None:
        return self._errors.get((table, code))

    @cached_property
    def _errors(self) -> dict[tuple[str, int], ErrorEntry]:
        return {(e.table, e.code): e for e in self.errors}

    def error_tables(self) -> list[str]:
        return sorted({e.table for e in self.errors})


_NODEID = re.compile(
    r"^\s*\$NODEID\s*([+-])\s*(0x[0-9a-f]+|\d+)\s*$|^\s*(0x[0-9a-f]+|\d+)\s*\+\s*\$NODEID\s*$", re.I
)


def resolve_value(raw: Scalar, data_type: DataType, node_id: int = 0) -> Value | None:
    """Turn an authored value into a typed one; ``$NODEID+0x180`` adds the node id."""
    if raw is None:
        return None
    if isinstance(raw, str) and "$NODEID" in raw.upper():
        m = _NODEID.match(raw)
        if not m:
            raise ValueError(f"cannot read {raw!r}: write $NODEID+0x180")
        if m.group(3):
            return int(m.group(3), 0) + node_id
        off = int(m.group(2), 0)
        return node_id + off if m.group(1) == "+" else node_id - off
    if data_type.is_integer:
        return coerce_int(raw, data_type)
    if data_type.is_real:
        return float(raw)
    if data_type in (DataType.OCTET_STRING, DataType.DOMAIN) and isinstance(raw, str):
        return bytes.fromhex(raw.replace(" ", ""))
    return raw if isinstance(raw, str) else str(raw)
