"""Plant files: a simulated axis described in TOML (``servodesk sim --plant FILE``).

docs/tuning.md, "Plant files". Every section is optional and takes its defaults when left
out; ``[compliance]`` left out means a rigid axis. Torques marked "of peak" are fractions of
``[motor] peak_torque``. Keys, defaults and the accepted ranges:

============ ================= ========== ===================================================
section      key               default    range
============ ================= ========== ===================================================
[motor]      inertia           3.7e-5     1e-7 .. 1 kg m²
             rated_torque      1.27       0.01 .. 1000 N m
             peak_torque       4.46       0.01 .. 3000 N m, and at least rated_torque
             encoder_counts    1048576    256 .. 2^31 counts per revolution (an integer)
             current_loop_hz   2000       100 .. 20000 Hz (the first-order current loop)
[load]       inertia_ratio     10         0.1 .. 100 (load inertia over motor inertia)
             coulomb           0.02       0 .. 0.5 of peak (at the load)
             viscous           0.0        0 .. 1 N m s/rad (at the motor)
             gravity           0.0        -0.8 .. 0.8 of peak (constant load torque)
[compliance] resonance_hz      400        10 .. rate_hz / 8 Hz (2000 Hz at 16 kHz)
             damping           0.03       0 .. 1 (damping ratio of the shaft mode)
[noise]      torque            0.005      0 .. 0.1 of peak (white, rms, per loop tick)
[loop]       rate_hz           16000      1000 .. 32000 Hz, a multiple of 1000
============ ================= ========== ===================================================

Why these bounds: the inertia and torque ranges cover small servo motors to large ones; an
encoder below 256 counts cannot close a velocity loop by differencing. The resonance must
stay at or below an eighth of the loop rate: the plant is exact for a torque held over each
tick (model/plant.py), but above ``rate / 8`` the hold and the loop's one-tick delays leave
little of the mode for a loop to act on, and a frequency response has few points per
resonance. The loop rate is a whole number of ticks per 1 ms motion cycle. Gravity above 0.8
of the peak torque leaves the drive too little to move.

Anything else is refused with a :class:`PlantFileError` naming the file, the section and key
and the allowed range: an unknown section or key, a value of the wrong type (a string for a
number, a float for ``encoder_counts``, a boolean anywhere), a value out of range.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from servodesk.errors import ValidationError
from servodesk.files import read_bounded
from servodesk.model.plant import PlantParams


class PlantFileError(ValidationError):
    """A plant file cannot be read or holds something it may not (CLI exit 2, API 400)."""


@dataclass(frozen=True, slots=True)
class _Key:
    field: str
    default: float | int | None
    lo: float
    hi: float
    unit: str
    integer: bool = False


#: section -> key -> (PlantSpec field, default, range, unit).
_SCHEMA: dict[str, dict[str, _Key]] = {
    "motor": {
        "inertia": _Key("motor_inertia", 3.7e-5, 1e-7, 1.0, "kg m²"),
        "rated_torque": _Key("rated_torque", 1.27, 0.01, 1000.0, "N m"),
        "peak_torque": _Key("peak_torque", 4.46, 0.01, 3000.0, "N m"),
        "encoder_counts": _Key("encoder_counts", 1 << 20, 256, 1 << 31, "counts", True),
        "current_loop_hz": _Key("current_loop_hz", 2000.0, 100.0, 20000.0, "Hz"),
    },
    "load": {
        "inertia_ratio": _Key("inertia_ratio", 10.0, 0.1, 100.0, ""),
        "coulomb": _Key("coulomb", 0.02, 0.0, 0.5, "of peak"),
        "viscous": _Key("viscous", 0.0, 0.0, 1.0, "N m s/rad"),
        "gravity": _Key("gravity", 0.0, -0.8, 0.8, "of peak"),
    },
    "compliance": {
        "resonance_hz": _Key("resonance_hz", 400.0, 10.0, 4000.0, "Hz"),
        "damping": _Key("damping", 0.03, 0.0, 1.0, ""),
    },
    "noise": {
        "torque": _Key("noise_torque", 0.005, 0.0, 0.1, "of peak"),
    },
    "loop": {
        "rate_hz": _Key("loop_rate_hz", 16000, 1000, 32000, "Hz"),
    },
}

#: The resonance may be at most the loop rate over this (module docstring).
RESONANCE_RATE_DIVISOR = 8
#: The largest plant file read: a few kB of TOML; /dev/zero is refused, not read to the end.
MAX_FILE = 1 << 20


@dataclass(frozen=True, slots=True)
class PlantSpec:
    """One plant file's values (SI; the "of peak" ones as the fractions the file gives)."""

    motor_inertia: float = 3.7e-5
    rated_torque: float = 1.27
    peak_torque: float = 4.46
    encoder_counts: int = 1 << 20
    current_loop_hz: float = 2000.0
    inertia_ratio: float = 10.0
    coulomb: float = 0.02
    viscous: float = 0.0
    gravity: float = 0.0
    #: None: rigid (no ``[compliance]`` section).
    resonance_hz: float | None = None
    damping: float = 0.03
    noise_torque: float = 0.005
    loop_rate_hz: int = 16000

    @property
    def load_inertia(self) -> float:
        return self.inertia_ratio * self.motor_inertia

    @property
    def rigid(self) -> bool:
        return self.resonance_hz is None

    def plant_params(self, seed: int = 0) -> PlantParams:
        """The simulation's parameters (torque fractions turned into N m)."""
        pk = self.peak_torque
        return PlantParams(
            motor_inertia=self.motor_inertia,
            load_inertia=self.load_inertia,
            viscous=self.viscous,
            coulomb=self.coulomb * pk,
            rated_torque=self.rated_torque,
            peak_torque=pk,
            counts_per_rev=self.encoder_counts,
            current_loop_hz=self.current_loop_hz,
            resonance_hz=self.resonance_hz,
            damping=self.damping,
            gravity=self.gravity * pk,
            torque_noise=self.noise_torque * pk,
            seed=seed,
            exact=True,  # A plant file's axis is simulated exactly (model/plant.py).
        )

    def canonical(self) -> dict[str, dict[str, float | int]]:
        """The values by section and key as a plant file names them; the compliance section
        only for a compliant axis (a rigid axis has no damping to speak of)."""
        out: dict[str, dict[str, float | int]] = {}
        for section, keys in _SCHEMA.items():
            if section == "compliance" and self.resonance_hz is None:
                continue
            values: dict[str, float | int] = {}
            for key, k in keys.items():
                v = getattr(self, k.field)
                values[key] = int(v) if k.integer or key == "rate_hz" else float(v)
            out[section] = values
        return out

    def sha256(self) -> str:
        """A stable hash of the canonical values (to cache results per plant)."""
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def to_toml(self) -> str:
        """The spec as a plant file (every key written out)."""
        lines: list[str] = []
        for section, values in self.canonical().items():
            lines.append(f"[{section}]")
            lines.extend(f"{k} = {v!r}" for k, v in values.items())
            lines.append("")
        return "\n".join(lines)


