"""Golden plans: the exact ordered writes of each family's remapping procedure.

Each expected list is written out literally, so any change to the order or a value of a
planned write (which a real drive may refuse) shows up here. Node id 5 for the CANopen
families, so COB-IDs read 0x205, 0x185, ...
"""

from __future__ import annotations

from pathlib import Path

import pytest

from servodesk.domain import pdo
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import PdoRefused

PROFILES = Path(__file__).resolve().parents[2] / "profiles"
CATALOG = ProfileCatalog([PROFILES])

Golden = list[tuple[str, str] | tuple[str, str, int]]


def prof(pid: str) -> DeviceProfile:
    return CATALOG.get(pid)


def steps(plan: pdo.Plan) -> Golden:
    out: Golden = []
    for s in plan.steps:
        if s.kind == "nmt":
            assert s.command is not None
            out.append(("nmt", s.command))
        else:
            out.append(("write", str(s.address), s.value))
        # Every step says why, with the clause or manual section it follows.
        assert "§" in s.why, s.why
    return out


def test_canopen_template_from_operational_cia301_order() -> None:
    # CiA 301 §7.5.2.35/36: NMT pre-operational; per changed PDO: COB-ID bit 31 = 1, mapping
    # sub 0 = 0, entries, sub 0 = n, communication parameters, COB-ID bit 31 = 0; NMT back.
    p = prof("cia402-generic")
    cur = pdo.default_config(p, 5)
    plan = pdo.plan(p, cur, pdo.apply_template(p, cur, "pv-velocity"), nmt_state="operational")
    assert steps(plan) == [
        ("nmt", "preop"),
        ("write", "0x1400:01", 0x80000205),
        ("write", "0x1600:00", 0x0),
        ("write", "0x1600:01", 0x60400010),
        ("write", "0x1600:02", 0x60600008),
        ("write", "0x1600:03", 0x60FF0020),
        ("write", "0x1600:00", 0x3),
        ("write", "0x1400:02", 0x1),
        ("write", "0x1400:01", 0x205),
        ("write", "0x1800:01", 0x80000185),
        ("write", "0x1A00:00", 0x0),
        ("write", "0x1A00:01", 0x60410010),
        ("write", "0x1A00:02", 0x60610008),
        ("write", "0x1A00:03", 0x606C0020),
        ("write", "0x1A00:00", 0x3),
        ("write", "0x1800:02", 0x1),
        ("write", "0x1800:01", 0x185),
        ("nmt", "start"),
    ]
    assert plan.touched == ("RPDO1", "TPDO1")


def test_canopen_cob_id_change_and_disable_from_stopped() -> None:
    # The old id is made invalid first, the new id written last; a PDO switched off stays
    # invalid; a stopped node is put back into stopped.
    p = prof("cia402-generic")
    cur = pdo.default_config(p, 5)
    desired = pdo.config_from_json(
        p,
        {
            "pdos": [
                {"direction": "tx", "number": 2, "cob_id": 0x3A0},
                {"direction": "rx", "number": 4, "enabled": False},
            ]
        },
        current=cur,
    )
    plan = pdo.plan(p, cur, desired, nmt_state="stopped")
    assert steps(plan) == [
        ("nmt", "preop"),
        ("write", "0x1403:01", 0x80000505),
        ("write", "0x1801:01", 0x80000285),
        ("write", "0x1801:01", 0x3A0),
        ("nmt", "stop"),
    ]
    assert plan.touched == ("RPDO4", "TPDO2")


def test_canopen_no_change_is_an_empty_plan() -> None:
    p = prof("cia402-generic")
    cur = pdo.default_config(p, 5)
    plan = pdo.plan(p, cur, cur, nmt_state="operational")
    assert plan.steps == () and plan.touched == ()


