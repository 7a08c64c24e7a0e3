"""Documented facts of the CTMM04x manual (003) asserted against the ctmm04x profile.

Each test names the manual section it checks. The profile describes one axis (the X objects);
the other axes are the same objects offset by 0x800 (quirk axis_object_offset).
"""

from __future__ import annotations

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import Access, DeviceProfile, ObjectSpec
from servodesk.domain.profile_loader import ProfileCatalog, check_profile


@pytest.fixture(scope="module")
def p() -> DeviceProfile:
    return ProfileCatalog().get("ctmm04x")


def spec(p: DeviceProfile, index: int, sub: int = 0) -> ObjectSpec:
    s = p.spec(ObjectAddress(index, sub))
    assert s is not None, f"0x{index:04X}:{sub:02X} missing"
    return s


def test_profile_is_consistent_and_on_cclink(p: DeviceProfile) -> None:
    assert check_profile(p) == []
    assert p.fieldbus == "cclink-ie-tsn"
    assert [m.id for m in p.manuals] == ["003"]


def test_identity_is_vendor_058f_with_two_product_codes(p: DeviceProfile) -> None:
    # 003 §4-3-1: 1018h:01 = 0x0000058F, 1018h:02 = 0x00040001 or 0x00040002, serial not supported.
    assert p.identity.vendor_id == 0x0000058F
    assert set(p.identity.product_codes) == {0x00040001, 0x00040002}
    assert spec(p, 0x1018, 0).default_value() == 4
    assert spec(p, 0x1018, 1).default_value() == 0x0000058F
    assert spec(p, 0x1018, 4).default_value() == 0
    assert p.identity.matches(0x58F, 0x00040002, 0)
    assert not p.identity.matches(0x58F, 0x00040003, 0)


def test_device_name_is_printed_but_not_used_for_identification(p: DeviceProfile) -> None:
    # 003 §4-3-1: 1008h prints "AECAT-AXIS4", another product's name.
    assert spec(p, 0x1008).default == "AECAT-AXIS4"
    assert p.identity.device_name is None
    assert p.quirk("device_name_not_for_identification") == "AECAT-AXIS4"


def test_device_type_is_the_printed_nonstandard_value(p: DeviceProfile) -> None:
    # 003 §4-3-1: 1000h initial value 0x00010000 (not 0x00020192).
    assert spec(p, 0x1000).default_value() == 0x00010000
    assert p.quirk("device_type_nonstandard") == 0x00010000


def test_store_and_restore_use_the_standard_signatures(p: DeviceProfile) -> None:
    # 003 §4-3-1: 1010h:01 "save", 1011h:01 "load"; both read 0x00000001.
    save, load = spec(p, 0x1010, 1), spec(p, 0x1011, 1)
    assert save.access is Access.RW and save.default_value() == 1
    assert load.access is Access.RW and load.default_value() == 1
    assert p.quirk("store_parameters") is None and p.quirk("restore_defaults") is None
    assert "0x65766173" in (save.description or "")
    assert "0x64616F6C" in (load.description or "")


def test_restore_is_refused_in_operation_enabled(p: DeviceProfile) -> None:
    # 003 §4-3-1: a 1011h:01 write in Operation enabled returns an abort.
    load = spec(p, 0x1011, 1)
    assert load.writable_in and "operation_enabled" not in load.writable_in
    assert "switch_on_disabled" in load.writable_in
    assert p.quirk("restore_refused_in_operation_enabled") is True
    assert p.quirk("store_parameters_duration_s") == 10  # "up to about 10 s"


def test_eeprom_saved_objects_are_exactly_table_4_3_1_1(p: DeviceProfile) -> None:
    # 003 §4-3-1 table 4-3-1-1: the objects 1010h:01 saves.
    table = {
        (0x605C, 0),
        (0x605D, 0),
        (0x6060, 0),
        (0x6065, 0),
        (0x6067, 0),
        (0x607C, 0),
        (0x607D, 1),
        (0x607D, 2),
        (0x607F, 0),
        (0x6081, 0),
        (0x6083, 0),
        (0x6084, 0),
        (0x6098, 0),
        (0x6099, 1),
        (0x6099, 2),
        (0x609A, 0),
        (0x2000, 0),
        (0x2002, 0),
        (0x2003, 0),
        (0x2004, 0),
        (0x2005, 0),
        (0x2006, 0),
    }
    persisted = {(a.index, a.subindex) for a, s in p.variables.items() if s.persist}
    assert persisted == table
    # Volatile settings a tool must re-apply after power-up (not in the table).
    for index in (0x605B, 0x605E, 0x6066, 0x60B0):
        assert not spec(p, index).persist


