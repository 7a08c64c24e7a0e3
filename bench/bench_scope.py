"""Live scope benchmark (issue 7 "Measure"): a thin wrapper of ``servodesk bench scope``.

    python bench/bench_scope.py [--json] [--seconds 10] [--drives 4] [--clients 5] [--channels 8]

The code is servodesk/benchmarks/scope.py (inside the package, so the installed console
script runs it too).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "backend"))

from servodesk.benchmarks.scope import main

if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
