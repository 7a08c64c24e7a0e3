"""Shared helpers of the device-description readers and writers (EDS/DCF, ESI, XDD).

Holds the number syntax the standard files use, the list of profile fields that the standard
formats cannot carry (kept in ``servodesk_`` extras so a round trip is lossless), and the
construction of :class:`~servodesk.domain.profile.DeviceProfile` objects from parsed data with
every pydantic error turned into a :class:`~servodesk.errors.ProfileError`.
"""

from __future__ import annotations

import contextlib
import contextvars
import enum
import json
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import pydantic

from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import (
    Access,
    DeviceProfile,
    Group,
    ObjectEntry,
    ObjectSpec,
    ObjectType,
    PdoMapping,
    SubSpec,
    resolve_value,
)
from servodesk.errors import ProfileError, ServodeskError

#: Fields of a flattened variable, in the order ObjectSpec declares them (address excluded).
SPEC_FIELDS: tuple[str, ...] = tuple(
    f for f in ObjectSpec.model_fields if f not in ("index", "subindex")
)
#: Fields of an ARRAY/RECORD entry that describe the whole index (not its subs).
ENTRY_FIELDS: tuple[str, ...] = tuple(
    f for f in ObjectEntry.model_fields if f not in ("index", "object_type", "subs")
)
#: Profile fields carried as one JSON value (everything but the id and the objects).
PROFILE_EXCLUDE = frozenset({"id", "objects", "extends", "schema_version"})

EXTRA_PREFIX = "servodesk_"

_SPEC_DEFAULTS: dict[str, Any] = {
    name: f.default for name, f in ObjectSpec.model_fields.items() if not f.is_required()
}
_ENTRY_DEFAULTS: dict[str, Any] = {
    name: f.default for name, f in ObjectEntry.model_fields.items() if not f.is_required()
}


def spec_default(name: str) -> Any:
    """The value an ObjectSpec field has when a file says nothing about it."""
    return _SPEC_DEFAULTS.get(name)


def entry_default(name: str) -> Any:
    return _ENTRY_DEFAULTS.get(name)


def same(a: Any, b: Any) -> bool:
    """Equal and of the same type (0 and 0.0, 1 and True are different authored values)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return bool(a == b)


def diff(actual: Mapping[str, Any], baseline: Mapping[str, Any], names: Iterable[str]) -> list[str]:
    """The field names whose actual value the standard keys do not reproduce."""
    return [n for n in names if not same(actual.get(n), baseline.get(n))]


_INT = re.compile(r"^([+-]?)\s*(0x[0-9a-f]+|#x[0-9a-f]+|0[0-7]+|0|[1-9][0-9]*)$", re.I)


def parse_int(text: str) -> int:
    """A CiA 306 / ETG.2000 integer: decimal, ``0x`` or ``#x`` hex, leading ``0`` octal.

    Raises ValueError with a short reason.
    """
    t = text.strip().replace(" ", "")
    m = _INT.match(t)
    if not m:
        raise ValueError(f"{text!r} is not an integer")
    sign = -1 if m.group(1) == "-" else 1
    body = m.group(2).lower()
    if body.startswith(("0x", "#x")):
        v = int(body[2:], 16)
    elif len(body) > 1 and body.startswith("0"):
        v = int(body, 8)  # CiA 306 §4.3: a leading 0 means octal.
    else:
        v = int(body)
    return sign * v


def to_signed(value: int, dt: DataType) -> int:
    """Hex text of a signed type is the two's complement: 0xFFFF for INTEGER16 is -1."""
    if dt.is_signed and value >= 0:
        bits = dt.bits
        if value >= 1 << (bits - 1) and value < 1 << bits:
            return value - (1 << bits)
    return value