def test_canopen_full_plan_rewrites_every_pdo() -> None:
    # Rollback: every PDO is disabled, remapped and its parameters written, whatever the
    # drive holds; timers going to 0 before the type (smartris 001 §2-8 ordering).
    p = prof("cia402-generic")
    cfg = pdo.default_config(p, 5)
    plan = pdo.full_plan(p, cfg, nmt_state="preop")
    expected: Golden = []
    rx_maps = {
        1: [0x60400010],
        2: [0x60400010, 0x607A0020],
        3: [0x60400010, 0x60FF0020],
        4: [0x60400010, 0x60710010],
    }
    for n, entries in rx_maps.items():
        cob = 0x100 * (n + 1) + 5
        expected += [
            ("write", f"0x140{n - 1}:01", 0x80000000 | cob),
            ("write", f"0x160{n - 1}:00", 0),
            *[("write", f"0x160{n - 1}:{k:02X}", e) for k, e in enumerate(entries, 1)],
            ("write", f"0x160{n - 1}:00", len(entries)),
            ("write", f"0x140{n - 1}:03", 0),
            ("write", f"0x140{n - 1}:05", 0),
            ("write", f"0x140{n - 1}:02", 0xFF),
            ("write", f"0x140{n - 1}:01", cob),
        ]
    tx_maps = {
        1: [0x60410010],
        2: [0x60410010, 0x60640020],
        3: [0x60410010, 0x606C0020],
        4: [0x60410010, 0x60770010],
    }
    for n, entries in tx_maps.items():
        cob = 0x100 * n + 0x80 + 5
        expected += [
            ("write", f"0x180{n - 1}:01", 0x80000000 | cob),
            ("write", f"0x1A0{n - 1}:00", 0),
            *[("write", f"0x1A0{n - 1}:{k:02X}", e) for k, e in enumerate(entries, 1)],
            ("write", f"0x1A0{n - 1}:00", len(entries)),
            ("write", f"0x180{n - 1}:03", 0),
            ("write", f"0x180{n - 1}:05", 0),
            ("write", f"0x180{n - 1}:06", 0),
            ("write", f"0x180{n - 1}:02", 0xFF),
            ("write", f"0x180{n - 1}:01", cob),
        ]
    assert steps(plan) == expected
    assert plan.touched == tuple(f"RPDO{n}" for n in range(1, 5)) + tuple(
        f"TPDO{n}" for n in range(1, 5)
    )


def test_smartris_event_driven_tpdos_in_preop() -> None:
    # 001 §2-8: the event timer is written while the PDO is invalid and after the type is
    # 254/255; already in pre-operational, so no NMT command.
    p = prof("smartris")
    cur = pdo.default_config(p, 1)
    plan = pdo.plan(p, cur, pdo.apply_template(p, cur, "event-tpdos"), nmt_state="preop")
    assert steps(plan) == [
        ("write", "0x1801:01", 0x80000281),
        ("write", "0x1801:02", 0xFE),
        ("write", "0x1801:05", 0x14),
        ("write", "0x1801:01", 0x281),
        ("write", "0x1802:01", 0x80000381),
        ("write", "0x1802:02", 0xFE),
        ("write", "0x1802:05", 0x14),
        ("write", "0x1802:01", 0x381),
        ("write", "0x1803:01", 0x80000481),
        ("write", "0x1803:02", 0xFE),
        ("write", "0x1803:05", 0x14),
        ("write", "0x1803:01", 0x481),
    ]
    assert plan.touched == ("TPDO2", "TPDO3", "TPDO4")


def test_smartris_event_timer_cleared_before_leaving_type_254() -> None:
    # 001 §2-8: the event timer only with 254/255, so it goes to 0 before the type changes.
    p = prof("smartris")
    ev = pdo.apply_template(p, pdo.default_config(p, 1), "event-tpdos")
    back = pdo.config_from_json(
        p,
        {"pdos": [{"direction": "tx", "number": 2, "transmission_type": 1, "event_timer": 0}]},
        current=ev,
    )
    assert steps(pdo.plan(p, ev, back, nmt_state="operational")) == [
        ("nmt", "preop"),
        ("write", "0x1801:01", 0x80000281),
        ("write", "0x1801:05", 0x0),
        ("write", "0x1801:02", 0x1),
        ("write", "0x1801:01", 0x281),
        ("nmt", "start"),
    ]


