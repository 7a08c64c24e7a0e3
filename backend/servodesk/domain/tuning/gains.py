"""The canonical servo gains: one set of SI values per axis, shared by tuning and simulation.

:class:`ServoGains` is the contract of ``docs/tuning.md`` ("Canonical gains"): every field is an
SI quantity at the motor shaft, and the profile's ``tuning.gains`` map turns each into a drive
object with a scale. The simulated servo loop (``model/servo.py``) runs exactly these gains, and the
analysis in this package (``model.py``) evaluates exactly these gains, so a tuned result means the
same thing on both sides.

Pure standard library: the simulator imports this module on its hot path.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class ServoGains:
    """Gains and filters of the discrete position / velocity cascade (docs/tuning.md).

    Zero switches a feature off where the table says so: ``ti_vel = 0`` (no integral),
    ``inertia_ff = 0`` (no torque feed-forward), ``torque_lpf_hz = 0`` and ``notchN_hz = 0``
    (filter bypassed).
    """

    #: Position loop gain [1/s].
    kp_pos: float = 0.0
    #: Velocity loop proportional gain [N m s/rad].
    kp_vel: float = 0.0
    #: Velocity loop integral time [s] (0: no integral).
    ti_vel: float = 0.0
    #: Velocity feed-forward [1] (0..1).
    vel_ff: float = 0.0
    #: Inertia for the acceleration (torque) feed-forward [kg m^2] (0: off).
    inertia_ff: float = 0.0
    #: Corner of the first-order torque command low-pass [Hz] (0: off).
    torque_lpf_hz: float = 0.0
    #: Notch 1 centre [Hz] (0: off), -3 dB width / centre [1], gain at the centre [1] (0: full).
    notch1_hz: float = 0.0
    notch1_width: float = 0.0
    notch1_depth: float = 0.0
    #: Notch 2, same meaning as notch 1.
    notch2_hz: float = 0.0
    notch2_width: float = 0.0
    notch2_depth: float = 0.0

    def as_dict(self) -> dict[str, float]:
        """Field name -> value, in declaration order (the order of docs/tuning.md)."""
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ServoGains:
        """Gains from a mapping; missing fields take their default (0).

        Raises :class:`ValueError` naming an unknown key or a value that is not a finite number,
        so that a typo in a stored gain set is not silently dropped.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        values: dict[str, float] = {}
        for key, raw in data.items():
            if key not in names:
                raise ValueError(f"unknown servo gain {key!r}")
            if isinstance(raw, bool) or not isinstance(raw, int | float):
                raise ValueError(f"servo gain {key!r} must be a number, not {raw!r}")
            value = float(raw)
            if not math.isfinite(value):
                raise ValueError(f"servo gain {key!r} must be finite, not {raw!r}")
            values[key] = value
        return cls(**values)

    def replace(self, **changes: float) -> ServoGains:
        """A copy with some fields changed (unknown names raise :class:`ValueError`)."""
        names = {f.name for f in dataclasses.fields(self)}
        for key in changes:
            if key not in names:
                raise ValueError(f"unknown servo gain {key!r}")
        return dataclasses.replace(self, **changes)
