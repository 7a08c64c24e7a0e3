"""Parameter sets (backups) and their file format.

Pure functions only: nothing here touches a bus, a file or a database. A
:class:`ParameterSet` is what a backup holds (raw bytes per object, as the drive holds them,
plus the typed view for people); :func:`dumps` / :func:`loads` are the versioned JSON file
format (docs/backup.md); :func:`~servodesk.domain.paramset_compare.compare` finds what differs;
:func:`~servodesk.domain.restore_plan.preflight` checks a set against a drive before anything
is written and :func:`~servodesk.domain.restore_plan.plan_writes` orders the writes the way the
profile and CiA 301 require.

The raw bytes are authoritative: a typed value that disagrees with its bytes makes a file
corrupt, never a silent choice between the two.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.ids import check_id
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.errors import ServodeskError, ValidationError

FORMAT = "servodesk-backup"
SCHEMA_VERSION = 1

#: CiA 301 §7.5.2.13/14: store (1010h) and restore-defaults (1011h) are commands, not
#: parameters: writing them saves or wipes the drive's memory, so no backup holds them.
_COMMAND_INDICES = frozenset({0x1010, 0x1011})
#: Quirks whose value names a command object ({index, subindex, value}): store, restore,
#: activation, history clear, reset (docs/profiles.md, quirk vocabulary).
_COMMAND_QUIRKS = (
    "store_parameters",
    "restore_defaults",
    "parameter_activation",
    "clear_alarm_history",
    "device_reset",
)


# ------------------------------------------------------------------------------------ model


@dataclass(frozen=True, slots=True)
class Entry:
    """One parameter of a set: the bytes as the drive holds them, with its description."""

    address: ObjectAddress
    name: str
    data_type: DataType
    raw: bytes
    unit: str | None = None

    @property
    def value(self) -> int | float | bool | str | None:
        return typed_value(self.data_type, self.raw)


@dataclass(frozen=True, slots=True)
class Unreadable:
    """A configurable object the drive did not give when the set was read."""

    address: ObjectAddress
    name: str
    code: int | None
    message: str


@dataclass(frozen=True)
class ParameterSet:
    """A backup: where it came from and one :class:`Entry` per configurable object."""

    profile_id: str
    profile_version: str
    time: str
    entries: tuple[Entry, ...]
    label: str = ""
    note: str = ""
    identity: dict[str, Any] = field(default_factory=dict)
    firmware: str | None = None
    bus: dict[str, Any] = field(default_factory=dict)
    drive_key: str = ""
    unreadable: tuple[Unreadable, ...] = ()
    tool: str = "servodesk"
    #: The drive's encoder (608Fh) when it is not the profile's: the engineering values of the
    #: objects counted in increments are for it (domain/encoder_units.py). None: the profile's.
    counts_per_rev: float | None = None

    def by_address(self) -> dict[ObjectAddress, Entry]:
        return {e.address: e for e in self.entries}


def typed_value(dt: DataType, raw: bytes) -> int | float | bool | str | None:
    """The JSON view of raw bytes: numbers, text, hex text for OCTET_STRING/DOMAIN."""
    try:
        v = codec(dt).decode(raw)
    except ServodeskError:
        return None
    if isinstance(v, bytes):
        return v.hex()
    if isinstance(v, float) and not math.isfinite(v):
        return None  # JSON has no NaN/inf; the raw bytes keep the exact value.
    return v


# ----------------------------------------------------------------------------- selection


def command_addresses(profile: DeviceProfile) -> set[ObjectAddress]:
    """Objects that are commands (store, restore, activate, reset), never parameters."""
    out = {a for a in profile.variables if a.index in _COMMAND_INDICES}
    # Commands the family's own objects take (a clear, a save, a gantry start): a backup that
    # held their idle value would write it back on restore, and a write is an order.
    out.update(quirk_addresses(profile, "command_objects"))
    for qid in _COMMAND_QUIRKS:
        q = profile.quirk(qid)
        if isinstance(q, dict) and "index" in q:
            out.add(ObjectAddress(int(q["index"]), int(q.get("subindex", 0))))
    return out


def quirk_addresses(profile: DeviceProfile, quirk_id: str) -> list[ObjectAddress]:
    q = profile.quirk(quirk_id)
    out: list[ObjectAddress] = []
    if isinstance(q, list):
        for text in q:
            try:
                out.append(ObjectAddress.parse(str(text)))
            except ValidationError:
                continue
    return out


def configurable(profile: DeviceProfile) -> list[ObjectSpec]:
    """What a backup reads: readable and writable objects that are not process values.

    Left out: command objects (:func:`command_addresses`), objects the drive sets itself
    (quirk ``auto_set_objects``: writing them is refused) and objects the manual marks as not
    usable (quirk ``objects_not_usable``, by index).
    """
    commands = command_addresses(profile)
    auto = set(quirk_addresses(profile, "auto_set_objects"))
    unusable = {a.index for a in quirk_addresses(profile, "objects_not_usable")}
    return [
        s
        for a, s in profile.variables.items()
        if not s.process
        and s.access.readable
        and s.access.writable
        and a not in commands
        and a not in auto
        and a.index not in unusable
    ]


def defaults_set(profile: DeviceProfile, node_id: int, time: str = "") -> ParameterSet:
    """The profile's default values of its configurable objects (those that have one)."""
    entries: list[Entry] = []
    for s in configurable(profile):
        try:
            v = s.default_value(node_id)
            if v is None:
                continue
            raw = codec(s.data_type).encode(v)
        except (ServodeskError, ValueError):
            continue
        entries.append(Entry(s.address, s.name, s.data_type, raw, s.unit))
    return ParameterSet(
        profile_id=profile.id,
        profile_version=profile.version,
        time=time,
        entries=tuple(entries),
        label=f"defaults of {profile.id}",
    )


