"""The dead-man's stop on EtherCAT does not wait for the event loop (issue "Motion safety"
item 3): ``EthercatLink.stop_frame`` writes the quick stop over CoE from another thread while
the loop is held, and the simulated HIWIN drive (behind its ESC on a veth pair) leaves
Operation enabled at once (CiA 402-2 §6.2.1 table 28, transition 11)."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.links.base import LinkParams
from servodesk.links.ethercat_link import EthercatLink
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.ethercat_slave import EthercatSlaveSim
from servodesk.sim.runner import SimRunner
from servodesk.sim.veth import VethPair

pytestmark = pytest.mark.asyncio

CONTROLWORD = ObjectAddress(0x6040)


def _state(drive: SimulatedDrive) -> int:
    """The statusword's state bits (CiA 402-2 §6.2.2 table 30: bits 0-3, 5, 6)."""
    return drive.statusword & 0x006F


async def test_the_quick_stop_goes_out_while_the_loop_is_held(veth: VethPair) -> None:
    drive = SimulatedDrive(ProfileCatalog().get("hiwin-e"), 1, 0x7000)
    runner = SimRunner([drive])  # The drive's own time: its state machine and axis.
    runner.start()
    try:
        await _stop_while_held(drive, veth)
    finally:
        runner.stop()


async def _stop_while_held(drive: SimulatedDrive, veth: VethPair) -> None:
    with EthercatSlaveSim([drive], veth.slave):
        link = EthercatLink(LinkParams(interface="ethercat", channel=veth.master, node_id=1))
        async with link:
            for word in (0x0006, 0x0007, 0x000F):  # Shutdown, switch on, enable operation.
                await link.write(CONTROLWORD, word.to_bytes(2, "little"))
                await asyncio.sleep(0.02)
            assert _state(drive) == 0x0027  # Operation enabled
            stop = link.stop_frame()
            assert stop is not None
            thread = threading.Thread(target=stop)
            started = time.monotonic()
            thread.start()
            stopped_at = None
            # The event loop is held from here (no await): only the thread can send.
            while time.monotonic() - started < 1.0:
                if _state(drive) != 0x0027:
                    stopped_at = time.monotonic()
                    break
                time.sleep(0.001)  # noqa: ASYNC251 - the point: the event loop is held
            thread.join(2.0)
            assert stopped_at is not None, "the drive was still enabled after 1 s"
            assert (stopped_at - started) < 0.1
            # Quick stop active (0x0007) or, its ramp done, Switch on disabled (0x0040).
            assert _state(drive) in (0x0007, 0x0040)
            assert int(drive.read(0x6040)) == 0x0002
