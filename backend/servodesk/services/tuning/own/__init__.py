"""servodesk's own one-touch tuning: identify, measure, design, verify (docs/tuning.md).

For a drive whose profile maps its servo gains (``tuning.kind: gains``). The steps, each a few
hundred milliseconds of axis motion inside the travel window the user confirmed:

1. Frequency response: a PRBS torque from the drive's test signal generator while the axis
   travels at a constant speed; the recorder captures the test signal, the torque command and
   the velocity at the loop rate; the plant's response is their instrumental estimate
   (domain/tuning/identify.py). Resonances come from its peaks over the rigid-body line.
2. Inertia and friction: back-and-forth profile-position moves, sized from the first estimate so
   that the inertial torque is about a third of the tuning torque limit and the acceleration
   phases last several periods of the lowest anti-resonance (anchors-tuning.md §3.7: faster
   moves identify the motor, not the machine); least squares on torque against acceleration.
   A resonance without an anti-resonance in the band has it below: the moves are sized for
   the band's lowest frequency, and their inertia places it (identify.py).
3. Before: the drive's gains as they are, a verification move sized for the inertia found,
   recorded by the drive-side recorder (the "before" step response).
4. Design: the identified two-mass model, notches where a resonance limits the loop, the
   highest velocity gain meeting PM >= 45 deg, GM >= 8 dB, Ms <= 6 dB (domain/tuning/design.py)
   scaled to the response level; then the candidates near it ranked by what they do to a move
   on the identified model (settling to +-10 counts, then +-100 counts, then following error),
   the same objective as the benchmark's oracle (domain/tuning/search.py).
5. Apply and verify: the new gains are written, the verification move runs again (the "after"
   step response); a result that does not settle or is worse than before is undone.

Safety (issue 8 §7): during tuning the torque limit 6072h is the user's and the following error
window 6065h is widened (the low default gains of an untuned axis lag far behind a brisk
identification move). The travel window W the user confirms is a total width centred on where
the axis stands: every move is planned so that its set-points, the loop's overshoot past them and
a stop's run-out stay within start +- W/2 (services/tuning/travel.py), and the drive's own
software position limits 607Dh are set there before the first move (CiA 402-2 §6.5.4), with the
quick-stop deceleration 6085h raised to each move's own so that a dead-man stop brakes no
gentler than the move. All of them, the mode and every gain are put back when the tuning ends,
fails or is cancelled (stop, dead-man), once the axis has stopped; the new gains stay only after
a successful verification, and nothing is stored to non-volatile memory unless the user asks
(POST .../tuning/store).

The procedure is one class, :class:`OwnTuning`, made of one part per phase (since 2026-12-07,
issue 51 item 3; before, one module, services/tuning/own.py, held all of it in 2,414 lines).
Each part is a class that builds on the one before it and may call it, as
services/motion/ and sim/engine are built; they share one run's state (:class:`base.TuningBase`):

- ``base.py``: the request, what is learnt of the drive (:class:`base.Drive`), the run's state,
  the gains read and written, the design worker's boundary (``_compute``, ``_search``).
- ``safety.py``: the drive learnt, the settings saved, set and given back, coming to rest.
- ``moves.py``: each move planned against the travel bound, sent, recorded and observed.
- ``frf.py``: the frequency response, its resonances and the record fits.
- ``identify.py``: the test moves, and which estimate of the inertia and friction is taken
  (:class:`identify.Identified`, what the design ranks on).
- ``design.py``: the friction the ranking takes, the gain search, the search again on the
  tries' fit.
- ``tries.py``: the verification moves and the tries of the winner and runners-up on the axis.
- ``report.py``: the result, the refusal of worse gains, JSON-safe figures.
- ``procedure.py``: :class:`OwnTuning` and its :meth:`~OwnTuning.run`, the phases in order;
  :func:`run_own_tuning` for a session.

Every search and fit runs in the design worker through ``TuningBase._compute`` (services/tuning/
worker.py): on the event loop they would hold the operator's heartbeats past the dead-man's
period. No job handed to the worker is defined in this package (the worker would import all of
it, and the session behind it, to unpickle one). Importing the package imports every part, with
the numerical stack: services/tuning/jobs.py does so in a thread on the first tuning, so that
nothing of it is imported later on the event loop.
"""

from servodesk.services.tuning.own.base import OwnTuningRequest, TuningFailed
from servodesk.services.tuning.own.procedure import OwnTuning, run_own_tuning

__all__ = ["OwnTuning", "OwnTuningRequest", "TuningFailed", "run_own_tuning"]
