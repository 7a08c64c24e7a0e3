"""Request and response models of the live scope routes (api/routes/scope.py, docs/scope.md
"REST"); the answers are built from the dicts of services/scope.py and domain/scope_export.py
(api/reply.py)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from servodesk.api.reply import Reply
from servodesk.domain.scope import MAX_CHANNELS

#: A request body takes only the fields it declares: a misspelt one is a 422 naming it.
_BODY = ConfigDict(extra="forbid")

Source = Literal["auto", "pdo", "sdo", "recorder"]
AchievedSource = Literal["pdo", "sdo", "recorder"]


class ScopeChannelStatus(Reply):
    """One channel as the scope has it (ScopeStatus.channels)."""

    id: int
    session: str
    address: str
    name: str
    unit: str | None = Field(description="engineering unit (profile)")
    raw_unit: str | None = Field(description="unit of the raw value in the drive (profile)")
    eng_scale: float = Field(description="engineering = raw x eng_scale (profile)")
    scale: float = Field(description="display scale: shown = engineering x scale + offset")
    offset: float
    visible: bool
    label: str | None
    source: AchievedSource = Field(description="the source the channel got")
    requested_source: Source
    requested_rate_hz: float | None = Field(description="null: as fast as it goes")
    rate_hz: float | None = Field(description="achieved sample rate (the samples' spacing)")
    throughput_hz: float | None = Field(
        description="samples per second that arrived lately (a recorder's uploads leave gaps)"
    )
    samples: int
    error: str | None


class ScopeTrigger(Reply):
    mode: Literal["roll", "single", "normal"]
    kind: Literal["level", "edge", "state", "fault"]
    channel: int
    level: float
    slope: Literal["rising", "falling", "either"]
    pre: float = Field(description="fraction of the window before the trigger, 0..1")
    window_s: float
    holdoff_s: float


class RecorderSourceStatus(Reply):
    """How one session's drive-side recorder fares (docs/scope.md "Streaming while recording")."""

    session: str
    channels: list[int]
    sample_rate_hz: float
    drive_trigger: bool = Field(description="the drive waits for the level crossing itself")
    streaming: bool = Field(
        description="the filled part is read while the rest records (false: each recording "
        "is uploaded whole once done, the drive has no stream objects or refused them)"
    )
    records: int
    recording_share: float | None = Field(
        description="share of the time the drive recorded (the rest: restarts and, "
        "without streaming, uploads)"
    )
    stream_skips: int = Field(
        description="times the stream skipped to the newest samples (a gap), behind by more "
        "than it may lag: the bus carries less than the recorder takes"
    )
    stream_lag_s: float | None = Field(
        description="age of the newest sample when the last stream read handed it on"
    )
    upload_bytes_per_s: int | None = Field(description="bytes per second while uploading")


class ScopeStatus(Reply):
    running: bool
    state: Literal["idle", "rolling", "armed", "triggered", "done"]
    trigger: ScopeTrigger
    channels: list[ScopeChannelStatus]
    clients: int = Field(description="stream clients connected")
    buffer_s: float
    frame_period_ms: float
    recorders: list[RecorderSourceStatus]


class ScopeStatusFrame(ScopeStatus):
    """The JSON body of the scope stream's status frame (kind 3, domain/scope_wire.py): the
    scope's state as GET /scope answers it, tagged. Its TypeScript type is generated with the
    REST models (frontend/src/scope/wire.ts reads it)."""

    type: Literal["status"]


class RecordingChannel(Reply):
    """One channel of a recording; the display settings only in a capture's."""

    id: int
    name: str
    unit: str
    raw_unit: str
    scale: float = Field(description="the profile's raw to engineering factor")
    address: str
    session: str
    source: str
    t: list[float | None] = Field(description="seconds from t_ref")
    v: list[float | None] = Field(description="raw values; null where there is no sample")
    eng_scale: float | None = Field(default=None, description="a capture: scale again")
    label: str | None = Field(default=None, description="a capture of a configured channel")
    display_scale: float | None = Field(
        default=None, description="a capture: shown = engineering x display_scale + offset"
    )
    offset: float | None = None


class ScopeRecording(Reply):
    """GET /scope/capture and POST /scope/import."""

    t_ref: float = Field(description="backend clock (time.time() seconds)")
    trigger_time: float | None
    channels: list[RecordingChannel]
    window: list[float] | None = Field(
        default=None, description="a capture: the window's bounds, seconds from t_ref"
    )


class RecorderInfo(Reply):
    """GET /sessions/{sid}/recorder: the drive-side recorder."""

    present: bool
    max_channels: int
    rate_hz: float
    depth: int
    objects: list[str] = Field(description="the objects it can record")
    section: str | None = Field(default=None, description="a present recorder: the manual's")


