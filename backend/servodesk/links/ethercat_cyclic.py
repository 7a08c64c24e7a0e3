"""Cyclic process data on an EtherCAT line: the :class:`~servodesk.links.cyclic.CyclicTransport`
of the EtherCAT link.

The cyclic exchange (services/cyclic.py) speaks in PDO frames by identifier and a SYNC that
paces them, as on CAN. On EtherCAT a slave's assigned RxPDO is its output image and its
assigned TxPDO its input image (HIWIN 000 §2.8: one of each, assigned in 1C12h / 1C13h), so
the identifiers are those the exchange already uses for them, 200h + node and 180h + node, and
"SYNC" is one process data cycle of the line: SOEM's ``send_processdata`` (one LRW through
the FMMUs) and ``receive_processdata``, after which every subscribed slave's inputs are handed
on. The transports of the slaves of one line share their master's receivers and outputs, so
that the one cycle thread of the line (one "SYNC producer" per bus) serves them all.

Each cycle also goes into the line's health (links/ethercat_health.py): inputs are handed on
only from a cycle with the expected working counter while the line is in its state; the link
is "lost" on the NIC's carrier or after cycles with nothing back, and once frames return the
same thread brings the slaves back to their AL state (:meth:`EthercatCyclic._recover`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from servodesk.links.cyclic import CyclicTransport
from servodesk.links.ethercat_health import (
    CARRIER_EVERY_S,
    DEGRADED,
    LOST,
    LOST_CYCLES,
    OK,
    RECOVER_EVERY_S,
    RECOVERING,
    read_carrier,
)
from servodesk.links.ethercat_link import (
    AL_OP,
    AL_SAFEOP,
    AL_STATES,
    PROCESS_DATA_TIMEOUT_US,
)

log = logging.getLogger(__name__)
#: The local time-out SOEM's slave recovery and reconfiguration take per request (µs).
RECOVER_TIMEOUT_US = 2000
#: After a recovery step that took longer than SLOW_STEP_S (SOEM waited for a slave that
#: does not answer, holding the line), the next one waits RECONFIGURE_EVERY_S [s].
RECONFIGURE_EVERY_S = 1.0
SLOW_STEP_S = 0.2

if TYPE_CHECKING:
    from servodesk.links.ethercat_link import EthercatLink


class EthercatCyclic(CyclicTransport):
    """The process data of the slaves of one EtherCAT line (see the module docstring)."""

    def __init__(self, link: EthercatLink) -> None:
        self._shared = link.line()
        self._channel = link.params.channel
        # A new exchange starts without the outputs of the last one (it may run inputs only).
        self._shared.outputs.pop(link.params.node_id - 1, None)
        #: Cycles whose inputs were not handed on (working counter short, link lost).
        self.missed = 0
        #: The slaves the last state reading found out of the line's state: the ones a
        #: short working counter is counted against.
        self._suspects: list[int] = []
        #: State reads in a row each slave did not answer (by position).
        self._silent: dict[int, int] = {}
        if not any(self._shared.receivers.values()):
            # No exchange of the line runs: the counters start again (another session's
            # running exchange keeps its own).
            self._shared.health.reset(self._shared.slaves)

    @property
    def bus_key(self) -> object:
        return ("ethercat", self._channel)

    def subscribe(self, ident: int, callback: Callable[[bytes, float], None]) -> None:
        with self._shared.lock:
            self._shared.receivers.setdefault(ident, []).append(callback)

    def unsubscribe(self, ident: int, callback: Callable[[bytes, float], None]) -> None:
        with self._shared.lock:
            found = self._shared.receivers.get(ident, [])
            if callback in found:
                found.remove(callback)

    def send(self, ident: int, data: bytes) -> None:
        """The outputs of slave ``ident - 200h`` for the next cycle."""
        position = ident - 0x200 - 1
        if 0 <= position < self._shared.slaves:
            self._shared.outputs[position] = bytes(data)

    def send_rtr(self, ident: int, length: int) -> None:
        """EtherCAT has no remote frames: the inputs come with every cycle."""

    def send_sync(self, counter: int | None = None) -> None:
        """One process data cycle of the line; each subscribed slave's inputs handed on
        when they are valid (the expected working counter, the line in its state). Every
        cycle is accounted for in the line's health (links/ethercat_health.py), and a line
        that lost its link is brought back to its state from here once frames return."""
        shared = self._shared
        health = shared.health
        with shared.lock:
            if not shared.mapped:
                return
            master = shared.master
            slaves = master.slaves
            for position, data in shared.outputs.items():
                out = slaves[position].output
                if len(out):
                    slaves[position].output = data[: len(out)].ljust(len(out), b"\x00")
            master.send_processdata()
            wkc = int(master.receive_processdata(PROCESS_DATA_TIMEOUT_US))
            now = time.monotonic()
            expected = int(master.expected_wkc)
            self._account(wkc, expected, now)
            # Not while no frame comes back: a state read would only wait for its time-out.
            if health.state != OK and wkc >= 0 and now >= health.recover_next:
                health.recover_next = now + RECOVER_EVERY_S
                self._recover(wkc == expected, now)
            if wkc != expected or health.state in (LOST, RECOVERING):
                self.missed += 1
                return
            inputs = [
                (callbacks, bytes(slaves[ident - 0x180 - 1].input))
                for ident, callbacks in shared.receivers.items()
                if callbacks and 0 <= ident - 0x180 - 1 < len(slaves)
            ]
        for callbacks, data in inputs:
            for cb in list(callbacks):
                cb(data, now)

    def health(self) -> dict[str, Any]:
        return self._shared.health.view()

    def link_state(self) -> str:
        return self._shared.health.state

    def _account(self, wkc: int, expected: int, now: float) -> None:
        """One cycle into the line's health: counters, stale inputs, the link lost."""
        health = self._shared.health
        health.cycles += 1
        health.last_wkc = wkc
        health.expected_wkc = expected
        if now - health.carrier_at >= CARRIER_EVERY_S:
            health.carrier_at = now
            health.carrier = read_carrier(self._channel)
        positions = range(len(self._shared.master.slaves))
        if wkc == expected and health.carrier is not False:
            health.bad_run = health.silent_run = 0
            health.good_cycles += 1
            health.last_good = now
            if health.state == LOST:
                health.state = RECOVERING
                health.reason = "frames come back: bringing the slaves back to their state"
                health.recover_next = now
            elif health.state == DEGRADED:
                health.state, health.reason = OK, None
            return
        health.bad_run += 1
        if wkc < 0:
            health.missing_frames += 1
            for p in positions:
                health.slave(p).missing_frames += 1
        else:
            health.wkc_errors += 1
            for p in self._suspects or positions:
                health.slave(p).wkc_errors += 1
        # Nothing back, or nothing that took part: the frame went nowhere or through
        # no configured slave. A counter of 0 after the link is back (slaves that lost
        # their configuration) is the recovery's to handle, not a new loss.
        answered = wkc >= 0 and health.carrier is not False
        if answered and health.state in (LOST, RECOVERING):
            health.silent_run = 0
        else:
            health.silent_run = health.silent_run + 1 if wkc <= 0 else 0
        if health.carrier is False or health.silent_run >= LOST_CYCLES:
            if health.state != LOST:
                health.state = LOST
                health.lost_at = now
                health.losses += 1
                health.reason = (
                    f"the NIC {self._channel} has no carrier (cable pulled?)"
                    if health.carrier is False
                    else f"no frame came back for {health.silent_run} cycles"
                    if wkc < 0
                    else f"working counter 0 for {health.silent_run} cycles"
                )
                log.warning("EtherCAT line %s: link lost (%s)", self._channel, health.reason)
            return
        if health.state == LOST:
            health.state = RECOVERING  # Something answers again.
            health.recover_next = now
        elif health.state == OK:
            health.state = DEGRADED
            health.recover_next = now
        if health.state == DEGRADED:
            health.reason = f"working counter {wkc} of {expected}"

    def _recover(self, full_wkc: bool, now: float) -> None:
        """Read the slaves' AL states and ask each one that is not in the line's state to
        go back (ETG.1000.6 §6.4.1): its error indication acknowledged (AL control bit 4),
        SAFE-OP to OP, a slave that lost its configuration (INIT, PRE-OP: power cycled)
        configured again by SOEM (``ecx_reconfig_slave``), one no longer answering at its
        station address found again (``ecx_recover_slave``). Only the line's state is
        restored: the drives' CiA 402 state is theirs (a drive that faulted stays in Fault
        until the user resets it; the outputs carry what services/cyclic.py left there)."""
        shared = self._shared
        health = shared.health
        master = shared.master
        if health.state == LOST or health.carrier is False:
            return
        try:
            master.read_state()
        except Exception as exc:
            log.debug("EtherCAT line %s: states not readable: %s", self._channel, exc)
            return
        suspects: list[int] = []
        slow = False
        for position, s in enumerate(master.slaves):
            target = shared.target_states.get(position, AL_SAFEOP)
            state = int(s.state)
            code = int(s.al_status) if state & 0x10 else 0
            h = health.slave(position)
            h.al_state = AL_STATES.get(state & 0x0F, "none")
            h.al_status_code = code
            if state & 0x0F:
                self._silent.pop(position, None)
            if state == target:
                continue
            suspects.append(position)
            log.info(
                "EtherCAT slave %d on %s: in %s (AL status 0x%02X, code 0x%04X), wants %s",
                position + 1,
                self._channel,
                h.al_state,
                state,
                code,
                AL_STATES.get(target, "?"),
            )
            try:
                if state & 0x10:
                    s.state = (state & 0x0F) | 0x10  # Acknowledge the error indication.
                    s.write_state()
                elif state & 0x0F == 0:
                    # No answer to the state read: a frame lost as the link came up is
                    # common; a slave that stays silent is looked for at its address.
                    self._silent[position] = self._silent.get(position, 0) + 1
                    if self._silent[position] >= 2:
                        t0 = time.monotonic()
                        s.recover(RECOVER_TIMEOUT_US)
                        slow = time.monotonic() - t0 > SLOW_STEP_S
                elif state & 0x0F in (AL_SAFEOP, AL_OP):
                    s.state = target
                    s.write_state()
                elif target in (AL_SAFEOP, AL_OP):
                    t0 = time.monotonic()
                    s.reconfig(RECOVER_TIMEOUT_US)
                    slow = time.monotonic() - t0 > SLOW_STEP_S
            except Exception as exc:
                log.info("EtherCAT slave %d: recovery step failed: %s", position + 1, exc)
        self._suspects = suspects
        if slow:
            # SOEM's recovery or reconfiguration waited for a slave (seconds at worst,
            # holding the line): not again at the next step.
            health.recover_next = time.monotonic() + RECONFIGURE_EVERY_S
        if not suspects and full_wkc and health.state == RECOVERING:
            health.state, health.reason = OK, None
            health.back_at = now
            health.bad_run = 0
            log.warning(
                "EtherCAT line %s: back in its state %.3f s after the link was lost",
                self._channel,
                now - (health.lost_at or now),
            )
