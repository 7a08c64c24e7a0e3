"""PDO planning: the ordered writes and NMT commands that change a drive's mapping.

:func:`plan` validates the desired configuration and returns a :class:`Plan` touching only the
PDOs that change, in the order each family needs (CiA 301 §7.5.2.35/36 for CANopen, unassign /
map / assign for EtherCAT, P922 then 1600h/1A00h for a telegram), wrapped in NMT
pre-operational when the drive remaps only there; :func:`full_plan` rewrites everything (the
rollback). Nothing is executed here: the session service runs the steps.
"""

from __future__ import annotations

from dataclasses import replace

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.pdo_model import Direction, Pdo, PdoConfig, PdoProblem, PdoStep, Plan
from servodesk.domain.pdo_objects import (
    _ASSIGN,
    _comm_fields,
    _has,
    _telegram_address,
    rules_of,
)
from servodesk.domain.pdo_validate import (
    _CIA_COMM,
    _CIA_MAP,
    _fixed_problem,
    _spec_name,
    validate,
)
from servodesk.domain.profile import DeviceProfile, PdoRules
from servodesk.errors import NotFoundError, PdoRefused


def _norm_state(state: str | None) -> str:
    s = (state or "").strip().lower().replace("-", "").replace("_", "").replace(" ", "")
    return {
        "preop": "preop",
        "preoperational": "preop",
        "operational": "operational",
        "op": "operational",
        "started": "operational",
        "start": "operational",
        "stopped": "stopped",
        "stop": "stopped",
    }.get(s, s or "unknown")


def _write(
    profile: DeviceProfile, index: int, sub: int, value: int, why: str, fallback: DataType
) -> PdoStep:
    addr = ObjectAddress(index, sub)
    spec = profile.spec(addr)
    return PdoStep("write", addr, value, spec.data_type if spec else fallback, None, why)


def _nmt(command: str, why: str) -> PdoStep:
    return PdoStep("nmt", None, 0, None, command, why)


def _mapping_steps(profile: DeviceProfile, pdo: Pdo, cite: str) -> list[PdoStep]:
    mi = pdo.mapping_index
    name = pdo.name
    steps = [
        _write(profile, mi, 0, 0, f"clear the mapping of {name} (sub 0 = 0) - {cite}", _U8),
    ]
    for k, e in enumerate(pdo.entries, start=1):
        steps.append(
            _write(
                profile, mi, k, e.raw, f"{name} entry {k}: {_spec_name(profile, e)} - {cite}", _U32
            )
        )
    steps.append(
        _write(
            profile,
            mi,
            0,
            len(pdo.entries),
            f"{name} maps {len(pdo.entries)} objects ({pdo.bits} bits) - {cite}",
            _U8,
        )
    )
    return steps


_U8, _U16, _U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32


