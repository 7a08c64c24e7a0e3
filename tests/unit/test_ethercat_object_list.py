"""EthercatLink.object_list against a scripted pysoem slave (issue 46, ETG.1000.6 §5.6.3): a
description SOEM did not take is asked once more after the slave's mailbox was emptied, a
second failure fails the read, and a slave that refuses the service is asked only once."""

from __future__ import annotations

from typing import Any

import pysoem
import pytest

from servodesk.errors import LinkError
from servodesk.links import ethercat_link
from servodesk.links.base import LinkParams
from servodesk.links.ethercat_link import EthercatLink


class _Entry:
    def __init__(self, name: bytes, data_type: int, bits: int, access: int) -> None:
        self.name, self.data_type, self.bit_length, self.obj_access = name, data_type, bits, access


class _Object:
    """pysoem's CdefCoeObject: each read of a description asks the slave (here: fails
    ``fails`` times first)."""

    def __init__(self, index: int, fails: int) -> None:
        self.index, self.name, self.object_code, self.data_type = index, b"Identity", 9, 0
        self.fails = fails

    @property
    def entries(self) -> list[_Entry]:
        if self.fails:
            self.fails -= 1
            raise pysoem.SdoInfoError("Sdo ObjectEntry Info read failed")
        # Sub-index 2 refused by the slave: SOEM leaves it zero.
        return [
            _Entry(b"SubIndex 000", 5, 8, 7),
            _Entry(b"Vendor ID", 7, 32, 7),
            _Entry(b"", 0, 0, 0),
        ]


class _Master:
    def __init__(self) -> None:
        self.errors: list[Any] = []

    def _collect_mailbox_errors(self) -> list[Any]:
        out, self.errors = self.errors, []
        return out


class _Slave:
    def __init__(self, objects: list[_Object] | Exception, refusal: Any = None) -> None:
        self.objects, self.refusal, self.polls, self.stale = objects, refusal, 0, 1
        self.lists = 0
        self.master = _Master()

    @property
    def od(self) -> list[_Object]:
        self.lists += 1
        if isinstance(self.objects, Exception):
            if self.refusal is not None:  # SOEM keeps the mailbox error in its list.
                self.master.errors.append(self.refusal)
            raise self.objects
        return self.objects

    def mbx_receive(self) -> int:
        self.polls += 1
        if self.stale:  # One late answer waits in the out mailbox.
            self.stale -= 1
            return 1
        return 0


def _link(slave: _Slave) -> EthercatLink:
    link = EthercatLink(LinkParams(interface="ethercat", channel="sdfake0", node_id=1))
    link._shared = ethercat_link._Master(master=slave.master, slaves=1)
    link._slave = slave
    return link


@pytest.fixture(autouse=True)
def _no_waits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ethercat_link, "FLUSH_POLL_S", 0.0)


def test_a_lost_description_is_asked_again_after_the_mailbox_is_emptied() -> None:
    slave = _Slave([_Object(0x1018, fails=1)])
    listed = _link(slave)._object_list()
    assert listed is not None
    (obj,) = listed
    assert [(e.subindex, e.name, e.data_type) for e in obj.entries] == [
        (0, "SubIndex 000", 5),
        (1, "Vendor ID", 7),
    ]
    assert slave.stale == 0  # The late answer was read and dropped, not left for an SDO.


def test_two_failures_fail_the_read() -> None:
    slave = _Slave([_Object(0x1018, fails=2)])
    link = _link(slave)
    with pytest.raises(LinkError, match=r"1018h .* failed 2 times"):
        link._object_list()


def test_a_slave_without_the_service_is_asked_once() -> None:
    refusal = pysoem.MailboxError(1, 4, "The service is no supported")
    slave = _Slave(pysoem.SdoInfoError("Sdo List Info read failed"), refusal)
    assert _link(slave)._object_list() is None
    assert slave.lists == 1


def test_an_object_list_lost_without_a_refusal_is_asked_again() -> None:
    slave = _Slave(pysoem.SdoInfoError("Sdo List Info read failed"))
    assert _link(slave)._object_list() is None
    assert slave.lists == 2 and slave.stale == 0
