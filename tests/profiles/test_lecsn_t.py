"""Documented facts of the LECSN-T PROFINET manual (004, chapter 20) asserted against lecsn-t.

Each assertion names the manual section it checks. Addresses are CoE index/subindex; the PNU
is the index in decimal (004 §20.1.5.1) and array elements sit one CoE subindex above their
PNU subindex (quirk pnu_subindex_offset).
"""

from __future__ import annotations

from typing import Any

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import Access, DeviceProfile, ObjectSpec, PdoMapping
from servodesk.domain.profile_loader import ProfileCatalog, check_profile


@pytest.fixture(scope="module")
def p() -> DeviceProfile:
    return ProfileCatalog().get("lecsn-t")


def spec(p: DeviceProfile, index: int, sub: int = 0) -> ObjectSpec:
    s = p.spec(ObjectAddress(index, sub))
    assert s is not None, f"0x{index:04X}:{sub:02X} missing"
    return s


def test_profile_is_consistent_and_on_profinet(p: DeviceProfile) -> None:
    assert check_profile(p) == []
    assert p.fieldbus == "profinet"
    assert [m.id for m in p.manuals] == ["004"]
    # About a thousand documented objects (servo parameters and 255 point tables included).
    assert len(p.objects) > 950


def test_pnu_is_the_index_in_decimal(p: DeviceProfile) -> None:
    # 004 §20.1.5.1: P24698 = 607Ah, P4112 = 1010h, P8193 = 2001h (PA01), P11616 = 2D60h.
    for e in p.objects:
        assert e.pnu == e.index, f"0x{e.index:04X} has PNU {e.pnu}"
    assert spec(p, 0x607A).name == "Target position"
    assert spec(p, 0x2001).symbol == "PA01"
    assert spec(p, 0x2D60).pnu == 11616


@pytest.mark.parametrize(
    ("symbol", "index", "group"),
    [
        # 004 §20.8.14 / §20.9.2: servo parameter PNU blocks, all Integer32 R/W, EEP-ROM.
        ("PA01", 0x2001, "PA"),
        ("PA32", 0x2020, "PA"),
        ("PB01", 0x2081, "PB"),
        ("PB64", 0x20C0, "PB"),
        ("PC80", 0x2150, "PC"),
        ("PD48", 0x21B0, "PD"),
        ("PE64", 0x2240, "PE"),
        ("PF01", 0x2281, "PF"),
        ("PO32", 0x2320, "PO"),
        ("PL48", 0x2430, "PL"),
        ("PT80", 0x24D0, "PT"),
        ("PN32", 0x25A0, "PN"),
    ],
)
def test_servo_parameter_blocks(p: DeviceProfile, symbol: str, index: int, group: str) -> None:
    s = spec(p, index)
    assert (s.symbol, s.group, s.pnu) == (symbol, group, index)
    assert s.data_type is DataType.INTEGER32 and s.access is Access.RW and s.persist


def test_servo_parameter_counts_per_group(p: DeviceProfile) -> None:
    # 004 §20.9.2: PA 32, PB 64, PC 80, PD 48, PE 64, PF 64, PO 32, PL 48, PT 80, PN 32.
    counts: dict[str, int] = {}
    for s in p.variables.values():
        if s.symbol:
            counts[s.symbol[:2]] = counts.get(s.symbol[:2], 0) + 1
    assert counts == {
        "PA": 32,
        "PB": 64,
        "PC": 80,
        "PD": 48,
        "PE": 64,
        "PF": 64,
        "PO": 32,
        "PL": 48,
        "PT": 80,
        "PN": 32,
    }


def test_groups_follow_the_manual_order(p: DeviceProfile) -> None:
    # 004 §20.4.3 then the §20.9.2 list order.
    ids = [g.id for g in p.groups]
    assert ids[:12] == [
        "profidrive",
        "general",
        "PA",
        "PB",
        "PC",
        "PD",
        "PE",
        "PF",
        "PO",
        "PL",
        "PT",
        "PN",
    ]
    assert (
        ids.index("alarm")
        < ids.index("monitor")
        < ids.index("pds_control")
        < ids.index("touch_probe")
    )


