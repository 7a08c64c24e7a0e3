"""The 3D twin: one viser server that shows every session's axis as a moving stage.

Each axis is a rotary stage (a disc turning about its axis, scale in counts per revolution) or
a linear stage (a carriage on a rail, scale in counts per mm). The moving part follows the
actual position (6064h), a translucent ghost shows the target (the motion service's set-point
of a profile-position move, else 607Ah), the colour shows the CiA 402 state (disabled, enabled,
quick stop, fault), and the software position limits (607Dh) are drawn: posts on the rail of a
linear stage, red radial marks and the allowed arc on a rotary one.

viser runs its own websockets server in a thread with its own event loop (it is not an ASGI
app, so it cannot be mounted in FastAPI); it serves the client bundled in its wheel, so the
viewer needs no network. The scene is updated from the backend's event loop by a 36 Hz task
that reads each session's latest polled state; while the viewer has clients, every session is
asked to poll at least ``poll_hz`` (Session.min_poll_hz) so each frame has a fresh position.
The task runs at 36 Hz rather than 30 because a frame moves an axis only when a new position
arrived: at 30 Hz an axis saw 29.0-29.8 updates/s, at 36 Hz 33.6-33.8 (bench/bench_viewer.py),
so every axis moves 30 times a second or more as issue 4 asks.

viser's websocket server has no token check: when the backend is bound beyond loopback (where
every API request needs the token), the viewer is started only with ``public`` set
(SERVODESK_VIEWER_PUBLIC=1); otherwise ``error`` says why it is off.

Over 700 lines: one viser scene, its stages and the task that moves them share the scene's
handles and viser's thread; what is pure (the stage geometry, the colours of CiA 402 states) is
already in small classes at the top.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from servodesk import hosts
from servodesk.domain import cia402
from servodesk.domain.address import ObjectAddress
from servodesk.domain.cia402 import POSITION, SOFT_LIMIT_MAX, SOFT_LIMIT_MIN, TARGET_POSITION
from servodesk.domain.datatypes import DataType, codec
from servodesk.domain.profile import DeviceProfile
from servodesk.errors import ServodeskError, ValidationError
from servodesk.services.manager import SessionManager
from servodesk.services.session import Session

log = logging.getLogger(__name__)

StageKind = Literal["rotary", "linear"]

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1

#: Distance between two stages along x, in scene units (metres in the viewer).
SPACING = 2.0
#: The longest profile name a stage's label shows whole; longer ones end in an ellipsis. No
#: longer than the state's line ("Switch on disabled"): the label's width is the row's budget.
LABEL_NAME_CHARS = 16
#: Where a stage's label hangs, along y from the stage's centre (scene units): below the
#: stage (in front, nearer the camera) for the even slots, above it (behind) for the odd ones.
LABEL_OFFSET = 0.72
#: Half a label's width on screen (px), with its padding and a margin: at font_screen_scale
#: 0.8 "Switch on disabled" is about 90 px wide and "Not ready to switch on", the longest
#: line, about 105 px (measured in Chromium at 640 px).
LABEL_HALF_WIDTH_PX = 62.0
#: Radius of a rotary stage's disc and length of a linear stage's rail window.
DISC_RADIUS = 0.5
RAIL_LENGTH = 1.2
#: The travel a linear stage shows when the drive has no software limits (mm).
DEFAULT_TRAVEL_MM = 200.0
#: How often 607Ah and 607Dh are read again (s); they change only by writes.
TARGET_PERIOD = 0.2
LIMITS_PERIOD = 1.0

Rgb = tuple[int, int, int]
#: Colour of the moving part per CiA 402 state (disabled grey, enabled green, fault red).
DISABLED: Rgb = (140, 140, 150)
ENABLED: Rgb = (40, 170, 90)
QUICK_STOP: Rgb = (235, 160, 20)
FAULT: Rgb = (215, 45, 45)
OFFLINE: Rgb = (70, 70, 75)
GHOST: Rgb = (90, 140, 255)
LIMIT: Rgb = (215, 45, 45)
FRAME: Rgb = (60, 64, 72)
SCALE: Rgb = (225, 225, 230)


def state_colour(state: str | None, connected: bool = True) -> Rgb:
    """The colour of a stage's moving part for a CiA 402 state (State.value)."""
    if not connected or state is None:
        return OFFLINE
    if state in (cia402.State.FAULT.value, cia402.State.FAULT_REACTION_ACTIVE.value):
        return FAULT
    if state == cia402.State.OPERATION_ENABLED.value:
        return ENABLED
    if state == cia402.State.QUICK_STOP_ACTIVE.value:
        return QUICK_STOP
    if state == cia402.State.UNKNOWN.value:
        return OFFLINE
    return DISABLED


