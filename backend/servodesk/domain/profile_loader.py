"""Finding, loading and checking profiles (``profiles/<id>/profile.yaml``).

Search order: directories named in ``SERVODESK_PROFILE_DIRS``, then the profiles packaged in
the wheel (``servodesk/_profiles``), then the checkout's top-level ``profiles/``. The first
profile with a given id wins, so a user can shadow a shipped profile.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import pydantic
import yaml

from servodesk import files
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.encoder_units import INCREMENT_UNITS
from servodesk.domain.ids import check_id
from servodesk.domain.profile import DeviceProfile, resolve_value
from servodesk.domain.quirks import check_quirks
from servodesk.errors import NotFoundError, ProfileError, ServodeskError

try:  # libyaml is ~10x faster on the large profiles.
    _Loader: Any = yaml.CSafeLoader
except AttributeError:  # pragma: no cover - libyaml missing
    _Loader = yaml.SafeLoader

PROFILE_FILE = "profile.yaml"


def default_profile_dirs(extra: Iterable[Path] = ()) -> list[Path]:
    here = Path(__file__).resolve()
    shipped = [
        here.parent.parent / "_profiles",  # In the wheel.
        here.parents[3] / "profiles",  # In a checkout: backend/servodesk/domain.
    ]
    # User directories are kept even before they exist: an import may create them.
    return [Path(p) for p in extra] + [d for d in shipped if d.is_dir()]


def read_profile_file(path: Path) -> DeviceProfile:
    """Parse and validate one profile file (without resolving ``extends``)."""
    try:
        data = yaml.load(path.read_text(encoding="utf-8"), Loader=_Loader)
    except OSError as exc:
        raise ProfileError(f"cannot read: {exc.strerror}", path=str(path)) from exc
    except yaml.YAMLError as exc:
        raise ProfileError(f"not valid YAML: {exc}", path=str(path)) from exc
    if not isinstance(data, dict):
        raise ProfileError("the file must hold a mapping at the top", path=str(path))
    return parse_profile(data, source=str(path))


def parse_profile(data: dict[str, Any], source: str = "<profile>") -> DeviceProfile:
    try:
        profile = DeviceProfile.model_validate(data)
    except pydantic.ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        more = f" (and {exc.error_count() - 1} more problems)" if exc.error_count() > 1 else ""
        raise ProfileError(f"{where}: {first['msg']}{more}", path=source) from exc
    # A quirk id with a typo would read as "the family has no such deviation": refused here,
    # naming the closest known id (domain/quirks.py).
    problems = check_quirks([(q.id, q.value) for q in profile.quirks])
    if problems:
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        raise ProfileError(f"{problems[0]}{more}", path=source)
    return profile


def merge(base: DeviceProfile, child: DeviceProfile) -> DeviceProfile:
    """The child profile with the base's objects and errors it does not redefine."""
    own_idx = {e.index for e in child.objects}
    objects = sorted(
        [e for e in base.objects if e.index not in own_idx] + list(child.objects),
        key=lambda e: e.index,
    )
    own_codes = {(e.table, e.code) for e in child.errors}
    errors = [e for e in base.errors if (e.table, e.code) not in own_codes] + list(child.errors)
    groups = list(child.groups) + [
        g for g in base.groups if g.id not in {c.id for c in child.groups}
    ]
    update: dict[str, object] = {
        "objects": tuple(objects),
        "errors": tuple(errors),
        "groups": tuple(groups),
    }
    if child.recorder is None and base.recorder is not None:
        # The base's recorder objects come along with its objects, so its recorder does too.
        update["recorder"] = base.recorder
    if child.tuning is None and base.tuning is not None:
        # Likewise the gain objects and the signal generator.
        update["tuning"] = base.tuning
    # The base's ``network:`` is not inherited: it says how the base's own family is addressed
    # on its fieldbus (its switches, LEDs, manual sections), which a derived family's manual
    # says for itself.
    return child.model_copy(update=update)


