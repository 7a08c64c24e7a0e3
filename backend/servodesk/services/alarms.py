"""Alarms: the present fault with its meaning, the EMCY log, the error histories, reset, clear.

Everything family-specific is profile data:

- the present fault is 603Fh, and for families whose alarm numbers do not fit 603Fh the object
  named by the quirk ``current_alarm`` (LECSN-T 2A41h, table ``alarm``);
- the history is 1003h (CiA 301 §7.5.2.3) where the family has it, plus the objects of the
  quirk ``alarm_history`` (``{index, subindex_first, count, index_stride, time_subindex}``);
- the fault reset follows the quirks ``fault_reset`` / ``no_fault_reset_bit7`` /
  ``fault_reset_hold_ms``: a rising edge of controlword bit 7 (CiA 402-2 §6.2.1), and where bit
  7 is documented as unusable (smartris 001 §5-4) the documented alternative, an NMT reset of
  the node;
- clearing the history writes 1003h:00 <- 0 and the family's ``clear_alarm_history`` command.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

from servodesk.domain import cia402, diagnosis
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import CONTROLWORD, ERROR_CODE, STATUSWORD
from servodesk.domain.datatypes import coerce_int
from servodesk.domain.profile import DeviceProfile, ErrorEntry
from servodesk.errors import ServodeskError, ValidationError
from servodesk.services.session import Session, error_info

ERROR_HISTORY = 0x1003
_TABLES = ("error_code", "emcy", "alarm")


def _entry(
    profile: DeviceProfile, code: int, tables: tuple[str, ...] = _TABLES
) -> ErrorEntry | None:
    for t in tables:
        e = profile.error(t, code)
        if e is not None:
            return e
    return None


def _hex(code: int) -> str:
    return f"0x{code:04X}" if code <= 0xFFFF else f"0x{code:08X}"


def _described(
    profile: DeviceProfile, code: int, tables: tuple[str, ...] = _TABLES
) -> dict[str, Any]:
    e = _entry(profile, code, tables)
    return {
        "code": code,
        "code_hex": _hex(code),
        "name": e.name if e else ("No error" if code == 0 else "Unknown error code"),
        "cause": e.cause if e else None,
        "remedy": e.remedy if e else None,
    }


def _addr(value: Any) -> ObjectAddress | None:
    if not isinstance(value, dict) or "index" not in value:
        return None
    return ObjectAddress(coerce_int(value["index"]), coerce_int(value.get("subindex", 0)))


def reset_procedure(profile: DeviceProfile) -> str:
    """The family's fault-reset procedure in words (from its quirks)."""
    q = next((q for q in profile.quirks if q.id == "fault_reset"), None)
    if _bit7_resets(profile):
        hold = profile.quirk("fault_reset_hold_ms")
        text = "controlword bit 7 0 -> 1 (Fault -> Switch on disabled)"
        if hold:
            text += f", held {hold} ms"
        if q is not None and q.section:
            text += f" ({q.section})"
        return text
    if q is not None:
        return f"{q.note or q.value} ({q.section})" if q.section else str(q.note or q.value)
    return "NMT reset node (controlword bit 7 does not reset faults)"


def _bit7_resets(profile: DeviceProfile) -> bool:
    return not profile.quirk("no_fault_reset_bit7", False) and profile.quirk(
        "fault_reset", "bit7_edge"
    ) in (None, "bit7_edge")


def _history_writable(profile: DeviceProfile) -> bool:
    spec = profile.spec(ObjectAddress(ERROR_HISTORY, 0))
    return spec is not None and spec.access.writable


def can_clear_history(profile: DeviceProfile) -> bool:
    return _history_writable(profile) or _addr(profile.quirk("clear_alarm_history")) is not None


async def _int(session: Session, address: ObjectAddress) -> int | None:
    if session.profile.spec(address) is None:
        return None
    try:
        value = (await session.read_object(address)).value
    except ServodeskError:
        # CiA 301: an empty 1003h entry may be answered with an abort (smartris 08000024h).
        return None
    return value if isinstance(value, int) else None