def test_cia402_objects_the_twin_needs(p: DeviceProfile) -> None:
    # 004 §20.9.3.6-§20.9.3.11: types and defaults of the CiA 402 objects.
    assert spec(p, 0x6040).data_type is DataType.UNSIGNED16 and spec(p, 0x6040).default_value() == 0
    assert spec(p, 0x6041).data_type is DataType.UNSIGNED16
    assert spec(p, 0x6060).data_type is DataType.INTEGER8 and spec(p, 0x6060).default_value() == 0
    assert spec(p, 0x6061).data_type is DataType.INTEGER8
    assert spec(p, 0x6064).data_type is DataType.INTEGER32
    assert spec(p, 0x606C).data_type is DataType.INTEGER32
    assert spec(p, 0x6081).default_value() == 10000  # §20.9.3.10(6), 0.01 r/min
    assert spec(p, 0x6083).default_value() == 0 and spec(p, 0x6084).default_value() == 0
    assert spec(p, 0x6085).default_value() == 100  # §20.9.3.10(9)
    assert spec(p, 0x603F).default_value() == 0  # §20.9.3.6(1)


def test_velocity_units_are_hundredths_of_rpm(p: DeviceProfile) -> None:
    # 004 §20.9.3.8(2): Velocity actual value in vel units = 0.01 r/min.
    s = spec(p, 0x606C)
    assert s.unit == "r/min" and s.scale == pytest.approx(0.01)
    # 004 §20.9.3.9(7): torque limits 0-2710h in 0.1 % of rated torque, default 10000.
    t = spec(p, 0x60E0)
    assert (t.min, t.max, t.default_value(), t.scale) == (0, 10000, 10000, pytest.approx(0.1))


def test_quick_stop_and_halt_option_codes_are_fixed(p: DeviceProfile) -> None:
    # 004 §20.9.3.6(4)/(5): 605Ah only 2, 605Dh only 1, both backed by PT68.
    qs, halt = spec(p, 0x605A), spec(p, 0x605D)
    assert (qs.data_type, qs.default_value(), qs.min, qs.max) == (DataType.INTEGER16, 2, 2, 2)
    assert (halt.default_value(), halt.min, halt.max) == (1, 1, 1)
    assert qs.persist and halt.persist


def test_following_error_window_default(p: DeviceProfile) -> None:
    # 004 §20.9.3.7(3): default 00C00000h, EEP-ROM PC67/PC68.
    s = spec(p, 0x6065)
    assert s.data_type is DataType.UNSIGNED32 and s.default_value() == 0x00C00000 and s.persist


def test_max_profile_velocity_limits(p: DeviceProfile) -> None:
    # 004 §20.9.3.10(4): 0 to 001E8480h (2000000), default 2000000.
    s = spec(p, 0x607F)
    assert (s.min, s.max, s.default_value()) == (0, 2000000, 2000000)


def test_motion_profile_type_is_s_pattern_only(p: DeviceProfile) -> None:
    # 004 §20.9.3.10(10): Integer16, FFFFh to FFFFh, default -1.
    s = spec(p, 0x6086)
    assert (s.data_type, s.default_value(), s.min, s.max) == (DataType.INTEGER16, -1, -1, -1)


def test_homing_objects(p: DeviceProfile) -> None:
    # 004 §20.9.3.11(2): 6098h Integer8, D5h (-43) to 25h (37), default 37 (PT45).
    hm = spec(p, 0x6098)
    assert (hm.data_type, hm.min, hm.max, hm.default_value()) == (DataType.INTEGER8, -43, 37, 37)
    # 004 §20.9.3.11(3): P24729.0 = 10000, P24729.1 = 1000 (CoE 6099h:01/02).
    assert spec(p, 0x6099, 1).default_value() == 10000
    assert spec(p, 0x6099, 2).default_value() == 1000
    # 004 §20.9.3.11(5): 60E3h lists 39 methods, first 37, last -43.
    assert spec(p, 0x60E3, 0).default_value() == 39
    assert spec(p, 0x60E3, 1).default_value() == 37
    assert spec(p, 0x60E3, 39).default_value() == -43


