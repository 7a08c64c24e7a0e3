"""Facts from the HIWIN E1/E2 EtherCAT manuals (000 JP V1.7, 002 CN V1.6) checked in hiwin-e.

Each assertion names the manual section it comes from, so a failing test points at the page
to re-read. The profile is loaded from the checkout's profiles/ folder, exactly as the
catalog loads it for a session or the simulated twin.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.domain.profile_loader import ProfileCatalog, check_profile

PROFILES = Path(__file__).resolve().parents[2] / "profiles"


@pytest.fixture(scope="module")
def hiwin() -> DeviceProfile:
    return ProfileCatalog([PROFILES]).get("hiwin-e")


def spec(p: DeviceProfile, index: int, sub: int = 0) -> ObjectSpec:
    s = p.spec(ObjectAddress(index, sub))
    assert s is not None, f"0x{index:04X}:{sub:02X} missing from hiwin-e"
    return s


def test_profile_is_consistent(hiwin: DeviceProfile) -> None:
    assert check_profile(hiwin) == []
    assert hiwin.fieldbus == "ethercat"
    assert [m.id for m in hiwin.manuals] == ["000", "002"]


def test_identity(hiwin: DeviceProfile) -> None:
    # 000 §3.1 (1018h): vendor ID 0xAAAA, product code 0x05 for the E series.
    assert hiwin.identity.vendor_id == 0xAAAA
    assert hiwin.identity.product_codes == (0x05,)
    assert spec(hiwin, 0x1018, 1).default_value() == 0xAAAA
    assert spec(hiwin, 0x1018, 2).default_value() == 0x05
    # 000 §3.1 (1000h): device type 0x00020192.
    dt = spec(hiwin, 0x1000)
    assert (dt.data_type.name, dt.access.value) == ("UNSIGNED32", "ro")
    assert dt.default_value() == 0x00020192
    assert ProfileCatalog([PROFILES]).match(0xAAAA, 0x05, None) is not None


# (index, sub, data type, access, PDO direction, min, max, unit) as printed in the tables.
OBJECT_FACTS = [
    # 000 §3.2 Table 3.2.1 and §3.4.
    (0x6040, 0, "UNSIGNED16", "rw", "rx", None, None, None),
    (0x6041, 0, "UNSIGNED16", "ro", "tx", None, None, None),
    (0x6061, 0, "INTEGER8", "ro", "tx", -2, 10, None),
    (0x6063, 0, "INTEGER32", "ro", "tx", None, None, "count"),
    (0x6064, 0, "INTEGER32", "ro", "tx", None, None, "inc"),
    (0x6066, 0, "UNSIGNED16", "rw", "rx", None, None, "ms"),
    (0x606C, 0, "INTEGER32", "ro", "tx", None, None, "inc/s"),
    # 000 §3.2: the velocity window is only 16 bits wide.
    (0x606D, 0, "UNSIGNED16", "rw", "rx", None, None, "inc/s"),
    (0x6071, 0, "INTEGER16", "rw", "rx", None, None, "%"),
    (0x6072, 0, "UNSIGNED16", "rw", "rx", None, None, "%"),
    (0x6075, 0, "UNSIGNED32", "ro", "none", None, None, "mA"),
    (0x6076, 0, "UNSIGNED32", "ro", "none", None, None, "mNm"),
    (0x607A, 0, "INTEGER32", "rw", "rx", None, None, "inc"),
    (0x607C, 0, "INTEGER32", "rw", "rx", None, None, "inc"),
    (0x6081, 0, "UNSIGNED32", "rw", "rx", None, None, "inc/s"),
    (0x6085, 0, "UNSIGNED32", "rw", "rx", None, None, "inc/s²"),
    (0x6087, 0, "UNSIGNED32", "rw", "rx", None, None, "%/s"),
    (0x6098, 0, "INTEGER8", "rw", "rx", None, None, None),
    (0x6099, 2, "UNSIGNED32", "rw", "rx", None, None, "inc/s"),
    (0x60FD, 0, "UNSIGNED32", "ro", "tx", None, None, None),
    (0x60FE, 1, "UNSIGNED32", "rw", "rx", None, None, None),
    # 000 §3.2 / §3.2.10: 607B:01h 0 or below, 607B:02h 0 or above.
    (0x607B, 1, "INTEGER32", "rw", "rx", -2147483648, 0, "inc"),
    (0x607B, 2, "INTEGER32", "rw", "rx", 0, 2147483647, "inc"),
    # 000 §3.2: 60C2:02h range -128 ~ 63; 60F2h 0x0 ~ 0x00C0.
    (0x60C2, 2, "INTEGER8", "rw", "none", -128, 63, None),
    (0x60F2, 0, "UNSIGNED16", "rw", "rx", 0, 0xC0, None),
    # 000 §3.1: store/restore, sync error limit 0 ~ 15, PDO assignment.
    (0x1010, 1, "UNSIGNED32", "rw", "none", None, None, None),
    (0x1011, 1, "UNSIGNED32", "rw", "none", None, None, None),
    (0x10F1, 2, "UNSIGNED16", "rw", "none", 0, 15, None),
    (0x1C12, 0, "UNSIGNED8", "rw", "none", 0, 1, None),
    (0x1C12, 1, "UNSIGNED16", "rw", "none", 0x1600, 0x1603, None),
    (0x1C13, 1, "UNSIGNED16", "rw", "none", 0x1A00, 0x1A03, None),
    (0x1C32, 2, "UNSIGNED32", "ro", "none", 250000, 4000000, "µs"),
    # 000 §3.3: analog input in mV (shown in V), gantry index 0x2000 ~ 0x4FFF.
    (0x3063, 0, "INTEGER16", "ro", "tx", -10000, 10000, "V"),
    (0x3080, 0, "UNSIGNED16", "rw", "none", 0x2000, 0x4FFF, None),
    (0x3120, 0, "UNSIGNED32", "ro", "none", None, None, None),
    (0x3200, 0, "INTEGER32", "rw", "both", 0, 1, None),
]


@pytest.mark.parametrize(
    ("index", "sub", "dtype", "access", "pdo", "lo", "hi", "unit"),
    OBJECT_FACTS,
    ids=[f"{f[0]:04X}:{f[1]:02X}" for f in OBJECT_FACTS],
)
def test_object_tables(
    hiwin: DeviceProfile,
    index: int,
    sub: int,
    dtype: str,
    access: str,
    pdo: str,
    lo: int | None,
    hi: int | None,
    unit: str | None,
) -> None:
    s = spec(hiwin, index, sub)
    assert s.data_type.name == dtype
    assert s.access.value == access
    assert s.pdo_mapping.value == pdo
    got_lo, got_hi = s.limits()
    if lo is not None:
        assert got_lo == lo
    if hi is not None:
        assert got_hi == hi
    assert s.unit == unit
    assert s.section and s.section.startswith("000 §")


def test_torque_is_in_tenths_of_a_percent(hiwin: DeviceProfile) -> None:
    # 000 §3.2: 6071h/6072h/6077h unit "0.1%" of rated torque.
    for index in (0x6071, 0x6072, 0x6077):
        s = spec(hiwin, index)
        assert (s.scale, s.raw_unit) == (0.1, "0.1 %")


def test_documented_defaults_and_constants(hiwin: DeviceProfile) -> None:
    # 000 §3.2 (6060h): default 0 = no mode change.
    assert spec(hiwin, 0x6060).default_value() == 0
    # 000 §3.2: only option 2 (605Ah) and 0 (605Bh, 605Ch) are supported.
    assert spec(hiwin, 0x605A).limits() == (2, 2)
    assert spec(hiwin, 0x605B).limits() == (0, 0)
    assert spec(hiwin, 0x605C).limits() == (0, 0)
    # 000 §3.1 (1C32h): minimum cycle time 187500 ns, calc and copy 31250 ns, types 5.
    assert spec(hiwin, 0x1C32, 5).default_value() == 187500
    assert spec(hiwin, 0x1C32, 6).default_value() == 31250
    assert spec(hiwin, 0x1C32, 4).default_value() == 5
    # 000 §3.1 (1C00h): SM0..SM3 communication types 1, 2, 3, 4.
    assert [spec(hiwin, 0x1C00, n).default_value() for n in range(1, 5)] == [1, 2, 3, 4]
    # 000 §3.2 (6502h): pp, pv, tq, hm, csp, csv, cst -> 0x000003AD.
    assert spec(hiwin, 0x6502).default_value() == 0x000003AD


def test_supported_drive_modes_match_modes(hiwin: DeviceProfile) -> None:
    # 000 §3.2 (6060h table): -2 fc, 1 pp, 3 pv, 4 tq, 6 hm, 8 csp, 9 csv, 10 cst.
    assert set(hiwin.modes) == {-2, 1, 3, 4, 6, 8, 9, 10}
    # 000 §3.2 (6502h): every CiA 402 mode in `modes` has its bit; fc (-2) has none.
    bits = spec(hiwin, 0x6502).default_value()
    assert isinstance(bits, int)
    for mode in hiwin.modes:
        if mode > 0:
            assert bits >> (mode - 1) & 1, f"6502h lacks mode {mode}"


def test_homing_methods(hiwin: DeviceProfile) -> None:
    # 000 §3.2 (6098h), Table 3.2.4.4: -3, 1, 2, 7~14, 17, 18, 23~30, 33, 34, 37.
    expected = [-3, 1, 2, *range(7, 15), 17, 18, *range(23, 31), 33, 34, 37]
    assert sorted(hiwin.homing_methods) == sorted(expected)
    assert 35 not in hiwin.homing_methods  # Not in the HIWIN list.
    values = spec(hiwin, 0x6098).values or {}
    assert sorted(values) == sorted(expected)


def test_error_codes(hiwin: DeviceProfile) -> None:
    # 000 §3.2 Table 3.2.1: 603Fh = FF**h; FF10h -> error 16 -> AL.320 regenerative overload.
    e = hiwin.error("error_code", 0xFF10)
    assert e is not None and e.name == "Regenerative overload"
    assert e.extra["alarm"] == "AL.320" and e.clear == "reset"
    first = hiwin.error("error_code", 0xFF04)
    last = hiwin.error("error_code", 0xFF50)
    assert first is not None and first.extra["alarm"] == "AL.024"
    assert last is not None and last.extra["alarm"] == "AL.EF9"
    # 002 §3.2: the V1.6 name of FF4Ah is the gantry communication error.
    fc0 = hiwin.error("error_code", 0xFF4A)
    assert fc0 is not None and fc0.name_local == "龍門系統通訊錯誤"
    # The table has 59 alarms (unused numbers such as FF08h are not listed).
    faults = [x for x in hiwin.errors if x.table == "error_code" and x.code != 0]
    assert len(faults) == 59
    assert hiwin.error("error_code", 0xFF08) is None
    assert all(x.code >> 8 == 0xFF for x in faults)


def test_alarm_numbers_and_warnings(hiwin: DeviceProfile) -> None:
    # 000 §3.2 Table 3.2.1: AL.7A1 drive overload <-> 603Fh FF1Dh.
    al = hiwin.error("alarm", 0x7A1)
    assert al is not None and al.display == "AL.7A1" and al.extra["error_code"] == "FF1Dh"
    # 000 §3.3.2: AL.980 is a warning; its causes are the bits of 3120h.
    w = hiwin.error("alarm", 0x980)
    assert w is not None and w.kind == "warning" and w.cause and "607B:01h > 0" in w.cause
    # 000 §3.3 (3111h bit 1): AL.943 fieldbus sync cycle time warning.
    sync = hiwin.error("alarm", 0x943)
    assert sync is not None and sync.kind == "warning"


def test_al_status_and_sdo_abort_codes(hiwin: DeviceProfile) -> None:
    # 000 §2.10 Table 2.10.1: 0x001A synchronization error -> SafeOp + error, single flash.
    al = hiwin.error("al_status", 0x001A)
    assert al is not None and al.name == "Synchronization error"
    assert al.extra["err_led"] == "Single flash"
    assert hiwin.error("al_status", 0x8000) is not None
    # 000 §2.6 Table 2.6.1: five abort codes; 06010002h also answers mapping writes in SafeOp/Op.
    aborts = {x.code for x in hiwin.errors if x.table == "sdo_abort"}
    assert aborts == {0x06010000, 0x06010002, 0x06020000, 0x06040042, 0x06090030}
    ro = hiwin.error("sdo_abort", 0x06010002)
    assert ro is not None and ro.cause and "SafeOp" in ro.cause


def test_pdo_rules(hiwin: DeviceProfile) -> None:
    # 000 §3.1 (1600h..:00 range 0 ~ 8), §2.2 (40 bytes), §2.8.1/§3.1.2 (only in PreOp).
    assert hiwin.pdo.max_entries == 8
    assert hiwin.pdo.max_bits == 40 * 8
    assert hiwin.pdo.mapping_state == "preop"
    assert hiwin.quirk("pdo_mapping_requires_state") == "preop"
    # 000 §2.8.2: one mapping object per sync manager.
    assert hiwin.quirk("pdo_assign_max_per_sm") == 1
    for index in (0x1600, 0x1603, 0x1A00, 0x1A03, 0x1C12, 0x1C13):
        assert spec(hiwin, index, 0).writable_in == ("preop",)
        assert spec(hiwin, index, 1).writable_in == ("preop",)
        assert spec(hiwin, index, 0).max == (1 if index >= 0x1C00 else 8)


def _default_mapping(p: DeviceProfile, index: int) -> list[int]:
    count = spec(p, index, 0).default_value()
    assert isinstance(count, int)
    out = []
    for n in range(1, count + 1):
        v = spec(p, index, n).default_value()
        assert isinstance(v, int)
        out.append(v)
    return out


def test_default_mappings(hiwin: DeviceProfile) -> None:
    # 000 §3.1.1 Table 3.1.1.1 (V1.7): 1600h = 6040h, 6060h, 607Ah, 60B8h, 60FE:01h.
    assert _default_mapping(hiwin, 0x1600) == [
        0x60400010,
        0x60600008,
        0x607A0020,
        0x60B80010,
        0x60FE0120,
    ]
    # 000 §3.1.1 Table 3.1.1.4: 1A03h has no 603Fh and ends with 60FDh.
    tx4 = _default_mapping(hiwin, 0x1A03)
    assert len(tx4) == 8 and 0x603F0010 not in tx4 and tx4[-1] == 0x60FD0020
    # Each default mapping must be one the drive accepts: mappable objects of the right
    # direction, matching sizes, no duplicates, within 8 entries and 40 bytes (§2.8.1, §3.1).
    for base, rx in ((0x1600, True), (0x1A00, False)):
        for index in range(base, base + 4):
            entries = _default_mapping(hiwin, index)
            assert len(entries) <= hiwin.pdo.max_entries
            assert len(set(entries)) == len(entries)
            assert sum(e & 0xFF for e in entries) <= hiwin.pdo.max_bits
            for e in entries:
                s = spec(hiwin, e >> 16, (e >> 8) & 0xFF)
                assert s.bits == e & 0xFF
                assert s.pdo_mapping.rx if rx else s.pdo_mapping.tx


def test_default_assignment_points_at_a_mapping_object(hiwin: DeviceProfile) -> None:
    # 000 §2.8.2 / Fig. 2.8.2.1: 1C12h -> 1600h (the manual gives no other default).
    assert spec(hiwin, 0x1C12, 1).default_value() == 0x1600
    assert spec(hiwin, 0x1C13, 1).default_value() == 0x1A00


def test_touch_probe_and_modulo_objects(hiwin: DeviceProfile) -> None:
    # 000 §3.2.9 Table 3.2.9.1: 60B8h..60BCh; no TP2 negative edge (60BDh).
    for index in (0x60B8, 0x60B9, 0x60BA, 0x60BB, 0x60BC):
        assert spec(hiwin, index).group == "touch_probe"
    assert hiwin.spec(ObjectAddress(0x60BD, 0)) is None
    assert hiwin.quirk("touch_probe_exclusive") is True
    # 000 §3.2.10: modulo active when 607B:01h or :02h != 0.
    assert hiwin.quirk("modulo_position") is True
    assert spec(hiwin, 0x607B, 1).group == "modulo"
    # 000 §3.4: 607Dh software position limit is "Not support".
    assert hiwin.spec(ObjectAddress(0x607D, 0)) is None


def test_manufacturer_objects(hiwin: DeviceProfile) -> None:
    # 000 §3.3 (3000h): 0 linear, 1 DD/torque motor, 2 AC servo.
    assert spec(hiwin, 0x3000).values == {
        0: "Linear motor (LM)",
        1: "Direct drive / torque motor (DM/TM)",
        2: "AC servo motor (AC)",
    }
    # 000 §3.3.1 Table 3.3.1.1: 3200h reports 4 on success and 16 when the motor is enabled.
    values = spec(hiwin, 0x3200).values or {}
    assert {0, 1, 2, 4, 16, 32} == set(values)
    # 000 §3.3 (3217h): mastership cannot be changed while enabled.
    assert "operation_enabled" not in spec(hiwin, 0x3217).writable_in
    # 000 §3.3: index = 2000h + Pt number; 2316h is the csp velocity limit in rpm (§3.2.3).
    vlim = spec(hiwin, 0x2316)
    assert vlim.symbol == "Pt316" and vlim.unit == "rpm"


def test_contradictions_recorded(hiwin: DeviceProfile) -> None:
    topics = {c.topic: c for c in hiwin.contradictions}
    # 000 §3.1 (0 ~ 8 entries) against 000 §2.2 / 002 §3.1 (10 entries).
    c = topics["Maximum entries per PDO mapping object"]
    assert c.chosen.startswith("8") and "000 §2.2" in c.other_section
    # 000 §3.2 (60B2h -3000 ~ 3000) against §3.2.8 / §3.4 (-32768 ~ 32767).
    c = topics["Torque offset 60B2h range"]
    assert spec(hiwin, 0x60B2).limits() == (-3000, 3000)
    assert "-32768" in c.other
    # 000 §3.3 (3215h -1 ~ 2) against 000 §3.4 (0 ~ 1).
    assert spec(hiwin, 0x3215).limits() == (-1, 2)
    assert "Reset drive 3215h range" in topics
    # 002 (V1.6) 1600h default has 6072h; V1.7 dropped it.
    assert "6072h" in topics["Default RxPDO mapping 1600h"].other
    for c in hiwin.contradictions:
        assert c.chosen_section and c.other_section


def test_every_object_cites_a_source_and_a_group(hiwin: DeviceProfile) -> None:
    groups = {g.id for g in hiwin.groups}
    for s in hiwin.variables.values():
        assert s.section and s.section.startswith(("000 §", "CiA 301", "CiA 402")), s
        assert s.group in groups, s
