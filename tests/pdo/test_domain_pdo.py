"""The pure PDO layer (servodesk.domain.pdo): reading, validation, layout, pack/unpack, JSON
and exports, for every family's profile (docs/pdo.md)."""

from __future__ import annotations

import csv
import io
import json
import struct
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import pytest

from servodesk.devdesc import pdo_export
from servodesk.domain import pdo
from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.pdo import Direction, MapEntry
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog, parse_profile
from servodesk.errors import PdoRefused, ValidationError

PROFILES = Path(__file__).resolve().parents[2] / "profiles"
CATALOG = ProfileCatalog([PROFILES])
FAMILIES = ["cia402-generic", "smartris", "hiwin-e", "ctmm04x", "lecsn-t"]


def prof(pid: str) -> DeviceProfile:
    return CATALOG.get(pid)


def messages(problems: list[pdo.PdoProblem]) -> str:
    return " | ".join(p.message for p in problems)


def with_pdo(p: DeviceProfile, cfg: pdo.PdoConfig, **item: object) -> pdo.PdoConfig:
    return pdo.config_from_json(p, {"pdos": [item]}, current=cfg)


# --------------------------------------------------------------------------------------------
# Entries and reading


def test_map_entry_raw_round_trip_and_padding() -> None:
    e = MapEntry(0x607A, 0, 32)
    assert e.raw == 0x607A0020 and MapEntry.from_raw(0x607A0020) == e
    assert not e.is_padding
    assert MapEntry.from_raw(0x00000808).is_padding  # LECSN Reserved 8 bits
    assert MapEntry(0x0005, 0, 8).is_padding  # CiA 301 dummy UNSIGNED8
    assert MapEntry.reserved(16) == MapEntry(0, 16, 16)


@pytest.mark.parametrize("family", FAMILIES)
def test_factory_config_is_valid_and_round_trips(family: str) -> None:
    p = prof(family)
    cfg = pdo.default_config(p, 3)
    assert pdo.validate(p, cfg) == []
    # Object values <-> config, and JSON <-> config, lose nothing.
    values = pdo.config_values(p, cfg)
    assert set(values) <= set(pdo.config_addresses(p))
    assert pdo.parse_config(p, values) == cfg
    assert pdo.config_from_json(p, pdo.config_to_json(p, cfg)) == cfg
    assert json.loads(json.dumps(pdo.config_to_json(p, cfg))) == pdo.config_to_json(p, cfg)


@pytest.mark.parametrize("family", FAMILIES)
def test_every_template_is_valid_and_documented(family: str) -> None:
    p = prof(family)
    cur = pdo.default_config(p, 3)
    ts = pdo.templates(p)
    assert ts, f"{family} has no templates"
    for t in ts:
        assert t.name and t.description and t.section, t.id
        cfg = pdo.apply_template(p, cur, t.id)
        assert pdo.validate(p, cfg) == [], (t.id, messages(pdo.validate(p, cfg)))
        assert pdo.config_from_json(p, pdo.config_to_json(p, cfg)) == cfg


def test_factory_templates_equal_the_factory_configuration() -> None:
    for family in ("cia402-generic", "smartris", "hiwin-e"):
        p = prof(family)
        cur = pdo.default_config(p, 7)
        assert pdo.apply_template(p, cur, "factory") == cur, family


