"""Models of operation (issue 4): taking control of a drive (the dead-man and what protects
the axis when its operator is lost), the motions (jog, move, velocity, torque, cyclic), their
status, and the limits and units the motion requests are checked against."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

_I32_MIN, _I32_MAX, _U32_MAX = -(2**31), 2**31 - 1, 2**32 - 1


class ControlRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    action: Literal["take", "release", "force_take"]
    confirm: bool = Field(
        default=False, description="Must be true for force_take when another client holds it"
    )


class ProtectionOut(BaseModel):
    deadman_ms: int = Field(description="Heartbeats older than this stop the axis")
    stop_path: Literal["dead-man thread", "event loop"] = Field(
        description="Where the dead-man's quick stop is sent from: its own thread straight "
        "onto the fieldbus, or the event loop (fieldbuses without such a path)"
    )
    drive_watchdog: str | None = Field(
        description="The drive's own watchdog armed by servodesk (a dead PC stops the axis), "
        "or null: none is armed"
    )
    summary: str = Field(description="One sentence for people")


class ControlOut(BaseModel):
    session: str
    owner: str | None = Field(description="Client id (label) of the holder, or null")
    user: str | None = Field(
        default=None,
        description='The account holding control ("local" in the single-user mode), or null',
    )
    since: float | None = Field(description="When it was taken (Unix time)")
    you: bool = Field(description="The request's X-Servodesk-Control token is the holder's")
    token: str | None = Field(
        default=None,
        description="The control token, only to its holder: send it as X-Servodesk-Control "
        "and bind a WebSocket with it",
    )
    bound: bool = Field(
        default=False, description="A WebSocket is bound to this control (the dead-man)"
    )
    orphaned: bool = Field(
        default=False,
        description="The holder's WebSocket closed: the drive was made safe and control "
        "lapses unless the holder binds a socket again within the grace time",
    )
    protection: ProtectionOut | None = Field(
        default=None, description="What stops this drive when its operator is lost"
    )


class JogRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    velocity: int = Field(
        description="Signed velocity, raw units (e.g. inc/s)", ge=_I32_MIN, le=_I32_MAX
    )
    acceleration: int = Field(
        description="Acceleration and deceleration, raw units", gt=0, le=_U32_MAX
    )


class MoveRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    mode: Literal["absolute", "relative"] = "absolute"
    target: int = Field(
        description="Target position or distance, raw units", ge=_I32_MIN, le=_I32_MAX
    )
    velocity: int | None = Field(
        default=None, description="Profile velocity 6081h", gt=0, le=_U32_MAX
    )
    acceleration: int | None = Field(default=None, description="6083h", gt=0, le=_U32_MAX)
    deceleration: int | None = Field(default=None, description="6084h", gt=0, le=_U32_MAX)
    immediate: bool = Field(
        default=True,
        description="Controlword bit 5: true replaces a running move (single set-point), "
        "false queues it after the running one (set of set-points)",
    )


class VelocityRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    velocity: int = Field(description="Target velocity 60FFh, raw units", ge=_I32_MIN, le=_I32_MAX)
    acceleration: int | None = Field(default=None, gt=0, le=_U32_MAX)
    deceleration: int | None = Field(default=None, gt=0, le=_U32_MAX)


class TorqueRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    torque: int = Field(
        description="Target torque 6071h, raw units (0.1 % of rated)", ge=_I32_MIN, le=_I32_MAX
    )
    slope: int | None = Field(default=None, description="Torque slope 6087h", gt=0, le=_U32_MAX)


class CyclicMotionRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    mode: Literal["csp", "csv", "cst"]
    waveform: Literal["sine", "ramp"] = "sine"
    amplitude: float = Field(
        ge=0, le=2**31 - 1, description="Around the start (csp) or 0 (csv, cst), raw units"
    )
    frequency: float = Field(gt=0, le=10, description="Hz")
    duration: float = Field(gt=0, le=60, description="Seconds (rounded up to whole periods)")


class StopRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")


class MotionStatusOut(BaseModel):
    session: str
    active: bool
    kind: Literal["jog", "move", "velocity", "torque", "cyclic", "homing", "tuning"] | None
    owner: str | None
    mode: int | None
    target: float | None
    state: str = Field(
        description="idle, running, reached, done, halted, stopped, deadman, timeout (homing) "
        "or error"
    )
    message: str


class UnitOut(BaseModel):
    raw_unit: str | None
    unit: str | None
    scale: float
    default: int | None = Field(
        default=None, description="the profile's default of the object (raw), where it has one"
    )
    ramp: Literal["rate", "time", "register"] | None = Field(
        default=None,
        description="acceleration only: the ramp objects hold a rate (units per s²), a time "
        "(ms to the rated speed) or a register (docs/api.md)",
    )


class LimitsOut(BaseModel):
    position_min: int | None = Field(description="607Dh:01 (null: no limit)")
    position_max: int | None = Field(description="607Dh:02 (null: no limit)")
    max_velocity: int | None = Field(description="607Fh")
    max_torque: int | None = Field(description="6072h")
    max_acceleration: int | None = Field(description="60C5h")
    max_deceleration: int | None = Field(description="60C6h")
    modes: list[int]
    mode_names: dict[str, str]
    units: dict[str, UnitOut]
    sources: dict[str, str] = Field(description="Where each limit was read")
