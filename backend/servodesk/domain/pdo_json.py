"""PDO configurations as JSON, and the profile's PDO templates.

:func:`config_to_json` writes a configuration as the PdoLayout body of docs/pdo.md and
:func:`config_from_json` reads one back (PDOs and fields left out keep their current value; bad
input raises a :class:`~servodesk.errors.ValidationError` naming the field). :func:`templates`
lists a profile's templates and :func:`apply_template` applies one to the current configuration
through the same JSON reader.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

from servodesk.domain.datatypes import DataType, coerce_int
from servodesk.domain.pdo_model import Direction, MapEntry, Pdo, PdoComm, PdoConfig, Template
from servodesk.domain.pdo_objects import (
    _comm_index,
    _count,
    _directions,
    _map_index,
    _resolve,
    _telegram_entries,
    rules_of,
)
from servodesk.domain.profile import DeviceProfile, PdoTelegram, PdoTemplate, resolve_value
from servodesk.errors import NotFoundError, ValidationError


def templates(profile: DeviceProfile) -> list[Template]:
    return list(rules_of(profile).templates)


def apply_template(profile: DeviceProfile, current: PdoConfig, template_id: str) -> PdoConfig:
    """``current`` with the template's PDOs (the others unchanged); not validated."""
    for t in rules_of(profile).templates:
        if t.id == template_id:
            return config_from_json(profile, _template_json(t), current=current)
    raise NotFoundError(
        f"no PDO template {template_id!r} for {profile.name}",
        hint="templates: " + ", ".join(t.id for t in rules_of(profile).templates),
    )


def _template_json(t: PdoTemplate) -> dict[str, Any]:
    pdos: list[dict[str, Any]] = []
    for p in t.pdos:
        item: dict[str, Any] = {"direction": p.direction, "number": p.number}
        if p.entries is not None:
            item["entries"] = [
                w.address if w.bits is None else {"address": w.address, "bits": w.bits}
                for w in p.entries
            ]
        for k in (
            "enabled",
            "cob_id",
            "rtr_allowed",
            "transmission_type",
            "inhibit_time",
            "event_timer",
            "sync_start",
        ):
            v = getattr(p, k)
            if v is not None:
                item[k] = v
        pdos.append(item)
    out: dict[str, Any] = {"pdos": pdos}
    if t.assignment is not None:
        out["assignment"] = {k: list(v) for k, v in t.assignment.items()}
    if t.telegram is not None:
        out["telegram"] = t.telegram
    return out


def _entry_json(profile: DeviceProfile, e: MapEntry) -> str | dict[str, int]:
    if e.index == 0 and e.subindex in (0, e.bits):
        return f"reserved:{e.bits}"
    try:
        if _resolve(profile, str(e), "entry") == e:
            return str(e)
    except ValidationError:
        pass
    return {"index": e.index, "subindex": e.subindex, "bits": e.bits}


def config_to_json(profile: DeviceProfile, config: PdoConfig) -> dict[str, Any]:
    """The configuration as a PdoLayout body (docs/pdo.md); :func:`config_from_json` reads
    it back unchanged."""
    pdos: list[dict[str, Any]] = []
    for p in config.pdos:
        item: dict[str, Any] = {
            "direction": p.direction.value,
            "number": p.number,
            "entries": [_entry_json(profile, e) for e in p.entries],
        }
        if p.comm is not None:
            c = p.comm
            item.update(
                cob_id=c.cob_id,
                enabled=c.enabled,
                rtr_allowed=c.rtr_allowed,
                transmission_type=c.transmission_type,
                inhibit_time=c.inhibit_time,
                event_timer=c.event_timer,
                sync_start=c.sync_start,
            )
        pdos.append(item)
    out: dict[str, Any] = {"pdos": pdos}
    if config.assignment is not None:
        out["assignment"] = {d.value: list(v) for d, v in config.assignment.items()}
    if config.telegram is not None:
        out["telegram"] = config.telegram
    return out


