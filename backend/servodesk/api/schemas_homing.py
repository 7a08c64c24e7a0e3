"""Models of homing and alarms (issue 4): the homing methods a profile offers, a run's
request, plan (estimate and time-out, domain/homing.py) and status, and the drive's alarms
(EMCY log, error history 1003h or the family's own, reset and clear)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from servodesk.api.schemas_profiles import ErrorInfo
from servodesk.services.homing import Outcome

HomingSignal = Literal["home_switch", "limit_negative", "limit_positive", "index"]


class HomingMethodOut(BaseModel):
    method: int
    name: str
    description: str
    uses: list[HomingSignal]
    direction: Literal["negative", "positive"] | None
    section: str | None
    equivalent: int | None = Field(
        default=None, description="vendor method: the CiA 402 method it is simulated as"
    )
    needs_enable: bool = Field(default=True, description="needs Operation enabled to start")


class HomingRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    method: int = Field(ge=-128, le=127)
    speed_switch: int | None = Field(default=None, ge=0, le=0xFFFFFFFF, description="6099h:01")
    speed_zero: int | None = Field(default=None, ge=0, le=0xFFFFFFFF, description="6099h:02")
    acceleration: int | None = Field(default=None, ge=0, le=0xFFFFFFFF, description="609Ah")
    offset: int | None = Field(default=None, ge=-(2**31), le=2**31 - 1, description="607Ch")
    max_travel: int | None = Field(
        default=None,
        gt=0,
        le=2**32 - 1,
        description="the span the searches may cover (position units) for the estimate; "
        "default: the software position limits 607Dh, or the twin's switches",
    )
    timeout_s: float | None = Field(
        default=None,
        gt=0,
        le=86400,
        description="halt and quick-stop the run after this many seconds; default: twice the "
        "estimate plus 30 s, within 60 s .. 1 h (300 s without an estimate)",
    )


class HomingBits(BaseModel):
    target_reached: bool
    homing_attained: bool
    homing_error: bool


class HomingPhaseOut(BaseModel):
    name: str
    distance: float = Field(description="position units")
    speed: float = Field(description="position units per s")
    seconds: float
    speed_object: str = Field(description='the object that sets the speed, e.g. "6099h:02"')


class HomingEstimateOut(BaseModel):
    seconds: float = Field(description="the longest a normal run takes from any start")
    phases: list[HomingPhaseOut]
    assumptions: list[str]


#: How a run ended, "running" while it lasts: the service's one list (services/homing.py).
HomingOutcome = Outcome


class HomingPlanOut(BaseModel):
    """What a run is expected to take: the estimate and the time-out (domain/homing.py)."""

    estimate_s: float | None
    estimate: HomingEstimateOut | None
    basis: str = Field(description="where the travel came from, or why there is no estimate")
    travel: float | None
    speed_switch: float | None = Field(description="6099h:01 in position units per s")
    speed_zero: float | None = Field(description="6099h:02 in position units per s")
    acceleration: float | None = Field(description="609Ah in position units per s²")
    timeout_s: float
    timeout_source: Literal["user", "estimate", "default"]
    warnings: list[str]


class HomingRunOut(HomingPlanOut):
    id: int
    method: int
    active: bool
    outcome: HomingOutcome = Field(
        description="how the run ended (running while it lasts): the motion's end, not only "
        "the statusword (docs/api.md)"
    )
    message: str
    watched: bool = Field(description="a motion under the client's dead-man")
    started_at: float = Field(description="Unix time")
    elapsed_s: float
    phase: str | None = Field(description="what statusword bits 13/12/10 say (mode 6 only)")


class HomingStatus(BaseModel):
    session: str
    method: int | None
    state: Literal["idle", "running", "attained", "error"]
    position: int | None
    statusword_bits: HomingBits
    message: str
    run: HomingRunOut | None = Field(
        default=None, description="the last run started through servodesk on this session"
    )


class EmcyLogEntry(BaseModel):
    model_config = ConfigDict(populate_by_name=True)

    time: float | None
    code: int
    code_hex: str
    name: str | None
    cause: str | None
    remedy: str | None
    # "register" would shadow a BaseModel attribute; the JSON key stays "register".
    error_register: int = Field(alias="register", description="error register (1001h)")


class AlarmHistoryEntry(BaseModel):
    source: str = Field(description='"1003h" or the family object, e.g. "0x2A00:01"')
    index: int
    code: int
    code_hex: str
    name: str
    cause: str | None
    remedy: str | None
    time_h: int | None = None


class AlarmsOut(BaseModel):
    session: str
    current: ErrorInfo | None
    state: str
    emcy_log: list[EmcyLogEntry]
    history: list[AlarmHistoryEntry]
    reset_procedure: str
    can_clear_history: bool
    #: POST /alarms/reset: what the reset did (nothing is sent outside Fault, CiA 402-2 §6.2.1).
    message: str | None = None


class ClearHistoryRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    confirm: Literal[True] = Field(description="Must be true: the history is gone afterwards")
