"""Shared fixtures. Tests run against simulated drives on python-can virtual buses."""

from __future__ import annotations

import gc
import itertools
import logging
import os
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from servodesk.sim.bus import SimulatedBus

# The 3D viewer binds a TCP port per app; tests that want it (tests/viewer, the viewer page)
# set their own free port, every other app in the suite runs without it.
os.environ.setdefault("SERVODESK_VIEWER_PORT", "0")
# The server answers only to its own host names (docs/security.md): beside the loopback
# names, those the suite's clients send: Starlette's TestClient ("testserver") and the httpx
# ASGITransport clients' base URLs ("http://test", "http://t").
os.environ.setdefault("SERVODESK_ALLOWED_HOSTS", "testserver,test,t")
# Never the user's ~/.servodesk (backups, audit log, accounts, the store's schema): a test
# that gives no data directory of its own, and every command it starts, gets this one. A
# store left at a newer schema revision by one checkout failed another's run.
os.environ.setdefault("SERVODESK_DATA_DIR", tempfile.mkdtemp(prefix="servodesk-tests-"))
# A response model that leaves out a key its service sends fails the request (api/reply.py):
# served, the key would vanish from the answer unnoticed.
os.environ.setdefault("SERVODESK_STRICT_REPLIES", "1")

_counter = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual CAN channel no other test uses (virtual buses are shared by name)."""
    return f"test-{os.getpid()}-{next(_counter)}"


#: ``sim_bus(("cia402-generic", 5), ...)``: see :func:`sim_bus`.
StartSims = Callable[..., "SimulatedBus"]


@pytest.fixture
def sim_bus(channel: str) -> Iterator[StartSims]:
    """Start simulated drives: ``sim_bus(("cia402-generic", 5), channel=..., **start_args)``
    returns the running SimulatedBus (on the test's ``channel`` unless told otherwise). Every
    bus it started stops after the test, last first, however the test ended: after the test's
    own clean-up (a session manager closes its links before the drives go)."""
    from servodesk.sim.bus import SimulatedBus

    started: list[SimulatedBus] = []

    def start(*drives: tuple[str, int], **kwargs: Any) -> SimulatedBus:
        kwargs.setdefault("channel", channel)
        bus = SimulatedBus.start(drives=list(drives) or [("cia402-generic", 1)], **kwargs)
        started.append(bus)
        return bus

    try:
        yield start
    finally:
        for bus in reversed(started):
            bus.stop()


#: How long a thread started by a module's tests may take to end after its last test: the
#: slowest clean shutdown in the suite is python-can's cyclic sender, which notices its stop
#: at the next period (servodesk's heartbeat: 1 s, the twins': up to 1 s).
THREAD_GRACE_S = 3.0


def _thread_text(t: threading.Thread) -> str:
    target = getattr(t, "_target", None)
    where = getattr(target, "__qualname__", None) or type(t).__qualname__
    module = getattr(target, "__module__", None) or type(t).__module__
    return f"{t.name!r} ({module}.{where}, daemon={t.daemon})"


@pytest.fixture(scope="module", autouse=True)
def _no_leaked_threads(request: pytest.FixtureRequest) -> Iterator[None]:
    """Every thread a module's tests started has ended once its fixtures are torn down, and
    no asyncio task was left pending when its event loop closed.

    A thread that outlives its app or bus is a stop that did not happen: a heartbeat still
    on the bus after the link closed, a worker process's feeder still waiting (issue 51,
    item 6). Checked per module, not per test: module-scoped fixtures (an app, a twin's
    bus) rightly outlive one test, and are torn down before this fixture's check runs."""
    before = {t.ident for t in threading.enumerate()}
    tasks = _ErrorLog()
    asyncio_log = logging.getLogger("asyncio")
    asyncio_log.addHandler(tasks)
    try:
        yield
        # A task still pending when its loop closed is destroyed with the loop's last reference
        # and asyncio logs it then: collect now, so it is logged for this module.
        gc.collect()
    finally:
        asyncio_log.removeHandler(tasks)
    lost = [m for m in tasks.messages if "Task was destroyed but it is pending" in m]
    deadline = time.monotonic() + THREAD_GRACE_S
    while True:
        leaked = [t for t in threading.enumerate() if t.ident not in before and t.is_alive()]
        if not leaked or time.monotonic() >= deadline:
            break
        time.sleep(0.05)
    if lost:
        tasks_text = " | ".join(m.splitlines()[0][:300] for m in lost[:5])
        report = os.environ.get("SERVODESK_THREAD_REPORT")
        if report:
            with open(report, "a", encoding="utf-8") as out:
                out.write(f"{request.node.nodeid}\ttasks: {tasks_text}\n")
        else:
            pytest.fail(
                f"{len(lost)} asyncio task(s) of {request.node.nodeid} were still pending when "
                f"their event loop closed: {tasks_text}. Cancel and await them where they are "
                "started (a fixture, the app's shutdown).",
                pytrace=False,
            )
    if leaked:
        names = "; ".join(_thread_text(t) for t in leaked)
        report = os.environ.get("SERVODESK_THREAD_REPORT")
        if report:
            with open(report, "a", encoding="utf-8") as out:
                out.write(f"{request.node.nodeid}\t{names}\n")
            return
        pytest.fail(
            f"{len(leaked)} thread(s) started by {request.node.nodeid} still run "
            f"{THREAD_GRACE_S:g} s after its last test: {names}. Stop what started them "
            "in the fixture or the app's shutdown that owns them.",
            pytrace=False,
        )


