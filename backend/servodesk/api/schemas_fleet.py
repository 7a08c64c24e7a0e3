"""Request and response models of the fleet routes (api/routes/fleet.py, docs/api.md
"Fleet and drift")."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

DriftStateName = Literal["unknown", "in_step", "drifted"]

#: Names and search text: printable (a NUL cannot even reach PostgreSQL: a clear 422 here).
PRINTABLE = r"^[^\x00-\x1f\x7f]*$"
#: A reason: something that is not blank, and no NUL (PostgreSQL refuses it in text). In the
#: schema rather than only in the service, so a blank one is refused as the schema says.
REASON = r"^[^\x00]*[^\s\x00][^\x00]*$"


class GatewayOut(BaseModel):
    name: str
    url: str
    buses: list[str] = Field(description="interface:channel of the drives it has connected")
    version: str
    started: str
    last_seen: str
    alive: bool = Field(description="seen within the last three heartbeats (90 s)")


class ApprovedOut(BaseModel):
    backup: str
    by: str | None
    at: str | None
    reason: str | None


class DriftStateOut(BaseModel):
    state: DriftStateName
    count: int | None = Field(description="differing parameters at the last check")
    time: str | None = Field(description="when the last check ran (ISO 8601, UTC)")


class LastTuningOut(BaseModel):
    id: str = Field(description="the stored tuning (GET /tuning/results/{id})")
    time: str = Field(description="when it ended (ISO 8601, UTC)")
    status: Literal["done", "failed", "stopped"]
    mode: str


class FleetDrive(BaseModel):
    drive_key: str = Field(description="vendor-product-serial (1018h), else profile@bus")
    plant_tag: str | None
    serial: str | None
    profile_id: str = Field(description="the drive's family (profile)")
    firmware: str | None
    gateway: str | None = Field(description="the gateway that connected it last")
    session: str | None = Field(description="its session on that gateway when last seen")
    link: str | None = Field(description="the drive's page on its gateway")
    seen: str | None = Field(description="when a gateway last saw it connected")
    last_backup: str | None
    last_backup_time: str | None
    approved: ApprovedOut | None
    drift: DriftStateOut
    alarms: int | None = Field(description="open alarms when last seen (None: not known)")
    last_tuning: LastTuningOut | None = Field(
        description="the newest tuning kept in the store (None: none)"
    )


class FleetPage(BaseModel):
    total: int = Field(description="drives matching the filter")
    offset: int
    limit: int
    drives: list[FleetDrive]


class PlantTagRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    drive: str = Field(
        min_length=1, max_length=200, pattern=PRINTABLE, description="drive_key or plant tag"
    )
    tag: str | None = Field(
        max_length=200,
        pattern=PRINTABLE,
        description="the new plant tag (e.g. L2.Press.X); null or '': clear",
    )


class ApproveRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    drive: str = Field(
        min_length=1, max_length=200, pattern=PRINTABLE, description="drive_key or plant tag"
    )
    backup: str = Field(
        min_length=1, max_length=200, pattern=PRINTABLE, description="the backup to approve"
    )
    reason: str = Field(
        max_length=2000,
        pattern=REASON,
        description="why this backup is the reference (not blank)",
    )


class ClearApprovalRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    drive: str = Field(
        min_length=1, max_length=200, pattern=PRINTABLE, description="drive_key or plant tag"
    )
    reason: str = Field(
        max_length=2000,
        pattern=REASON,
        description="why the drive has no reference any more (not blank)",
    )


class DriftDifference(BaseModel):
    address: str
    name: str | None
    group: str | None
    unit: str | None
    raw_unit: str | None
    kind: Literal["changed", "only_a", "only_b"] = Field(
        description="changed; only_a: only in the approved backup; only_b: only on the drive"
    )
    approved_value: int | float | bool | str | None
    drive_value: int | float | bool | str | None
    approved_raw_hex: str | None
    drive_raw_hex: str | None
    approved_engineering: float | None
    drive_engineering: float | None


class DriftResult(BaseModel):
    id: int
    drive_key: str
    plant_tag: str | None
    time: str
    gateway: str
    session: str
    backup: str = Field(description="the approved backup the drive was compared with")
    state: Literal["in_step", "drifted"]
    count: int
    differences: list[DriftDifference]
    webhook: str | None = Field(description="the webhook's outcome (None: not sent)")
