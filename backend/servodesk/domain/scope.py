"""The pure core of the live scope: trigger settings, sample rings, the trigger engine, statistics
and math channels.

The contract is docs/scope.md (issue 7). Nothing here does I/O or reads a clock: the scope service
feeds samples with their backend times (``time.time()`` seconds, see "Model" in docs/scope.md) and
asks :class:`TriggerEngine` whether a captured window is complete; :class:`Ring` keeps the recent
samples of one channel so that the window can be cut out of it afterwards.

Trigger kinds (docs/scope.md "Model"):

- ``level``: fires on the first sample that crosses ``level`` in the slope's direction, i.e. the
  previous sample lies strictly on the other side and this one is at or past the level (a sample
  exactly at the level counts as crossed). The trigger time is that sample's time.
- ``edge``: fires on a step between two consecutive samples larger than ``abs(level)`` in the
  slope's direction (``level`` 0: any change). Meant for digital inputs and status words, where a
  threshold between two states is awkward to choose; an oscilloscope's "edge" trigger is ``level``
  here.
- ``state`` / ``fault``: the service decides that the CiA 402 state changed or entered Fault (or an
  EMCY arrived) and calls :meth:`TriggerEngine.event` with the time it happened.

Re-arming (``normal`` mode) happens by time, not by call order: after a trigger at ``T`` the next
trigger can only come from a sample after the end of that window and at least ``holdoff_s`` after
``T``. So a chunk of samples that spans several windows yields every capture, in order.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from servodesk.errors import ValidationError

FloatArray = npt.NDArray[np.float64]

MODES = ("roll", "single", "normal")
KINDS = ("level", "edge", "state", "fault")
SLOPES = ("rising", "falling", "either")
#: Channels per scope (docs/scope.md "Model"): 4 drives x 8, issue 50's browser target (a 10 s
#: window of 32 channels at 4 kHz drawn at >= 30 fps). 8 per drive is Startdrive's trace and
#: every recorder profile's (profile_tuning.RecorderSpec.max_channels); a drive's recorder
#: keeps its own limit (services/scope.py refuses recorder channels beyond it). The one
#: source: services/scope_channels.py, the API's bounds and the UI's ChannelTable.tsx follow.
MAX_CHANNELS = 32
MATH_OPS = ("diff", "sum", "deriv")

EngineState = Literal["idle", "armed", "triggered", "done"]


@dataclass(frozen=True)
class Trigger:
    """Trigger settings (docs/scope.md "Model"); invalid values raise :class:`ValidationError`."""

    mode: str
    kind: str = "level"
    channel: int = 0
    level: float = 0.0
    slope: str = "rising"
    pre: float = 0.2
    window_s: float = 1.0
    holdoff_s: float = 0.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValidationError(
                f"trigger mode {self.mode!r} is unknown; use one of {', '.join(MODES)}",
                field="mode",
            )
        if self.kind not in KINDS:
            raise ValidationError(
                f"trigger kind {self.kind!r} is unknown; use one of {', '.join(KINDS)}",
                field="kind",
            )
        if self.slope not in SLOPES:
            raise ValidationError(
                f"trigger slope {self.slope!r} is unknown; use one of {', '.join(SLOPES)}",
                field="slope",
            )
        if isinstance(self.channel, bool) or not isinstance(self.channel, int):
            raise ValidationError(
                f"trigger channel must be an integer 0..{MAX_CHANNELS - 1}, not {self.channel!r}",
                field="channel",
            )
        if not 0 <= self.channel < MAX_CHANNELS:
            raise ValidationError(
                f"trigger channel {self.channel} is out of range; use 0..{MAX_CHANNELS - 1}",
                field="channel",
            )
        if not math.isfinite(self.level):
            raise ValidationError("trigger level must be a finite number", field="level")
        if not 0.0 <= self.pre <= 1.0:
            raise ValidationError(
                f"pre-trigger fraction {self.pre} is outside 0..1 (0.2 = 20 % before the trigger)",
                field="pre",
            )
        if not (math.isfinite(self.window_s) and self.window_s > 0.0):
            raise ValidationError(
                f"window_s must be a positive number of seconds, not {self.window_s}",
                field="window_s",
            )
        if not (math.isfinite(self.holdoff_s) and self.holdoff_s >= 0.0):
            raise ValidationError(
                f"holdoff_s must be zero or a positive number of seconds, not {self.holdoff_s}",
                field="holdoff_s",
            )

    @property
    def pre_s(self) -> float:
        """Seconds of the window before the trigger sample."""
        return self.pre * self.window_s

    @property
    def post_s(self) -> float:
        """Seconds of the window after the trigger sample."""
        return self.window_s - self.pre_s


def _as_samples(t: object, v: object) -> tuple[FloatArray, FloatArray]:
    ta = np.asarray(t, dtype=np.float64).reshape(-1)
    va = np.asarray(v, dtype=np.float64).reshape(-1)
    if ta.shape != va.shape:
        raise ValidationError(
            f"times and values differ in length ({ta.size} times, {va.size} values); "
            "pass one time per value"
        )
    return ta, va


class Ring:
    """The most recent ``capacity`` samples of one channel (float64 times and values).

    Times must not decrease (samples are fed in the order they were taken). The buffer is twice
    the capacity and is compacted when its end is reached, so :meth:`extend` costs O(1) per sample
    amortised and the stored samples stay contiguous for :func:`numpy.searchsorted`.
    """

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValidationError(f"ring capacity must be at least 1 sample, not {capacity}")
        self.capacity = int(capacity)
        self._t: FloatArray = np.empty(2 * self.capacity, dtype=np.float64)
        self._v: FloatArray = np.empty(2 * self.capacity, dtype=np.float64)
        self._start = 0
        self._end = 0

    def __len__(self) -> int:
        return self._end - self._start

    @property
    def first_time(self) -> float | None:
        """Time of the oldest stored sample, None when empty."""
        return float(self._t[self._start]) if self._end > self._start else None

    @property
    def last_time(self) -> float | None:
        """Time of the newest stored sample, None when empty."""
        return float(self._t[self._end - 1]) if self._end > self._start else None

    def clear(self) -> None:
        self._start = self._end = 0

    def extend(self, t: npt.ArrayLike, v: npt.ArrayLike) -> None:
        """Append samples; the oldest ones fall out beyond the capacity."""
        ta, va = _as_samples(t, v)
        n = ta.size
        if n == 0:
            return
        if n > 1 and bool((ta[1:] < ta[:-1]).any()):
            raise ValidationError("sample times go backwards inside one block; feed them in order")
        last = self.last_time
        if last is not None and ta[0] < last:
            raise ValidationError(
                f"sample time {ta[0]!r} is before the last stored sample {last!r}; "
                "feed samples in time order"
            )
        cap = self.capacity
        if n >= cap:
            self._t[:cap] = ta[-cap:]
            self._v[:cap] = va[-cap:]
            self._start, self._end = 0, cap
            return
        if self._end + n > 2 * cap:
            # Compact: move the newest samples that survive this extend to the front. This happens
            # at most once per `cap` appended samples, hence O(1) amortised per sample.
            keep = min(self._end - self._start, cap - n)
            self._t[:keep] = self._t[self._end - keep : self._end]
            self._v[:keep] = self._v[self._end - keep : self._end]
            self._start, self._end = 0, keep
        self._t[self._end : self._end + n] = ta
        self._v[self._end : self._end + n] = va
        self._end += n
        if self._end - self._start > cap:
            self._start = self._end - cap

    def window(self, t0: float, t1: float) -> tuple[FloatArray, FloatArray]:
        """Copies of the samples with ``t0 <= t <= t1``."""
        ts = self._t[self._start : self._end]
        i0 = int(np.searchsorted(ts, t0, side="left"))
        i1 = int(np.searchsorted(ts, t1, side="right"))
        i1 = max(i0, i1)
        return (
            self._t[self._start + i0 : self._start + i1].copy(),
            self._v[self._start + i0 : self._start + i1].copy(),
        )

    def since(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Copies of the samples strictly after ``t`` (what a stream has not sent yet)."""
        ts = self._t[self._start : self._end]
        i0 = self._start + int(np.searchsorted(ts, t, side="right"))
        return self._t[i0 : self._end].copy(), self._v[i0 : self._end].copy()

    def all(self) -> tuple[FloatArray, FloatArray]:
        """Copies of every stored sample."""
        return (
            self._t[self._start : self._end].copy(),
            self._v[self._start : self._end].copy(),
        )


