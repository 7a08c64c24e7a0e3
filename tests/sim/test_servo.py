"""The servo loop of the simulated drives (model/servo.py), its filters, the test signal
generator (sim/siggen.py) and their objects on the generic twin (docs/tuning.md)."""

from __future__ import annotations

import cmath
import math
import struct
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from servodesk.domain.profile import SERVO_GAIN_NAMES, DeviceProfile, TuningSpec
from servodesk.domain.profile_loader import check_profile, parse_profile
from servodesk.domain.tuning.gains import ServoGains as DomainGains
from servodesk.errors import ProfileError
from servodesk.model.plant import Plant
from servodesk.model.plantfile import PlantSpec
from servodesk.model.servo import (
    POSITION,
    TORQUE,
    VELOCITY,
    ServoGains,
    ServoLoop,
    default_gains,
    gain_names,
    lowpass_coefficients,
    notch_coefficients,
)
from servodesk.sim.engine import SIGNATURE_SAVE, SimAbort, SimulatedDrive
from servodesk.sim.siggen import (
    CHIRP,
    DONE,
    IDLE,
    PRBS,
    PRBS_TAPS,
    RUNNING,
    SINE,
    SignalConfig,
    SignalGenerator,
    prbs_order,
)
from tests.sim.support import enable, generic, new_drive

SIG = 0x2110  # The generic twin's test signal generator.
REC = 0x2F00  # ... and its recorder.


def _abort(fn: Any, *args: Any) -> int:
    with pytest.raises(SimAbort) as info:
        fn(*args)
    return info.value.code


def profile_gains() -> ServoGains:
    """The generic profile's default gains, as its objects give them."""
    gains = SimulatedDrive(generic(), 1).servo_gains
    assert gains is not None
    return gains


# ---------------------------------------------------------------------- gains and filters


def test_the_gain_fields_are_the_documented_canonical_gains() -> None:
    assert gain_names() == SERVO_GAIN_NAMES
    assert ServoGains is DomainGains  # The simulator runs the domain's gain set.
    assert SERVO_GAIN_NAMES[:6] == (
        "kp_pos",
        "kp_vel",
        "ti_vel",
        "vel_ff",
        "inertia_ff",
        "torque_lpf_hz",
    )
    g = default_gains(1.48e-4, 50.0)
    w = 2 * math.pi * 50.0
    assert (g.kp_vel, g.ti_vel, g.kp_pos) == pytest.approx((1.48e-4 * w, 4 / w, w / 5))
    assert (g.vel_ff, g.inertia_ff, g.notch1_hz, g.notch2_hz) == (1.0, 1.48e-4, 0.0, 0.0)
    # The generic profile's defaults are the documented design, rounded (servo.py).
    design = default_gains(
        1.48e-4, 50.0, integral_ratio=3.0, position_ratio=4.0, inertia_margin=31 / 4
    )
    ours = profile_gains()
    for name in ("kp_pos", "kp_vel", "ti_vel", "inertia_ff"):
        assert getattr(ours, name) == pytest.approx(getattr(design, name), rel=0.02), name
    # Filters off (the notch widths are the objects' neutral 1.0; unused at 0 Hz).
    assert ours == replace(
        design,
        kp_pos=ours.kp_pos,
        kp_vel=ours.kp_vel,
        ti_vel=ours.ti_vel,
        notch1_width=1.0,
        notch2_width=1.0,
    )


def _response(b: tuple[float, ...], a: tuple[float, ...], f: float, rate: float) -> complex:
    z = cmath.exp(-2j * math.pi * f / rate)  # z^-1
    num = sum(c * z**i for i, c in enumerate(b))
    den = 1 + sum(c * z ** (i + 1) for i, c in enumerate(a))
    return num / den


