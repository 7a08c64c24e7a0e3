"""Object access of the simulated drive: reads, writes, their checks and side effects.

Part of :class:`~servodesk.sim.engine.SimulatedDrive` (sim/engine.py says why the parts are a
chain of base classes). An SDO download (:meth:`ObjectAccess.write_bytes`) checks, in order,
existence (0602 0000h, 0609 0011h for a missing sub-index), access (0601 0002h), length (0607
0012h/0013h), the state the object may be written in (``writable_in``; PDO mapping objects by
the family's rules, sim/engine_pdo_rules.py), and the value (limits 0609 0031h/0032h, the
objects with a meaning of their own); then the write acts: the controlword drives the state
machine, 6060h changes the mode, 1003h sub 0 clears the error history (CiA 301 §7.5.2.3),
1010h/1011h store or restore parameters (§7.5.2.13/14, or the family's command objects), the
recorder, one-touch tuning and test signal objects go to their owners, and a gain object
reloads the servo loop's gains. Process data (sim/pdo.py) takes the same path through
:meth:`ObjectAccess.write_process` and reads through :meth:`ObjectAccess.sample`.
"""

from __future__ import annotations

from collections.abc import Sequence

from servodesk.domain.datatypes import Value, codec, coerce_int
from servodesk.domain.homing import resolve_method
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.sim.engine_base import (
    ENABLED_STATES,
    FALLBACK,
    K_CONTROLWORD,
    K_ERROR_HISTORY,
    K_HOMING_METHOD,
    K_MODE,
    NMT_ALIASES,
    SimAbort,
    key,
    norm,
)
from servodesk.sim.engine_pdo_rules import is_mapping, is_pdo_object
from servodesk.sim.engine_states import StateMachine


def command_quirk(
    profile: DeviceProfile, quirk_id: str, index: int, signature: int
) -> tuple[int, int | None, int]:
    """The store (1010h) or restore (1011h) command of a family: the object, its sub-index
    (None: the CiA 301 sub-indices with their scopes) and the signature it takes, from the
    quirk ``quirk_id`` when the family has its own command object."""
    q = profile.quirk(quirk_id)
    if isinstance(q, dict):
        return (
            coerce_int(q["index"]),
            coerce_int(q.get("subindex", 1)),
            coerce_int(q.get("value", signature)),
        )
    return (index, None, signature)


