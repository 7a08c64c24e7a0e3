"""The per-device turn of a link: requests to one drive run one at a time, first come first served.

Every service relies on this through DriveLink.read/write (the SDO protocol has no transaction
ids, so two overlapping requests to one node would mix their answers).
"""

from __future__ import annotations

import asyncio

import pytest

from servodesk.domain.address import ObjectAddress
from servodesk.links.base import DriveLink, LinkParams, _Turn


async def _holder(turn: _Turn, name: str, log: list[str]) -> None:
    await turn.take()
    try:
        log.append(f"{name} in")
        await asyncio.sleep(0.01)
        log.append(f"{name} out")
    finally:
        turn.give()


async def test_holders_never_overlap_and_keep_their_arrival_order() -> None:
    turn = _Turn()
    log: list[str] = []
    await asyncio.gather(*(_holder(turn, n, log) for n in "abcd"))
    assert log == [f"{n} {w}" for n in "abcd" for w in ("in", "out")]
    assert turn.try_take()  # Free again once everybody has left.


async def test_a_free_turn_is_taken_at_once_and_a_held_one_is_not() -> None:
    turn = _Turn()
    assert turn.try_take()
    assert not turn.try_take()
    turn.give()
    assert turn.try_take()


async def test_a_waiter_cancelled_in_the_queue_is_skipped() -> None:
    turn = _Turn()
    log: list[str] = []
    assert turn.try_take()
    tasks = [asyncio.create_task(_holder(turn, n, log)) for n in "abc"]
    await asyncio.sleep(0)  # All three queue behind the holder.
    tasks[1].cancel()
    turn.give()
    results = await asyncio.gather(*tasks, return_exceptions=True)
    assert isinstance(results[1], asyncio.CancelledError)
    assert log == ["a in", "a out", "c in", "c out"]
    assert turn.try_take()


async def test_a_waiter_cancelled_just_after_the_hand_over_passes_the_turn_on() -> None:
    turn = _Turn()
    assert turn.try_take()
    first = asyncio.create_task(turn.take())
    second = asyncio.create_task(turn.take())
    await asyncio.sleep(0)
    turn.give()  # The turn now belongs to `first`, which has not run yet ...
    first.cancel()  # ... and is cancelled before it does.
    with pytest.raises(asyncio.CancelledError):
        await first
    await asyncio.wait_for(second, 1.0)  # `second` got the turn: no deadlock.
    assert not turn.try_take()
    turn.give()
    assert turn.try_take()


async def test_a_link_held_exclusive_keeps_its_requests_until_the_block_ends() -> None:
    # Another master talking to the same device meanwhile (tests/pdo: a plain canopen master
    # reading 1A01h) must not have the session's poll on the same SDO channel.

    log: list[str] = []

    class Recorder(DriveLink):
        fieldbus = "test"

        def _open(self) -> None:
            pass

        def _close(self) -> None:
            pass

        async def _aread(self, address: ObjectAddress) -> bytes:
            log.append(f"read {address.index:04X}h")
            return b"\x00\x00"

    link = Recorder(LinkParams())
    await link.open()
    async with link.exclusive():
        poll = asyncio.create_task(link.read(ObjectAddress(0x6041)))
        await asyncio.sleep(0.02)
        log.append("other master done")
    assert await poll == b"\x00\x00"
    assert log == ["other master done", "read 6041h"]
    await link.close()


@pytest.mark.wallclock  # A 0.2 s open in a thread against a 0.05 s time-out.
async def test_an_open_that_ends_after_its_time_out_is_closed_again() -> None:
    # A bus or an EtherCAT master opened after the caller gave up must not stay held by a link
    # nobody has (a shared master was kept for good; the next open of that NIC reused it).
    import threading
    import time

    from servodesk.errors import NotFoundError

    events: list[str] = []
    closed = threading.Event()

    class Slow(DriveLink):
        fieldbus = "test"
        OPEN_TIMEOUT = 0.05

        def _open(self) -> None:
            time.sleep(0.2)
            events.append("opened")

        def _close(self) -> None:
            events.append("closed")
            closed.set()

    link = Slow(LinkParams())
    with pytest.raises(NotFoundError, match=r"did not open within 0\.05 s"):
        await link.open()
    assert link.closed
    assert await asyncio.to_thread(closed.wait, 2.0)
    assert events == ["opened", "closed"]