def test_rxpdo_1600_is_fixed_with_five_entries_of_15_bytes(p: DeviceProfile) -> None:
    # 003 §4-1 table 4-1-1, §4-3-1: 6040h, 6060h, 607Ah, 60FFh, 60FEh.
    assert spec(p, 0x1600, 0).default_value() == 5
    entries = [spec(p, 0x1600, n).default_value() for n in range(1, 6)]
    assert entries == [0x60400010, 0x60600008, 0x607A0020, 0x60FF0020, 0x60FE0020]
    assert sum(int(e) & 0xFF for e in entries) == 15 * 8
    for n in range(6):
        assert spec(p, 0x1600, n).access is Access.RO


def test_txpdo_1a00_is_fixed_with_ten_entries_of_29_bytes(p: DeviceProfile) -> None:
    # 003 §4-1 table 4-1-2, §4-3-1.
    assert spec(p, 0x1A00, 0).default_value() == 10
    entries = [int(spec(p, 0x1A00, n).default_value() or 0) for n in range(1, 11)]
    assert [e >> 16 for e in entries] == [
        0x6041,
        0x6061,
        0x6062,
        0x6064,
        0x606C,
        0x60FD,
        0x200A,
        0x2011,
        0x2012,
        0x2013,
    ]
    assert sum(e & 0xFF for e in entries) == 29 * 8 == p.pdo.max_bits
    assert p.pdo.rpdo_count == 1 and p.pdo.tpdo_count == 1 and p.pdo.max_entries == 10
    assert p.pdo.mapping_state == "fixed" and p.quirk("pdo_mapping_fixed") is True


def test_every_mapped_object_is_mappable_in_its_direction_with_its_size(p: DeviceProfile) -> None:
    # 003 §4-1: the mapping entries name objects of table 4-4-1 / 4-5-1 with their bit length.
    for pdo, direction in ((0x1600, "rx"), (0x1A00, "tx")):
        count = int(spec(p, pdo, 0).default_value() or 0)
        for n in range(1, count + 1):
            entry = int(spec(p, pdo, n).default_value() or 0)
            target = spec(p, entry >> 16, (entry >> 8) & 0xFF)
            assert target.bits == entry & 0xFF, target.name
            assert getattr(target.pdo_mapping, direction), target.name


def test_pdo_mappable_objects_are_those_of_tables_4_4_1_and_4_5_1(p: DeviceProfile) -> None:
    # 003 §4-4 table 4-4-1 ("Yes") and §4-5 table 4-5-1 ("Possible").
    rx = {a.index for a, s in p.variables.items() if s.pdo_mapping.rx}
    tx = {a.index for a, s in p.variables.items() if s.pdo_mapping.tx}
    assert rx == {0x6040, 0x6060, 0x607A, 0x60FE, 0x60FF}
    assert tx == {0x6041, 0x6061, 0x6062, 0x6064, 0x606C, 0x60FD, 0x200A, 0x2011, 0x2012, 0x2013}


def test_modes_are_pp_pv_hm_and_match_6502(p: DeviceProfile) -> None:
    # 003 §4-4-4 table 4-4-4-1; §4-4-8 6502h = 0x00000025.
    assert p.modes == (1, 3, 6)
    supported = int(spec(p, 0x6502).default_value() or 0)
    assert supported == 0x25
    bit_of_mode = {1: 0, 3: 2, 6: 5}
    assert {m for m, b in bit_of_mode.items() if supported >> b & 1} == set(p.modes)
    # 0: no mode, any other value makes the axis perform no control (the twin starts there).
    assert set(spec(p, 0x6060).values or {}) == {0, 1, 3, 6}


def test_homing_methods_match_60e3_and_6098(p: DeviceProfile) -> None:
    # 003 §4-4-7 table 4-4-7-2 (○), §4-4-8 60E3h (11 entries 0x03nn) and 6098h.
    assert p.homing_methods == (1, 2, 7, 8, 11, 12, 17, 18, 24, 28, 35)
    assert spec(p, 0x60E3, 0).default_value() == 11
    listed = [int(spec(p, 0x60E3, n).default_value() or 0) for n in range(1, 12)]
    assert all(v >> 8 == 0x03 for v in listed)
    assert tuple(v & 0xFF for v in listed) == p.homing_methods
    method = spec(p, 0x6098)
    assert method.data_type is DataType.INTEGER8
    assert method.default_value() == 35 and (method.min, method.max) == (1, 35)
    assert tuple(sorted(method.values or {})) == p.homing_methods


