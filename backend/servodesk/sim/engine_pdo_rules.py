"""The simulated drive's rules for writes to PDO mapping and assignment objects.

A collaborator of :class:`~servodesk.sim.engine.SimulatedDrive` (sim/engine.py builds it from
the profile's ``pdo`` rules and quirks, and its object access asks it before storing a write
to 1600h-17FFh, 1A00h-1BFFh, 1C12h and 1C13h). It keeps no state of its own: it reads the
drive's object values and specifications it is given.

- A mapping object without its own ``writable_in`` accepts writes in the NMT state named by
  ``pdo.mapping_state`` ("any": no restriction) or whenever its PDO is invalid (bit 31 of the
  COB-ID set): CiA 301 §7.5.2.36 re-mapping procedure, which disables the PDO first and so may
  run in OPERATIONAL too. Outside it the family's abort (quirk ``pdo_state_abort``, HIWIN 000
  §2.8.1 note 1: 0601 0002h; CiA 301: 0800 0022h).
- Setting a mapping's count checks the entries (0604 0041h; quirk
  ``pdo_unknown_object_abort`` for an entry naming no object, smartris 001 §2-8 note 1),
  the family's entry and bit limits (0604 0042h) and, where duplicates are not allowed, an
  object mapped twice (HIWIN 000 §3.1: 0604 0043h).
- Setting 1C12h/1C13h sub 0 checks the assigned mapping objects against ``max_entries`` and
  ``max_bytes`` (HIWIN 000 §3.1.2 note 1: 0604 0042h).
"""

from __future__ import annotations

from dataclasses import dataclass

from servodesk.domain.datatypes import Value
from servodesk.domain.profile import ObjectSpec, PdoRules
from servodesk.sim.engine_base import SimAbort, key


def is_mapping(index: int) -> bool:
    return 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF


def is_pdo_object(index: int) -> bool:
    """A mapping object or a sync manager assignment (1C12h/1C13h)."""
    return is_mapping(index) or index in (0x1C12, 0x1C13)


@dataclass(frozen=True, slots=True)
class MappingRules:
    """One family's PDO mapping rules, as the simulated drive applies them."""

    #: The profile's limits (entries, bits, bytes per assignment).
    rules: PdoRules
    #: The NMT state where mappings may change ("preop", "op", ...; "any": every state).
    mapping_state: str
    #: The abort for a mapping or assignment write outside the state that allows it.
    state_abort: int
    #: The abort for a mapping entry naming no object.
    unknown_abort: int
    #: PROFIdrive telegrams pad with Reserved entries: index 0, 0/8/16 bits (004 §20.1.2).
    reserved: bool
    #: False where an object may be mapped only once (HIWIN 000 §3.1, 1600h).
    duplicates: bool

    def check_state(self, index: int, nmt_state: str, values: dict[int, Value | None]) -> None:
        """A write to mapping object ``index`` (one without its own ``writable_in``) in
        ``nmt_state``: allowed in the mapping state or while the PDO is invalid."""
        if self.mapping_state == "any" or nmt_state == self.mapping_state:
            return
        comm = values.get(key(index - 0x200, 1))
        if isinstance(comm, int) and comm & 0x80000000:
            return
        raise SimAbort(
            self.state_abort,
            "PDO mapping changes need PRE-OPERATIONAL or the PDO disabled",
        )

    def check_mapping(
        self,
        spec: ObjectSpec,
        value: Value,
        values: dict[int, Value | None],
        specs: dict[int, ObjectSpec],
    ) -> None:
        """CiA 301 §7.5.2.36: mapped objects must exist, be mappable and fit the PDO."""
        assert isinstance(value, int)
        rx = spec.index < 0x1A00
        if spec.subindex == 0:
            rules = self.rules
            if value > rules.max_entries:
                raise SimAbort(0x06040042, f"at most {rules.max_entries} entries")
            bits = 0
            seen: set[int] = set()
            for i in range(1, value + 1):
                entry = values.get(key(spec.index, i))
                if not isinstance(entry, int):
                    raise SimAbort(0x06040041)
                self._check_mapped_object(entry, rx, specs)
                bits += entry & 0xFF
                obj = entry >> 8
                if not self.duplicates and entry >> 16 and obj in seen:
                    # HIWIN 000 §3.1 (1600h): the same object may not be mapped twice.
                    raise SimAbort(0x06040043, f"0x{entry:08X} is mapped twice")
                seen.add(obj)
            if bits > rules.max_bits:
                raise SimAbort(0x06040042)
        elif value:
            self._check_mapped_object(value, rx, specs)

    def check_assignment(self, index: int, value: Value, values: dict[int, Value | None]) -> None:
        """HIWIN 000 §3.1.2 note 1: setting 1C12h/1C13h sub 0 to n checks the assigned
        mapping objects (0604 0042h when they hold too many objects or bytes)."""
        assert isinstance(value, int)
        rules = self.rules
        limit = rules.max_bytes * 8 if rules.max_bytes is not None else rules.max_bits
        total = 0
        for i in range(1, value + 1):
            mapping = values.get(key(index, i))
            if not isinstance(mapping, int) or not is_mapping(mapping):
                raise SimAbort(0x06040043, f"sub {i} names no mapping object")
            count = values.get(key(mapping, 0))
            if not isinstance(count, int) or count > rules.max_entries:
                raise SimAbort(0x06040042, f"0x{mapping:04X}: over {rules.max_entries} entries")
            for s in range(1, count + 1):
                entry = values.get(key(mapping, s))
                total += entry & 0xFF if isinstance(entry, int) else 0
        if total > limit:
            raise SimAbort(0x06040042, f"{total // 8} bytes assigned, at most {limit // 8}")

    def _check_mapped_object(self, entry: int, rx: bool, specs: dict[int, ObjectSpec]) -> None:
        if self.reserved and not entry >> 16 and entry & 0xFF in (0, 8, 16):
            return  # A Reserved entry (004 §20.1.2).
        target = specs.get(entry >> 8 & 0xFFFFFF)
        if target is None:
            raise SimAbort(self.unknown_abort, f"0x{entry:08X} names no object")
        ok = target.pdo_mapping.rx if rx else target.pdo_mapping.tx
        if not ok or target.bits != entry & 0xFF:
            raise SimAbort(0x06040041, f"0x{entry:08X} cannot be mapped")