@pytest.mark.parametrize("rate", [4000.0, 16000.0])
def test_lowpass_matches_the_continuous_response(rate: float) -> None:
    fc = rate / 32  # 125 Hz at 4 kHz, 500 Hz at 16 kHz.
    b0, b1, b2, a1, a2 = lowpass_coefficients(fc, rate)
    assert b2 == a2 == 0.0  # A first-order section.
    for f in (0.1 * fc, 0.5 * fc, fc, 2 * fc):
        h = _response((b0, b1), (a1,), f, rate)
        analytic = 1 / abs(1 + 1j * f / fc)
        assert abs(h) == pytest.approx(analytic, rel=0.01), f
    # Pre-warped at the corner: exactly -3 dB and -45° there, unity at DC.
    h = _response((b0, b1), (a1,), fc, rate)
    assert abs(h) == pytest.approx(math.sqrt(0.5), rel=1e-9)
    assert math.degrees(cmath.phase(h)) == pytest.approx(-45.0, abs=1e-6)
    assert abs(_response((b0, b1), (a1,), 0.0, rate)) == pytest.approx(1.0)


@pytest.mark.parametrize(("f0", "width", "depth"), [(500.0, 0.5, 0.0), (120.0, 1.0, 0.1)])
def test_notch_matches_the_continuous_response(f0: float, width: float, depth: float) -> None:
    rate = 16000.0
    b0, b1, b2, a1, a2 = notch_coefficients(f0, width, depth, rate)
    z = width / 2

    def analytic(f: float) -> complex:
        s, w = 2j * math.pi * f, 2 * math.pi * f0
        return (s * s + 2 * depth * z * w * s + w * w) / (s * s + 2 * z * w * s + w * w)

    for f in (0.3 * f0, 0.8 * f0, 0.95 * f0, 1.05 * f0, 1.3 * f0, 2.0 * f0):
        h = _response((b0, b1, b2), (a1, a2), f, rate)
        assert abs(h) == pytest.approx(abs(analytic(f)), rel=0.01, abs=1e-3), f
    at = abs(_response((b0, b1, b2), (a1, a2), f0, rate))
    if depth == 0.0:
        assert 20 * math.log10(max(at, 1e-300)) < -40.0  # Full notch.
        # Width: the -3 dB points of a full notch are width * f apart.
        lo, hi = f0 * (math.sqrt(1 + z * z) - z), f0 * (math.sqrt(1 + z * z) + z)
        for f in (lo, hi):
            h = abs(_response((b0, b1, b2), (a1, a2), f, rate))
            assert h == pytest.approx(math.sqrt(0.5), rel=0.01)
    else:
        assert at == pytest.approx(depth, rel=0.01)
    assert abs(_response((b0, b1, b2), (a1, a2), 0.0, rate)) == pytest.approx(1.0)


def test_filter_arguments_are_checked() -> None:
    with pytest.raises(ValueError, match="Nyquist"):
        lowpass_coefficients(2000.0, 4000.0)
    with pytest.raises(ValueError, match="Nyquist"):
        notch_coefficients(2500.0, 1.0, 0.0, 4000.0)
    with pytest.raises(ValueError, match="width"):
        notch_coefficients(100.0, 0.0, 0.0, 4000.0)
    with pytest.raises(ValueError, match="depth"):
        notch_coefficients(100.0, 1.0, 1.5, 4000.0)
    # 0 Hz is a filter switched off: a pass-through.
    assert notch_coefficients(0.0, 1.0, 0.0, 4000.0) == lowpass_coefficients(0.0, 4000.0)
    # The loop takes what a drive would: an odd width or depth, a notch above Nyquist (off).
    loop = ServoLoop(replace(FILTERED, notch1_width=0.0, notch2_depth=3.0), 4000, 4096, 1.0)
    assert loop._n1_on and loop._n2_on
    loop.set_gains(replace(FILTERED, notch1_hz=2500.0, torque_lpf_hz=5000.0))
    assert not loop._n1_on and not loop._lp_on


# ---------------------------------------------------------------------- the loop itself

FILTERED = ServoGains(
    kp_pos=30.0,
    kp_vel=0.05,
    ti_vel=0.02,
    vel_ff=0.8,
    inertia_ff=1e-4,
    torque_lpf_hz=700.0,
    notch1_hz=300.0,
    notch1_width=0.6,
    notch1_depth=0.05,
    notch2_hz=900.0,
    notch2_width=1.2,
    notch2_depth=0.0,
)