class ObjectAccess(StateMachine):
    """The object dictionary as the bus sees it: typed and byte reads and writes."""

    def sample(self, keys: Sequence[int]) -> list[Value | None]:
        """Current values of objects by key (``index << 8 | subindex``), for process data.

        No access checks: the caller maps only existing, readable objects.
        """
        with self._lock:
            live = self._live
            values = self._values
            return [f() if (f := live.get(k)) is not None else values.get(k) for k in keys]

    def write_process(self, items: Sequence[tuple[int, Value]]) -> None:
        """Write received process data (``(key, value)`` pairs, in mapping order).

        The normal write path runs (the objects' side effects, e.g. controlword transitions,
        and the state rules that the drive applies to any write); a value the drive refuses is
        dropped without an answer, as there is none for a PDO (CiA 301 §7.2.2). The
        controlword is acted upon last, with the other values of the same PDO in place (a new
        set-point and its target position arrive together).
        """
        done: list[tuple[int, int, Value]] = []
        refresh = False
        with self._lock:
            values = self._values
            cw: list[Value] = []
            for k, value in items:
                if k == K_CONTROLWORD:
                    cw.append(value)
                    continue
                # A PDO repeats its data every cycle: an unchanged value has nothing to do
                # (the controlword always goes through, as its handling counts commands).
                if values.get(k) == value:
                    continue
                spec = self._specs.get(k)
                if spec is None or not spec.access.writable:
                    continue
                try:
                    self._write(spec, value)
                except SimAbort:
                    continue
                done.append((spec.index, spec.subindex, value))
                refresh = refresh or k in FALLBACK
            if refresh:
                self._refresh()
            spec = self._specs.get(K_CONTROLWORD)
            for value in cw:
                if spec is not None:
                    try:
                        self._write(spec, value)
                    except SimAbort:
                        continue
                    done.append((spec.index, spec.subindex, value))
        for index, subindex, value in done:
            for cb in self._write_listeners:
                cb(index, subindex, value)
        self._flush()

    def has_object(self, index: int, subindex: int = 0) -> bool:
        return key(index, subindex) in self._specs

    def spec(self, index: int, subindex: int = 0) -> ObjectSpec:
        """The specification of an object, or :class:`SimAbort` as the bus would answer."""
        return self._lookup(index, subindex)

    def set_status(self, index: int, subindex: int, value: Value) -> None:
        """Set an object the device itself keeps, read-only ones too (the sync mode an
        EtherCAT slave takes from its ESC's DC registers, 1C32h / 1C33h); nothing is checked
        but that the object exists."""
        with self._lock:
            spec = self._lookup(index, subindex)
            self._values[key(spec.index, spec.subindex)] = value
            self._refresh()

    def withhold(self, index: int, subindex: int = 0) -> None:
        """Hold no value for an object from now on: reads answer 0800 0024h "no data
        available" (CiA 301 §7.2.4.3.17), as a drive whose firmware lacks the value does.
        Every object of the manual has a value in the twins (issue 47); this is how a test
        meets a drive that refuses one. A write gives it a value again."""
        with self._lock:
            spec = self._lookup(index, subindex)
            self._values[key(spec.index, spec.subindex)] = None
            self._refresh()

    def read(self, index: int, subindex: int = 0) -> Value:
        """The typed value of an object, as an SDO upload would return it."""
        with self._lock:
            spec = self._lookup(index, subindex)
            return self._read(spec)

    def read_bytes(self, index: int, subindex: int = 0) -> bytes:
        with self._lock:
            spec = self._lookup(index, subindex)
            return codec(spec.data_type).encode(self._read(spec))

    def check_download(self, index: int, subindex: int) -> None:
        """Refuse a download early (before a segmented transfer) when it cannot succeed."""
        with self._lock:
            spec = self._lookup(index, subindex)
            if not spec.access.writable:
                raise SimAbort(0x06010002)

    def write_bytes(self, index: int, subindex: int, data: bytes) -> None:
        """An SDO download: checks, in order, existence, access, length, state, value."""
        with self._lock:
            spec = self._lookup(index, subindex)
            if not spec.access.writable:
                raise SimAbort(0x06010002)
            n = spec.data_type.bits // 8
            if n:
                if len(data) > n:
                    raise SimAbort(0x06070012)
                if len(data) < n:
                    raise SimAbort(0x06070013)
            value = codec(spec.data_type).decode(bytes(data))
            if isinstance(value, bool):
                value = int(value)
            self._write(spec, value)
            self._refresh()
        self._after_write(index, subindex, value)

    def write(self, index: int, subindex: int, value: Value) -> None:
        """A typed write with the same checks as :meth:`write_bytes`."""
        with self._lock:
            spec = self._lookup(index, subindex)
            if not spec.access.writable:
                raise SimAbort(0x06010002)
            dt = spec.data_type
            if dt.is_integer:
                value = coerce_int(value, dt)
            elif dt.is_real:
                value = float(value)
            self._write(spec, value)
            self._refresh()
        self._after_write(index, subindex, value)

    def _lookup(self, index: int, subindex: int) -> ObjectSpec:
        spec = self._specs.get(key(index, subindex))
        if spec is None:
            if index in self._subs:
                raise SimAbort(0x06090011)
            raise SimAbort(0x06020000)
        return spec

    def _read(self, spec: ObjectSpec) -> Value:
        if not spec.access.readable:
            raise SimAbort(0x06010001)
        k = key(spec.index, spec.subindex)
        live = self._live.get(k)
        v = live() if live is not None else self._values.get(k)
        if v is None:
            raise SimAbort(0x08000024)
        return v

    def _write(self, spec: ObjectSpec, value: Value) -> None:
        k = key(spec.index, spec.subindex)
        self._check_state(spec)
        if spec.index == K_ERROR_HISTORY and spec.subindex == 0:
            # CiA 301 §7.5.2.3: only 0 may be written (clears the history).
            if value != 0:
                raise SimAbort(0x06090030, "write 0 to clear the error history")
            for s in self._subs[K_ERROR_HISTORY]:
                self._values[key(K_ERROR_HISTORY, s)] = self._defaults[key(K_ERROR_HISTORY, s)]
            self._values[k] = 0
            return
        cmd = self._store_restore(spec, value)
        if cmd:
            return
        if isinstance(value, int) and spec.data_type.is_integer:
            lo, hi = spec.limits()
            if lo is not None and value < lo:
                raise SimAbort(0x06090032, f"minimum is {lo}")
            if hi is not None and value > hi:
                raise SimAbort(0x06090031, f"maximum is {hi}")
        elif isinstance(value, float) and spec.data_type.is_real:
            if spec.min is not None and value < spec.min:
                raise SimAbort(0x06090032, f"minimum is {spec.min}")
            if spec.max is not None and value > spec.max:
                raise SimAbort(0x06090031, f"maximum is {spec.max}")
        if k == K_CONTROLWORD:
            assert isinstance(value, int)
            self._controlword(value)
            return
        if k == K_MODE:
            if value not in self._mode_values:
                raise SimAbort(0x06090030, f"supported modes: {sorted(self._mode_values)}")
            self._values[k] = value
            # 0 changes nothing: the mode running stays, 6061h with it (000 §3.2: "set to 0
            # ... the mode is not changed").
            if value != 0 and self._mode != value:
                self._enter_mode(int(value))
            return
        if k == K_HOMING_METHOD:
            if value not in self._homing_methods:
                raise SimAbort(0x06090030, f"supported methods: {sorted(self._homing_methods)}")
            if resolve_method(int(value), self._homing_equiv) is None:
                # A vendor method the profile does not map to a documented behaviour.
                raise SimAbort(0x06090030, f"homing method {value} is not simulated")
        if self.faults.is_clear_command(spec.index, spec.subindex):
            if not self.faults.clear(self._values, self._defaults, value):
                raise SimAbort(0x06090030, "not the documented clear value")
            return
        if is_mapping(spec.index):
            self._pdo_rules.check_mapping(spec, value, self._values, self._specs)
        elif spec.index in (0x1C12, 0x1C13) and spec.subindex == 0:
            self._pdo_rules.check_assignment(spec.index, value, self._values)
        elif self.recorder is not None and self.recorder.owns(spec.index):
            refusal = self.recorder.write(spec.index, spec.subindex, value)
            if refusal is not None:
                raise SimAbort(*refusal)
        elif self.one_touch is not None and self.one_touch.owns(spec.index):
            refusal = self.one_touch.write(spec.index, spec.subindex, value)
            if refusal is not None:
                raise SimAbort(*refusal)
        elif spec.index == self._sig_index:
            self._signal_write(spec.subindex, value)
        self._values[k] = value
        if k in self._gain_keys:
            self._load_gains()  # docs/tuning.md: a gain acts from the next loop tick on.

    def _after_write(self, index: int, subindex: int, value: Value) -> None:
        for cb in self._write_listeners:
            cb(index, subindex, value)
        self._flush()

    def _check_state(self, spec: ObjectSpec) -> None:
        allowed = spec.writable_in
        if not allowed and is_mapping(spec.index):
            self._pdo_rules.check_state(spec.index, self.nmt_state, self._values)
            return
        if not allowed:
            return
        here = {self.nmt_state, self._state.name.lower()}
        if self._state not in ENABLED_STATES:
            here.update(("disabled", "servo_off"))
        for name in allowed:
            n = norm(name)
            if NMT_ALIASES.get(n, n) in here:
                return
        code = self._pdo_rules.state_abort if is_pdo_object(spec.index) else 0x08000022
        raise SimAbort(code, f"writable only in {', '.join(allowed)}")

    def _store_restore(self, spec: ObjectSpec, value: Value) -> bool:
        """Store (1010h) / restore (1011h) commands; True when the write was one."""
        for cmd, store in ((self._store_cmd, True), (self._restore_cmd, False)):
            index, sub, signature = cmd
            if spec.index != index:
                continue
            if (sub is None and spec.subindex == 0) or (sub is not None and spec.subindex != sub):
                continue
            if value != signature:
                raise SimAbort(0x08000020, f"write the signature 0x{signature:08X}")
            lo, hi = _scope(spec.subindex if sub is None else 1)
            for k, s in self._specs.items():
                if s.persist and lo <= s.index <= hi:
                    if store:
                        self._nv[k] = self._values.get(k)
                    else:
                        self._nv.pop(k, None)  # Defaults apply at the next reset.
            return True
        return False


def _scope(sub: int) -> tuple[int, int]:
    """Index range a 1010h/1011h sub-index covers (CiA 301 §7.5.2.13)."""
    if sub == 2:
        return (0x1000, 0x1FFF)  # Communication parameters.
    if sub == 3:
        return (0x6000, 0x9FFF)  # Application (device profile) parameters.
    if sub >= 4:
        return (0x2000, 0x5FFF)  # Manufacturer-specific parameters.
    return (0x0000, 0xFFFF)  # All parameters.