_PDO_KEYS = {
    "direction",
    "number",
    "entries",
    "cob_id",
    "enabled",
    "rtr_allowed",
    "transmission_type",
    "inhibit_time",
    "event_timer",
    "sync_start",
}
_COMM_LIMITS = {
    "transmission_type": 0xFF,
    "inhibit_time": 0xFFFF,
    "event_timer": 0xFFFF,
    "sync_start": 0xFF,
}


def _json_int(v: Any, where: str, lo: int, hi: int, node_id: int = 0) -> int:
    try:
        if isinstance(v, str) and "$NODEID" in v.upper():
            r = resolve_value(v, DataType.UNSIGNED32, node_id)
            n = int(r) if isinstance(r, int) else coerce_int(str(r))
        elif isinstance(v, bool) or not isinstance(v, int | str | float):
            raise ValidationError(f"{v!r} is not a number")
        else:
            n = coerce_int(v)
    except (ValidationError, ValueError) as exc:
        msg = exc.message if isinstance(exc, ValidationError) else str(exc)
        raise ValidationError(f"{where}: {msg}", field=where) from None
    if not lo <= n <= hi:
        raise ValidationError(f"{where}: {n} is outside {lo}..{hi}", field=where)
    return n


def _json_bool(v: Any, where: str) -> bool:
    if isinstance(v, bool):
        return v
    raise ValidationError(f"{where}: {v!r} is not true or false", field=where)