def test_hiwin_append_object_like_the_manual_example() -> None:
    # 000 §3.1.2: 1C12:00 = 0, 1600:00 = 0, entries, 1600:00 = n, 1C12:01 = 1600h,
    # 1C12:00 = 1 (the manual's worked example appends 607Fh as entry 6). 1C13h untouched.
    p = prof("hiwin-e")
    cur = pdo.default_config(p, 1)
    desired = pdo.config_from_json(
        p,
        {
            "pdos": [
                {
                    "direction": "rx",
                    "number": 1,
                    "entries": [
                        "0x6040:00",
                        "0x6060:00",
                        "0x607A:00",
                        "0x60B8:00",
                        "0x60FE:01",
                        "0x607F:00",
                    ],
                }
            ]
        },
        current=cur,
    )
    plan = pdo.plan(p, cur, desired, nmt_state="preop")
    assert steps(plan) == [
        ("write", "0x1C12:00", 0x0),
        ("write", "0x1600:00", 0x0),
        ("write", "0x1600:01", 0x60400010),
        ("write", "0x1600:02", 0x60600008),
        ("write", "0x1600:03", 0x607A0020),
        ("write", "0x1600:04", 0x60B80010),
        ("write", "0x1600:05", 0x60FE0120),
        ("write", "0x1600:06", 0x607F0020),
        ("write", "0x1600:00", 0x6),
        ("write", "0x1C12:01", 0x1600),
        ("write", "0x1C12:00", 0x1),
    ]
    assert plan.touched == ("RxPDO 1600h",)


def test_hiwin_template_remaps_and_reassigns_both_sync_managers() -> None:
    p = prof("hiwin-e")
    cur = pdo.default_config(p, 1)
    plan = pdo.plan(p, cur, pdo.apply_template(p, cur, "pv-velocity"), nmt_state="operational")
    assert steps(plan) == [
        ("nmt", "preop"),
        ("write", "0x1C12:00", 0x0),
        ("write", "0x1601:00", 0x0),
        ("write", "0x1601:01", 0x60400010),
        ("write", "0x1601:02", 0x60600008),
        ("write", "0x1601:03", 0x60FF0020),
        ("write", "0x1601:04", 0x60830020),
        ("write", "0x1601:05", 0x60840020),
        ("write", "0x1601:00", 0x5),
        ("write", "0x1C12:01", 0x1601),
        ("write", "0x1C12:00", 0x1),
        ("write", "0x1C13:00", 0x0),
        ("write", "0x1A01:00", 0x0),
        ("write", "0x1A01:01", 0x603F0010),
        ("write", "0x1A01:02", 0x60410010),
        ("write", "0x1A01:03", 0x60610008),
        ("write", "0x1A01:04", 0x60640020),
        ("write", "0x1A01:05", 0x606C0020),
        ("write", "0x1A01:06", 0x60FD0020),
        ("write", "0x1A01:00", 0x6),
        ("write", "0x1C13:01", 0x1A01),
        ("write", "0x1C13:00", 0x1),
        ("nmt", "start"),
    ]
    assert plan.touched == ("RxPDO 1601h", "RxPDO 1600h", "TxPDO 1A01h", "TxPDO 1A00h")


def test_hiwin_assignment_only() -> None:
    # Set 2 is already in 1601h/1A01h from the factory: only the assignment changes.
    p = prof("hiwin-e")
    cur = pdo.default_config(p, 1)
    plan = pdo.plan(p, cur, pdo.apply_template(p, cur, "set2-csv"), nmt_state="preop")
    assert steps(plan) == [
        ("write", "0x1C12:00", 0x0),
        ("write", "0x1C12:01", 0x1601),
        ("write", "0x1C12:00", 0x1),
        ("write", "0x1C13:00", 0x0),
        ("write", "0x1C13:01", 0x1A01),
        ("write", "0x1C13:00", 0x1),
    ]


def test_lecsn_custom_actual_value_mapping_on_the_twin() -> None:
    # 004 §20.3 (3): telegram 102 stays, the actual-value mapping changes, 48 bytes exactly.
    p = prof("lecsn-t")
    cur = pdo.apply_template(p, pdo.default_config(p, 1), "telegram-102")
    entries = [
        "0x6061:00",
        "reserved:8",
        "0x6041:00",
        "0x6064:00",
        "0x606C:00",
        "0x6077:00",
        "reserved:16",
        "0x60F4:00",
        "0x60FD:00",
        "0x60B9:00",
        "0x60BA:00",
        "0x60BB:00",
        "0x60BC:00",
        "0x60BD:00",
        "0x2D11:00",
        "reserved:16",
        "reserved:16",
    ]
    desired = pdo.config_from_json(
        p, {"pdos": [{"direction": "tx", "number": 1, "entries": entries}]}, current=cur
    )
    plan = pdo.plan(p, cur, desired, nmt_state="operational")
    assert steps(plan) == [
        ("nmt", "preop"),
        ("write", "0x1A00:00", 0x0),
        ("write", "0x1A00:01", 0x60610008),
        ("write", "0x1A00:02", 0x808),
        ("write", "0x1A00:03", 0x60410010),
        ("write", "0x1A00:04", 0x60640020),
        ("write", "0x1A00:05", 0x606C0020),
        ("write", "0x1A00:06", 0x60770010),
        ("write", "0x1A00:07", 0x1010),
        ("write", "0x1A00:08", 0x60F40020),
        ("write", "0x1A00:09", 0x60FD0020),
        ("write", "0x1A00:0A", 0x60B90010),
        ("write", "0x1A00:0B", 0x60BA0020),
        ("write", "0x1A00:0C", 0x60BB0020),
        ("write", "0x1A00:0D", 0x60BC0020),
        ("write", "0x1A00:0E", 0x60BD0020),
        ("write", "0x1A00:0F", 0x2D110010),
        ("write", "0x1A00:10", 0x1010),
        ("write", "0x1A00:11", 0x1010),
        ("write", "0x1A00:00", 0x11),
        ("nmt", "start"),
    ]
    assert plan.touched == ("actual-value telegram",)


