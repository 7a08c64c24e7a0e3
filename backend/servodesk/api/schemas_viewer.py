"""Models of the 3D viewer (issue 4 item 6): whether the viser viewer runs and where, and the
stage (rotary or linear, scale) of each session's axis."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class ViewerAxisOut(BaseModel):
    session: str
    kind: Literal["rotary", "linear"]
    scale: float = Field(description="Counts per revolution (rotary) or per mm (linear)")
    scale_unit: Literal["counts/rev", "counts/mm"]
    source: Literal["user", "profile", "default"] = Field(
        description="Who chose the stage: PUT /viewer/axes, the profile (6064h in mm), or the "
        "default (a rotary motor with the profile's counts per revolution)"
    )
    limits: list[int] | None = Field(
        default=None, description="Software position limits 607Dh [min, max] in counts, if on"
    )


class ViewerOut(BaseModel):
    enabled: bool = Field(description="False when SERVODESK_VIEWER_PORT is 0")
    running: bool
    url: str | None = Field(description="Address of the viser client page (embed it in an iframe)")
    port: int | None = Field(description="Port the viewer is bound to (on the backend's host)")
    clients: int = Field(description="Browsers connected to the viewer now")
    rate_hz: float = Field(description="Scene update rate")
    error: str | None = Field(default=None, description="Why an enabled viewer is not running")
    axes: list[ViewerAxisOut]


class ViewerAxisRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    kind: Literal["rotary", "linear"]
    scale: float | None = Field(
        default=None,
        gt=0,
        description="Counts per revolution (rotary) or per mm (linear); omitted: keep the "
        "present scale (rotary: the profile's counts per revolution)",
    )
