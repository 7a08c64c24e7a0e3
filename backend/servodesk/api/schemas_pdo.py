"""Request and response models of the PDO mapping and cyclic data routes (api/routes/pdo.py,
docs/pdo.md "REST"); the answers are built from the dicts of services/pdo.py and
services/cyclic.py (api/reply.py)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from servodesk.api.reply import Reply

#: A request body takes only the fields it declares: a misspelt one is a 422 naming it.
_BODY = ConfigDict(extra="forbid")

Direction = Literal["rx", "tx"]
SyncMode = Literal["freerun", "dc"]


class PdoProblemOut(Reply):
    """A reason a mapping is refused, shown next to the PDO, entry and field it names."""

    message: str
    pdo: str | None = Field(description='the PDO ("TPDO2"); null: the whole mapping')
    entry: int | None = Field(description="0-based entry position in that PDO")
    field: str | None = Field(description='"entries", "cob_id", "assignment", "telegram", ...')
    section: str | None = Field(description="the manual's section of the rule")


class PdoEntryOut(Reply):
    index: int
    subindex: int
    bits: int
    raw_hex: str = Field(description="the mapping entry as written (CiA 301 §7.5.2.36)")
    address: str | None = Field(description='"0x6064:00"; null for padding')
    name: str
    data_type: str | None = Field(description='the type\'s name ("INTEGER32")')
    unit: str | None
    offset_bits: int
    offset_byte: int
    padding: bool


class PdoOut(Reply):
    direction: Direction
    number: int
    name: str
    mapping_index: int
    comm_index: int | None = Field(
        description="null: the family has no communication parameters (ethercat, fixed, telegram)"
    )
    cob_id: int = Field(description="the identifier it travels on: its COB-ID, or 180h/200h + node")
    cob_id_hex: str
    enabled: bool
    rtr_allowed: bool | None
    transmission_type: int | None
    transmission_text: str | None
    inhibit_time: int | None = Field(description="[100 us]")
    inhibit_time_ms: float | None
    event_timer: int | None = Field(description="[ms]")
    sync_start: int | None
    active: bool = Field(
        description="on the bus: enabled (canopen), assigned (ethercat), always (fixed, telegram)"
    )
    bits: int
    max_bits: int
    bytes: int
    frame_length: int
    entries: list[PdoEntryOut]


class PdoTelegramOut(Reply):
    """One PROFIdrive telegram of the family (004 §20.3): a fixed one's layout cannot change."""

    number: int
    name: str
    bytes: int = Field(description="IO data per direction; a variable mapping must fill it")
    max_entries: int
    variable: bool
    controlword: bool = Field(
        description="the setpoint telegram carries the controlword 6040h (the CiA 402 state "
        "machine: servo on, jog and moves)"
    )


class PdoRulesOut(Reply):
    max_entries: int
    max_bits: int
    max_bytes: int | None = Field(description="bytes per direction over all active PDOs")
    mapping_state: str = Field(description='"preop", "safeop", "any" or "fixed"')
    section: str | None
    rpdo_count: int
    tpdo_count: int
    telegrams: list[PdoTelegramOut] = Field(description="empty but for the telegram kind")


class PdoAssignment(Reply):
    """EtherCAT: the mapping objects assigned to the sync managers (1C12h/1C13h); the
    configuration always has both (domain/pdo_objects.py, domain/pdo_json.py)."""

    rx: list[int]
    tx: list[int]


class PdoView(Reply):
    """GET /pdo, and the ``view`` of validate, templates and apply."""

    kind: Literal["canopen", "ethercat", "fixed", "telegram"]
    byte_order: Literal["little", "big"]
    rules: PdoRulesOut
    pdos: list[PdoOut]
    assignment: PdoAssignment | None = Field(description="EtherCAT's; null for the others")
    telegram: int | None
    nmt_state: str
    apply_unavailable: str | None = Field(
        description="why the session's link does not write the mapping (PROFINET: the IO "
        "controller's); the layout can still be edited, checked and exported"
    )
    problems: list[PdoProblemOut]