def config_from_json(
    profile: DeviceProfile,
    data: Mapping[str, Any],
    *,
    current: PdoConfig | None = None,
) -> PdoConfig:
    """A configuration from a PdoLayout body (docs/pdo.md).

    PDOs (and fields) left out keep their value in ``current``; without ``current`` every PDO
    must be given. Bad input raises :class:`ValidationError` naming the field."""
    if not isinstance(data, Mapping):
        raise ValidationError("the PDO layout must be a JSON object", field="pdos")
    unknown = set(data) - {"pdos", "assignment", "telegram"}
    if unknown:
        raise ValidationError(
            f"unknown key {sorted(unknown)[0]!r}",
            field=sorted(unknown)[0],
            hint="a PDO layout has pdos, assignment and telegram",
        )
    rules = rules_of(profile)
    kind = rules.kind
    node_id = _node_id_of(current)
    telegram = current.telegram if current is not None else None
    if "telegram" in data and data["telegram"] is not None:
        if kind != "telegram":
            raise ValidationError(
                f"{profile.name} has no telegrams", field="telegram", hint="leave telegram out"
            )
        telegram = _json_int(data["telegram"], "telegram", 0, 0xFFFF)
    tg = rules.telegram(telegram) if telegram is not None else None
    if kind == "telegram" and tg is None:
        known = ", ".join(str(t.number) for t in rules.telegrams)
        raise ValidationError(
            f"telegram {telegram} is not supported", field="telegram", hint=f"choose {known}"
        )
    telegram_changed = current is not None and current.telegram != telegram
    given: dict[tuple[Direction, int], Mapping[str, Any]] = {}
    raw_pdos = data.get("pdos", [])
    if not isinstance(raw_pdos, Sequence) or isinstance(raw_pdos, str):
        raise ValidationError("pdos must be a list", field="pdos")
    for i, item in enumerate(raw_pdos):
        where = f"pdos[{i}]"
        if not isinstance(item, Mapping):
            raise ValidationError(f"{where} must be an object", field=where)
        bad = set(item) - _PDO_KEYS
        if bad:
            k = sorted(bad)[0]
            raise ValidationError(f"{where}.{k}: unknown key", field=f"{where}.{k}")
        try:
            d = Direction(str(item.get("direction", "")).lower())
        except ValueError:
            raise ValidationError(
                f"{where}.direction: {item.get('direction')!r} is not rx or tx",
                field=f"{where}.direction",
            ) from None
        n = _json_int(item.get("number"), f"{where}.number", 1, _count(profile, d) or 1)
        if n > _count(profile, d):
            raise ValidationError(
                f"{where}.number: {profile.name} has {_count(profile, d)} {d.value} PDOs",
                field=f"{where}.number",
            )
        if (d, n) in given:
            raise ValidationError(f"{where}: {d.value} PDO {n} is given twice", field=where)
        given[(d, n)] = item
    pdos: list[Pdo] = []
    for d, n in _directions(profile):
        base = _base_pdo(profile, current, d, n, tg if telegram_changed else None)
        item = given.get((d, n))
        if item is None:
            if base is None:
                raise ValidationError(
                    f"{d.value} PDO {n} is missing",
                    field="pdos",
                    hint="give every PDO, or pass the current configuration",
                )
            if tg is not None and not tg.variable:
                base = replace(base, entries=_telegram_entries(profile, tg, d))
            pdos.append(base)
            continue
        where = f"pdos[{raw_pdos.index(item)}]"
        if "entries" in item and item["entries"] is not None:
            ents = item["entries"]
            if not isinstance(ents, Sequence) or isinstance(ents, str):
                raise ValidationError(f"{where}.entries must be a list", field=f"{where}.entries")
            entries = tuple(
                _entry_from_json(profile, e, f"{where}.entries[{k}]") for k, e in enumerate(ents)
            )
        elif base is not None:
            entries = base.entries
        else:
            raise ValidationError(f"{where}.entries is missing", field=f"{where}.entries")
        if tg is not None and not tg.variable:
            # A fixed telegram always has its own layout (004 §20.3); entries sent along
            # (e.g. the previous telegram's, merged by a client) do not apply to it.
            entries = _telegram_entries(profile, tg, d)
        comm: PdoComm | None = None
        ci: int | None = None
        if kind == "canopen":
            ci = _comm_index(d, n)
            bc = base.comm if base is not None else None
            vals: dict[str, Any] = {}
            for k in ("cob_id", "enabled", "rtr_allowed", *_COMM_LIMITS):
                if k in item and item[k] is not None:
                    vals[k] = item[k]
                elif bc is not None:
                    vals[k] = getattr(bc, k)
                elif k in ("cob_id", "enabled"):
                    raise ValidationError(f"{where}.{k} is missing", field=f"{where}.{k}")
            cob = _json_int(vals["cob_id"], f"{where}.cob_id", 0, 0x1FFFFFFF, node_id)
            comm = PdoComm(
                cob_id=cob,
                enabled=_json_bool(vals["enabled"], f"{where}.enabled"),
                rtr_allowed=_json_bool(vals.get("rtr_allowed", True), f"{where}.rtr_allowed"),
                **{
                    k: _json_int(
                        vals.get(k, 255 if k == "transmission_type" else 0), f"{where}.{k}", 0, hi
                    )
                    for k, hi in _COMM_LIMITS.items()
                },
            )
        elif any(k in item for k in (*_COMM_LIMITS, "cob_id", "enabled", "rtr_allowed")):
            k = next(k for k in (*_COMM_LIMITS, "cob_id", "enabled", "rtr_allowed") if k in item)
            raise ValidationError(
                f"{where}.{k}: {profile.name} has no communication parameters ({kind} family)",
                field=f"{where}.{k}",
                hint="give only direction, number and entries",
            )
        mi = _map_index(d, n)
        pdos.append(Pdo(d, n, mi, ci, comm, entries, kind))
    assignment: dict[Direction, tuple[int, ...]] | None = None
    if kind == "ethercat":
        assignment = dict(current.assignment or {}) if current is not None else {}
        raw = data.get("assignment")
        if raw is not None:
            if not isinstance(raw, Mapping):
                raise ValidationError(
                    'assignment must be {"rx": [0x1600], "tx": [0x1A00]}', field="assignment"
                )
            for k, v in raw.items():
                try:
                    d = Direction(str(k).lower())
                except ValueError:
                    raise ValidationError(
                        f"assignment.{k}: not rx or tx", field=f"assignment.{k}"
                    ) from None
                seq = [v] if isinstance(v, int | str) else v
                if not isinstance(seq, Sequence):
                    raise ValidationError(f"assignment.{k} must be a list", field=f"assignment.{k}")
                assignment[d] = tuple(
                    _json_int(x, f"assignment.{k}[{j}]", 0, 0xFFFF) for j, x in enumerate(seq)
                )
        for d in Direction:
            if d not in assignment:
                raise ValidationError(
                    f"assignment.{d.value} is missing", field=f"assignment.{d.value}"
                )
    elif data.get("assignment") is not None:
        raise ValidationError(f"{profile.name} has no sync manager assignment", field="assignment")
    return PdoConfig(tuple(pdos), assignment, telegram)