def test_homing_methods_and_modes(p: DeviceProfile) -> None:
    # 004 §20.9.3.11(5): the 39 supported methods; §20.9.3.6(6): the modes of operation.
    assert len(p.homing_methods) == 39
    assert {35, 37, -1, -43, 3, 34} <= set(p.homing_methods)
    assert -5 not in p.homing_methods and -35 not in p.homing_methods
    assert list(p.homing_methods) == [spec(p, 0x60E3, i).default_value() for i in range(1, 40)]
    assert sorted(p.modes) == [-103, -101, -100, 1, 3, 4, 6]
    assert (
        spec(p, 0x6060).values is not None
        and spec(p, 0x6060).values[-101] == "Point table mode (pt)"
    )
    assert p.quirk("indexer_homing_methods") == [37, 35, -1, -3, -33]


def test_store_parameters_is_1010h_sub_1(p: DeviceProfile) -> None:
    # 004 §20.9.1 / §20.9.3.1: write 65766173h to P4112.0; P4112 = 1010h, PNU sub 0 = CoE sub 1.
    assert p.quirk("store_parameters") == {"index": 0x1010, "subindex": 1, "value": 0x65766173}
    s = spec(p, 0x1010, 1)
    assert s.pnu == 4112 and s.data_type is DataType.UNSIGNED32 and s.access is Access.RW
    assert "not supported" in (spec(p, 0x1010, 2).description or "").lower()


def test_parameter_activation_via_p11572(p: DeviceProfile) -> None:
    # 004 §20.8.14.1 / §20.9.3.5(25): write 1EA5h to P11572 (2D34h); reads 1 when done.
    q: dict[str, Any] = p.quirk("parameter_activation")
    assert (q["index"], q["value"], q["done_value"]) == (0x2D34, 0x1EA5, 1)
    assert spec(p, 0x2D34).default_value() == 1


def test_one_touch_tuning_objects(p: DeviceProfile) -> None:
    # 004 §20.9.3.5(27)-(31) and §20.8.7.
    mode = spec(p, 0x2D50)
    assert (mode.pnu, mode.data_type, mode.min, mode.max, mode.default_value()) == (
        11600,
        DataType.UNSIGNED8,
        0,
        3,
        0,
    )
    assert mode.values == {
        0: "One-touch tuning stopped",
        1: "Basic mode",
        2: "High mode",
        3: "Low mode",
    }
    assert spec(p, 0x2D51).max == 100  # 00h-64h %
    stop = spec(p, 0x2D52)
    assert stop.access is Access.WO and stop.values is not None and 0x1EA5 in stop.values
    assert spec(p, 0x2D53).values == {
        0: "restore the initial (default) values",
        1: "restore the values before one-touch tuning",
    }
    assert spec(p, 0x2D54).max == 0xC00F


def test_tuning_error_codes(p: DeviceProfile) -> None:
    # 004 §20.9.3.5(31): 0000h normal, C000h-C005h, C00Fh.
    codes = {e.code for e in p.errors if e.table == "tuning"}
    assert codes == {0x0000, 0xC000, 0xC001, 0xC002, 0xC003, 0xC004, 0xC005, 0xC00F}
    assert p.error("tuning", 0xC002) is not None
    assert p.error("tuning", 0xC002).name == "Servo-off during tuning"  # type: ignore[union-attr]
    assert p.error("tuning", 0xC00F).name == "One-touch tuning disabled"  # type: ignore[union-attr]


def test_profidrive_error_numbers(p: DeviceProfile) -> None:
    # 004 §20.4.2: 17 error numbers 00h-FFh.
    codes = sorted(e.code for e in p.errors if e.table == "profidrive")
    assert codes == [
        0x00,
        0x01,
        0x02,
        0x03,
        0x04,
        0x05,
        0x07,
        0x0F,
        0x11,
        0x14,
        0x15,
        0x16,
        0x17,
        0x18,
        0x19,
        0x21,
        0xFF,
    ]
    e02 = p.error("profidrive", 0x02)
    assert e02 is not None and e02.name == "Low or high limit exceeded"
    assert p.error("profidrive", 0xFF).name == "Read of a write-only parameter"  # type: ignore[union-attr]