def test_lecsn_selecting_a_fixed_telegram_writes_only_p922() -> None:
    p = prof("lecsn-t")
    cur = pdo.apply_template(p, pdo.default_config(p, 1), "telegram-102")
    plan = pdo.plan(p, cur, pdo.apply_template(p, cur, "telegram-100"), nmt_state="preop")
    assert steps(plan) == [("write", "0x039A:00", 100)]


def test_lecsn_telegram_then_mapping_from_telegram_1() -> None:
    # P922 first (the mapping belongs to the selected telegram), then 1600h and 1A00h.
    p = prof("lecsn-t")
    cur = pdo.default_config(p, 1)
    assert cur.telegram == 1
    plan = pdo.plan(p, cur, pdo.apply_template(p, cur, "telegram-102"), nmt_state="preop")
    got = steps(plan)
    rx = [
        0x60600008, 0x00000808, 0x60400010, 0x2D010010, 0x2D020010, 0x2D030010,
        0x60710010, 0x60870020, 0x607A0020, 0x60FF0020, 0x2D200020, 0x60810020,
        0x60830020, 0x60840020, 0x60B80010, 0x00001010, 0x00001010, 0x00001010,
    ]  # fmt: skip
    tx = [
        0x60610008, 0x00000808, 0x60410010, 0x2D110010, 0x2D120010, 0x2D130010,
        0x60770010, 0x60FD0020, 0x60640020, 0x606C0020, 0x60F40020, 0x60BA0020,
        0x60BB0020, 0x60BC0020, 0x60BD0020, 0x60B90010, 0x00001010,
    ]  # fmt: skip
    expected: Golden = [("write", "0x039A:00", 102)]
    for index, entries in ((0x1600, rx), (0x1A00, tx)):
        expected.append(("write", f"0x{index:04X}:00", 0))
        expected += [("write", f"0x{index:04X}:{k:02X}", e) for k, e in enumerate(entries, 1)]
        expected.append(("write", f"0x{index:04X}:00", len(entries)))
    assert got == expected


def test_fixed_family_refuses_any_change_with_the_manual_section() -> None:
    p = prof("ctmm04x")
    cur = pdo.default_config(p, 1)
    assert pdo.plan(p, cur, cur, nmt_state="operational").steps == ()
    desired = pdo.config_from_json(
        p, {"pdos": [{"direction": "rx", "number": 1, "entries": ["0x6040:00"]}]}, current=cur
    )
    with pytest.raises(PdoRefused) as info:
        pdo.plan(p, cur, desired, nmt_state="preop")
    assert info.value.problems
    prob = info.value.problems[0]
    assert isinstance(prob, pdo.PdoProblem)
    assert prob.section == "003 §4-1" and "pre-assigned" in prob.message
    assert pdo.full_plan(p, cur, nmt_state="preop").steps == ()


def test_invalid_desired_is_refused_before_any_write() -> None:
    p = prof("smartris")
    cur = pdo.default_config(p, 1)
    desired = pdo.config_from_json(
        p, {"pdos": [{"direction": "rx", "number": 1, "transmission_type": 250}]}, current=cur
    )
    with pytest.raises(PdoRefused) as info:
        pdo.plan(p, cur, desired, nmt_state="operational")
    d = info.value.to_dict()
    assert d["problems"] and d["problems"][0]["field"] == "transmission_type"  # type: ignore[index]