class MappableObject(Reply):
    address: str
    index: int
    subindex: int
    name: str
    data_type: str
    bits: int
    unit: str | None
    direction: Literal["rx", "tx", "both"]


class PdoMappable(Reply):
    rx: list[MappableObject]
    tx: list[MappableObject]


class PdoTemplateOut(Reply):
    id: str
    name: str
    description: str
    section: str | None


class PdoValidation(Reply):
    ok: bool
    problems: list[PdoProblemOut]
    view: PdoView


class PdoStepOut(Reply):
    kind: Literal["write", "nmt"]
    address: str | None
    value: int
    value_hex: str | None
    command: str | None = Field(description='nmt: "preop", "start" or "stop"')
    why: str


class PdoPlan(Reply):
    steps: list[PdoStepOut]
    touched: list[str] = Field(description="the PDOs the plan changes")


class PdoApplyReport(Reply):
    ok: bool
    dry_run: bool
    steps: list[PdoStepOut]
    touched: list[str]
    done: int = Field(description="steps done before the end (all of them when ok)")
    duration_s: float
    verified: bool
    rolled_back: bool
    error: str | None
    failed_step: PdoStepOut | None
    view: PdoView | None = Field(description="the drive after the run; null when unreadable")
    rollback_error: str | None = Field(
        default=None, description="a failed apply: why the previous mapping is not back"
    )


class PdoIdleFix(Reply):
    """One change that makes a silent event-driven TPDO send (a PDO change, needs control)."""

    label: str
    transmission_type: int | None
    event_timer: int | None = Field(description="[ms]")


class PdoIdle(Reply):
    why: str
    fixes: list[PdoIdleFix]


class PdoRate(Reply):
    name: str
    cob_id: int
    cob_id_hex: str
    count: int
    rate_hz: float | None = Field(description="null for RX PDOs (sent with each SYNC)")
    errors: int = Field(description="frames that could not be decoded")
    idle: PdoIdle | None = Field(
        description="why this TPDO sends nothing now and what makes it send (issue 48)"
    )


class PdoLiveValue(Reply):
    """One mapped object's latest value from the cyclic data."""

    value: int | float | bool | str = Field(description="as the frame carries it")
    engineering: float | None
    unit: str | None
    raw_unit: str | None
    pdo: str = Field(description="the PDO that carried it")
    age_s: float | None = Field(description="seconds since the frame that carried it")
    stale: bool = Field(description="the link cannot vouch for it (docs/ethercat.md)")


class SlaveHealth(Reply):
    position: int
    node_id: int
    wkc_errors: int
    missing_frames: int
    al_state: str | None
    al_status_code: int


class PdoLinkHealth(Reply):
    """What the cycles say about an EtherCAT line (links/ethercat_health.py) or a PROFINET
    IO AR (links/profinet_io.py: ``ar``, ``data_status_errors``, ``cycle_ms``,
    ``watchdog_ms``; ``missing_frames`` are the input frames lost)."""

    state: Literal["ok", "degraded", "link lost", "recovering"]
    reason: str | None
    stale: bool
    cycles: int
    wkc_errors: int
    missing_frames: int
    last_wkc: int | None
    expected_wkc: int
    carrier: bool | None
    losses: int
    since_good_s: float | None
    slaves: list[SlaveHealth]
    ar: str | None = Field(default=None, description="PROFINET: the AR cyclic data runs in")
    data_status_errors: int | None = Field(
        default=None, description="PROFINET: input frames whose DataStatus or IOPS was not good"
    )
    cycle_ms: float | None = Field(default=None, description="PROFINET: the IOCR's cycle")
    frames_received: int | None = Field(
        default=None, description="PROFINET: input frames received from the device"
    )
    watchdog_ms: float | None = Field(
        default=None, description="PROFINET: inputs missing this long make the link lost"
    )