class _ErrorLog(logging.Handler):
    """The ERROR records a logger wrote while it was attached (messages only)."""

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@pytest.fixture(autouse=True)
def _websocket_messages_in_contract(request: pytest.FixtureRequest) -> Iterator[None]:
    """Every WebSocket message a test's server tries to send is one of ServerMessage's
    (api/ws_messages.py): the UI's types are generated from it, and api/ws.py logs and drops
    any other, so a publisher that sends a field or type the union lacks fails the test that
    makes it send one, whatever that test is about."""
    handler = _ErrorLog()
    logger = logging.getLogger("servodesk.api.ws")
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
    refused = [m for m in handler.messages if "not sent" in m]
    if refused and request.node.get_closest_marker("refuses_ws_messages") is None:
        pytest.fail("WebSocket messages not sent:\n" + "\n".join(refused))


#: Test directories whose tests run on simulated time or none: CPU-bound computation (the
#: tuning's searches on simulated drives), nothing that waits on the wall clock. ``make test``
#: (scripts/run_tests.sh) runs these first on every core, then the rest: those run drives,
#: buses and browsers on the wall clock and must not be kept waiting for a core.
#: A test here that times something is marked ``wallclock``.
SIMTIME_DIRS = ("tests/tuning", "tests/unit")


#: The fast tier, ``make check`` (docs/testing.md): pure tests only. No bus (not even a
#: virtual CAN channel), no server, no browser, no subprocess, nothing that waits on the wall
#: clock: codecs, profiles, device descriptions, PDO rules, the scope's maths and files, the
#: simulated drive's engine stepped in simulated time. A directory or a file; a test here is
#: marked ``check`` (a wall-clock one is marked ``wallclock`` and left out).
CHECK_PATHS = (
    "tests/unit/test_address.py",
    "tests/unit/test_cia402.py",
    "tests/unit/test_datatypes.py",
    "tests/unit/test_homing_estimate.py",
    "tests/unit/test_ramps.py",
    "tests/unit/test_sdo_frames.py",
    "tests/unit/test_sdo_block_frames.py",
    "tests/unit/test_values.py",
    "tests/unit/test_viewer_camera.py",
    "tests/devdesc",
    "tests/profiles",
    "tests/pdo/test_domain_pdo.py",
    "tests/pdo/test_plan_golden.py",
    "tests/scope/test_scope_core.py",
    "tests/scope/test_scope_export.py",
    "tests/scope/test_scope_wire.py",
    "tests/backup/test_paramset.py",
    "tests/report/test_report_document.py",
    "tests/sim/test_sim_plant.py",
    "tests/sim/test_servo.py",
    "tests/sim/test_twomass.py",
    "tests/sim/test_sim_objects.py",
    "tests/sim/test_sim_state_machine.py",
    "tests/sim/test_sim_modes.py",
    "tests/sim/test_sim_recorder.py",
    "tests/sim/test_onetouch.py",
    "tests/sim/test_fused_move.py",
)
#: Wall-clock tests that must run alone (``make test``'s last part, ``-m serial``): they time
#: something (a dead-man's latency, a loop never held, a stream's rate), run a browser, or
#: hold a fixed resource (a multicast group). Every other wall-clock test runs two at a time,
#: one test file per worker (``-m shared``): measured on 2 cores, tests/security with
#: tests/profinet took 99 s that way against 155 s one at a time, all passing.
SERIAL_PATHS = (
    "tests/browser",
    "tests/operation/test_deadman.py",
    "tests/operation/test_heavy_requests.py",
    "tests/operation/test_stop_all.py",
    "tests/operation/test_control.py",
    "tests/operation/test_drive_watchdog.py",
    "tests/operation/test_offload.py",
    "tests/ethercat/test_link_loss.py",
    "tests/ethercat/test_deadman_stop.py",
    "tests/ethercat/test_status.py",
    "tests/ethercat/test_scope_process_data.py",
    # The ESI twins answered an SDO late under load (issue 46's note): one at a time.
    "tests/ethercat/test_esi_twins.py",
    "tests/ethercat/test_sdo_info_profile.py",
    # PROFINET cyclic IO: RT frames every 1-2 ms with a 200 ms watchdog; beside the shared
    # part's workers a CI run saw no input frame for 516 ms ("link lost" in a move).
    "tests/profinet/test_cyclic.py",
    "tests/api/test_status_api.py",
    "tests/homing/test_homing_deadman.py",
    "tests/integration/test_canopen_link.py",
    "tests/integration/test_link_udp_multicast.py",
    # CAN on UDP multicast: python-can uses one port for every group, so on Linux a socket
    # receives every group joined on the host, and a master opened by an earlier test in the
    # same process (the schemathesis runs open sessions on udp_multicast) answered into the
    # plain master's SDO transfers ("Unexpected response 0x60") when it ran two at a time.
    "tests/integration/test_plain_canopen.py",
    "tests/scope/test_scope_stream.py",
    "tests/scope/test_scope_service.py",
    "tests/tuning_api/test_tuning_api.py",
)
#: Tests that share something on the host run on one worker, one at a time: the twins of
#: PROFINET (RPC port 34964, DCP on raw Ethernet), SLMP and EtherCAT (veth pairs); and CAN on
#: UDP multicast, whose groups all use one port (python-can's), so a socket receives every
#: group joined on the host (Linux's IP_MULTICAST_ALL): the plain-canopen master saw the
#: schemathesis runs' SDO requests (their session bodies may name udp_multicast).
_ONE_WORKER: dict[str, str] = {
    "tests/profinet": "profinet",
    "tests/slmp": "slmp",
    "tests/ethercat": "ethercat",
    "tests/api/test_schemathesis.py": "udp_multicast",
    "tests/security/test_rights_schemathesis.py": "udp_multicast",
}
#: Fixtures that put a test on a bus or a server: never in the fast tier.
_NOT_PURE = frozenset({"channel", "sim_bus", "rig", "app_client", "loopback_app"})


