"""import_file picks the reader by suffix; XDD (CiA 311) import."""

from __future__ import annotations

import contextlib
import random
from collections.abc import Callable
from pathlib import Path

import pytest

from servodesk.devdesc import (
    export_dcf,
    export_eds,
    export_esi,
    import_eds,
    import_esi,
    import_file,
    import_xdd,
)
from servodesk.domain.address import ObjectAddress
from servodesk.domain.datatypes import DataType
from servodesk.domain.profile import Access, ObjectType, PdoMapping
from servodesk.domain.profile_loader import check_profile
from servodesk.errors import NotFoundError, ProfileError, ValidationError
from tests.devdesc.helpers_devdesc import load, variable_differences

DATA = Path(__file__).resolve().parents[1] / "data" / "devdesc"


def test_import_file_chooses_by_suffix(tmp_path: Path) -> None:
    profile = load("cia402-generic")
    (tmp_path / "Generic Drive.EDS").write_text(export_eds(profile), encoding="ascii")
    (tmp_path / "drive.dcf").write_text(
        export_dcf(profile, 3, {ObjectAddress(0x1017): 100}), encoding="ascii"
    )
    (tmp_path / "drive.xml").write_text(export_esi(profile), encoding="utf-8")
    eds = import_file(tmp_path / "Generic Drive.EDS")
    assert eds.id == "generic-drive"
    assert variable_differences(profile, eds) == []
    assert variable_differences(profile, import_file(tmp_path / "drive.dcf", "d")) == []
    assert variable_differences(profile, import_file(tmp_path / "drive.xml", "x")) == []
    assert import_file(DATA / "acme_ad400.xdd").id == "acme-ad400"


def test_import_file_refuses_unknown_suffixes_and_missing_files(tmp_path: Path) -> None:
    (tmp_path / "drive.gsd").write_text("x")
    with pytest.raises(ValidationError, match=r"cannot import a \.gsd file") as info:
        import_file(tmp_path / "drive.gsd")
    assert info.value.hint is not None
    for suffix in (".eds", ".dcf", ".xml", ".xdd"):
        assert suffix in info.value.hint
    with pytest.raises(NotFoundError):
        import_file(tmp_path / "missing.eds")


def test_import_file_reads_latin1_eds(tmp_path: Path) -> None:
    text = (DATA / "acme_ad400.eds").read_text(encoding="ascii")
    path = tmp_path / "latin.eds"
    path.write_bytes(
        text.replace("ParameterName=Velocity loop gain", "ParameterName=Verstärkung").encode(
            "latin-1"
        )
    )
    p = import_file(path)
    assert p.variables[ObjectAddress(0x2000)].name == "Verstärkung"


def test_xdd_imports_to_a_usable_profile() -> None:
    p = import_xdd((DATA / "acme_ad400.xdd").read_text(encoding="utf-8"), profile_id="ad400")
    assert check_profile(p) == []
    assert (p.name, p.vendor, p.fieldbus) == ("AD-400", "ACME Motion GmbH", "canopen")
    assert p.identity.vendor_id == 0x4D2 and p.identity.product_codes == (0x400,)
    v = p.variables
    assert p.entries[0x1018].object_type is ObjectType.RECORD
    assert v[ObjectAddress(0x1018, 0)].access is Access.CONST
    assert v[ObjectAddress(0x1400, 1)].default_value(4) == 0x204
    assert v[ObjectAddress(0x6040)].pdo_mapping is PdoMapping.RX
    assert v[ObjectAddress(0x6041)].name == "Statusword"  # via uniqueIDRef, English label
    assert v[ObjectAddress(0x6041)].pdo_mapping is PdoMapping.TX
    s = v[ObjectAddress(0x6060)]
    assert (s.data_type, s.min, s.max, s.pdo_mapping) == (
        DataType.INTEGER8,
        -4,
        10,
        PdoMapping.BOTH,
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("<ISO15745ProfileContainer", r"not well-formed XML"),
        ("<EtherCATInfo/>", r"the root element is <EtherCATInfo>"),
        ("<ISO15745ProfileContainer/>", r"no ApplicationLayers/CANopenObjectList"),
        (
            "<ISO15745ProfileContainer><CANopenObjectList><CANopenObject index='6040' "
            "name='C' objectType='7' dataType='0999' accessType='rw'/></CANopenObjectList>"
            "</ISO15745ProfileContainer>",
            r"CANopenObject 6040 DataType=0x0999: 0x0999 is not a CiA 301 basic data type",
        ),
        (
            "<ISO15745ProfileContainer><CANopenObjectList><CANopenObject index='60x0' "
            "name='C'/></CANopenObjectList></ISO15745ProfileContainer>",
            r"index='60x0': not a hex index",
        ),
        (
            "<ISO15745ProfileContainer><CANopenObjectList><CANopenObject index='6040' "
            "name='C' objectType='7' dataType='0006' accessType='rw' PDOmapping='maybe'/>"
            "</CANopenObjectList></ISO15745ProfileContainer>",
            r"PDOmapping='maybe': unknown value",
        ),
    ],
)
def test_malformed_xdd_gives_a_precise_profile_error(text: str, message: str) -> None:
    with pytest.raises(ProfileError, match=message):
        import_xdd(text, profile_id="x", source="bad.xdd")


@pytest.mark.parametrize("name", ["acme_ad400.eds", "acme_ae200_esi.xml", "acme_ad400.xdd"])
def test_randomly_damaged_files_give_profile_errors_only(name: str) -> None:
    """Flipped, dropped and duplicated characters: a profile or a ProfileError, nothing else."""
    readers: dict[str, Callable[..., object]] = {
        ".eds": import_eds,
        ".xml": import_esi,
        ".xdd": import_xdd,
    }
    reader = readers[Path(name).suffix]
    text = (DATA / name).read_text(encoding="latin-1")
    rng = random.Random(311306)
    alphabet = "0123456789abcdefxX$[]=;<>/#-_. \n\"'"
    for _ in range(150):
        chars = list(text)
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(chars))
            op = rng.randrange(3)
            if op == 0:
                chars[i] = rng.choice(alphabet)
            elif op == 1:
                del chars[i]
            else:
                chars.insert(i, chars[i])
        with contextlib.suppress(ProfileError):
            reader("".join(chars), profile_id="fuzz")
