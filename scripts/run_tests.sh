#!/usr/bin/env bash
# The pytest suite as `make test` runs it, in three parts (tests/conftest.py).
#
# First the tests on simulated time (the tuning's searches on simulated drives: CPU-bound,
# nothing waits on the wall clock) and the pure tests on every core (pytest -n, at most 4).
# Then the tests on the wall clock that are safe two at a time (-m shared: one test file per
# worker; the twins of a fixed port share one worker, SERIAL_PATHS' comment). Last those
# that must run alone (-m serial): they time something, run a browser or hold a fixed
# resource. The parts must not overlap: run beside the first, even at nice 19, the wall-clock
# tests took 1159 s instead of 690 s on this project's 2-core machine and five browser tests
# ran out of time.
# Every part always runs; the exit status is 0 only if all passed.
set -uo pipefail
cd "$(dirname "$0")/.."
pytest=.venv/bin/pytest
# Only those directories are collected for the first part (collecting the whole suite takes
# 20 s here, in each worker); the list is the one tests/conftest.py marks by.
# The pure tests of `make check` (CHECK_PATHS: no bus, no server, no wall clock) run there
# too: they share nothing, and serially they took about a minute of the second part.
simtime_dirs=$(.venv/bin/python -c "from tests.conftest import SIMTIME_DIRS, CHECK_PATHS; print(*SIMTIME_DIRS, *CHECK_PATHS)") || exit 1
# shellcheck disable=SC2086 # the directories are words
"$pytest" -q -p no:cacheprovider -m "simtime or check" -n auto --maxprocesses 4 $simtime_dirs
sim=$?
"$pytest" -q -p no:cacheprovider -m "shared" -n 2 --dist loadgroup
shared=$?
"$pytest" -q -p no:cacheprovider -m "serial"
serial=$?
if [ "$sim" -ne 0 ] || [ "$shared" -ne 0 ] || [ "$serial" -ne 0 ]; then
  echo "make test: failed (on simulated time: exit $sim; on the wall clock two at a time:" \
    "exit $shared; alone: exit $serial)"
  exit 1
fi