@dataclass(frozen=True, slots=True)
class AxisChoice:
    """How one axis is drawn: the stage kind and its scale (counts per rev or per mm)."""

    kind: StageKind
    scale: float
    #: "user" (PUT /viewer/axes), "profile" (6064h in mm) or "default" (rotary motor).
    source: str

    @property
    def scale_unit(self) -> str:
        return "counts/rev" if self.kind == "rotary" else "counts/mm"


def default_axis(profile: DeviceProfile) -> AxisChoice:
    """The stage a profile suggests: linear when 6064h is in mm or µm, else a rotary motor."""
    spec = profile.spec(POSITION)
    if spec is not None and spec.unit and spec.scale:
        unit = spec.unit.strip().lower()
        # The scale converts counts to the unit, so counts per mm is its inverse.
        if unit == "mm":
            return AxisChoice("linear", 1.0 / spec.scale, "profile")
        if unit in ("um", "µm", "μm"):
            return AxisChoice("linear", 1000.0 / spec.scale, "profile")
    return AxisChoice("rotary", float(profile.simulation.counts_per_rev), "default")


def rotation_z(angle: float) -> tuple[float, float, float, float]:
    """The quaternion (w, x, y, z) of a rotation by ``angle`` radians about +z."""
    return (math.cos(angle / 2.0), 0.0, 0.0, math.sin(angle / 2.0))


@dataclass(eq=False)
class Stage:
    """The scene nodes of one axis and what they show now."""

    session: Session
    choice: AxisChoice
    slot: int
    #: Software limits (607Dh) in counts, None when off or unreadable.
    limits: tuple[int, int] | None
    root: Any
    moving: Any
    ghost: Any
    body: Any
    label: Any
    nodes: list[Any] = field(default_factory=list)
    #: The linear stage's window: the mm at the rail's centre and mm per scene unit.
    centre_mm: float = 0.0
    mm_per_unit: float = 1.0
    position: int | None = None
    target: float | None = None
    ghost_shown: float | None = None
    colour: Rgb | None = None
    label_text: str = ""
    label_at: float = 0.0

    @property
    def sid(self) -> str:
        return self.session.id

    def place(self, counts: float) -> tuple[tuple[float, float, float, float], np.ndarray]:
        """The (wxyz, position) of the moving part for a position in counts."""
        if self.choice.kind == "rotary":
            return rotation_z(2.0 * math.pi * counts / self.choice.scale), np.zeros(3)
        x = (counts / self.choice.scale - self.centre_mm) / self.mm_per_unit
        return (1.0, 0.0, 0.0, 0.0), np.array([x, 0.0, 0.0])

    def show(self, handle: Any, counts: float) -> None:
        wxyz, pos = self.place(counts)
        if self.choice.kind == "rotary":
            handle.wxyz = wxyz
        else:
            handle.position = pos

    def remove(self) -> None:
        for node in reversed(self.nodes):
            with contextlib.suppress(Exception):
                node.remove()
        self.nodes.clear()