def load_plant_file(path: str | Path) -> PlantSpec:
    """Read and check a plant file; :class:`PlantFileError` names what is wrong."""
    p = Path(path)
    try:
        text = read_bounded(p, MAX_FILE).decode("utf-8")
    except OSError as exc:
        raise PlantFileError(
            f"plant file {p}: cannot read: {exc.strerror or exc}",
            field="plant",
            hint="give the path of a TOML plant file (docs/tuning.md, Plant files)",
        ) from exc
    except UnicodeDecodeError as exc:
        raise PlantFileError(f"plant file {p}: not UTF-8 text ({exc.reason})") from exc
    return parse_plant_toml(text, source=p.name)


def parse_plant_toml(text: str, source: str = "<plant>") -> PlantSpec:
    """Parse plant-file text (``source`` names it in messages)."""
    where = f"plant file {source}"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PlantFileError(f"{where}: not valid TOML: {exc}", field="plant") from exc
    values: dict[str, Any] = {}
    for section, content in data.items():
        keys = _SCHEMA.get(section)
        if keys is not None and not isinstance(content, dict):
            raise PlantFileError(
                f"{where}: {section} = {content!r} must be a section [{section}]",
                field=section,
            )
        if keys is None or not isinstance(content, dict):
            what = f"section [{section}]" if isinstance(content, dict) else f"key {section}"
            raise PlantFileError(
                f"{where}: unknown {what} (sections: {', '.join(_SCHEMA)})",
                field=section,
                hint="docs/tuning.md lists the plant file's sections and keys",
            )
        if section == "compliance":
            values["resonance_hz"] = keys["resonance_hz"].default
        for key, raw in content.items():
            k = keys.get(key)
            if k is None:
                raise PlantFileError(
                    f"{where}: unknown key [{section}] {key} (keys: {', '.join(keys)})",
                    field=f"{section}.{key}",
                )
            values[k.field] = _value(where, section, key, raw, k)
    spec = PlantSpec(**values)
    _check_together(where, spec)
    return spec