async def _history(session: Session) -> list[dict[str, Any]]:
    profile = session.profile
    out: list[dict[str, Any]] = []
    if profile.spec(ObjectAddress(ERROR_HISTORY, 0)) is not None:
        n = await _int(session, ObjectAddress(ERROR_HISTORY, 0)) or 0
        for sub in range(1, n + 1):
            raw = await _int(session, ObjectAddress(ERROR_HISTORY, sub))
            if not raw:
                continue
            # CiA 301 §7.5.2.3: bits 15-0 the error code, 31-16 manufacturer information.
            code = raw & 0xFFFF
            out.append({"source": "1003h", "index": sub, **_described(profile, code), "raw": raw})
    hist = profile.quirk("alarm_history")
    if isinstance(hist, dict) and hist.get("format") == "etg1020":
        out.extend(await _diagnosis_history(session, hist))
    elif isinstance(hist, dict) and coerce_int(hist.get("index", 0)) != ERROR_HISTORY:
        index = coerce_int(hist["index"])
        first = coerce_int(hist.get("subindex_first", 1))
        stride = coerce_int(hist.get("index_stride", 0))
        tsub = hist.get("time_subindex")
        for i in range(coerce_int(hist.get("count", 1))):
            idx, sub = (index + i * stride, first) if stride else (index, first + i)
            number = await _int(session, ObjectAddress(idx, sub))
            if not number:
                continue
            item: dict[str, Any] = {
                "source": f"0x{idx:04X}:{sub:02X}",
                "index": i + 1,
                **_described(profile, number, ("alarm", "error_code", "emcy")),
            }
            if tsub is not None:
                item["time_h"] = await _int(session, ObjectAddress(idx, coerce_int(tsub)))
            out.append(item)
    return out


async def _diagnosis_history(session: Session, hist: dict[str, Any]) -> list[dict[str, Any]]:
    """An EtherCAT drive's diagnosis history (ETG.1020 10F3h; HIWIN 000 §2.7: its faults are
    emergency messages): the messages of the ring, newest first (sub 02h names the newest).
    Messages that are no emergency error code are left out; an empty one answers an abort."""
    profile = session.profile
    index = coerce_int(hist["index"])
    first = coerce_int(hist.get("subindex_first", 6))
    count = coerce_int(hist.get("count", 1))
    newest = await _int(session, ObjectAddress(index, 2)) or 0
    if not first <= newest < first + count:
        return []
    out: list[dict[str, Any]] = []
    for i in range(count):
        sub = first + (newest - first - i) % count
        try:
            raw = bytes.fromhex((await session.read_object(ObjectAddress(index, sub))).raw_hex)
        except ServodeskError:
            continue  # Not written yet: no data.
        msg = diagnosis.parse(raw)
        code = msg.emergency_code if msg is not None else None
        if msg is None or code is None:
            continue
        out.append(
            {
                "source": f"0x{index:04X}:{sub:02X}",
                "index": len(out) + 1,
                **_described(profile, code),
                "raw": msg.diag_code,
            }
        )
    return out


async def alarms(session: Session) -> dict[str, Any]:
    """``Alarms``: present fault, EMCY log, history, reset procedure."""
    profile = session.profile
    sw = await _int(session, STATUSWORD)
    state = cia402.decode_state(sw).value if sw is not None else "unknown"
    current: dict[str, Any] | None = None
    cur_addr = _addr(profile.quirk("current_alarm"))
    if cur_addr is not None:
        code = await _int(session, cur_addr)
        if code:
            e = _entry(profile, code, ("alarm",))
            current = error_info(e) if e else {**_described(profile, code), "table": "alarm"}
    if current is None:
        code = await _int(session, ERROR_CODE)
        if code:
            e = _entry(profile, code)
            current = error_info(e) if e else {**_described(profile, code), "table": "error_code"}
    if current is not None:
        current.setdefault("display", None)
        current.setdefault("kind", "fault")
        current.setdefault("section", None)
    log = [
        {
            "time": m.get("time"),
            "code": m["code"],
            "code_hex": m["code_hex"],
            "name": m.get("name"),
            "cause": m.get("cause"),
            "remedy": m.get("remedy"),
            "register": m.get("register", 0),
        }
        for m in session.emcy_log
    ]
    return {
        "session": session.id,
        "current": current,
        "state": state,
        "emcy_log": log,
        "history": await _history(session),
        "reset_procedure": reset_procedure(profile),
        "can_clear_history": can_clear_history(profile),
    }