@dataclass(frozen=True)
class _Window:
    t0: float
    trigger: float
    t1: float


class TriggerEngine:
    """Decides when the trigger fires and when the captured window is complete.

    Feed the trigger channel's samples with :meth:`feed` (level/edge kinds) or report events with
    :meth:`event` (state/fault kinds), then poll :meth:`complete` with the time up to which all
    channels have data; it returns ``(t0, t1)`` once per captured window. ``roll`` mode has no
    trigger: the engine stays ``idle`` (the service shows the scope as rolling).
    """

    def __init__(self, trigger: Trigger) -> None:
        self.trigger = trigger
        self._accepting = False
        self._done = False
        self._pending: deque[_Window] = deque()
        self._prev: float = math.nan
        self._fed_until = -math.inf
        # The next trigger needs a sample strictly after `_after` and at or after `_at_least`.
        self._after = -math.inf
        self._at_least = -math.inf
        self._trigger_time: float | None = None
        self._last_window: tuple[float, float, float] | None = None

    @property
    def state(self) -> EngineState:
        if self._pending:
            return "triggered"
        if self._accepting:
            return "armed"
        if self._done:
            return "done"
        return "idle"

    @property
    def trigger_time(self) -> float | None:
        """Time of the most recent trigger (the crossing sample's or the event's time)."""
        return self._trigger_time

    @property
    def last_window(self) -> tuple[float, float, float] | None:
        """``(t0, trigger_time, t1)`` of the window :meth:`complete` returned last."""
        return self._last_window

    def arm(self) -> None:
        """Wait for the next trigger (discarding a window in flight); a no-op in roll mode."""
        self._pending.clear()
        self._done = False
        self._after = self._at_least = -math.inf
        self._accepting = self.trigger.mode != "roll"

    def stop(self) -> None:
        """Stop waiting and drop a window in flight."""
        self._pending.clear()
        self._accepting = False
        self._done = False

    def _fire(self, t: float) -> None:
        tr = self.trigger
        self._pending.append(_Window(t - tr.pre_s, t, t + tr.post_s))
        self._trigger_time = t
        if tr.mode == "single":
            self._accepting = False
        else:
            # Normal mode re-arms after the captured window, and not before the holdoff.
            self._after = t + tr.post_s
            self._at_least = t + tr.holdoff_s

    def feed(self, t: npt.ArrayLike, v: npt.ArrayLike) -> float | None:
        """Feed samples of the trigger channel in time order; returns the first trigger time in
        them, or None."""
        ta, va = _as_samples(t, v)
        if ta.size == 0:
            return None
        prev = self._prev
        self._prev = float(va[-1])
        self._fed_until = max(self._fed_until, float(ta[-1]))
        tr = self.trigger
        if not self._accepting or tr.kind not in ("level", "edge"):
            return None
        prevs = np.empty_like(va)
        prevs[0] = prev
        prevs[1:] = va[:-1]
        with np.errstate(invalid="ignore"):
            if tr.kind == "level":
                up = (prevs < tr.level) & (va >= tr.level)
                down = (prevs > tr.level) & (va <= tr.level)
            else:
                step = va - prevs
                thr = abs(tr.level)
                up = step > thr
                down = step < -thr
        mask = up if tr.slope == "rising" else down if tr.slope == "falling" else up | down
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            return None
        cand = ta[idx]
        first: float | None = None
        pos = 0
        while self._accepting:
            pos = max(
                pos,
                int(np.searchsorted(cand, self._after, side="right")),
                int(np.searchsorted(cand, self._at_least, side="left")),
            )
            if pos >= cand.size:
                break
            when = float(cand[pos])
            self._fire(when)
            if first is None:
                first = when
            pos += 1
        return first

    def event(self, t: float) -> float | None:
        """A state change or fault at ``t`` (state/fault kinds); returns ``t`` when it fires."""
        if not self._accepting or self.trigger.kind not in ("state", "fault"):
            return None
        if t <= self._after or t < self._at_least:
            return None
        self._fire(float(t))
        return float(t)

    def complete(self, now: float) -> tuple[float, float] | None:
        """``(t0, t1)`` of the next captured window once data up to ``now`` covers its end.

        ``now`` is the time up to which the service has data for every channel. For level and
        edge triggers the trigger channel must also have been fed up to the window's end.
        """
        if not self._pending:
            return None
        horizon = now if self.trigger.kind in ("state", "fault") else min(now, self._fed_until)
        w = self._pending[0]
        if horizon < w.t1:
            return None
        self._pending.popleft()
        self._last_window = (w.t0, w.trigger, w.t1)
        if self.trigger.mode == "single" and not self._pending:
            self._done = True
        return (w.t0, w.t1)


