"""ESI (ETG.2000) export and import: every shipped profile round-trips losslessly, the XML has
the ESI structure, vendor-style files import, and bad files give a precise ProfileError."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from servodesk.devdesc import export_esi, import_esi, import_file
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.profile import Access, ObjectType, PdoMapping
from servodesk.domain.profile_loader import check_profile
from servodesk.errors import ProfileError
from tests.devdesc.helpers_devdesc import (
    edge_profile,
    entry_differences,
    load,
    profile_ids,
    profile_level_differences,
    variable_differences,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "devdesc"


@pytest.mark.parametrize("profile_id", profile_ids())
def test_every_profile_round_trips_through_esi(profile_id: str) -> None:
    profile = load(profile_id)
    text = export_esi(profile)
    back = import_esi(text, profile_id=profile.id)
    assert variable_differences(profile, back) == []
    assert entry_differences(profile, back) == []
    assert profile_level_differences(profile, back) == []


def test_esi_export_is_deterministic_and_stable() -> None:
    profile = load("cia402-generic")
    text = export_esi(profile)
    assert export_esi(profile) == text
    assert export_esi(import_esi(text, profile_id=profile.id)) == text


def test_edge_values_round_trip_through_esi() -> None:
    profile = edge_profile()
    back = import_esi(export_esi(profile), profile_id=profile.id)
    assert variable_differences(profile, back) == []
    assert entry_differences(profile, back) == []


def _dictionary(text: str) -> tuple[ET.Element, dict[int, ET.Element], dict[str, ET.Element]]:
    root = ET.fromstring(text)
    device = root.find("Descriptions/Devices/Device")
    assert device is not None
    objects = {
        int(o.findtext("Index", "")[2:], 16): o
        for o in device.iterfind("Profile/Dictionary/Objects/Object")
    }
    types = {
        t.findtext("Name", ""): t for t in device.iterfind("Profile/Dictionary/DataTypes/DataType")
    }
    return device, objects, types


@pytest.mark.parametrize("profile_id", profile_ids())
def test_esi_structure_matches_the_profile(profile_id: str) -> None:
    """Objects, types, access, PDO flags and DefaultData bytes as ETG.2000 lays them out."""
    profile = load(profile_id)
    _, objects, types = _dictionary(export_esi(profile))
    assert set(objects) == {e.index for e in profile.objects}
    for entry in profile.objects:
        obj = objects[entry.index]
        assert obj.findtext("Name") == entry.name
        type_name = obj.findtext("Type", "")
        if entry.object_type is ObjectType.VAR:
            spec = next(entry.specs())
            flags = obj.find("Flags")
            assert flags is not None
            expected_access = (
                "wo" if spec.access is Access.WO else ("rw" if spec.access.writable else "ro")
            )
            assert flags.findtext("Access") == expected_access, spec.address
            pdo = {PdoMapping.RX: "R", PdoMapping.TX: "T", PdoMapping.BOTH: "RT"}.get(
                spec.pdo_mapping
            )
            assert flags.findtext("PdoMapping") == pdo, spec.address
            data = obj.findtext("Info/DefaultData")
            if isinstance(spec.default, int) and spec.data_type.is_integer:
                # Little-endian bytes of the value (ETG.2000 DefaultData).
                assert data == codec(spec.data_type).encode(spec.default).hex().upper()
        else:
            assert type_name in types, f"0x{entry.index:04X} type {type_name} defined"
            items = [s.findtext("Name") for s in obj.iterfind("Info/SubItem")]
            assert items == [s.name for s in entry.specs()]
    base_types = {
        t
        for t, el in types.items()
        if el.find("SubItem") is None
        and el.find("ArrayInfo") is None
        and el.find("BaseType") is None
    }
    assert {"UINT", "UDINT"} <= base_types | {"UINT", "UDINT"}


def test_rx_tx_pdo_elements_follow_the_default_mapping() -> None:
    profile = load("cia402-generic")
    device, _, _ = _dictionary(export_esi(profile))
    rx = device.findall("RxPdo")
    tx = device.findall("TxPdo")
    assert [p.findtext("Index") for p in rx] == ["#x1600", "#x1601", "#x1602", "#x1603"]
    assert [p.findtext("Index") for p in tx] == ["#x1A00", "#x1A01", "#x1A02", "#x1A03"]
    # Without 1C12h/1C13h the first non-empty PDO of each direction is assigned to its SM.
    assert [p.get("Sm") for p in rx] == ["2", None, None, None]
    assert [p.get("Sm") for p in tx] == ["3", None, None, None]
    entries = [
        (e.findtext("Index"), e.findtext("BitLen"), e.findtext("DataType"))
        for e in rx[1].iterfind("Entry")
    ]
    assert entries == [("#x6040", "16", "UINT"), ("#x607A", "32", "DINT")]
    assert [sm.text for sm in device.findall("Sm")] == ["MBoxOut", "MBoxIn", "Outputs", "Inputs"]


def test_hiwin_esi_when_the_profile_exists() -> None:
    if "hiwin-e" not in profile_ids():
        pytest.skip("profile hiwin-e not present")
    profile = load("hiwin-e")
    text = export_esi(profile)
    back = import_esi(text, profile_id="hiwin-e")
    assert variable_differences(profile, back) == []
    device, objects, _ = _dictionary(text)
    assert 0x6040 in objects and device.find("RxPdo") is not None


def test_vendor_style_esi_imports_to_a_usable_profile() -> None:
    p = import_file(DATA / "acme_ae200_esi.xml", profile_id="acme-ae200")
    assert check_profile(p) == []
    assert (p.name, p.vendor, p.fieldbus) == ("AE-200 servo drive", "ACME Motion GmbH", "ethercat")
    assert p.identity.vendor_id == 1234 and p.identity.product_codes == (0x200,)
    v = p.variables
    assert v[ObjectAddress(0x1000)].default == 0x00020192  # DefaultData 92010200 (LE)
    assert v[ObjectAddress(0x1008)].default == "AE-200"
    assert p.entries[0x1018].object_type is ObjectType.RECORD
    assert [v[ObjectAddress(0x1018, s)].name for s in range(5)] == [
        "SubIndex 000",
        "Vendor ID",
        "Product code",
        "Revision",
        "Serial number",
    ]
    assert v[ObjectAddress(0x1018, 3)].default == 0x00010004
    assert v[ObjectAddress(0x1600, 2)].default == 0x607A0020
    assert v[ObjectAddress(0x1600, 1)].writable_in == ("preop",)
    # ARRAY through DataTypes/ArrayInfo.
    assert p.entries[0x1C12].object_type is ObjectType.ARRAY
    assert v[ObjectAddress(0x1C12, 1)].data_type is DataType.UNSIGNED16
    assert v[ObjectAddress(0x1C12, 1)].default == 0x1600
    assert v[ObjectAddress(0x2000)].default == 1.25 and v[ObjectAddress(0x2000)].persist
    c = v[ObjectAddress(0x2001)]
    assert (c.default, c.min, c.max) == (3000, 0, 5000)  # DefaultValue #x0BB8, Min/MaxValue
    t = v[ObjectAddress(0x607A)]
    assert (t.min, t.max, t.pdo_mapping) == (-(1 << 31), (1 << 31) - 1, PdoMapping.RX)
    m = v[ObjectAddress(0x6060)]
    assert m.data_type is DataType.INTEGER8 and m.default == 8
    assert m.values == {1: "Profile position", 6: "Homing", 8: "Cyclic synchronous position"}
    sw = v[ObjectAddress(0x6041)]
    assert sw.pdo_mapping is PdoMapping.TX and sw.process
    # TxPDO 1A00h is not in the dictionary: built from the TxPdo element (Fixed: read-only),
    # and 606Ch, mapped but not described, becomes a TxPDO variable.
    assert [v[ObjectAddress(0x1A00, s)].default for s in range(5)] == [
        4,
        0x60410010,
        0x60640020,
        0x606C0020,
        0x00000010,
    ]
    assert v[ObjectAddress(0x1A00, 0)].access is Access.RO
    vel = v[ObjectAddress(0x606C)]
    assert (vel.name, vel.data_type, vel.access) == (
        "Velocity actual value",
        DataType.INTEGER32,
        Access.RO,
    )


def test_esi_with_a_default_namespace_and_product_choice() -> None:
    text = (DATA / "acme_ae200_esi.xml").read_text(encoding="latin-1")
    text = text.replace("<EtherCATInfo ", '<EtherCATInfo xmlns="urn:example:esi" ', 1)
    p = import_esi(text, profile_id="ns", product_code=0x200)
    assert p.variables[ObjectAddress(0x6060)].default == 8
    with pytest.raises(ProfileError, match="no device with product code #x00000999"):
        import_esi(text, profile_id="ns", product_code=0x999)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("this is not XML", r"not well-formed XML \(line 1, column 0\)"),
        ("<EtherCATInfo><Vendor><Id>1</Id>", r"not well-formed XML"),
        (
            "<ISO15745ProfileContainer/>",
            r"the root element is <ISO15745ProfileContainer>, "
            r"not <EtherCATInfo>",
        ),
        (
            "<EtherCATInfo><Vendor><Id>x</Id></Vendor></EtherCATInfo>",
            r"Vendor/Id 'x' is not a number",
        ),
        (
            "<EtherCATInfo><Descriptions><Devices/></Descriptions></EtherCATInfo>",
            r"no Descriptions/Devices/Device",
        ),
        (
            "<EtherCATInfo><Descriptions><Devices><Device><Profile><Dictionary><Objects><Object>"
            "<Index>#x2000</Index><Name>X</Name><Type>FANCY</Type><BitSize>8</BitSize>"
            "</Object></Objects></Dictionary></Profile></Device></Devices></Descriptions>"
            "</EtherCATInfo>",
            r"bad.xml: Object #x2000: unknown data type 'FANCY'",
        ),
        (
            "<EtherCATInfo><Descriptions><Devices><Device><Profile><Dictionary><Objects><Object>"
            "<Index>#x2000</Index><Name>X</Name><Type>UINT</Type><BitSize>16</BitSize>"
            "<Info><DefaultData>zz</DefaultData></Info></Object></Objects></Dictionary></Profile>"
            "</Device></Devices></Descriptions></EtherCATInfo>",
            r"Object #x2000 DefaultData='zz': not hex bytes",
        ),
        (
            "<EtherCATInfo><Descriptions><Devices><Device><Profile><Dictionary><Objects><Object>"
            "<Index>#x2000</Index><Name>X</Name><Type>UINT</Type><BitSize>16</BitSize>"
            "<Flags><Access>rx</Access></Flags></Object></Objects></Dictionary></Profile>"
            "</Device></Devices></Descriptions></EtherCATInfo>",
            r"Object #x2000 sub 0: Access 'rx' is not ro, rw or wo",
        ),
    ],
)
def test_malformed_esi_gives_a_precise_profile_error(text: str, message: str) -> None:
    with pytest.raises(ProfileError, match=message) as info:
        import_esi(text, profile_id="x", source="bad.xml")
    assert info.value.hint


def test_truncated_esi_never_escapes_as_a_traceback() -> None:
    # Cut inside the document: a cut that drops only the closing newline leaves it whole.
    text = export_esi(load("cia402-generic")).rstrip()
    for cut in range(0, len(text), max(1, len(text) // 40)):
        with pytest.raises(ProfileError):
            import_esi(text[:cut], profile_id="x")