async def _in_fault(session: Session) -> bool:
    sw = await _int(session, STATUSWORD)
    return sw is not None and bool(sw & 0x08)


async def reset(session: Session, client: str | None = None) -> dict[str, Any]:
    """Run the family's fault-reset procedure when the drive is in Fault, then answer the
    alarms; ``message`` says what was done.

    CiA 402-2 §6.2.1 (IEC 61800-7-201): the fault reset (controlword bit 7, rising edge) is
    transition 15, Fault -> Switch on disabled; in any other state it has no meaning. The
    procedure writes the controlword (bit 7 low, high, low): 0000h is "disable voltage", so on
    an enabled drive it would switch the power stage off. Outside Fault nothing is sent.
    """
    profile = session.profile
    sw = await _int(session, STATUSWORD)
    state = cia402.decode_state(sw) if sw is not None else cia402.State.UNKNOWN
    if state is not cia402.State.FAULT:
        out = await alarms(session)
        seen = "its statusword (6041h) is not readable" if sw is None else f"it is in {state.value}"
        out["message"] = (
            f"No fault reset sent: {seen}, not in Fault; a fault reset acts only in Fault "
            "(CiA 402-2 §6.2.1) and the drive's state is unchanged."
        )
        return out
    # Bit 7 low, then high (the rising edge resets), then low again so the next command is
    # taken (003 §4-4-2: "return bit 7 to 0 before the next command"). The session keeps the
    # family's minimum controlword interval (smartris 40 ms).
    await session.write_object(CONTROLWORD, 0x0000, client=client)
    await session.write_object(CONTROLWORD, 0x0080, client=client)
    hold = profile.quirk("fault_reset_hold_ms")
    if hold:
        await asyncio.sleep(float(hold) / 1000.0)
    await session.write_object(CONTROLWORD, 0x0000, client=client)
    if not _bit7_resets(profile) and await _in_fault(session):
        # smartris 001 §5-4: bit 7 is not usable; NMT reset application clears the fault
        # (the drive boots and sends EMCY 0000h).
        await session.link.nmt("reset")
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            await asyncio.sleep(0.05)
            try:
                if not await _in_fault(session):
                    break
            except ServodeskError:
                continue  # Still booting.
    out = await alarms(session)
    out["message"] = (
        "Fault reset sent; the fault is still there: remove its cause first."
        if out["current"] is not None and out["state"] == cia402.State.FAULT.value
        else f"Fault reset done: the drive is in {out['state']}."
    )
    return out


async def clear_history(
    session: Session, confirm: bool, client: str | None = None
) -> dict[str, Any]:
    """1003h:00 <- 0 and the family's clear command (e.g. LECSN-T 2A40h <- 1EA5h)."""
    if not confirm:
        raise ValidationError(
            "clearing the alarm history needs confirmation",
            field="confirm",
            hint='send {"confirm": true}; the history cannot be restored afterwards',
        )
    profile = session.profile
    if not can_clear_history(profile):
        raise ValidationError(
            f"{profile.name} documents no way to clear its alarm history",
            hint="the history stays in the drive",
        )
    if _history_writable(profile):
        await session.write_object(ObjectAddress(ERROR_HISTORY, 0), 0, client=client)
    clear = profile.quirk("clear_alarm_history")
    addr = _addr(clear)
    if addr is not None and isinstance(clear, dict):
        await session.write_object(addr, coerce_int(clear.get("value", 0)), client=client)
    return await alarms(session)
