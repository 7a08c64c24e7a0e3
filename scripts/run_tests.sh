#!/usr/bin/env bash
# The pytest suite as `make test` runs it: two parts at once (tests/conftest.py, SIMTIME_DIRS).
#
# The tests on simulated time (the tuning's searches on simulated drives: CPU-bound, nothing
# waits on the wall clock) run on every core (pytest -n, at most 4) at the lowest priority
# (nice 19). Beside them, the rest runs one test at a time at normal priority: its drives,
# buses, servers and browsers run on the wall clock and used 0.76 of a core on average, so
# the niced part takes the idle time and yields the cores whenever the rest needs them.
# The niced part's output follows the rest's. Exit status: 0 only if both parts passed.
set -uo pipefail
cd "$(dirname "$0")/.."
pytest=.venv/bin/pytest
log=$(mktemp -t servodesk-simtime-XXXXXX.log)
nice -n 19 "$pytest" -q -p no:cacheprovider -m simtime -n auto --maxprocesses 4 >"$log" 2>&1 &
simtime=$!
trap 'kill "$simtime" 2>/dev/null; rm -f "$log"' EXIT
"$pytest" -q -p no:cacheprovider -m "not simtime" "$@"
rest=$?
wait "$simtime"
sim=$?
echo
echo "--- the tests on simulated time (pytest -m simtime -n auto, niced, run alongside) ---"
cat "$log"
if [ "$rest" -ne 0 ] || [ "$sim" -ne 0 ]; then
  echo "make test: failed (tests on the wall clock: exit $rest; on simulated time: exit $sim)"
  exit 1
fi
