"""SOEM (pysoem) against the simulated slaves on a veth pair: what ``config_init`` finds and
CoE SDO transfers, expedited, normal and segmented, with aborts."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pysoem
import pytest

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.ethercat_slave import EthercatSlaveSim
from servodesk.sim.veth import VethPair, create_veth

NAME = b"HIWIN E series EtherCAT drive"


def _drives(n: int) -> list[SimulatedDrive]:
    cat = ProfileCatalog()
    return [SimulatedDrive(cat.get("hiwin-e"), i + 1, 0x5000 + i) for i in range(n)]


@pytest.fixture
def master(veth: VethPair) -> Iterator[pysoem.CdefMaster]:
    m = pysoem.Master()
    m.always_release_gil = True  # The slaves run in this process: SOEM must let them.
    m.open(veth.master)
    try:
        yield m
    finally:
        m.close()


def test_config_init_finds_the_line_with_the_hiwin_identity(
    veth: VethPair, master: pysoem.CdefMaster
) -> None:
    with EthercatSlaveSim(_drives(2), veth.slave) as line:
        assert master.config_init(release_gil=True) == 2
        for i, slave in enumerate(master.slaves):
            assert (slave.man, slave.id, slave.rev) == (0x0000AAAA, 0x00000005, 0)
            assert slave.name == NAME.decode()
            assert line.slaves[i].station_address == 0x1001 + i  # SOEM's node offset
            # SOEM programmed the mailbox SyncManagers and asked for PRE-OP: granted.
            assert (line.slaves[i].al_state, line.slaves[i].al_status_code) == (2, 0)
        serials = [s.sdo_read(0x1018, 4, release_gil=True) for s in master.slaves]
        assert [int.from_bytes(b, "little") for b in serials] == [0x5000, 0x5001]
        assert line.frames > 20 and line.dropped == 0


def test_sdo_expedited_and_normal_transfers_and_aborts(
    veth: VethPair, master: pysoem.CdefMaster
) -> None:
    drives = _drives(1)
    with EthercatSlaveSim(drives, veth.slave):
        assert master.config_init(release_gil=True) == 1
        slave = master.slaves[0]
        slave.sdo_write(0x6081, 0, (123456).to_bytes(4, "little"), release_gil=True)
        assert drives[0].read(0x6081) == 123456
        assert slave.sdo_read(0x6081, 0, release_gil=True) == (123456).to_bytes(4, "little")
        assert slave.sdo_read(0x1008, 0, release_gil=True) == NAME  # normal upload
        with pytest.raises(pysoem.SdoError) as info:
            slave.sdo_read(0x5FFF, 0, release_gil=True)
        assert info.value.abort_code == 0x06020000
        with pytest.raises(pysoem.SdoError) as info:
            slave.sdo_write(0x6041, 0, b"\x00\x00", release_gil=True)
        assert info.value.abort_code == 0x06010002
        # 6 bytes into a 4-byte object: a normal download, refused for its length.
        with pytest.raises(pysoem.SdoError) as info:
            slave.sdo_write(0x6081, 0, bytes(6), release_gil=True)
        assert info.value.abort_code == 0x06070012
        assert drives[0].read(0x6081) == 123456
        with pytest.raises(pysoem.SdoError) as info:
            slave.sdo_read(0x6081, 0, ca=True, release_gil=True)
        assert info.value.abort_code == 0x06010000  # no complete access


def test_segmented_transfers_through_a_small_mailbox(
    veth: VethPair, master: pysoem.CdefMaster
) -> None:
    drives = _drives(1)
    # A 32-byte mailbox carries 16 bytes in an initiate and 23 in a segment: the 29-byte
    # device name needs a segmented upload, a 40-byte download two segments.
    with EthercatSlaveSim(drives, veth.slave, mailbox_size=32) as line:
        assert master.config_init(release_gil=True) == 1
        slave = master.slaves[0]
        before = line.slaves[0].mailbox_requests
        assert slave.sdo_read(0x1008, 0, release_gil=True) == NAME
        assert line.slaves[0].mailbox_requests - before == 2  # initiate + 1 segment
        before = line.slaves[0].mailbox_requests
        with pytest.raises(pysoem.SdoError) as info:
            slave.sdo_write(0x6081, 0, bytes(range(40)), release_gil=True)
        # Every segment was taken; the drive refuses the 40 bytes for a 4-byte object.
        assert info.value.abort_code == 0x06070012
        assert line.slaves[0].mailbox_requests - before == 3  # initiate + 2 segments
        with pytest.raises(pysoem.SdoError) as info:
            slave.sdo_write(0x6041, 0, bytes(40), release_gil=True)
        assert info.value.abort_code == 0x06010002  # refused at the initiate


def test_the_interface_going_away_stops_no_thread_with_a_traceback(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    failures: list[object] = []
    monkeypatch.setattr(threading, "excepthook", failures.append)
    pair = create_veth("sdg")
    try:
        line = EthercatSlaveSim(_drives(1), pair.slave).start()
    except BaseException:
        pair.delete()
        raise
    try:
        time.sleep(0.1)
        pair.delete()  # recv answers ENETDOWN: the line waits, as for a pulled cable.
        time.sleep(0.3)
        assert failures == []
    finally:
        line.stop()
    assert failures == []
