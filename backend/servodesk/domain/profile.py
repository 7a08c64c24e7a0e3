"""The device profile model: what a drive family is, as data (see docs/profiles.md).

A profile is authored as ``profiles/<id>/profile.yaml`` and validated on load by these
pydantic models (unknown keys are refused). Objects are authored per index (VAR, ARRAY or
RECORD) and flattened into one :class:`ObjectSpec` per (index, subindex), which is what
every other layer uses.

The sections of a profile that have a life of their own are models in their own modules
(profile_pdo.py: ``pdo:``, profile_tuning.py: ``tuning:``, profile_network.py: ``network:``,
their shared configuration in profile_base.py); this module is the model's one entry point
and names them too, so ``from servodesk.domain.profile import PdoRules`` is the import.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Iterator
from functools import cached_property
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from servodesk.domain import quirks
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value, coerce_int
from servodesk.domain.profile_base import STRICT, parse_data_type
from servodesk.domain.profile_network import (
    NetworkLed as NetworkLed,
)
from servodesk.domain.profile_network import (
    NetworkObject as NetworkObject,
)
from servodesk.domain.profile_network import (
    NetworkRule as NetworkRule,
)
from servodesk.domain.profile_network import (
    NetworkSpec as NetworkSpec,
)
from servodesk.domain.profile_pdo import (
    DcOpMode as DcOpMode,
)
from servodesk.domain.profile_pdo import (
    PdoRules as PdoRules,
)
from servodesk.domain.profile_pdo import (
    PdoTelegram as PdoTelegram,
)
from servodesk.domain.profile_pdo import (
    PdoTemplate as PdoTemplate,
)
from servodesk.domain.profile_pdo import (
    PdoTemplatePdo as PdoTemplatePdo,
)
from servodesk.domain.profile_pdo import (
    PdoWord as PdoWord,
)
from servodesk.domain.profile_pdo import (
    SyncManagerSpec as SyncManagerSpec,
)
from servodesk.domain.profile_pdo import (
    parse_type_ranges as parse_type_ranges,
)
from servodesk.domain.profile_tuning import (
    REQUIRED_GAINS as REQUIRED_GAINS,
)
from servodesk.domain.profile_tuning import (
    SERVO_GAIN_NAMES as SERVO_GAIN_NAMES,
)
from servodesk.domain.profile_tuning import (
    GainObject as GainObject,
)
from servodesk.domain.profile_tuning import (
    RecorderSpec as RecorderSpec,
)
from servodesk.domain.profile_tuning import (
    TuningSpec as TuningSpec,
)

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


class ObjectSpec(BaseModel):
    """One variable of the object dictionary: what it is, its limits, its units."""

    model_config = STRICT

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

    _dt = field_validator("data_type", mode="before")(parse_data_type)

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

    model_config = STRICT

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

    _dt = field_validator("data_type", mode="before")(parse_data_type)


class ObjectEntry(BaseModel):
    """One index as authored in profile.yaml."""

    model_config = STRICT

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
        return parse_data_type(v)

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

    model_config = STRICT

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

    model_config = STRICT

    id: str
    value: Any = True
    section: str | None = None
    note: str | None = None


class Contradiction(BaseModel):
    """Two passages (or manual versions) that disagree, and which value the profile uses."""

    model_config = STRICT

    topic: str
    chosen: str
    chosen_section: str
    other: str
    other_section: str
    note: str | None = None


class FamilyIdentity(BaseModel):
    """How a session recognises the family from 1018h (or the fieldbus's identity)."""

    model_config = STRICT

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
    model_config = STRICT

    id: str
    title: str
    version: str | None = None
    language: str | None = None


class Group(BaseModel):
    """A parameter group as shown on the Parameters page (ordered)."""

    model_config = STRICT

    id: str
    name: str
    name_local: str | None = None
    description: str | None = None


class SimSettings(BaseModel):
    """How the simulated twin behaves beyond what the objects say."""

    model_config = STRICT

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
