"""What a drive's profile says about its tuning (issue 8; docs/tuning.md "Service and API").

The queries the job service, the built-in driver and the API share: the kind of tuning a family
gets (:func:`tuning_kind`, and for ``none`` what applies instead), its gains, the position units
per revolution, the drive's one-touch tuning objects P11600-P11604 and their error table, and the
safety inputs' limits. Reads of the drive's objects are here too (:func:`read_value`), decoded
with the profile's data types.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import POSITION, PROFILE_VELOCITY
from servodesk.domain.datatypes import DataType, Value, codec, coerce_int
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.errors import ServodeskError
from servodesk.services.session import Session, error_info

if TYPE_CHECKING:
    # Only the type: the design pulls in numpy, and the API and CLI import this module early.
    from servodesk.domain.tuning.design import ResponseLevel

Kind = Literal["builtin", "gains", "none"]
MODES: tuple[ResponseLevel, ...] = ("low", "basic", "high")
#: P11600 values of the response modes (004 §20.9.3.5(27)).
BUILTIN_MODE: dict[str, int] = {"basic": 1, "high": 2, "low": 3}
#: P11602: the stop command (004 §20.9.3.5(29)).
STOP_VALUE = 0x1EA5
#: P11603 values (004 §20.9.3.5(30)).
CLEAR_VALUE: dict[str, int] = {"before": 0x0001, "defaults": 0x0000}
#: The LECSN-T gain parameters one-touch tuning sets (004 §20.8.7; the twin's sim/onetouch.py).
BUILTIN_SYMBOLS = ("PB06", "PB07", "PB08", "PB09", "PB10")
BUILTIN_LABELS = {
    "PB06": "Load to motor inertia ratio",
    "PB07": "Model loop gain",
    "PB08": "Position loop gain",
    "PB09": "Speed loop gain",
    "PB10": "Speed integral compensation",
}

#: The safety inputs the UI and the CLI start from.
DEFAULTS: dict[str, Any] = {"mode": "basic", "travel_window_rev": 0.5, "torque_limit_pct": 100.0}
#: What the travel window means, per kind of tuning (GET .../tuning ``travel_rule``).
TRAVEL_RULE: dict[str, str] = {
    "gains": (
        "The travel window is the total width, centred on where the axis stands: the axis "
        "stays within ± half of it (rounded down to whole position units). servodesk sizes "
        "every move so that its overshoot and a stop's run-out stay inside, and sets the "
        "drive's software position limits (607Dh) there for the run where the drive has them."
    ),
    "builtin": (
        "The travel window is the total width, centred on where the axis stands: servodesk "
        "commands the axis between its two ends (± half of it, rounded down to whole position "
        "units). The drive tunes its own gains meanwhile, and how far it overshoots those ends "
        "is the drive's: keep room beyond them."
    ),
}
MAX_TRAVEL_REV = 100.0
MAX_TORQUE_PCT = 300.0
#: The peak torque of the machine's moves the own tuning ranks its gains for (% of rated): only
#: arithmetic on the model, never a limit of the drive, so it may exceed MAX_TORQUE_PCT.
MAX_MOVE_TORQUE_PCT = 1000.0


def _quirk_dict(profile: DeviceProfile, quirk: str) -> dict[str, Any] | None:
    q = profile.quirk(quirk)
    return q if isinstance(q, dict) else None


def tuning_kind(profile: DeviceProfile) -> tuple[Kind, str]:
    """How ``profile``'s family is tuned, and in plain words why (for ``none``: what applies).

    The profile's ``tuning:`` block decides where it exists; without one the family's quirks
    do (``one_touch_tuning``: built-in; otherwise nothing servodesk can tune).
    """
    spec = getattr(profile, "tuning", None)
    kind = getattr(spec, "kind", None) if spec is not None else None
    note = getattr(spec, "note", None) if spec is not None else None
    if kind == "builtin" or (kind is None and profile.quirk("one_touch_tuning") is not None):
        return "builtin", (
            f"The {profile.name} tunes itself: its one-touch tuning (004 §20.8.7, P11600-P11604) "
            "estimates the load to motor inertia ratio and sets the gains while the motor turns "
            "under the master's command. servodesk moves the axis back and forth inside the "
            "travel window you confirm, starts the drive's tuning, follows its progress and "
            "decodes its result."
        )
    if kind == "gains":
        return "gains", (
            f"servodesk tunes the {profile.name} itself through the profile's gain map: it "
            "identifies the axis, measures its frequency response, designs the gains and "
            "filters, and verifies them (docs/tuning.md)."
        )
    return "none", _none_reason(profile, note if kind == "none" else None)


def _none_reason(profile: DeviceProfile, note: str | None) -> str:
    if profile.quirk("no_tuning_gains"):
        return (
            f"Nothing to tune: the {profile.name} outputs pulse trains to external drives "
            "(003 §1), so it has no current, velocity or position loop and no gain to set. Tune "
            "each external drive with its own tool. What applies on this unit: the pulse output "
            "settings (pulse format, encoder, operation settings) and the speed and ramp "
            "settings, on the Parameters page."
        )
    text = (
        f"No documented gain map for servodesk's tuning: the {profile.name} profile does not "
        "say which objects hold the servo gains and in which units, so servodesk cannot tune it."
    )
    if note:
        text += f" {note}"
    q = _quirk_dict(profile, "tuning_gains")
    gain_objs = [
        spec
        for spec in profile.variables.values()
        if "gain" in spec.name.lower() and spec.access.writable
    ]
    if q:
        text += (
            f" What applies: its gain and filter objects ({', '.join(sorted(q.values()))}) are "
            "raw numbers without documented units; set them by hand on the Parameters page "
            "(group Tuning) and save them to non-volatile memory there."
        )
    elif gain_objs:
        names = ", ".join(f"{s.name} ({s.address})" for s in gain_objs[:3])
        text += (
            f" What applies: set its gain parameters by hand on the Parameters page ({names}; "
            "type, range and unit are in the drive's user manual), or use the drive "
            "maker's tuning tool."
        )
    else:
        text += " What applies: the drive maker's tuning tool, and the Parameters page."
    return text


def applies_instead(profile: DeviceProfile) -> list[dict[str, str]]:
    """For kind ``none``: the pages and parameter groups that apply instead (UI links).

    Only groups the Parameters page lists: those with a writable object that is not a process
    value (HIWIN's "Motor" holds read-only data, 3000h/3001h/6075h/6076h: a link to it opened
    another group, issue 48).
    """
    wanted = ("pulse_output", "velocity", "tuning", "pt_parameters", "motor")
    listed = {s.group for s in profile.variables.values() if not s.process and s.access.writable}
    out: list[dict[str, str]] = []
    for g in profile.groups:
        if g.id in wanted and g.id in listed:
            out.append({"page": "parameters", "group": g.id, "label": f"Parameters: {g.name}"})
    if not out:
        out.append({"page": "parameters", "group": "", "label": "Parameters"})
    return out


@dataclass(frozen=True, slots=True)
class GainRef:
    """One gain the tuning reads and changes: SI / engineering value = raw * ``scale``."""

    name: str
    label: str
    address: ObjectAddress
    unit: str | None
    scale: float
    raw_unit: str | None
    symbol: str | None
    data_type: DataType
    default: Value | None


def gain_refs(profile: DeviceProfile, kind: Kind) -> list[GainRef]:
    """The gains of the family: PB06-PB10 by symbol (builtin), the gain map (gains)."""
    out: list[GainRef] = []
    if kind == "builtin":
        by_symbol = {s.symbol: s for s in profile.variables.values() if s.symbol}
        q = _quirk_dict(profile, "one_touch_tuning") or {}
        params = q.get("parameters") if isinstance(q.get("parameters"), dict) else {}
        by_address: dict[ObjectAddress, str] = {}
        for name, addr in (params or {}).items():
            with contextlib.suppress(ServodeskError, ValueError):
                by_address[ObjectAddress.parse(str(addr))] = str(name)
        specs = [by_symbol[s] for s in BUILTIN_SYMBOLS if s in by_symbol]
        if not specs:  # No symbols: the quirk's own list.
            specs = [s for a in by_address if (s := profile.spec(a)) is not None]
        for spec in specs:
            sym = spec.symbol
            name = by_address.get(spec.address) or (sym or str(spec.address)).lower()
            label = BUILTIN_LABELS.get(sym or "", name.replace("_", " ").capitalize())
            out.append(_ref(spec, name, f"{sym} {label}" if sym else label, spec.unit, spec.scale))
        return out
    if kind == "gains":
        tspec = getattr(profile, "tuning", None)
        gains = getattr(tspec, "gains", None) or {}
        for name, g in gains.items():
            address = ObjectAddress.parse(str(getattr(g, "object", "")))
            found = profile.spec(address)
            if found is None:
                continue
            spec = found
            unit = getattr(g, "unit", None)
            scale = float(getattr(g, "scale", 1.0) or 1.0)
            out.append(_ref(spec, str(name), str(name), unit, scale))
    return out


def _ref(spec: ObjectSpec, name: str, label: str, unit: str | None, scale: float) -> GainRef:
    default: Value | None = None
    with contextlib.suppress(ValueError, ServodeskError):
        default = spec.default_value()
    return GainRef(
        name=name,
        label=label,
        address=spec.address,
        unit=unit,
        scale=scale,
        raw_unit=spec.raw_unit,
        symbol=spec.symbol,
        data_type=spec.data_type,
        default=default,
    )


def units_per_rev(profile: DeviceProfile) -> tuple[float, str]:
    """Position units (6064h raw) per motor revolution, and where that number comes from."""
    spec = profile.spec(POSITION)
    raw = (spec.raw_unit if spec else None) or "units"
    if spec is not None and spec.scale > 0 and spec.unit in ("deg", "°"):
        return 360.0 / spec.scale, f"6064h: {spec.scale:g} deg per {raw}"
    if spec is not None and spec.scale > 0 and spec.unit in ("rev", "r"):
        return 1.0 / spec.scale, f"6064h: {spec.scale:g} rev per {raw}"
    uu = _quirk_dict(profile, "user_units_factor_group")
    if uu and isinstance(uu.get("counts_per_rev"), int):
        return float(uu["counts_per_rev"]), "quirk user_units_factor_group: counts_per_rev"
    cpr = profile.simulation.counts_per_rev
    return float(cpr), (
        f"{cpr} {raw} per revolution: the profile's simulation setting; on a real drive the "
        "electronic gear decides"
    )


def speed_raw(profile: DeviceProfile, rps: float, upr: float) -> int | None:
    """``rps`` revolutions per second in 6081h's raw unit (None: the family has no 6081h)."""
    spec = profile.spec(PROFILE_VELOCITY)
    if spec is None:
        return None
    if spec.unit in ("r/min", "rpm", "min-1") and spec.scale > 0:
        return max(1, round(rps * 60.0 / spec.scale))
    return max(1, round(rps * upr))