class ViewerService:
    """One viser server owned by the backend, and the 36 Hz task that moves its stages."""

    def __init__(
        self,
        manager: SessionManager,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        rate_hz: float = 36.0,
        poll_hz: float = 45.0,
        target_of: Callable[[str], float | None] | None = None,
        public: bool = False,
    ) -> None:
        self.manager = manager
        self.host = host
        self.requested_port = port
        #: SERVODESK_VIEWER_PUBLIC: serve the viewer beyond loopback although its port has no
        #: token check.
        self.public = public
        self.rate_hz = rate_hz
        #: Poll rate asked of the sessions while clients watch: above ``rate_hz`` so that
        #: nearly every frame has a new sample (a poll also spends time on its reads).
        self.poll_hz = poll_hz
        #: The motion service's position set-point of a session, when it has one.
        self.target_of = target_of
        self.server: Any = None
        self._choices: dict[str, AxisChoice] = {}
        self._stages: dict[str, Stage] = {}
        self._tasks: list[asyncio.Task[None]] = []
        self._rebuild: set[str] = set()
        #: The software limits last read from each drive (None: off).
        self._limits: dict[str, tuple[int, int] | None] = {}
        self._frames = 0
        self._static: list[Any] = []
        #: The number of stages the initial camera was placed for.
        self._framed = -1
        #: Why the viewer is not running although enabled (None: it runs or is disabled).
        self.error: str | None = None

    # Lifecycle ----------------------------------------------------------------------------

    @property
    def enabled(self) -> bool:
        return self.requested_port != 0

    @property
    def running(self) -> bool:
        return self.server is not None

    @property
    def port(self) -> int | None:
        """The port actually bound (viser takes the next free one when it is taken)."""
        return int(self.server.get_port()) if self.server is not None else None

    @property
    def url(self) -> str | None:
        port = self.port
        if port is None:
            return None
        host = self.host
        if host in ("0.0.0.0", "::", ""):
            host = "127.0.0.1"  # Bound to every address: this machine's own is one of them.
        if ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{port}/"

    @property
    def clients(self) -> int:
        return len(self.server.get_clients()) if self.server is not None else 0

    @property
    def frames(self) -> int:
        """Scene updates sent so far (ticks in which something moved or changed)."""
        return self._frames

    @property
    def exposed(self) -> bool:
        """True when the viewer would be reachable from other machines (host beyond loopback)."""
        return not is_loopback(self.host)

    async def start(self) -> None:
        """Bind the viser server and start the update loop (nothing when the port is 0).

        viser's websocket server has no token check, so beyond loopback (where the API needs
        the token) it is not started unless ``public`` is set.
        """
        if not self.enabled or self.server is not None:
            return
        if self.exposed and not self.public:
            self.error = (
                f"the backend is bound to {self.host}, beyond loopback, and the viewer's port "
                f"{self.requested_port} has no token check, so anyone reaching it would see the "
                "axes; set SERVODESK_VIEWER_PUBLIC=1 to serve it anyway, or bind the backend to "
                "127.0.0.1"
            )
            log.warning("the 3D viewer is not started: %s", self.error)
            return
        try:
            self.server = await asyncio.to_thread(_make_server, self.host, self.requested_port)
        except (ServodeskError, OSError) as exc:
            # The backend runs on without its 3D view; GET /viewer says why.
            self.error = str(exc)
            log.error("the 3D viewer did not start: %s", exc)
            return
        self.error = None
        if self.port != self.requested_port:
            log.warning(
                "viewer port %d is taken; the 3D viewer uses port %s",
                self.requested_port,
                self.port,
            )
        log.info("3D viewer at %s", self.url)
        if self.exposed:
            log.warning(
                "the 3D viewer on port %s is served beyond loopback without a token check "
                "(SERVODESK_VIEWER_PUBLIC=1): anyone who reaches %s:%s sees the axes",
                self.port,
                self.host,
                self.port,
            )
        self._add_static()
        self.server.on_client_connect(self._fit_client)
        self._tasks = [
            asyncio.create_task(self._frame_loop(), name="viewer frames"),
            asyncio.create_task(self._refresh_loop(), name="viewer targets and limits"),
        ]

    async def stop(self) -> None:
        """Stop the update loop and the viser server; its port is free afterwards."""
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks = []
        for s in self.manager.all():
            s.min_poll_hz = 0.0
        server, self.server = self.server, None
        self._stages.clear()
        self._static.clear()
        if server is not None:
            await asyncio.to_thread(server.stop)

    # Axis choices -------------------------------------------------------------------------

    def choice(self, session: Session) -> AxisChoice:
        return self._choices.get(session.id) or default_axis(session.profile)

    def set_axis(self, sid: str, kind: str, scale: float | None = None) -> AxisChoice:
        """Draw session ``sid`` as a ``kind`` stage with ``scale`` counts per rev or mm."""
        session = self.manager.get(sid)
        if kind not in ("rotary", "linear"):
            raise ValidationError(
                f"unknown stage kind {kind!r}", field="kind", hint="use rotary or linear"
            )
        if scale is None:
            current = self.choice(session)
            if current.kind == kind:
                scale = current.scale
            elif kind == "rotary":
                scale = float(session.profile.simulation.counts_per_rev)
            else:
                raise ValidationError(
                    "a linear stage needs its scale in counts per mm",
                    field="scale",
                    hint='send e.g. {"kind": "linear", "scale": 1000}',
                )
        if not (scale > 0 and math.isfinite(scale)):
            raise ValidationError(
                f"scale {scale:g} is not a positive number of counts",
                field="scale",
                hint="counts per revolution (rotary) or per mm (linear), above 0",
            )
        choice = AxisChoice("rotary" if kind == "rotary" else "linear", float(scale), "user")
        self._choices[sid] = choice
        self._rebuild.add(sid)
        return choice

    def axes(self) -> list[dict[str, Any]]:
        out = []
        for s in self.manager.all():
            c = self.choice(s)
            stage = self._stages.get(s.id)
            out.append(
                {
                    "session": s.id,
                    "kind": c.kind,
                    "scale": c.scale,
                    "scale_unit": c.scale_unit,
                    "source": c.source,
                    "limits": list(stage.limits) if stage and stage.limits else None,
                }
            )
        return out

    def stage(self, sid: str) -> Stage | None:
        """The scene nodes of a session's axis (None before the first frame shows it)."""
        return self._stages.get(sid)

    def info(self) -> dict[str, Any]:
        return {
            "enabled": self.enabled,
            "running": self.running,
            "url": self.url,
            "port": self.port,
            "clients": self.clients,
            "rate_hz": self.rate_hz,
            "error": self.error,
            "axes": self.axes(),
        }

    # Frames -------------------------------------------------------------------------------

    async def _frame_loop(self) -> None:
        period = 1.0 / self.rate_hz
        next_at = time.monotonic()
        while True:
            try:
                self.frame()
            except Exception:  # A scene error must not end the viewer.
                log.exception("viewer frame")
            next_at += period
            now = time.monotonic()
            if next_at < now - period:
                next_at = now  # Late by more than a frame (a busy loop): do not catch up.
            await asyncio.sleep(max(0.0, next_at - now))

    def frame(self) -> None:
        """One frame: add and remove stages, then move each to its session's latest state."""
        sessions = {s.id: s for s in self.manager.all()}
        targets: dict[str, float | None] = {}
        for sid, stage in list(self._stages.items()):
            if sessions.get(sid) is not stage.session or sid in self._rebuild:
                stage.remove()
                del self._stages[sid]
                if sid in sessions:
                    targets[sid] = stage.target
        self._rebuild.clear()
        if len(sessions) != self._framed:
            self._frame_camera(len(sessions))
        floor = self.poll_hz if self.clients else 0.0
        changed = False
        with self.server.atomic():
            for slot, (sid, session) in enumerate(sessions.items()):
                session.min_poll_hz = floor
                old = self._stages.get(sid)
                if old is None or old.slot != slot:
                    if old is not None:
                        old.remove()
                    stage = self._build(session, slot, self._limits.get(sid))
                    stage.target = old.target if old else targets.get(sid)
                    self._stages[sid] = stage
                    changed = True
                else:
                    stage = old
                changed |= self._update(stage)
        if changed:
            self._frames += 1

    def _update(self, stage: Stage) -> bool:
        session = stage.session
        st = session.last_state
        changed = False
        colour = state_colour(st.state if st else None, session.connected)
        if colour != stage.colour:
            stage.body.color = colour
            stage.colour = colour
            changed = True
        if st is not None and st.position is not None and st.position != stage.position:
            stage.show(stage.moving, st.position)
            stage.position = st.position
            changed = True
        target = self.target_of(session.id) if self.target_of is not None else None
        if target is None:
            target = stage.target
        if target is not None:
            if stage.ghost.visible is False:
                stage.ghost.visible = True
            if target != stage.ghost_shown:
                stage.show(stage.ghost, target)
                stage.ghost_shown = target
                changed = True
        now = time.monotonic()
        if now - stage.label_at > 0.2:
            # The readout changes every frame while moving: 5 Hz is enough to read it.
            text = self._label_text(stage)
            if text != stage.label_text:
                stage.label.text = text
                stage.label_text = text
            stage.label_at = now
        return changed

    def _frame_camera(self, n: int) -> None:
        """Point the camera new clients start with at the row of ``n`` stages."""
        look_at, position = row_camera(n)
        self.server.initial_camera.look_at = look_at
        self.server.initial_camera.position = position
        self._framed = n

    def _fit_client(self, client: Any) -> None:
        """Keep a new client's camera stepped back far enough to show the whole row.

        The initial camera is framed for a laptop screen; a narrower canvas (the operation
        page's compact view, a browser beside the drive's manual) saw the row's ends cut off,
        the first axis among them. viser calls this once per client, after its first camera
        message. The client reports its canvas again whenever it is resized (the docked
        panel takes its width just after the first message): each report refits the camera,
        until the user orbits or zooms it, which is left alone from then on.
        """
        camera = client.camera
        placed = np.asarray(camera.position, dtype=float)

        def refit(_: Any) -> None:
            nonlocal placed
            if not np.allclose(camera.position, placed, atol=1e-3):
                return  # The user has taken the camera.
            if camera.image_height <= 0 or camera.image_width <= 0:
                return  # A hidden frame (a folded panel, a tab in the background): no canvas.
            aspect = camera.image_width / camera.image_height
            look_at, position = row_camera(
                max(self._framed, 0), aspect, camera.fov, float(camera.image_width)
            )
            if np.allclose(position, placed, atol=1e-3):
                return
            placed = np.asarray(position, dtype=float)
            with client.atomic():
                camera.look_at = look_at
                camera.position = position

        refit(camera)
        camera.on_update(refit)

    def _label_text(self, stage: Stage) -> str:
        s = stage.session
        st = s.last_state
        # Short enough for the label to stay within its stage's slot (LABEL_NAME_CHARS).
        n = LABEL_NAME_CHARS
        name = s.profile.name if len(s.profile.name) <= n else s.profile.name[: n - 1] + "…"
        lines = [s.id, name, f"node {s.link.params.node_id}"]
        if st is not None:
            lines.append(st.state if s.connected else "link lost")
            if st.position is not None:
                if stage.choice.kind == "rotary":
                    lines.append(f"{st.position / stage.choice.scale:+.3f} rev")
                else:
                    lines.append(f"{st.position / stage.choice.scale:+.2f} mm")
        return "\n".join(lines)

    # Scene building -----------------------------------------------------------------------

    def _add_static(self) -> None:
        scene = self.server.scene
        self._static.append(
            scene.add_grid(
                "/floor",
                width=20.0,
                height=6.0,
                cell_size=0.2,
                section_size=1.0,
                position=(0.0, 0.0, -0.06),
            )
        )

    def _build(self, session: Session, slot: int, limits: tuple[int, int] | None) -> Stage:
        scene = self.server.scene
        choice = self.choice(session)
        base = f"/axes/{_node_name(session.id)}"
        root = scene.add_frame(base, show_axes=False, position=(slot * SPACING, 0.0, 0.0))
        nodes: list[Any] = [root]
        colour = state_colour(None)
        if choice.kind == "rotary":
            nodes.append(
                scene.add_cylinder(
                    f"{base}/housing",
                    radius=DISC_RADIUS + 0.06,
                    height=0.08,
                    color=FRAME,
                    position=(0.0, 0.0, -0.05),
                )
            )
            moving = scene.add_frame(f"{base}/rotor", show_axes=False)
            body = scene.add_cylinder(
                f"{base}/rotor/disc", radius=DISC_RADIUS, height=0.04, color=colour
            )
            pointer = scene.add_box(
                f"{base}/rotor/pointer",
                color=(250, 250, 250),
                dimensions=(DISC_RADIUS * 0.9, 0.05, 0.03),
                position=(DISC_RADIUS * 0.45, 0.0, 0.03),
            )
            ghost = scene.add_frame(f"{base}/ghost", show_axes=False, visible=False)
            ghost_body = scene.add_box(
                f"{base}/ghost/pointer",
                color=GHOST,
                dimensions=(DISC_RADIUS * 1.05, 0.05, 0.02),
                position=(DISC_RADIUS * 0.525, 0.0, 0.06),
                opacity=0.45,
            )
            nodes += [moving, body, pointer, ghost, ghost_body]
            nodes.append(self._rotary_scale(base, choice))
            if limits is not None:
                nodes += self._rotary_limits(base, choice, limits)
            stage = Stage(session, choice, slot, limits, root, moving, ghost, body, None, nodes)
        else:
            if limits is not None:
                lo, hi = limits[0] / choice.scale, limits[1] / choice.scale
                span = max(hi - lo, 1e-6) * 1.2
                centre = (lo + hi) / 2.0
            else:
                span, centre = DEFAULT_TRAVEL_MM, 0.0
            mm_per_unit = span / RAIL_LENGTH
            nodes.append(
                scene.add_box(
                    f"{base}/rail",
                    color=FRAME,
                    dimensions=(RAIL_LENGTH + 0.1, 0.12, 0.04),
                    position=(0.0, 0.0, -0.04),
                )
            )
            moving = scene.add_frame(f"{base}/carriage", show_axes=False)
            body = scene.add_box(
                f"{base}/carriage/body",
                color=colour,
                dimensions=(0.12, 0.2, 0.08),
                position=(0.0, 0.0, 0.02),
            )
            ghost = scene.add_frame(f"{base}/ghost", show_axes=False, visible=False)
            ghost_body = scene.add_box(
                f"{base}/ghost/body",
                color=GHOST,
                dimensions=(0.13, 0.21, 0.09),
                position=(0.0, 0.0, 0.02),
                opacity=0.35,
            )
            nodes += [moving, body, ghost, ghost_body]
            stage = Stage(session, choice, slot, limits, root, moving, ghost, body, None, nodes)
            stage.centre_mm, stage.mm_per_unit = centre, mm_per_unit
            nodes.append(self._linear_scale(base, stage, span))
            if limits is not None:
                for i, lim in enumerate(limits):
                    _, pos = stage.place(lim)
                    nodes.append(
                        scene.add_box(
                            f"{base}/limit_{'min' if i == 0 else 'max'}",
                            color=LIMIT,
                            dimensions=(0.02, 0.3, 0.2),
                            position=(pos[0], 0.0, 0.08),
                        )
                    )
        # The labels keep their size on screen (screen-space font) while the row shrinks with
        # the canvas: side by side, five of them overlapped on a 640 px browser (about 70 px
        # between stages, a label was about 110 px wide). So they alternate: an even slot's
        # label hangs down from in front of its stage, an odd slot's stands up from behind it.
        # Either row grows away from the other, whatever the zoom, and a label's neighbours
        # in its row are two stages away (about 130 px at 640 px).
        below = slot % 2 == 0
        stage.label = scene.add_label(
            f"{base}/label",
            "",
            position=(0.0, -LABEL_OFFSET if below else LABEL_OFFSET, 0.0),
            anchor="top-center" if below else "bottom-center",
            font_screen_scale=0.8,
        )
        nodes.append(stage.label)
        return stage

    def _rotary_scale(self, base: str, choice: AxisChoice) -> Any:
        """Tick marks every 1/8 revolution (a long one at zero) around the disc."""
        segs = []
        for i in range(8):
            a = 2.0 * math.pi * i / 8
            r0 = DISC_RADIUS + (0.0 if i == 0 else 0.02)
            r1 = DISC_RADIUS + 0.1
            segs.append(
                [
                    [r0 * math.cos(a), r0 * math.sin(a), 0.0],
                    [r1 * math.cos(a), r1 * math.sin(a), 0.0],
                ]
            )
        return self.server.scene.add_line_segments(
            f"{base}/scale",
            points=np.array(segs, dtype=np.float32),
            colors=SCALE,
            thickness=0.012,
        )

    def _rotary_limits(self, base: str, choice: AxisChoice, limits: tuple[int, int]) -> list[Any]:
        """Red radial marks at 607Dh min and max, and the allowed arc between them."""
        lo, hi = (2.0 * math.pi * v / choice.scale for v in limits)
        r = DISC_RADIUS + 0.14
        marks = [[[0.0, 0.0, 0.02], [r * math.cos(a), r * math.sin(a), 0.02]] for a in (lo, hi)]
        # Over one revolution or more the limits are not a mark on the disc: draw the circle.
        sweep = min(hi - lo, 2.0 * math.pi)
        n = max(2, int(64 * sweep / (2.0 * math.pi)))
        arc = []
        for i in range(n):
            a0 = lo + sweep * i / n
            a1 = lo + sweep * (i + 1) / n
            arc.append(
                [
                    [r * math.cos(a0), r * math.sin(a0), 0.0],
                    [r * math.cos(a1), r * math.sin(a1), 0.0],
                ]
            )
        scene = self.server.scene
        return [
            scene.add_line_segments(
                f"{base}/limit_marks",
                points=np.array(marks, dtype=np.float32),
                colors=LIMIT,
                thickness=0.02,
            ),
            scene.add_line_segments(
                f"{base}/limit_arc",
                points=np.array(arc, dtype=np.float32),
                colors=LIMIT,
                thickness=0.012,
            ),
        ]

    def _linear_scale(self, base: str, stage: Stage, span_mm: float) -> Any:
        """Ticks along the rail at a round step in mm (about ten of them)."""
        step = _nice_step(span_mm / 10.0)
        lo = stage.centre_mm - span_mm / 2.0
        first = math.ceil(lo / step) * step
        segs = []
        mm = first
        while mm <= stage.centre_mm + span_mm / 2.0:
            _, pos = stage.place(mm * stage.choice.scale)
            long = abs(mm) < step / 2
            segs.append([[pos[0], -0.08, 0.0], [pos[0], -0.16 if long else -0.12, 0.0]])
            mm += step
        return self.server.scene.add_line_segments(
            f"{base}/scale",
            points=np.array(segs, dtype=np.float32),
            colors=SCALE,
            thickness=0.008,
        )

    # Targets and limits (read from the drive) ----------------------------------------------

    async def _refresh_loop(self) -> None:
        limits_at = 0.0
        while True:
            read_limits = time.monotonic() - limits_at >= LIMITS_PERIOD
            if read_limits:
                limits_at = time.monotonic()
            for stage in list(self._stages.values()):
                try:
                    await self._refresh(stage, read_limits)
                except asyncio.CancelledError:
                    raise
                except Exception:
                    log.debug("viewer refresh of %s", stage.sid, exc_info=True)
            await asyncio.sleep(TARGET_PERIOD)

    async def _refresh(self, stage: Stage, read_limits: bool) -> None:
        session = stage.session
        if not session.connected:
            return
        if self.target_of is None or self.target_of(session.id) is None:
            stage.target = await _read_int(session, TARGET_POSITION)
        if read_limits:
            lo = await _read_int(session, SOFT_LIMIT_MIN)
            hi = await _read_int(session, SOFT_LIMIT_MAX)
            # CiA 402-2 §6.5.4: min = max = 0 switches the software limits off; the whole
            # INTEGER32 range (the generic default) limits nothing either.
            limits = None
            if lo is not None and hi is not None and (lo, hi) != (0, 0):
                limits = None if lo <= INT32_MIN and hi >= INT32_MAX else (lo, hi)
            self._limits[stage.sid] = limits
            if limits != stage.limits and self._stages.get(stage.sid) is stage:
                self._rebuild.add(stage.sid)  # Drawn again by the next frame.


