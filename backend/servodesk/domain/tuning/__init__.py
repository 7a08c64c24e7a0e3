"""Servo tuning analysis: the cascade model, identification, gain design, metrics, oracle.

Pure domain code (numpy and scipy only; no simulator, links, services or API imports), used by
the tuning service on real and simulated drives and by the tuning benchmark:

- ``gains``: :class:`ServoGains`, the canonical SI gain set of docs/tuning.md;
- ``filters``: the drive's low-pass / notch biquads (pure Python: the simulator imports it);
- ``model``: :class:`PlantModel`, :class:`LoopModel` (frequency responses, margins, stability,
  linear simulation of the discrete cascade);
- ``identify``: inertia / friction least squares, closed-loop FRF, resonances;
- ``design``: :func:`design_gains`, filters and gains from an identified model;
- ``metrics``: the benchmark move and its settling / following-error metrics;
- ``oracle``: :func:`oracle_search`, the reference tuning with exact plant knowledge.

Only ``gains`` and ``filters`` are imported here, so that ``from servodesk.domain.tuning import
ServoGains`` stays cheap (no numpy / scipy import) for the simulated drive.
"""

from servodesk.domain.tuning.filters import lowpass_coefficients, notch_coefficients
from servodesk.domain.tuning.gains import ServoGains

__all__ = ["ServoGains", "lowpass_coefficients", "notch_coefficients"]