def parse_number(text: str, dt: DataType) -> int | float:
    """A number of type ``dt`` as an EDS or ESI writes it; ints stay ints for REAL types."""
    t = text.strip()
    if dt.is_real:
        try:
            return parse_int(t)
        except ValueError:
            return float(t)
    return to_signed(parse_int(t), dt)


def dumps(value: Any) -> str:
    """JSON for a ``servodesk_`` key: ASCII only, and never a ``;`` (an INI comment start)."""
    return json.dumps(value, ensure_ascii=True, separators=(",", ":")).replace(";", "\\u003b")


_DICT_TAG = "__servodesk_dict__"
_TUPLE_TAG = "__servodesk_tuple__"


def _tagged(obj: Any) -> Any:
    """JSON-ready data that keeps what JSON would lose: tuples and non-text dict keys.

    Free-form profile values (quirk values) may be ``{11: "X"}`` or tuples; plain JSON would
    give them back as ``{"11": "X"}`` and lists.
    """
    if isinstance(obj, dict):
        if all(isinstance(k, str) for k in obj):
            return {k: _tagged(v) for k, v in obj.items()}
        return {_DICT_TAG: [[_tagged(k), _tagged(v)] for k, v in obj.items()]}
    if isinstance(obj, tuple):
        return {_TUPLE_TAG: [_tagged(v) for v in obj]}
    if isinstance(obj, list):
        return [_tagged(v) for v in obj]
    return obj


def _untag(obj: dict[str, Any]) -> Any:
    if len(obj) == 1 and _DICT_TAG in obj:
        return {_hashable(k): v for k, v in obj[_DICT_TAG]}
    if len(obj) == 1 and _TUPLE_TAG in obj:
        return tuple(obj[_TUPLE_TAG])
    return obj


def _hashable(k: Any) -> Any:
    return tuple(k) if isinstance(k, list) else k


def dumps_typed(value: Any) -> str:
    """Like :func:`dumps`, keeping tuples and int dict keys (read back by :func:`loads`)."""
    return dumps(_tagged(value))


def loads(text: str, where: str) -> Any:
    try:
        return json.loads(text, object_hook=_untag)
    except json.JSONDecodeError as exc:
        raise ProfileError(
            f"{where}: not valid JSON ({exc.msg} at character {exc.pos})",
            hint="servodesk_ keys hold JSON written by servodesk; remove the key to drop it",
        ) from None
    except (TypeError, ValueError, RecursionError):
        raise ProfileError(
            f"{where}: not the JSON servodesk writes",
            hint="servodesk_ keys hold JSON written by servodesk; remove the key to drop it",
        ) from None


def json_fields(spec_or_entry: pydantic.BaseModel, names: Iterable[str]) -> dict[str, Any]:
    """The JSON form of some fields (enums as values, tuples as lists)."""
    wanted = list(names)
    if not wanted:
        return {}
    dumped = spec_or_entry.model_dump(mode="json", include=set(wanted))
    return {n: dumped[n] for n in wanted}


def profile_meta(profile: DeviceProfile) -> str:
    """Every profile-level field a description file has no place for, as typed JSON text."""
    data = profile.model_dump(exclude=set(PROFILE_EXCLUDE))
    return dumps_typed(_plain(data))