async def _read_int(session: Session, address: ObjectAddress) -> int | None:
    """An integer object of the drive, None when the family lacks it or it cannot be read."""
    profile = session.profile
    spec = profile.spec(address)
    if spec is None and profile.variables:
        return None
    if spec is not None and not spec.access.readable:
        return None
    unusable = {str(a).upper() for a in profile.quirk("objects_not_usable", []) or []}
    if f"0X{address.index:04X}" in unusable or str(address).upper() in unusable:
        return None
    try:
        raw = await session.link.read(address)
    except ServodeskError:
        return None
    v = codec(spec.data_type if spec else DataType.INTEGER32).decode(raw)
    return int(v) if isinstance(v, int | bool) else None


def _nice_step(raw: float) -> float:
    """1, 2 or 5 times a power of ten, at least ``raw``."""
    if raw <= 0:
        return 1.0
    p = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * p >= raw:
            return m * p
    return 10.0 * p


def is_loopback(host: str) -> bool:
    """The same rule as Settings.is_loopback: the addresses only this machine reaches."""
    return hosts.is_loopback(host)


def _node_name(sid: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in sid)


def row_camera(
    n: int, aspect: float | None = None, fov: float | None = None, width_px: float | None = None
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The camera's (look_at, position) that shows a row of ``n`` stages from the front, above.

    Without ``aspect`` (canvas width / height) and ``fov`` (vertical field of view, radians):
    the framing for a laptop screen, where a row of five fills the view (at 0.62 x the row's
    width the five twins' labels overlapped on a 1280 px screen, about 100 px between stages).
    With them, the camera steps back further when that canvas is too narrow to show the
    whole row, never closer. With the canvas's width in pixels too (``width_px``), far enough
    that the outer stages' labels, whose size is fixed on screen, are whole on it.
    """
    span = max(n - 1, 0) * SPACING
    width = span + 2.0 * DISC_RADIUS + 0.6
    cx = span / 2.0
    d = max(2.0, 0.48 * width)
    if aspect is not None and fov is not None and aspect > 0.0 and 0.0 < fov < math.pi:
        # The camera looks along (0, 1, -0.8) at the row's middle, from sqrt(1 + 0.8^2) * d:
        # the row (along x, across the view) fits when its half width (and a 10 % margin)
        # is within the horizontal half angle, tan = aspect * tan(fov / 2).
        half_angle = aspect * math.tan(fov / 2.0)
        d = max(d, 1.1 * (width / 2.0) / (half_angle * math.sqrt(1.64)))
        if width_px is not None and width_px > 4.0 * LABEL_HALF_WIDTH_PX:
            # An outer stage's centre lands at x / (distance * half_angle) of the half canvas;
            # half a label must fit beside it. (A canvas narrower than two labels cannot
            # show the end labels whole at any distance: the row's framing stands.)
            inner = 1.0 - 2.0 * LABEL_HALF_WIDTH_PX / width_px
            d = max(d, (span / 2.0) / (half_angle * math.sqrt(1.64) * inner))
    return (cx, 0.0, 0.0), (cx, -d, 0.8 * d)


def _make_server(host: str, port: int) -> Any:
    """A viser server serving its bundled client, never building or downloading one."""
    import viser
    from viser import _client_autobuild

    index = _client_autobuild.build_dir / "index.html"
    if not index.is_file():
        raise ServodeskError(
            f"the viser package has no built client ({index})",
            hint="reinstall viser from its wheel, or set SERVODESK_VIEWER_PORT=0",
        )
    # viser rebuilds its client with Node when the sources look newer than the build (an
    # editable install); the bundled build is what we serve, so that check is skipped, as
    # viser's own tests do.
    saved = _client_autobuild.ensure_client_is_built
    _client_autobuild.ensure_client_is_built = lambda: None
    try:
        server = viser.ViserServer(host=host, port=port, label="servodesk", verbose=False)
    finally:
        _client_autobuild.ensure_client_is_built = saved
    # No share button: viser's share link tunnels the view through a public relay, and the
    # axes of a machine must not leave its network from a click. The control panel is small
    # and docked to the right (the user can fold it), so that it does not float over the row
    # of stages on a laptop screen.
    server.gui.configure_theme(
        control_width="small", show_share_button=False, show_logo=False, brand_color=GHOST
    )
    server.gui.main_panel.dock_right()
    # The panel shows what the colours mean. A panel with content of the server's own is also
    # what keeps viser's developer controls ("Dev Settings", "Save Canvas") folded behind its
    # settings button: with none, viser shows them as the panel's content (issue 48).
    server.gui.add_markdown(LEGEND)
    return server


#: The control panel's text: what the scene's colours and marks mean (state_colour).
LEGEND = """**servodesk 3D view**: one stage per open drive, moving with its actual
position (6064h).

- grey: not enabled (switch on disabled, ready, switched on)
- green: operation enabled
- amber: quick stop active
- red: fault; red marks: the software position limits (607Dh)
- dark: no link to the drive
- blue ghost: the target (the move's set-point, else 607Ah)
"""
