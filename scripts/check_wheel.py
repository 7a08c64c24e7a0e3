"""Check that a built wheel carries the UI and every profile (pip install + serve must work)."""

from __future__ import annotations

import sys
import zipfile
from pathlib import Path


def main(argv: list[str]) -> int:
    wheels = sorted(Path(argv[1] if len(argv) > 1 else "dist").glob("servodesk-*.whl"))
    if not wheels:
        print("check_wheel: no servodesk wheel found", file=sys.stderr)
        return 2
    names = set(zipfile.ZipFile(wheels[-1]).namelist())
    profiles = sorted(p.parent.name for p in Path("profiles").glob("*/profile.yaml"))
    required = [
        "servodesk/web/dist/index.html",
        "servodesk/web/dist/vendor/swagger-ui/swagger-ui-bundle.js",
        "servodesk/py.typed",
        *(f"servodesk/_profiles/{p}/profile.yaml" for p in profiles),
    ]
    missing = [r for r in required if r not in names]
    if missing:
        print(f"check_wheel: {wheels[-1].name} lacks {', '.join(missing)}", file=sys.stderr)
        return 1
    print(f"check_wheel: {wheels[-1].name} has the UI and {len(profiles)} profiles")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