def _plain(obj: Any) -> Any:
    """Enums to their values (str/int subclasses json would write anyway, made explicit)."""
    if isinstance(obj, dict):
        return {_plain(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, tuple):
        return tuple(_plain(v) for v in obj)
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    if isinstance(obj, enum.Enum):
        return obj.value
    return obj


def slug(text: str) -> str:
    """A profile id from a product name: lower case, digits and dashes."""
    s = re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
    return s or "imported"


def ascii_text(text: str) -> str:
    """Text safe as a plain INI value: one line, ASCII, no ``;`` comment starts."""
    out = text.replace("\r", " ").replace("\n", " ").replace(";", ",")
    return out.encode("ascii", errors="replace").decode("ascii").strip()


@dataclass
class ParsedObject:
    """One index as read from a file, before it becomes an ObjectEntry."""

    index: int
    object_type: ObjectType
    where: str
    #: Entry-level fields (name, and for ARRAY/RECORD the servodesk extras of the index).
    entry: dict[str, Any] = field(default_factory=dict)
    #: Sub-index -> full ObjectSpec fields (for a VAR only sub-index 0).
    subs: dict[int, dict[str, Any]] = field(default_factory=dict)


def _fit(f: dict[str, Any], where: str) -> None:
    """Make one variable's fields fit servodesk's model, warning about each change.

    Vendor files hold limits the type cannot take (a signed MinValue on an UNSIGNED16),
    defaults outside their own limits, PDO-mappable values without a fixed size and
    RxPDO-mappable objects that SDO access calls read-only (ETG.2000 Flags/Access is the SDO
    access; the object is still written by the RxPDO).
    """
    dt = f.get("data_type")
    if not isinstance(dt, DataType):
        return
    rng = dt.range if dt.is_numeric else None
    for key in ("min", "max"):
        v = f.get(key)
        if v is None:
            continue
        if (
            isinstance(v, bool)
            or not isinstance(v, int | float)
            or not math.isfinite(v)
            or (rng is not None and not rng[0] <= v <= rng[1])
        ):
            warn(f"{where}: {key} {v!r} does not fit {dt.name}; limit left out")
            f[key] = None
    lo, hi = f.get("min"), f.get("max")
    if lo is not None and hi is not None and lo > hi:
        warn(f"{where}: min {lo} above max {hi}; both limits left out")
        f["min"] = f["max"] = None
    d = f.get("default")
    if isinstance(d, float) and not math.isfinite(d):
        warn(f"{where}: default {d} is not a finite number; left out")
        f["default"] = d = None
    if d is not None and not (isinstance(d, str) and "$NODEID" in d.upper()):
        try:
            value = resolve_value(d, dt, 1)
        except (ValueError, ServodeskError):
            warn(f"{where}: default {d!r} is not a {dt.name}; left out")
            f["default"] = None
            value = None
        if isinstance(value, int | float) and not isinstance(value, bool) and dt.is_numeric:
            lo, hi = f.get("min"), f.get("max")
            if lo is not None and value < lo:
                warn(f"{where}: default {value} below min {lo}; limit left out")
                f["min"] = None
            if hi is not None and value > hi:
                warn(f"{where}: default {value} above max {hi}; limit left out")
                f["max"] = None
    pdo = f.get("pdo_mapping")
    if isinstance(pdo, PdoMapping) and pdo is not PdoMapping.NONE and dt.bits == 0:
        warn(f"{where}: PDO-mappable {dt.name} without a fixed size; not mappable here")
        f["pdo_mapping"] = PdoMapping.NONE
        pdo = PdoMapping.NONE
    access = f.get("access")
    if (
        isinstance(pdo, PdoMapping)
        and pdo.rx
        and isinstance(access, Access)
        and not access.writable
    ):
        # CiA 306 rww: written by an RPDO; a process value, never backed up.
        warn(f"{where}: RxPDO-mappable but access {access.value}; taken as rww")
        f["access"] = Access.RWW
        f["process"] = True


def build_entry(obj: ParsedObject) -> ObjectEntry:
    """An ObjectEntry from parsed fields; a model error names the file location."""
    for sub, fields in obj.subs.items():
        if isinstance(fields, dict):
            _fit(
                fields,
                f"{obj.where} sub {sub}" if obj.object_type is not ObjectType.VAR else obj.where,
            )
    try:
        if obj.object_type is ObjectType.VAR:
            fields = dict(obj.subs.get(0, {}))
            fields.update({k: v for k, v in obj.entry.items() if k not in fields})
            return ObjectEntry(index=obj.index, object_type=ObjectType.VAR, **fields)
        subs = tuple(
            SubSpec(sub=s, **{k: v for k, v in f.items() if k in SubSpec.model_fields})
            for s, f in sorted(obj.subs.items())
        )
        if not subs:
            raise ProfileError(
                f"{obj.where}: {obj.object_type.value.upper()} 0x{obj.index:04X} has no "
                "sub-indices",
                hint="add its sub-index descriptions or remove the object",
            )
        return ObjectEntry(index=obj.index, object_type=obj.object_type, subs=subs, **obj.entry)
    except pydantic.ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise ProfileError(
            f"{obj.where}: object 0x{obj.index:04X}: {loc}: {first['msg']}",
            hint="correct the value in the file (see docs/device-descriptions.md)",
        ) from None


#: Groups of an imported file without servodesk extras, by CiA 301 index area (§7.4.3).
AREA_GROUPS: tuple[tuple[int, int, str, str], ...] = (
    (0x1000, 0x1FFF, "communication", "Communication (CiA 301)"),
    (0x2000, 0x5FFF, "manufacturer", "Manufacturer specific"),
    (0x6000, 0x9FFF, "device_profile", "Device profile (CiA 402)"),
)


def area_group(index: int) -> str | None:
    for lo, hi, gid, _ in AREA_GROUPS:
        if lo <= index <= hi:
            return gid
    return None


def make_profile(
    *,
    profile_id: str,
    meta: dict[str, Any] | None,
    standard: dict[str, Any],
    objects: list[ObjectEntry],
    where: str,
) -> DeviceProfile:
    """The profile: the servodesk extras (if any), then the file's standard keys over them."""
    data: dict[str, Any] = dict(meta or {})
    for k, v in standard.items():
        if k == "identity" and isinstance(v, dict):
            ident = dict(data.get("identity") or {})
            for ik, iv in v.items():
                if ik == "product_codes":
                    if iv and iv[0] not in (ident.get("product_codes") or ()):
                        ident[ik] = list(iv)
                elif iv is not None:
                    ident[ik] = iv
            data["identity"] = ident
        elif k == "pdo" and isinstance(v, dict):
            pdo = dict(data.get("pdo") or {})
            pdo.update(v)
            data["pdo"] = pdo
        elif k in ("name", "vendor", "description") and k in data and data[k]:
            # The extras hold the exact text; the standard key may be an ASCII rendering.
            continue
        elif v is not None:
            data[k] = v
    data.setdefault("name", profile_id)
    data.setdefault("vendor", "unknown")
    data["id"] = profile_id
    data["objects"] = objects
    if meta is None:
        used = {s.group for e in objects for s in e.specs() if s.group}
        data["groups"] = [
            Group(id=gid, name=name) for _, _, gid, name in AREA_GROUPS if gid in used
        ]
    try:
        return DeviceProfile.model_validate(data)
    except pydantic.ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"])
        raise ProfileError(
            f"{where}: {loc}: {first['msg']}",
            hint="the profile id must be lower case letters, digits and dashes",
        ) from None


# --------------------------------------------------------------------------------------------
# What an import skipped or changed. Real vendor files use things servodesk's model has no
# place for (modules, bit-sized types, values outside the type); the import goes on and each
# reader reports here exactly what it left out, so the user sees it (CLI, API) instead of a
# silently different profile.

_NOTES: contextvars.ContextVar[list[str] | None] = contextvars.ContextVar(
    "servodesk_devdesc_notes", default=None
)


def warn(message: str) -> None:
    """Record what the running import skipped or changed (no-op outside :func:`collecting`)."""
    notes = _NOTES.get()
    if notes is not None and message not in notes:
        notes.append(message)


@contextlib.contextmanager
def collecting() -> Iterator[list[str]]:
    """Collect the :func:`warn` messages of the imports run inside the block."""
    notes: list[str] = []
    token = _NOTES.set(notes)
    try:
        yield notes
    finally:
        _NOTES.reset(token)