def stats(t: npt.ArrayLike, v: npt.ArrayLike) -> dict[str, float | None]:
    """Per-channel statistics of a window: ``min max mean rms freq_hz n rate_hz``.

    NaN samples are left out. ``freq_hz`` comes from the rising zero crossings of ``v - mean``
    (with a hysteresis of 10 % of the AC RMS so noise does not add crossings), timed by linear
    interpolation between the samples around each crossing; None with fewer than two crossings.
    ``rate_hz`` is the achieved sample rate, ``(n - 1) / duration``.
    """
    ta, va = _as_samples(t, v)
    ok = np.isfinite(va) & np.isfinite(ta)
    ta, va = ta[ok], va[ok]
    n = int(va.size)
    out: dict[str, float | None] = {
        "min": None,
        "max": None,
        "mean": None,
        "rms": None,
        "freq_hz": None,
        "n": n,
        "rate_hz": None,
    }
    if n == 0:
        return out
    mean = float(np.mean(va))
    out.update(
        min=float(np.min(va)),
        max=float(np.max(va)),
        mean=mean,
        rms=float(np.sqrt(np.mean(va * va))),
    )
    if n > 1 and ta[-1] > ta[0]:
        out["rate_hz"] = (n - 1) / float(ta[-1] - ta[0])
    out["freq_hz"] = _frequency(ta, va - mean)
    return out


