"""The simulated drives' test signal generator: a torque added to the servo loop's command.

Real drives call it a "function generator"; servodesk's own one-touch tuning uses it to
measure the frequency response (docs/tuning.md, "Test signal generator"). The profile's
``tuning.signal_index`` (generic twin: 2110h, ``sim_only``) holds:

=== ========= =============================================================================
sub type      meaning
=== ========= =============================================================================
1   UNSIGNED8 kind: 0 off, 1 logarithmic chirp, 2 PRBS, 3 sine
2   REAL32    amplitude [N m]
3   REAL32    start frequency [Hz] (chirp, sine)
4   REAL32    end frequency [Hz] (chirp)
5   REAL32    duration [s]
6   UNSIGNED8 control/status: write 1 start, 0 stop; read 0 idle, 1 running, 2 done
7   REAL32    the torque command [N m] after the filters (recordable: the FRF input)
=== ========= =============================================================================

The signal (one value per servo-loop tick, tick ``k`` at ``t = k / rate``, ``N =
round(duration * rate)`` ticks, then done):

- chirp: ``A sin(2 pi f0 D / ln(r) (r^(t/D) - 1))``, ``r = f1 / f0``: the instantaneous
  frequency ``f0 r^(t/D)`` sweeps from ``f0`` to ``f1`` logarithmically over ``D``
  (equal time per octave, so every decade gets the same excitation energy);
- PRBS: ``+-A``, one bit of a maximum-length sequence per tick (Galois LFSR, all-ones seed,
  order ``n`` the smallest of 7..24 whose period ``2^n - 1`` covers the ``N`` ticks, so the
  run holds at most one period: white up to the loop's Nyquist frequency);
- sine: ``A sin(2 pi f0 t)``.

Deterministic: the same configuration gives the same samples. Checks at start (the engine
answers 0800 0020h with the message): a kind, an amplitude above 0, ``0 < f0 < f1 <= rate/2``
for the chirp and ``0 < f0 <= rate/2`` for the sine, a duration of 1 ms to 600 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

OFF, CHIRP, PRBS, SINE = 0, 1, 2, 3
IDLE, RUNNING, DONE = 0, 1, 2

KIND_NAMES = {OFF: "off", CHIRP: "chirp", PRBS: "prbs", SINE: "sine"}

#: Sub-indexes of the generator objects (docs/tuning.md).
(
    SUB_KIND,
    SUB_AMPLITUDE,
    SUB_F_START,
    SUB_F_END,
    SUB_DURATION,
    SUB_CONTROL,
    SUB_TORQUE,
    SUB_VALUE,
) = range(1, 9)

MAX_DURATION = 600.0

#: Galois LFSR feedback masks of maximum-length sequences (period 2^n - 1) by order n
#: (the usual tap table, e.g. Xilinx XAPP 052; tests/sim/test_servo.py checks the period).
PRBS_TAPS: dict[int, int] = {
    7: 0x60,
    8: 0xB8,
    9: 0x110,
    10: 0x240,
    11: 0x500,
    12: 0xE08,
    13: 0x1C80,
    14: 0x3802,
    15: 0x6000,
    16: 0xD008,
    17: 0x12000,
    18: 0x20400,
    19: 0x72000,
    20: 0x90000,
    21: 0x140000,
    22: 0x300000,
    23: 0x420000,
    24: 0xE10000,
}


def prbs_order(ticks: int) -> int:
    """The PRBS order for a run of ``ticks``: the smallest 7..24 with ``2^n - 1 >= ticks``."""
    for n in sorted(PRBS_TAPS):
        if (1 << n) - 1 >= ticks:
            return n
    return max(PRBS_TAPS)


@dataclass(frozen=True, slots=True)
class SignalConfig:
    """One configuration of the generator (subs 1-5)."""

    kind: int
    amplitude: float
    f_start: float = 0.0
    f_end: float = 0.0
    duration: float = 1.0

    def problem(self, rate_hz: float) -> str | None:
        """Why the generator cannot start with this configuration (None: it can)."""
        nyq = 0.5 * rate_hz
        if self.kind not in (CHIRP, PRBS, SINE):
            return f"kind {self.kind}: 1 chirp, 2 PRBS or 3 sine"
        if not self.amplitude > 0.0 or not math.isfinite(self.amplitude):
            return f"amplitude {self.amplitude} N m: must be above 0"
        if not 1e-3 <= self.duration <= MAX_DURATION:
            return f"duration {self.duration} s: 0.001..{MAX_DURATION:g} s"
        if self.kind == CHIRP and not 0.0 < self.f_start < self.f_end <= nyq:
            return (
                f"chirp {self.f_start}..{self.f_end} Hz: needs 0 < start < end <= {nyq:g} Hz "
                "(half the loop rate)"
            )
        if self.kind == SINE and not 0.0 < self.f_start <= nyq:
            return f"sine {self.f_start} Hz: needs 0 < frequency <= {nyq:g} Hz"
        return None


class SignalGenerator:
    """The generator of one drive, stepped once per servo-loop tick by the engine."""

    __slots__ = (
        "_a",
        "_c",
        "_g",
        "_k",
        "_kind",
        "_lfsr",
        "_n",
        "_taps",
        "_w",
        "_x",
        "config",
        "rate_hz",
        "status",
        "value",
    )

    def __init__(self, rate_hz: float) -> None:
        self.rate_hz = float(rate_hz)
        self.status = IDLE
        #: The last sample [N m] (0 when not running).
        self.value = 0.0
        self.config: SignalConfig | None = None
        self._kind = OFF
        self._k = 0
        self._n = 0
        self._a = 0.0
        self._c = 0.0
        self._g = 1.0
        self._x = 1.0
        self._w = 0.0
        self._lfsr = 1
        self._taps = 0

    @property
    def running(self) -> bool:
        return self.status == RUNNING

    @property
    def ticks(self) -> int:
        """Ticks the running (or last) signal lasts."""
        return self._n

    def start(self, config: SignalConfig) -> None:
        """Start (or restart) with ``config``; ValueError with the reason when it cannot."""
        why = config.problem(self.rate_hz)
        if why is not None:
            raise ValueError(why)
        rate = self.rate_hz
        self.config = config
        self._kind = config.kind
        self._n = max(1, round(config.duration * rate))
        self._k = 0
        self._a = config.amplitude
        if config.kind == CHIRP:
            d = self._n / rate
            ratio = config.f_end / config.f_start
            # phase(t) = c (x(t) - 1) with x(t) = ratio^(t/D), advanced by one factor a tick.
            self._c = 2.0 * math.pi * config.f_start * d / math.log(ratio)
            self._g = ratio ** (1.0 / self._n)
            self._x = 1.0
        elif config.kind == SINE:
            self._w = 2.0 * math.pi * config.f_start / rate
        else:
            order = prbs_order(self._n)
            self._taps = PRBS_TAPS[order]
            self._lfsr = (1 << order) - 1
        self.status = RUNNING
        self.value = 0.0

    def stop(self) -> None:
        """Stop at once (status idle); the output returns to 0."""
        self.status = IDLE
        self.value = 0.0

    def next(self) -> float:
        """The sample of this tick [N m]; 0 once the signal is done."""
        if self.status != RUNNING:
            return 0.0
        k = self._k
        if k >= self._n:
            self.status = DONE
            self.value = 0.0
            return 0.0
        self._k = k + 1
        kind = self._kind
        if kind == CHIRP:
            v = self._a * math.sin(self._c * (self._x - 1.0))
            self._x *= self._g
        elif kind == SINE:
            v = self._a * math.sin(self._w * k)
        else:
            s = self._lfsr
            bit = s & 1
            s >>= 1
            if bit:
                s ^= self._taps
            self._lfsr = s
            v = self._a if bit else -self._a
        self.value = v
        return v

    def instantaneous_frequency(self, t: float) -> float:
        """The chirp's (or sine's) frequency at ``t`` seconds after the start [Hz]."""
        cfg = self.config
        if cfg is None or cfg.kind not in (CHIRP, SINE):
            return 0.0
        if cfg.kind == SINE:
            return cfg.f_start
        d = self._n / self.rate_hz
        return float(cfg.f_start * (cfg.f_end / cfg.f_start) ** (t / d))
