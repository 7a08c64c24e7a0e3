"""The object store: defaults, store/restore, PDO mapping checks, the OD builder."""

from __future__ import annotations

import pytest
from canopen import objectdictionary as od

from servodesk.sim.engine import SIGNATURE_LOAD, SIGNATURE_SAVE, SimAbort
from servodesk.sim.od_build import build_object_dictionary

from .support import generic, new_drive, with_quirks


def aborts(code: int, fn, *args) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(SimAbort) as exc:
        fn(*args)
    assert exc.value.code == code, str(exc.value)


def test_defaults_resolve_node_id_and_serial() -> None:
    d = new_drive(node_id=7)
    assert d.read(0x1400, 1) == 0x207
    assert d.read(0x1800, 1) == 0x187
    assert d.read(0x1018, 4) == 1


def test_store_keeps_persist_objects_across_reset_and_restore_brings_defaults() -> None:
    d = new_drive()
    d.write(0x6065, 0, 1234)
    d.write(0x607A, 0, 999)  # Not a persist object.
    d.write(0x1010, 1, SIGNATURE_SAVE)
    d.reset_node()
    assert d.read(0x6065, 0) == 1234
    assert d.read(0x607A, 0) == 0
    d.write(0x1011, 1, SIGNATURE_LOAD)
    assert d.read(0x6065, 0) == 1234
    d.reset_node()
    assert d.read(0x6065, 0) == 20000
    aborts(0x08000020, d.write, 0x1010, 1, 1)


def test_store_parameters_quirk_changes_the_signature() -> None:
    d = new_drive(
        with_quirks(
            generic(), store_parameters={"index": 0x1010, "subindex": 1, "value": 0x11223344}
        )
    )
    aborts(0x08000020, d.write, 0x1010, 1, SIGNATURE_SAVE)
    d.write(0x6065, 0, 4321)
    d.write(0x1010, 1, 0x11223344)
    d.reset_node()
    assert d.read(0x6065, 0) == 4321


def test_pdo_mapping_checks() -> None:
    d = new_drive()
    d.nmt_state = "preop"
    aborts(0x06040041, d.write, 0x1600, 1, 0x60410010)  # 6041h is not RPDO-mappable.
    aborts(0x06040041, d.write, 0x1600, 1, 0x607A0010)  # Wrong length for 607Ah.
    aborts(0x06040041, d.write, 0x1600, 1, 0x20000010)  # No such object.
    d.write(0x1600, 0, 0)
    for sub in (1, 2, 3):
        d.write(0x1600, sub, 0x607A0020)
    aborts(0x06040042, d.write, 0x1600, 0, 3)  # 96 bits > 64.
    d.write(0x1600, 0, 2)
    d.nmt_state = "op"
    aborts(0x08000022, d.write, 0x1600, 0, 1)


def test_write_only_checks_and_typed_reads() -> None:
    d = new_drive()
    aborts(0x06020000, d.read, 0x2000, 0)
    aborts(0x06090011, d.read, 0x6099, 3)
    aborts(0x06010002, d.write, 0x6041, 0, 1)
    aborts(0x06090031, d.write, 0x6072, 0, 3001)
    assert d.read(0x1008, 0) == "servodesk simulated CiA 402 drive"
    assert d.read_bytes(0x6040, 0) == b"\x00\x00"


def test_object_dictionary_builder() -> None:
    d = build_object_dictionary(generic(), 9)
    assert d[0x1000].data_type == od.UNSIGNED32 and d[0x1000].access_type == "const"
    assert d[0x1008].default == "servodesk simulated CiA 402 drive"
    assert isinstance(d[0x1018], od.ODRecord) and d[0x1018][1].default == 0x5344534B
    assert isinstance(d[0x1003], od.ODArray)
    assert d[0x1400][1].default == 0x209
    assert d[0x6040].pdo_mappable and d[0x605A].min == 0 and d[0x605A].max == 8