def test_option_codes_use_minus_one_and_minus_two(p: DeviceProfile) -> None:
    # 003 §4-4-8: 605Bh, 605Ch, 605Eh default -1, range -2..-1; 605Dh has no detail.
    for index in (0x605B, 0x605C, 0x605E):
        s = spec(p, index)
        assert s.data_type is DataType.INTEGER16
        assert s.default_value() == -1 and (s.min, s.max) == (-2, -1)
        assert set(s.values or {}) == {-2, -1}
    halt = spec(p, 0x605D)
    assert halt.data_type is DataType.INTEGER16 and not halt.values
    # Undocumented: the twin holds the CiA 402 value it acts on, 1 (notes.md, issue 47).
    assert halt.default_value() == 1 and "not documented" in (halt.description or "")


def test_no_quick_stop_objects(p: DeviceProfile) -> None:
    # 003 §4-4-1/§4-4-2: quick stop not supported; 605Ah and 6085h are not in table 4-4-1.
    assert p.spec(ObjectAddress(0x605A)) is None and p.spec(ObjectAddress(0x6085)) is None
    assert p.quirk("no_quick_stop") is True


def test_position_windows(p: DeviceProfile) -> None:
    # 003 §4-4-8: 6065h 32767 (0..32767 pulse), 6066h 65535 ms, 6067h 100 (0..32767 pulse).
    few, fet, pw = spec(p, 0x6065), spec(p, 0x6066), spec(p, 0x6067)
    assert few.default_value() == 32767 and few.max == 32767 and few.unit == "pulse"
    assert fet.default_value() == 65535 and fet.data_type is DataType.UNSIGNED16
    assert fet.unit == "ms"
    assert pw.default_value() == 100 and pw.max == 32767


def test_following_error_actual_is_a_16_bit_counter(p: DeviceProfile) -> None:
    # 003 §4-4-8: 60F4h display range -32768..+32767, INT32.
    s = spec(p, 0x60F4)
    assert s.data_type is DataType.INTEGER32 and (s.min, s.max) == (-32768, 32767)


def test_speeds_in_pps_with_their_defaults(p: DeviceProfile) -> None:
    # 003 §4-4-8 and §4-5-1: 607Fh 8191, 6081h 5000, 60FFh 5000, 2000h 10, 6099h 3000/10.
    expected = {
        (0x607F, 0): 8191,
        (0x6081, 0): 5000,
        (0x60FF, 0): 5000,
        (0x2000, 0): 10,
        (0x6099, 1): 3000,
        (0x6099, 2): 10,
    }
    for (index, sub), default in expected.items():
        s = spec(p, index, sub)
        assert s.default_value() == default and s.unit == "pps"
    assert (spec(p, 0x607F).min, spec(p, 0x607F).max) == (1, 8191000)
    assert spec(p, 0x60FF).data_type is DataType.INTEGER32  # The sign is the direction.


def test_pv_moves_at_the_default_target_velocity(p: DeviceProfile) -> None:
    # 003 §4-4-6: output starts at 60FFh when pv becomes active; set 0 first.
    assert spec(p, 0x60FF).default_value() != 0
    assert p.quirk("pv_starts_on_enable") is True
    lowest = spec(p, 0x60FF).min
    assert lowest is not None and lowest < 0


def test_ramps_are_raw_rate_registers(p: DeviceProfile) -> None:
    # 003 §4-4-8, §5-3-1: 6083h, 6084h, 609Ah default 100, range 1..8191, no unit.
    for index in (0x6083, 0x6084, 0x609A):
        s = spec(p, index)
        assert s.default_value() == 100 and (s.min, s.max) == (1, 8191)
        assert s.unit is None and s.raw_unit == "PMC842SR RATE DATA"
    assert p.quirk("ramp_rate_registers")["fclk_hz"] == 32_768_000


def test_speed_multiplier_table(p: DeviceProfile) -> None:
    # 003 §5-3-1 table 5-3-1-2: range top = 8191 x multiplier, RANGE_DATA = 1000 / multiplier.
    table = p.quirk("speed_multiplier")["table"]
    assert len(table) == 16 and table[0] == [8191, 1, 1000] and table[-1] == [8191000, 1000, 1]
    for top, multiplier, range_data in table:
        assert top == 8191 * multiplier
        assert range_data * multiplier == 1000
    monitor = spec(p, 0x2001)
    assert monitor.access is Access.RO and monitor.default_value() == 1
    assert sorted(monitor.values or {}) == [row[1] for row in table]


def test_velocity_actual_and_multiplier_types_follow_the_object_lists(p: DeviceProfile) -> None:
    # 003 table 4-4-1 (606Ch INT32) and table 4-5-1 (2001h UINT16); the details disagree.
    assert spec(p, 0x606C).data_type is DataType.INTEGER32
    assert spec(p, 0x2001).data_type is DataType.UNSIGNED16
    topics = {c.topic for c in p.contradictions}
    assert {"606Ch data type", "2001h data type", "PDO mapping fixed or writable"} <= topics