def check_profile(p: DeviceProfile) -> list[str]:
    """Consistency problems of a loaded profile; an empty list means it is consistent."""
    problems: list[str] = []
    seen: set[tuple[int, int]] = set()
    for entry in p.objects:
        subs: set[int] = set()
        for spec in entry.specs():
            key = (spec.index, spec.subindex)
            where = f"{spec.address} {spec.name}"
            if spec.subindex in subs:
                problems.append(f"{where}: duplicate subindex")
            subs.add(spec.subindex)
            if key in seen and spec.subindex == 0 and len(subs) == 1:
                problems.append(f"{where}: duplicate index")
            seen.add(key)
            problems.extend(_check_value_fields(spec, where))
            if spec.pdo_mapping.value != "none" and spec.bits == 0:
                problems.append(f"{where}: PDO-mappable but {spec.data_type.name} has no size")
            if spec.pdo_mapping.rx and not spec.access.writable:
                problems.append(f"{where}: RPDO-mappable but not writable ({spec.access.value})")
    idx_count: dict[int, int] = {}
    for entry in p.objects:
        idx_count[entry.index] = idx_count.get(entry.index, 0) + 1
    problems.extend(f"0x{i:04X}: defined {n} times" for i, n in idx_count.items() if n > 1)
    codes: dict[tuple[str, int], int] = {}
    for e in p.errors:
        codes[(e.table, e.code)] = codes.get((e.table, e.code), 0) + 1
    problems.extend(
        f"error table {t!r}: code 0x{c:X} defined {n} times" for (t, c), n in codes.items() if n > 1
    )
    group_ids = {g.id for g in p.groups}
    if group_ids:
        for spec in p.variables.values():
            if spec.group and spec.group not in group_ids:
                problems.append(f"{spec.address} {spec.name}: group {spec.group!r} not in groups")
    problems.extend(check_quirks([(q.id, q.value) for q in p.quirks]))
    problems.extend(_check_pdo_rules(p))
    problems.extend(_check_tuning(p))
    problems.extend(_check_network(p))
    problems.extend(_check_increment_scales(p))
    for m in p.modes:
        if not -128 <= m <= 127:
            problems.append(f"mode {m} does not fit 6060h (INTEGER8)")
    for h in p.homing_methods:
        if not -128 <= h <= 127:
            problems.append(f"homing method {h} does not fit 6098h (INTEGER8)")
    return problems


#: Engineering units of a rotary axis, in (raw unit, unit) -> the unit per revolution: an
#: increment object's scale is this over the encoder's counts per revolution.
_PER_REV: dict[tuple[str, str], float] = {
    ("inc", "deg"): 360.0,
    ("inc", "rev"): 1.0,
    ("inc/s", "rpm"): 60.0,
    ("inc/s²", "rpm/s"): 60.0,
    ("inc/s^2", "rpm/s"): 60.0,
}


def _check_increment_scales(p: DeviceProfile) -> list[str]:
    """Objects counted in increments with an angular unit have their scale for the encoder
    of ``simulation.counts_per_rev``: a session rescales them from there to the encoder the
    drive reports in 608Fh (domain/encoder_units.py), which is only right if they agree."""
    out: list[str] = []
    cpr = p.simulation.counts_per_rev
    for spec in p.variables.values():
        if spec.raw_unit not in INCREMENT_UNITS or spec.unit is None:
            continue
        per_rev = _PER_REV.get((spec.raw_unit, spec.unit))
        if per_rev is not None and not math.isclose(spec.scale * cpr, per_rev, rel_tol=1e-9):
            out.append(
                f"{spec.address} {spec.name}: scale {spec.scale:g} {spec.unit} per "
                f"{spec.raw_unit} is not {per_rev:g} / simulation.counts_per_rev ({cpr})"
            )
    return out


#: Test signal generator sub-index -> (data type, writable) (docs/tuning.md).
_SIGNAL_OBJECTS: dict[int, tuple[DataType, bool]] = {
    1: (DataType.UNSIGNED8, True),
    2: (DataType.REAL32, True),
    3: (DataType.REAL32, True),
    4: (DataType.REAL32, True),
    5: (DataType.REAL32, True),
    6: (DataType.UNSIGNED8, True),
    7: (DataType.REAL32, False),
    8: (DataType.REAL32, False),
}


