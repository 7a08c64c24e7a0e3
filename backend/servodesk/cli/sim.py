"""``servodesk sim``: one simulated CiA 402 drive as a standalone process, on a CAN bus or
its own fieldbus.

Other programs (servodesk itself, a PLC, plain python-canopen code) talk to it over the bus:
``servodesk sim --profile cia402-generic --node-id 5 --interface udp_multicast
--channel 239.74.163.9``. Runs until SIGINT or SIGTERM.

``--interface slmp --channel HOST:PORT`` serves the drive as an axis of a CC-Link IE TSN
station answering SLMP on that UDP port instead (node id 1..4 = axis X..U; docs/slmp.md):
``servodesk sim --profile ctmm04x --interface slmp --channel 127.0.0.1:5010``.

``--interface profinet --channel HOST:PORT`` serves the drive as a PROFINET IO device
answering PNIO-CM record access (PROFIdrive parameter access) on that UDP port (node id 1,
the DO-ID; docs/profinet.md):
``servodesk sim --profile lecsn-t --interface profinet --channel 127.0.0.1:34964``.

``--dcp NIC`` (with ``--interface profinet``) makes the device also answer PROFINET DCP on that
network interface, e.g. the device end of a veth pair: ``servodesk dcp identify`` on the other
end finds it, and an address set there must be one of the host's for PNIO-CM to follow it
(needs root or CAP_NET_RAW).

``--interface ethercat --channel NIC`` serves the drive as slave 1 of a simulated EtherCAT line
on that network interface (CoE SDO; docs/ethercat.md), e.g. the slave end of a veth pair:
``servodesk sim --profile hiwin-e --interface ethercat --channel veth-s`` (needs root or
CAP_NET_RAW).

``--plant FILE`` simulates the axis a TOML plant file describes (docs/tuning.md, "Plant
files"; model/plantfile.py) at its loop rate, in place of the profile's ``simulation`` section;
a file that cannot be read or holds a bad key or value is refused with the message (exit 2).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from types import FrameType

from servodesk.errors import ServodeskError, ValidationError


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "sim",
        help="run one simulated drive (CAN bus, SLMP station, PROFINET device, EtherCAT slave)",
        description="Serve one simulated CiA 402 drive until interrupted: a CANopen device on a "
        "python-can bus, or with --interface slmp / profinet / ethercat an SLMP station axis, a "
        "PROFINET IO device or an EtherCAT slave.",
    )
    p.add_argument("--profile", default="cia402-generic", help="device profile id")
    p.add_argument("--node-id", type=int, default=1, help="CANopen node id (1..127)")
    p.add_argument(
        "--interface",
        default="virtual",
        help="python-can interface (virtual, udp_multicast, socketcan, ...), or slmp: an SLMP "
        "station on UDP, profinet: a PROFINET IO device on UDP, or ethercat: an EtherCAT "
        "slave on a network interface",
    )
    p.add_argument(
        "--channel",
        default="servodesk-sim",
        help="python-can channel, host:port for slmp and profinet, or the network interface for "
        "ethercat",
    )
    p.add_argument("--bitrate", type=int, default=None, help="bit rate for real interfaces")
    p.add_argument(
        "--serial", type=lambda s: int(s, 0), default=None, help="serial number (1018h:04)"
    )
    p.add_argument(
        "--plant",
        default=None,
        metavar="FILE",
        help="TOML plant file: motor, load, compliance, noise, loop rate (docs/tuning.md)",
    )
    p.add_argument(
        "--axes",
        type=int,
        default=1,
        metavar="N",
        help="with --interface slmp: serve N axes (1..4, X..U: multidrop 0..N-1, node ids "
        "1..N) from the one station, as a multi-axis unit does (003 §4-2)",
    )
    p.add_argument(
        "--dcp",
        default=None,
        metavar="NIC",
        help="with --interface profinet: also answer PROFINET DCP on this network interface",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # Imported here so that `servodesk --help` does not load canopen.
    from servodesk.model.plantfile import PlantSpec, load_plant_file
    from servodesk.sim.bus import SimulatedBus

    stop = threading.Event()

    def _on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    plant_file: str | None = getattr(args, "plant", None)
    axes: int = getattr(args, "axes", 1)
    try:
        if axes != 1 and args.interface != "slmp":
            raise ValidationError(
                "--axes serves several axes of one SLMP station",
                field="axes",
                hint="add --interface slmp --channel HOST:PORT, or leave --axes out",
            )
        if not 1 <= axes <= 4:
            raise ValidationError(
                f"--axes {axes} is outside 1..4", field="axes", hint="a station has axes X..U"
            )
        drives = (
            [(args.profile, args.node_id)]
            if axes == 1
            else [(args.profile, n) for n in range(1, axes + 1)]
        )
        plant: PlantSpec | None = load_plant_file(plant_file) if plant_file else None
        bus = SimulatedBus.start(
            drives=drives,
            interface=args.interface,
            channel=args.channel,
            bitrate=args.bitrate,
            serials=[args.serial],
            plant=plant,
        )
        dcp_nic: str | None = getattr(args, "dcp", None)
        if dcp_nic is not None:
            if not bus.profinet:
                bus.stop()
                raise ValidationError(
                    "--dcp answers DCP for a PROFINET device",
                    field="dcp",
                    hint="add --interface profinet --channel HOST:PORT",
                )
            try:
                bus.profinet[0].serve_dcp(dcp_nic)
            except ServodeskError:
                bus.stop()
                raise
    except ServodeskError as exc:
        print(f"servodesk sim: error: {exc.message}", file=sys.stderr)
        if exc.hint:
            print(f"  hint: {exc.hint}", file=sys.stderr)
        return 2
    old = {s: signal.signal(s, _on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        for drive in bus.drives:
            _fieldbus, interface, channel, node = bus.link_of(drive)
            print(
                f"servodesk sim: serving {drive.profile.id} ({drive.profile.name}) as node "
                f"{node} on {interface}:{channel}; Ctrl+C stops",
                flush=True,
            )
        if getattr(args, "dcp", None):
            print(f"servodesk sim: answering PROFINET DCP on {args.dcp}", flush=True)
        if plant is not None:
            kind = "rigid" if plant.rigid else f"resonance {plant.resonance_hz:g} Hz"
            print(
                f"servodesk sim: plant {plant_file}: inertia ratio {plant.inertia_ratio:g}, "
                f"{kind}, loop {plant.loop_rate_hz} Hz",
                flush=True,
            )
        while not stop.wait(0.5):
            pass
    finally:
        bus.stop()
        for s, h in old.items():
            signal.signal(s, h)
    return 0