def test_documented_default_mappings() -> None:
    # smartris 001 Tables 2-15..2-24: RPDO1 6040h/6060h/60FEh:01 (7 bytes), TPDO1 6041h/
    # 6061h/60FDh with type 255 and inhibit 5 (500 µs), TPDO2-4 RTR-only (253).
    s = pdo.default_config(prof("smartris"), 1)
    assert [str(e) for e in s.pdo("rx", 1).entries] == ["0x6040:00", "0x6060:00", "0x60FE:01"]
    t1 = s.pdo("tx", 1)
    assert t1.comm == pdo.PdoComm(0x181, True, True, 255, 5, 0, 0)
    assert {s.pdo("tx", n).comm.transmission_type for n in (2, 3, 4)} == {253}  # type: ignore[union-attr]
    # HIWIN 000 §3.1.1 set 1 assigned: 1600h 13 bytes, 1A00h 23 bytes.
    h = pdo.default_config(prof("hiwin-e"), 1)
    assert [p.name for p in h.active("rx")] == ["RxPDO 1600h"]
    assert h.active("rx")[0].bytes == 13 and h.active("tx")[0].bytes == 23
    # LECSN: telegram 1 from the factory (P922 default 1); the twin's 1600h holds 102's map.
    lp = prof("lecsn-t")
    lc = pdo.default_config(lp, 1)
    assert lc.telegram == 1
    assert pdo.layout(lp, lc.pdo("rx", 1))[0].name.startswith("STW1")
    assert pdo.default_values(lp, 1)[A(0x1600, 0)] == 18
    assert lp.spec(A(0x1600, 1)).sim_only  # type: ignore[union-attr]
    assert lp.spec(A(0x039A, 0)).access.writable  # type: ignore[union-attr]


def test_parse_config_names_what_is_missing() -> None:
    p = prof("cia402-generic")
    values = pdo.default_values(p, 1)
    del values[A(0x1801, 1)]
    with pytest.raises(ValidationError) as info:
        pdo.parse_config(p, values)
    assert info.value.field == "0x1801:01"
    values = pdo.default_values(p, 1)
    values[A(0x1600, 0)] = 9
    with pytest.raises(ValidationError, match="8 entries"):
        pdo.parse_config(p, values)


def test_real_lecsn_without_twin_objects_reads_the_telegram_layout() -> None:
    p = prof("lecsn-t")
    cfg = pdo.parse_config(p, {A(0x039A, 0): 103})
    assert cfg.telegram == 103
    assert cfg.pdo("tx", 1).bytes == 60 and len(cfg.pdo("tx", 1).entries) == 24
    assert pdo.validate(p, cfg) == []


# --------------------------------------------------------------------------------------------
# Validation


def test_canopen_entry_problems() -> None:
    p = prof("cia402-generic")
    cfg = pdo.default_config(p, 1)
    bad = with_pdo(
        p,
        cfg,
        direction="rx",
        number=1,
        entries=[
            {"index": 0x6099, "subindex": 5, "bits": 32},  # no such object
            "0x6041:00",  # TX only
            {"index": 0x6040, "subindex": 0, "bits": 8},  # wrong length
        ],
    )
    probs = pdo.validate(p, bad)
    assert [(x.pdo, x.entry, x.field) for x in probs] == [
        ("RPDO1", 0, "entries"),
        ("RPDO1", 1, "entries"),
        ("RPDO1", 2, "entries"),
    ]
    assert "not an object" in probs[0].message
    assert "cannot be mapped into a RPDO" in probs[1].message
    assert "UNSIGNED16 (16 bits)" in probs[2].message and "Write 16" in probs[2].message
    assert all(x.section for x in probs)


def test_canopen_limits_64_bits_and_8_entries() -> None:
    p = prof("cia402-generic")
    cfg = pdo.default_config(p, 1)
    big = with_pdo(
        p, cfg, direction="tx", number=1, entries=["0x6064:00", "0x606C:00", "0x6041:00"]
    )
    (prob,) = pdo.validate(p, big)
    assert (
        "80 bits" in prob.message and "at most 64" in prob.message and "remove 16" in prob.message
    )
    many = with_pdo(p, cfg, direction="tx", number=1, entries=["0x6061:00"] * 9)
    text = messages(pdo.validate(p, many))
    assert "9 entries" in text and "at most 8" in text


@pytest.mark.parametrize(
    ("cob_id", "needle"),
    [
        (0x000, "NMT"),
        (0x080, "SYNC"),
        (0x085, "EMCY"),
        (0x581, "SDO"),
        (0x601, "SDO"),
        (0x701, "NMT error control"),
        (0x800, "11 bits"),
    ],
)
def test_bad_cob_ids(cob_id: int, needle: str) -> None:
    p = prof("cia402-generic")
    cfg = with_pdo(p, pdo.default_config(p, 1), direction="rx", number=2, cob_id=cob_id)
    (prob,) = pdo.validate(p, cfg)
    assert prob.field == "cob_id" and prob.pdo == "RPDO2" and needle in prob.message
    assert prob.section == "CiA 301 §7.3.5"