@pytest.mark.parametrize("mode", [POSITION, VELOCITY, TORQUE])
def test_a_cycle_in_one_call_equals_tick_by_tick(mode: int) -> None:
    """ServoLoop.run (the engine's fast path) does exactly what update*() do per tick."""

    def make() -> tuple[ServoLoop, Plant, SignalGenerator]:
        spec = PlantSpec(resonance_hz=400.0, inertia_ratio=5)
        plant = Plant(spec.plant_params(seed=4))
        loop = ServoLoop(FILTERED, 16000, spec.encoder_counts, 0.3)  # Clamps sometimes.
        gen = SignalGenerator(16000)
        gen.start(SignalConfig(CHIRP, 0.4, 10.0, 2000.0, 0.2))
        return loop, plant, gen

    a_loop, a_plant, a_gen = make()
    b_loop, b_plant, b_gen = make()
    rad = a_loop._rad
    dt = 1 / 16000
    a_out: list[float] = []
    b_out: list[float] = []
    counts_a = counts_b = 0
    for cycle in range(150):
        p0, inc, v, acc = cycle * 160.0, 8.0 + cycle % 3, 3.0 - 0.01 * cycle, 40.0
        for k in range(1, 17):
            a_loop.tau_test = a_gen.next()
            if mode == POSITION:
                tau = a_loop.update((p0 + inc * k) * rad, v, acc, counts_a)
            elif mode == VELOCITY:
                tau = a_loop.update_velocity(v, acc, counts_a)
            else:
                tau = a_loop.update_torque(0.1 * math.sin(cycle), counts_a, 2.0)
            a_out.append(tau)
            counts_a = a_plant.step_counts(tau, dt)

        def after(_k: int) -> None:
            b_out.append(b_loop.command)

        counts_b, _ = b_loop.run(
            16,
            b_plant.step_counts,
            dt,
            counts_b,
            mode=mode,
            p0=p0,
            inc=inc,
            v_demand=v,
            a_demand=acc,
            tau_demand=0.1 * math.sin(cycle),
            v_limit=2.0,
            signal=b_gen.next,
            after=after,
        )
    assert a_out == b_out and counts_a == counts_b
    assert (a_loop.integral, a_loop.command, a_loop.velocity) == (
        b_loop.integral,
        b_loop.command,
        b_loop.velocity,
    )
    assert any(o == 0.3 or o == -0.3 for o in a_out)  # The clamp was exercised.


def test_the_command_reaches_the_plant_one_tick_late() -> None:
    loop = ServoLoop(ServoGains(kp_pos=0.0, kp_vel=1.0, ti_vel=0.0), 4000, 4096, 10.0)
    loop.reset(0)
    assert loop.update_velocity(2.0, 0.0, 0) == 0.0  # Computed 2 N m, applies last tick's 0.
    assert loop.update_velocity(2.0, 0.0, 0) == pytest.approx(2.0)
    # Velocity by differencing: one count per tick is 2 pi / 4096 * 4000 rad/s.
    loop.update_velocity(0.0, 0.0, 1)
    assert loop.velocity == pytest.approx(2 * math.pi / 4096 * 4000)


def test_the_integral_is_held_while_the_torque_is_clamped() -> None:
    loop = ServoLoop(ServoGains(kp_pos=0.0, kp_vel=1.0, ti_vel=0.01), 1000, 4096, 0.5)
    loop.reset(0)
    for _ in range(50):
        loop.update_velocity(10.0, 0.0, 0)  # Far beyond the limit: clamped at 0.5 N m.
    assert loop.saturated == 1 and loop.command == 0.5
    held = loop.integral
    assert held == pytest.approx(1.0 * 10.0 * 0.001 / 0.01)  # Only the first tick integrated.
    loop.update_velocity(-10.0, 0.0, 0)  # Out of the limit's direction: integrates again.
    assert loop.integral < held
    # Ti = 0: no integral at all.
    p = ServoLoop(ServoGains(kp_pos=0.0, kp_vel=0.001, ti_vel=0.0), 1000, 4096, 0.5)
    for _ in range(10):
        p.update_velocity(1.0, 0.0, 0)
    assert p.integral == 0.0


