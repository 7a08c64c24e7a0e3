"""A simulated twin of any CiA 402 drive from its device description (issue 46).

``servodesk sim --interface ethercat --esi FILE [--device N]`` serves an EtherCAT slave whose
identity, object dictionary, default PDO assignment, sync managers and DC settings come from
the ESI (ETG.2000), with the CiA 402 engine (:class:`~servodesk.sim.engine.SimulatedDrive`)
behind it; ``--eds FILE`` the same as a CANopen node from an EDS, DCF or XDD.

The file is imported as any profile is (:mod:`servodesk.devdesc`), then completed where it is
not enough to run the engine (:func:`twin_profile`, each step reported as a note):

- CiA 402 objects the file lacks come from the generic profile of its fieldbus
  (``cia402-ethercat`` / ``cia402-generic``, its CiA 402-2 objects); an object the engine runs
  on (controlword, statusword, modes, positions, velocities, torques, error code) whose data
  type in the file is not CiA 402-2's is replaced by the generic one (the ETG sample
  ModulesSlots_CiA402 declares 6041h in a module's slot with another type).
- An object with no default (ETG.2000 makes ``DefaultData`` optional) reads 0 or the empty
  string, as a real drive answers something: the device description is not the device.
- Modes from 6502h's default (CiA 402-2 §6.2.6, bit 0 pp ... bit 9 cst), else the generic
  profile's; the homing methods and the simulation settings are the generic profile's.
- The default assignment (the ESI's RxPdo/TxPdo with ``Sm``, template ``esi-default``) is
  written into 1C12h / 1C13h and the mapping objects' defaults where the dictionary's
  defaults leave them empty, as the slave's firmware sets them at power-on.

:class:`TwinOptions` reproduces what real slaves do differently, each off by default (the
command line's flags, docs/ethercat.md "A twin from an ESI").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import (
    Access,
    DeviceProfile,
    ObjectEntry,
    ObjectType,
    Quirk,
    SubSpec,
)
from servodesk.domain.profile_loader import ProfileCatalog, merge

__all__ = ["ENGINE_OBJECTS", "TwinOptions", "twin_profile"]

#: The objects the engine runs on (sim/engine_base.py K_*): where the file gives them another
#: data type than CiA 402-2, the generic profile's definition is taken.
ENGINE_OBJECTS = (
    0x603F,
    0x6040,
    0x6041,
    0x6060,
    0x6061,
    0x6064,
    0x606C,
    0x6071,
    0x6077,
    0x607A,
    0x60FF,
)

#: CiA 402-2 §6.2.6 (6502h supported drive modes): bit -> mode of operation (6060h).
_MODE_BITS = {0: 1, 1: 2, 2: 3, 3: 4, 5: 6, 6: 7, 7: 8, 8: 9, 9: 10}

#: The SYNC0 cycles offered where the ESI has a DC mode with SYNC0 (AssignActivate bit 9,
#: ETG.2000 Dc/OpMode): ETG.2000 gives no range (CycleTimeSync0 0 means "the bus cycle"), so
#: the twin takes 125 µs steps from 125 µs to 10 ms, the range ETG.6010 §15 names for CiA 402
#: drives' cycle times.
DC_CYCLES_NS = {"min": 125_000, "max": 10_000_000, "step": 125_000}


@dataclass(frozen=True)
class TwinOptions:
    """What a real slave does that the plain twin does not (docs/ethercat.md)."""

    #: The SII claims SDO complete access (ETG.2010 General CoE details bit 5) though the
    #: firmware aborts it (0601 0000h). Without, complete access is not claimed and refused.
    claims_complete_access: bool = False
    #: The SDO Information service (ETG.1000.6 §5.6.3) is offered and answered.
    sdo_info: bool = False
    #: The SII's vendor id, product code, revision where they differ from 1018h (an SII
    #: programmed for another revision than the firmware reports); None: 1018h's.
    sii_identity: tuple[int, int, int] | None = None
    #: Seconds after power-on during which the firmware is not ready: a request of PRE-OP
    #: leaves the slave in INIT (no error) until then.
    boot_delay_s: float = 0.0
    #: The device has no 1008h (device name; CiA 301 makes it optional): the SII's name is
    #: then the ESI's.
    no_device_name: bool = False
    #: The SyncManager watchdog is enforced (OP -> SAFE-OP + error 001Bh when the outputs stop);
    #: False: a slave whose watchdog is switched off in its PDI configuration.
    watchdog: bool = True
    #: SDO abort frames with the reserved bits 0-4 of the command byte set (CiA 301 §7.2.4.3.17
    #: says 0; some firmware sends 1s).
    abort_reserved_bits: bool = False


def _same_kind(own: ObjectEntry, base: ObjectEntry) -> bool:
    """``own`` has the object type, data type and writability of ``base`` (the engine's)."""
    if own.object_type is not base.object_type or own.data_type != base.data_type:
        return False
    if own.access is None or base.access is None:
        return own.access is base.access
    return own.access.writable == base.access.writable


def _copy(profile: DeviceProfile, **update: Any) -> DeviceProfile:
    """``profile`` with ``update``, validated again: ``model_copy`` would carry the cached
    ``variables`` and ``entries`` of the old objects along."""
    fields = {k: getattr(profile, k) for k in DeviceProfile.model_fields}
    return DeviceProfile.model_validate({**fields, **update})


def _zero(dt: DataType) -> Any:
    if dt.is_numeric:
        return 0.0 if "REAL" in dt.name else 0
    if dt.name == "BOOLEAN":
        return False
    return ""  # Strings, OCTET_STRING and DOMAIN: empty.


def _filled(entry: ObjectEntry, base: DeviceProfile) -> tuple[ObjectEntry, int]:
    """The entry with a default where the file gives none (the generic profile's, of the
    same data type, else zero), and how many were filled."""

    def fill(sub: int, dt: DataType, lo: Any = None, hi: Any = None) -> Any:
        spec = base.spec(ObjectAddress(entry.index, sub))
        if spec is not None and spec.data_type == dt and spec.default is not None:
            return spec.default
        z = _zero(dt)
        if isinstance(z, int | float) and not isinstance(z, bool):
            # Zero where the file's range allows it, else the bound nearest to it.
            z = lo if lo is not None and z < lo else hi if hi is not None and z > hi else z
        return z

    if entry.object_type is ObjectType.VAR:
        assert entry.data_type is not None
        if entry.default is not None:
            return entry, 0
        z = fill(0, entry.data_type, entry.min, entry.max)
        return (entry.model_copy(update={"default": z}), 1) if z is not None else (entry, 0)
    subs: list[SubSpec] = []
    n = 0
    for s in entry.subs:
        lo = s.min if s.min is not None else entry.min
        hi = s.max if s.max is not None else entry.max
        z = (
            fill(s.sub, s.data_type, lo, hi)
            if s.default is None and entry.default is None
            else None
        )
        if z is not None and s.repeat == 1:
            s = s.model_copy(update={"default": z})
            n += 1
        subs.append(s)
    return entry.model_copy(update={"subs": tuple(subs)}), n


#: The cyclic synchronous modes (CiA 402-2 §6.2.6) and the target each one cycles.
_CYCLIC_TARGETS = {8: 0x607A, 9: 0x60FF, 10: 0x6071}


def _default(profile: DeviceProfile, index: int, sub: int) -> int:
    spec = profile.spec(ObjectAddress(index, sub))
    value = spec.default_value() if spec is not None else None
    return value if isinstance(value, int) else 0


def _default_rx_objects(profile: DeviceProfile) -> set[int]:
    """The objects the RxPDOs assigned by default (1C12h's defaults) map by default."""
    out: set[int] = set()
    for n in range(1, _default(profile, 0x1C12, 0) + 1):
        pdo = _default(profile, 0x1C12, n)
        for k in range(1, _default(profile, pdo, 0) + 1 if pdo else 1):
            out.add(_default(profile, pdo, k) >> 16)
    return out


def _modes(profile: DeviceProfile, base: DeviceProfile) -> tuple[int, ...]:
    """The modes of 6502h's default, and a cyclic synchronous mode whose target the ESI's
    default RxPDO maps (its master cycles that target: ETG.6010 §7's default mappings; the
    Synapticon files' 6502h default names pp, pv, tq and hm only, their 1600h maps 607Ah);
    the generic profile's where 6502h has no default."""
    spec = profile.spec(ObjectAddress(0x6502, 0))
    bits = spec.default_value() if spec is not None else None
    supported = set(base.modes)
    modes = set(profile.modes) & supported
    if isinstance(bits, int):
        modes |= {m for b, m in _MODE_BITS.items() if bits >> b & 1 and m in supported}
    if not modes:
        return base.modes
    mapped = _default_rx_objects(profile)
    modes |= {m for m, target in _CYCLIC_TARGETS.items() if target in mapped and m in supported}
    return tuple(sorted(modes)) or base.modes


def _set_defaults(entry: ObjectEntry, values: dict[int, int]) -> ObjectEntry:
    """``entry`` (ARRAY / RECORD) with the given subindices' defaults (repeats expanded)."""
    subs: list[SubSpec] = []
    for s in entry.subs:
        for k in range(s.repeat):
            sub = s.sub + k
            name = s.name.replace("{n}", str(k + 1)) if s.repeat > 1 or "{n}" in s.name else s.name
            one = s.model_copy(update={"sub": sub, "repeat": 1, "name": name})
            if sub in values:
                one = one.model_copy(update={"default": values[sub]})
            subs.append(one)
    return entry.model_copy(update={"subs": tuple(subs)})


def _assignment(
    profile: DeviceProfile, notes: list[str], template: str = "esi-default"
) -> DeviceProfile:
    """The ESI's default assignment in 1C12h / 1C13h and the mapping objects, where the
    dictionary leaves them empty (module doc)."""
    tpl = next((t for t in profile.pdo.templates if t.id == template), None)
    if tpl is None or not tpl.assignment:
        return profile
    entries = dict(profile.entries)

    def empty(index: int) -> bool:
        spec = profile.spec(ObjectAddress(index, 0))
        return spec is None or not spec.default_value()

    changed: list[str] = []
    for direction, sm_index in (("rx", 0x1C12), ("tx", 0x1C13)):
        pdos = tpl.assignment.get(direction, ())  # type: ignore[call-overload]
        e = entries.get(sm_index)
        if not pdos or e is None or e.object_type is ObjectType.VAR or not empty(sm_index):
            continue
        entries[sm_index] = _set_defaults(
            e, {0: len(pdos), **{i + 1: p for i, p in enumerate(pdos)}}
        )
        changed.append(f"{sm_index:04X}h")
    for pdo in tpl.pdos:
        index = (0x1600 if pdo.direction == "rx" else 0x1A00) + pdo.number - 1
        e = entries.get(index)
        if e is None or e.object_type is ObjectType.VAR or pdo.entries is None:
            continue
        if template == "esi-default" and not empty(index):
            continue
        words: dict[int, int] = {0: len(pdo.entries)}
        for i, w in enumerate(pdo.entries, start=1):
            text = w.address or ""
            if text.startswith("reserved:"):
                words[i] = int(text.split(":")[1])  # Padding: index 0, the bit length.
                continue
            if not text:
                words[i] = w.bits or 0
                continue
            a = ObjectAddress.parse(text)
            spec = profile.spec(a)
            bits = w.bits or (spec.bits if spec is not None else 0)
            words[i] = a.index << 16 | a.subindex << 8 | bits
        entries[index] = _set_defaults(e, words)
        changed.append(f"{index:04X}h")
    if not changed:
        return profile
    notes.append(f"default PDO assignment of the ESI written into {', '.join(changed)}")
    return _copy(profile, objects=tuple(entries[i] for i in sorted(entries)))


def twin_profile(
    profile: DeviceProfile,
    catalog: ProfileCatalog | None = None,
    *,
    options: TwinOptions = TwinOptions(),
) -> tuple[DeviceProfile, list[str]]:
    """The profile a twin of ``profile`` (an imported device description) runs on, and one
    note per completion made (module doc)."""
    catalog = catalog or ProfileCatalog()
    base = catalog.get("cia402-ethercat" if profile.fieldbus == "ethercat" else "cia402-generic")
    notes: list[str] = []
    # The assignment first: the generic profile's 1600h / 1A00h defaults must not fill the
    # file's empty mapping objects before the ESI's own default assignment does.
    profile = _assignment(profile, notes)
    own = profile.entries
    base_entries = base.entries
    replaced = [
        i
        for i in ENGINE_OBJECTS
        if i in own and i in base_entries and not _same_kind(own[i], base_entries[i])
    ]
    kept = tuple(e for e in profile.objects if e.index not in replaced)
    if replaced:
        notes.append(
            ", ".join(f"{i:04X}h" for i in replaced)
            + f" differ from CiA 402-2 (object type, data type or access): {base.id}'s taken"
        )
    added = [e.index for e in base.objects if e.index not in own]
    if added:
        notes.append(f"{len(added)} objects the file lacks taken from {base.id}")
    merged = merge(base, _copy(profile, objects=kept))
    filled_total = 0
    objects: list[ObjectEntry] = []
    for e in merged.objects:
        if options.no_device_name and e.index == 0x1008:
            continue
        e, n = _filled(e, base)
        filled_total += n
        objects.append(e)
    if filled_total:
        notes.append(
            f"{filled_total} objects without a default in the file: {base.id}'s default, else 0"
        )
    if options.no_device_name and 0x1008 in merged.entries:
        notes.append("no 1008h (option)")
    twin = _copy(merged, objects=tuple(objects))
    quirks = list(twin.quirks)
    ids = {q.id for q in quirks}
    quirks += [q for q in base.quirks if q.id not in ids]
    if twin.dc_cycles_ns() is None and any(m.assign_activate & 0x0200 for m in twin.pdo.dc_modes):
        quirks.append(
            Quirk(
                id="dc_cycle_time_ns",
                value=dict(DC_CYCLES_NS),
                section="ETG.2000 Dc/OpMode",
                note="the ESI names a SYNC0 mode but no range: servodesk's twin assumption",
            )
        )
    update: dict[str, Any] = {
        "homing_methods": twin.homing_methods or base.homing_methods,
        "simulation": base.simulation,
        "quirks": tuple(quirks),
    }
    twin = _sm_types(_identity(_copy(twin, **update), 0x1008 in own, notes), notes)
    twin = _mappings_usable(twin, base, notes)
    return _copy(twin, modes=_modes(twin, base), pdo=_templates(twin, notes)), notes


def _templates(profile: DeviceProfile, notes: list[str]) -> Any:
    """The PDO rules without the templates that name objects the twin does not have (the ETG
    ModulesSlots sample's default maps 6064h:01 of a module's record, now a VAR)."""
    kept = []
    for t in profile.pdo.templates:
        words = [w.address for p in t.pdos for w in p.entries or () if w.address]
        missing = [
            w
            for w in words
            if not w.startswith("reserved") and profile.spec(ObjectAddress.parse(w)) is None
        ]
        if missing:
            notes.append(f"PDO template {t.id} left out: {', '.join(missing)} not in the twin")
            continue
        kept.append(t)
    return profile.pdo.model_copy(update={"templates": tuple(kept)})


#: SyncManager communication types (ETG.1000.6 §5.6.7.4.8, 1C00h) by the ESI's Sm text.
_SM_TYPES = {"mboxout": 1, "mboxin": 2, "outputs": 3, "inputs": 4}


def _sm_types(profile: DeviceProfile, notes: list[str]) -> DeviceProfile:
    """1C00h from the ESI's ``Sm`` elements (the four of ETG.1000.6 where it names none),
    where the file has no 1C00h: SOEM's config_map reads it to find SM2 / SM3 and maps
    nothing without it (cia402-ethercat has none either)."""
    if profile.pdo.kind != "ethercat":
        return profile
    types = [_SM_TYPES.get(sm.kind.lower(), 0) for sm in profile.pdo.sync_managers] or [1, 2, 3, 4]
    own = profile.entries.get(0x1C00)
    if own is not None:
        u8 = all(s.data_type == DataType.UNSIGNED8 for s in own.subs)
        if own.object_type is ObjectType.VAR or (u8 and _default(profile, 0x1C00, 0)):
            return profile
        # The Elmo Gold file's 1C00h: UINT subs without defaults. SOEM reads each type into
        # one byte (ethercatconfig.c ecx_readPDOmap; a longer answer is its packet error 3),
        # so the twin answers ETG.1000.6's UNSIGNED8 with the types of the Sm elements.
        notes.append("1C00h replaced: UNSIGNED8 types of the ESI's sync managers (ETG.1000.6)")
    else:
        notes.append("1C00h made from the ESI's sync managers (the file has none)")
    subs = [
        SubSpec(
            sub=0,
            name="Number of used sync manager channels",
            data_type=DataType.UNSIGNED8,
            access=Access.RO,
            default=len(types),
        )
    ]
    subs += [
        SubSpec(
            sub=n + 1,
            name=f"Communication type sync manager {n}",
            data_type=DataType.UNSIGNED8,
            access=Access.RO,
            default=t,
        )
        for n, t in enumerate(types)
    ]
    entry = ObjectEntry(
        index=0x1C00,
        name="Sync manager communication type",
        object_type=ObjectType.ARRAY,
        subs=tuple(subs),
        section="ETG.1000.6 §5.6.7.4.8",
    )
    objects = sorted(
        [*(e for e in profile.objects if e.index != 0x1C00), entry], key=lambda e: e.index
    )
    return _copy(profile, objects=tuple(objects))


def _identity(profile: DeviceProfile, has_name: bool, notes: list[str]) -> DeviceProfile:
    """1018h:01-03 as the ESI's ``Vendor/Id`` and ``Type`` say (what a master compares with
    the SII and the ESI, ETG.1000.6 §5.6.7.4.6), and 1008h the device's name where the file
    has no 1008h of its own."""
    ident = profile.identity
    revision = ident.revision_min if ident.revision_min == ident.revision_max else None
    want = {
        1: ident.vendor_id,
        2: ident.product_codes[0] if ident.product_codes else None,
        3: revision,
    }
    entries = dict(profile.entries)
    e = entries.get(0x1018)
    if e is not None and e.object_type is not ObjectType.VAR:
        values = {
            sub: v
            for sub, v in want.items()
            if v is not None and profile.spec(ObjectAddress(0x1018, sub)) is not None
        }
        differ = [f"{sub:02X}" for sub, v in values.items() if _default(profile, 0x1018, sub) != v]
        if differ:
            entries[0x1018] = _set_defaults(e, values)
            notes.append(f"1018h:{', :'.join(differ)} set to the ESI's Vendor Id / Type")
    name = entries.get(0x1008)
    if name is not None and not has_name and name.object_type is ObjectType.VAR:
        entries[0x1008] = name.model_copy(update={"default": profile.name})
    return _copy(profile, objects=tuple(entries[i] for i in sorted(entries)))


def _is_mapping(index: int) -> bool:
    return 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF


def _usable(profile: DeviceProfile, word: int) -> bool:
    """A mapping entry a master can exchange: padding, or an object of the twin that is no
    mapping object, of the entry's length."""
    index, sub, bits = word >> 16, word >> 8 & 0xFF, word & 0xFF
    if index == 0:
        return True
    spec = profile.spec(ObjectAddress(index, sub))
    return spec is not None and not _is_mapping(index) and spec.bits == bits


def _mappings_usable(
    profile: DeviceProfile, base: DeviceProfile, notes: list[str]
) -> DeviceProfile:
    """Default mappings a master could not exchange, made exchangeable (a twin is for
    exchanging process data), each step a note:

    - a count above the entries defined is the count (Inovance IS620N: 1B03h:00 defaults to
      16 with 10 entries; servodesk refuses such a mapping);
    - an entry naming subindex n of an object the twin has as a VAR of that length names
      the VAR (ETG ModulesSlots: 6041h:01 of the module's record, which the twin replaced);
    - a mapping still naming no mappable object takes the generic profile's csp mapping
      (ETG.6010 §7) into the file's own subindices (the Synapticon multi-device sample maps
      1600h:01..05, the mapping object itself, named "Controlword", "Op Modes", ...).
    """
    entries = dict(profile.entries)
    csp_profile = _assignment(_copy(base, objects=tuple(base.objects)), [], "csp")
    clamped: list[str] = []
    renamed: list[str] = []
    fixed: list[str] = []
    for index, e in profile.entries.items():
        if not _is_mapping(index) or not e.subs:
            continue
        room = len([a for a in profile.variables if a.index == index and a.subindex > 0])
        count = _default(profile, index, 0)
        if count > room:
            clamped.append(f"{index:04X}h")
            count = room
        words = [_default(profile, index, k) for k in range(1, count + 1)]
        new = [
            w if _usable(profile, w) or not _usable(profile, w & 0xFFFF00FF) else w & 0xFFFF00FF
            for w in words
        ]
        if new != words:
            renamed.append(f"{index:04X}h")
        if not all(_usable(profile, w) for w in new) and index in csp_profile.entries:
            n = _default(csp_profile, index, 0)
            new = [_default(csp_profile, index, k) for k in range(1, n + 1)]
            if n > room:
                entries[index] = csp_profile.entries[index]
                fixed.append(f"{index:04X}h")
                continue
            fixed.append(f"{index:04X}h")
        if new != words or len(words) != _default(profile, index, 0):
            entries[index] = _set_defaults(
                e, {0: len(new), **{k: w for k, w in enumerate(new, start=1)}}
            )
    if clamped:
        notes.append(f"{', '.join(clamped)}:00 default more entries than defined: the count")
    if renamed:
        notes.append(f"{', '.join(renamed)} map a subindex of an object the twin has as a VAR")
    if fixed:
        notes.append(
            f"{', '.join(fixed)} map no mappable object by default in the file: {base.id}'s "
            "csp mapping taken"
        )
    if not (clamped or renamed or fixed):
        return profile
    return _copy(profile, objects=tuple(entries[i] for i in sorted(entries)))
