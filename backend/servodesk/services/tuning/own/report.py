"""The own tuning's result (docs/tuning.md ``TuningResult``): what was identified, the Bode plot
of the measurement and the model, the margins, the gains before and after, both verification
moves, the travel, the notes; the refusal of gains that moved the axis worse than before; the
result as JSON allows it (services/tuning/own)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from servodesk.domain.cia402 import SOFT_LIMIT_MAX, SOFT_LIMIT_MIN
from servodesk.domain.tuning.gains import ServoGains
from servodesk.domain.tuning.identify import model_damping
from servodesk.domain.tuning.model import LoopModel, PlantModel
from servodesk.domain.tuning.search import SearchResult
from servodesk.services.tuning.own.base import Drive, TuningFailed
from servodesk.services.tuning.own.identify import Identified
from servodesk.services.tuning.own.tries import Tries


class Report(Tries):
    """The result of a tuning that ended with new gains."""

    def _travel_result(self, drive: Drive) -> dict[str, Any]:
        """The bound and how far the axis went from the start, from the drive's recordings of
        every move (its position at the loop rate, or a divider of it on long records)."""
        g = self.guard
        b = drive.bound
        reach = max(-g.lowest, g.highest)
        return {
            **b.as_dict(drive.counts_per_rev),
            "lowest": round(b.start + g.lowest),
            "highest": round(b.start + g.highest),
            "max_excursion": round(reach),
            "max_excursion_rev": reach / drive.counts_per_rev,
            "software_limits": self._writable(SOFT_LIMIT_MIN) and self._writable(SOFT_LIMIT_MAX),
        }

    def _travel_notes(self, drive: Drive) -> list[str]:
        g = self.guard
        cpr = drive.counts_per_rev
        reach = max(-g.lowest, g.highest)
        out = [
            f"the axis went at most {reach / cpr:.4g} rev ({reach:.0f} counts) from where it "
            f"stood, within ±{drive.bound.half / cpr:.4g} rev ({drive.bound.half} counts)"
        ]
        if g.surprises:
            worst = max(g.surprises, key=lambda s: s[1] - s[0])
            out.append(
                f"{len(g.surprises)} move(s) ran on past their target further than foretold "
                f"(worst {worst[1]:.0f} counts against {worst[0]:.0f}); what followed was "
                f"sized by what they showed"
            )
        return out

    def _result(
        self,
        drive: Drive,
        before: ServoGains,
        design: SearchResult,
        ident: Identified,
        model: PlantModel,
        step_before: dict[str, Any],
        step_after: dict[str, Any],
    ) -> dict[str, Any]:
        """The job's result (docs/tuning.md ``TuningResult``): what ``ident`` found (with the
        Coulomb friction the frequency response's slow travel measured, None where it gave
        none, and the one the ranking's model took), the gains of ``design`` on ``model``."""
        est, cruise_rad_s, resonances, frf = (
            ident.est,
            ident.cruise_rad_s,
            ident.resonances,
            ident.frf,
        )
        travel_friction, ranking_friction = ident.travel_friction, ident.friction
        new = design.gains
        gains = []
        b, a = before.as_dict(), new.as_dict()
        for name, g in self.spec.gains.items():
            gains.append(
                {
                    "name": name,
                    "object": g.object,
                    "unit": g.unit,
                    "before": b[name],
                    "after": a[name],
                    "raw_before": b[name] / g.scale,
                    "raw_after": a[name] / g.scale,
                }
            )
        loop = LoopModel(model, drive.rate_hz, new)
        w = 2.0 * math.pi * frf.f_hz
        # The identified plant as the recorder measures it: the mechanics behind the drive's
        # current loop (2109h), the command held over each period and the velocity read at its
        # end (the twin's 606Ch is the plant's velocity after each step, not a differenced
        # encoder, so no loop delay). The mechanics alone were 15 dB above the generic twin's
        # measurement at its 2 kHz Nyquist frequency (docs/tuning.md, "Bode plot").
        g_model = model.sampled_velocity_response(w, drive.rate_hz)
        jm = model.motor_inertia
        return {
            "kind": "gains",
            "status": "done",
            "error": None,
            "mode": self.request.mode,
            "identified": {
                "inertia_kgm2": est.inertia,
                "inertia_ratio": (est.inertia - jm) / jm if model.resonance_hz else None,
                "coulomb_nm": est.coulomb,
                "viscous_nms": est.viscous,
                # What the moves measured: their friction at their cruise speed, c + b v. They
                # run at one speed, where the fit cannot tell c from b (it may trade them to a
                # negative b); the sum is what it measured.
                "moves_friction_nm": est.coulomb + est.viscous * cruise_rad_s,
                "moves_speed_rad_s": cruise_rad_s,
                "gravity_nm": est.gravity,
                # The Coulomb friction the frequency response's slow travel measured (the
                # moves' c and b come from one brisk speed); None where it gave none.
                "travel_friction_nm": travel_friction,
                # The one the ranking's model took: the travel's, or the moves' c + b v at
                # their cruise speed (c alone below a low anti-resonance).
                "ranking_friction_nm": ranking_friction,
                "resonances": [
                    {
                        "freq_hz": r.freq_hz,
                        "anti_freq_hz": r.anti_freq_hz,
                        "peak_db": r.peak_db,
                        # The damping the design used (plant_from_identification's rule).
                        "damping": model_damping(r.damping_estimate),
                    }
                    for r in resonances
                ],
                # The inertias the winner's try fitted and what came of it (:meth:`_redesign`):
                # None where no try was fitted (a rigid axis ranked on the instrumented inertia,
                # a response that did not show the anti-resonance, the basic and low levels, no
                # axis time left).
                "refit": self._refit,
            },
            "bode": {
                "freq_hz": _round(frf.f_hz),
                "measured_mag_db": _round(20.0 * np.log10(np.abs(frf.g))),
                "measured_phase_deg": _round(np.degrees(np.angle(frf.g))),
                "coherence": _round(frf.coherence),
                "model_mag_db": _round(20.0 * np.log10(np.abs(g_model))),
                "model_phase_deg": _round(np.degrees(np.angle(g_model))),
            },
            "margins": {
                "phase_margin_deg": design.margins.phase_margin_deg,
                "gain_margin_db": design.margins.gain_margin_db,
                "crossover_hz": design.margins.crossover_hz,
                "bandwidth_hz": design.bandwidth_hz,
            },
            "notes": [
                *design.notes,
                *self._notes,
                *self._travel_notes(drive),
                f"gains ranked for a 0.5 rev move accelerating at 70 % of "
                f"{100.0 * drive.move_torque / drive.rated_torque:.0f} % of the rated torque "
                + (
                    "(the machine's move torque given)"
                    if self.request.move_torque_pct is not None
                    else "(the tuning's torque limit: give the machine's move torque to tune "
                    "for its moves)"
                ),
            ],
            "gains": gains,
            "step": {"before": step_before, "after": step_after},
            "axis_time_s": self.axis_time_s,
            "excursion_rev": self.excursion[1] - self.excursion[0],
            "travel": self._travel_result(drive),
            "peak_torque_pct": 100.0 * self.peak_torque / drive.rated_torque,
            # From the drive's recordings of every test move, tick by tick: not polled.
            "peak_torque_polled_s": None,
            "loop_rate_hz": drive.rate_hz,
            "counts_per_rev": drive.counts_per_rev,
            "applied": True,
            "stored": False,
            "_loop": loop,
        }


