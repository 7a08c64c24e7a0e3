"""Twins made from the vendor corpus's CiA 402 ESIs over the wire (issue 46): ``servodesk sim
--esi FILE`` on a veth pair, identified by ``servodesk scan``, backed up, its PDOs shown, and
in CSP through cyclic data (servodesk/benchmarks/esi_twins.py does each step; the bench
bench/bench_esi_twins.py prints the same as a table). Then one test per behaviour of real
slaves the twin reproduces on request (docs/ethercat.md, "A twin from an ESI")."""

from __future__ import annotations

import asyncio
import json
import time
from pathlib import Path

import pytest

from servodesk.benchmarks.esi_twins import (
    CIA402_ESIS,
    SDO_TIMEOUT_S,
    check_twin,
    cli,
    data_dir,
    esi_twin,
    import_esi,
)
from servodesk.devdesc import read_file
from servodesk.domain.address import ObjectAddress
from servodesk.errors import ServodeskError
from servodesk.links.base import LinkParams
from servodesk.links.ethercat_link import EthercatLink
from servodesk.sim.veth import VethPair

pytestmark = pytest.mark.timeout(120)

CORPUS = Path(__file__).resolve().parents[3] / "shared" / "corpus"
#: The smallest CiA 402 ESI of the corpus (27 kB): the real-slave options' twin.
SMALL = "esi/Synapticon_SOMANET_CiA402-single.xml"


def _corpus() -> Path:
    if (CORPUS / SMALL).is_file():
        return CORPUS
    pytest.skip("the vendor corpus (../shared/corpus) is not here")


@pytest.mark.parametrize(("name", "device"), CIA402_ESIS, ids=[n for n, _ in CIA402_ESIS])
def test_an_esi_twin_is_identified_backed_up_and_follows_a_target_in_csp(
    veth: VethPair, tmp_path: Path, name: str, device: int | None
) -> None:
    row = check_twin(_corpus() / name, device, veth.master, veth.slave, tmp_path / "1")
    if any("working counter -1" in e for e in row["errors"]):
        # Known, not understood (2026-12-07): about one run in ten under a load of 5, the
        # twin's ESC process answered no frame for seconds (SOEM: working counter -1) in
        # the middle of a check, never in 27 backups in a row from the shell. Once again,
        # and the first failure stays in the output.
        print("retried after:", row["errors"])
        row = check_twin(_corpus() / name, device, veth.master, veth.slave, tmp_path / "2")
    assert row["errors"] == [], row
    # scan: the identity the ESI gives (1018h, the SII) picks the profile imported from it.
    want = read_file(_corpus() / name, device=device).profile.id
    assert row["identity_ok"] and row["scan_id"] == want
    # A backup reads what the profile says is there (the Synapticon single file's objects
    # are all process data or read-only: nothing to back up).
    assert row["backup_read"] >= 0.95 * row["backup_readable"], row
    assert row["pdo_show"] and row["oe_csp"] and row["follows"], row


def _link(veth: VethPair) -> EthercatLink:
    return EthercatLink(
        LinkParams(interface="ethercat", channel=veth.master, node_id=1, timeout=SDO_TIMEOUT_S)
    )


def _scan(veth: VethPair) -> dict[str, object]:
    code, out, err = cli(["scan", "--interface", "ethercat", "--channel", veth.master, "--json"])
    assert code == 0, err
    node: dict[str, object] = json.loads(out)["nodes"][0]
    return node


def test_a_twin_without_1008h_is_named_by_its_sii(veth: VethPair, tmp_path: Path) -> None:
    with data_dir(tmp_path):
        want = import_esi(_corpus() / SMALL, None)
        with esi_twin(_corpus() / SMALL, None, veth.slave, ["--no-device-name"]):
            node = _scan(veth)
    assert node["profile_id"] == want["profile_id"]
    assert node["device_name"] == "CiA402 Drive"  # The SII's string (ETG.2010), the ESI's name.


def test_an_sii_identity_other_than_1018h_is_told_by_1018h(veth: VethPair, tmp_path: Path) -> None:
    # An SII programmed for another revision than the firmware reports: CoE (1018h) wins,
    # so the profile is the one of the drive's own identity.
    with data_dir(tmp_path):
        want = import_esi(_corpus() / SMALL, None)
        opts = ["--sii-identity", f"{want['vendor_id']}:{want['product_code']}:0x7777"]
        with esi_twin(_corpus() / SMALL, None, veth.slave, opts):
            node = _scan(veth)
    assert node["profile_id"] == want["profile_id"] and node["revision"] != 0x7777, node


def test_an_abort_with_reserved_bits_set_is_reported_clearly(veth: VethPair) -> None:
    with esi_twin(_corpus() / SMALL, None, veth.slave, ["--abort-reserved-bits"]):

        async def read_missing() -> str:
            async with _link(veth) as link:
                assert len(await link.read(ObjectAddress(0x6041))) == 2
                with pytest.raises(ServodeskError) as err:
                    await link.read(ObjectAddress(0x5FFF))
                # The next request still works: the refusal was consumed.
                assert len(await link.read(ObjectAddress(0x6041))) == 2
                return err.value.message + " / " + (err.value.hint or "")

        text = asyncio.run(read_missing())
    assert "0x5FFF:00" in text and "SDO abort with reserved bits" in text, text


