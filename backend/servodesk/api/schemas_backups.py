"""Models of backup, compare and restore (issue 5; docs/api.md, docs/backup.md): the backup
records and file format, the comparison of two sources, the restore's preflight and report,
and the audit of writes through servodesk."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field


class BackupCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    label: str = Field(default="", max_length=200)
    note: str = Field(default="", max_length=4000)


class PlantBackupCreate(BaseModel):
    """POST /backups/plant: a backup of several drives at once (issue 50)."""

    model_config = ConfigDict(extra="forbid")

    #: The sessions to back up (one named twice is backed up once); left out: every open
    #: session.
    sessions: list[Annotated[str, Field(min_length=1, max_length=128)]] | None = Field(
        default=None, min_length=1, max_length=256
    )
    label: str = Field(default="", max_length=200)
    note: str = Field(default="", max_length=4000)


class BackupPatch(BaseModel):
    model_config = ConfigDict(extra="forbid")

    label: str | None = Field(default=None, max_length=200)
    note: str | None = Field(default=None, max_length=4000)


class BackupIdentity(BaseModel):
    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None
    serial: int | None = None
    device_name: str | None = None
    hardware_version: str | None = None
    software_version: str | None = None


class BackupBus(BaseModel):
    interface: str | None = None
    channel: str | None = None
    bitrate: int | None = None
    node_id: int | None = None


class UnreadableOut(BaseModel):
    """An object the drive refused when the set was read: the set lacks it."""

    address: str
    name: str
    code: int | None
    code_hex: str | None
    message: str


class BackupInfo(BaseModel):
    id: str
    time: str
    label: str
    note: str
    profile_id: str
    profile_version: str
    drive_key: str = Field(description="vendor-product-serial from 1018h, else profile@bus:node")
    identity: BackupIdentity
    firmware: str | None
    bus: BackupBus
    entries: int
    file: str = Field(description="File name in the data directory's backups/ folder")
    sha256: str
    source: str = Field(description="drive, upload or pre-restore (taken before a restore)")
    unreadable: list[UnreadableOut] = Field(
        default_factory=list,
        description="objects the drive refused when the backup was read (with the abort "
        "code and error text): the backup lacks them",
    )
    complete: bool = Field(
        default=True, description="false when the backup lacks unreadable objects"
    )
    queued: bool = Field(
        default=False,
        description="true when the central store was unreachable: the backup waits in this "
        "gateway's local queue and is synced when the store answers (docs/deployment.md)",
    )


class BackupEntryOut(BaseModel):
    address: str
    name: str
    data_type: str
    raw_hex: str
    value: int | float | bool | str | None
    unit: str | None


class BackupProfileRef(BaseModel):
    id: str
    version: str


class BackupFile(BaseModel):
    format: Literal["servodesk-backup"]
    schema_version: Literal[1]
    tool: str
    time: str
    label: str
    note: str
    profile: BackupProfileRef
    drive_key: str
    identity: BackupIdentity
    firmware: str | None
    bus: BackupBus
    entries: list[BackupEntryOut]
    unreadable: list[UnreadableOut]
    checksum: str


class SourceDrive(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["drive"]
    session: str = Field(min_length=1, max_length=200)


class SourceBackup(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["backup"]
    id: str = Field(min_length=1, max_length=200)


class SourceDefaults(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["defaults"]
    profile: str = Field(min_length=1, max_length=200)
    node_id: int = Field(default=1, ge=1, le=127, description="resolves $NODEID defaults")


Source = Annotated[SourceDrive | SourceBackup | SourceDefaults, Field(discriminator="kind")]


class CompareRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    a: Source
    b: Source
    all: bool = Field(default=False, description="also list equal entries (kind 'same')")


class DifferenceOut(BaseModel):
    address: str
    name: str
    group: str | None
    unit: str | None
    raw_unit: str | None
    a_value: int | float | bool | str | None
    b_value: int | float | bool | str | None
    a_raw_hex: str | None
    b_raw_hex: str | None
    a_engineering: float | None
    b_engineering: float | None
    kind: Literal["changed", "only_a", "only_b", "same"]


class Comparison(BaseModel):
    a: str
    b: str
    equal: bool
    differences: list[DifferenceOut]
    same: int
    a_unreadable: list[UnreadableOut] = Field(
        default_factory=list, description="objects A lacks (unreadable): not compared"
    )
    b_unreadable: list[UnreadableOut] = Field(
        default_factory=list, description="objects B lacks (unreadable): not compared"
    )


class PreflightRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    backup: str = Field(min_length=1, max_length=200)
    map_by_name: bool = False


class ProblemOut(BaseModel):
    address: str | None
    name: str | None
    message: str
    hint: str | None


class MappingOut(BaseModel):
    address: str
    name: str
    target: str | None
    reason: str | None


class PreflightOut(BaseModel):
    ok: bool
    problems: list[ProblemOut]
    warnings: list[str]
    to_write: int
    unchanged: int
    read_only_skipped: int
    mapping: list[MappingOut] | None
    unreadable: list[UnreadableOut] = Field(
        default_factory=list,
        description="objects the backup lacks (unreadable when taken): a restore cannot set them",
    )


class RestoreRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    backup: str = Field(min_length=1, max_length=200)
    dry_run: bool = False
    store: bool = Field(default=True, description="store to non-volatile memory when verified")
    force: bool = Field(default=False, description="store even when items failed")
    map_by_name: bool = False


class RestoreCounts(BaseModel):
    written: int
    unchanged: int
    skipped: int
    failed: int
    pending: int
    would_write: int


class RestoreItemOut(BaseModel):
    address: str
    name: str
    status: Literal["written", "unchanged", "skipped_read_only", "failed", "pending", "would_write"]
    old_raw_hex: str | None
    new_raw_hex: str | None
    code: int | None
    code_hex: str | None
    meaning: str | None
    message: str | None


class RestoreStepOut(BaseModel):
    address: str
    raw_hex: str
    entry: str | None = Field(description="the item this write sets; null for procedure steps")
    why: str


class RestoreReport(BaseModel):
    id: str
    backup: str
    session: str
    time: str
    dry_run: bool
    finished: bool
    stored: bool
    interrupted: bool
    pre_backup: str | None
    message: str | None
    warnings: list[str]
    counts: RestoreCounts
    items: list[RestoreItemOut]
    steps: list[RestoreStepOut] = Field(description="the writes in order (a dry run: planned)")
    unreadable: list[UnreadableOut] = Field(
        default_factory=list,
        description="objects the backup lacks (unreadable when taken): this restore did not "
        "set them",
    )


class AuditEntry(BaseModel):
    time: float
    client: str
    session: str
    drive_key: str
    address: str
    name: str | None
    old_raw_hex: str | None
    new_raw_hex: str
    old_value: int | float | bool | str | None
    new_value: int | float | bool | str | None


class PlantBackupItem(BaseModel):
    """One drive of a plant backup: its backup, or why it has none."""

    session: str
    ok: bool
    backup: BackupInfo | None = None
    error: str | None = None
    hint: str | None = None


class PlantBackupReport(BaseModel):
    """POST /backups/plant's answer: every drive's result and how long the whole took."""

    items: list[PlantBackupItem]
    saved: int = Field(description="drives backed up")
    failed: int = Field(description="drives whose backup failed (each item says why)")
    duration_s: float = Field(description="wall time of the whole, the drives read at once")