def test_two_enabled_pdos_on_one_cob_id() -> None:
    p = prof("cia402-generic")
    cfg = with_pdo(p, pdo.default_config(p, 1), direction="tx", number=2, cob_id=0x181)
    (prob,) = pdo.validate(p, cfg)
    assert prob.pdo == "TPDO2" and "TPDO1" in prob.message
    # A disabled PDO may keep the id.
    off = with_pdo(p, cfg, direction="tx", number=2, enabled=False)
    assert pdo.validate(p, off) == []


def test_smartris_transmission_types_and_event_timer() -> None:
    p = prof("smartris")
    cfg = pdo.default_config(p, 1)
    # 001 Table 2-11: 241-253 reserved for RPDOs.
    (prob,) = pdo.validate(p, with_pdo(p, cfg, direction="rx", number=1, transmission_type=252))
    assert prob.field == "transmission_type" and "001 §2-8" in (prob.section or "")
    # Table 2-10: 241-251 reserved for TPDOs; 252/253 (RTR) are fine.
    (prob,) = pdo.validate(p, with_pdo(p, cfg, direction="tx", number=1, transmission_type=245))
    assert prob.field == "transmission_type"
    assert pdo.validate(p, with_pdo(p, cfg, direction="tx", number=1, transmission_type=252)) == []
    # §2-8: the event timer only with 254/255, also for RPDOs on smartris.
    for d in ("rx", "tx"):
        c = with_pdo(p, cfg, direction=d, number=2, transmission_type=1, event_timer=10)
        (prob,) = pdo.validate(p, c)
        assert prob.field == "event_timer" and "254/255" in prob.message
    # No SYNC start value object (1800h has subs up to 5).
    (prob,) = pdo.validate(p, with_pdo(p, cfg, direction="tx", number=1, sync_start=2))
    assert prob.field == "sync_start" and "0x1800:06" in prob.message


def test_generic_sync_start_and_rtr_rules() -> None:
    p = prof("cia402-generic")
    cfg = pdo.default_config(p, 1)
    # CiA 301 §7.5.2.35: SYNC start only for cyclic synchronous types.
    (prob,) = pdo.validate(p, with_pdo(p, cfg, direction="tx", number=1, sync_start=3))
    assert prob.field == "sync_start" and "1-240" in prob.message
    assert (
        pdo.validate(
            p, with_pdo(p, cfg, direction="tx", number=1, sync_start=3, transmission_type=4)
        )
        == []
    )
    # RTR-only TPDO with RTR forbidden.
    c = with_pdo(p, cfg, direction="tx", number=1, transmission_type=253, rtr_allowed=False)
    (prob,) = pdo.validate(p, c)
    assert prob.field == "rtr_allowed"
    # Generic: the RPDO event timer is deadline monitoring, allowed with any type.
    assert (
        pdo.validate(
            p, with_pdo(p, cfg, direction="rx", number=1, transmission_type=1, event_timer=50)
        )
        == []
    )