def _canopen_steps(
    profile: DeviceProfile, cur: Pdo | None, pdo: Pdo, section: str | None
) -> list[PdoStep]:
    assert pdo.comm is not None and pdo.comm_index is not None
    c, ci, name, d = pdo.comm, pdo.comm_index, pdo.name, pdo.direction
    cc = cur.comm if cur is not None else None
    map_changed = cur is None or cur.entries != pdo.entries
    comm_changed = cc is None or cc != c
    if not map_changed and not comm_changed:
        return []
    # The family's own section when it is not the standard itself (smartris 001 §2-8).
    fam = f"; {section}" if section and not section.startswith("CiA") else ""
    steps: list[PdoStep] = []
    written: int | None = None
    if cc is None or cc.enabled:
        # CiA 301 §7.5.2.35: the PDO is made invalid (bit 31) before its id, its
        # parameters or its mapping change; its old id stays until then.
        base = cc if cc is not None else c
        written = replace(base, enabled=False).cob_raw(d)
        steps.append(
            _write(
                profile,
                ci,
                1,
                written,
                f"disable {name} (COB-ID bit 31 = 1) - {_CIA_COMM}{fam}",
                _U32,
            )
        )
    else:
        written = cc.cob_raw(d)
    if map_changed:
        steps.extend(_mapping_steps(profile, pdo, f"{_CIA_MAP}{fam}"))
    old = dict(_comm_fields(cc)) if cc is not None else {}
    fields = {2: "transmission type", 3: "inhibit time", 5: "event timer", 6: "SYNC start value"}
    changed = [
        (sub, v) for sub, v in _comm_fields(c) if _has(profile, ci, sub) and old.get(sub) != v
    ]
    # Timers going to 0 first, the type next, timers with a value last: a drive that takes
    # an event timer only with type 254/255 (smartris 001 §2-8) accepts every step.
    order = (
        [(s, v) for s, v in changed if s != 2 and v == 0]
        + [(s, v) for s, v in changed if s == 2]
        + [(s, v) for s, v in changed if s != 2 and v != 0]
    )
    for sub, v in order:
        steps.append(
            _write(
                profile,
                ci,
                sub,
                v,
                f"{name} {fields[sub]} = {v} (while the PDO is invalid) - {_CIA_COMM}{fam}",
                _U8 if sub in (2, 6) else _U16,
            )
        )
    final = c.cob_raw(d)
    if final != written:
        what = f"enable {name} on COB-ID 0x{c.cob_id:03X}" if c.enabled else f"{name} stays off"
        steps.append(
            _write(
                profile,
                ci,
                1,
                final,
                f"{what} (COB-ID bit 31 = {0 if c.enabled else 1}) - {_CIA_COMM}{fam}",
                _U32,
            )
        )
    return steps


def _body(
    profile: DeviceProfile, current: PdoConfig | None, desired: PdoConfig
) -> tuple[list[PdoStep], list[str]]:
    rules = rules_of(profile)
    kind = rules.kind
    section = rules.section
    steps: list[PdoStep] = []
    touched: list[str] = []

    def cur_of(p: Pdo) -> Pdo | None:
        if current is None:
            return None
        try:
            return current.pdo(p.direction, p.number)
        except NotFoundError:
            return None

    if kind == "canopen":
        for p in desired.pdos:
            s = _canopen_steps(profile, cur_of(p), p, section)
            if s:
                steps.extend(s)
                touched.append(p.name)
        return steps, touched
    if kind == "ethercat":
        for d in Direction:
            idx = _ASSIGN[d.value]
            want = (desired.assignment or {}).get(d, ())
            had = (current.assignment or {}).get(d, ()) if current is not None else None
            changed_maps = [
                p for p in desired.of(d) if (c := cur_of(p)) is None or c.entries != p.entries
            ]
            if not changed_maps and had == want:
                continue
            cite = section or "ETG.1000.6"
            steps.append(
                _write(
                    profile,
                    idx,
                    0,
                    0,
                    f"unassign the {d.value.upper()} PDOs (0x{idx:04X}:00 = 0) - {cite}",
                    _U8,
                )
            )
            for p in changed_maps:
                steps.extend(_mapping_steps(profile, p, cite))
                touched.append(p.name)
            for k, a in enumerate(want, start=1):
                steps.append(
                    _write(
                        profile, idx, k, a, f"assign 0x{a:04X} (0x{idx:04X}:{k:02X}) - {cite}", _U16
                    )
                )
            if want:
                steps.append(
                    _write(
                        profile,
                        idx,
                        0,
                        len(want),
                        f"{len(want)} {d.value.upper()} PDO assigned; the drive checks the "
                        f"mapping here - {cite}",
                        _U8,
                    )
                )
            names = {p.mapping_index: p.name for p in desired.of(d)}
            for a in sorted(set(want) ^ set(had or ())):
                if a in names and names[a] not in touched:
                    touched.append(names[a])
        return steps, touched
    if kind == "telegram":
        t = _telegram_address(profile)
        tg = rules.telegram(desired.telegram) if desired.telegram is not None else None
        if tg is None or t is None:
            return steps, touched
        cite = tg.section or section or ""
        telegram_changed = current is None or current.telegram != desired.telegram
        if telegram_changed:
            steps.append(
                _write(
                    profile,
                    t.index,
                    t.subindex,
                    tg.number,
                    f"select telegram {tg.number} (P{t.index}) - {cite}",
                    _U16,
                )
            )
        if tg.variable:
            for p in desired.pdos:
                c = cur_of(p)
                if c is None or c.entries != p.entries or telegram_changed:
                    steps.extend(_mapping_steps(profile, p, cite))
                    touched.append(p.name)
        elif telegram_changed:
            touched.extend(p.name for p in desired.pdos)
        return steps, touched
    return steps, touched


