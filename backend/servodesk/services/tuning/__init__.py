"""Tuning of drive sessions (issue 8; docs/tuning.md).

- :mod:`.capabilities`: what a profile says about its tuning (kind, gains, units, limits).
- :mod:`.jobs`: the job lifecycle, :class:`~.jobs.TuningService` (start, stop, undo, store);
  :mod:`.records`: a job, its run, the travel bound and the result both kinds start from.
- :mod:`.builtin`: the drive's own one-touch tuning, driven by servodesk (LECSN-T).
- :mod:`.own`: servodesk's own tuning (identify, design, try, verify); :mod:`.travel` keeps its
  moves inside the travel window, :mod:`.calibrate` fits the model to its tries, :mod:`.io`
  reads and writes the drive, :mod:`.worker` runs its searches in a spawned process.

Nothing is imported here: the worker process imports this package to unpickle its jobs, and the
backend imports the own tuning's numerical stack (scipy) only with the first tuning.
"""
