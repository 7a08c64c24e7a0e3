"""Facts from the smartris CANopen manual (001) checked in the smartris profile.

Each fact names the manual section it comes from, so a failing test points at the page to
re-read. The profile is loaded from the checkout's profiles/ folder, the way the catalog loads
it for a session or the simulated twin.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile import DeviceProfile, ObjectSpec
from servodesk.domain.profile_loader import ProfileCatalog, check_profile

PROFILES = Path(__file__).resolve().parents[2] / "profiles"
OE_QSA = ("operation_enabled", "quick_stop_active")


@pytest.fixture(scope="module")
def smartris() -> DeviceProfile:
    return ProfileCatalog([PROFILES]).get("smartris")


def spec(p: DeviceProfile, index: int, sub: int = 0) -> ObjectSpec:
    s = p.spec(ObjectAddress(index, sub))
    assert s is not None, f"0x{index:04X}:{sub:02X} missing from smartris"
    return s


def test_profile_is_consistent(smartris: DeviceProfile) -> None:
    assert check_profile(smartris) == []
    assert smartris.fieldbus == "canopen"
    assert [m.id for m in smartris.manuals] == ["001"]
    assert all(s.section and s.section.startswith("001") for s in smartris.variables.values())


def test_identity_and_device_type(smartris: DeviceProfile) -> None:
    # 001 §5-1 (1018h), Table 2-46: vendor ID 0x000001FB; product code, revision, serial are 0.
    assert smartris.identity.vendor_id == 0x1FB
    assert spec(smartris, 0x1018, 1).default_value() == 0x1FB
    assert spec(smartris, 0x1018, 2).default_value() == 0
    matched = ProfileCatalog([PROFILES]).match(0x1FB, 0, 0)
    assert matched is not None and matched.id == "smartris"
    # 001 §5-1 (1000h): device type 0xFF7A0192 (low word 402, non-standard high word), also a quirk.
    assert spec(smartris, 0x1000).default_value() == 0xFF7A0192
    assert smartris.quirk("device_type") == 0xFF7A0192
    # 001 §5-1 (1008h): the device name is the string "SMA".
    assert spec(smartris, 0x1008).default_value() == "SMA"


# (index, sub, data type, access, PDO direction, default, min, max) as the manual documents them.
OBJECT_FACTS = [
    # 001 §5-1: heartbeat on by default, 200 ms.
    (0x1017, 0, "UNSIGNED16", "rw", "none", 200, 0, 65535),
    # 001 §5-1: guard time 0 = node guarding off.
    (0x100C, 0, "UNSIGNED16", "rw", "none", 0, 0, 65535),
    # 001 §5-1 / §2-10: COB-ID SYNC 0x80.
    (0x1005, 0, "UNSIGNED32", "rw", "none", 0x80, None, None),
    # 001 §8-3: 1003h:00 is 1 byte (upload answers 0x4F), written with 0 to clear; up to 15 entries.
    (0x1003, 0, "UNSIGNED8", "rw", "none", 0, 0, 15),
    # 001 §5-2: node ID 1..127, default 1.
    (0x2000, 0, "UNSIGNED8", "rw", "none", 1, 1, 127),
    # 001 §5-2: bit rate in kbit/s, default 0x03E8 = 1000 kbit/s.
    (0x2001, 0, "UNSIGNED16", "rw", "none", 0x03E8, 10, 1000),
    # 001 §5-3: warning word, UNSIGNED32, mappable.
    (0x2003, 0, "UNSIGNED32", "ro", "tx", 0, None, None),
    # 001 §5-3: motor temperature, -400..1300 in 0.1 °C, mappable.
    (0x2031, 0, "INTEGER16", "ro", "tx", 0, -400, 1300),
    # 001 §5-2: motor brake delay 20 x 10 ms, range 1..32767.
    (0x3002, 2, "INTEGER16", "rw", "none", 20, 1, 32767),
    # 001 §5-2: dynamic brake decrement step ramp 45 (x 100 rpm/s), range 1..8191.
    (0x3007, 4, "INTEGER16", "rw", "none", 45, 1, 8191),
    # 001 §5-3: feedback resolution 0x4000 = 16384 inc/rev.
    (0x3004, 2, "INTEGER16", "ro", "none", 0x4000, 0, 32767),
    # 001 §5-3: CAN error sensitivity default 1 (low), passive timeout 100 x 10 ms.
    (0x4102, 1, "INTEGER16", "rw", "none", 1, 0, 1),
    (0x4102, 2, "INTEGER16", "rw", "none", 100, 0, 32767),
    # 001 §5-4: controlword / statusword, mapped by default.
    (0x6040, 0, "UNSIGNED16", "rw", "rx", 0, None, None),
    (0x6041, 0, "UNSIGNED16", "ro", "tx", 0, None, None),
    # 001 §5-4: modes of operation, INTEGER8, default 0, RPDO1.
    (0x6060, 0, "INTEGER8", "rw", "rx", 0, -3, 10),
    # 001 §6-4: target velocity INTEGER32 ±2147483647.
    (0x60FF, 0, "INTEGER32", "rw", "rx", 0, -2147483647, 2147483647),
    # 001 §11-1: factory defaults in inc units of the dependent velocity objects.
    (0x606D, 0, "UNSIGNED16", "rw", "none", 13653, 1, 65535),
    (0x606F, 0, "UNSIGNED16", "rw", "none", 1365, 0, 65535),
    (0x6083, 0, "UNSIGNED32", "rw", "none", 273066, 1, 2147483647),
    (0x60C5, 0, "UNSIGNED32", "rw", "none", 608393, 1, 2147483647),
    # 001 §6-6: torque slope default 1000, per mille of 6075h per second.
    (0x6087, 0, "UNSIGNED32", "rw", "none", 1000, 1, 2147483647),
    # 001 §6-6 (Ch7, Table 6-4 for the access): torque limits 0..100 % of peak, default 100.
    (0x60E0, 0, "UNSIGNED16", "rw", "none", 100, 0, 100),
    # 001 §3-1: velocity factor numerator default 1, 1..2147483647.
    (0x6096, 1, "UNSIGNED32", "rw", "none", 1, 1, 2147483647),
    # 001 §5-4: polarity 0..192, default 0.
    (0x607E, 0, "UNSIGNED8", "rw", "none", 0, 0, 192),
    # 001 §5-3: motor type 0x000A (sinusoidal PM brushless).
    (0x6402, 0, "UNSIGNED16", "rw", "none", 0x000A, 0, 0xFFFF),
]


@pytest.mark.parametrize(("index", "sub", "dt", "acc", "pdo", "default", "lo", "hi"), OBJECT_FACTS)
def test_object_facts(
    smartris: DeviceProfile,
    index: int,
    sub: int,
    dt: str,
    acc: str,
    pdo: str,
    default: int,
    lo: int | None,
    hi: int | None,
) -> None:
    s = spec(smartris, index, sub)
    assert (s.data_type.name, s.access.value, s.pdo_mapping.value) == (dt, acc, pdo)
    assert s.default_value(1) == default
    assert (s.min, s.max) == (lo, hi)


def test_default_pdo_configuration(smartris: DeviceProfile) -> None:
    # 001 §2-8 Tables 2-13..2-26: default mappings and transmission types.
    assert [spec(smartris, 0x1600, k).default_value() for k in range(4)] == [
        3,
        0x60400010,
        0x60600008,
        0x60FE0120,
    ]
    assert spec(smartris, 0x1601, 2).default_value() == 0x607A0020
    assert spec(smartris, 0x1A02, 2).default_value() == 0x606C0020
    assert spec(smartris, 0x1400, 1).default_value(5) == 0x205
    # TPDO1 event-driven 0xFF, TPDO2..4 RTR-only 0xFD, inhibit 5 x 100 µs.
    assert spec(smartris, 0x1800, 2).default_value() == 0xFF
    assert [spec(smartris, 0x1801 + n, 2).default_value() for n in range(3)] == [0xFD] * 3
    inhibit = spec(smartris, 0x1803, 3)
    assert inhibit.default_value() == 5 and inhibit.raw_unit == "100 µs"
    # 001 §10-4: 1803h:04 is answered with abort 0x06090011, so sub 4 is not in the dictionary.
    assert smartris.spec(ObjectAddress(0x1803, 4)) is None
    assert smartris.quirk("pdo_comm_param_no_sub4") is True
    # 001 §2-8: at most 8 entries / 64 bits per PDO, remapping in Pre-operational.
    assert (smartris.pdo.max_entries, smartris.pdo.max_bits, smartris.pdo.mapping_state) == (
        8,
        64,
        "preop",
    )
    assert spec(smartris, 0x1400, 1).writable_in == ("preop",)


def test_mappable_objects(smartris: DeviceProfile) -> None:
    # 001 §5-3 / §5-4 / §6-4: objects marked mappable, and 60FDh (default TPDO1 map, §2-8).
    tx = {0x6041, 0x6061, 0x6064, 0x606C, 0x6077, 0x60FD, 0x2002, 0x2003, 0x2004, 0x2030, 0x2054}
    rx = {0x6040, 0x6060, 0x60FF, 0x6071, 0x607A}
    for i in tx:
        assert spec(smartris, i).pdo_mapping.tx, f"{i:04X}h"
    for i in rx:
        assert spec(smartris, i).pdo_mapping.rx, f"{i:04X}h"
    assert spec(smartris, 0x60FE, 1).pdo_mapping.value == "rx"
    # 001 §5-4 / §6-4: 603Fh, 6073h and 6075h are not mappable.
    for i in (0x603F, 0x6073, 0x6075):
        assert spec(smartris, i).pdo_mapping.value == "none"


def test_modes_pv_and_tq_only_and_no_homing(smartris: DeviceProfile) -> None:
    # 001 §6-1: only profile velocity (3) and profile torque (4) work; no homing (§6-2, §2-14).
    assert smartris.modes == (3, 4)
    assert smartris.homing_methods == ()
    assert smartris.spec(ObjectAddress(0x6098)) is None
    # 001 §5-3 (6502h): supported drive modes = pv + tq bits.
    assert spec(smartris, 0x6502).default_value() == 0x0C


def test_mode_change_refused_while_torque_is_produced(smartris: DeviceProfile) -> None:
    # 001 §5-4 (6060h): abort 0x060B0002 in Operation enabled / Quick stop active, EMCY 0x8C01.
    mode = spec(smartris, 0x6060)
    assert not set(OE_QSA) & set(mode.writable_in)
    assert "switched_on" in mode.writable_in and "switch_on_disabled" in mode.writable_in
    abort = smartris.error("sdo_abort", 0x060B0002)
    assert abort is not None and abort.extra.get("nonstandard")
    assert smartris.error("emcy", 0x8C01) is not None


def test_store_refused_in_operation_enabled_and_quick_stop(smartris: DeviceProfile) -> None:
    # 001 §5-1 (1010h), Table 2-49: no EEPROM store in Operation enabled or Quick stop active.
    assert tuple(smartris.quirk("store_refused_in_states")) == OE_QSA
    for sub in range(1, 5):
        s = spec(smartris, 0x1010, sub)
        assert not set(OE_QSA) & set(s.writable_in)
    # 001 §6-6: 60E0h/60E1h are RAM only, never stored.
    assert not spec(smartris, 0x60E0).persist and not spec(smartris, 0x60E1).persist
    # 001 §2-14: 1010h:04 stores 3200h/3201h gains; 1010h:03 stores 6075h.
    assert spec(smartris, 0x3200, 1).persist and spec(smartris, 0x6075).persist


EMCY_FACTS = [
    # (code, kind, LED green,yellow) - 001 §2-9 Tables 2-31..2-36.
    (0x2340, "fault", "3,1"),  # short circuit, motor side
    (0x2350, "fault", "5,2"),  # I²t overload
    (0x2351, "warning", None),  # I²t limit warning
    (0x3210, "fault", "4,2"),  # DC link overvoltage
    (0x3220, "fault", "4,1"),  # DC link undervoltage
    (0x4A00, "fault", "1,10"),  # motor temperature > 140 °C
    (0x7375, "fault", "2,10"),  # resolver hardware error
    (0x8121, "fault", "6,2"),  # CAN bus off
    (0x8130, "warning", None),  # heartbeat / life guarding
    (0x8412, "fault", "5,8"),  # overspeed
    (0x8B22, "fault", "8,2"),  # invalid stored 6073h at boot
    (0x8C01, "fault", "6,5"),  # 6060h written in Operation enabled
]


@pytest.mark.parametrize(("code", "kind", "led"), EMCY_FACTS)
def test_emcy_codes(smartris: DeviceProfile, code: int, kind: str, led: str | None) -> None:
    e = smartris.error("emcy", code)
    assert e is not None, f"EMCY 0x{code:04X} missing"
    assert e.kind == kind
    assert e.extra.get("led") == led
    assert e.section == "001 §2-9"


def test_emcy_table_details(smartris: DeviceProfile) -> None:
    # 001 §2-9 Table 2-32: EEPROM parameter errors 1..62 are 0x5532..0x556F.
    assert smartris.error("emcy", 0x556F) is not None and smartris.error("emcy", 0x5570) is None
    # 001 §10-3: an oversized RPDO1 gives EMCY 0x8220 with error register 0x11.
    e8220 = smartris.error("emcy", 0x8220)
    assert e8220 is not None and e8220.extra.get("error_register") == 0x11
    assert smartris.quirk("rpdo_dlc_mismatch_emcy") == 0x8220
    # 001 §2-9 Table 2-35 / §11-1: 0x8B19 = invalid stored 6096h after a unit change.
    e = smartris.error("emcy", 0x8B19)
    assert e is not None and e.extra.get("object") == "0x6096"
    # 001 Ch9 Table 9-2: LED green 6 / yellow 2 = CANopen communication error.
    led = smartris.error("led_blink", 602)
    assert led is not None and led.name == "CANopen"
    # 001 §5-3 (2003h): warning bit 20 = I²t lock-out, acknowledged with controlword bit 11.
    w = smartris.error("warning_bit", 20)
    assert w is not None and w.clear == "warning_ack"
    assert smartris.quirk("warning_ack_bit") == 11


def test_nonstandard_sdo_abort_codes(smartris: DeviceProfile) -> None:
    # 001 §2-7 Table 2-8 lists codes outside CiA 301; §5-2 uses 0x08000002.
    assert smartris.quirk("sdo_abort_nonstandard") is True
    for code in (0x06040030, 0x060A0000, 0x08000030, 0x08000002, 0x060B0002):
        e = smartris.error("sdo_abort", code)
        assert e is not None, f"abort 0x{code:08X}"
        assert e.extra.get("nonstandard")  # true (stored as 1: extra holds scalars)
    # 001 §8-3: reading an empty 1003h entry -> 0x08000024 (a standard code, documented usage).
    assert "1003h" in (smartris.error("sdo_abort", 0x08000024).cause or "")  # type: ignore[union-attr]


def test_quirks(smartris: DeviceProfile) -> None:
    # 001 §5-4 caution: controlword commands at least 40 ms apart.
    assert smartris.quirk("controlword_min_interval_ms") == 40
    # 001 §10-1: Quick stop active reads 0x1716 (bit 0 = 0, not the CiA pattern).
    assert smartris.quirk("quick_stop_statusword") == 0x1716
    # 001 §5-4 Table 5-2 note 1: fault reset (bit 7) not usable.
    assert smartris.quirk("no_fault_reset_bit7") is True
    # 001 §11-1: re-write 606Dh, 606Fh, 60C5h, 60C6h, 6083h, 6084h in this order after the factors.
    seq = [ObjectAddress.parse(a) for a in smartris.quirk("unit_change_sequence")]
    assert [(a.index, a.subindex) for a in seq[:4]] == [
        (0x6096, 1),
        (0x6096, 2),
        (0x6097, 1),
        (0x6097, 2),
    ]
    assert [a.index for a in seq[4:]] == [0x606D, 0x606F, 0x60C5, 0x60C6, 0x6083, 0x6084]
    for a in seq:
        assert smartris.spec(a) is not None
    # 001 §5-2: the tuning gains are 3200h/3201h subs 1-3, raw 0..32767, writable.
    gains = smartris.quirk("tuning_gains")
    kp = spec(smartris, *_addr(gains["velocity_kp"]))
    assert (kp.index, kp.subindex, kp.access.value) == (0x3201, 1, "rw")
    assert (kp.min, kp.max, kp.scale) == (0, 32767, 1.0)
    assert spec(smartris, 0x3201, 4).access.value == "ro"  # Kd reserved


def _addr(text: str) -> tuple[int, int]:
    a = ObjectAddress.parse(text)
    return a.index, a.subindex


def test_units_and_scaling(smartris: DeviceProfile) -> None:
    # 001 §6-6: target torque in per mille of 6075h (2000 mA of 12 500 mA -> 160 = 16.0 %).
    tq = spec(smartris, 0x6071)
    assert tq.data_type.name == "INTEGER16" and tq.pdo_mapping.value == "rx"
    assert tq.unit == "%" and tq.scale == pytest.approx(0.1)
    assert 160 * tq.scale == pytest.approx(16.0)
    # 001 §5-3: 2053h in rpm/4, 2041h in 0.01 V.
    assert spec(smartris, 0x2053).scale == pytest.approx(0.25)
    assert spec(smartris, 0x2041).scale == pytest.approx(0.01)
    # 001 §3-1: 16384 inc/rev, so 60FFh at factor 1/1 is inc/s: 163 840 inc/s = 600 rpm.
    assert 163840 * spec(smartris, 0x60FF).scale == pytest.approx(600.0)
    assert smartris.simulation.counts_per_rev == 16384


def test_contradictions_are_recorded(smartris: DeviceProfile) -> None:
    topics = {c.topic: c for c in smartris.contradictions}
    # 001 §5-1 vs Ch7: 1001h is UNSIGNED8 (chosen) vs UINT32.
    c = topics["1001h error register data type"]
    assert "UNSIGNED8" in c.chosen and c.other == "UINT32"
    assert (c.chosen_section, c.other_section) == ("001 §5-1", "001 Ch7")
    assert spec(smartris, 0x1001).data_type.name == "UNSIGNED8"
    # 001 §6-6 vs §6-5: step torque profile is -1 (table), not 1 (text).
    c = topics["6088h value for a step torque profile"]
    assert c.chosen == "-1" and c.other == "1"
    assert spec(smartris, 0x6088).values[-1].startswith("Step")  # type: ignore[index]
    for c in smartris.contradictions:
        assert c.chosen_section.startswith("001") and c.other_section.startswith("001")