def _node_id_of(current: PdoConfig | None) -> int:
    """The node id the current default COB-IDs imply (for ``$NODEID`` in templates)."""
    if current is None:
        return 0
    for p in current.pdos:
        if p.comm is not None and p.number == 1:
            base = 0x200 if p.direction is Direction.RX else 0x180
            if base < p.comm.cob_id <= base + 127:
                return p.comm.cob_id - base
    return 0


def _base_pdo(
    profile: DeviceProfile,
    current: PdoConfig | None,
    d: Direction,
    n: int,
    new_telegram: PdoTelegram | None,
) -> Pdo | None:
    if current is None:
        return None
    try:
        p = current.pdo(d, n)
    except NotFoundError:
        return None
    if new_telegram is not None:
        # Another telegram: its default mapping, not the old one (004 §20.3).
        return replace(p, entries=_telegram_entries(profile, new_telegram, d))
    return p


# --------------------------------------------------------------------------------------------
# Mapping entries from JSON


def _entry_from_json(profile: DeviceProfile, item: Any, where: str) -> MapEntry:
    if isinstance(item, str):
        return _resolve(profile, item, where)
    if isinstance(item, int) and not isinstance(item, bool):
        return MapEntry.from_raw(item)
    if isinstance(item, Mapping):
        unknown = set(item) - {"index", "subindex", "bits", "address", "raw"}
        if unknown:
            raise ValidationError(
                f"{where}: unknown key {sorted(unknown)[0]!r}",
                field=where,
                hint='an entry is "0x607A:00" or {"index", "subindex", "bits"}',
            )
        try:
            if "raw" in item:
                return MapEntry.from_raw(coerce_int(item["raw"]))
            if "address" in item:
                e = _resolve(profile, str(item["address"]), where)
                bits = item.get("bits")
                return e if bits is None else replace(e, bits=coerce_int(bits))
            index = coerce_int(item["index"])
            sub = coerce_int(item.get("subindex", 0))
            if "bits" in item:
                bits = coerce_int(item["bits"])
            else:
                bits = _resolve(profile, f"0x{index:04X}:{sub:02X}", where).bits
        except KeyError as exc:
            raise ValidationError(f"{where}: {exc.args[0]!r} is missing", field=where) from None
        except ValidationError as exc:
            raise ValidationError(
                exc.message if exc.message.startswith(where) else f"{where}: {exc.message}",
                field=where,
                hint=exc.hint,
            ) from None
        if not (0 <= index <= 0xFFFF and 0 <= sub <= 0xFF and 0 <= bits <= 0xFF):
            raise ValidationError(f"{where}: index, subindex or bits out of range", field=where)
        return MapEntry(index, sub, bits)
    raise ValidationError(
        f"{where}: {item!r} is not a mapping entry",
        field=where,
        hint='write "0x607A:00" or {"index": 24698, "subindex": 0, "bits": 32}',
    )