def decode_tuning_error(profile: DeviceProfile, code: int) -> dict[str, Any]:
    """P11604 with the profile's ``tuning`` error table: code, name, cause, remedy."""
    e = profile.error("tuning", code)
    if e is not None:
        info = error_info(e)
        return {k: info[k] for k in ("code", "code_hex", "name", "cause", "remedy", "section")}
    return {
        "code": code,
        "code_hex": f"0x{code:04X}",
        "name": f"Unknown one-touch tuning code 0x{code:04X}",
        "cause": "The drive reported a code the profile's tuning table does not list.",
        "remedy": "See the drive manual's one-touch tuning chapter.",
        "section": None,
    }


def _reason_error(name: str, cause: str, remedy: str | None = None) -> dict[str, Any]:
    return {"code": None, "code_hex": None, "name": name, "cause": cause, "remedy": remedy}


def builtin_objects(profile: DeviceProfile) -> dict[str, ObjectAddress]:
    """P11600-P11604 (quirk ``one_touch_tuning``; 2D50h-2D54h when it names none)."""
    q = _quirk_dict(profile, "one_touch_tuning") or {}
    out: dict[str, ObjectAddress] = {}
    for key, default in (
        ("mode", 0x2D50),
        ("status", 0x2D51),
        ("stop", 0x2D52),
        ("clear", 0x2D53),
        ("error", 0x2D54),
    ):
        text = q.get(key)
        out[key] = ObjectAddress.parse(str(text)) if text else ObjectAddress(default)
    return out


def si(raw: Value | None, scale: float) -> float | None:
    """A raw gain value in the gain's SI or engineering unit (None where it has no number)."""
    if raw is None or isinstance(raw, bool):
        return None
    value: float | None = None
    if isinstance(raw, int | float):
        value = float(raw) * scale
    else:
        with contextlib.suppress(ValueError, ServodeskError):
            value = float(coerce_int(raw)) * scale
    if value is None or not math.isfinite(value):
        return value
    return float(f"{value:.12g}")  # 370 * 0.1 is 37.0, not 37.000000000000004.


# Reads of the drive's objects -------------------------------------------------------------


async def read_value(session: Session, address: ObjectAddress) -> Value:
    spec = session.profile.spec(address)
    raw = await session.link.read(address)
    return codec(spec.data_type if spec else DataType.INTEGER32).decode(raw)


async def read_int(session: Session, address: ObjectAddress) -> int | None:
    v = await read_value(session, address)
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None
    return int(v)


async def read_raw(session: Session, refs: list[GainRef]) -> dict[str, Value]:
    return {g.name: await read_value(session, g.address) for g in refs}