#: A verification move that does not settle and overshoots this many times as far as the


#: one with the previous gains means the new gains are worse, whatever the model said ...
WORSE_OVERSHOOT = 1.25
#: ... when its overshoot matters at all (a share of the move): a slow axis that crept in
#: without overshoot before must not fail the tuning over a few counts past the target now.
WORSE_OVERSHOOT_MIN = 0.05


def refuse_if_worse(before: dict[str, Any], after: dict[str, Any]) -> None:
    """Raise :class:`TuningFailed` when the new gains moved the axis worse than the old ones:
    the verification move did not settle to +-100 counts where it did before, or it settled
    neither time and overshot :data:`WORSE_OVERSHOOT` times as far (and more than
    :data:`WORSE_OVERSHOOT_MIN` of the move). The model behind the
    gains was then not the machine (stress-soft60Hz: an anti-resonance at 11 Hz, below the
    frequency response's 20 Hz, left the tuner with the motor's inertia alone; its gains had
    6 deg of phase margin on the real axis and overshot 71 % of the move, the factory gains
    28 %)."""
    b, a = before["metrics"], after["metrics"]
    if math.isfinite(a["settling_100_s"]):
        return
    if math.isfinite(b["settling_100_s"]):
        raise TuningFailed(
            "the verification move did not settle to +-100 counts with the new gains (it did "
            f"with the previous ones in {1e3 * b['settling_100_s']:.0f} ms); "
            "the previous gains are back",
            hint="tune with a lower response level",
        )
    if a["overshoot"] > max(WORSE_OVERSHOOT * b["overshoot"], WORSE_OVERSHOOT_MIN):
        raise TuningFailed(
            "the new gains moved the axis worse than the previous ones: the verification move "
            f"overshot {100.0 * a['overshoot']:.0f} % of its distance, against "
            f"{100.0 * b['overshoot']:.0f} % before, and settled neither time; "
            "the previous gains are back",
            hint="the axis may have a resonance below 20 Hz that the frequency response "
            "cannot measure (a long belt, a soft coupling to a heavy load): tune it by hand, "
            "starting from low gains",
        )


def json_safe(x: Any) -> Any:
    """The result as JSON allows it: a figure that is not finite (a move that did not settle
    in the observation window, a following error without a demand) becomes null."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.floating):
        return json_safe(float(x))
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    return x


def _round(x: np.ndarray) -> list[float]:
    return [round(float(v), 4) if math.isfinite(float(v)) else 0.0 for v in x]