# -------------------------------------------------------------------------------- file


def to_document(ps: ParameterSet, tool: str) -> dict[str, Any]:
    """The JSON document of a set (without its checksum); see docs/backup.md."""
    return {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "tool": tool,
        "time": ps.time,
        "label": ps.label,
        "note": ps.note,
        "profile": {"id": ps.profile_id, "version": ps.profile_version},
        "drive_key": ps.drive_key,
        "identity": dict(ps.identity),
        "firmware": ps.firmware,
        "bus": dict(ps.bus),
        # Written only when the drive's encoder is not the profile's, so that a set of any other
        # drive reads (and checksums) as before.
        **({"encoder": {"counts_per_rev": ps.counts_per_rev}} if ps.counts_per_rev else {}),
        "entries": [
            {
                "address": str(e.address),
                "name": e.name,
                "data_type": e.data_type.name,
                "raw_hex": e.raw.hex(),
                "value": e.value,
                "unit": e.unit,
            }
            for e in ps.entries
        ],
        "unreadable": unreadable_dicts(ps.unreadable),
    }


def unreadable_dicts(items: Iterable[Unreadable]) -> list[dict[str, Any]]:
    """The objects a set lacks because the drive refused them, as the file and the API show
    them: address, name, abort code (CiA 301 §7.2.4.3.17) and the error text."""
    return [
        {
            "address": str(u.address),
            "name": u.name,
            "code": u.code,
            "code_hex": f"0x{u.code:08X}" if u.code is not None else None,
            "message": u.message,
        }
        for u in items
    ]


