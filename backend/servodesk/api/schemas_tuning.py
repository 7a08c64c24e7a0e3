"""Response models of the tuning routes (api/routes/tuning.py, docs/tuning.md "Service and
API"), built from the dicts of services/tuning/ (api/reply.py).

A result is put together in several places: services/tuning/records.py (``job_result``: every
result), builtin.py (the drive's own one-touch tuning) and own.py (servodesk's, merged over
the former by jobs.py). A key only one of them sends is a field with a default here, and the
routes leave out what a producer did not send (``response_model_exclude_unset``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from servodesk.api.reply import Reply
from servodesk.domain.tuning.design import ResponseLevel
from servodesk.services.tuning.capabilities import (
    MAX_MOVE_TORQUE_PCT,
    MAX_TORQUE_PCT,
    MAX_TRAVEL_REV,
)

#: A request body takes only the fields it declares: a misspelt one is a 422 naming it.
_BODY = ConfigDict(extra="forbid")

Kind = Literal["builtin", "gains", "none"]
JobState = Literal["running", "done", "failed", "stopped"]
#: A gain's raw value as the drive holds it (domain/datatypes.py Value: a gain is a number,
#: or a string where the drive's type is one).
GainValue = int | float | str
#: Position units: whole counts where the code rounds, else a float (both kept as sent).
Units = int | float


class TuningError(Reply):
    """A decoded result code: the drive's (builtin: P11604 with the profile's table) or
    servodesk's reason (code null)."""

    code: int | None
    code_hex: str | None
    name: str
    cause: str | None
    remedy: str | None
    section: str | None = Field(default=None, description="the drive's codes only")


class TravelBound(Reply):
    """The travel bound: start +- half the window [position units] (docs/tuning.md "Travel
    window"); servodesk's own tuning adds how far the axis went."""

    start: Units
    low: Units
    high: Units
    half: Units
    half_rev: float | None
    raw_unit: str | None
    text: str | None = Field(default=None, description="the bound in words, rev and units")
    lowest: Units | None = None
    highest: Units | None = None
    max_excursion: Units | None = None
    max_excursion_rev: float | None = None
    software_limits: bool | None = Field(
        default=None, description="the drive's software position limits (607Dh) held it too"
    )


class TuningJob(Reply):
    id: str
    session: str
    kind: Kind
    mode: str
    state: JobState
    progress: float
    step: str
    owner: str
    started: float
    ended: float | None
    message: str
    error: TuningError | None
    travel_window_rev: float
    bound: TravelBound | None = Field(description="the bound the window gives around the start")
    torque_limit_pct: float
    move_torque_pct: float | None = Field(description="null: the torque limit of the run")


class GainRow(Reply):
    name: str
    label: str
    object: str
    symbol: str | None
    unit: str | None
    raw_unit: str | None
    scale: float = Field(description="value = raw x scale")
    value: float | None
    raw: GainValue | None
    default: GainValue | None
    error: str | None = Field(description="why the gain could not be read")


class TuningApplies(Reply):
    """Where to tune a drive servodesk does not tune (a parameters page)."""

    page: str
    group: str
    label: str


class TuningDefaults(Reply):
    mode: ResponseLevel
    travel_window_rev: float
    torque_limit_pct: float


class TuningRange(Reply):
    min: float
    max: float


class TuningLimits(Reply):
    travel_window_rev: TuningRange
    torque_limit_pct: TuningRange
    move_torque_pct: TuningRange


class TuningPosition(Reply):
    actual: int | None
    raw_unit: str | None
    unit: str | None
    scale: float
    units_per_rev: Units
    units_per_rev_source: str
    min: Units | None
    max: Units | None
    limits_source: str | None


class TuningTorqueLimit(Reply):
    object: str | None
    present_pct: float | None


class TuningUndo(Reply):
    before: bool
    defaults: bool
    note: str | None


class TuningInfo(Reply):
    """GET /tuning: what the drive's tuning is, its gains and limits, and the job."""

    session: str
    profile_id: str
    profile_name: str
    kind: Kind
    reason: str
    applies: list[TuningApplies]
    modes: list[ResponseLevel]
    mode_notes: dict[str, str] = Field(
        description="what servodesk's own tuning promises at each level (empty otherwise)"
    )
    gains: list[GainRow]
    loop_rate_hz: float | None
    defaults: TuningDefaults
    travel_rule: str | None = Field(description="what the travel window means for this kind")
    limits: TuningLimits
    position: TuningPosition
    torque_limit: TuningTorqueLimit
    state: str = Field(description="the CiA 402 state")
    step_source: Literal["recorder", "sdo"] | None
    undo: TuningUndo
    job: TuningJob | None
    result_available: bool


class Resonance(Reply):
    freq_hz: float
    anti_freq_hz: float | None
    peak_db: float | None
    damping: float = Field(description="the damping ratio the design used")


class Refit(Reply):
    """The model's inertias fitted to the recordings of the winner's try (services/tuning/
    own.py ``_redesign``)."""

    motor_inertia_factor: float
    load_inertia_factor: float
    total_held: bool = Field(description="only the split between motor and load was fitted")
    error_rms_counts_before: float
    error_rms_counts_after: float
    outcome: Literal["fit_not_used", "searched_again", "first_kept"]
    searched_settling_s: float | None
    first_settling_s: float | None


