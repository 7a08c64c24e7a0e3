"""The quirk vocabulary is checked on both sides (issue 51 item 5, domain/quirks.py): a profile
naming a quirk servodesk does not know, or giving it a value of the wrong shape, is refused
at load with the closest id; code reading an id that is not registered fails; and the
registry's "read by" column is true of the code as it is."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import servodesk
from servodesk.domain.profile_loader import ProfileCatalog, check_profile, parse_profile
from servodesk.domain.quirks import QUIRKS, UnknownQuirk
from servodesk.errors import ProfileError

SRC = Path(servodesk.__file__).parent
#: How code reads a quirk by a literal id: ``profile.quirk("id")``, the tuning's
#: ``_quirk_dict(profile, "id")``, the parameter set's ``_quirk_addresses(profile, "id")``,
#: the session's ``_procedure("id", ...)``, the alarms' ``q.id == "id"``.
_READS = re.compile(
    r"""(?:\.quirk|_quirk_dict|_quirk_addresses|_procedure)\(\s*(?:profile,\s*)?"([a-z0-9_]+)"
      |q\.id\s*==\s*"([a-z0-9_]+)"
    """,
    re.VERBOSE,
)


def _code() -> dict[str, str]:
    return {
        ".".join(p.relative_to(SRC).with_suffix("").parts): p.read_text(encoding="utf-8")
        for p in SRC.rglob("*.py")
    }


def _base() -> dict[str, object]:
    return {"id": "x-drive", "name": "X", "vendor": "X", "fieldbus": "canopen"}


def test_a_misspelt_quirk_in_a_profile_is_refused_naming_the_right_one() -> None:
    with pytest.raises(
        ProfileError, match=r"'sm_watchdog_fualt'.*did you mean 'sm_watchdog_fault'"
    ):
        parse_profile({**_base(), "quirks": [{"id": "sm_watchdog_fualt", "value": "FF49h"}]})


def test_a_quirk_value_of_the_wrong_shape_is_refused() -> None:
    with pytest.raises(
        ProfileError, match=r"fault_reset_hold_ms.*'long' has the wrong shape \(expected int\)"
    ):
        parse_profile({**_base(), "quirks": [{"id": "fault_reset_hold_ms", "value": "long"}]})
    # A float where an integer count of milliseconds is meant: refused too.
    with pytest.raises(ProfileError, match="fault_reset_hold_ms"):
        parse_profile({**_base(), "quirks": [{"id": "fault_reset_hold_ms", "value": 2.5}]})
    # bool is not an int here, though Python says it is.
    with pytest.raises(ProfileError, match="pdo_state_abort"):
        parse_profile({**_base(), "quirks": [{"id": "pdo_state_abort", "value": True}]})


def test_a_quirk_given_twice_is_refused() -> None:
    q = {"id": "no_quick_stop", "value": True}
    with pytest.raises(ProfileError, match="more than once"):
        parse_profile({**_base(), "quirks": [q, q]})


def test_code_asking_for_an_unregistered_quirk_fails() -> None:
    p = ProfileCatalog().get("hiwin-e")
    assert p.quirk("sm_watchdog_fault") is not None
    with pytest.raises(UnknownQuirk, match="did you mean 'sm_watchdog_fault'"):
        p.quirk("sm_watchdog_fualt")


def test_every_shipped_profile_names_only_known_quirks_of_the_right_shape() -> None:
    catalog = ProfileCatalog()
    for pid in catalog.ids():
        p = catalog.get(pid)
        assert not [x for x in check_profile(p) if x.startswith("quirk")], pid


def test_every_quirk_the_code_reads_is_registered_and_every_reader_reads_it() -> None:
    code = _code()
    read: dict[str, set[str]] = {}
    for module, text in code.items():
        for m in _READS.finditer(text):
            read.setdefault(m.group(1) or m.group(2), set()).add(module)
    assert set(read) - set(QUIRKS) == set(), "code reads quirks the registry does not know"
    assert len(read) >= 30  # the pattern still finds the reads (it found 35 when written)
    for quirk_id, entry in QUIRKS.items():
        for module in entry.read_by:
            assert module in code, f"{quirk_id}: reader {module} does not exist"
            assert f'"{quirk_id}"' in code[module], f"{quirk_id}: {module} no longer reads it"
    # A read the pattern sees in a module the registry does not name is a reader left out.
    for quirk_id, modules in read.items():
        missing = modules - set(QUIRKS[quirk_id].read_by)
        assert not missing, f"{quirk_id}: read by {sorted(missing)}, not in its read_by"