def test_a_slave_that_claims_complete_access_is_still_backed_up(
    veth: VethPair, tmp_path: Path
) -> None:
    with data_dir(tmp_path):
        import_esi(_corpus() / SMALL, None)
        with esi_twin(_corpus() / SMALL, None, veth.slave, ["--claims-complete-access"]):
            node = ["--interface", "ethercat", "--channel", veth.master, "--node-id", "1"]
            code, out, err = cli(["backup", "-o", str(tmp_path / "b.json"), *node, "--json"])
            assert code == 0, err
            code, out, err = cli(["pdo", "show", *node, "--export", "json"])
            assert code == 0 and "0x6040:00" in out, err


def test_a_slow_boot_is_waited_for_or_told(veth: VethPair) -> None:
    # The firmware answers PRE-OP only after 1.5 s: a link opened at once either waits for it
    # or says the slave does not answer; once booted, it works.
    with esi_twin(_corpus() / SMALL, None, veth.slave, ["--boot-delay", "1.5"]):
        t0 = time.monotonic()

        async def early() -> None:
            try:
                async with _link(veth) as link:
                    await link.read(ObjectAddress(0x6041))
            except ServodeskError as exc:
                assert "Traceback" not in exc.message and exc.message, exc

        asyncio.run(early())
        time.sleep(max(0.0, 1.6 - (time.monotonic() - t0)))

        async def later() -> int:
            async with _link(veth) as link:
                return len(await link.read(ObjectAddress(0x6041)))

        assert asyncio.run(later()) == 2


@pytest.mark.parametrize("watchdog", [True, False], ids=["enforced", "not-enforced"])
def test_the_sync_manager_watchdog_enforced_or_not(veth: VethPair, watchdog: bool) -> None:
    # In OP, outputs nobody writes: the slave whose watchdog is enforced falls back to
    # SAFE-OP (AL status code 001Bh, 100 ms), the other stays in OP.
    opts = [] if watchdog else ["--no-watchdog"]
    with esi_twin(_corpus() / SMALL, None, veth.slave, opts):

        async def run() -> str:
            async with _link(veth) as link:
                await link.nmt("start")
                await asyncio.sleep(1.2)  # The network state is read at most once a second.
                state = await link.network_state()
                await link.nmt("preop")
                return state

        state = asyncio.run(run())
    assert state == ("safeop" if watchdog else "op"), state


def test_an_unmatched_slave_is_scanned_as_cia402_ethercat(veth: VethPair, tmp_path: Path) -> None:
    # No profile imported for it and no SDO Information: scan names the profile a session
    # would take, the generic EtherCAT one (never null, never the CANopen cia402-generic).
    with data_dir(tmp_path), esi_twin(_corpus() / SMALL, None, veth.slave):
        node = _scan(veth)
        node_args = ["--interface", "ethercat", "--channel", veth.master, "--node-id", "1"]
        code, out, err = cli(["backup", "-o", str(tmp_path / "b.json"), *node_args, "--json"])
    assert node["profile_id"] == "cia402-ethercat", node
    assert code == 0 and json.loads(out)["profile_id"] == "cia402-ethercat", err


@pytest.mark.parametrize("offered", [True, False], ids=["sdo-info", "no-sdo-info"])
def test_sdo_information_lists_the_twins_objects_when_offered(
    veth: VethPair, offered: bool
) -> None:
    # ETG.1000.6 §5.6.3 through SOEM (ecx_readODlist / ecx_readODdescription / ecx_readOE,
    # pysoem's slave.od): the twin's dictionary with names, types and access, fragmented
    # over several mailbox answers; without the option the service is not offered.
    import pysoem

    opts = ["--sdo-info"] if offered else []
    with esi_twin(_corpus() / SMALL, None, veth.slave, opts):
        master = pysoem.Master()
        master.open(veth.master)
        try:
            assert master.config_init() == 1
            slave = master.slaves[0]
            if not offered:
                with pytest.raises(pysoem.SdoInfoError):
                    slave.od  # noqa: B018 (the property reads the list)
                return
            # pysoem reads each description when it is asked for: while the master is open.
            od = {o.index: o for o in slave.od}
            status = od[0x6041]
            assert status.name == b"Statusword" and status.data_type == 6  # UNSIGNED16
            assert status.object_code == 7 and status.bit_length == 16
            mapping = od[0x1600]
            entries = mapping.entries
            assert mapping.object_code in (8, 9) and len(entries) > 1
            assert entries[1].bit_length == 32 and entries[1].obj_access & 0x07
        finally:
            master.close()
    assert len(od) > 50 and 0x1C12 in od
