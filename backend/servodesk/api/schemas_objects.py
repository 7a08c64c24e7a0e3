"""Models of a session's object access: reading and writing objects by address (SDO or the
fieldbus's record access), storing to non-volatile memory and restoring the defaults."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from servodesk.api.schemas import ErrorOut


class ObjectValueOut(BaseModel):
    address: str
    index: int
    subindex: int
    name: str | None
    data_type: str | None
    access: str | None
    value: int | float | bool | str | None
    raw_hex: str
    engineering: float | None
    unit: str | None
    raw_unit: str | None
    value_text: str | None


class WriteRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    # bool first: pydantic would otherwise make true an int 1 before the kind is checked.
    value: bool | int | float | str | None = Field(
        default=None,
        description="Typed value of the object's kind: a number (integer, real), true/false "
        "or 0/1 (BOOLEAN), text (VISIBLE_STRING, UNICODE_STRING), hex text (OCTET_STRING, "
        "DOMAIN). A number in hex goes as raw_hex.",
    )
    raw_hex: str | None = Field(
        default=None, max_length=2048, description="Raw bytes, little-endian, as hex"
    )


class ReadRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    addresses: list[str] = Field(min_length=1, max_length=512)


class ReadFailure(BaseModel):
    address: str
    error: ErrorOut


class ReadResults(BaseModel):
    results: list[ObjectValueOut | ReadFailure]


class StoreResult(BaseModel):
    stored: int = Field(description="Dirty entries now saved")
    duration_s: float
    procedure: str


class RestoreDefaultsRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    confirm: Literal[True] = Field(
        description="Must be true: restoring defaults overwrites every setting"
    )
    reset: bool = Field(default=False, description="Reset the node afterwards so they apply")
