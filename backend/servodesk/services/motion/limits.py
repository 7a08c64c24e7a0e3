"""The limits of a motion: where each comes from, and the checks before anything is sent.

The drive's own limits are read from the drive (software position limits 607Dh, max profile
velocity 607Fh, max torque 6072h, max acceleration / deceleration 60C5h / 60C6h) and cached
per session by the service; without the drive object, the profile's range of the set-point
object stands in, and ``Limits.sources`` says which. The checks here refuse a request before
the bus: a mode the family does not have, a value beyond a limit, a target outside the
software position limits, continuous motion toward a limit the axis is at, a write the profile
refuses. While continuous motion runs, :func:`limit_ahead` tells the monitor when to halt so
the axis stops before a software limit.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import (
    HALT_OPTION,
    POSITION,
    PROFILE_ACC,
    PROFILE_DEC,
    QUICK_STOP_DEC,
    TARGET_POSITION,
    TARGET_TORQUE,
    TARGET_VELOCITY,
    TORQUE_ACTUAL,
    VELOCITY,
)
from servodesk.domain.datatypes import DataType, Value, codec
from servodesk.domain.ramps import ramp_kind
from servodesk.domain.values import encode_write
from servodesk.errors import ObjectAccessError, ValidationError
from servodesk.services.session import Session

if TYPE_CHECKING:
    from servodesk.domain.profile import DeviceProfile
    from servodesk.services.motion.axis import Axis, Motion


LIMIT_OBJECTS: dict[str, ObjectAddress] = {
    "position_min": ObjectAddress(0x607D, 1),
    "position_max": ObjectAddress(0x607D, 2),
    "max_velocity": ObjectAddress(0x607F),
    "max_torque": ObjectAddress(0x6072),
    "max_acceleration": ObjectAddress(0x60C5),
    "max_deceleration": ObjectAddress(0x60C6),
}

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
#: Continuous motion (jog, profile velocity) near a software position limit: the monitor
#: samples the position this often, and assumes this stopping time when the family's
#: deceleration is not in position units per s² (LECSN-T ms ramps, CTMM04x rate registers).
LIMIT_GUARD_PERIOD = 0.02
FALLBACK_STOP_S = 0.5


@dataclass(frozen=True, slots=True)
class Limits:
    position_min: int | None
    position_max: int | None
    max_velocity: int | None
    max_torque: int | None
    max_acceleration: int | None
    max_deceleration: int | None
    modes: list[int]
    units: dict[str, dict[str, Any]]
    sources: dict[str, str]

    def as_dict(self) -> dict[str, Any]:
        return {
            "position_min": self.position_min,
            "position_max": self.position_max,
            "max_velocity": self.max_velocity,
            "max_torque": self.max_torque,
            "max_acceleration": self.max_acceleration,
            "max_deceleration": self.max_deceleration,
            "modes": self.modes,
            "mode_names": {str(m): cia402.mode_name(m) for m in self.modes},
            "units": self.units,
            "sources": self.sources,
        }


async def read_limits(session: Session) -> Limits:
    profile = session.profile
    unusable = {str(a).upper() for a in profile.quirk("objects_not_usable", []) or []}
    values: dict[str, int | None] = {}
    sources: dict[str, str] = {}
    for name, address in LIMIT_OBJECTS.items():
        values[name] = None
        spec = profile.spec(address)
        if spec is None or not spec.access.readable:
            sources[name] = f"unknown: {profile.name} has no readable {address}"
            continue
        if f"0X{address.index:04X}" in unusable or str(address).upper() in unusable:
            sources[name] = f"unknown: {address} is not usable (quirk objects_not_usable)"
            continue
        try:
            v = await read_int(session, address)
        except ObjectAccessError as exc:
            # A limit the drive does not have or refuses to give is unknown, not an
            # error: the checks that need it are skipped. Only a dead link (LinkError)
            # fails the whole read.
            sources[name] = (
                f"unknown: the drive refused {address} (abort 0x{exc.code:08X}: {exc.meaning})"
            )
            continue
        except ValidationError as exc:  # An answer that does not decode as the type.
            sources[name] = f"unknown: {address} could not be read ({exc.message})"
            continue
        values[name] = v
        if v is not None:
            sources[name] = str(address)
    if values["position_min"] == 0 and values["position_max"] == 0:
        # CiA 402-2 §6.5.4: min = max = 0 switches the software limits off.
        values["position_min"] = values["position_max"] = None
        sources["position_min"] = sources["position_max"] = "607Dh = 0/0: limits off"
    if values["max_velocity"] == 0:
        values["max_velocity"] = None
        sources["max_velocity"] = "607Fh = 0: no extra limit"
    _velocity_in_setpoint_units(profile, values, sources)
    # Without the drive objects, the profile's own range of the set-point objects.
    for name, address in (
        ("max_velocity", TARGET_VELOCITY),
        ("max_torque", TARGET_TORQUE),
        ("max_acceleration", PROFILE_ACC),
        ("max_deceleration", PROFILE_DEC),
    ):
        spec = profile.spec(address)
        if values[name] is None and spec is not None and isinstance(spec.max, int):
            values[name] = spec.max
            why = sources.get(name)
            sources[name] = f"profile {address} max" + (f" ({why})" if why else "")
    units: dict[str, dict[str, Any]] = {}
    for kind, candidates in (
        ("position", (POSITION, TARGET_POSITION)),
        ("velocity", (VELOCITY, TARGET_VELOCITY)),
        ("torque", (TARGET_TORQUE, TORQUE_ACTUAL)),
        ("acceleration", (PROFILE_ACC,)),
    ):
        for address in candidates:
            spec = profile.spec(address)
            if spec is not None:
                dv = spec.default_value()
                units[kind] = {
                    "raw_unit": spec.raw_unit,
                    "unit": spec.unit,
                    "scale": spec.scale,
                    # The family's own default of that object: where a ramp is neither a
                    # rate nor a time (CTMM04x: PMC842SR rate registers, 003 §5-3-1), the
                    # panels start from it.
                    "default": dv if isinstance(dv, int) and not isinstance(dv, bool) else None,
                }
                if kind == "acceleration":
                    # What the ramp objects hold, so the UI need not parse the unit.
                    units[kind]["ramp"] = ramp_kind(spec.raw_unit)
                break
    return Limits(
        position_min=values["position_min"],
        position_max=values["position_max"],
        max_velocity=values["max_velocity"],
        max_torque=values["max_torque"],
        max_acceleration=values["max_acceleration"],
        max_deceleration=values["max_deceleration"],
        modes=sorted(profile.modes),
        units=units,
        sources=sources,
    )


def _velocity_in_setpoint_units(
    profile: DeviceProfile, values: dict[str, int | None], sources: dict[str, str]
) -> None:
    """607Fh in the velocity set-points' raw unit, which the checks compare it with.

    Most families hold 607Fh in the units of 60FFh / 6081h (CiA 402-2 §6.4.6); smartris holds
    it in whole r/min (001 §6-4) while its set-points are inc/s: 4500 rpm read as 4500 inc/s
    refused every jog above 16.5 rpm. Where the raw units differ and the engineering unit is
    the same, 607Fh goes through it (raw x scale / the set-point's scale)."""
    v = values.get("max_velocity")
    cap, target = profile.spec(LIMIT_OBJECTS["max_velocity"]), profile.spec(TARGET_VELOCITY)
    if v is None or cap is None or target is None or cap.raw_unit == target.raw_unit:
        return
    if not cap.unit or cap.unit != target.unit or not cap.scale or not target.scale:
        return
    values["max_velocity"] = int(v * cap.scale / target.scale)
    sources["max_velocity"] = (
        f"607Fh = {v} {cap.raw_unit} = {v * cap.scale:g} {cap.unit}, in {target.raw_unit}"
    )


async def read_int(session: Session, address: ObjectAddress) -> int | None:
    spec = session.profile.spec(address)
    raw = await session.link.read(address)
    v = codec(spec.data_type if spec else DataType.INTEGER32).decode(raw)
    return int(v) if isinstance(v, int | bool) else None


def need_mode(axis: Axis, mode: int, what: str) -> None:
    p = axis.session.profile
    if mode not in p.modes:
        have = ", ".join(cia402.mode_name(m) for m in sorted(p.modes)) or "none"
        raise ValidationError(
            f"{p.name} ({p.id}) has no {cia402.mode_name(mode)}, which {what} needs; "
            f"its modes: {have}",
            field="mode",
            hint="use a motion this family supports (see GET /limits: modes)",
        )


def check_abs(value: float, limit: int | None, name: str, field_name: str, lim: Limits) -> None:
    if limit is not None and abs(value) > limit:
        src = lim.sources.get(name, name)
        raise ValidationError(
            f"{field_name} {value:g} exceeds the {name.replace('_', ' ')} {limit} ({src}); "
            "nothing was sent",
            field=field_name,
            hint=f"stay within ±{limit}, or raise the limit on the drive",
        )


def check_position(value: float, lim: Limits, field_name: str) -> None:
    lo, hi = lim.position_min, lim.position_max
    if lo is not None and value < lo:
        raise ValidationError(
            f"{field_name} {value:g} is below the software position limit min {lo} "
            f"({lim.sources.get('position_min', '607Dh:01')}); nothing was sent",
            field=field_name,
            hint=f"stay within {lo} .. {hi}",
        )
    if hi is not None and value > hi:
        raise ValidationError(
            f"{field_name} {value:g} is above the software position limit max {hi} "
            f"({lim.sources.get('position_max', '607Dh:02')}); nothing was sent",
            field=field_name,
            hint=f"stay within {lo} .. {hi}",
        )


async def check_toward_limit(axis: Axis, lim: Limits, direction: float, field_name: str) -> None:
    """Refuse continuous motion toward a software limit the axis is already at or beyond."""
    lo, hi = lim.position_min, lim.position_max
    if not (direction > 0 and hi is not None) and not (direction < 0 and lo is not None):
        return
    pos = await read_int(axis.session, POSITION)
    if pos is None:
        return
    if direction > 0 and hi is not None and pos >= hi:
        which, value, src = "max", hi, lim.sources.get("position_max", "607Dh:02")
    elif direction < 0 and lo is not None and pos <= lo:
        which, value, src = "min", lo, lim.sources.get("position_min", "607Dh:01")
    else:
        return
    raise ValidationError(
        f"the axis is at {pos}, at or beyond the software position limit {which} {value} "
        f"({src}); {field_name} {direction:g} moves toward it, so it was refused and "
        "nothing was sent",
        field=field_name,
        hint=f"move the other way, back inside {lo} .. {hi}",
    )


async def ramp_rate(axis: Axis, address: ObjectAddress, requested: int | None) -> float | None:
    """An acceleration or deceleration in position units per s², when it is in those units.

    ``requested`` is the value the motion writes; without it the drive's value is read.
    """
    spec = axis.session.profile.spec(address)
    if spec is None or not per_s2(spec.raw_unit):
        return None
    value: int | None = requested
    if value is None:
        with contextlib.suppress(ObjectAccessError, ValidationError):
            value = await read_int(axis.session, address)
    return float(value) if value is not None and value > 0 else None


async def halt_rate(axis: Axis, requested: int | None) -> float | None:
    """The deceleration a halt uses: CiA 402-2 §6.3.4 halt option code 605Dh.

    1 (and vendor values): the slow-down ramp 6084h; 2: the quick-stop ramp 6085h; 3/4: the
    current or voltage limit, at least as hard as 6084h, so 6084h is a safe estimate.
    """
    option = 1
    if axis.session.profile.spec(HALT_OPTION) is not None:
        with contextlib.suppress(ObjectAccessError, ValidationError):
            option = await read_int(axis.session, HALT_OPTION) or 1
    if option == 2:
        return await ramp_rate(axis, QUICK_STOP_DEC, None)
    return await ramp_rate(axis, PROFILE_DEC, requested)


async def limit_guard(
    axis: Axis,
    lim: Limits,
    velocity: int,
    acceleration: int | None,
    deceleration: int | None,
) -> dict[str, Any]:
    """What the monitor needs to halt continuous motion before a software limit."""
    lo, hi = lim.position_min, lim.position_max
    if lo in (None, INT32_MIN) and hi in (None, INT32_MAX):
        return {}  # No limit, or the whole INTEGER32 range (the generic default).
    p = axis.session.profile
    spec = p.spec(TARGET_VELOCITY)
    # The commanded velocity bounds the speed ahead when 60FFh is in position units per s.
    cap = float(abs(velocity)) if spec is not None and per_s(spec.raw_unit) else None
    actual = p.spec(VELOCITY)
    return {
        "guard": lim,
        "halt_decel": await halt_rate(axis, deceleration),
        "acceleration": await ramp_rate(axis, PROFILE_ACC, acceleration),
        "speed_cap": cap,
        "read_velocity": actual is not None and per_s(actual.raw_unit),
    }


def encode_writes(
    axis: Axis, writes: list[tuple[ObjectAddress, Value]]
) -> list[tuple[ObjectAddress, Value]]:
    """Validate every planned write against the profile before the first one is sent."""
    p = axis.session.profile
    for address, value in writes:
        spec = p.spec(address)
        if spec is None and p.variables:
            raise ValidationError(
                f"{p.name} ({p.id}) has no object {address}, which this motion needs",
                field=str(address),
                hint="this family does not support that part of the motion",
            )
        encode_write(address, spec, value)
    return writes


def per_s2(raw_unit: str | None) -> bool:
    """True when a ramp object's raw unit is position units per s² (domain/ramps.py); with a
    time or a register the stopping distance is estimated with ``FALLBACK_STOP_S``."""
    return ramp_kind(raw_unit) == "rate"


def per_s(raw_unit: str | None) -> bool:
    """True when a velocity object's raw unit is position units per second."""
    if raw_unit is None:
        return True
    unit = raw_unit.replace(" ", "")
    return ("/s" in unit) and not per_s2(raw_unit)


def limit_ahead(
    motion: Motion,
    lim: Limits,
    pos: int,
    vel: int | None,
    last: tuple[float, int] | None,
    now: float,
) -> str | None:
    """Why continuous motion must halt now to stop before a software limit (None: it need not).

    The velocity is 606Ch when it is in position units per second, else the difference of
    two position samples. The stopping distance is what the axis covers until the next sample
    and the halt take effect, plus the braking distance at the halt deceleration
    (``FALLBACK_STOP_S`` of braking when that deceleration is not known in position units).
    """
    lo, hi = lim.position_min, lim.position_max
    if vel is not None:
        v = float(vel)
    elif last is not None and now > last[0]:
        v = (pos - last[1]) / (now - last[0])
    else:
        v = 0.0
    direction = v if v != 0 else (motion.target or 0.0)
    # Until the next sample and the halt reach the drive: three periods, more when the last
    # samples came late (a busy event loop), since the next one may come as late.
    interval = now - last[0] if last is not None else LIMIT_GUARD_PERIOD
    lead = max(3 * LIMIT_GUARD_PERIOD, 1.5 * interval + LIMIT_GUARD_PERIOD)
    speed = abs(v) + (motion.acceleration or 0.0) * lead
    if motion.speed_cap is not None:
        # Still accelerating: not beyond the commanded speed (nor below the measured one).
        speed = max(abs(v), min(speed, motion.speed_cap))
    if motion.halt_decel:
        braking = speed * speed / (2.0 * motion.halt_decel)
    else:
        braking = speed * FALLBACK_STOP_S / 2.0
    distance = speed * lead + braking
    if direction > 0 and hi is not None and pos + distance >= hi:
        which, value, src = "max", hi, lim.sources.get("position_max", "607Dh:02")
    elif direction < 0 and lo is not None and pos - distance <= lo:
        which, value, src = "min", lo, lim.sources.get("position_min", "607Dh:01")
    else:
        return None
    return (
        f"halted at {pos} before the software position limit {which} {value} ({src}): "
        f"at {abs(v):.0f}/s the axis needs about {distance:.0f} to stop"
    )
