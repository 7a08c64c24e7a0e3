"""A set of simulated drives serving CANopen on one python-can bus.

``SimulatedBus.start(drives=[(profile_id, node_id), ...])`` opens its own ``canopen.Network``
on the bus (the python-can ``virtual`` bus delivers between different Bus instances on the
same channel, ``udp_multicast`` between processes), attaches one
:class:`~servodesk.sim.canopen_device.SimCanopenDevice` per drive, sends their boot-up
messages and steps them all from one :class:`~servodesk.sim.runner.SimRunner` thread.
``servodesk serve --sim`` and ``servodesk sim`` use it. With a ``plant``
(:class:`~servodesk.model.plantfile.PlantSpec`, ``servodesk sim --plant FILE``) every drive
simulates that axis at its loop rate instead of the profile's ``simulation`` section (the
torque noise seeded with the node id).

SLMP (:class:`~servodesk.sim.slmp_station.SlmpStation`): with ``interface="slmp"`` every drive
is an axis of one SLMP station on ``channel`` (``host:port``; node id 1..4 = axis X..U), and
no CAN bus is opened. With ``slmp_channel``, the drives whose profile speaks CC-Link IE TSN
(the CTMM04x) are the station's axes X, Y, ... in order, and the others are CANopen nodes
(``servodesk serve --sim``). A drive on the station is not on the CAN bus.

PROFINET (:class:`~servodesk.sim.profinet_device.ProfinetDevice`): with
``interface="profinet"`` the one drive (node id 1, its DO-ID) is a PROFINET IO device
answering PNIO-CM record access on ``channel`` (``host:port`` on UDP), and no CAN bus is
opened. With ``profinet_channel``, the drives whose profile speaks PROFINET (the LECSN-T) are
devices there (port 0: each on a free port), and the others are CANopen nodes
(``servodesk serve --sim``).

EtherCAT (:class:`~servodesk.sim.ethercat_slave.EthercatSlaveProcess`): with
``interface="ethercat"`` every drive is a slave of one simulated line on ``channel``, a
network interface (the slave end of a veth pair, :mod:`servodesk.sim.veth`); node id N is
the N-th slave, and no CAN bus is opened. Opening the interface needs root or CAP_NET_RAW.
With ``ethercat`` (a :class:`~servodesk.sim.veth.VethPair`, which the bus then owns and
deletes at stop), the drives whose profile speaks EtherCAT (the HIWIN E) are the slaves of a
line on the pair's slave end, reached on its master end, and the others are CANopen nodes
(``servodesk serve --sim`` with ``SERVODESK_SIM_ETHERCAT=1``).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Sequence
from typing import Any

import can
import canopen

from servodesk.domain import pnio, slmp
from servodesk.domain.profile import DeviceProfile
from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import LinkError, LinkUnavailableError, ValidationError
from servodesk.model.plantfile import PlantSpec
from servodesk.sim.canopen_device import SimCanopenDevice
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.esi_twin import TwinOptions
from servodesk.sim.ethercat_slave import EthercatSlaveProcess
from servodesk.sim.profinet_device import ProfinetDevice
from servodesk.sim.runner import SimRunner
from servodesk.sim.slmp_station import SlmpStation
from servodesk.sim.veth import VethPair

#: The fieldbus name of the profiles a station serves over SLMP.
SLMP_FIELDBUS = "cclink-ie-tsn"
#: The interface (and link) name of a simulated EtherCAT line.
ETHERCAT = "ethercat"
#: The interface (and link) name of a simulated PROFINET IO device.
PROFINET = "profinet"

log = logging.getLogger(__name__)


class SimulatedBus:
    """Handle of running simulated drives: ``.drives``, ``.devices``, ``.stop()``."""

    def __init__(
        self,
        network: Any,
        devices: list[SimCanopenDevice],
        runner: SimRunner,
        interface: str,
        channel: str,
        drives: list[SimulatedDrive] | None = None,
        station: SlmpStation | None = None,
        line: EthercatSlaveProcess | None = None,
        veth: VethPair | None = None,
        profinet: Sequence[ProfinetDevice] = (),
        dcp: VethPair | None = None,
    ) -> None:
        self.network = network
        self.devices = devices
        #: Every drive, in the order they were asked for (CANopen and SLMP).
        self.drives: list[SimulatedDrive] = (
            drives if drives is not None else [d.drive for d in devices]
        )
        #: The SLMP station serving the drives not on the CAN bus, if any.
        self.station = station
        #: The simulated EtherCAT line, if any: every drive with ``interface="ethercat"``, the
        #: EtherCAT profiles' with ``ethercat`` (on ``veth``, deleted at stop).
        self.line = line
        self.veth = veth
        #: The simulated PROFINET IO devices, one drive each.
        self.profinet = list(profinet)
        #: The veth pair whose slave end the first PROFINET device answers DCP on (deleted
        #: at stop); a DCP client searches its ``master`` end.
        self.dcp = dcp
        self.runner = runner
        self.interface = interface
        self.channel = channel
        self._stopped = False

    @classmethod
    def start(
        cls,
        drives: Sequence[tuple[str, int]] = (("cia402-generic", 1),),
        interface: str = "virtual",
        channel: str = "servodesk-sim",
        bitrate: int | None = None,
        catalog: ProfileCatalog | None = None,
        serials: Sequence[int | None] | None = None,
        plant: PlantSpec | None = None,
        slmp_channel: str | None = None,
        ethercat: VethPair | None = None,
        profinet_channel: str | None = None,
        dcp: VethPair | None = None,
        profiles: Sequence[DeviceProfile] = (),
        twin_options: TwinOptions | None = None,
    ) -> SimulatedBus:
        """Start the drives; raises ValidationError / NotFoundError / LinkError. With
        ``dcp`` (a veth pair the bus then owns) the first PROFINET device also answers DCP
        on its slave end and takes the addresses set there (docs/profinet.md).

        ``profiles``: profiles that are not in the catalog (a twin made from a device
        description, sim/esi_twin.py), found by id before it; ``twin_options``: the
        EtherCAT line's slaves are such twins (their SII from the profile's sync managers,
        and the options' behaviour of real slaves)."""
        own = {p.id: p for p in profiles}
        catalog = catalog or ProfileCatalog()
        seen: set[int] = set()
        sims: list[SimulatedDrive] = []
        all_slmp = interface == "slmp"
        all_ethercat = interface == ETHERCAT
        all_profinet = interface == PROFINET
        if all_profinet and [n for _, n in drives] != [1]:
            raise ValidationError(
                "a simulated PROFINET device holds one drive object, node id 1",
                hint="PROFINET node ids are the drive object's DO-ID (1 on the LECSN-T); run "
                "one servodesk sim per device",
            )
        for i, (profile_id, node_id) in enumerate(drives):
            if all_slmp and not 1 <= node_id <= 4:
                raise ValidationError(
                    f"node id {node_id} is no axis of an SLMP station",
                    hint="SLMP node ids are the axis + 1: 1 = X, 2 = Y, 3 = Z, 4 = U",
                )
            if all_ethercat and node_id != i + 1:
                raise ValidationError(
                    f"node id {node_id} is not the position of drive {i + 1} in the EtherCAT line",
                    hint="EtherCAT node ids are the slave's position + 1: give the drives 1..N "
                    "in order",
                )
            if not 1 <= node_id <= 127:
                raise ValidationError(
                    f"node id {node_id} is outside 1..127", hint="CANopen node ids are 1..127"
                )
            if node_id in seen:
                raise ValidationError(
                    f"node id {node_id} is used twice", hint="give every drive its own node id"
                )
            seen.add(node_id)
            serial = serials[i] if serials is not None and i < len(serials) else None
            profile = own.get(profile_id) or catalog.get(profile_id)
            if plant is None:
                sims.append(SimulatedDrive(profile, node_id, serial))
            else:
                sims.append(
                    SimulatedDrive(
                        profile,
                        node_id,
                        serial,
                        plant_params=plant.plant_params(seed=node_id),
                        loop_rate_hz=plant.loop_rate_hz,
                    )
                )
        # Where each drive is served: an EtherCAT line, an SLMP station, or the CAN bus.
        line_nic: str | None
        if all_ethercat:
            on_line, line_nic = sims, channel
        else:
            on_line = [s for s in sims if ethercat is not None and s.profile.fieldbus == ETHERCAT]
            line_nic = ethercat.slave if ethercat is not None else None
        if all_slmp:
            axes = {sim.node_id - 1: sim for sim in sims}
            station_channel: str | None = channel
        else:
            on_station = [s for s in sims if slmp_channel and s.profile.fieldbus == SLMP_FIELDBUS]
            axes = dict(enumerate(on_station[:4]))
            station_channel = slmp_channel if axes else None
        pn_channel: str | None
        if all_profinet:
            on_pn, pn_channel = sims, channel
        else:
            on_pn = [s for s in sims if profinet_channel and s.profile.fieldbus == PROFINET]
            pn_channel = profinet_channel
        on_can = [
            sim
            for sim in sims
            if sim not in axes.values() and sim not in on_line and sim not in on_pn
        ]
        with contextlib.ExitStack() as undo:
            # What is started is stopped again when a later part fails; the veth pair the bus
            # was given is deleted then too (it owns it from here on).
            if ethercat is not None:
                undo.callback(ethercat.delete)
            if dcp is not None:
                undo.callback(dcp.delete)
            ecat_line = None
            if on_line:
                assert line_nic is not None
                try:
                    ecat_line = EthercatSlaveProcess(
                        on_line, line_nic, options=twin_options
                    ).start()
                except ValueError as exc:
                    raise ValidationError(str(exc)) from exc
                undo.callback(ecat_line.stop)
            station = None
            if station_channel is not None:
                host, port = slmp.parse_channel(station_channel, server=True)
                try:
                    station = SlmpStation(axes, host, port).start()
                except OSError as exc:
                    raise LinkError(
                        f"cannot serve SLMP on udp {host}:{port}: {exc}",
                        hint="choose another port, or stop the program that holds this one",
                    ) from exc
                undo.callback(station.stop)
            devices_pn: list[ProfinetDevice] = []
            if on_pn:
                assert pn_channel is not None
                host, port = pnio.parse_channel(pn_channel, server=True)
                if port and len(on_pn) > 1:
                    raise ValidationError(
                        f"{len(on_pn)} PROFINET drives cannot share udp port {port}",
                        hint="give port 0 (each device on a free port)",
                    )
                for sim in on_pn:
                    try:
                        pn_dev = ProfinetDevice(sim, host, port).start()
                    except OSError as exc:
                        raise LinkError(
                            f"cannot serve PROFINET on udp {host}:{port}: {exc}",
                            hint="choose another port, or stop the program that holds this one",
                        ) from exc
                    undo.callback(pn_dev.stop)
                    devices_pn.append(pn_dev)
                if dcp is not None:
                    # One device per interface: it answers with the interface's MAC.
                    devices_pn[0].serve_dcp(dcp.slave, manage_addresses=True)
                    # And takes an IO controller's AR with RT frames there (cyclic data).
                    devices_pn[0].serve_io(dcp.slave)
            network = cls._connect(interface, channel, bitrate) if on_can else None
            undo.pop_all()
        devices: list[SimCanopenDevice] = []
        for sim in on_can:
            dev = SimCanopenDevice(sim)
            assert network is not None  # Opened above when any drive is on the CAN bus.
            network.add_node(dev)
            devices.append(dev)
        runner = SimRunner(sims)
        for sim in sims:
            sim.step(sim.CONTROL_PERIOD)  # Leave "Not ready to switch on" before boot-up.
        for dev in devices:
            dev.boot()
        runner.start()
        log.info("simulated drives %s on %s:%s", list(drives), interface, channel)
        return cls(
            network,
            devices,
            runner,
            interface,
            channel,
            sims,
            station,
            ecat_line,
            ethercat,
            devices_pn,
            dcp,
        )

    @staticmethod
    def _connect(interface: str, channel: str, bitrate: int | None) -> Any:
        network = canopen.Network()
        # The notifier thread wakes this often to see whether it should stop (default 1 s).
        network.NOTIFIER_CYCLE = 0.05
        kwargs: dict[str, Any] = {"interface": interface, "channel": channel}
        if bitrate is not None:
            kwargs["bitrate"] = bitrate
        try:
            network.connect(**kwargs)
        except can.CanInterfaceNotImplementedError as exc:
            hint = (
                "python-can's udp_multicast interface needs the msgpack package"
                if interface == "udp_multicast"
                else f"use one of: {', '.join(sorted(can.VALID_INTERFACES))}"
            )
            raise LinkUnavailableError(
                f"the CAN interface {interface!r} is not available: {exc}", hint=hint
            ) from exc
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise LinkError(
                f"cannot open CAN bus {interface}:{channel}: {exc}",
                hint="check --interface and --channel (and --bitrate for real interfaces)",
            ) from exc
        return network

    def link_of(self, drive: SimulatedDrive) -> tuple[str, str, str, int]:
        """(fieldbus, interface, channel, node id) a client reaches ``drive`` at."""
        if self.station is not None:
            for axis, sim in self.station.axes.items():
                if sim is drive:
                    return SLMP_FIELDBUS, "slmp", self.station.channel, axis + 1
        if self.line is not None and drive in self.line.drives:
            # The master's end of the pair, where the line was made for serve --sim; else the
            # interface the line is on (servodesk sim: the other end is the caller's).
            where = self.veth.master if self.veth is not None else self.line.ifname
            return ETHERCAT, ETHERCAT, where, self.line.drives.index(drive) + 1
        for pn in self.profinet:
            if pn.drive is drive:
                return PROFINET, PROFINET, pn.channel, 1
        return "canopen", self.interface, self.channel, drive.node_id

    def stop(self) -> None:
        """Stop stepping, silence the heartbeats and close the bus (idempotent)."""
        if self._stopped:
            return
        self._stopped = True
        self.runner.stop()
        if self.station is not None:
            self.station.stop()
        for pn in self.profinet:
            pn.stop()
        if self.line is not None:
            self.line.stop()
        for pair in (self.veth, self.dcp):
            if pair is None:
                continue
            try:
                pair.delete()
            except Exception:  # Best effort: the pair may be gone with its namespace.
                log.debug("veth pair not deleted", exc_info=True)
        for dev in self.devices:
            try:
                dev.shutdown()
            except Exception:  # Best effort: the bus may already be gone.
                log.debug("device shutdown failed", exc_info=True)
        try:
            if self.network is not None:
                self.network.disconnect()
        except Exception:
            log.debug("network disconnect failed", exc_info=True)

    def __enter__(self) -> SimulatedBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