def _wrap_nmt(rules: PdoRules, nmt_state: str, body: list[PdoStep]) -> list[PdoStep]:
    state = _norm_state(nmt_state)
    need = _norm_state(rules.mapping_state)
    if need != "preop" or state == "preop":
        return body
    cite = rules.section or "CiA 301 §7.3.2"
    if rules.kind == "ethercat":
        why = (
            f"ESM PreOp (the twin: NMT pre-operational): mapping and assignment only there - {cite}"
        )
    elif rules.kind == "telegram":
        why = (
            "NMT pre-operational: the telegram and its mapping are set only while no process "
            f"data is exchanged - {cite}"
        )
    else:
        why = f"NMT pre-operational: PDOs are remapped only there - CiA 301 §7.3.2; {cite}"
        if cite.startswith("CiA"):
            why = "NMT pre-operational: PDOs are remapped only there - CiA 301 §7.3.2"
    out = [_nmt("preop", why)]
    out.extend(body)
    if state == "operational":
        out.append(_nmt("start", "NMT operational again, as before the change - CiA 301 §7.3.2"))
    elif state == "stopped":
        out.append(_nmt("stop", "NMT stopped again, as before the change - CiA 301 §7.3.2"))
    return out


def _refuse(problems: list[PdoProblem]) -> PdoRefused:
    more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
    first = problems[0]
    where = f"{first.pdo}: " if first.pdo and not first.message.startswith(first.pdo) else ""
    return PdoRefused(
        f"PDO configuration refused: {where}{first.message}{more}",
        problems=list(problems),
        field=first.field,
        hint="correct the fields the problems name; nothing was written",
    )


def _same(profile: DeviceProfile, a: PdoConfig, b: PdoConfig) -> bool:
    return a == b


def plan(profile: DeviceProfile, current: PdoConfig, desired: PdoConfig, *, nmt_state: str) -> Plan:
    """The ordered writes that turn ``current`` into ``desired``; only changed PDOs are
    touched. Raises :class:`PdoRefused` when ``desired`` breaks the family's rules."""
    rules = rules_of(profile)
    if rules.kind == "fixed" or rules.mapping_state == "fixed":
        if not _same(profile, current, desired):
            changed: list[str | None] = [p.name for p in desired.pdos if p not in current.pdos]
            raise _refuse([_fixed_problem(profile, n) for n in changed or [None]])
        return Plan((), ())
    problems = validate(profile, desired)
    if problems:
        raise _refuse(problems)
    body, touched = _body(profile, current, desired)
    if not body:
        return Plan((), ())
    return Plan(tuple(_wrap_nmt(rules, nmt_state, body)), tuple(touched))


def full_plan(profile: DeviceProfile, desired: PdoConfig, *, nmt_state: str) -> Plan:
    """Rewrite every PDO to ``desired`` whatever the drive holds (used for rollback).

    Not validated: it puts back a configuration the drive had before."""
    rules = rules_of(profile)
    if rules.kind == "fixed" or rules.mapping_state == "fixed":
        return Plan((), ())
    body, touched = _body(profile, None, desired)
    return Plan(tuple(_wrap_nmt(rules, nmt_state, body)), tuple(touched))
