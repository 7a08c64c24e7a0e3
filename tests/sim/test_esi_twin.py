"""A twin's profile made from any device description (sim/esi_twin.py, issue 46): every CiA
402 ESI of the vendor corpus gives a drive that the CiA 402 engine takes to Operation enabled
in CSP and that follows a target, whatever its file lacks; what was completed is said."""

from __future__ import annotations

from pathlib import Path

import pytest

from servodesk.devdesc import read_file
from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import check_profile
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.esi_twin import TwinOptions, twin_profile

CORPUS = Path(__file__).resolve().parents[3] / "shared" / "corpus"
FILES = [
    ("esi/Ingenia_EVE-XCR-E.xml", None),
    ("esi/Elmo_Gold_ECAT_00010420_V11.xml", 3),
    ("esi/Inovance_IS620N.xml", None),
    ("esi/Synapticon_SOMANET_CiA402-single.xml", None),
    ("esi/Synapticon_SOMANET_CiA402-multi.xml", None),
    ("esi/ETG_ModulesSlots_CiA402.xml", None),
    ("eds/ROS-Industrial_CIA402VTD.eds", None),
    ("eds/Elmo_Gold.dcf", None),
]


def _file(name: str) -> Path:
    if (CORPUS / name).is_file():
        return CORPUS / name
    pytest.skip("the vendor corpus (../shared/corpus) is not here")


def _csp(drive: SimulatedDrive) -> int:
    """Enable in CSP, ramp the target by 2000 counts over 400 cycles (5 counts a cycle: the
    Ingenia file's following error window 6065h is 100 counts); the position moved."""
    drive.step(drive.CONTROL_PERIOD)
    drive.nmt_state = "operational"
    drive.write(0x6060, 0, 8)
    for cw in (0x06, 0x07, 0x0F):
        drive.write(0x6040, 0, cw)
        drive.step(0.01)
    assert drive.statusword & 0x6F == 0x27, f"{drive.statusword:04X}"
    start = int(drive.read(0x6064, 0))
    for k in range(1, 401):
        drive.write(0x607A, 0, start + 5 * k)
        drive.step(drive.CONTROL_PERIOD)
    drive.step(0.05)
    assert drive.statusword & 0x6F == 0x27, f"{drive.statusword:04X}"  # No fault.
    return int(drive.read(0x6064, 0)) - start


@pytest.mark.parametrize(("name", "device"), FILES, ids=[n for n, _ in FILES])
def test_a_twin_of_each_cia402_file_runs_csp(name: str, device: int | None) -> None:
    imported = read_file(_file(name), device=device).profile
    twin, notes = twin_profile(imported)
    assert check_profile(twin) == []
    assert notes  # Each file lacks something the engine needs.
    drive = SimulatedDrive(twin, 1)
    # Everything the dictionary says is readable reads (a real drive answers something).
    for a, spec in twin.variables.items():
        if spec.access.readable and a != ObjectAddress(0x2F07):  # The recorder: no data yet.
            drive.read_bytes(a.index, a.subindex)
    # 1018h is the ESI's identity, as the SII will be.
    ident = imported.identity
    if ident.vendor_id is not None and twin.spec(ObjectAddress(0x1018, 1)) is not None:
        assert drive.read(0x1018, 1) == ident.vendor_id
    if name.startswith("esi/"):  # Their default RxPDO carries 607Ah: CSP (esi_twin._modes).
        assert 8 in twin.modes
        assert _csp(drive) == pytest.approx(2000, abs=100)
    else:  # The EDS / DCF twins: their 6502h's modes, profile position first.
        assert 1 in twin.modes


def test_the_twin_without_1008h_has_none() -> None:
    p = read_file(_file("esi/Inovance_IS620N.xml")).profile
    twin, notes = twin_profile(p, options=TwinOptions(no_device_name=True))
    assert twin.spec(ObjectAddress(0x1008)) is None and "no 1008h (option)" in notes


def test_a_twin_notes_what_it_completed() -> None:
    p = read_file(_file("esi/Synapticon_SOMANET_CiA402-multi.xml")).profile
    _, notes = twin_profile(p)
    text = "\n".join(notes)
    # The sample maps its own mapping objects (1600h:01 named "Controlword"): replaced.
    assert "1600h" in text and "csp mapping taken" in text
