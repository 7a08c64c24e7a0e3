"""An EtherCAT slave no profile matches gets a profile built from its own SDO Information
(issue 46, ETG.1000.6 §5.6.3; docs/ethercat.md "A profile from SDO Information"): scan, a
session (backup, pdo show) name the same generated profile, whose objects are the slave's,
a vendor object only its ESI has among them; without SDO Information, ``cia402-ethercat``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from servodesk.api.app import create_app
from servodesk.benchmarks.esi_twins import SDO_TIMEOUT_S, cli, data_dir, esi_twin
from servodesk.devdesc.sdo_info import sdo_info_profile_id
from servodesk.settings import Settings
from servodesk.sim.veth import VethPair

pytestmark = pytest.mark.timeout(60)

CORPUS = Path(__file__).resolve().parents[3] / "shared" / "corpus"
SMALL = CORPUS / "esi" / "Synapticon_SOMANET_CiA402-single.xml"
#: Vendor 22D2h, product code 201h: the Synapticon sample's identity (its ESI's Type).
WANT_ID = sdo_info_profile_id(0x22D2, 0x201)
#: A manufacturer object (CiA 301 §7.4.3: 2000h-5FFFh) that cia402-ethercat does not know,
#: read-write with the default 42: a parameter a backup must hold.
VENDOR_OBJECT = """<Object>
    <Index>#x2345</Index><Name>Vendor tuning gain</Name><Type>UDINT</Type><BitSize>32</BitSize>
    <Info><DefaultData>2A000000</DefaultData></Info>
    <Flags><Access>rw</Access><Category>o</Category></Flags>
</Object>
"""


def _esi(tmp_path: Path) -> Path:
    """The Synapticon sample with the vendor object added to its dictionary."""
    if not SMALL.is_file():
        pytest.skip("the vendor corpus (../shared/corpus) is not here")
    text = SMALL.read_text(encoding="utf-8")
    first = text.index("<Object>")
    path = tmp_path / "vendor-object.xml"
    path.write_text(text[:first] + VENDOR_OBJECT + text[first:], encoding="utf-8")
    return path


@pytest.mark.parametrize("offered", [True, False], ids=["sdo-info", "no-sdo-info"])
def test_an_unmatched_slave_gets_the_profile_of_its_sdo_information(
    veth: VethPair, tmp_path: Path, offered: bool
) -> None:
    esi = _esi(tmp_path)
    node = ["--interface", "ethercat", "--channel", veth.master, "--node-id", "1"]
    want = WANT_ID if offered else "cia402-ethercat"
    # No profile imported for it (a data directory of its own): nothing matches its identity.
    with data_dir(tmp_path), esi_twin(esi, None, veth.slave, ["--sdo-info"] if offered else []):
        code, out, err = cli(
            ["scan", "--interface", "ethercat", "--channel", veth.master, "--json"]
        )
        assert code == 0, err
        scanned = json.loads(out)["nodes"][0]
        code, out, err = cli(["backup", "-o", str(tmp_path / "b.json"), *node, "--json"])
        assert code == 0, err
        backed_up = json.loads(out)
        code, shown, err = cli(["pdo", "show", *node, "--export", "json"])
        assert code == 0, err
        if offered:
            _check_api(veth, tmp_path)
    # scan names the profile the session takes.
    assert scanned["profile_id"] == want and backed_up["profile_id"] == want, (scanned, backed_up)
    assert "0x6041:00" in shown  # The TxPDO's statusword: the slave's PDO assignment.
    saved = (tmp_path / "b.json").read_text(encoding="utf-8")
    # The vendor object is in the backup only where the slave described it.
    assert ("0x2345:00" in saved) is offered, saved[:2000]
    if offered:
        entry = next(e for e in json.loads(saved)["entries"] if e["address"] == "0x2345:00")
        assert entry["value"] == 42 and entry["name"] == "Vendor tuning gain", entry


def _check_api(veth: VethPair, tmp_path: Path) -> None:
    """The UI's way: a session opened without a profile takes the generated one, the profile
    page loads it by id (the server's catalog holds it), and scan names it too."""
    settings = Settings(data_dir=tmp_path / "api", sdo_timeout=SDO_TIMEOUT_S, viewer_port=0)
    with TestClient(create_app(settings)) as client:
        body = {"interface": "ethercat", "channel": veth.master}
        r = client.post("/api/v1/sessions", json={**body, "node_id": 1})
        assert r.status_code == 201, r.text
        session = r.json()
        assert session["profile_id"] == WANT_ID and "SDO Information" in session["note"]
        r = client.get(f"/api/v1/profiles/{WANT_ID}")
        assert r.status_code == 200, r.text
        profile = r.json()
        assert "SDO Information" in profile["description"], profile["description"]
        names = {o["address"]: o["name"] for o in profile["object_list"]}
        assert names["0x2345:00"] == "Vendor tuning gain", names
        r = client.post("/api/v1/bus/scan", json=body)
        assert r.status_code == 200, r.text
        (node,) = r.json()["nodes"]
        assert (node["profile_id"], node["session_id"]) == (WANT_ID, session["id"]), node
        assert client.delete(f"/api/v1/sessions/{session['id']}").status_code == 204