def _check_tuning(p: DeviceProfile) -> list[str]:
    """The ``tuning:`` block names objects the profile has, of usable types; the recorder
    samples at the simulation's loop rate (docs/tuning.md)."""
    out: list[str] = []
    rec = p.recorder
    if rec is not None and rec.rate_hz != p.simulation.loop_rate_hz:
        out.append(
            f"recorder.rate_hz {rec.rate_hz:g} is not simulation.loop_rate_hz "
            f"{p.simulation.loop_rate_hz} (the recorder samples every loop tick)"
        )
    t = p.tuning
    if t is None:
        return out
    for name, g in t.gains.items():
        spec = p.spec(g.address)
        where = f"tuning.gains.{name}: {g.object}"
        if spec is None:
            out.append(f"{where} is not an object of the profile")
        elif not (spec.data_type.is_integer or spec.data_type.is_real):
            out.append(f"{where} {spec.name} is {spec.data_type.name}, not a number")
        elif not (spec.access.readable and spec.access.writable):
            out.append(f"{where} {spec.name} must be readable and writable")
    addr = t.loop_rate_address
    if addr is not None:
        spec = p.spec(addr)
        if spec is None:
            out.append(f"tuning.loop_rate_object: {addr} is not an object of the profile")
        elif not spec.access.readable or not spec.data_type.is_integer:
            out.append(f"tuning.loop_rate_object: {addr} must be a readable integer")
    if t.signal_index is not None:
        entry = p.entries.get(t.signal_index)
        if entry is None:
            out.append(f"tuning.signal_index: {t.signal_index:04X}h is missing")
            return out
        if not entry.sim_only:
            out.append(f"tuning.signal_index: {t.signal_index:04X}h is not marked sim_only")
        subs = {s.subindex: s for s in entry.specs()}
        for sub, (dt, writable) in _SIGNAL_OBJECTS.items():
            s = subs.get(sub)
            if s is None or s.data_type is not dt or s.access.writable != writable:
                access = "writable" if writable else "read-only"
                out.append(f"tuning: {t.signal_index:04X}h:{sub:02X} must be a {access} {dt.name}")
    return out


def _check_network(p: DeviceProfile) -> list[str]:
    """The ``network:`` section names objects the profile has, each once: the Network page
    reads them from the drive, so an object only the twin has (``sim_only``) or a write-only
    one has no place there."""
    net = p.network
    if net is None:
        return []
    out: list[str] = []
    seen: set[ObjectAddress] = set()
    for i, o in enumerate(net.objects):
        addr = o.address
        where = f"network.objects.{i}: {o.object}"
        spec = p.spec(addr)
        if spec is None:
            out.append(f"{where} is not an object of the profile")
        elif not spec.access.readable:
            out.append(f"{where} {spec.name} is write-only: the Network page reads it")
        elif spec.sim_only:
            out.append(f"{where} {spec.name} is the simulated twin's only (sim_only)")
        if addr in seen:
            out.append(f"{where} is listed twice")
        seen.add(addr)
    return out


def _check_pdo_word(p: DeviceProfile, text: str, direction: str, where: str) -> str | None:
    """A template / telegram entry must name an object mappable in its direction."""
    if text.strip().lower().startswith("reserved"):
        return None
    try:
        addr = ObjectAddress.parse(text)
    except ServodeskError as exc:
        return f"{where}: {exc.message}"
    if addr.index == 0 or 0x0002 <= addr.index <= 0x0007:
        return None  # Reserved / dummy entries (validated by domain/pdo.py).
    spec = p.spec(addr)
    if spec is None:
        return f"{where}: {addr} is not an object of the profile"
    ok = spec.pdo_mapping.rx if direction == "rx" else spec.pdo_mapping.tx
    if not ok:
        return f"{where}: {addr} {spec.name} is not mappable in {direction}"
    return None