def test_hiwin_limits_duplicates_and_assignment() -> None:
    p = prof("hiwin-e")
    cfg = pdo.default_config(p, 1)
    # 000 §2.8.1: the same object may not be mapped twice.
    dup = with_pdo(p, cfg, direction="rx", number=1, entries=["0x6040:00", "0x6040:00"])
    (prob,) = pdo.validate(p, dup)
    assert prob.entry == 1 and "only once" in prob.message
    # §2.2: at most 40 bytes per direction (and 8 entries, V1.7).
    big = [f"0x{i:04X}:00" for i in range(0x3201, 0x3209)] + ["0x3210:00", "0x3211:00"]
    probs = pdo.validate(p, with_pdo(p, cfg, direction="tx", number=1, entries=big))
    text = messages(probs)
    assert "10 entries" in text and "at most 8" in text
    eight_words = [f"0x{i:04X}:00" for i in range(0x3201, 0x3209)]  # 8 x 32 bits = 32 bytes
    assert pdo.validate(p, with_pdo(p, cfg, direction="tx", number=1, entries=eight_words)) == []
    # §2.8.2: one mapping object per sync manager.
    two = pdo.config_from_json(p, {"assignment": {"rx": [0x1600, 0x1601]}}, current=cfg)
    probs = pdo.validate(p, two)
    assert any(x.field == "assignment" and "assign one" in x.message for x in probs)
    # ... and 6040h would then be mapped twice in one direction.
    assert any("only once per direction" in x.message for x in probs)
    wrong = pdo.config_from_json(p, {"assignment": {"tx": [0x1600]}}, current=cfg)
    (prob,) = pdo.validate(p, wrong)
    assert "not a TX mapping object" in prob.message


def test_byte_limit_per_direction() -> None:
    # HIWIN 000 §2.2: 40 bytes per direction. With at most 8 entries of at most 32 bits
    # (V1.7) one mapping object stays at 32 bytes, so the limit is checked with a lower one.
    p = prof("hiwin-e")
    cfg = pdo.default_config(p, 1)
    heavy = [f"0x{i:04X}:00" for i in range(0x3201, 0x3209)]
    assert pdo.validate(p, with_pdo(p, cfg, direction="rx", number=1, entries=heavy)) == []
    small = p.model_copy(update={"pdo": p.pdo.model_copy(update={"max_bytes": 30})})
    probs = pdo.validate(small, with_pdo(small, cfg, direction="rx", number=1, entries=heavy))
    assert any("32 bytes" in x.message and "at most 30" in x.message for x in probs)


def test_lecsn_telegram_rules() -> None:
    p = prof("lecsn-t")
    cfg = pdo.apply_template(p, pdo.default_config(p, 1), "telegram-102")
    # 004 §20.3 note: the total must be exactly 48 bytes.
    short = with_pdo(
        p, cfg, direction="rx", number=1, entries=["0x6060:00", "reserved:8", "0x6040:00"]
    )
    (prob,) = pdo.validate(p, short)
    assert "4 bytes" in prob.message and "exactly 48" in prob.message
    assert "Reserved" in prob.message and prob.section and "§20.3" in prob.section
    # Reserved entries are 0, 8 or 16 bits.
    odd = with_pdo(
        p, cfg, direction="rx", number=1, entries=[{"index": 0, "subindex": 24, "bits": 24}]
    )
    assert any("0, 8 or 16" in x.message for x in pdo.validate(p, odd))
    # At most 24 entries in telegram 102 (48 bytes of 8-bit Reserved = 48 entries).
    many = with_pdo(p, cfg, direction="rx", number=1, entries=["reserved:8"] * 48)
    assert any("at most 24" in x.message for x in pdo.validate(p, many))
    # Unknown telegram.
    with pytest.raises(ValidationError) as info:
        pdo.config_from_json(p, {"telegram": 5}, current=cfg)
    assert info.value.field == "telegram"
    # Fixed telegrams refuse other entries.
    t1 = replace(pdo.apply_template(p, cfg, "telegram-1"))
    t1 = t1.replace_pdo(replace(t1.pdo("rx", 1), entries=(MapEntry(0x6040, 0, 16),)))
    (prob,) = pdo.validate(p, t1)
    assert "fixed layout" in prob.message and "102" in prob.message


def test_every_problem_says_what_to_do() -> None:
    p = prof("hiwin-e")
    cfg = pdo.default_config(p, 1)
    bad = with_pdo(
        p, cfg, direction="rx", number=1, entries=["0x6041:00", "0x6040:00", "0x6040:00"]
    )
    probs = pdo.validate(p, bad)
    assert probs
    for x in probs:
        assert x.section, x
        assert ";" in x.message or "," in x.message, x.message  # problem; remedy
    with pytest.raises(PdoRefused) as info:
        pdo.plan(p, cfg, bad, nmt_state="preop")
    assert info.value.problems == probs
    assert info.value.to_dict()["problems"] == [x.to_dict() for x in probs]