class Identified(Reply):
    inertia_kgm2: float | None
    inertia_ratio: float | None
    coulomb_nm: float | None
    viscous_nms: float | None
    gravity_nm: float | None
    travel_friction_nm: float | None
    ranking_friction_nm: float | None
    resonances: list[Resonance]
    moves_friction_nm: float | None = Field(
        default=None, description="servodesk's own: the test moves' friction c + b v [N m]"
    )
    moves_speed_rad_s: float | None = Field(default=None, description="their cruise speed")
    refit: Refit | None = Field(default=None, description="servodesk's own tuning only")


class Bode(Reply):
    freq_hz: list[float]
    measured_mag_db: list[float]
    measured_phase_deg: list[float]
    coherence: list[float]
    model_mag_db: list[float]
    model_phase_deg: list[float]


class Margins(Reply):
    phase_margin_deg: float | None
    gain_margin_db: float | None
    crossover_hz: float | None
    bandwidth_hz: float | None


class ResultGain(Reply):
    name: str
    object: str
    unit: str | None
    before: float | None
    after: float | None
    raw_before: GainValue | None
    raw_after: GainValue | None
    label: str | None = Field(default=None, description="the drive's own tuning")
    symbol: str | None = None
    raw_unit: str | None = None


class StepMetrics(Reply):
    settling_s: float | None
    overshoot: float | None
    following_error_rms: float | None
    # servodesk's own tuning's figures beside them (docs/tuning.md).
    settling_10_s: float | None = None
    settling_100_s: float | None = None
    settling_10_smoothed_s: float | None = None
    overshoot_counts: float | None = None


class StepResponse(Reply):
    t_s: list[float]
    position: list[float]
    target: float
    unit: str
    metrics: StepMetrics
    # The drive's own tuning: how the response was sampled.
    units_per_rev: float | None = None
    source: Literal["recorder", "sdo"] | None = None
    rate_hz: float | None = None
    note: str | None = None


class StepPair(Reply):
    before: StepResponse | None
    after: StepResponse | None


class TuningResult(Reply):
    """GET /tuning/result: the last job's (docs/tuning.md ``TuningResult``)."""

    kind: Kind
    status: Literal["done", "failed", "stopped"]
    error: TuningError | None
    drive_code: TuningError | None
    mode: str
    job: str = Field(description="the job's id")
    identified: Identified | None
    bode: Bode | None
    margins: Margins | None
    gains: list[ResultGain]
    step: StepPair | None
    axis_time_s: float | None
    excursion_rev: float | None = Field(description="the span the axis moved over [rev]")
    travel: TravelBound | None
    peak_torque_pct: float | None
    peak_torque_polled_s: float | None = Field(
        description="the peak is the largest of 6077h polls this far apart; null: recorded"
    )
    applied: bool
    stored: bool
    notes: list[str]
    loop_rate_hz: float | None = Field(default=None, description="servodesk's own tuning")
    counts_per_rev: Units | None = Field(default=None, description="servodesk's own tuning")
    undone: Literal["before", "defaults"] | None = Field(
        default=None, description="the gains were put back since"
    )


class UndoResult(Reply):
    session: str
    to: Literal["before", "defaults"]
    gains: list[GainRow]
    stored: bool
    note: str


class TuningStored(Reply):
    """POST /tuning/store: the session's store (StoreResult) and the session."""

    session: str
    stored: int = Field(description="dirty entries now saved")
    duration_s: float
    procedure: str


class TuningRecord(Reply):
    """A tuning kept in the store (services/tuning_store.py): which drive, where, how it
    ended. GET /sessions/{sid}/tuning/results lists them, newest first."""

    id: str = Field(description="the stored result's id (GET /tuning/results/{id})")
    drive_key: str = Field(description="vendor-product-serial (1018h), else profile@bus")
    session: str = Field(description="the session it ran in")
    gateway: str = Field(description="the gateway it ran on")
    kind: Kind
    mode: str
    status: Literal["done", "failed", "stopped"]
    started: float = Field(description="when the job started [s since the epoch]")
    ended: float = Field(description="when the job ended [s since the epoch]")
    by: str = Field(description="the user who started it ('local' in single-user mode)")
    client: str = Field(description="the client (browser tab, CLI) that started it")
    applied: bool = Field(description="the tuning's gains were left on the drive when it ended")


class StoredTuningResult(TuningRecord):
    """GET /tuning/results/{id}: a stored tuning with its TuningResult as it ended."""

    result: TuningResult


class StartRequest(BaseModel):
    model_config = _BODY
    mode: ResponseLevel = Field(description="response mode")
    travel_window_rev: float = Field(
        gt=0,
        le=MAX_TRAVEL_REV,
        allow_inf_nan=False,
        description="total width of the travel window [rev], centred on where the axis stands: "
        "the axis stays within +- half of it, rounded down to whole position units (the job's "
        "`bound` says it in revolutions and units)",
    )
    torque_limit_pct: float = Field(
        gt=0,
        le=MAX_TORQUE_PCT,
        allow_inf_nan=False,
        description="torque limit during the run [% of rated], written to 6072h",
    )
    move_torque_pct: float | None = Field(
        default=None,
        gt=0,
        le=MAX_MOVE_TORQUE_PCT,
        allow_inf_nan=False,
        description="servodesk's own tuning: the peak torque of the machine's own moves "
        "[% of rated]; the gains are ranked on a 0.5 rev jerk-limited move accelerating at 70 % "
        "of it. Null: the torque limit of the run",
    )


class UndoRequest(BaseModel):
    model_config = _BODY
    to: Literal["before", "defaults"]


class EmptyBody(BaseModel):
    model_config = _BODY