def test_alarm_encoding_and_remedies(p: DeviceProfile) -> None:
    # 004 §20.9.3.3(1): [AL 16.3] reads 00160003h (bits 31-16 number, 15-0 detail).
    a = p.error("alarm", 0x00160003)
    assert a is not None and a.display == "AL 16.3"
    # 004 §20.6.3(2): relative move in degree unit -> [AL F4.8] = 00F40008h.
    f48 = p.error("alarm", 0x00F40008)
    assert f48 is not None and f48.kind == "warning" and "degree" in (f48.cause or "")
    # 004 §20.5.3.1(3): [AL F4] is reset by C_ORST (Control DI 2 bit 15) off -> on.
    f4 = p.error("alarm", 0x00F40000)
    assert f4 is not None and "C_ORST" in (f4.remedy or "")
    # 004 §20.8.3: [AL 98 Software limit warning]: command the opposite direction.
    al98 = p.error("alarm", 0x00980000)
    assert al98 is not None and al98.kind == "warning" and "opposite" in (al98.remedy or "")
    # 004 §20.6.1: [AL 37 Parameter error] is a fault.
    al37 = p.error("alarm", 0x00370000)
    assert al37 is not None and al37.kind == "fault" and al37.name == "Parameter error"
    # 004 §20.6.6(4): [AL 90.5 Z-phase unpassed].
    assert p.error("alarm", 0x00900005) is not None


def test_alarm_objects(p: DeviceProfile) -> None:
    # 004 §20.9.3.3: latest history 2A00h, histories 1-15 at 2A01h-2A0Fh, clear 2A40h.
    assert spec(p, 0x2A00, 1).data_type is DataType.UNSIGNED32
    assert spec(p, 0x2A0F, 2).unit == "h" and spec(p, 0x2A0F).pnu == 10767
    assert spec(p, 0x2A40).access is Access.WO and spec(p, 0x2A40).values == {
        0x1EA5: "clear the alarm history"
    }
    assert spec(p, 0x2A44).max == 0x1F4  # §20.9.3.3(5): 0000h-01F4h
    assert p.quirk("clear_alarm_history") == {"index": 0x2A40, "subindex": 0, "value": 0x1EA5}


def test_profidrive_identification(p: DeviceProfile) -> None:
    # 004 §20.4.3.5 / §20.4.4: manufacturer ID 540; §20.4.3.6: profile 3, version 41 (29h).
    assert p.identity.vendor_id == 540
    assert spec(p, 964, 0).default_value() == 540
    assert spec(p, 965, 0).default_value() == 3 and spec(p, 965, 1).default_value() == 0x29
    assert spec(p, 975, 5).default_value() == 1  # DO type class 1 = axis
    assert spec(p, 922).values == {
        1: "Standard telegram 1",
        100: "Telegram 100",
        102: "Telegram 102",
        103: "Telegram 103",
    }
    assert spec(p, 930).values is not None and 32768 in spec(p, 930).values


def test_point_tables(p: DeviceProfile) -> None:
    # 004 §20.9.3.12(4): P10241-P10495 = point tables 1-255, Array[7] Integer32, EEP-ROM.
    tables = [e for e in p.objects if 0x2801 <= e.index <= 0x28FF]
    assert len(tables) == 255
    pos = spec(p, 0x28FF, 1)
    assert pos.pnu == 10495 and (pos.min, pos.max) == (-999999, 999999) and pos.persist
    aux = spec(p, 0x2801, 6)
    assert aux.values is not None and set(aux.values) == {0, 1, 2, 3, 8, 9, 10, 11}
    assert spec(p, 0x2801, 7).max == 99  # M code 0-99
    # 004 §20.9.3.12(1): target point table -1 (high-speed homing) to 255, telegram 103.
    tpt = spec(p, 0x2D60)
    assert (tpt.min, tpt.max) == (-1, 255) and tpt.pdo_mapping is PdoMapping.RX