def test_pdo_refused_is_http_422() -> None:
    from servodesk.api.errors import status_for

    assert status_for(PdoRefused("x", problems=[])) == 422


# --------------------------------------------------------------------------------------------
# Layout, pack, unpack


def test_layout_offsets_and_frame_length() -> None:
    p = prof("hiwin-e")
    cfg = pdo.default_config(p, 1)
    tx = cfg.active("tx")[0]
    slots = pdo.layout(p, tx)
    assert [(s.offset_bits // 8, s.bits) for s in slots] == [
        (0, 16), (2, 16), (4, 8), (5, 32), (9, 16), (11, 32), (15, 32), (19, 32)
    ]  # fmt: skip
    assert slots[3].name == p.spec(A(0x6064, 0)).name  # type: ignore[union-attr]
    assert pdo.frame_length(p, tx) == 24  # 23 bytes -> CAN FD 24
    assert pdo.frame_length(p, cfg.active("rx")[0]) == 16  # 13 -> 16
    g = prof("cia402-generic")
    assert pdo.frame_length(g, pdo.default_config(g, 1).pdo("rx", 2)) == 6  # classic CAN
    lp = prof("lecsn-t")
    l3 = pdo.apply_template(lp, pdo.default_config(lp, 1), "telegram-103")
    assert pdo.frame_length(lp, l3.pdo("tx", 1)) == 64  # 60 -> 64
    l2 = pdo.apply_template(lp, pdo.default_config(lp, 1), "telegram-102")
    assert pdo.frame_length(lp, l2.pdo("tx", 1)) == 48


def test_pack_unpack_little_endian_signed() -> None:
    p = prof("cia402-generic")
    rpdo = pdo.default_config(p, 1).pdo("rx", 2)  # 6040h, 607Ah
    data = pdo.pack(p, rpdo, {A(0x6040, 0): 0x000F, A(0x607A, 0): -2})
    assert data == bytes([0x0F, 0x00, 0xFE, 0xFF, 0xFF, 0xFF])
    assert pdo.unpack(p, rpdo, data) == {A(0x6040, 0): 15, A(0x607A, 0): -2}
    # Missing values are 0; bytes past the mapping are ignored; a short frame is refused.
    assert pdo.pack(p, rpdo, {}) == bytes(6)
    assert pdo.unpack(p, rpdo, data + b"\0\0")[A(0x607A, 0)] == -2
    with pytest.raises(ValidationError, match="5 bytes received"):
        pdo.unpack(p, rpdo, data[:5])
    with pytest.raises(ValidationError):
        pdo.pack(p, rpdo, {A(0x6040, 0): 70000})


def test_pack_big_endian_telegram_102() -> None:
    # 004 §20.1.2: big-endian; telegram 102 byte 0 mode, byte 1 Reserved, 2-3 controlword ...
    p = prof("lecsn-t")
    cfg = pdo.apply_template(p, pdo.default_config(p, 1), "telegram-102")
    rx = cfg.pdo("rx", 1)
    data = pdo.pack(p, rx, {A(0x6060, 0): -1, A(0x6040, 0): 0x1234, A(0x607A, 0): 0x01020304})
    assert len(data) == 48
    assert data[0] == 0xFF and data[1] == 0 and data[2:4] == b"\x12\x34"
    assert data[16:20] == b"\x01\x02\x03\x04"  # target position at bytes 16-19 (§20.3)
    back = pdo.unpack(p, rx, data)
    assert back[A(0x6060, 0)] == -1 and back[A(0x607A, 0)] == 0x01020304
    assert A(0, 8) not in back  # Reserved entries carry nothing


def test_pack_sub_byte_entries_and_reals() -> None:
    # CiA 301 §7.4.7.1: a BOOLEAN mapped as 1 bit; entries fill from bit 0 of byte 0.
    def obj(index: int, dt: str) -> dict[str, object]:
        return {"index": index, "name": dt, "data_type": dt, "access": "rw", "pdo_mapping": "both"}

    p = parse_profile(
        {
            "id": "bits",
            "name": "bits",
            "vendor": "t",
            "fieldbus": "canopen",
            "pdo": {"rpdo_count": 1, "tpdo_count": 1},
            "objects": [
                obj(0x2000, "BOOLEAN"),
                obj(0x2001, "BOOLEAN"),
                obj(0x2002, "INTEGER8"),
                obj(0x2003, "REAL32"),
            ],
        }
    )
    entries = (MapEntry(0x2000, 0, 1), MapEntry(0x2001, 0, 1), MapEntry(0x2002, 0, 8))
    tp = pdo.Pdo(Direction.TX, 1, 0x1A00, 0x1800, pdo.PdoComm(0x181, True), entries)
    data = pdo.pack(p, tp, {A(0x2000, 0): False, A(0x2001, 0): True, A(0x2002, 0): -3})
    assert data == bytes([0b10 | (0xFD << 2) & 0xFF, 0xFD >> 6])
    assert pdo.unpack(p, tp, data) == {A(0x2000, 0): False, A(0x2001, 0): True, A(0x2002, 0): -3}
    rp = replace(tp, entries=(MapEntry(0x2003, 0, 32),))
    raw = pdo.pack(p, rp, {A(0x2003, 0): 1.5})
    assert raw == struct.pack("<f", 1.5) and pdo.unpack(p, rp, raw) == {A(0x2003, 0): 1.5}
    assert [s.offset_bits for s in pdo.layout(p, tp)] == [0, 1, 2]


# --------------------------------------------------------------------------------------------
# JSON input


def test_config_from_json_accepts_addresses_and_triples() -> None:
    p = prof("cia402-generic")
    cur = pdo.default_config(p, 1)
    a = with_pdo(p, cur, direction="tx", number=3, entries=["0x6041:00", "606Ch"])
    b = with_pdo(
        p,
        cur,
        direction="tx",
        number=3,
        entries=[{"index": 0x6041, "subindex": 0, "bits": 16}, {"index": "0x606C", "subindex": 0}],
    )
    assert a == b and a.pdo("tx", 3).entries[1] == MapEntry(0x606C, 0, 32)
    assert a.pdo("tx", 1) == cur.pdo("tx", 1)  # left out: unchanged


def _rx1(**kw: object) -> dict[str, object]:
    return {"pdos": [{"direction": "rx", "number": 1, **kw}]}


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"pdos": [{"direction": "up", "number": 1}]}, "pdos[0].direction"),
        ({"pdos": [{"direction": "rx", "number": 9}]}, "pdos[0].number"),
        (_rx1(entries=["0x9999:00"]), "pdos[0].entries[0]"),
        (_rx1(entries=["nonsense"]), "pdos[0].entries[0]"),
        (_rx1(transmission_type=300), "pdos[0].transmission_type"),
        (_rx1(cob_id="x"), "pdos[0].cob_id"),
        (_rx1(enabled="yes"), "pdos[0].enabled"),
        (_rx1(colour=1), "pdos[0].colour"),
        ({**_rx1(), "telegram": 102}, "telegram"),
        ({**_rx1(), "assignment": {"rx": [0x1600]}}, "assignment"),
        ({"extra": 1}, "extra"),
    ],
)
def test_config_from_json_errors_name_the_field(body: dict[str, object], field: str) -> None:
    p = prof("cia402-generic")
    with pytest.raises(ValidationError) as info:
        pdo.config_from_json(p, body, current=pdo.default_config(p, 1))
    assert info.value.field == field, info.value.message