def _check_pdo_rules(p: DeviceProfile) -> list[str]:
    out: list[str] = []
    rules = p.pdo
    numbers = {t.number for t in rules.telegrams}
    for t in rules.telegrams:
        for direction, words in (("rx", t.rx), ("tx", t.tx)):
            for i, w in enumerate(words):
                if w.address is not None:
                    err = _check_pdo_word(
                        p, w.address, direction, f"telegram {t.number} {direction}[{i}]"
                    )
                    if err:
                        out.append(err)
    ids: set[str] = set()
    for tpl in rules.templates:
        if tpl.id in ids:
            out.append(f"PDO template {tpl.id!r} defined twice")
        ids.add(tpl.id)
        if tpl.telegram is not None and tpl.telegram not in numbers:
            out.append(f"PDO template {tpl.id}: telegram {tpl.telegram} is not in pdo.telegrams")
        for q in tpl.pdos:
            count = rules.rpdo_count if q.direction == "rx" else rules.tpdo_count
            if q.number > count:
                out.append(f"PDO template {tpl.id}: {q.direction} PDO {q.number} > {count}")
            for i, w in enumerate(q.entries or ()):
                if w.address is not None:
                    where = f"PDO template {tpl.id} {q.direction}{q.number}[{i}]"
                    err = _check_pdo_word(p, w.address, q.direction, where)
                    if err:
                        out.append(err)
    return out


def _check_value_fields(spec: Any, where: str) -> list[str]:
    out: list[str] = []
    dt: DataType = spec.data_type
    rng = dt.range
    for name in ("min", "max"):
        v = getattr(spec, name)
        if v is None:
            continue
        if rng is not None and not (rng[0] <= v <= rng[1]):
            out.append(f"{where}: {name} {v} does not fit {dt.name}")
        if isinstance(v, float) and not math.isfinite(v):
            out.append(f"{where}: {name} is not finite")
    if spec.min is not None and spec.max is not None and spec.min > spec.max:
        out.append(f"{where}: min {spec.min} is above max {spec.max}")
    try:
        d = resolve_value(spec.default, dt, node_id=1)
    except (ValueError, ProfileError) as exc:
        return [*out, f"{where}: default {spec.default!r}: {exc}"]
    except Exception as exc:  # servodesk ValidationError from coercion
        return [*out, f"{where}: default {spec.default!r}: {exc}"]
    if isinstance(d, int | float) and not isinstance(d, bool) and dt.is_numeric:
        lo, hi = spec.limits()
        if isinstance(spec.default, str) and "$NODEID" in spec.default.upper():
            return out  # Checked per node when the device is built.
        if lo is not None and d < lo:
            out.append(f"{where}: default {d} is below min {lo}")
        if hi is not None and d > hi:
            out.append(f"{where}: default {d} is above max {hi}")
    return out


def profile_to_yaml(p: DeviceProfile) -> str:
    """The profile in its authoring format (used to save imported profiles)."""
    data = p.model_dump(mode="json", exclude_defaults=True)
    # A quirk's value is always written: exclude_defaults compares with ==, and 1 == True,
    # so a quirk of value 1 (HIWIN's pdo_assign_max_per_sm) lost its value and read back as
    # True (found by the quirk registry's shape check, domain/quirks.py).
    if p.quirks:
        data["quirks"] = [
            {"id": q.id, "value": q.model_dump(mode="json")["value"]}
            | {k: v for k, v in (("section", q.section), ("note", q.note)) if v is not None}
            for q in p.quirks
        ]
    data = {"schema_version": 1, **data}
    return str(yaml.safe_dump(data, sort_keys=False, allow_unicode=True, width=100))


def save_profile(p: DeviceProfile, directory: Path, *, overwrite: bool = False) -> Path:
    """Write ``directory/<id>/profile.yaml`` atomically; an existing one is kept unless asked."""
    # The id names the folder: checked, and the folder confirmed inside ``directory``.
    folder = files.inside(directory, check_id(p.id, "profile id"))
    target = folder / PROFILE_FILE
    if target.exists() and not overwrite:
        raise ProfileError(
            f"a profile {p.id!r} already exists",
            path=str(target),
            hint="choose another profile id",
        )
    folder.mkdir(parents=True, exist_ok=True)
    files.remove_stale_temp_files(folder)
    files.write_atomic(target, profile_to_yaml(p).encode("utf-8"))  # Never half-written.
    return target


