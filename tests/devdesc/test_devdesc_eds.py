"""EDS/DCF export and import (CiA 306): every shipped profile round-trips losslessly, the
canopen library reads what servodesk writes, and bad files give a precise ProfileError."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path
from typing import Any

import canopen
import pytest

from servodesk.devdesc import export_dcf, export_eds, import_dcf, import_eds, read_dcf
from servodesk.devdesc._common import collecting
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType, Value
from servodesk.domain.profile import DeviceProfile, ObjectType, PdoMapping
from servodesk.errors import ProfileError, ValidationError
from tests.devdesc.helpers_devdesc import (
    edge_profile,
    entry_differences,
    load,
    profile_ids,
    profile_level_differences,
    strict_equal,
    variable_differences,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "devdesc"
NODE = 5


def canopen_od(text: str, node_id: int = NODE) -> Any:
    buf = io.StringIO(text)
    buf.name = "servodesk.eds"  # canopen.import_od asks file objects for a name.
    return canopen.import_od(buf, node_id=node_id)


def check_canopen_matches(profile: DeviceProfile, text: str) -> None:
    """canopen reads the same indices, sub-indices, types, access and defaults."""
    od = canopen_od(text)
    indices = {e.index for e in profile.objects}
    assert {obj.index for obj in od.values()} == indices
    for entry in profile.objects:
        obj = od[entry.index]
        if entry.object_type is ObjectType.VAR:
            assert isinstance(obj, canopen.objectdictionary.ODVariable)
        else:
            assert isinstance(
                obj, canopen.objectdictionary.ODRecord | canopen.objectdictionary.ODArray
            )
            assert sorted(obj.subindices) == [s.subindex for s in entry.specs()]
        for spec in entry.specs():
            var = obj if entry.object_type is ObjectType.VAR else obj[spec.subindex]
            where = f"{spec.address}"
            if spec.name.isascii() and ";" not in spec.name:
                assert var.name == spec.name, where
            assert var.data_type == int(spec.data_type), where
            assert var.access_type == spec.access.value, where
            assert var.pdo_mappable == (spec.pdo_mapping is not PdoMapping.NONE), where
            expected = spec.default_value(node_id=NODE)
            if spec.data_type.is_integer and expected is not None:
                assert var.default == int(expected), where
            elif spec.data_type.is_real and expected is not None:
                assert var.default == pytest.approx(float(expected)), where
            elif (
                spec.data_type is DataType.VISIBLE_STRING
                and expected is not None
                and str(expected).isascii()
                and ";" not in str(expected)
            ):
                assert var.default == str(expected).strip(), where
            if spec.data_type.is_integer:
                assert var.min == spec.min and var.max == spec.max, where


@pytest.mark.parametrize("profile_id", profile_ids())
def test_every_profile_exports_to_an_eds_canopen_reads(profile_id: str) -> None:
    profile = load(profile_id)
    text = export_eds(profile)
    assert text.isascii(), "CiA 306 files are ASCII"
    check_canopen_matches(profile, text)


@pytest.mark.parametrize("profile_id", profile_ids())
def test_every_profile_round_trips_through_eds(profile_id: str) -> None:
    profile = load(profile_id)
    text = export_eds(profile)
    back = import_eds(text, profile_id=profile.id)
    assert variable_differences(profile, back) == []
    assert entry_differences(profile, back) == []
    assert profile_level_differences(profile, back) == []


def test_eds_export_is_deterministic_and_stable() -> None:
    profile = load("cia402-generic")
    text = export_eds(profile)
    assert export_eds(profile) == text
    assert export_eds(import_eds(text, profile_id=profile.id)) == text


def test_edge_values_round_trip_and_canopen_reads_them() -> None:
    profile = edge_profile()
    text = export_eds(profile)
    assert text.isascii()
    back = import_eds(text, profile_id=profile.id)
    assert variable_differences(profile, back) == []
    assert entry_differences(profile, back) == []
    assert profile_level_differences(profile, back) == []
    check_canopen_matches(profile, text)
    od = canopen_od(text, node_id=7)
    assert od[0x1800][1].default == 0x187
    assert od[0x2005][1].default == -(1 << 63)


def test_canopen_ignores_the_servodesk_keys() -> None:
    """Stripping every servodesk_ key changes nothing canopen reads."""
    text = export_eds(edge_profile())
    plain = "\n".join(ln for ln in text.splitlines() if not ln.startswith("servodesk_"))
    assert "servodesk_" in text and "servodesk_" not in plain
    with_keys, without = canopen_od(text), canopen_od(plain)

    def summary(od: Any) -> list[tuple[Any, ...]]:
        out: list[tuple[Any, ...]] = []
        for obj in od.values():
            members = (
                [obj]
                if isinstance(obj, canopen.objectdictionary.ODVariable)
                else list(obj.values())
            )
            out.extend(
                (
                    v.index,
                    v.subindex,
                    v.name,
                    v.data_type,
                    v.access_type,
                    v.default,
                    v.min,
                    v.max,
                    v.pdo_mappable,
                    v.unit,
                    v.factor,
                    v.description,
                )
                for v in members
            )
        return out

    assert summary(with_keys) == summary(without)


def test_eds_layout_follows_cia306() -> None:
    text = export_eds(load("cia402-generic"))
    for section in (
        "FileInfo",
        "DeviceInfo",
        "DummyUsage",
        "MandatoryObjects",
        "OptionalObjects",
        "ManufacturerObjects",
        "1018",
        "1018sub4",
        "6040",
    ):
        assert f"\n[{section}]\n" in f"\n{text}", section
    assert re.search(
        r"^\[MandatoryObjects\]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018$", text, re.M
    )
    assert "DefaultValue=$NODEID+0x180" in text
    assert re.search(r"^NrOfRXPDO=4$", text, re.M) and re.search(r"^NrOfTXPDO=4$", text, re.M)
    assert re.search(r"^VendorNumber=0x5344534B$", text, re.M)
    assert re.search(
        r"^\[1018\]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=0x5$", text, re.M
    )


def test_dcf_round_trips_values_and_canopen_reads_them() -> None:
    profile = edge_profile()
    values: dict[ObjectAddress, Value] = {
        ObjectAddress(0x2000): 2.5,
        ObjectAddress(0x2001): -0.125,
        ObjectAddress(0x2002): 0xBEEF,
        ObjectAddress(0x2003): "a ; tricky\nvalue",
        ObjectAddress(0x2004): b"\x00\xff\x10",
        ObjectAddress(0x2005, 1): -42,
        ObjectAddress(0x2005, 2): (1 << 64) - 1,
        ObjectAddress(0x2005, 3): True,
        ObjectAddress(0x1800, 1): 0x40000185,
    }
    text = export_dcf(profile, 5, values, bitrate=250_000)
    contents = read_dcf(text, profile_id=profile.id)
    assert contents.node_id == 5 and contents.bitrate == 250_000
    assert set(contents.values) == set(values)
    for addr, v in values.items():
        assert strict_equal(contents.values[addr], v), addr
    assert variable_differences(profile, contents.profile) == []
    _, back_values = import_dcf(text, profile_id=profile.id)
    assert back_values == contents.values
    od = canopen_od(text, node_id=5)
    assert od.node_id == 5 and od.bitrate == 250_000
    assert od[0x2002].value == 0xBEEF
    assert od[0x2005][1].value == -42
    assert od[0x2000].value == 2.5
    assert od[0x1800][1].value == 0x40000185


def test_dcf_of_a_shipped_profile_with_node_relative_values() -> None:
    profile = load("cia402-generic")
    text = export_dcf(profile, 12, {ObjectAddress(0x1017): 250, ObjectAddress(0x6060): 3})
    text = text.replace("ParameterValue=250", "ParameterValue=250\n") + (
        "\n"  # A hand-edited DCF: a node-relative ParameterValue (CiA 306 §5.2).
    )
    text = re.sub(
        r"(\[1400sub1\]\n(?:.*\n)*?)(PDOMapping=0\n)",
        r"\1\2ParameterValue=$NODEID+0x200\n",
        text,
        count=1,
    )
    _, values = import_dcf(text, profile_id="x")
    assert values == {
        ObjectAddress(0x1017): 250,
        ObjectAddress(0x6060): 3,
        ObjectAddress(0x1400, 1): 0x200 + 12,
    }


def test_dcf_refuses_values_the_profile_cannot_hold() -> None:
    profile = load("cia402-generic")
    with pytest.raises(ValidationError, match="0x6041"):
        export_dcf(profile, 1, {ObjectAddress(0x6041): 70000})
    with pytest.raises(ValidationError, match="not an object"):
        export_dcf(profile, 1, {ObjectAddress(0x2FFF): 1})
    with pytest.raises(ValidationError, match="node id"):
        export_dcf(profile, 0, {})


# ---------------------------------------------------------------------------------------------
# A third-party file


def test_hand_written_vendor_eds_imports_to_a_usable_profile() -> None:
    from servodesk.devdesc import import_file
    from servodesk.domain.profile_loader import check_profile

    p = import_file(DATA / "acme_ad400.eds", profile_id="acme-ad400")
    assert check_profile(p) == []
    assert (p.name, p.vendor, p.fieldbus) == ("AD-400", "ACME Motion GmbH", "canopen")
    assert p.identity.vendor_id == 0x4D2 and p.identity.product_codes == (0x400,)
    assert (p.pdo.rpdo_count, p.pdo.tpdo_count) == (2, 2)
    assert p.description is not None and "firmware 2.3" in p.description
    v = p.variables
    # CompactSubObj: sub 0 plus four elements, names from [1003Name], others generated.
    assert [s.subindex for a, s in v.items() if a.index == 0x1003] == [0, 1, 2, 3, 4]
    assert v[ObjectAddress(0x1003, 0)].default == 4
    assert v[ObjectAddress(0x1003, 1)].name == "Newest error"
    assert v[ObjectAddress(0x1003, 2)].name == "Pre-defined error field 2"
    assert v[ObjectAddress(0x1003, 4)].name == "Oldest error"
    # $NODEID kept, with an inline comment stripped; resolved per node.
    cob = v[ObjectAddress(0x1400, 1)]
    assert cob.default == "$NODEID+0x200" and cob.default_value(3) == 0x203
    assert v[ObjectAddress(0x1800, 1)].default_value(3) == 0x40000183  # [1800Sub1] spelling
    assert v[ObjectAddress(0x1400, 2)].default == 255  # octal 0377
    assert v[ObjectAddress(0x2001)].default == -1  # INTEGER16 0xFFFF, two's complement
    assert (v[ObjectAddress(0x2001)].min, v[ObjectAddress(0x2001)].max) == (-1, 3000)
    assert v[ObjectAddress(0x2000)].default == 1.25
    assert v[ObjectAddress(0x607D, 1)].default == -(1 << 31)
    assert v[ObjectAddress(0x6041)].default is None  # no DefaultValue
    assert v[ObjectAddress(0x1017)].persist is True  # StorageLocation=PERSIST_COMM
    # PDO direction from the access type.
    assert v[ObjectAddress(0x6040)].pdo_mapping is PdoMapping.RX
    assert v[ObjectAddress(0x6041)].pdo_mapping is PdoMapping.TX
    assert v[ObjectAddress(0x6060)].pdo_mapping is PdoMapping.BOTH
    assert v[ObjectAddress(0x6041)].process and not v[ObjectAddress(0x6060)].process
    # canopen reads the same file to the same objects. (canopen 2.4 reads [xxxxName] only
    # when it lists every sub-index 1..NrOfEntries, so give it the full list.)
    full = _vendor_text().replace(
        "NrOfEntries=2\n1=Newest error\n4=Oldest error",
        "NrOfEntries=4\n1=Newest error\n2=e2\n3=e3\n4=Oldest error",
    )
    od = canopen_od(full, node_id=3)
    # (canopen also lists the [DummyUsage] data-type entries 0x0002.. as objects.)
    assert {o.index for o in od.values() if o.index >= 0x1000} == {e.index for e in p.objects}
    assert od[0x1400][1].default == 0x203 and od[0x2001].default == 0xFFFF
    # And the imported profile exports and re-imports unchanged.
    assert variable_differences(p, import_eds(export_eds(p), profile_id=p.id)) == []


# ---------------------------------------------------------------------------------------------
# Malformed files


def _vendor_text() -> str:
    return (DATA / "acme_ad400.eds").read_text(encoding="ascii")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda t: t.replace("[DeviceInfo]", "[DeviceInformation]"),
            r"the section \[DeviceInfo\] is missing",
        ),
        (
            lambda t: t.replace(
                "[6060]\nParameterName=Modes of operation\nObjectType=0x7\nDataType=0x0002",
                "[6060]\nParameterName=Modes of operation\nObjectType=0x7\nDataType=0x0999",
            ),
            r"\[6060\] DataType=0x0999: 0x0999 is not a CiA 301 basic data type",
        ),
        (
            lambda t: t.replace(
                "DataType=0x0004\nAccessType=rww", "DataType=int32\nAccessType=rww", 1
            ),
            r"\[607A\] DataType='int32': not a number",
        ),
        (
            lambda t: t.replace("AccessType=rww", "AccessType=readwrite", 1),
            r"\[6040\] AccessType='readwrite': unknown access type",
        ),
        (
            lambda t: t.replace("DefaultValue=10000", "DefaultValue=ten thousand"),
            r"\[6081\] DefaultValue='ten thousand': not a UNSIGNED32 number",
        ),
        (
            lambda t: t.replace("ParameterName=Statusword\n", ""),
            r"\[6041\]: the key ParameterName is missing",
        ),
        (
            lambda t: "garbage before any section\n" + t,
            r"line 1: 'garbage before any section' comes before any \[section\]",
        ),
    ],
)
def test_malformed_eds_gives_a_precise_profile_error(edit: Any, message: str) -> None:
    with pytest.raises(ProfileError, match=message) as info:
        import_eds(edit(_vendor_text()), profile_id="x", source="bad.eds")
    assert info.value.hint, "every error says what to do"
    assert str(info.value).startswith("bad.eds")


@pytest.mark.parametrize(
    ("edit", "warning", "missing"),
    [
        (
            lambda t: re.sub(r"\[6041\]\n(.*\n)*?\n", "", t, count=1),
            r"\[OptionalObjects\] 9=0x6041: there is no section \[6041\]; object skipped",
            ObjectAddress(0x6041),
        ),
        (
            lambda t: t.replace("[1018sub3]", "[1018subX]"),
            r"\[1018\] SubNumber=4 but 3 sub-index sections \[1018subN\] exist; imported those",
            ObjectAddress(0x1018, 3),
        ),
        (
            lambda t: t.replace("SupportedObjects=17", "SupportedObjects=18"),
            r"\[OptionalObjects\] SupportedObjects=18 but the entries are 1\.\.17; read the "
            r"entries that are there",
            None,
        ),
    ],
)
def test_vendor_file_mistakes_import_with_a_warning(
    edit: Any, warning: str, missing: ObjectAddress | None
) -> None:
    """Real vendor files miscount (CiA 306 §4.6.2, §4.6.3.2): the import goes on, says so."""
    with collecting() as notes:
        p = import_eds(edit(_vendor_text()), profile_id="x", source="bad.eds")
    assert any(re.search(warning, n) for n in notes), notes
    if missing is not None:
        assert missing not in p.variables
    assert ObjectAddress(0x6040) in p.variables


def test_truncated_eds_never_escapes_as_a_traceback() -> None:
    text = export_eds(load("cia402-generic"))
    # Cut at a line end near the middle: whole lines, but sections the object list names are gone.
    mid = text[: text.rfind("\n", 0, len(text) // 2) + 1]
    with collecting() as notes:
        import_eds(mid, profile_id="x")
    assert any(re.search(r"there is no section \[[0-9A-F]{4}\]; object skipped", n) for n in notes)
    for cut in range(0, len(text), max(1, len(text) // 60)):
        with contextlib.suppress(ProfileError):
            import_eds(text[:cut], profile_id="x")


def test_empty_and_binary_input() -> None:
    with pytest.raises(ProfileError, match=r"\[DeviceInfo\] is missing"):
        import_eds("", profile_id="x")
    with pytest.raises(ProfileError):
        import_eds("\x00\x01\x02PK\x03\x04", profile_id="x")