def checksum(doc: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of everything but the checksum itself."""
    body = {k: v for k, v in doc.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return "sha256:" + hashlib.sha256(text.encode("utf-8")).hexdigest()


def dumps(ps: ParameterSet, tool: str) -> bytes:
    """The backup file's bytes: indented UTF-8 JSON ending in a newline, with its checksum."""
    doc = to_document(ps, tool)
    doc["checksum"] = checksum(doc)
    return (json.dumps(doc, indent=2, ensure_ascii=False) + "\n").encode("utf-8")


def _bad(source: str, message: str, hint: str, where: str | None = None) -> ValidationError:
    return ValidationError(f"{source}: {message}", field=where or "file", hint=hint)


def loads(data: bytes, source: str = "backup") -> ParameterSet:
    """Read and check a backup file; every defect is a ValidationError naming the place."""
    try:
        doc = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise _bad(source, "not UTF-8 text", "choose a servodesk backup (.json) file") from None
    except json.JSONDecodeError as exc:
        raise _bad(
            source,
            f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg}); "
            "the file is truncated or corrupt",
            "use an intact copy of the backup",
        ) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise _bad(
            source,
            'not a servodesk backup (no "format": "servodesk-backup")',
            "choose a file written by servodesk backup, or import a DCF",
        )
    version = doc.get("schema_version")
    if version != SCHEMA_VERSION:
        raise _bad(
            source,
            f"backup schema version {version!r} is not supported (this servodesk reads "
            f"version {SCHEMA_VERSION})",
            "open the file with the servodesk version that wrote it",
        )
    stated = doc.get("checksum")
    if not isinstance(stated, str):
        raise _bad(source, "the checksum is missing", "use an intact copy of the backup")
    if stated != checksum(doc):
        raise _bad(
            source,
            "checksum mismatch: the file was changed or damaged after it was written",
            "use an intact copy of the backup (files are never edited by servodesk)",
        )
    profile = doc.get("profile")
    if isinstance(profile, dict) and "id" in profile:
        # The profile id names the stored file (services/backup.py): checked before anything
        # else is read from the document.
        try:
            check_id(profile["id"], "profile.id")
        except ValidationError as exc:
            raise _bad(source, exc.message, exc.hint or "", "profile.id") from None
    try:
        return _from_document(doc)
    except (KeyError, TypeError, ValueError, ServodeskError) as exc:
        msg = exc.message if isinstance(exc, ServodeskError) else str(exc)
        raise _bad(source, f"malformed backup: {msg}", "use an intact copy of the backup") from None


def _str(v: Any, name: str, *, optional: bool = False) -> Any:
    if v is None and optional:
        return None
    if not isinstance(v, str):
        raise ValueError(f"{name} must be text")
    return v


def _from_document(doc: dict[str, Any]) -> ParameterSet:
    profile = doc["profile"]
    entries: list[Entry] = []
    seen: set[ObjectAddress] = set()
    for i, e in enumerate(doc["entries"]):
        where = f"entries[{i}]"
        address = ObjectAddress.parse(_str(e["address"], f"{where}.address"))
        if address in seen:
            raise ValueError(f"{where}: {address} appears twice")
        seen.add(address)
        dt = DataType.from_name(_str(e["data_type"], f"{where}.data_type"))
        try:
            raw = bytes.fromhex(_str(e["raw_hex"], f"{where}.raw_hex"))
        except ValueError:
            raise ValueError(f"{where} {address}: raw_hex is not hex bytes") from None
        n = dt.bits // 8
        if n and len(raw) != n:
            raise ValueError(
                f"{where} {address}: {dt.name} needs {n} bytes, raw_hex has {len(raw)}"
            )
        entry = Entry(address, _str(e["name"], f"{where}.name"), dt, raw, e.get("unit"))
        if not _same_value(entry.value, e.get("value")):
            raise ValueError(
                f"{where} {address}: value {e.get('value')!r} disagrees with raw_hex "
                f"{raw.hex()} ({entry.value!r})"
            )
        entries.append(entry)
    unreadable = tuple(
        Unreadable(
            ObjectAddress.parse(u["address"]), str(u.get("name", "")), u.get("code"), u["message"]
        )
        for u in doc.get("unreadable", [])
    )
    encoder = doc.get("encoder") or {}
    cpr = encoder.get("counts_per_rev") if isinstance(encoder, dict) else None
    if cpr is not None and (
        isinstance(cpr, bool) or not isinstance(cpr, int | float) or not 0 < cpr < 2**32
    ):
        raise ValueError(f"encoder.counts_per_rev {cpr!r} is not a positive number of counts")
    return ParameterSet(
        counts_per_rev=float(cpr) if cpr is not None else None,
        profile_id=_str(profile["id"], "profile.id"),
        profile_version=str(profile.get("version", "")),
        time=_str(doc["time"], "time"),
        entries=tuple(entries),
        label=str(doc.get("label") or ""),
        note=str(doc.get("note") or ""),
        identity=dict(doc.get("identity") or {}),
        firmware=_str(doc.get("firmware"), "firmware", optional=True),
        bus=dict(doc.get("bus") or {}),
        drive_key=str(doc.get("drive_key") or ""),
        unreadable=unreadable,
        tool=str(doc.get("tool") or ""),
    )


def _same_value(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        try:
            return float(a) == float(b)
        except (TypeError, ValueError):
            return False
    return bool(a == b and type(a) is type(b))
