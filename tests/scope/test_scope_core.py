"""The pure scope core: trigger placement and modes, the sample ring, statistics, math channels."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from servodesk.domain.scope import Ring, Trigger, TriggerEngine, math_channel, stats
from servodesk.errors import ValidationError

FS = 1000.0  # samples per second of the test signals
DT = 1.0 / FS


def first_crossing(t: np.ndarray, v: np.ndarray, level: float, slope: str, after: float) -> float:
    """The time of the first sample after ``after`` that crosses ``level``, by a plain loop."""
    for i in range(1, t.size):
        if t[i] < after:
            continue
        up = v[i - 1] < level <= v[i]
        down = v[i - 1] > level >= v[i]
        if (
            (slope == "rising" and up)
            or (slope == "falling" and down)
            or (slope == "either" and (up or down))
        ):
            return float(t[i])
    raise AssertionError("the signal never crosses the level")


def run_scope(
    signal: Callable[[np.ndarray], np.ndarray],
    trigger: Trigger,
    *,
    duration: float = 6.0,
    arm_at: float = 1.0,
    chunk: int = 37,
) -> tuple[np.ndarray, np.ndarray, list[tuple[float, float, float, np.ndarray, np.ndarray]]]:
    """Stream a signal through a ring and the engine like the service does; return the captures
    as (t0, trigger time, t1, window times, window values)."""
    t = np.arange(int(duration * FS)) * DT + 100.0  # backend-clock-like offset
    v = signal(t - 100.0)
    ring = Ring(int(10 * FS))
    engine = TriggerEngine(trigger)
    captures = []
    armed = False
    for i in range(0, t.size, chunk):
        tc, vc = t[i : i + chunk], v[i : i + chunk]
        if not armed and tc[0] >= 100.0 + arm_at:
            engine.arm()
            armed = True
        ring.extend(tc, vc)
        engine.feed(tc, vc)
        while (window := engine.complete(float(tc[-1]))) is not None:
            t0, t1 = window
            assert engine.last_window is not None
            wt, wv = ring.window(t0, t1)
            captures.append((t0, engine.last_window[1], t1, wt, wv))
    return t, v, captures


def ramp(t: np.ndarray) -> np.ndarray:
    return 10.0 * t - 10.0  # crosses 5.0 at t = 1.5 s


def sine(t: np.ndarray) -> np.ndarray:
    return 3.0 * np.sin(2 * np.pi * 2.0 * t)  # 2 Hz


def step(t: np.ndarray) -> np.ndarray:
    return np.where(t < 2.0, 0.0, 1.0)


@pytest.mark.parametrize(
    ("signal", "level", "slope"),
    [(ramp, 5.0, "rising"), (sine, 1.5, "rising"), (sine, -1.0, "falling"), (step, 0.5, "rising")],
    ids=["ramp", "sine-rising", "sine-falling", "step"],
)
def test_level_trigger_with_20_percent_pre_trigger_places_the_event_at_20_percent(
    signal: Callable[[np.ndarray], np.ndarray], level: float, slope: str
) -> None:
    trigger = Trigger(mode="single", level=level, slope=slope, pre=0.2, window_s=0.5)
    t, v, captures = run_scope(signal, trigger)
    assert len(captures) == 1
    t0, when, t1, wt, wv = captures[0]
    # The trigger is the first sample after arming that crosses the level.
    assert when == first_crossing(t, v, level, slope, after=101.0)
    assert t1 - t0 == pytest.approx(0.5)
    # The window holds 0.5 s of samples with the trigger sample at 20 % of it.
    assert wt[0] - t0 < DT and t1 - wt[-1] < DT
    k = int(np.searchsorted(wt, when))
    assert wt[k] == when
    assert abs((when - wt[0]) - 0.2 * 0.5) <= DT
    assert abs(k - 0.2 * (wt.size - 1)) <= 1
    # And that sample is on the far side of the level, its predecessor on the near side.
    if slope == "rising":
        assert wv[k - 1] < level <= wv[k]
    else:
        assert wv[k - 1] > level >= wv[k]


def test_a_sample_exactly_at_the_level_counts_as_crossed() -> None:
    engine = TriggerEngine(Trigger(mode="single", level=1.0, window_s=1.0))
    engine.arm()
    assert engine.feed([0.0, 0.1, 0.2, 0.3], [0.0, 0.5, 1.0, 2.0]) == 0.2
    # Touching the level from below and leaving upwards fires once, at the touch.
    engine = TriggerEngine(Trigger(mode="normal", level=1.0, window_s=0.05))
    engine.arm()
    assert engine.feed([0.0, 0.1, 0.2, 0.3], [1.0, 1.0, 2.0, 3.0]) is None
    assert engine.feed([0.4, 0.5], [0.0, 1.0]) == 0.5


def test_either_slope_fires_both_ways_and_the_crossing_spans_feed_calls() -> None:
    engine = TriggerEngine(Trigger(mode="normal", level=0.0, slope="either", window_s=0.01))
    engine.arm()
    assert engine.feed([0.0], [-1.0]) is None
    assert engine.feed([0.1], [1.0]) == 0.1  # previous sample came in the previous call
    assert engine.feed([0.2], [-1.0]) == 0.2


def test_single_captures_one_window_and_stops() -> None:
    trigger = Trigger(mode="single", level=0.0, window_s=0.2)
    _, _, captures = run_scope(sine, trigger)
    assert len(captures) == 1
    engine = TriggerEngine(trigger)
    engine.arm()
    assert engine.state == "armed"
    assert engine.feed([0.0, 0.01], [-1.0, 1.0]) == 0.01
    assert engine.state == "triggered"
    assert engine.feed([0.02, 0.03, 0.5, 0.51], [1.0, -1.0, -1.0, 1.0]) is None
    assert engine.complete(10.0) == pytest.approx((0.01 - 0.04, 0.01 + 0.16))
    assert engine.state == "done"
    assert engine.feed([0.6, 0.61], [-1.0, 1.0]) is None
    assert engine.complete(10.0) is None
    engine.arm()  # a new single shot
    assert engine.feed([0.7, 0.71], [-1.0, 1.0]) == 0.71


def test_normal_mode_re_arms_after_each_window() -> None:
    trigger = Trigger(mode="normal", level=0.0, window_s=0.2, pre=0.5)
    t, v, captures = run_scope(sine, trigger, duration=4.0, arm_at=1.0)
    whens = [c[1] for c in captures]
    # 2 Hz: a rising zero crossing every 0.5 s; armed at 1.04 s (chunk boundary), so the ones at
    # 1.5 .. 3.5 s are captured, each one.
    assert len(whens) == 5
    assert whens[0] == first_crossing(t, v, 0.0, "rising", after=101.1)
    assert np.allclose(np.diff(whens), 0.5, atol=DT)
    for t0, when, t1, wt, _ in captures:
        assert abs((when - wt[0]) - 0.1) <= DT and t1 - t0 == pytest.approx(0.2)


def test_normal_mode_holdoff_skips_triggers_inside_it() -> None:
    trigger = Trigger(mode="normal", level=0.0, window_s=0.2, holdoff_s=0.9)
    _, _, captures = run_scope(sine, trigger, duration=4.0, arm_at=1.0)
    whens = [c[1] for c in captures]
    assert len(whens) == 3
    assert np.allclose(np.diff(whens), 1.0, atol=DT)


def test_one_big_chunk_yields_every_window_in_order() -> None:
    t = np.arange(4000) * DT
    v = sine(t)
    engine = TriggerEngine(Trigger(mode="normal", level=0.0, window_s=0.2))
    engine.arm()
    assert engine.feed(t, v) == first_crossing(t, v, 0.0, "rising", after=0.0)
    windows = []
    while (w := engine.complete(float(t[-1]))) is not None:
        windows.append(w)
    assert len(windows) == 7  # crossings at 0.5 .. 3.5 s (t = 0 has no previous sample)
    assert engine.state == "armed"


def test_window_completes_only_when_its_post_trigger_time_was_fed() -> None:
    engine = TriggerEngine(Trigger(mode="single", level=0.5, window_s=1.0, pre=0.25))
    engine.arm()
    assert engine.feed([10.0, 10.1], [0.0, 1.0]) == 10.1
    # Other channels may be further on, but the trigger channel has only been fed to 10.1 s.
    assert engine.complete(20.0) is None
    engine.feed([10.2, 10.3, 10.4, 10.5, 10.6, 10.7], np.ones(6))
    assert engine.complete(20.0) is None  # fed to 10.7, the window ends at 10.85
    assert engine.complete(10.9) is None
    engine.feed([10.9], [1.0])
    assert engine.complete(10.84) is None  # the service's data ends before the window does
    assert engine.complete(10.9) == pytest.approx((9.85, 10.85))


def test_state_and_fault_triggers_come_as_events() -> None:
    engine = TriggerEngine(Trigger(mode="normal", kind="fault", window_s=1.0, pre=0.5))
    engine.arm()
    assert engine.feed([0.0, 1.0], [0.0, 100.0]) is None  # samples do not fire an event trigger
    assert engine.event(5.0) == 5.0
    assert engine.event(5.2) is None  # inside the window in flight
    assert engine.complete(5.4) is None
    assert engine.complete(5.5) == (4.5, 5.5)
    assert engine.event(5.6) == 5.6
    level = TriggerEngine(Trigger(mode="normal", kind="level"))
    level.arm()
    assert level.event(1.0) is None


def test_edge_trigger_fires_on_a_step_of_a_digital_value() -> None:
    engine = TriggerEngine(
        Trigger(mode="normal", kind="edge", level=0, slope="rising", window_s=0.1)
    )
    engine.arm()
    assert engine.feed([0.0, 0.1, 0.2], [0.0, 0.0, 0.0]) is None
    assert engine.feed([0.3, 0.4], [1.0, 1.0]) == 0.3
    assert engine.feed([0.5, 0.6, 0.7], [0.0, 0.0, 4.0]) == 0.7  # the fall is not a rising edge
    big = TriggerEngine(Trigger(mode="single", kind="edge", level=2.0, slope="falling"))
    big.arm()
    assert big.feed([0.0, 0.1, 0.2], [10.0, 9.0, 5.0]) == 0.2  # only a drop of more than 2


def test_stop_and_roll() -> None:
    engine = TriggerEngine(Trigger(mode="normal", level=0.0))
    engine.arm()
    engine.feed([0.0, 0.1], [-1.0, 1.0])
    assert engine.state == "triggered"
    engine.stop()
    assert engine.state == "idle" and engine.complete(100.0) is None
    assert engine.feed([0.2, 0.3], [-1.0, 1.0]) is None
    roll = TriggerEngine(Trigger(mode="roll"))
    roll.arm()
    assert roll.state == "idle" and roll.feed([0.0, 0.1], [-1.0, 1.0]) is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"mode": "auto"}, "trigger mode 'auto' is unknown"),
        ({"mode": "single", "kind": "window"}, "trigger kind 'window' is unknown"),
        ({"mode": "single", "slope": "up"}, "trigger slope 'up' is unknown"),
        ({"mode": "single", "pre": 1.5}, "pre-trigger fraction 1.5 is outside 0..1"),
        ({"mode": "single", "window_s": 0.0}, "window_s must be a positive number"),
        ({"mode": "single", "holdoff_s": -1.0}, "holdoff_s must be zero or a positive"),
        ({"mode": "single", "channel": 32}, "trigger channel 32 is out of range"),
        ({"mode": "single", "level": math.nan}, "trigger level must be a finite number"),
    ],
)
def test_bad_trigger_settings_are_refused(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        Trigger(**kwargs)  # type: ignore[arg-type]


def test_ring_keeps_the_newest_capacity_samples_in_order() -> None:
    rng = np.random.default_rng(3)
    ring = Ring(1000)
    t_all = np.arange(50_000) * 0.001
    v_all = rng.normal(size=t_all.size)
    i = 0
    while i < t_all.size:
        n = int(rng.integers(0, 300))
        ring.extend(t_all[i : i + n], v_all[i : i + n])
        i = min(i + n, t_all.size)
        kept = min(i, 1000)
        assert len(ring) == kept
        t, v = ring.all()
        assert np.array_equal(t, t_all[i - kept : i]) and np.array_equal(v, v_all[i - kept : i])
    ring.extend(t_all[-1] + 1.0 + np.arange(2500) * 0.001, np.arange(2500.0))
    t, v = ring.all()
    assert len(ring) == 1000 and v[0] == 1500.0 and v[-1] == 2499.0


def test_ring_window_and_since_by_time() -> None:
    ring = Ring(100)
    ring.extend(np.arange(10) * 0.125, np.arange(10.0))
    t, v = ring.window(0.25, 0.625)  # both ends included
    assert v.tolist() == [2.0, 3.0, 4.0, 5.0]
    assert ring.window(0.3, 0.3)[1].size == 0
    assert ring.since(0.875)[1].tolist() == [8.0, 9.0]  # strictly after
    assert ring.since(-1.0)[1].size == 10
    assert (ring.first_time, ring.last_time) == (0.0, 1.125)
    t[0] = 99.0  # copies: the caller cannot change the ring
    assert ring.window(0.25, 0.625)[0][0] == 0.25
    with pytest.raises(ValidationError, match="before the last stored sample"):
        ring.extend([0.5], [1.0])
    with pytest.raises(ValidationError, match="go backwards"):
        ring.extend([2.0, 1.5], [1.0, 1.0])
    with pytest.raises(ValidationError, match="differ in length"):
        ring.extend([3.0], [1.0, 2.0])
    ring.clear()
    assert len(ring) == 0 and ring.last_time is None


def test_stats_of_a_sine_with_offset_and_noise() -> None:
    rng = np.random.default_rng(4)
    f, amp, offset = 7.3, 2.0, 0.5
    t = 1000.0 + np.arange(int(1.37 * FS)) * DT
    v = offset + amp * np.sin(2 * np.pi * f * t) + rng.normal(scale=0.02 * amp, size=t.size)
    s = stats(t, v)
    assert s["freq_hz"] == pytest.approx(f, rel=0.01)
    assert s["n"] == t.size and s["rate_hz"] == pytest.approx(FS)
    assert s["mean"] == pytest.approx(offset, abs=0.05)
    assert s["rms"] == pytest.approx(math.sqrt(offset**2 + amp**2 / 2), rel=0.01)
    assert s["max"] == pytest.approx(float(v.max())) and s["min"] == pytest.approx(float(v.min()))


@pytest.mark.parametrize("f", [1.3, 13.0, 61.7, 240.0])
def test_stats_frequency_is_within_1_percent(f: float) -> None:
    t = np.arange(int(2.0 * FS)) * DT  # 2 s hold at least two rising crossings (one period)
    assert stats(t, np.sin(2 * np.pi * f * t + 0.3))["freq_hz"] == pytest.approx(f, rel=0.01)
    assert stats(t[:300], np.sin(2 * np.pi * 1.3 * t[:300]))["freq_hz"] is None  # < 1 period


def test_stats_of_empty_constant_and_irregular_data() -> None:
    empty = stats([], [])
    assert empty["n"] == 0 and all(
        empty[k] is None for k in ("min", "max", "mean", "rms", "freq_hz", "rate_hz")
    )
    flat = stats(np.arange(10) * 0.1, np.full(10, 3.0))
    assert flat["freq_hz"] is None and flat["rms"] == pytest.approx(3.0)
    # SDO polling: irregular times; the achieved rate is (n - 1) / duration; NaN is left out.
    s = stats([0.0, 0.03, 0.05, 0.11, 0.2], [1.0, math.nan, 2.0, 3.0, 4.0])
    assert s["n"] == 4 and s["rate_hz"] == pytest.approx(3 / 0.2) and s["mean"] == 2.5


def test_math_diff_and_sum_interpolate_b_onto_a() -> None:
    ta = np.arange(0, 1.0, 0.001)
    tb = np.arange(0.1, 0.9, 1 / 370)  # another source, another rate
    a = (ta, 3.0 * ta)
    b = (tb, 2.0 * tb + 1.0)  # linear: interpolation is exact
    t, d = math_channel("diff", a, b)
    assert np.array_equal(t, ta)
    inside = (ta >= tb[0]) & (ta <= tb[-1])
    np.testing.assert_allclose(d[inside], ta[inside] - 1.0, atol=1e-12)
    assert np.isnan(d[~inside]).all()  # no invented samples outside b's span
    _, s = math_channel("sum", a, b)
    np.testing.assert_allclose(s[inside], 5.0 * ta[inside] + 1.0, atol=1e-12)


def test_math_deriv_uses_central_differences() -> None:
    t = np.arange(0, 1.0, 0.01)
    _, d = math_channel("deriv", (t, t * t))
    np.testing.assert_allclose(d[1:-1], 2 * t[1:-1], atol=1e-12)  # exact for a parabola
    assert d[0] == pytest.approx(0.01) and d[-1] == pytest.approx(2 * t[-1] - 0.01)
    # SDO polling: jittered times (central differences on an uneven grid are first order).
    tt = np.arange(400) * 0.0025 + np.random.default_rng(5).uniform(-5e-4, 5e-4, 400)
    _, ds = math_channel("deriv", (tt, np.sin(tt)))
    np.testing.assert_allclose(ds[1:-1], np.cos(tt[1:-1]), atol=2e-3)
    _, dup = math_channel("deriv", ([0.0, 0.0, 1.0], [1.0, 2.0, 3.0]))
    assert math.isnan(dup[0]) and dup[1] == 2.0
    assert math.isnan(math_channel("deriv", ([1.0], [2.0]))[1][0])


def test_math_refuses_unknown_operations() -> None:
    a = (np.zeros(2), np.zeros(2))
    with pytest.raises(ValidationError, match="math operation 'mul' is unknown"):
        math_channel("mul", a, a)
    with pytest.raises(ValidationError, match="needs two channels"):
        math_channel("diff", a)
