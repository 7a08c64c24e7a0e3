"""Family fault data for the simulated drive: which code each condition raises, alarm objects.

Read from the profile's quirks, never from vendor names:

- ``sim_fault_codes``: ``{following_error: 0x8611, limit_switch: ..., overload: ...}`` maps the
  conditions the simulation detects to the family's own code (its 603Fh / EMCY table, or its
  ``alarm`` table for drives whose alarm numbers do not fit 603Fh). A condition mapped to null,
  or missing, raises no fault (the drive only reports it in its status bits). Profiles without
  the quirk get the CiA 402-2 annex A code for a following error (8611h) and nothing else.
- ``alarm_history``: ``{index, subindex_first, count, index_stride, time_subindex}`` where the
  family keeps its own alarm history besides 1003h (e.g. LECSN-T 2A00h-2A0Fh: one object per
  entry, ``index_stride: 1``; sub 1 the alarm number, sub 2 the time in hours). 1003h itself is
  handled by the engine (CiA 301 §7.5.2.3).
  With ``format: etg1020`` (HIWIN 000 §2.7: faults are emergency messages, kept in the EtherCAT
  diagnosis history 10F3h) the entries are ETG.1020 diagnosis messages in a ring at
  ``subindex_first`` .. ``+count-1``; sub 02h names the newest, sub 04h says new ones arrived.
- ``current_alarm``: ``{index, subindex}`` of the object that shows the active alarm (LECSN-T
  2A41h), cleared by the fault reset.
- ``clear_alarm_history``: ``{index, subindex, value}``: writing ``value`` there clears the
  family history (LECSN-T 2A40h <- 1EA5h); another value is refused (abort 0609 0030h).
"""

from __future__ import annotations

from typing import Any

from servodesk.domain import diagnosis
from servodesk.domain.datatypes import Value, coerce_int
from servodesk.domain.profile import DeviceProfile

#: CiA 402-2 annex A, used when a profile has no ``sim_fault_codes`` quirk.
_STANDARD = {"following_error": 0x8611}


def _key(index: int, subindex: int) -> int:
    return index << 8 | subindex


def _addr(value: Any, default_sub: int = 0) -> tuple[int, int] | None:
    if not isinstance(value, dict) or "index" not in value:
        return None
    return coerce_int(value["index"]), coerce_int(value.get("subindex", default_sub))


class FaultModel:
    """The profile's fault codes and alarm objects, applied to the drive's object store."""

    def __init__(self, profile: DeviceProfile) -> None:
        q = profile.quirk("sim_fault_codes")
        if isinstance(q, dict):
            self.codes: dict[str, int | None] = {
                str(k): (coerce_int(v) if v is not None else None) for k, v in q.items()
            }
        else:
            self.codes = dict(_STANDARD)
        hist = profile.quirk("alarm_history")
        self._hist: list[tuple[int, int | None]] = []  # (number key, time key) newest first
        #: ETG.1020 diagnosis history: (index, first message sub, count).
        self._diag: tuple[int, int, int] | None = None
        if isinstance(hist, dict) and hist.get("format") == "etg1020":
            self._diag = (
                coerce_int(hist["index"]),
                coerce_int(hist.get("subindex_first", 6)),
                coerce_int(hist.get("count", 1)),
            )
        elif isinstance(hist, dict) and coerce_int(hist.get("index", 0)) != 0x1003:
            index = coerce_int(hist["index"])
            first = coerce_int(hist.get("subindex_first", 1))
            count = coerce_int(hist.get("count", 1))
            stride = coerce_int(hist.get("index_stride", 0))
            tsub = hist.get("time_subindex")
            for i in range(count):
                if stride:
                    idx, sub = index + i * stride, first
                else:
                    idx, sub = index, first + i
                tkey = _key(idx, coerce_int(tsub)) if tsub is not None else None
                self._hist.append((_key(idx, sub), tkey))
        cur = _addr(profile.quirk("current_alarm"))
        self._current = _key(*cur) if cur else None
        clear = profile.quirk("clear_alarm_history")
        ca = _addr(clear)
        self._clear: tuple[int, int] | None = None
        if ca is not None and isinstance(clear, dict):
            self._clear = (_key(*ca), coerce_int(clear.get("value", 0)))

    def code(self, condition: str) -> int | None:
        """The family's code for ``following_error``, ``limit_switch``, ``overload``..."""
        return self.codes.get(condition)

    def on_fault(self, values: dict[int, Value | None], code: int, hours: int) -> None:
        """Record a fault in the family's current-alarm object and alarm history."""
        if self._current is not None and self._current in values:
            values[self._current] = code
        if self._diag is not None:
            self._record_diagnosis(values, code)
        hist = self._hist
        if not hist or hist[0][0] not in values:
            return
        for i in range(len(hist) - 1, 0, -1):
            values[hist[i][0]] = values.get(hist[i - 1][0])
            t_new, t_old = hist[i][1], hist[i - 1][1]
            if t_new is not None and t_old is not None:
                values[t_new] = values.get(t_old)
        values[hist[0][0]] = code
        if hist[0][1] is not None:
            values[hist[0][1]] = hours

    def _record_diagnosis(self, values: dict[int, Value | None], code: int) -> None:
        """ETG.1020 ring: the message after the newest (the first when none), overwriting
        the oldest once full; sub 02h names it, sub 04h says a new one is there."""
        assert self._diag is not None
        index, first, count = self._diag
        newest = values.get(_key(index, 2))
        n = newest if isinstance(newest, int) else 0
        sub = n + 1 if first <= n < first + count - 1 else first
        values[_key(index, sub)] = diagnosis.emergency_message(code)
        values[_key(index, 2)] = sub
        if _key(index, 4) in values:
            values[_key(index, 4)] = True

    def on_reset(self, values: dict[int, Value | None]) -> None:
        if self._current is not None and self._current in values:
            values[self._current] = 0

    def is_clear_command(self, index: int, subindex: int) -> bool:
        return self._clear is not None and self._clear[0] == _key(index, subindex)

    def clear(
        self,
        values: dict[int, Value | None],
        defaults: dict[int, Value | None],
        value: Value,
    ) -> bool:
        """Apply a write to the clear command; False when ``value`` is not the documented one."""
        assert self._clear is not None
        if value != self._clear[1]:
            return False
        for num, tkey in self._hist:
            values[num] = defaults.get(num, 0)
            if tkey is not None:
                values[tkey] = defaults.get(tkey, 0)
        return True