class ProfileCatalog:
    """All profiles found on the search path, loaded lazily and cached by id."""

    def __init__(self, dirs: Sequence[Path] | None = None) -> None:
        self.dirs = list(dirs) if dirs is not None else default_profile_dirs()
        self._paths: dict[str, Path] | None = None
        self._cache: dict[str, DeviceProfile] = {}
        self._extra: dict[str, DeviceProfile] = {}

    def _index(self) -> dict[str, Path]:
        if self._paths is None:
            paths: dict[str, Path] = {}
            for d in self.dirs:
                if not d.is_dir():
                    continue
                for f in sorted(d.glob(f"*/{PROFILE_FILE}")):
                    paths.setdefault(f.parent.name, f)
            self._paths = paths
        return self._paths

    def ids(self) -> list[str]:
        return sorted(set(self._index()) | set(self._extra))

    def add(self, profile: DeviceProfile) -> None:
        """Register a profile made at run time (e.g. imported from an EDS)."""
        self._extra[profile.id] = profile
        self._cache.pop(profile.id, None)

    def refresh(self) -> None:
        """Look at the directories again (after a profile was saved into one)."""
        self._paths = None

    def get(self, profile_id: str) -> DeviceProfile:
        if profile_id in self._cache:
            return self._cache[profile_id]
        if profile_id in self._extra:
            p = self._extra[profile_id]
        else:
            path = self._index().get(profile_id)
            if path is None:
                raise NotFoundError(
                    f"no profile {profile_id!r}",
                    hint=f"known profiles: {', '.join(self.ids()) or 'none'}",
                )
            p = read_profile_file(path)
            if p.id != profile_id:
                raise ProfileError(f"id {p.id!r} differs from its folder name", path=str(path))
        if p.extends:
            if p.extends == p.id:
                raise ProfileError(f"profile {p.id} extends itself")
            p = merge(self.get(p.extends), p)
        self._cache[profile_id] = p
        return p

    def all(self) -> list[DeviceProfile]:
        return [self.get(i) for i in self.ids()]

    def match(
        self,
        vendor_id: int | None,
        product_code: int | None,
        revision: int | None,
        device_name: str | None = None,
        *,
        fieldbus: str | None = None,
    ) -> DeviceProfile | None:
        """The profile whose identity matches 1018h (most specific first); with ``fieldbus``,
        only profiles of that fieldbus are candidates."""
        best: tuple[int, DeviceProfile] | None = None
        for p in self.all():
            if fieldbus is not None and p.fieldbus != fieldbus:
                continue
            if p.identity.matches(vendor_id, product_code, revision, device_name):
                # A revision range (one of several revisions of an ESI) is the most specific.
                score = (
                    (p.identity.vendor_id is not None)
                    + bool(p.identity.product_codes) * 2
                    + (p.identity.revision_min is not None or p.identity.revision_max is not None)
                    * 4
                )
                if best is None or score > best[0]:
                    best = (score, p)
        return best[1] if best else None

    def match_dcp(self, vendor_id: int | None, device_id: int | None) -> DeviceProfile | None:
        """The profile whose ``dcp`` quirk names this PROFINET vendor and device ID (what a
        DCP Identify answers, the GSDML file's IDs)."""
        if vendor_id is None or device_id is None:
            return None
        for p in self.all():
            q = p.quirk("dcp")
            if (
                isinstance(q, dict)
                and _int(q.get("vendor_id")) == vendor_id
                and _int(q.get("device_id")) == device_id
            ):
                return p
        return None

    def dcp_refusal_hint(
        self, vendor_id: int | None, device_id: int | None, block_error: int
    ) -> str | None:
        """What to do about a DCP BlockError the device answered, from the profile whose
        ``dcp`` quirk names its vendor and device ID (the quirk's ``refusals``, by code), as
        "<profile name>: <what to do>"; None where no profile says."""
        profile = self.match_dcp(vendor_id, device_id)
        quirk = profile.quirk("dcp") if profile is not None else None
        refusals = quirk.get("refusals") if isinstance(quirk, dict) else None
        if profile is None or not isinstance(refusals, dict):
            return None
        hint = refusals.get(block_error, refusals.get(str(block_error)))
        return f"{profile.name}: {hint}" if isinstance(hint, str) else None


def _int(v: object) -> int | None:
    if isinstance(v, bool):
        return None
    if isinstance(v, int):
        return v
    if isinstance(v, str):
        try:
            return int(v, 0)
        except ValueError:
            return None
    return None