def test_config_from_json_without_current_needs_every_pdo() -> None:
    p = prof("smartris")
    with pytest.raises(ValidationError, match="missing"):
        pdo.config_from_json(p, {"pdos": [{"direction": "rx", "number": 1, "entries": []}]})


def test_mappable_by_direction() -> None:
    p = prof("smartris")
    rx = {str(s.address) for s in pdo.mappable(p, "rx")}
    tx = {str(s.address) for s in pdo.mappable(p, Direction.TX)}
    assert {"0x6040:00", "0x60FF:00", "0x6071:00", "0x60FE:01"} <= rx
    assert {"0x6041:00", "0x6064:00", "0x606C:00", "0x60FD:00"} <= tx
    assert not rx & tx


# --------------------------------------------------------------------------------------------
# Exports


def test_export_csv_one_row_per_slot() -> None:
    p = prof("smartris")
    cfg = pdo.default_config(p, 2)
    rows = list(csv.DictReader(io.StringIO(pdo_export.export(p, cfg, "csv", 2))))
    assert list(rows[0]) == [
        "pdo", "cob_id", "byte_offset", "bit_offset", "bits", "address", "name", "type", "unit"
    ]  # fmt: skip
    rpdo1 = [r for r in rows if r["pdo"] == "RPDO1"]
    assert [(r["address"], r["byte_offset"], r["bits"]) for r in rpdo1] == [
        ("0x6040:00", "0", "16"),
        ("0x6060:00", "2", "8"),
        ("0x60FE:01", "3", "32"),
    ]
    assert rpdo1[0]["cob_id"] == "0x202" and rpdo1[0]["type"] == "UNSIGNED16"
    assert len(rows) == sum(len(x.entries) for d in Direction for x in cfg.active(d))