def test_telegram_layouts_and_mapping_limits(p: DeviceProfile) -> None:
    # 004 §20.1.2: T102 max 48 bytes / 24 entries, T103 max 60 bytes / 30 entries; §20.3 layouts.
    tgs = p.quirk("telegrams")
    assert {t["id"] for t in tgs} == {1, 100, 102, 103}
    bits = {
        "INTEGER8": 8,
        "UNSIGNED8": 8,
        "INTEGER16": 16,
        "UNSIGNED16": 16,
        "INTEGER32": 32,
        "UNSIGNED32": 32,
    }
    for t in tgs:
        total = sum(
            (bits[w["data_type"]] if "data_type" in w else w["bits"]) * w.get("repeat", 1)
            for w in t["words"]
        )
        assert total == t["bytes"] * 8, (t["id"], t["direction"])
        entries = sum(w.get("repeat", 1) for w in t["words"])
        if t["id"] == 102:
            assert t["bytes"] == 48 and t["max_entries"] == 24 and entries <= 24
        if t["id"] == 103:
            assert t["bytes"] == 60 and t["max_entries"] == 30 and entries <= 30
        for w in t["words"]:
            if w.get("pnu") and "name" not in w:
                # Every mapped PNU is an object with the right direction of mapping (NSOLL_A /
                # NIST_A are 16-bit scaled views of 60FFh / 606Ch, §20.6.4, so they are skipped).
                s = spec(p, w["pnu"])
                assert s.data_type.name == w["data_type"]
                assert s.pdo_mapping.rx if t["direction"] == "rx" else s.pdo_mapping.tx
    assert p.pdo.max_entries == 30 and p.pdo.max_bits == 480


def test_fault_reset_and_state_machine_quirks(p: DeviceProfile) -> None:
    # 004 §20.5.2: fault reset holds bit 7 for 10 ms (or 2 cycles); IDLE forces Switch on disabled.
    assert p.quirk("fault_reset") == "bit7_edge"
    assert p.quirk("fault_reset_hold_ms") == 10
    assert p.quirk("idle_forces_switch_on_disabled") is True
    # 004 §20.6.4: NSOLL_A = 60FFh / 100, not N2 normalised.
    assert p.quirk("telegram1_speed_scaling")["setpoint"] == "NSOLL_A = 60FFh / 100"


def test_digital_inputs_and_polarity(p: DeviceProfile) -> None:
    # 004 §20.9.3.14(1): 60FDh range 00000000h-037E0007h; §20.9.3.13(1): 607Eh only 00h/C0h/E0h.
    assert spec(p, 0x60FD).max == 0x037E0007
    assert set(spec(p, 0x607E).values or {}) == {0x00, 0xC0, 0xE0}
    # 004 §20.9.3.14(2): P24830 physical outputs / bit mask at 60FEh:01/02, max 000E0000h.
    assert spec(p, 0x60FE, 1).name == "Physical outputs" and spec(p, 0x60FE, 2).max == 0x000E0000


def test_monitors(p: DeviceProfile) -> None:
    # 004 §20.9.3.4(12): P11022 inertia ratio Unsigned16 in 0.01 times; (13) bus voltage in V.
    s = spec(p, 0x2B0E)
    assert s.pnu == 11022 and s.data_type is DataType.UNSIGNED16 and s.scale == pytest.approx(0.01)
    assert spec(p, 0x2B0F).unit == "V"
    # 004 §20.9.3.4(45): alarm monitor 15 bus voltage is Integer32 (live monitor: Unsigned16).
    assert spec(p, 0x2B8F).data_type is DataType.INTEGER32
    # 004 §20.9.3.4(1): cumulative feedback pulses is R/W, cleared by writing 00001EA5h.
    assert spec(p, 0x2B01).access is Access.RW


def test_contradictions_are_recorded(p: DeviceProfile) -> None:
    # 004 §20.9.3.11(2) says default 37, §20.6.6(1) says -1: the profile uses 37 and records it.
    c = next(c for c in p.contradictions if c.topic.startswith("Homing method 6098h"))
    assert c.chosen == "37" and c.other == "-1"
    assert c.chosen_section == "004 §20.9.3.11(2)" and c.other_section == "004 §20.6.6(1)"
    # 004 §20.6.5 vs §20.9.3.9(6): torque profile type Int16 chosen over Unsigned32.
    assert spec(p, 0x6088).data_type is DataType.INTEGER16
    assert any("6088h" in c.topic for c in p.contradictions)
