"""Motion of a drive session: jog, moves, velocity, torque, cyclic set-points, homing, dead-man.

Every motion is started by the holder of control (:mod:`servodesk.services.control`) and
lives while the heartbeats of its bound WebSocket arrive. The dead-man's watch runs on a
thread of its own (:mod:`servodesk.services.deadman`): once the last heartbeat is
``deadman_s`` old it puts a quick stop on the wire without the event loop where the link can
(``DriveLink.stop_frame``), and the loop then halts (controlword bit 8) and quick-stops the
axis through the link as before. Losing the holder (its socket closing, release, force take)
and shutting the backend down stop it the same way, and losing the holder also disables the
drive at standstill (:meth:`MotionService.make_safe`).

Before anything is sent, a request is checked against the family's modes (profile) and the
drive's own limits, read from the drive and cached per session (refreshed after any write
through the API): software position limits 607Dh, max profile velocity 607Fh, max torque 6072h,
max acceleration / deceleration 60C5h / 60C6h. A refused request names the limit and its
value and nothing reaches the bus. A limit object the drive refuses (SDO abort) is unknown
(None, with the reason in ``sources``); only a dead link fails the read.

Jog and profile velocity have no target to check: a command toward a software limit the axis
is at or beyond is refused, and while they run the monitor halts the axis once the distance it
needs to stop (sampling lead plus braking at the halt deceleration) reaches the limit.
Homing started through the API is a motion too (kind ``homing``), under the same dead-man.

Choices where CiA 402 leaves room (documented once):

- Motion needs Operation enabled: servo on is the user's explicit step (``POST /state`` with
  ``enable``, which walks the state machine with the family's controlword spacing).
- The mode (6060h) is set by the motion that needs it. Quirk ``mode_change_at_standstill``
  refuses a change while the axis moves; quirk ``mode_change_refused`` (states where 6060h is
  refused) is handled by disable operation -> 6060h -> enable operation at standstill.
- Profile position: bit 5 (change set immediately) comes from ``immediate``; a set-point that
  is not immediate joins the drive's set-point buffer (set of set-points) and is sent only when
  set-point acknowledge (statusword bit 12) is 0, since drives discard it otherwise
  (quirk ``pp_set_point_buffer``: HIWIN 000 §3.2.2, CTMM 003 §4-4-5).
- Cyclic modes (csp, csv, cst) need the family to list mode 8/9/10. Without PDOs the backend
  writes the set-point by SDO every ``cyclic_period`` seconds; the drive interpolates between
  them. Before csp starts, 607Ah is set to the actual position (HIWIN 000 quirk
  ``csp_align_target_before_enable``: otherwise the axis jumps). ``duration`` is rounded up to
  whole periods of the waveform so the set-point ends where it started. The waveform's time is
  counted in set-points: a stall of the backend stretches it (the drive holds the last
  set-point) rather than skipping part of it, which would step the set-point. The motion's
  message says how often and how long it stalled, while it runs and after it ends.
- Limits 607Dh min = max = 0 switch the position limits off (CiA 402-2 §6.5.4); 607Fh = 0 is
  read as "no extra limit", as the simulated drive does. Objects a family lists in the quirk
  ``objects_not_usable`` are not read.

The service is one class, :class:`MotionService`, made of one part per seam (since
2026-12-07, issue 51 item 3; before, one module, services/motion.py, held all of it in 1,823 lines):

- ``axis.py``: the axis and its motion as the service keeps them; the CiA 402 bits and modes.
- ``limits.py``: where each limit comes from, the checks before the bus, the guard that halts
  continuous motion before a software limit.
- ``base.py``: the service's state, the bus reads every part shares, how a motion ends
  (settings given back, listeners, audit), the status.
- ``stopping.py``: halt and quick stop.
- ``monitor.py``: the monitor of a running motion (move reached, homing's end, the drive
  leaving Operation enabled, the software limit ahead).
- ``lost_holder.py``: the dead-man glue: the dead-man's stop, making the drive safe when the
  holder is lost, the drive's own watchdog, closing a session, shutdown.
- ``start.py``: the one start template every motion follows.
- ``commands.py`` (jog, velocity, torque, move, home), ``cyclic.py`` (cyclic set-points),
  ``tuning_motion.py`` (the tuning's motion): the motions, each on the template.
- ``service.py``: :class:`MotionService`, the parts put together.
"""

from servodesk.domain.cia402 import (
    CW_ENABLE,
    CW_HALT,
    CW_IMMEDIATE,
    CW_NEW_SETPOINT,
    CW_RELATIVE,
    SW_SETPOINT_ACK,
    SW_TARGET_REACHED,
)
from servodesk.services.motion.axis import (
    CSP,
    CST,
    CSV,
    CYCLIC_MODES,
    DEFAULT_STANDSTILL,
    HM,
    HOMING_SETTLE_S,
    PP,
    PV,
    SAFE_STOP_S,
    TQ,
    Motion,
)
from servodesk.services.motion.limits import (
    FALLBACK_STOP_S,
    INT32_MAX,
    INT32_MIN,
    LIMIT_GUARD_PERIOD,
    LIMIT_OBJECTS,
    Limits,
)
from servodesk.services.motion.service import MotionService

__all__ = [
    "CSP",
    "CST",
    "CSV",
    "CW_ENABLE",
    "CW_HALT",
    "CW_IMMEDIATE",
    "CW_NEW_SETPOINT",
    "CW_RELATIVE",
    "CYCLIC_MODES",
    "DEFAULT_STANDSTILL",
    "FALLBACK_STOP_S",
    "HM",
    "HOMING_SETTLE_S",
    "INT32_MAX",
    "INT32_MIN",
    "LIMIT_GUARD_PERIOD",
    "LIMIT_OBJECTS",
    "PP",
    "PV",
    "SAFE_STOP_S",
    "SW_SETPOINT_ACK",
    "SW_TARGET_REACHED",
    "TQ",
    "Limits",
    "Motion",
    "MotionService",
]
