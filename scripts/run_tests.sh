#!/usr/bin/env bash
# The pytest suite as `make test` runs it, in two parts (tests/conftest.py, SIMTIME_DIRS).
#
# First the tests on simulated time (the tuning's searches on simulated drives: CPU-bound,
# nothing waits on the wall clock) and the pure tests on every core (pytest -n, at most 4).
# Then the rest, one test at a time: its drives, buses, servers and browsers run on the wall
# clock. The two parts
# must not overlap: run beside the first, even at nice 19, the second took 1159 s instead of
# 690 s on this project's 2-core machine and five browser tests ran out of time.
# Both parts always run; the exit status is 0 only if both passed.
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
"$pytest" -q -p no:cacheprovider -m "not simtime and not check"
rest=$?
if [ "$sim" -ne 0 ] || [ "$rest" -ne 0 ]; then
  echo "make test: failed (tests on simulated time: exit $sim; on the wall clock: exit $rest)"
  exit 1
fi
