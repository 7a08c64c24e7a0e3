"""Models of the device profiles (GET /profiles, /profiles/{id}, POST /profiles/import): the
object dictionary, error table, groups, quirks and network section a profile documents
(docs/profiles.md). ErrorInfo is also the drive state's and the alarms' error entry."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from servodesk.api.schemas import Scalar


class ProfileSummary(BaseModel):
    id: str
    name: str
    vendor: str
    fieldbus: str
    description: str | None
    objects: int
    variables: int
    errors: int
    modes: list[int]
    homing_methods: list[int]


class ImportedProfile(ProfileSummary):
    """POST /profiles/import: the new profile and what the import left out or changed."""

    warnings: list[str] = Field(
        default_factory=list,
        description="One line per thing the file holds that the profile does not (skipped "
        "modules, values outside their type, ...); docs/device-descriptions.md",
    )


class ObjectInfo(BaseModel):
    index: int
    subindex: int
    address: str
    name: str
    name_local: str | None
    data_type: str
    access: str
    pdo_mapping: str
    default: Scalar
    min: int | float | None
    max: int | float | None
    unit: str | None
    scale: float
    raw_unit: str | None
    group: str | None
    persist: bool
    process: bool
    description: str | None
    section: str | None
    values: dict[str, str] | None
    pnu: int | None
    symbol: str | None


class ErrorInfo(BaseModel):
    table: str
    code: int
    code_hex: str
    display: str | None
    name: str
    kind: str
    cause: str | None
    remedy: str | None
    section: str | None


class GroupInfo(BaseModel):
    id: str
    name: str
    name_local: str | None
    description: str | None


class QuirkInfo(BaseModel):
    id: str
    value: Any
    section: str | None
    note: str | None


class NetworkObjectInfo(BaseModel):
    #: Canonical address, as in ``object_list`` (``"0x1017:00"``).
    address: str
    note: str
    section: str


class NetworkRuleInfo(BaseModel):
    text: str
    section: str


class NetworkLedInfo(BaseModel):
    led: str
    state: str
    meaning: str
    section: str


class NetworkInfo(BaseModel):
    """How the family is addressed on its fieldbus (profile ``network:``, docs/profiles.md)."""

    summary: str
    section: str
    objects: list[NetworkObjectInfo]
    addressing: list[NetworkRuleInfo]
    leds: list[NetworkLedInfo]


class ProfileDetail(ProfileSummary):
    groups: list[GroupInfo]
    object_list: list[ObjectInfo]
    error_list: list[ErrorInfo]
    quirks: list[QuirkInfo]
    #: None: the profile documents no network section.
    network: NetworkInfo | None = None