def test_torque_mode_passes_the_demand_and_limits_the_speed() -> None:
    loop = ServoLoop(ServoGains(kp_pos=0.0, kp_vel=0.01, ti_vel=0.0), 1000, 1000, 2.0)
    loop.reset(0)
    loop.update_torque(1.5, 0, 50.0)
    assert loop.update_torque(1.5, 0, 50.0) == 1.5
    # 10 counts per ms is 62.8 rad/s, above the 50 rad/s limit: cut to Kv (vlim - v).
    loop.update_torque(1.5, 10, 50.0)
    assert loop.update_torque(1.5, 20, 50.0) == pytest.approx(0.01 * (50.0 - 62.83185), rel=1e-4)
    loop.update_torque(5.0, 20, 50.0)
    assert loop.update_torque(5.0, 20, 50.0) == 2.0 and loop.saturated == 1


def _step(spec: PlantSpec, gains: ServoGains, seconds: float, step: float = 0.1) -> list[float]:
    plant = Plant(spec.plant_params(seed=1))
    loop = ServoLoop(gains, spec.loop_rate_hz, spec.encoder_counts, spec.peak_torque)
    rad = 2 * math.pi / spec.encoder_counts
    counts = 0
    errors = []
    for _ in range(int(seconds * spec.loop_rate_hz)):
        counts = plant.step_counts(loop.update(step, 0.0, 0.0, counts), 1 / spec.loop_rate_hz)
        errors.append(step - counts * rad)
    return errors