def _in(rel: str, paths: tuple[str, ...]) -> bool:
    return any(rel == p or rel.startswith(p.rstrip("/") + "/") for p in paths)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    root = Path(config.rootpath)
    for item in items:
        rel = Path(item.path).resolve().relative_to(root).as_posix()
        wallclock = item.get_closest_marker("wallclock") is not None
        if _in(rel, SIMTIME_DIRS) and not wallclock:
            item.add_marker(pytest.mark.simtime)
        if _in(rel, CHECK_PATHS) and not wallclock:
            # A bus or a server in the fast tier would make it slow and flaky on a busy
            # machine: refused when collected, naming the test and what to do.
            bus = _NOT_PURE.intersection(getattr(item, "fixturenames", ()))
            if bus:
                raise pytest.UsageError(
                    f"{item.nodeid} uses {', '.join(sorted(bus))}: not a pure test; move it out "
                    "of the paths in tests/conftest.py CHECK_PATHS or mark it wallclock"
                )
            item.add_marker(pytest.mark.check)
        if item.get_closest_marker("simtime") or item.get_closest_marker("check"):
            continue
        if wallclock or _in(rel, SERIAL_PATHS):
            item.add_marker(pytest.mark.serial)
        else:
            item.add_marker(pytest.mark.shared)
            # pytest-xdist --dist loadgroup: one file (or one directory above) per worker.
            one = next((g for path, g in _ONE_WORKER.items() if _in(rel, (path,))), rel)
            item.add_marker(pytest.mark.xdist_group(one))