class PdoCyclicStatus(Reply):
    """The cyclic exchange. Keys with a default are in some answers only: ``link`` and
    ``stale`` while it runs, ``unavailable`` in GET's, the offer in all but PUT outputs'."""

    running: bool
    sync_period_ms: float | None
    sync: SyncMode | None
    outputs: bool
    syncs: int = Field(description="SYNCs sent")
    rx_pdos: list[PdoRate]
    tx_pdos: list[PdoRate]
    frames_per_s: float
    decode_errors: int
    values: dict[str, PdoLiveValue] = Field(description="by address")
    link: PdoLinkHealth | None = Field(
        default=None, description="EtherCAT: the line's health; null elsewhere"
    )
    stale: bool = Field(
        default=False, description="the received values are not the drive's present ones"
    )
    unavailable: str | None = Field(
        default=None, description="why the session's link carries no cyclic data (SLMP)"
    )
    sync_modes: list[SyncMode] = Field(
        default_factory=list, description='"freerun", and "dc" where the drive takes SYNC0'
    )
    dc_cycle_ns: list[int] | None = Field(
        default=None, description="the SYNC0 cycles the drive takes: [min, max, step] [ns]"
    )
    periods_ms: list[float] | None = Field(
        default=None,
        description="the only cycles the link offers (PROFINET: 1 ms send clock x reduction "
        "ratio); null: any period from 1 to 1000 ms",
    )
    telegrams: list[PdoTelegramOut] | None = Field(
        default=None,
        description="PROFINET: the telegrams servodesk's IO AR can be set up with (POST's "
        "telegram); null where cyclic data has no telegram to choose",
    )
    telegram: int | None = Field(
        default=None, description="PROFINET: the telegram the running IO AR exchanges"
    )


class EntryIn(BaseModel):
    model_config = _BODY
    index: int = Field(ge=0, le=0xFFFF)
    subindex: int = Field(ge=0, le=0xFF)
    bits: int = Field(ge=0, le=64)


class PdoIn(BaseModel):
    model_config = _BODY
    direction: Literal["rx", "tx"]
    number: int = Field(ge=1, le=512)
    entries: list[Annotated[str, Field(max_length=32)] | EntryIn] | None = Field(
        default=None, max_length=64
    )
    cob_id: int | None = Field(default=None, ge=0, le=0x7FF)
    enabled: bool | None = None
    rtr_allowed: bool | None = None
    transmission_type: int | None = Field(default=None, ge=0, le=255)
    inhibit_time: int | None = Field(default=None, ge=0, le=0xFFFF)
    event_timer: int | None = Field(default=None, ge=0, le=0xFFFF)
    sync_start: int | None = Field(default=None, ge=0, le=240)


class PdoLayout(BaseModel):
    model_config = _BODY
    pdos: list[PdoIn] = Field(default_factory=list, max_length=64)
    assignment: dict[Literal["rx", "tx"], list[Annotated[int, Field(ge=0, le=0xFFFF)]]] | None = (
        None
    )
    telegram: int | None = Field(default=None, ge=0, le=65535)


class ApplyRequest(PdoLayout):
    dry_run: bool = False


class PdoCyclicRequest(BaseModel):
    model_config = _BODY
    sync_period_ms: float = Field(default=10.0, ge=1.0, le=1000.0)
    outputs: bool = False
    #: "dc": the drive's SYNC0 event from the distributed clocks at the period (EtherCAT
    #: drives whose profile names the cycles they take); "freerun": its own cycle.
    sync: Literal["freerun", "dc"] = "freerun"
    #: PROFINET: the telegram servodesk's IO AR is set up with (its expected submodule, as an
    #: IO controller's configuration tool chooses it from the GSD file, 004 §20.1.1; the
    #: drive's P922 follows). Left out: the drive's present telegram.
    telegram: int | None = Field(default=None, ge=1, le=65535)


class OutputsRequest(BaseModel):
    model_config = _BODY
    values: dict[Annotated[str, Field(max_length=32)], int | float | bool] = Field(max_length=64)