def _value(where: str, section: str, key: str, raw: Any, k: _Key) -> float | int:
    name = f"[{section}] {key}"
    field = f"{section}.{key}"
    unit = f" {k.unit}" if k.unit else ""
    if isinstance(raw, bool) or not isinstance(raw, int | float):
        kind = "an integer" if k.integer else "a number"
        raise PlantFileError(
            f"{where}: {name} = {raw!r} must be {kind} ({_range(k)}{unit})", field=field
        )
    if k.integer and not isinstance(raw, int):
        raise PlantFileError(
            f"{where}: {name} = {raw!r} must be an integer ({_range(k)}{unit})", field=field
        )
    if not math.isfinite(raw) or not k.lo <= raw <= k.hi:
        raise PlantFileError(
            f"{where}: {name} = {raw!r} is out of range ({_range(k)}{unit})", field=field
        )
    if key == "rate_hz":
        if raw != int(raw) or int(raw) % 1000:
            raise PlantFileError(
                f"{where}: {name} = {raw!r} must be a multiple of 1000 Hz "
                f"({_range(k)}{unit}: whole ticks per 1 ms motion cycle)",
                field=field,
            )
        return int(raw)
    return raw if k.integer else float(raw)


def _range(k: _Key) -> str:
    def fmt(x: float) -> str:
        if k.integer and x >= 1 << 16:
            return f"2^{int(math.log2(x))}" if x == 1 << int(math.log2(x)) else str(int(x))
        return f"{x:g}"

    return f"{fmt(k.lo)}..{fmt(k.hi)}"


def _check_together(where: str, spec: PlantSpec) -> None:
    """The limits that depend on another key."""
    if spec.peak_torque < spec.rated_torque:
        raise PlantFileError(
            f"{where}: [motor] peak_torque = {spec.peak_torque:g} is out of range "
            f"({spec.rated_torque:g}..3000 N m: at least rated_torque)",
            field="motor.peak_torque",
        )
    if spec.resonance_hz is not None:
        top = spec.loop_rate_hz / RESONANCE_RATE_DIVISOR
        if spec.resonance_hz > top:
            raise PlantFileError(
                f"{where}: [compliance] resonance_hz = {spec.resonance_hz:g} is out of range "
                f"(10..{top:g} Hz: at most [loop] rate_hz / {RESONANCE_RATE_DIVISOR}, "
                f"{spec.loop_rate_hz} Hz)",
                field="compliance.resonance_hz",
            )


def spec_keys() -> dict[str, tuple[str, ...]]:
    """The accepted keys by section (for messages and documentation)."""
    return {section: tuple(keys) for section, keys in _SCHEMA.items()}


# The schema and the dataclass must agree (a key without a field would be lost silently).
assert {k.field for keys in _SCHEMA.values() for k in keys.values()} == {
    f.name for f in fields(PlantSpec)
}