def _settles(e: list[float], rate: int, step: float = 0.1) -> bool:
    """Within 2 % of the step from 0.6 s on, and no oscillation left in the last 0.2 s."""
    tail = np.array(e[-rate // 5 :])
    return (
        max(e) <= step
        and max(abs(x) for x in e[int(0.6 * rate) :]) < 0.02 * step
        and float(np.ptp(tail)) < 0.001 * step
    )


@pytest.mark.parametrize("ratio", [1, 30])
@pytest.mark.parametrize("resonance", [None, 100.0, 400.0, 800.0, 1000.0])
def test_default_gains_settle_a_step_on_ratio_1_and_30(
    ratio: float, resonance: float | None
) -> None:
    """The profile's defaults on plant-file axes (16 kHz, 2^20 counts, 2 kHz current loop)
    without friction and noise (the linear plant decides stability)."""
    spec = PlantSpec(inertia_ratio=ratio, resonance_hz=resonance, coulomb=0.0, noise_torque=0.0)
    e = _step(spec, profile_gains(), 1.5)
    assert -min(e) < 0.05 * 0.1  # Overshoot below 5 %.
    assert _settles(e, spec.loop_rate_hz)


def test_the_step_check_fails_where_the_defaults_are_unstable() -> None:
    """At 4 kHz a 400 Hz mode is too close to the loop's delays for notch-free defaults (a
    case for the tuning's notch): the loop ends in a limit cycle at the torque limit."""
    spec = PlantSpec(
        inertia_ratio=10, resonance_hz=400.0, coulomb=0.0, noise_torque=0.0, loop_rate_hz=4000
    )
    e = _step(spec, profile_gains(), 1.5)
    assert not _settles(e, 4000)
    assert max(abs(x) for x in e[4000:]) > 0.2 * 0.1
    # Ten times the velocity gain at 16 kHz excites even a 1000 Hz mode.
    spec = PlantSpec(inertia_ratio=1, resonance_hz=1000.0, coulomb=0.0, noise_torque=0.0)
    wild = replace(profile_gains(), kp_vel=profile_gains().kp_vel * 100)
    assert not _settles(_step(spec, wild, 1.5), 16000)


@pytest.mark.parametrize("ratio", [1, 30])
def test_default_gains_hold_a_plant_file_axis_with_noise_and_friction(ratio: float) -> None:
    # The documented plant file (Coulomb 2 %, torque noise 0.5 % of peak) with a resonance.
    spec = PlantSpec(inertia_ratio=ratio, resonance_hz=400.0)
    e = _step(spec, profile_gains(), 3.0)
    # Stick-slip and noise keep it within 10 % of the step; nothing grows.
    assert max(abs(x) for x in e[16000:]) < 0.1 * 0.1
    assert max(abs(x) for x in e[32000:]) <= max(abs(x) for x in e[16000:32000]) + 1e-4


# ---------------------------------------------------------------------- the signal generator


def test_chirp_sweeps_logarithmically_through_the_band() -> None:
    rate = 16000
    gen = SignalGenerator(rate)
    gen.start(SignalConfig(CHIRP, 0.5, 10.0, 1000.0, 2.0))
    samples = [gen.next() for _ in range(gen.ticks)]
    assert gen.status == RUNNING and gen.next() == 0.0 and gen.status == DONE
    assert len(samples) == 32000 and max(map(abs, samples)) == pytest.approx(0.5, rel=1e-3)
    # Rising zero crossings, interpolated between the ticks.
    rising = [
        i - 1 + samples[i - 1] / (samples[i - 1] - samples[i])
        for i in range(1, len(samples))
        if samples[i - 1] < 0.0 <= samples[i]
    ]
    for t in (0.2, 1.0, 1.6):
        k = next(j for j, x in enumerate(rising) if x >= t * rate)
        period = (rising[k + 1] - rising[k]) / rate
        mid = (rising[k + 1] + rising[k]) / 2 / rate
        expected = 10.0 * 100.0 ** (mid / 2.0)  # f0 (f1/f0)^(t/D) in the period's middle.
        assert 1 / period == pytest.approx(expected, rel=0.01), t
        assert gen.instantaneous_frequency(mid) == pytest.approx(expected)
    # The sweep covers the band: about the integral of f(t) cycles in 2 s.
    cycles = 2.0 * (1000.0 - 10.0) / math.log(100.0)
    assert len(rising) == pytest.approx(cycles, abs=2)


def test_prbs_is_maximum_length_balanced_and_deterministic() -> None:
    for order in (7, 9, 12):
        n = (1 << order) - 1
        gen = SignalGenerator(1000)
        gen.start(SignalConfig(PRBS, 2.0, duration=2 * n / 1000))
        assert prbs_order(gen.ticks) == order + 1  # Two periods need the next order...
        gen = SignalGenerator(1000)
        gen.start(SignalConfig(PRBS, 2.0, duration=n / 1000))
        assert prbs_order(gen.ticks) == order  # ... one fits this one exactly.
        bits = [gen.next() for _ in range(n)]
        assert set(bits) == {2.0, -2.0}
        assert bits.count(2.0) == bits.count(-2.0) + 1  # An m-sequence: one more one.
        again = SignalGenerator(1000)
        again.start(SignalConfig(PRBS, 2.0, duration=n / 1000))
        assert [again.next() for _ in range(n)] == bits
    # Every tap mask in the table gives the full period (the small ones checked here).
    for order in (7, 8, 10, 11, 13):
        taps, state, period = PRBS_TAPS[order], (1 << order) - 1, 0
        while True:
            bit = state & 1
            state >>= 1
            if bit:
                state ^= taps
            period += 1
            if state == (1 << order) - 1:
                break
        assert period == (1 << order) - 1


def test_sine_and_the_configuration_checks() -> None:
    gen = SignalGenerator(4000)
    gen.start(SignalConfig(SINE, 1.0, 100.0, duration=0.01))
    s = [gen.next() for _ in range(40)]
    assert s[0] == 0.0 and s[10] == pytest.approx(math.sin(2 * math.pi * 100 * 10 / 4000))
    gen.stop()
    assert gen.status == IDLE and gen.next() == 0.0
    bad = [
        (SignalConfig(0, 1.0), "kind 0"),
        (SignalConfig(CHIRP, 0.0, 1.0, 10.0), "amplitude"),
        (SignalConfig(CHIRP, 1.0, 10.0, 5.0), "start < end"),
        (SignalConfig(CHIRP, 1.0, 10.0, 2001.0), "2000 Hz"),
        (SignalConfig(SINE, 1.0, 0.0), "sine 0.0 Hz"),
        (SignalConfig(PRBS, 1.0, duration=0.0), "duration"),
        (SignalConfig(PRBS, 1.0, duration=601.0), "duration"),
    ]
    for cfg, message in bad:
        with pytest.raises(ValueError, match=message):
            gen.start(cfg)


# ---------------------------------------------------------------------- on the generic twin


def _configure(d: SimulatedDrive, kind: int, amp: float, f0: float, f1: float, s: float) -> None:
    for sub, value in ((1, kind), (2, amp), (3, f0), (4, f1), (5, s)):
        d.write(SIG, sub, value)


def test_the_generic_profile_maps_every_gain_and_the_generator() -> None:
    p = generic()
    t = p.tuning
    assert t is not None and t.kind == "gains" and set(t.gains) == set(SERVO_GAIN_NAMES)
    assert t.signal_index == SIG and str(t.loop_rate_address) == "0x2108:00"
    assert p.simulation.loop_rate_hz == 4000 and check_profile(p) == []
    d = new_drive()
    assert d.loop_rate_hz == 4000 and d.read(0x2108) == 4000 and d.servo is not None
    assert d.servo_gains == profile_gains()
    # Another family keeps the cycle-rate cascade.
    from tests.sim.support import _CATALOG

    assert SimulatedDrive(_CATALOG.get("hiwin-e"), 1).servo is None


def test_writing_a_gain_over_sdo_changes_the_loop() -> None:
    """A 20 Hz torque disturbance (the generator's sine) moves a held axis; four times the
    velocity gain, written as REAL32 bytes like an SDO download, moves it far less."""
    d = new_drive()
    enable(d)
    d.step(0.05)

    def wobble() -> float:
        _configure(d, SINE, 0.3, 20.0, 0.0, 0.5)
        d.write(SIG, 6, 1)
        d.step(0.2)
        seen = []
        for _ in range(200):
            d.step(0.001)
            seen.append(d.position)
        d.write(SIG, 6, 0)
        d.step(0.3)
        return float(max(seen) - min(seen))

    soft = wobble()
    kv = profile_gains().kp_vel * 4
    d.write_bytes(0x2101, 0, struct.pack("<f", kv))
    assert d.servo_gains is not None
    assert d.servo_gains.kp_vel == pytest.approx(kv, rel=1e-6)
    stiff = wobble()
    assert stiff < 0.4 * soft
    # A notch written over SDO is in the loop from the next tick.
    d.write_bytes(0x2106, 1, struct.pack("<f", 150.0))
    assert d.servo_gains.notch1_hz == 150.0 and d.servo._n1_on  # type: ignore[union-attr]


def test_gains_are_stored_and_restored_like_the_other_parameters() -> None:
    d = new_drive()
    d.write(0x2100, 0, 25.0)
    d.write(0x1010, 1, SIGNATURE_SAVE)
    d.write(0x2100, 0, 5.0)
    d.reset_node()
    assert d.read(0x2100) == 25.0 and d.servo_gains.kp_pos == 25.0  # type: ignore[union-attr]
    assert _abort(d.write, 0x2101, 0, -1.0) == 0x06090032  # Below the object's minimum.
    assert _abort(d.write, 0x2108, 0, 8000) == 0x06010002  # The loop rate is read-only.


def test_the_generator_runs_only_enabled_and_guards_its_configuration() -> None:
    d = new_drive()
    _configure(d, CHIRP, 0.1, 5.0, 500.0, 0.05)
    assert _abort(d.write, SIG, 6, 1) == 0x08000022  # Not in Operation enabled.
    enable(d)
    d.write(SIG, 1, 0)
    assert _abort(d.write, SIG, 6, 1) == 0x08000020  # Kind 0: nothing to run.
    d.write(SIG, 1, CHIRP)
    d.write(SIG, 4, 3000.0)
    assert _abort(d.write, SIG, 6, 1) == 0x08000020  # Above half the 4 kHz loop rate.
    d.write(SIG, 4, 500.0)
    assert _abort(d.write, SIG, 6, 7) == 0x06090030
    d.write(SIG, 6, 1)
    assert d.read(SIG, 6) == RUNNING
    assert _abort(d.write, SIG, 2, 0.2) == 0x08000022  # Configuration refused while running.
    d.step(0.02)
    assert d.read(SIG, 7) != 0.0  # The torque command carries the signal.
    d.step(0.04)
    assert d.read(SIG, 6) == DONE
    d.write(SIG, 6, 1)
    d.write(0x6040, 0, 0x06)  # Disabled: the signal stops with the loops.
    assert d.read(SIG, 6) == IDLE
    d.step(0.002)
    assert d.read(SIG, 7) == 0.0


def test_the_recorder_samples_the_loop_at_16_khz_for_a_frequency_response() -> None:
    spec = PlantSpec(resonance_hz=400.0)
    d = SimulatedDrive(generic(), 5, plant_params=spec.plant_params(), loop_rate_hz=16000)
    d.step(0.001)
    assert d.recorder is not None and d.recorder.rate_hz == 16000.0 and d.read(0x2108) == 16000
    enable(d)
    d.write(0x6060, 0, 3)  # Velocity mode at standstill: the loop holds 0 rad/s.
    d.step(0.05)
    log: list[tuple[float, int, int]] = []

    def tick() -> None:
        servo = d.servo
        assert servo is not None
        log.append((servo.command, round(d.velocity), d.position))

    d.on_substep(tick)
    depth = 24000  # 1.5 s at 16 kHz, three channels (docs/tuning.md).
    for n, entry in enumerate((0x21100720, 0x606C0020, 0x60640020), 1):
        d.write(REC, n, entry)
    for offset, value in ((1, 1), (2, depth), (3, 0)):
        d.write(REC + offset, 0, value)
    _configure(d, PRBS, 0.05, 0.0, 0.0, 1.5)
    d.write(SIG, 6, 1)
    d.write(REC + 6, 0, 1)
    first = len(log)
    d.step(1.6)
    assert d.read(REC + 6) == 3 and d.read(REC + 8) == depth
    data = d.read_bytes(REC + 7)
    rows = list(struct.iter_unpack("<fii", data))
    assert len(rows) == depth
    # One sample per loop tick: the recording is the loop's own per-tick values.
    expected = [(struct.unpack("<f", struct.pack("<f", c))[0], v, p) for c, v, p in log]
    assert rows == expected[first : first + depth]
    torques = np.array([r[0] for r in rows])
    assert float(np.abs(torques).max()) > 0.04  # The PRBS is in the recorded input.


# ---------------------------------------------------------------------- the profile block


def _with_tuning(**tuning: Any) -> dict[str, Any]:
    data = generic().model_dump(mode="json")
    data["tuning"] = {**data["tuning"], **tuning}
    return data


def test_the_tuning_block_is_validated() -> None:
    with pytest.raises(ProfileError, match="unknown gain kp_speed"):
        parse_profile(
            _with_tuning(gains={"kp_speed": {"object": "0x2100:00", "unit": "1/s"}}),
        )
    with pytest.raises(ProfileError, match="needs the gains kp_vel, ti_vel"):
        parse_profile(_with_tuning(gains={"kp_pos": {"object": "0x2100:00", "unit": "1/s"}}))
    with pytest.raises(ProfileError, match=r"tuning\.gains\.kp_pos\.object"):
        parse_profile(_with_tuning(gains={"kp_pos": {"object": "banana", "unit": "1/s"}}))
    with pytest.raises(ProfileError, match=r"tuning\.kind"):
        parse_profile(_with_tuning(kind="magic"))
    with pytest.raises(ProfileError, match="loop_rate_hz"):
        data = generic().model_dump(mode="json")
        data["simulation"]["loop_rate_hz"] = 2500
        parse_profile(data)
    # Objects that are not there, or not usable, are consistency problems.
    gains = dict(generic().model_dump(mode="json")["tuning"]["gains"])
    gains["kp_pos"] = {"object": "0x2199:00", "unit": "1/s"}
    gains["kp_vel"] = {"object": "0x1008:00", "unit": "N m s/rad"}
    p: DeviceProfile = parse_profile(_with_tuning(gains=gains, signal_index=0x2F00))
    problems = check_profile(p)
    assert any("tuning.gains.kp_pos: 0x2199:00 is not an object" in x for x in problems)
    assert any("tuning.gains.kp_vel: 0x1008:00" in x and "not a number" in x for x in problems)
    assert any("2F00h:01 must be a writable UNSIGNED8" in x for x in problems)
    assert TuningSpec(kind="none").gains == {}
