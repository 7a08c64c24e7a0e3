"""PDO configuration of a session: read, validate, plan, apply with rollback, and cyclic data.

The planning is pure (``domain/pdo.py``); this module runs it against a drive. An apply reads
the present configuration, refuses an invalid one before anything is written, runs the plan's
steps in order with progress, reads everything back, and when a step fails puts the previous
configuration back (a full rewrite, since the failure may have left any part half done) and
says in the report what happened. Cyclic data is stopped while the mapping changes and
restarted on the new one.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
import weakref
from typing import TYPE_CHECKING, Any

from servodesk.domain import pdo as pdomod
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import Value, codec, coerce_int
from servodesk.domain.profile_pdo import PdoTelegram
from servodesk.errors import (
    ConflictError,
    LinkError,
    ObjectAccessError,
    PdoRefused,
    ServodeskError,
    ValidationError,
)
from servodesk.links.cyclic import no_cyclic_reason, padded_length, transport_for
from servodesk.services.cyclic import MAX_PERIOD, MIN_PERIOD, CyclicExchange, bus_cob_id

if TYPE_CHECKING:
    from servodesk.services.session import Session

#: CiA 301 gives no time for an NMT command to take effect (it is not confirmed); real
#: drives need a few milliseconds before the next SDO is served in the new state.
NMT_SETTLE_S = 0.02

_TRANSMISSION = {
    0: "synchronous, acyclic",
    252: "RTR only, synchronous",
    253: "RTR only, event-driven",
    254: "event-driven (manufacturer)",
    255: "event-driven (profile)",
}

_busy: weakref.WeakKeyDictionary[Any, asyncio.Lock] = weakref.WeakKeyDictionary()


def _lock(session: Session) -> asyncio.Lock:
    lock = _busy.get(session)
    if lock is None:
        lock = _busy[session] = asyncio.Lock()
    return lock


def transmission_text(t: int | None) -> str | None:
    if t is None:
        return None
    if 1 <= t <= 240:
        return "synchronous, every SYNC" if t == 1 else f"synchronous, every {t}th SYNC"
    return _TRANSMISSION.get(t, "reserved")


# Reading -------------------------------------------------------------------------------------


async def read_config(session: Session, telegram: int | None = None) -> pdomod.PdoConfig:
    """The drive's PDO configuration, read object by object; with ``telegram``, the drive's
    mapping under that telegram (the one servodesk's IO AR is about to set up: the IO
    controller's configuration chooses it, 004 §20.1.1, and the drive's P922 follows)."""
    profile = session.profile
    values: dict[ObjectAddress, int] = {}
    for address in pdomod.config_addresses(profile):
        try:
            raw = await session.link.read(address)
        except ObjectAccessError:
            continue  # An entry the drive does not have (e.g. sub 6 of an older firmware).
        spec = profile.spec(address)
        if spec is None:
            continue
        v = codec(spec.data_type).decode(raw)
        if isinstance(v, bool | int):
            values[address] = int(v)
    t = profile.pdo.telegram_object
    if telegram is not None and t:
        values[ObjectAddress.parse(t)] = telegram
    return pdomod.parse_config(profile, values)


def _pdo_out(session: Session, config: pdomod.PdoConfig, p: pdomod.Pdo) -> dict[str, Any]:
    profile = session.profile
    rules = profile.pdo
    active = p in config.active(p.direction)
    entries = []
    for s in pdomod.layout(profile, p):
        entries.append(
            {
                "index": s.entry.index,
                "subindex": s.entry.subindex,
                "bits": s.bits,
                "raw_hex": f"0x{s.entry.raw:08X}",
                "address": str(s.address) if s.address is not None else None,
                "name": s.name,
                "data_type": s.data_type.name if s.data_type is not None else None,
                "unit": s.unit,
                "offset_bits": s.offset_bits,
                "offset_byte": s.offset_bits // 8,
                "padding": s.entry.is_padding,
            }
        )
    c = p.comm
    max_bits = rules.max_bits
    if rules.kind == "telegram" and config.telegram is not None:
        tg = _telegram_rules(session, config.telegram)
        if tg is not None:
            max_bits = int(tg.get("bytes", max_bits // 8)) * 8
    nbytes = (p.bits + 7) // 8
    return {
        "direction": p.direction.value,
        "number": p.number,
        "name": p.name,
        "mapping_index": p.mapping_index,
        "comm_index": p.comm_index,
        "cob_id": bus_cob_id(profile, p, session.link.params.node_id),
        "cob_id_hex": f"0x{bus_cob_id(profile, p, session.link.params.node_id):03X}",
        "enabled": c.enabled if c is not None else active,
        "rtr_allowed": c.rtr_allowed if c is not None else None,
        "transmission_type": c.transmission_type if c is not None else None,
        "transmission_text": transmission_text(c.transmission_type) if c is not None else None,
        "inhibit_time": c.inhibit_time if c is not None else None,
        "inhibit_time_ms": c.inhibit_time / 10 if c is not None else None,
        "event_timer": c.event_timer if c is not None else None,
        "sync_start": c.sync_start if c is not None else None,
        "active": active,
        "bits": p.bits,
        "max_bits": max_bits,
        "bytes": nbytes,
        "frame_length": padded_length(nbytes) if nbytes <= 64 else nbytes,
        "entries": entries,
    }


def _telegram_rules(session: Session, telegram: int) -> dict[str, Any] | None:
    tgs = getattr(session.profile.pdo, "telegrams", None)
    if not tgs:
        return None
    if isinstance(tgs, dict):
        t = tgs.get(telegram) or tgs.get(str(telegram))
        return t if isinstance(t, dict) else None
    for t in tgs:
        number = t.get("number") if isinstance(t, dict) else getattr(t, "number", None)
        if number == telegram:
            return t if isinstance(t, dict) else t.model_dump()
    return None


def problem_dict(p: pdomod.PdoProblem) -> dict[str, Any]:
    return {
        "message": p.message,
        "pdo": p.pdo,
        "entry": p.entry,
        "field": p.field,
        "section": p.section,
    }


async def view(
    session: Session,
    config: pdomod.PdoConfig | None = None,
    problems: list[pdomod.PdoProblem] | None = None,
) -> dict[str, Any]:
    """The ``PdoView`` of docs/pdo.md (reads the drive when ``config`` is None)."""
    if config is None:
        config = await read_config(session)
    rules = session.profile.pdo
    try:
        nmt = await session.link.network_state()
    except ServodeskError:
        nmt = "unknown"
    return {
        "kind": rules.kind,
        "byte_order": rules.byte_order,
        "rules": {
            "max_entries": rules.max_entries,
            "max_bits": rules.max_bits,
            "max_bytes": rules.max_bytes,
            "mapping_state": rules.mapping_state,
            "section": rules.section,
            "rpdo_count": rules.rpdo_count,
            "tpdo_count": rules.tpdo_count,
            # The family's telegrams (PROFIdrive, 004 §20.3): the page labels its telegram
            # choice from them and keeps a fixed telegram's entries as they are.
            "telegrams": [
                _telegram_out(t) for t in (rules.telegrams if rules.kind == "telegram" else ())
            ],
        },
        "pdos": [_pdo_out(session, config, p) for p in config.pdos],
        "assignment": (
            {d.value: list(v) for d, v in config.assignment.items()}
            if config.assignment is not None
            else None
        ),
        "telegram": config.telegram,
        "nmt_state": nmt,
        "apply_unavailable": getattr(session.link, "mapping_owner", None),
        "problems": [problem_dict(p) for p in (problems or [])],
    }


def mappable(session: Session) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {}
    for d in pdomod.Direction:
        items = []
        for spec in pdomod.mappable(session.profile, d):
            items.append(
                {
                    "address": str(spec.address),
                    "index": spec.index,
                    "subindex": spec.subindex,
                    "name": spec.name,
                    "data_type": spec.data_type.name,
                    "bits": spec.bits,
                    "unit": spec.unit,
                    "direction": spec.pdo_mapping.value,
                }
            )
        out[d.value] = items
    return out


def templates(session: Session) -> list[dict[str, Any]]:
    return [
        {"id": t.id, "name": t.name, "description": t.description, "section": t.section}
        for t in pdomod.templates(session.profile)
    ]


async def from_template(session: Session, template_id: str) -> dict[str, Any]:
    current = await read_config(session)
    desired = pdomod.apply_template(session.profile, current, template_id)
    return await view(session, desired, pdomod.validate(session.profile, desired))


async def desired_from(
    session: Session, body: dict[str, Any], current: pdomod.PdoConfig | None = None
) -> pdomod.PdoConfig:
    """The present configuration with the PDOs of a ``PdoLayout`` body replaced."""
    if current is None:
        current = await read_config(session)
    return pdomod.config_from_json(session.profile, body, current=current)


async def check(session: Session, body: dict[str, Any]) -> dict[str, Any]:
    desired = await desired_from(session, body)
    problems = pdomod.validate(session.profile, desired)
    return {
        "ok": not problems,
        "problems": [problem_dict(p) for p in problems],
        "view": await view(session, desired, problems),
    }


def step_dict(s: pdomod.PdoStep) -> dict[str, Any]:
    return {
        "kind": s.kind,
        "address": str(s.address) if s.address is not None else None,
        "value": s.value,
        "value_hex": f"0x{s.value:X}" if s.kind == "write" else None,
        "command": s.command,
        "why": s.why,
    }


async def _nmt_state(session: Session) -> str:
    try:
        return await session.link.network_state()
    except ServodeskError:
        return "unknown"


async def make_plan(session: Session, body: dict[str, Any]) -> pdomod.Plan:
    current = await read_config(session)
    desired = await desired_from(session, body, current)
    return pdomod.plan(session.profile, current, desired, nmt_state=await _nmt_state(session))


# Applying ------------------------------------------------------------------------------------


async def _run_step(session: Session, step: pdomod.PdoStep, client: str | None) -> None:
    if step.kind == "nmt":
        assert step.command is not None
        await session.link.nmt(step.command)
        await asyncio.sleep(NMT_SETTLE_S)
        return
    assert step.address is not None and step.data_type is not None
    data = codec(step.data_type).encode(coerce_int(step.value, step.data_type))
    await session.link.write(step.address, data)
    spec = session.profile.spec(step.address)
    if spec is None or spec.persist:
        session.dirty.add(step.address)
    audit = session.hub.audit
    if audit is not None:
        audit(session, step.address, None, data, client or "unknown")


async def _run(
    session: Session, steps: tuple[pdomod.PdoStep, ...], label: str, client: str | None
) -> tuple[int, pdomod.PdoStep | None, ServodeskError | None]:
    n = len(steps)
    for i, step in enumerate(steps):
        try:
            await _run_step(session, step, client)
        except ServodeskError as exc:
            return i, step, exc
        if i % 4 == 0 or i == n - 1:
            session._progress("pdo", (i + 1) / max(1, n) * 0.9, f"{label}: {step.why}")
    return n, None, None


def _same(a: pdomod.PdoConfig, b: pdomod.PdoConfig, names: tuple[str, ...] | None) -> bool:
    for p in b.pdos:
        if names is not None and p.name not in names:
            continue
        q = a.pdo(p.direction, p.number)
        if q.entries != p.entries or (p.comm is not None and q.comm != p.comm):
            return False
    return a.assignment == b.assignment and a.telegram == b.telegram


async def apply(
    session: Session, body: dict[str, Any], *, dry_run: bool, client: str | None = None
) -> dict[str, Any]:
    """Apply a ``PdoLayout``: the ``ApplyReport`` of docs/pdo.md."""
    owner: str | None = getattr(session.link, "mapping_owner", None)
    if owner is not None and not dry_run:
        # PROFINET: the IO controller sets the telegram up from the GSD file; refused before
        # anything is read or written.
        raise ConflictError(
            f"servodesk does not write the process data mapping of {session.id} over "
            f"{session.link.fieldbus}",
            hint=owner,
        )
    lock = _lock(session)
    if lock.locked():
        raise ConflictError(
            f"a PDO apply on {session.id} is already running",
            hint="wait for its report (progress on the WebSocket)",
        )
    async with lock:
        profile = session.profile
        current = await read_config(session)
        desired = await desired_from(session, body, current)
        nmt = await _nmt_state(session)
        plan = pdomod.plan(profile, current, desired, nmt_state=nmt)  # PdoRefused if invalid
        report: dict[str, Any] = {
            "ok": True,
            "dry_run": dry_run,
            "steps": [step_dict(s) for s in plan.steps],
            "touched": list(plan.touched),
            "done": 0,
            "duration_s": 0.0,
            "verified": False,
            "rolled_back": False,
            "error": None,
            "failed_step": None,
        }
        if dry_run:
            report["view"] = await view(session, desired)
            return report
        t0 = time.monotonic()
        restart = stop_cyclic_now(session)
        session._progress("pdo", 0.0, f"applying {len(plan.steps)} steps")
        done, failed, exc = await _run(session, plan.steps, "apply", client)
        report["done"] = done
        final = desired
        if exc is None:
            after = await read_config(session)
            report["verified"] = _same(after, desired, plan.touched)
            if not report["verified"]:
                report["ok"] = False
                report["error"] = "read back differs from what was written"
            final = after
        else:
            report["ok"] = False
            report["error"] = exc.message
            report["failed_step"] = step_dict(failed) if failed else None
            report.update(await _roll_back(session, current, client))
            final = current
        report["duration_s"] = round(time.monotonic() - t0, 3)
        if restart is not None:
            with contextlib.suppress(ServodeskError):
                await start_cyclic(session, restart[0] * 1000, restart[1], restart[2])
        session._progress(
            "pdo",
            1.0,
            "applied and verified"
            if report["ok"]
            else f"failed: {report['error']}; "
            + ("previous mapping restored" if report["rolled_back"] else "see the report"),
        )
        report["view"] = await _view_or_none(session, final)
        return report


async def _view_or_none(session: Session, config: pdomod.PdoConfig) -> dict[str, Any] | None:
    try:
        return await view(session)
    except LinkError:
        return None


async def _roll_back(
    session: Session, previous: pdomod.PdoConfig, client: str | None
) -> dict[str, Any]:
    """Put ``previous`` back, everything rewritten; report whether it is back."""
    out: dict[str, Any] = {"rolled_back": False, "rollback_error": None}
    try:
        nmt = await _nmt_state(session)
        plan = pdomod.full_plan(session.profile, previous, nmt_state=nmt)
    except ServodeskError as exc:
        out["rollback_error"] = exc.message
        return out
    _, _, failure = await _run(session, plan.steps, "rollback", client)
    if failure is not None:
        out["rollback_error"] = failure.message
        return out
    try:
        out["rolled_back"] = _same(await read_config(session), previous, None)
    except ServodeskError as e:
        out["rollback_error"] = e.message
    return out


# Cyclic data ---------------------------------------------------------------------------------


def cyclic_of(session: Session) -> CyclicExchange | None:
    ex: CyclicExchange | None = getattr(session, "cyclic", None)
    return ex


def stop_cyclic_now(session: Session) -> tuple[float, bool, str] | None:
    """Stop the exchange; returns (period, outputs, sync) when it ran, to restart it later."""
    ex = cyclic_of(session)
    if ex is None:
        return None
    ex.stop()
    session.cyclic = None
    return ex.period, ex.outputs, ex.sync


def sync_modes(session: Session) -> list[str]:
    """How the session's cyclic data may be synchronised: "freerun" always; "dc" where the
    link has distributed clocks (EtherCAT) and the profile says which SYNC0 cycles the drive
    takes (quirk ``dc_cycle_time_ns``)."""
    modes = list(session.link.sync_modes)
    if "dc" in modes and session.profile.dc_cycles_ns() is None:
        modes.remove("dc")
    return modes


def _check_sync(session: Session, sync: str, period: float) -> None:
    """Refuse a synchronisation the link or the drive does not offer, and a DC cycle the
    profile says the drive does not take, before anything is sent."""
    if sync == "freerun":
        return
    if sync != "dc":
        raise ValidationError(
            f"sync {sync!r} is not a synchronisation", field="sync", hint="use freerun or dc"
        )
    if "dc" not in session.link.sync_modes:
        raise ValidationError(
            f"DC synchronisation is EtherCAT's; this session's link is "
            f"{session.link.params.interface}",
            field="sync",
            hint="use freerun",
        )
    cycles = session.profile.dc_cycles_ns()
    if cycles is None:
        raise ConflictError(
            f"the {session.profile.name} profile names no SYNC0 cycle the drive takes",
            hint="use freerun",
        )
    low, high, step = cycles
    ns = round(period * 1e9)
    if not low <= ns <= high or ns % step:
        raise ValidationError(
            f"sync_period_ms {period * 1000:g} is not a SYNC0 cycle the drive takes: "
            f"{step / 1e6:g} ms steps from {low / 1e6:g} to {high / 1e6:g} ms",
            field="sync_period_ms",
            hint="choose a multiple of the step within the range (the profile's dc_cycle_time_ns)",
        )


def _check_telegram(session: Session, telegram: int | None) -> None:
    """Refuse a telegram where servodesk does not set one up (every link but PROFINET's IO
    AR) and one the drive does not have, before anything is sent."""
    if telegram is None:
        return
    rules = session.profile.pdo
    if not session.link.sets_up_telegram or rules.kind != "telegram":
        raise ValidationError(
            f"{session.id} is on {session.link.fieldbus}: a telegram is chosen for a PROFINET "
            "IO AR only",
            field="telegram",
            hint="leave telegram out; the PDO mapping says what is exchanged",
        )
    if rules.telegram(telegram) is None:
        raise ValidationError(
            f"telegram {telegram} is not one of the {session.profile.name}'s telegrams",
            field="telegram",
            hint="known: " + ", ".join(str(t.number) for t in rules.telegrams),
        )


def telegram_offer(session: Session) -> list[dict[str, Any]] | None:
    """The telegrams servodesk's IO AR may be set up with (PROFINET: the expected
    submodule of the connect, as an IO controller's configuration tool chooses it, 004
    §20.1.1); None where cyclic data has no telegram to choose."""
    rules = session.profile.pdo
    if not session.link.sets_up_telegram or rules.kind != "telegram":
        return None
    return [_telegram_out(t) for t in rules.telegrams]


def _telegram_out(t: PdoTelegram) -> dict[str, Any]:
    """A telegram as the API gives it (``PdoTelegramOut``)."""
    return {
        "number": t.number,
        "name": t.name,
        "bytes": t.bytes,
        "max_entries": t.max_entries,
        "variable": t.variable,
        # The CiA 402 state machine over the telegram: servo on, jog and moves from the
        # Operation page need the controlword in the setpoint telegram (telegram 1 carries
        # PROFIdrive's STW1 instead, 004 §20.5.1).
        "controlword": any(
            w.address is not None
            and not w.address.startswith("reserved")
            and ObjectAddress.parse(w.address).index == 0x6040
            for w in t.rx
        ),
    }


async def start_cyclic(
    session: Session,
    sync_period_ms: float,
    outputs: bool,
    sync: str = "freerun",
    telegram: int | None = None,
) -> dict[str, Any]:
    period = sync_period_ms / 1000.0
    if not MIN_PERIOD <= period <= MAX_PERIOD:
        raise ValidationError(
            f"sync_period_ms {sync_period_ms} is outside "
            f"{MIN_PERIOD * 1000:g}..{MAX_PERIOD * 1000:g}",
            field="sync_period_ms",
        )
    _check_sync(session, sync, period)
    _check_telegram(session, telegram)
    transport = transport_for(session.link)
    config = await read_config(session, telegram)
    if not config.active(pdomod.Direction.TX) and not config.active(pdomod.Direction.RX):
        raise ValidationError(
            "no PDO is enabled and mapped: nothing to exchange",
            hint="map objects into a PDO and apply first",
        )
    if session.link.cyclic_outputs_always:
        # An IO controller sends the setpoint telegram every cycle (PROFINET): "inputs only"
        # is the present values sent back, which the image below is (the PDO page's Start
        # asks for inputs only; refused, it could not start cyclic data over PROFINET).
        outputs = True
    image: dict[ObjectAddress, Value] = {}
    if outputs:
        # Start the output image from the drive's present values: turning outputs on
        # must not change anything on the axis.
        for p in config.active(pdomod.Direction.RX):
            for s in pdomod.layout(session.profile, p):
                if s.address is not None and s.data_type is not None:
                    with contextlib.suppress(ObjectAccessError):
                        image[s.address] = codec(s.data_type).decode(
                            await session.link.read(s.address)
                        )
    if session.link.sets_up_telegram:
        # PROFINET: the IO AR is set up for the drive's telegram at this cycle (its lengths
        # from the telegram's layout), checked before anything changes; its first frames
        # carry the image from the drive's present values, not zeros (a controlword 0).
        first = b"".join(
            pdomod.pack(
                session.profile,
                p,
                {
                    s.address: image.get(s.address, 0)
                    for s in pdomod.layout(session.profile, p)
                    if s.address is not None
                },
            )
            for p in config.active(pdomod.Direction.RX)
        )
        # A telegram's frame is its fixed size (004 §20.1.2: 48 bytes for 102), the mapping
        # padded with Reserved entries.
        tel = session.profile.pdo.telegram(config.telegram) if config.telegram else None
        size = tel.bytes if tel is not None else 0
        rx = max(size, sum(p.bytes for p in config.active(pdomod.Direction.RX)))
        tx = max(size, sum(p.bytes for p in config.active(pdomod.Direction.TX)))
        session.link.prepare_io(config.telegram, rx, tx, period, outputs, first)
    previous = cyclic_of(session)
    stop_cyclic_now(session)
    # CiA 301 §7.3.2.2.1: PDOs are exchanged only in NMT OPERATIONAL. The node is put back
    # into the state it had when cyclic data is stopped (a restart keeps the first state).
    before = previous.nmt_before if previous is not None else await _nmt_state(session)
    # Sent even when the node is believed OPERATIONAL: NMT is unconfirmed and the belief can
    # be a heartbeat old, while "start" to an OPERATIONAL node changes nothing (CiA 301 §7.3.2.2.1).
    # With the outputs off, a link whose slaves take the outputs of every cycle in their
    # operational state (EtherCAT) goes to its inputs-only state instead (SAFE-OP).
    command = "start" if outputs else session.link.inputs_only_command
    configure = getattr(session.link, "configure_sync", None)
    if configure is not None:
        configure(sync, period)
    await session.link.nmt(command)
    await asyncio.sleep(NMT_SETTLE_S)
    ex = CyclicExchange(session, transport, config, period=period, outputs=outputs, image=image)
    ex.sync = sync
    ex.nmt_before = before
    ex.start()
    session.cyclic = ex
    return _with_offer(session, ex.status())


async def stop_cyclic(session: Session) -> dict[str, Any]:
    ex = cyclic_of(session)
    stop_cyclic_now(session)
    if ex is None:
        return _with_offer(session, idle_status())
    if ex.nmt_before in ("preop", "unknown", "bootup"):
        with contextlib.suppress(ServodeskError):
            await session.link.nmt("preop")
    status = ex.status()
    status["running"] = False
    return _with_offer(session, status)


def idle_status() -> dict[str, Any]:
    return {
        "running": False,
        "sync_period_ms": None,
        "sync": None,
        "outputs": False,
        "syncs": 0,
        "rx_pdos": [],
        "tx_pdos": [],
        "frames_per_s": 0.0,
        "decode_errors": 0,
        "values": {},
    }


def cyclic_status(session: Session) -> dict[str, Any]:
    """The exchange's status; ``unavailable`` says why the session's link has none (SLMP)."""
    ex = cyclic_of(session)
    out = ex.status() if ex is not None else idle_status()
    out["unavailable"] = no_cyclic_reason(session.link)
    return _with_offer(session, out)


def _with_offer(session: Session, status: dict[str, Any]) -> dict[str, Any]:
    """``status`` with what the session offers: its synchronisations and the drive's
    SYNC0 cycles (the PDO page shows the choice from any answer, start and stop too)."""
    status["sync_modes"] = sync_modes(session)
    cycles = session.profile.dc_cycles_ns() if "dc" in status["sync_modes"] else None
    status["dc_cycle_ns"] = list(cycles) if cycles is not None else None
    periods = session.link.cyclic_periods_ms
    status["periods_ms"] = list(periods) if periods is not None else None
    status["telegrams"] = telegram_offer(session)
    ex = cyclic_of(session)
    status["telegram"] = ex.config.telegram if ex is not None and status["running"] else None
    return status


def set_outputs(session: Session, values: dict[str, Any]) -> dict[str, Any]:
    ex = cyclic_of(session)
    if ex is None or not ex.outputs:
        raise ConflictError(
            "cyclic outputs are off", hint="start cyclic data with outputs: true first"
        )
    from servodesk.domain.values import check_value

    allowed = ex.rx_addresses()
    parsed: dict[ObjectAddress, Value] = {}
    for key, value in values.items():
        address = ObjectAddress.parse(key)
        if address not in allowed:
            raise ValidationError(
                f"{address} is not mapped into an active RX PDO",
                field=key,
                hint="map it first, or write it by SDO",
            )
        spec = session.profile.spec(address)
        if spec is None:
            raise ValidationError(f"{address} is not in the profile", field=key)
        parsed[address] = check_value(spec, value)
    ex.set_outputs(parsed)
    return ex.status()


__all__ = [
    "PdoRefused",
    "apply",
    "check",
    "cyclic_status",
    "from_template",
    "make_plan",
    "mappable",
    "read_config",
    "set_outputs",
    "start_cyclic",
    "stop_cyclic",
    "templates",
    "view",
]
