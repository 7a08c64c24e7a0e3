"""A set of simulated drives serving CANopen on one python-can bus.

``SimulatedBus.start(drives=[(profile_id, node_id), ...])`` opens its own ``canopen.Network``
on the bus (the python-can ``virtual`` bus delivers between different Bus instances on the
same channel, ``udp_multicast`` between processes), attaches one
:class:`~servodesk.sim.canopen_device.SimCanopenDevice` per drive, sends their boot-up
messages and steps them all from one :class:`~servodesk.sim.runner.SimRunner` thread.
``servodesk serve --sim`` and ``servodesk sim`` use it. With a ``plant``
(:class:`~servodesk.sim.plantfile.PlantSpec`, ``servodesk sim --plant FILE``) every drive
simulates that axis at its loop rate instead of the profile's ``simulation`` section (the
torque noise seeded with the node id).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import can
import canopen

from servodesk.domain.profile_loader import ProfileCatalog
from servodesk.errors import LinkError, LinkUnavailableError, ValidationError
from servodesk.sim.canopen_device import SimCanopenDevice
from servodesk.sim.engine import SimulatedDrive
from servodesk.sim.plantfile import PlantSpec
from servodesk.sim.runner import SimRunner

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
    ) -> None:
        self.network = network
        self.devices = devices
        self.drives: list[SimulatedDrive] = [d.drive for d in devices]
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
    ) -> SimulatedBus:
        """Start the drives; raises ValidationError / NotFoundError / LinkError."""
        catalog = catalog or ProfileCatalog()
        seen: set[int] = set()
        sims: list[SimulatedDrive] = []
        for i, (profile_id, node_id) in enumerate(drives):
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
            profile = catalog.get(profile_id)
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
        devices: list[SimCanopenDevice] = []
        for sim in sims:
            dev = SimCanopenDevice(sim)
            network.add_node(dev)
            devices.append(dev)
        runner = SimRunner(sims)
        for sim in sims:
            sim.step(sim.CONTROL_PERIOD)  # Leave "Not ready to switch on" before boot-up.
        for dev in devices:
            dev.boot()
        runner.start()
        log.info("simulated drives %s on %s:%s", list(drives), interface, channel)
        return cls(network, devices, runner, interface, channel)

    def stop(self) -> None:
        """Stop stepping, silence the heartbeats and close the bus (idempotent)."""
        if self._stopped:
            return
        self._stopped = True
        self.runner.stop()
        for dev in self.devices:
            try:
                dev.shutdown()
            except Exception:  # Best effort: the bus may already be gone.
                log.debug("device shutdown failed", exc_info=True)
        try:
            self.network.disconnect()
        except Exception:
            log.debug("network disconnect failed", exc_info=True)

    def __enter__(self) -> SimulatedBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