def test_export_dcf_parameter_values() -> None:
    p = prof("cia402-generic")
    cfg = pdo.apply_template(p, pdo.default_config(p, 4), "pv-velocity")
    text = pdo_export.export(p, cfg, "dcf", 4)
    assert "[DeviceComissioning]\nNodeID=0x04" in text
    sect = text.split("[1600sub3]\n", 1)[1].split("\n\n", 1)[0]
    assert "ParameterValue=0x60FF0020" in sect
    assert "ParameterValue=0x00000204" in text.split("[1400sub1]\n", 1)[1].split("\n\n", 1)[0]
    assert "[1A00sub0]" in text and "[1800sub2]" in text
    with pytest.raises(ValidationError):
        pdo_export.export(p, cfg, "dcf", 0)


def test_export_esi_fragment() -> None:
    p = prof("hiwin-e")
    cfg = pdo.default_config(p, 1)
    root = ET.fromstring(f"<Device>{pdo_export.export(p, cfg, 'esi', 1)}</Device>")
    rx = root.findall("RxPdo")
    assert len(rx) == 4 and len(root.findall("TxPdo")) == 4
    assigned = [x for x in rx if x.get("Sm") == "2"]
    assert [x.findtext("Index") for x in assigned] == ["#x1600"]
    first = assigned[0].find("Entry")
    assert first is not None
    assert first.findtext("Index") == "#x6040" and first.findtext("SubIndex") == "0"
    assert first.findtext("BitLen") == "16" and first.findtext("DataType") == "UINT"
    assert first.findtext("Name")


def test_export_json_has_layout() -> None:
    p = prof("lecsn-t")
    cfg = pdo.apply_template(p, pdo.default_config(p, 1), "telegram-102")
    body = json.loads(pdo_export.export(p, cfg, "json", 1))
    assert body["telegram"] == 102
    assert pdo.config_from_json(p, {k: body[k] for k in ("pdos", "telegram")}) == cfg
    tx = next(x for x in body["layout"] if x["direction"] == "tx")
    assert tx["bytes"] == 48 and tx["entries"][1]["name"] == "Reserved"


def test_profile_check_catches_bad_templates() -> None:
    from servodesk.domain.profile_loader import check_profile

    p = prof("smartris")
    bad = p.pdo.model_copy(
        update={
            "templates": (
                *p.pdo.templates,
                p.pdo.templates[0].model_copy(
                    update={
                        "id": "broken",
                        "pdos": (
                            p.pdo.templates[0]
                            .pdos[0]
                            .model_copy(
                                update={"entries": (p.pdo.templates[0].pdos[4].entries or ())}
                            ),
                        ),
                    }
                ),
            )
        }
    )
    problems = check_profile(p.model_copy(update={"pdo": bad}))
    assert any("broken" in x and "not mappable in rx" in x for x in problems), problems
