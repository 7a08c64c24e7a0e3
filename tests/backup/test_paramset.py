"""Pure parameter-set logic: file format byte for byte, refusals, ordering, PDO procedure,
preflight and name mapping (no bus)."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from servodesk.domain import paramset, paramset_compare, restore_plan
from servodesk.domain.address import ObjectAddress as A
from servodesk.domain.datatypes import DataType
from servodesk.domain.paramset import Entry, ParameterSet
from servodesk.domain.restore_plan import DriveFacts
from servodesk.errors import ValidationError
from tests.backup.conftest import catalog

CAT = catalog()
GENERIC = CAT.get("cia402-generic")


def sample() -> ParameterSet:
    return ParameterSet(
        profile_id="cia402-generic",
        profile_version="1",
        time="2025-01-01T00:00:00.000Z",
        entries=(
            Entry(
                A(0x6081),
                "Profile velocity",
                DataType.UNSIGNED32,
                (200000).to_bytes(4, "little"),
                "rpm",
            ),
            Entry(
                A(0x607C),
                "Home offset",
                DataType.INTEGER32,
                (-5).to_bytes(4, "little", signed=True),
            ),
            Entry(A(0x1008), "Name", DataType.VISIBLE_STRING, "Drive ä".encode("latin-1")),
        ),
        label="after tuning",
        identity={"vendor_id": 1, "product_code": 2, "serial": 3},
        firmware="1.0",
        bus={"interface": "virtual", "channel": "x", "node_id": 1, "bitrate": None},
        drive_key="00000001-00000002-3",
    )


def test_file_round_trip_is_byte_for_byte() -> None:
    data = paramset.dumps(sample(), "servodesk test")
    back = paramset.loads(data)
    assert back.entries == sample().entries
    assert paramset.dumps(back, "servodesk test") == data
    doc = json.loads(data)
    assert doc["schema_version"] == 1 and doc["format"] == "servodesk-backup"
    assert doc["entries"][1] == {
        "address": "0x607C:00",
        "name": "Home offset",
        "data_type": "INTEGER32",
        "raw_hex": "fbffffff",
        "value": -5,
        "unit": None,
    }


def _rewrite(data: bytes, change: object) -> bytes:
    doc = json.loads(data)
    change(doc)  # type: ignore[operator]
    doc["checksum"] = paramset.checksum(doc)
    return json.dumps(doc).encode()


@pytest.mark.parametrize(
    ("mangle", "words"),
    [
        (lambda d: d[: len(d) // 2], "truncated or corrupt"),
        (lambda d: b"\xff\xfe" + d, "not UTF-8"),
        (lambda d: d.replace(b'"fbffffff"', b'"fbfffffe"'), "checksum mismatch"),
        (lambda d: _rewrite(d, lambda doc: doc.update(schema_version=7)), "schema version 7"),
        (lambda d: _rewrite(d, lambda doc: doc.pop("format")), "not a servodesk backup"),
        (
            lambda d: _rewrite(d, lambda doc: doc["entries"][1].update(value=4)),
            "disagrees with raw_hex",
        ),
        (
            lambda d: _rewrite(d, lambda doc: doc["entries"][0].update(raw_hex="00")),
            "needs 4 bytes",
        ),
    ],
)
def test_damaged_files_are_refused_with_a_clear_message(mangle: object, words: str) -> None:
    data = paramset.dumps(sample(), "t")
    with pytest.raises(ValidationError) as err:
        paramset.loads(mangle(data), "x.json")  # type: ignore[operator]
    assert words in err.value.message
    assert err.value.message.startswith("x.json: ")


def test_configurable_leaves_out_commands_and_process_values() -> None:
    addrs = {s.address for s in paramset.configurable(GENERIC)}
    assert A(0x1010, 1) not in addrs and A(0x1011, 1) not in addrs  # store/restore commands
    assert A(0x6040) not in addrs and A(0x6064) not in addrs  # controlword, actual position
    assert A(0x6081) in addrs and A(0x1600, 1) in addrs
    lecsn = CAT.get("lecsn-t")
    lecsn_addrs = {s.address for s in paramset.configurable(lecsn)}
    assert A(0x607B, 1) not in lecsn_addrs  # quirk auto_set_objects
    assert A(0x2D34) not in lecsn_addrs  # quirk parameter_activation (a command)


def test_write_order_puts_unit_factors_and_limits_first() -> None:
    smartris = CAT.get("smartris")
    order = restore_plan.write_order(
        smartris, [A(0x6081), A(0x6084), A(0x6083), A(0x607F), A(0x6097, 2), A(0x6096, 1)]
    )
    # Quirk unit_change_sequence (001 §11-1) order first, then the limit 607Fh, then the rest.
    assert order == [A(0x6096, 1), A(0x6097, 2), A(0x6083), A(0x6084), A(0x607F), A(0x6081)]


def u32(v: int) -> bytes:
    return v.to_bytes(4, "little")


def test_pdo_restore_follows_the_cia301_procedure() -> None:
    cur = {
        A(0x1400, 1): u32(0x201),
        A(0x1400, 2): b"\xff",
        A(0x1600, 0): b"\x02",
        A(0x1600, 1): u32(0x60400010),
        A(0x1600, 2): u32(0x60600008),
    }
    targets = dict(cur)
    targets[A(0x1400, 2)] = b"\x01"
    targets[A(0x1600, 1)] = u32(0x607A0020)
    to_write = {a: targets[a] for a in (A(0x1400, 2), A(0x1600, 1))}
    steps = restore_plan.plan_writes(GENERIC, to_write, targets, cur)
    got = [(s.address, s.raw.hex(), s.entry) for s in steps]
    assert got == [
        (A(0x1400, 1), u32(0x80000201).hex(), None),  # PDO invalid (bit 31)
        (A(0x1400, 2), "01", A(0x1400, 2)),  # communication parameter while invalid
        (A(0x1600, 0), "00", None),  # mapping sub 0 = 0
        (A(0x1600, 1), u32(0x607A0020).hex(), A(0x1600, 1)),  # entries
        (A(0x1600, 0), "02", None),  # sub 0 = n
        (A(0x1400, 1), u32(0x201).hex(), None),  # COB-ID back as in the set
    ]


def test_plain_parameters_come_before_pdos() -> None:
    cur = {A(0x1400, 1): u32(0x80000201), A(0x6081): u32(1)}
    targets = {A(0x1400, 1): u32(0x201), A(0x6081): u32(2)}
    steps = restore_plan.plan_writes(GENERIC, targets, targets, cur)
    assert [s.address for s in steps] == [A(0x6081), A(0x1400, 1)]
    assert steps[-1].entry == A(0x1400, 1)


def facts(**kw: object) -> DriveFacts:
    base = {
        "profile": GENERIC,
        "identity": {"vendor_id": 1, "product_code": 2, "serial": 4},
        "firmware": "1.0",
        "state": "switch_on_disabled",
        "nmt": "preop",
        "current": {},
    }
    base.update(kw)
    return DriveFacts(**base)  # type: ignore[arg-type]


def test_preflight_lists_every_problem_at_once() -> None:
    ps = sample()
    bad = replace(
        ps,
        entries=(
            *ps.entries,
            # 6098h homing method: INTEGER8 value 127 is not a documented method
            Entry(A(0x6060), "Modes of operation", DataType.INTEGER8, b"\x7f"),
            Entry(A(0x7777), "Nothing", DataType.UNSIGNED8, b"\x00"),
        ),
    )
    pf = restore_plan.preflight(bad, facts(state="operation_enabled"))
    assert not pf.ok
    msgs = [p.message for p in pf.problems]
    assert any("drive not enabled" in m for m in msgs)
    assert any("0x7777:00" in m and "not an object" in m for m in msgs)
    assert any("0x6060:00" in m and "not an allowed value" in m for m in msgs)
    assert len(msgs) == 3


def test_preflight_counts_and_replacement_drive() -> None:
    ps = sample()
    cur = {ps.entries[0].address: ps.entries[0].raw, ps.entries[1].address: u32(0)}
    pf = restore_plan.preflight(ps, facts(current=cur))
    assert pf.ok, pf.problems
    c = pf.counts()
    assert c["unchanged"] == 1 and c["to_write"] == 1 and c["read_only_skipped"] == 1
    assert any("serial 3" in w and "serial 4" in w for w in pf.warnings)


def test_preflight_refuses_another_family_unless_mapped_by_name() -> None:
    smartris = CAT.get("smartris")
    ps = sample()
    pf = restore_plan.preflight(ps, facts(profile=smartris))
    assert not pf.ok
    assert "another drive family" in pf.problems[0].message
    pf = restore_plan.preflight(ps, facts(profile=smartris), map_names=True)
    rows = {str(m.address): m for m in pf.mapping or []}
    assert rows["0x6081:00"].target == A(0x6081)
    assert rows["0x1008:00"].target is not None or rows["0x1008:00"].reason


def test_writable_in_is_checked_against_the_state() -> None:
    assert restore_plan.state_allows(("preop",), "switch_on_disabled", "operational") is False
    assert restore_plan.state_allows(("preop",), "switch_on_disabled", "preop") is True
    assert restore_plan.state_allows(("preop",), None, "unknown") is None
    assert restore_plan.state_allows(("switch_on_disabled",), "operation_enabled", "preop") is False


def test_compare_groups_differences() -> None:
    a = sample()
    b = replace(a, entries=(a.entries[0], replace(a.entries[1], raw=u32(7))))
    diffs, same = paramset_compare.compare(a.entries, b.entries, GENERIC)
    assert same == 1
    kinds = {d["address"]: d["kind"] for d in diffs}
    assert kinds == {"0x607C:00": "changed", "0x1008:00": "only_a"}
    d = next(x for x in diffs if x["address"] == "0x607C:00")
    assert (d["a_value"], d["b_value"], d["b_raw_hex"]) == (-5, 7, "07000000")
