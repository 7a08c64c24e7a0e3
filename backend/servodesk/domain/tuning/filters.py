"""Coefficients of the drive's discrete torque-command filters (low-pass and notch).

The drive implements each filter as one biquad (docs/tuning.md, "The servo loop"):
``y[k] = b0 x[k] + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]`` (scipy's sign convention,
``a0 = 1``), obtained from the continuous prototype by the bilinear transform with pre-warping
at the corner / centre frequency, so that the discrete filter has exactly the prototype's gain
there (a low-pass is -3 dB at its corner, a notch has gain ``depth`` at its centre).

Pure standard library so that the simulated drive can import it without numpy; the frequency
response of a biquad is in ``model.py``.
"""

from __future__ import annotations

import math

#: (b0, b1, b2, a1, a2) of one biquad, ``a0 = 1``.
Biquad = tuple[float, float, float, float, float]

#: The pass-through biquad (a filter switched off).
IDENTITY: Biquad = (1.0, 0.0, 0.0, 0.0, 0.0)


def _prewarp(freq_hz: float, rate_hz: float, what: str) -> float:
    """``tan(w T / 2)`` of the bilinear transform pre-warped at ``freq_hz``."""
    if rate_hz <= 0.0:
        raise ValueError(f"loop rate must be positive, not {rate_hz}")
    if not 0.0 < freq_hz < 0.5 * rate_hz:
        raise ValueError(
            f"{what} frequency {freq_hz} Hz must be above 0 and below the Nyquist frequency "
            f"{0.5 * rate_hz} Hz"
        )
    return math.tan(math.pi * freq_hz / rate_hz)


def lowpass_coefficients(freq_hz: float, rate_hz: float) -> Biquad:
    """First-order low-pass ``w / (s + w)`` as a biquad (b2 = a2 = 0); 0 Hz: pass-through.

    With ``s = K (1 - z^-1) / (1 + z^-1)``, ``K = w / tan(w T / 2)`` (pre-warped) and
    ``t = tan(w T / 2)``: ``H(z) = t (1 + z^-1) / ((1 + t) + (t - 1) z^-1)``.
    """
    if freq_hz == 0.0:
        return IDENTITY
    t = _prewarp(freq_hz, rate_hz, "low-pass")
    b = t / (1.0 + t)
    return (b, b, 0.0, (t - 1.0) / (1.0 + t), 0.0)


def notch_coefficients(freq_hz: float, width: float, depth: float, rate_hz: float) -> Biquad:
    """Notch ``(s^2 + 2 d z w s + w^2) / (s^2 + 2 z w s + w^2)`` as a biquad; 0 Hz: pass-through.

    ``w = 2 pi f``, ``z = width / 2`` (width = -3 dB bandwidth / f of the full-depth prototype)
    and ``d = depth`` (gain at the centre, 0 = full notch). Bilinear transform pre-warped at the
    centre: with ``q = 1 / tan(w T / 2)`` (that is ``K / w``) the numerator is
    ``(q^2 + 2 d z q + 1) + 2 (1 - q^2) z^-1 + (q^2 - 2 d z q + 1) z^-2`` and the denominator
    the same with ``d = 1``, both divided by the denominator's leading term.
    """
    if freq_hz == 0.0:
        return IDENTITY
    if width <= 0.0:
        raise ValueError(f"notch width must be positive, not {width}")
    if not 0.0 <= depth <= 1.0:
        raise ValueError(f"notch depth must be within 0..1, not {depth}")
    q = 1.0 / _prewarp(freq_hz, rate_hz, "notch")
    zeta = 0.5 * width
    q2 = q * q
    a0 = q2 + 2.0 * zeta * q + 1.0
    b0 = (q2 + 2.0 * depth * zeta * q + 1.0) / a0
    b1 = 2.0 * (1.0 - q2) / a0
    b2 = (q2 - 2.0 * depth * zeta * q + 1.0) / a0
    a2 = (q2 - 2.0 * zeta * q + 1.0) / a0
    return (b0, b1, b2, b1, a2)
