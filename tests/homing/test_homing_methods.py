"""Every documented homing method of every family ends where its manual says.

The simulated axis has the default switch layout of sim/homing.py, in revolutions: negative
limit switch at -1.7, home switch (dog) from 1.3 to 1.7, positive limit switch at 3.7, an index
pulse at every whole revolution. The expected end points below are read off the method
descriptions (CiA 402-2 §6.8.1; 000 §3.2.4 table 3.2.4.4; 003 §4-4-7; 004 §20.6.6(4)), not
computed by the simulation's code.
"""

from __future__ import annotations

import pytest

from servodesk.domain.homing import CIA402_METHODS, resolve_method
from servodesk.sim.engine import SimAbort

from .support import CATALOG, FAMILIES, SW_ATTAINED, SW_ERROR, SW_REACHED, run_homing, start_homing

#: Standard methods: start position and where the axis ends (revolutions).
#: 1: first index right of where the negative limit switch turns off (-1.7) -> -1.
#: 2: first index left of the positive limit switch (3.7) -> 3.
#: 3/4: positive home switch (lower dog edge 1.3): index left (1) / right (2) of it.
#: 5/6: negative home switch (upper dog edge 1.7), started right of it: index right (2) / left (1).
#: 7/8: lower edge, index left (1) / right (2); 9/10: upper edge, index left (1) / right (2).
#: 11/12: upper edge, index right (2) / left (1); 13/14: lower edge, right (2) / left (1);
#:        11-14 start negative, reverse at the negative limit switch.
#: 17-30: as 1-14 without index: the edge itself. 33/34: the next index below / above 0.
#: 35/37: the current position.
EXPECTED: dict[int, tuple[float, float]] = {
    1: (0, -1), 2: (0, 3), 3: (0, 1), 4: (0, 2), 5: (2.5, 2), 6: (2.5, 1),
    7: (0, 1), 8: (0, 2), 9: (0, 1), 10: (0, 2), 11: (0, 2), 12: (0, 1), 13: (0, 2), 14: (0, 1),
    17: (0, -1.7), 18: (0, 3.7), 19: (0, 1.3), 20: (0, 1.3), 21: (2.5, 1.7), 22: (2.5, 1.7),
    23: (0, 1.3), 24: (0, 1.3), 25: (0, 1.7), 26: (0, 1.7), 27: (0, 1.7), 28: (0, 1.7),
    29: (0, 1.3), 30: (0, 1.3), 33: (0.5, 0), 34: (0.5, 1), 35: (0.25, 0.25), 37: (0.25, 0.25),
}  # fmt: skip

#: Vendor methods, from the manuals' own descriptions (Fwd starts at 0, Rev at 2.5).
VENDOR_EXPECTED: dict[str, dict[int, tuple[float, float]]] = {
    # 000 §3.2.4: -3 "set current position": the current position becomes home.
    "hiwin-e": {-3: (0.25, 0.25)},
    # 004 §20.6.6(4), dog = home switch 1.3-1.7, Z phase = index pulse:
    "lecsn-t": {
        -1: (0, 2),  # dog type: first Z after the dog rear end (1.7, forward)
        -33: (2.5, 1),  # reverse: rear end is 1.3, first Z below it
        -2: (0, 2),  # count type: front end (1.3) + travel (0), then the first Z
        -34: (2.5, 1),
        -3: (0.25, 0.25),  # data set type: current position
        -6: (0, 1.7),  # dog rear-end reference
        -38: (2.5, 1.3),
        -7: (0, 1.3),  # count type front-end reference
        -39: (2.5, 1.7),
        -8: (0, 2),  # dog cradle: first Z after the front end
        -40: (2.5, 1),
        -9: (0, 1),  # last Z: back off past the dog (below 1.3), first Z
        -41: (2.5, 2),
        -10: (0, 1.3),  # dog front-end reference
        -42: (2.5, 1.7),
        -11: (0, 1),  # dogless: first Z
        -43: (2.5, 2),
    },
}


def _cases() -> list[tuple[str, int]]:
    out = []
    for fam in FAMILIES:
        for m in CATALOG.get(fam).homing_methods:
            out.append((fam, m))
    return out


CASES = _cases()


def _expected(family: str, method: int) -> tuple[float, float] | None:
    if method > 0:
        return EXPECTED[method]
    return VENDOR_EXPECTED.get(family, {}).get(method)


def test_every_family_method_is_covered() -> None:
    counts = {fam: len(CATALOG.get(fam).homing_methods) for fam in FAMILIES}
    assert counts == {
        "cia402-generic": 2,
        "hiwin-e": 24,
        "ctmm04x": 11,
        "lecsn-t": 39,
        "smartris": 0,
    }
    missing = [(f, m) for f, m in CASES if _expected(f, m) is None]
    # LECSN-T -4/-36 (stopper type) need a mechanical stopper: documented, not simulated.
    assert missing == [("lecsn-t", -4), ("lecsn-t", -36)]


@pytest.mark.parametrize(("family", "method"), [c for c in CASES if _expected(*c) is not None])
def test_method_ends_where_the_manual_says(family: str, method: int) -> None:
    profile = CATALOG.get(family)
    exp = _expected(family, method)
    assert exp is not None
    start, end = exp
    rev = profile.simulation.counts_per_rev
    d = start_homing(profile, method, start)
    run_homing(d)
    sw = d.statusword
    assert sw & (SW_ATTAINED | SW_ERROR | SW_REACHED) == SW_ATTAINED | SW_REACHED
    d.step(0.2)  # Settle.
    raw = d.plant.encoder_counts
    assert raw / rev == pytest.approx(end, abs=0.002)
    # 000 §3.2.4 / 003 §4-4-7: at the home position 6064h = 607Ch.
    assert d.read(0x6064, 0) == pytest.approx(d.read(0x607C, 0), abs=0.002 * rev)


def test_method_not_in_the_table_is_refused_by_6098h() -> None:
    # A standard method the family does not document (hiwin-e has no 3-6, 000 §3.2.4).
    d = start_homing(CATALOG.get("ctmm04x"), 35, 0)
    for fam, m in (("hiwin-e", 3), ("ctmm04x", 23), ("cia402-generic", 1), ("lecsn-t", -4)):
        drive = start_homing(CATALOG.get(fam), CATALOG.get(fam).homing_methods[0], 0)
        with pytest.raises(SimAbort) as exc:
            drive.write(0x6098, 0, m)
        assert exc.value.code == 0x06090030
    assert d.read(0x6098, 0) == 35


def test_descriptions_cover_every_standard_method() -> None:
    for n, info in CIA402_METHODS.items():
        assert info.description and info.section.startswith("CiA 402-2")
        if 1 <= n <= 30:
            assert ("index" in info.uses) == (n <= 14)
    lecsn = CATALOG.get("lecsn-t")
    info = resolve_method(-9, lecsn.quirk("homing_method_equivalent"))
    assert info is not None and info.equivalent == 7 and info.vendor
