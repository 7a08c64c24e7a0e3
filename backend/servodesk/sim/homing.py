"""Homing in the simulated drive: switch layout, index pulse and the homing procedure.

:class:`SwitchLayout` places the negative and positive limit switches, the home switch (a dog
between a lower and an upper edge) and the index pulse (once per revolution) on the plant's
encoder axis, from the profile's ``simulation`` settings. :class:`HomingProcedure` runs one
homing method (:mod:`servodesk.domain.homing` says what each method searches) as a sequence of
moves that react to the switch signals, the way a drive's homing firmware does: the searches run
at the switch-search speed 6099h:01, the approaches to the final edge and the index search at the
zero-search speed 6099h:02, every speed change with the homing acceleration 609Ah.

When the method has found its home point the axis stops, moves back onto it and the drive sets
6064h = 607Ch there (000 §3.2.4, 003 §4-4-7: "6062h = 6064h = 607Ch after homing").

Default layout (``None`` in the settings), in motor revolutions of the profile's
``counts_per_rev``: negative limit at -1.7, home switch from 1.3 to 1.7, positive limit at 3.7,
index pulses at whole revolutions. Every edge is 0.3 revolution away from the nearest index
pulse, so a drive that decelerates after an edge before it searches the index (003 §4-4-7:
"ORG ON -> decelerate to a stop -> ... stop at EZ") finds the same index pulse as the CiA 402
description, as long as the deceleration distance stays below 0.3 revolution.

The edges are latched at their exact positions (a drive latches them with a hardware capture),
so the end point does not depend on the search speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass

from servodesk.domain.homing import (
    TWIN_HOME_HIGH_REVS,
    TWIN_HOME_LOW_REVS,
    TWIN_LIMIT_NEGATIVE_REVS,
    TWIN_LIMIT_POSITIVE_REVS,
    HomingMethodInfo,
)
from servodesk.domain.profile import SimSettings

#: 60FDh bits (CiA 402-2 §6.9.1; 000 §3.2 60FDh; 003 §4-4-8 60FDh).
DI_LIMIT_NEGATIVE = 0x01
DI_LIMIT_POSITIVE = 0x02
DI_HOME_SWITCH = 0x04

# What the procedure generator is sent each cycle: (actual raw position, demand raw position,
# present velocity demand); it yields the next velocity demand.
_Feed = tuple[float, float, float]
_Gen = Generator[float, _Feed, bool]


@dataclass(frozen=True, slots=True)
class SwitchLayout:
    """Switch and index positions in raw encoder counts; None: the switch is not fitted."""

    counts_per_rev: int
    limit_negative: int | None
    limit_positive: int | None
    home_low: int | None
    home_high: int | None
    index_offset: int = 0

    @classmethod
    def from_settings(cls, s: SimSettings) -> SwitchLayout:
        rev = s.counts_per_rev

        def pick(value: int | None, revs: float) -> int:
            return value if value is not None else round(revs * rev)

        off = not s.homing_switches
        return cls(
            counts_per_rev=rev,
            limit_negative=None if off else pick(s.limit_negative, TWIN_LIMIT_NEGATIVE_REVS),
            limit_positive=None if off else pick(s.limit_positive, TWIN_LIMIT_POSITIVE_REVS),
            home_low=None if off else pick(s.home_switch_low, TWIN_HOME_LOW_REVS),
            home_high=None if off else pick(s.home_switch_high, TWIN_HOME_HIGH_REVS),
            index_offset=s.index_offset,
        )

    def nls(self, p: float) -> bool:
        return self.limit_negative is not None and p <= self.limit_negative

    def pls(self, p: float) -> bool:
        return self.limit_positive is not None and p >= self.limit_positive

    def home(self, p: float) -> bool:
        lo, hi = self.home_low, self.home_high
        return lo is not None and hi is not None and lo <= p <= hi

    def inputs(self, p: float) -> int:
        """The 60FDh bits for an axis at raw position ``p``."""
        return (
            (DI_LIMIT_NEGATIVE if self.nls(p) else 0)
            | (DI_LIMIT_POSITIVE if self.pls(p) else 0)
            | (DI_HOME_SWITCH if self.home(p) else 0)
        )

    def edge(self, name: str) -> int | None:
        return {
            "limit_negative": self.limit_negative,
            "limit_positive": self.limit_positive,
            "home_low": self.home_low,
            "home_high": self.home_high,
        }[name]

    def next_index(self, p: float, direction: int) -> int:
        """The first index pulse strictly beyond ``p`` in ``direction``."""
        rev = self.counts_per_rev
        k = (p - self.index_offset) / rev
        n = math.floor(k) + 1 if direction > 0 else math.ceil(k) - 1
        return self.index_offset + n * rev


class _Failed(Exception):
    """Homing cannot finish: a required switch was not found or a limit was reached."""


class HomingProcedure:
    """One homing run; :meth:`step` is called once per control cycle while it runs."""

    def __init__(
        self,
        info: HomingMethodInfo,
        layout: SwitchLayout,
        *,
        switch_speed: float,
        zero_speed: float,
        acceleration: float,
        period: float,
        max_travel: float,
    ) -> None:
        self.info = info
        self.layout = layout
        self.v_switch = max(abs(switch_speed), 1.0)
        self.v_zero = max(abs(zero_speed), 1.0)
        self.acc = acceleration if acceleration > 0 else 1e12
        self.T = period
        self.max_travel = max_travel
        #: Raw position of the home point once found.
        self.home_raw: int | None = None
        self.done = False
        self.error = False
        self.message = "running"
        self._snap: float | None = None
        self._gen = self._run()
        self._started = False

    # ------------------------------------------------------------------ public

    def step(self, p_actual: float, x_demand: float, v: float) -> tuple[float, float | None]:
        """Next velocity demand, and a demand position to snap to (on arrival), or None."""
        if self.done:
            return 0.0, None
        feed: _Feed = (p_actual, x_demand, v)
        self._snap = None
        try:
            if not self._started:
                self._started = True
                self._feed = feed
                out = next(self._gen)
            else:
                out = self._gen.send(feed)
        except StopIteration as stop:
            self.done = True
            if not stop.value:
                self.error = True
            return 0.0, self._snap
        return out, self._snap

    # ------------------------------------------------------------------ motion primitives

    def _ramp(self, v: float, target: float) -> float:
        dv = self.acc * self.T
        if v < target:
            return min(target, v + dv)
        return max(target, v - dv)

    def _move(
        self,
        direction: int,
        speed: float,
        until: Callable[[float, float], bool],
        *,
        guard: bool = True,
    ) -> Generator[float, _Feed, None]:
        """Run at ``direction * speed`` until ``until(previous, actual)`` is true.

        ``guard``: reaching the limit switch in the direction of motion is a failure.
        """
        p0 = p_prev = self._feed[0]
        v = self._feed[2]
        lay = self.layout
        while True:
            v = self._ramp(v, direction * speed)
            self._feed = yield v
            p, _x, v = self._feed
            if until(p_prev, p):
                return
            if guard and (lay.pls(p) if direction > 0 else lay.nls(p)):
                raise _Failed(f"{'positive' if direction > 0 else 'negative'} limit switch reached")
            if abs(p - p0) > self.max_travel:
                raise _Failed("the switch was not found within the maximum travel")
            p_prev = p

    def _stop(self) -> Generator[float, _Feed, None]:
        v = self._feed[2]
        while v != 0.0:
            v = self._ramp(v, 0.0)
            self._feed = yield v
            v = self._feed[2] if v != 0.0 else 0.0

    def _goto(self, target: float) -> Generator[float, _Feed, None]:
        """Position onto ``target`` (demand) at no more than the zero-search speed."""
        T = self.T
        while True:
            _p, x, v = self._feed
            e = target - x
            if abs(e) <= max(abs(v) * T, 0.5) and abs(v) <= self.acc * T + 1e-9:
                self._snap = target
                return
            h = 0.5 * self.acc * T
            vb = -h + math.sqrt(h * h + 2.0 * self.acc * abs(e))
            vdes = math.copysign(min(self.v_zero, vb), e)
            nv = self._ramp(v, vdes)
            if (e > 0 and nv * T >= e) or (e < 0 and nv * T <= e):
                self._snap = target
                return
            self._feed = yield nv

    # ------------------------------------------------------------------ the method

    def _run(self) -> _Gen:
        try:
            home = yield from self._search()
        except _Failed as exc:
            self.message = f"homing error: {exc}"
            yield from self._stop()
            return False
        self.home_raw = home
        yield from self._stop()
        yield from self._goto(float(home))
        self.message = "homing attained"
        return True

    def _search(self) -> Generator[float, _Feed, int]:
        info, lay = self.info, self.layout
        d = info.direction
        a = info.approach
        if info.edge is None:
            # Methods 33/34: the first index pulse in the direction of motion.
            target = lay.next_index(self._feed[0], d)
            yield from self._move(d, self.v_zero, _crossed(target, d))
            return target
        edge = lay.edge(info.edge)
        if edge is None:
            # The switch is not fitted: the search runs until the travel limit.
            yield from self._move(d, self.v_switch, lambda p0, p: False)
            raise _Failed("the switch is not fitted")
        if info.edge in ("limit_negative", "limit_positive"):
            active = lay.nls if info.edge == "limit_negative" else lay.pls
            if not active(self._feed[0]):
                yield from self._move(d, self.v_switch, lambda p0, p: active(p), guard=False)
                yield from self._stop()
            yield from self._move(a, self.v_zero, lambda p0, p: not active(p))
        else:
            yield from self._home_edge(edge)
        if not info.index:
            return edge
        target = lay.next_index(edge, a)
        yield from self._move(a, self.v_zero, _crossed(target, a))
        return target

    def _home_edge(self, edge: int) -> Generator[float, _Feed, None]:
        """Find the home switch edge ``edge`` met in the approach direction."""
        info, lay = self.info, self.layout
        a = info.approach
        home = lay.home
        # The approach leaves the switch through the edge (e.g. method 7: the lower edge met
        # moving negative) or enters it (method 8: the lower edge met moving positive).
        leaving = (info.edge == "home_low") == (a < 0)

        def entered(p0: float, p: float) -> bool:
            return home(p)

        def left(p0: float, p: float) -> bool:
            return not home(p)

        if home(self._feed[0]):
            # Started on the switch (000 §3.2.4 table 3.2.4.4: methods 7 and 8 then start
            # negative, 11 and 12 positive).
            if leaving:
                yield from self._move(a, self.v_zero, left)
            else:
                yield from self._move(-a, self.v_switch, left)
                yield from self._stop()
                yield from self._move(a, self.v_zero, entered)
            return
        direction = info.direction
        reversed_once = False
        while True:
            try:
                yield from self._move(direction, self.v_switch, entered)
                break
            except _Failed:
                if not info.reverse_at_limit or reversed_once:
                    raise
                # Methods 7-14 / 23-30: reverse at the limit switch in the search direction.
                reversed_once = True
                yield from self._stop()
                direction = -direction
        near = lay.home_low if direction > 0 else lay.home_high
        if edge == near and a == direction:
            return  # This crossing is the edge.
        if edge == near:
            yield from self._stop()
            yield from self._move(a, self.v_zero, left)
            return
        if a == direction:
            yield from self._move(direction, self.v_zero, left)
            return
        yield from self._move(direction, self.v_zero, left)
        yield from self._stop()
        yield from self._move(a, self.v_zero, entered)


def _crossed(target: float, direction: int) -> Callable[[float, float], bool]:
    if direction > 0:
        return lambda p0, p: p >= target
    return lambda p0, p: p <= target
