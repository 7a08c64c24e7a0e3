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

``--esi FILE [--device N]`` (with ``--interface ethercat``) serves a twin made from any ESI in
place of ``--profile``: its identity, object dictionary, default PDO assignment, sync managers
and DC modes from the file, completed where the CiA 402 engine needs more (sim/esi_twin.py; what
was completed is printed); ``--eds FILE`` the same from an EDS, DCF or XDD as a CANopen node.
Options reproduce what real slaves do differently (docs/ethercat.md, "A twin from an ESI"):
``--claims-complete-access``, ``--sdo-info``, ``--sii-identity V:P:R``, ``--boot-delay S``,
``--no-device-name``, ``--no-watchdog``, ``--abort-reserved-bits``.

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
from typing import TYPE_CHECKING

from servodesk.errors import ServodeskError, ValidationError

if TYPE_CHECKING:
    from servodesk.domain.profile import DeviceProfile
    from servodesk.sim.esi_twin import TwinOptions


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
    p.add_argument(
        "--esi",
        default=None,
        metavar="FILE",
        help="with --interface ethercat: a twin made from this ESI (ETG.2000) instead of --profile",
    )
    p.add_argument(
        "--device", type=int, default=None, metavar="N", help="with --esi: the file's N-th device"
    )
    p.add_argument(
        "--eds",
        default=None,
        metavar="FILE",
        help="a CANopen twin made from this EDS, DCF or XDD instead of --profile",
    )
    real = p.add_argument_group(
        "real-slave behaviour (with --esi)",
        "what real EtherCAT slaves do differently from the plain twin (docs/ethercat.md)",
    )
    real.add_argument(
        "--claims-complete-access",
        action="store_true",
        help="the SII claims SDO complete access, which the firmware aborts (0601 0000h)",
    )
    real.add_argument(
        "--sdo-info",
        action="store_true",
        help="offer the SDO Information service (ETG.1000.6 §5.6.3: OD list, descriptions)",
    )
    real.add_argument(
        "--sii-identity",
        default=None,
        metavar="V:P:R",
        help="the SII's vendor id, product code and revision, where they differ from 1018h",
    )
    real.add_argument(
        "--boot-delay",
        type=float,
        default=0.0,
        metavar="S",
        help="seconds after start during which PRE-OP is not reached (a slow boot)",
    )
    real.add_argument("--no-device-name", action="store_true", help="no object 1008h")
    real.add_argument(
        "--no-watchdog",
        action="store_true",
        help="the SyncManager watchdog is not enforced (no fall back to SAFE-OP)",
    )
    real.add_argument(
        "--abort-reserved-bits",
        action="store_true",
        help="SDO aborts with the command byte's reserved bits set (9Fh instead of 80h)",
    )
    p.set_defaults(func=run)


def _twin_options(args: argparse.Namespace) -> TwinOptions:
    """The real-slave options of the command line (ValidationError for a bad value)."""
    from servodesk.sim.esi_twin import TwinOptions

    identity: tuple[int, int, int] | None = None
    text: str | None = getattr(args, "sii_identity", None)
    if text is not None:
        try:
            v, pc, r = (int(x, 0) for x in text.split(":"))
        except ValueError:
            raise ValidationError(
                f"--sii-identity {text!r} is not VENDOR:PRODUCT:REVISION",
                field="sii_identity",
                hint="three numbers, e.g. 0x9A:0x30924:0x10000",
            ) from None
        if not all(0 <= x <= 0xFFFFFFFF for x in (v, pc, r)):
            raise ValidationError(
                f"--sii-identity {text!r}: each number is 32 bits", field="sii_identity"
            )
        identity = (v, pc, r)
    delay = float(getattr(args, "boot_delay", 0.0) or 0.0)
    if not 0.0 <= delay <= 60.0:
        raise ValidationError(f"--boot-delay {delay:g} is outside 0..60 s", field="boot_delay")
    return TwinOptions(
        claims_complete_access=bool(getattr(args, "claims_complete_access", False)),
        sdo_info=bool(getattr(args, "sdo_info", False)),
        sii_identity=identity,
        boot_delay_s=delay,
        no_device_name=bool(getattr(args, "no_device_name", False)),
        watchdog=not getattr(args, "no_watchdog", False),
        abort_reserved_bits=bool(getattr(args, "abort_reserved_bits", False)),
    )


def _twin(args: argparse.Namespace) -> tuple[DeviceProfile | None, TwinOptions | None]:
    """The profile of a twin made from ``--esi`` / ``--eds`` (its completions printed), and
    the real-slave options; (None, None) without either."""
    from servodesk.devdesc import read_file
    from servodesk.sim.esi_twin import TwinOptions, twin_profile

    esi: str | None = getattr(args, "esi", None)
    eds: str | None = getattr(args, "eds", None)
    options = _twin_options(args)
    if esi is None and eds is None:
        if options != TwinOptions():
            raise ValidationError(
                "the real-slave options change a twin made from an ESI",
                hint="add --esi FILE (and --interface ethercat)",
            )
        if getattr(args, "device", None) is not None:
            raise ValidationError("--device picks a device of --esi FILE", field="device")
        return None, None
    if esi is not None and eds is not None:
        raise ValidationError("give --esi or --eds, not both", field="esi")
    if esi is not None and args.interface != "ethercat":
        raise ValidationError(
            "--esi serves an EtherCAT slave", field="esi", hint="add --interface ethercat"
        )
    if eds is not None and args.interface in ("ethercat", "slmp", "profinet"):
        raise ValidationError(
            "--eds serves a CANopen node",
            field="eds",
            hint="use a python-can interface (virtual, udp_multicast, socketcan, ...)",
        )
    if eds is not None and options != TwinOptions(no_device_name=options.no_device_name):
        raise ValidationError(
            "the EtherCAT options (complete access, SDO information, SII, boot, watchdog, "
            "abort bits) are for --esi",
            hint="leave them out with --eds; --no-device-name works with both",
        )
    path = esi if esi is not None else eds
    assert path is not None
    result = read_file(path, device=getattr(args, "device", None))
    want = "ethercat" if esi is not None else "canopen"
    if result.profile.fieldbus != want:
        raise ValidationError(
            f"{path}: describes a {result.profile.fieldbus} device, not {want}",
            field="esi" if esi is not None else "eds",
            hint="--esi takes an ESI (.xml), --eds an EDS, DCF or XDD",
        )
    profile, notes = twin_profile(result.profile, options=options)
    for note in notes:
        print(f"servodesk sim: {path}: {note}", flush=True)
    return profile, options if esi is not None else None


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
        twin, options = _twin(args)
        profile_id = twin.id if twin is not None else args.profile
        drives = (
            [(profile_id, args.node_id)]
            if axes == 1
            else [(profile_id, n) for n in range(1, axes + 1)]
        )
        plant: PlantSpec | None = load_plant_file(plant_file) if plant_file else None
        bus = SimulatedBus.start(
            drives=drives,
            interface=args.interface,
            channel=args.channel,
            bitrate=args.bitrate,
            serials=[args.serial],
            plant=plant,
            profiles=[twin] if twin is not None else [],
            twin_options=options,
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
