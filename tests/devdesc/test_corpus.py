"""The corpus gate: every real vendor device description of ``../shared/corpus`` imports.

The corpus holds ESI, EDS/DCF and XDD files as vendors and open-source stacks publish them
(SOURCES.tsv names each one's repository and commit); it sits beside the repository and is
read in place, never copied into the project. Each file must import without error, pass the
profile consistency check (so ``servodesk profiles --import`` saves it), export again in its
fieldbus's format and re-import to the same profile. Where a file uses something servodesk
does not support, the import reports it as a warning instead of failing.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from servodesk import devdesc
from servodesk.devdesc._common import collecting as devdesc_collecting
from servodesk.devdesc.roundtrip import roundtrip_difference
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import Access, ObjectType, PdoMapping
from servodesk.domain.profile_loader import check_profile
from servodesk.errors import ProfileError

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus"

pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"the shared corpus is not at {CORPUS}")


def _files() -> list[Path]:
    if not CORPUS.is_dir():
        return []
    return sorted(
        p
        for p in CORPUS.rglob("*")
        if p.is_file() and p.suffix.lower() in devdesc.SUPPORTED_SUFFIXES
    )


def _id(p: Path) -> str:
    return p.relative_to(CORPUS).as_posix()


def test_the_corpus_is_what_sources_lists() -> None:
    listed = {
        line.split("\t", 1)[0]
        for line in (CORPUS / "SOURCES.tsv").read_text(encoding="utf-8").splitlines()[1:]
        if line.strip()
    }
    assert {_id(p) for p in _files()} == listed
    assert len(listed) >= 26


@pytest.mark.parametrize("path", _files(), ids=_id)
def test_every_corpus_file_imports_checks_and_round_trips(path: Path) -> None:
    result = devdesc.read_file(path)
    p = result.profile
    assert check_profile(p) == []
    assert roundtrip_difference(p) is None
    if path.suffix == ".xml":
        # An ESI makes an EtherCAT profile: its PDO procedure is EtherCAT's, never CANopen's.
        assert p.fieldbus == "ethercat"
        assert p.pdo.kind == "ethercat"
    else:
        assert p.fieldbus == "canopen"
    for w in result.warnings:
        assert w.strip() and "\n" not in w


def _profile(name: str, device: int | None = None) -> devdesc.ImportResult:
    return devdesc.read_file(CORPUS / name, device=device)


def test_esi_of_a_servo_drive_is_an_ethercat_profile() -> None:
    """Synapticon SOMANET: identity, sync managers, DC modes and the default assignment."""
    p = _profile("esi/Synapticon_SOMANET_CiA402-single.xml").profile
    assert p.identity.vendor_id == 0x22D2
    assert p.identity.product_codes
    kinds = [sm.kind for sm in p.pdo.sync_managers]
    assert kinds == ["MBoxOut", "MBoxIn", "Outputs", "Inputs"]
    assert p.pdo.sync_managers[2].start_address is not None
    assert any(m.assign_activate == 0x300 for m in p.pdo.dc_modes)
    assert p.pdo.rpdo_count >= 1 and p.pdo.tpdo_count >= 1
    # No CANopen-only expectations: no PDO communication parameters, no heartbeat object.
    for index in (0x1400, 0x1800, 0x1017):
        assert index not in p.entries


def test_esi_default_assignment_becomes_a_template() -> None:
    p = _profile("esi/Ingenia_EVE-XCR-E.xml").profile
    tpl = next(t for t in p.pdo.templates if t.id == "esi-default")
    assert tpl.assignment is not None
    assert tpl.assignment.get("rx") and tpl.assignment.get("tx")
    for q in tpl.pdos:
        for w in q.entries or ():
            if w.address and not w.address.startswith("reserved"):
                spec = p.spec(ObjectAddress.parse(w.address))
                assert spec is not None
                assert spec.pdo_mapping.rx if q.direction == "rx" else spec.pdo_mapping.tx


def test_several_devices_the_user_picks_one_and_the_profile_says_which() -> None:
    path = CORPUS / "esi" / "Elmo_Gold_ECAT_00010420_V11.xml"
    devices = devdesc.esi_devices(path.read_text(encoding="latin-1"), source=path.name)
    assert len(devices) == 4
    first = _profile("esi/Elmo_Gold_ECAT_00010420_V11.xml").profile
    assert "device 1 of 4" in (first.description or "")
    for d in devices:
        p = _profile("esi/Elmo_Gold_ECAT_00010420_V11.xml", device=d.number).profile
        assert f"device {d.number} of 4" in (p.description or "")
        assert p.identity.product_codes == ((d.product_code,) if d.product_code else ())
        if sum(1 for x in devices if x.product_code == d.product_code) > 1:
            # Revisions of one product: detection needs the revision to tell them apart.
            assert p.identity.revision_min == p.identity.revision_max == d.revision
    with pytest.raises(ProfileError, match=r"no device 5: the file describes 4"):
        _profile("esi/Elmo_Gold_ECAT_00010420_V11.xml", device=5)


def test_a_coupler_without_dictionary_is_an_identity_only_profile() -> None:
    r = _profile("esi/Beckhoff_EK11xx.xml")
    assert r.profile.objects == ()
    assert r.profile.identity.vendor_id == 2
    assert any("neither a Profile/Dictionary nor RxPdo/TxPdo" in w for w in r.warnings)


def test_byte_arrays_are_one_octet_string_not_one_subindex_per_byte() -> None:
    # Beckhoff EL1258 (device 99): FB00h sub 3 "Response" is ARRAY [0..5] OF BYTE with its own
    # SubIdx (ETG.2000 DataTypes); it used to become subs 0..5, overwriting sub 0.
    r = _profile("esi/Beckhoff_EL1xxx.xml", device=99)
    response = r.profile.spec(ObjectAddress(0xFB00, 3))
    assert response is not None and response.name == "Response"
    assert response.data_type is DataType.OCTET_STRING
    sub0 = r.profile.spec(ObjectAddress(0xFB00, 0))
    assert sub0 is not None and sub0.data_type is DataType.UNSIGNED8
    assert ObjectAddress(0xFB00, 5) not in r.profile.variables


def test_more_elements_than_subindices_is_one_value_with_a_warning() -> None:
    """ARRAY [0..511] OF BYTE in a record (the issue's Object #x58B2) imports as one value."""
    text = (
        "<EtherCATInfo><Vendor><Id>#x9A</Id><Name>V</Name></Vendor><Descriptions><Devices>"
        "<Device><Type ProductCode='#x1' RevisionNo='#x2'>D</Type><Name>D</Name><Profile>"
        "<Dictionary><DataTypes>"
        "<DataType><Name>ARRAY [0..511] OF BYTE</Name><BaseType>BYTE</BaseType>"
        "<BitSize>4096</BitSize><ArrayInfo><LBound>0</LBound><Elements>512</Elements>"
        "</ArrayInfo></DataType>"
        "<DataType><Name>DT58B2</Name><BitSize>4112</BitSize>"
        "<SubItem><SubIdx>0</SubIdx><Name>Count</Name><Type>USINT</Type><BitSize>8</BitSize>"
        "<BitOffs>0</BitOffs><Flags><Access>ro</Access></Flags></SubItem>"
        "<SubItem><Name>Elements</Name><Type>ARRAY [0..511] OF BYTE</Type>"
        "<BitSize>4096</BitSize><BitOffs>16</BitOffs><Flags><Access>ro</Access></Flags>"
        "</SubItem></DataType>"
        "<DataType><Name>DT2000</Name><BitSize>32</BitSize>"
        "<SubItem><SubIdx>0</SubIdx><Name>N</Name><Type>USINT</Type><BitSize>8</BitSize>"
        "<BitOffs>0</BitOffs></SubItem>"
        "<SubItem><SubIdx>1</SubIdx><Name>Inner</Name><Type>DT58B2</Type>"
        "<BitSize>4112</BitSize><BitOffs>16</BitOffs></SubItem></DataType>"
        "</DataTypes><Objects>"
        "<Object><Index>#x58B2</Index><Name>Buffer</Name><Type>DT58B2</Type>"
        "<BitSize>4112</BitSize></Object>"
        "<Object><Index>#x2000</Index><Name>Nested</Name><Type>DT2000</Type>"
        "<BitSize>32</BitSize></Object>"
        "<Object><Index>#x2001</Index><Name>Decimal</Name><Type>UINT</Type>"
        "<BitSize>16</BitSize><Info><DefaultData>100</DefaultData></Info></Object>"
        "</Objects></Dictionary></Profile></Device></Devices></Descriptions></EtherCATInfo>"
    )
    with devdesc_collecting() as notes:
        p = devdesc.import_esi(text, profile_id="x", source="big.xml")
    buf = p.spec(ObjectAddress(0x58B2, 1))
    assert buf is not None and buf.data_type is DataType.OCTET_STRING
    assert ObjectAddress(0x58B2, 2) not in p.variables
    assert any("512 elements" in n and "kept as one OCTET_STRING" in n for n in notes)
    nested = p.spec(ObjectAddress(0x2000, 1))
    assert nested is not None and nested.data_type is DataType.DOMAIN
    assert any("nested structure 'DT58B2'" in n for n in notes)
    # "100" cannot be hex bytes (three digits): a tool wrote the decimal number.
    dec = p.spec(ObjectAddress(0x2001))
    assert dec is not None and dec.default == 100
    assert any("DefaultData='100': decimal, not hex bytes" in n for n in notes)
    assert roundtrip_difference(p) is None


def test_module_file_imports_without_identity() -> None:
    r = _profile("extra/Weidmueller_UR20-IO_modules.xml")
    assert r.profile.identity.vendor_id is None
    assert any("EtherCATModule" in w for w in r.warnings)


def test_signed_minimum_on_unsigned_object_is_dropped_and_reported() -> None:
    r = _profile("esi/Inovance_IS620N.xml")
    spec = r.profile.spec(ObjectAddress(0x2004, 52))
    assert spec is not None and spec.data_type is DataType.UNSIGNED16 and spec.min is None
    assert any(
        re.search(r"#x2004 sub 52: min -10000 does not fit UNSIGNED16", w) for w in r.warnings
    )


def test_dcf_without_node_id_keeps_nodeid_defaults() -> None:
    r = _profile("eds/Elmo_Gold.dcf")
    cob = r.profile.spec(ObjectAddress(0x1400, 1))
    assert cob is not None and isinstance(cob.default, str) and "$NODEID" in cob.default.upper()
    assert cob.default_value(5) == 0x205
    assert any("has no NodeID" in w for w in r.warnings)


def test_xdd_types_come_from_the_parameters_and_xpd_is_read() -> None:
    for name in ("xdd/CANopenNode_demoDevice.xdd", "xdd/CANopenNode_DS301_profile.xpd"):
        p = _profile(name).profile
        dev_type = p.spec(ObjectAddress(0x1000))
        assert dev_type is not None and dev_type.data_type is DataType.UNSIGNED32
        errors = p.entries[0x1003]
        assert errors.object_type is ObjectType.ARRAY


def test_rx_mappable_read_only_object_is_rww() -> None:
    r = _profile("esi/rt-labs_SOES_xmc4_dynpdo.xml")
    led = r.profile.spec(ObjectAddress(0x7000, 1))
    assert led is not None and led.access is Access.RWW and led.pdo_mapping is PdoMapping.RX
    assert any("#x7000 sub 1: RxPDO-mappable but access ro; taken as rww" in w for w in r.warnings)


def test_read_only_object_flagged_r_but_in_a_txpdo_is_tx() -> None:
    """Elmo Gold: 603Fh says PdoMapping R, read-only, and sits in a TxPdo: it is an input."""
    r = _profile("esi/Elmo_Gold_ECAT_00010420_V11.xml", device=3)
    spec = r.profile.spec(ObjectAddress(0x603F))
    assert spec is not None and spec.pdo_mapping is PdoMapping.TX and spec.access is Access.RO
    assert any("603F sub 0: read-only, PdoMapping R but mapped in a TxPdo" in w for w in r.warnings)


def test_cli_lists_devices_imports_one_and_prints_the_warnings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from servodesk.cli import main

    monkeypatch.setenv("SERVODESK_DATA_DIR", str(tmp_path))
    esi = str(CORPUS / "esi" / "Elmo_Gold_ECAT_00010420_V11.xml")
    assert main(["profiles", "--import", esi, "--list-devices", "--json"]) == 0
    devices = json.loads(capsys.readouterr().out)
    assert [d["number"] for d in devices] == [1, 2, 3, 4]
    assert devices[2]["revision"] == 0x00010420
    assert main(["profiles", "--import", esi, "--device", "3", "--id", "elmo-3", "--json"]) == 0
    out, err = capsys.readouterr()
    body = json.loads(out)
    assert body["id"] == "elmo-3" and body["fieldbus"] == "ethercat"
    assert body["warnings"] and all(f"servodesk: warning: {w}" in err for w in body["warnings"])
    saved = tmp_path / "profiles" / "elmo-3" / "profile.yaml"
    assert saved.is_file() and "kind: ethercat" in saved.read_text(encoding="utf-8")
    # A bad device number and --device without --import: exit 2 with what to do.
    assert main(["profiles", "--import", esi, "--device", "7", "--id", "elmo-7"]) == 2
    assert "no device 7: the file describes 4" in capsys.readouterr().err
    assert main(["profiles", "--device", "2"]) == 2
    assert "--device and --list-devices go with --import FILE" in capsys.readouterr().err
    eds = str(CORPUS / "eds" / "Elmo_Gold.dcf")
    assert main(["profiles", "--import", eds, "--device", "2"]) == 2
    assert "describes one device" in capsys.readouterr().err


def test_slots_default_modules_are_placed_per_slot() -> None:
    """ETG modules/slots sample: two axis slots, default module "Position Mode" in each; the
    second slot's PDO moves by SlotPdoIncrement (16) and its objects by SlotIndexIncrement."""
    r = _profile("esi/ETG_ModulesSlots_CiA402.xml")
    p = r.profile
    for index in (0x1600, 0x1610, 0x1A00, 0x1A10, 0x607A, 0x687A, 0x6040, 0x6840):
        assert index in p.entries, hex(index)
    mapped = p.spec(ObjectAddress(0x1610, 1))
    assert mapped is not None and mapped.default == 0x687A0020
    tpl = next(t for t in p.pdo.templates if t.id == "esi-default")
    assert tpl.assignment == {"rx": (0x1600, 0x1610), "tx": (0x1A00, 0x1A10)}
    assert any("slot 2: Position Mode" in w for w in r.warnings)