def test_manufacturer_settings_defaults(p: DeviceProfile) -> None:
    # 003 §4-5-1: 2003h 0 (EL disabled), 2004h 0, 2005h 0x0003 (x4), 2006h 0; 2002h not printed.
    assert spec(p, 0x2003).default_value() == 0
    assert spec(p, 0x2004).default_value() == 0
    assert spec(p, 0x2005).default_value() == 0x0003
    assert spec(p, 0x2006).default_value() == 0
    # 2002h: not printed; the twin's 0 (linear ramps, pulse counter) is notes.md's (issue 47).
    assert spec(p, 0x2002).default_value() == 0
    assert "initial value is not printed" in (spec(p, 0x2002).description or "")
    for index in range(0x2002, 0x2007):
        assert spec(p, index).data_type is DataType.UNSIGNED16


def test_digital_outputs_are_all_reserved(p: DeviceProfile) -> None:
    # 003 §4-4-8: 60FEh bits 0-31 reserved, fixed 0; 60FDh is read-only.
    do = spec(p, 0x60FE)
    assert do.default_value() == 0 and (do.min, do.max) == (0, 0)
    assert spec(p, 0x60FD).access is Access.RO


def test_remaining_pulses_and_positions_are_in_pulses(p: DeviceProfile) -> None:
    # 003 §4-5-1 200Bh 0..2147483647 pulse; §4-4-8 6062h/6064h/607Ah/607Ch INT32 pulse.
    assert spec(p, 0x200B).max == 2147483647
    for index in (0x6062, 0x6064, 0x607A, 0x607C, 0x60B0):
        s = spec(p, index)
        assert s.data_type is DataType.INTEGER32 and s.unit == "pulse"


def test_error_codes_of_table_6_1_1(p: DeviceProfile) -> None:
    # 003 §6-1 table 6-1-1: seven codes, error register bit 0 or 7, all handled by the FR action.
    bits = {0x8611: 0, 0x8500: 0, 0x5530: 7, 0x6310: 7, 0x6320: 7, 0xFF00: 7, 0xFF01: 7}
    faults = {e.code: e for e in p.errors if e.table == "error_code" and e.kind == "fault"}
    assert set(faults) == set(bits)
    for code, bit in bits.items():
        e = faults[code]
        assert e.extra["error_register_bit"] == bit
        assert e.cause and e.remedy and e.name_local
    assert "2014h" in (faults[0x6320].cause or "")
    assert p.error_tables() == ["error_code"]  # No SLMP end codes or abort codes are printed.


def test_axes_offsets_and_slmp_addressing(p: DeviceProfile) -> None:
    # 003 §4-4-2: axis controlwords 6040h/6840h/7040h/7840h; §4-2 multidrop = axis number.
    offset = p.quirk("axis_object_offset")
    assert [0x6040 + n * offset for n in range(4)] == [0x6040, 0x6840, 0x7040, 0x7840]
    # 003 §5-3-2: Y target position 687Ah.
    assert 0x607A + offset == 0x687A
    assert p.quirk("axes")["names"] == ["X", "Y", "Z", "U"]
    assert p.quirk("slmp_axis_multidrop") is True


def test_interpolation_bits_of_the_x_controlword(p: DeviceProfile) -> None:
    # 003 §4-4-2 and §5-3-2 table 5-3-2-1: bits 11-14 X/Y/Z/U, bit 15 circular; XY circular 10011.
    q = p.quirk("controlword_interpolation_bits")
    assert q["axis_bits"] == {11: "X", 12: "Y", 13: "Z", 14: "U"} and q["type_bit"] == 15
    xy_circular = (1 << q["type_bit"]) | (1 << 11) | (1 << 12)
    assert xy_circular == 0x9800
    assert q["only_in_modes"] == [1, 3]
    assert p.quirk("statusword_bit15_interpolating") == 15


def test_mode_display_and_pp_buffer_quirks(p: DeviceProfile) -> None:
    # 003 §4-4-4 table 4-4-4-2 (6061h reads 0 unless Operation enabled); §4-4-5 set-points.
    assert spec(p, 0x6061).default_value() == 0
    assert 0 in (spec(p, 0x6061).values or {})
    assert p.quirk("mode_display_zero_unless_enabled") is True
    buf = p.quirk("pp_set_point_buffer")
    assert buf["depth"] == 1 and buf["ignored_while_ack"] is True
    assert buf["change_immediately_reversal"] == "rejected"


def test_no_tuning_gains(p: DeviceProfile) -> None:
    # 003 intro 1), §5-1: pulse-train output to external drives; no loop and no gain object.
    assert p.quirk("no_tuning_gains") is True
    assert "no tuning gains" in (p.description or "").lower()