class ChannelIn(BaseModel):
    model_config = _BODY
    id: int = Field(ge=0, le=255, description=f"Channel id 0..{MAX_CHANNELS - 1}")
    session: str = Field(min_length=1, max_length=128)
    address: str = Field(min_length=1, max_length=32, description='e.g. "0x6064:00"')
    source: Literal["auto", "pdo", "sdo", "recorder"] = "auto"
    scale: float = Field(default=1.0, allow_inf_nan=False)
    offset: float = Field(default=0.0, allow_inf_nan=False)
    visible: bool = True
    label: str | None = Field(default=None, max_length=64)
    rate_hz: float = Field(
        default=0.0,
        ge=0.0,
        le=100_000.0,
        description="SDO: requested poll rate (0: as fast as the link answers); "
        "recorder: requested sample rate (0: the recorder's fastest)",
    )


class ChannelsIn(BaseModel):
    model_config = _BODY
    # The scope's own limit (MAX_CHANNELS) is checked by the service, which names it in the
    # answer; channel ids too (ChannelIn.id is only bounded by the wire format's u8).
    channels: list[ChannelIn] = Field(max_length=64)


class TriggerIn(BaseModel):
    model_config = _BODY
    mode: Literal["roll", "single", "normal"] = "roll"
    kind: Literal["level", "edge", "state", "fault"] = "level"
    channel: int = Field(default=0, ge=0, le=MAX_CHANNELS - 1)
    level: float = Field(default=0.0, allow_inf_nan=False)
    slope: Literal["rising", "falling", "either"] = "rising"
    pre: float = Field(default=0.2, ge=0.0, le=1.0)
    window_s: float = Field(default=1.0, gt=0.0, le=60.0)
    holdoff_s: float = Field(default=0.0, ge=0.0, le=3600.0)


class RunIn(BaseModel):
    model_config = _BODY
    action: Literal["start", "stop", "arm"]


# Kept captures (issue 49; services/capture_store.py, docs/scope.md "Kept captures") ---------

#: A title or reason: not blank, no NUL (PostgreSQL refuses it in text); in the schema so that
#: a blank one is a 422 naming the field.
NOT_BLANK = r"^[^\x00]*[^\s\x00][^\x00]*$"
NO_NUL = r"^[^\x00]*$"


class CaptureKeep(BaseModel):
    """POST /sessions/{sid}/scope/captures: keep the scope's capture in the store."""

    model_config = _BODY
    title: str = Field(max_length=200, pattern=NOT_BLANK, description="not blank")
    note: str = Field(default="", max_length=4000, pattern=NO_NUL)
    window: Literal["capture", "buffer"] = Field(
        default="capture",
        description="capture: the last triggered window (GET /scope/capture); buffer: "
        "everything the scope holds (GET /scope/export?window=buffer)",
    )
    attach: bool = Field(default=False, description="show it in the drive's commissioning reports")


class CapturePatch(BaseModel):
    model_config = _BODY
    attached: bool = Field(description="show it in the drive's commissioning reports")


class CaptureDelete(BaseModel):
    model_config = _BODY
    reason: str = Field(
        max_length=2000, pattern=NOT_BLANK, description="why it goes (not blank; audited)"
    )


class CaptureChannelInfo(Reply):
    """One channel of a kept capture, without its samples."""

    id: int
    name: str
    unit: str = Field(description="engineering unit (profile)")
    raw_unit: str = Field(description="unit of the raw value in the drive (profile)")
    scale: float = Field(description="engineering = raw x scale (profile)")
    address: str
    session: str
    source: str
    samples: int
    period_s: float | None = Field(description="median sample spacing [s]; null: < 2 samples")


class CaptureInfo(Reply):
    """A scope capture kept in the store (its metadata)."""

    id: str = Field(description="GET /scope/captures/{id}")
    drive_key: str = Field(description="vendor-product-serial (1018h), else profile@bus")
    session: str = Field(description="the session it was kept from")
    gateway: str = Field(description="the gateway it was kept on")
    title: str
    note: str
    time: str = Field(description="when it was kept (ISO 8601, UTC)")
    created: float = Field(description="when it was kept [s since the epoch]")
    by: str = Field(description="the user who kept it ('local' in single-user mode)")
    client: str = Field(description="the client (browser tab, script) that kept it")
    window: Literal["capture", "buffer"]
    samples: int = Field(description="samples of all channels together")
    channels: list[CaptureChannelInfo]
    attached: bool = Field(description="the drive's commissioning reports show it")
    sha256: str = Field(description="SHA-256 of the stored recording and trigger (JSON)")


class StoredCapture(CaptureInfo):
    """GET /scope/captures/{id}: a kept capture with its samples, as the scope had them."""

    trigger: ScopeTrigger | None = Field(description="the trigger as set (null: the buffer)")
    recording: ScopeRecording