def _frequency(t: FloatArray, x: FloatArray) -> float | None:
    ac_rms = float(np.sqrt(np.mean(x * x)))
    if x.size < 3 or ac_rms == 0.0:
        return None
    h = 0.1 * ac_rms
    # Schmitt trigger: each sample is +1 above h, -1 below -h, 0 in between (ignored).
    side = np.where(x > h, 1, np.where(x < -h, -1, 0))
    where = np.flatnonzero(side)
    if where.size < 2:
        return None
    s = side[where]
    rises = where[1:][(s[:-1] < 0) & (s[1:] > 0)]  # first sample above +h after one below -h
    if rises.size < 2:
        return None
    # The zero crossing lies just after the last negative sample before each rise.
    idx = np.arange(x.size)
    last_neg = np.maximum.accumulate(np.where(x < 0.0, idx, -1))
    k = last_neg[rises]
    x0, x1 = x[k], x[k + 1]
    t0, t1 = t[k], t[k + 1]
    tc = t0 + (0.0 - x0) * (t1 - t0) / (x1 - x0)
    span = float(tc[-1] - tc[0])
    if span <= 0.0:
        return None
    return float((tc.size - 1) / span)


def math_channel(
    op: str,
    a: tuple[npt.ArrayLike, npt.ArrayLike],
    b: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """A math channel on ``a``'s time base: ``diff`` (a - b), ``sum`` (a + b), ``deriv`` (da/dt).

    ``b`` is interpolated linearly onto ``a``'s times; outside ``b``'s time span the result is NaN
    (the scope does not invent samples it did not take). ``deriv`` uses central differences
    ``(v[i+1] - v[i-1]) / (t[i+1] - t[i-1])`` inside and one-sided ones at both ends; NaN where two
    samples share a time.
    """
    if op not in MATH_OPS:
        raise ValidationError(
            f"math operation {op!r} is unknown; use one of {', '.join(MATH_OPS)}", field="op"
        )
    ta, va = _as_samples(*a)
    if op == "deriv":
        out = np.full(va.shape, np.nan)
        if va.size >= 2:
            with np.errstate(divide="ignore", invalid="ignore"):
                dv = np.empty_like(va)
                dt = np.empty_like(ta)
                dv[1:-1] = va[2:] - va[:-2]
                dt[1:-1] = ta[2:] - ta[:-2]
                dv[0], dt[0] = va[1] - va[0], ta[1] - ta[0]
                dv[-1], dt[-1] = va[-1] - va[-2], ta[-1] - ta[-2]
                out = np.where(dt > 0.0, dv / np.where(dt > 0.0, dt, 1.0), np.nan)
        return ta.copy(), out
    if b is None:
        raise ValidationError(f"math operation {op!r} needs two channels", field="b")
    tb, vb = _as_samples(*b)
    if tb.size == 0:
        vb_on_a = np.full(va.shape, np.nan)
    else:
        vb_on_a = np.interp(ta, tb, vb, left=np.nan, right=np.nan)
    return ta.copy(), (va - vb_on_a) if op == "diff" else (va + vb_on_a)
