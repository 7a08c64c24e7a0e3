"""A profile's tuning section (docs/tuning.md): where each canonical servo gain lives, the
kind of one-touch tuning the family has, and its drive-side recorder.

Part of the device profile model (domain/profile.py): :class:`TuningSpec` is ``tuning:`` in
profile.yaml."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile_base import STRICT, check_address
from servodesk.domain.tuning.gains import ServoGains
from servodesk.errors import ServodeskError

if TYPE_CHECKING:
    from servodesk.domain.profile import ObjectSpec


#: The canonical servo gains (docs/tuning.md, "Canonical gains"): the fields of
#: :class:`~servodesk.domain.tuning.gains.ServoGains`, in order.
SERVO_GAIN_NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(ServoGains))

#: Gains a ``tuning.kind: gains`` profile must map: the cascade cannot run without them.
REQUIRED_GAINS: tuple[str, ...] = ("kp_pos", "kp_vel", "ti_vel")


class GainObject(BaseModel):
    """Where one canonical gain lives: SI value = raw object value * ``scale``."""

    model_config = STRICT

    #: The object's address, e.g. ``"0x2101:00"``.
    object: str
    scale: float = Field(default=1.0, gt=0)
    #: The SI unit of the canonical gain (docs/tuning.md), e.g. ``"N m s/rad"``.
    unit: str

    _address = field_validator("object")(check_address)

    @property
    def address(self) -> ObjectAddress:
        return ObjectAddress.parse(self.object)


class TuningSpec(BaseModel):
    """How a family is tuned (docs/tuning.md): the drive's own built-in tuning, servodesk's
    tuning through a gain map, or nothing to tune."""

    model_config = STRICT

    #: Sub-indexes of the test signal generator objects at ``signal_index``.
    SIGNAL_SUBS: ClassVar[int] = 8

    kind: Literal["gains", "builtin", "none"]
    #: Canonical gain name -> object and scale (kind ``gains``).
    gains: dict[str, GainObject] = Field(default_factory=dict)
    #: The read-only object reporting the servo loop rate [Hz], e.g. ``"0x2108:00"``.
    loop_rate_object: str | None = None
    #: The read-only object reporting the current loop bandwidth [Hz] (the tuning's model).
    current_loop_object: str | None = None
    #: Index of the test signal generator (subs 1-8, docs/tuning.md); simulated twins only.
    signal_index: int | None = Field(default=None, ge=0x2000, le=0x5FFF)
    section: str | None = None
    note: str | None = None

    @model_validator(mode="after")
    def _check(self) -> TuningSpec:
        unknown = sorted(set(self.gains) - set(SERVO_GAIN_NAMES))
        if unknown:
            raise ValueError(
                f"unknown gain {', '.join(unknown)}: the gains are {', '.join(SERVO_GAIN_NAMES)}"
            )
        if self.kind == "gains":
            missing = [g for g in REQUIRED_GAINS if g not in self.gains]
            if missing:
                raise ValueError(f"kind gains needs the gains {', '.join(missing)} mapped")
        for key in ("loop_rate_object", "current_loop_object"):
            text = getattr(self, key)
            if text is not None:
                try:
                    ObjectAddress.parse(text)
                except ServodeskError as exc:
                    raise ValueError(f"{key}: {exc.message}") from exc
        return self

    @property
    def loop_rate_address(self) -> ObjectAddress | None:
        if self.loop_rate_object is None:
            return None
        return ObjectAddress.parse(self.loop_rate_object)

    @property
    def current_loop_address(self) -> ObjectAddress | None:
        if self.current_loop_object is None:
            return None
        return ObjectAddress.parse(self.current_loop_object)


class RecorderSpec(BaseModel):
    """A drive-side recorder (trace function): objects sampled inside the drive at a fixed
    rate, with a trigger and pre-trigger, uploaded afterwards by SDO (docs/scope.md).

    Its objects sit at consecutive indexes from ``index`` (the offsets below). None of the
    families documents a trace function reachable over the fieldbus, so the shipped profiles
    give their simulated twin one (``sim_only``) in an index range the family leaves free.
    """

    model_config = STRICT

    #: Offsets from ``index``: channels (ARRAY, sub n = ``index << 16 | sub << 8 | bits``),
    #: divider, depth, trigger, level, pre-trigger, control/status, data (DOMAIN), recorded
    #: count, trigger sample index; optionally the stream position and stream data (the
    #: filled part read while recording, docs/scope.md "Streaming while recording").
    CHANNELS: ClassVar[int] = 0
    DIVIDER: ClassVar[int] = 1
    DEPTH: ClassVar[int] = 2
    TRIGGER: ClassVar[int] = 3
    LEVEL: ClassVar[int] = 4
    PRE_TRIGGER: ClassVar[int] = 5
    CONTROL: ClassVar[int] = 6
    DATA: ClassVar[int] = 7
    COUNT: ClassVar[int] = 8
    TRIGGER_INDEX: ClassVar[int] = 9
    STREAM_POSITION: ClassVar[int] = 10
    STREAM_DATA: ClassVar[int] = 11

    #: First index of the recorder objects (manufacturer area).
    index: int = Field(ge=0x2000, le=0x5FFF - 11)
    max_channels: int = Field(default=8, ge=1, le=8)
    #: Most samples per channel (the depth object is UNSIGNED16).
    max_depth: int = Field(default=8192, ge=1, le=65535)
    #: Samples per second at divider 1: the simulated plant, ``simulation.loop_rate_hz``
    #: (a twin built from a plant file samples at that file's loop rate).
    rate_hz: float = Field(default=4000.0, gt=0)
    #: Only the simulated twin has it; a session on a real drive reports no recorder.
    sim_only: bool = True
    section: str | None = None
    note: str | None = None

    def object_index(self, offset: int) -> int:
        """The index of one recorder object, e.g. ``object_index(RecorderSpec.DATA)``."""
        return self.index + offset

    @staticmethod
    def recordable(spec: ObjectSpec) -> bool:
        """Whether the recorder can sample ``spec``: readable, and an integer of at most 32
        bits or a REAL32 (a sample is one INTEGER32 word)."""
        dt = spec.data_type
        return spec.access.readable and (
            (dt.is_integer and 0 < dt.bits <= 32) or dt is DataType.REAL32
        )
