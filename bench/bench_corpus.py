"""Import every real vendor device description of the shared corpus; export and re-import it.

The corpus (``../shared/corpus`` beside the repository: ESI, EDS/DCF, XDD files as vendors
publish them, see its README.md and SOURCES.tsv) is read in place, never copied. Per file:
import (with the warnings of what was left out), the profile consistency check, export in the
fieldbus's format and re-import to the same profile, and the time each took.

    python bench/bench_corpus.py [--json] [--corpus DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path
from typing import Any

from servodesk import devdesc
from servodesk.devdesc.roundtrip import export_again, first_difference
from servodesk.domain.profile_loader import check_profile
from servodesk.errors import ServodeskError

REPO = Path(__file__).resolve().parent.parent
DEFAULT_CORPUS = REPO.parent / "shared" / "corpus"


def corpus_files(corpus: Path) -> list[Path]:
    """The device descriptions of the corpus (files servodesk has a reader for)."""
    return sorted(
        p
        for p in corpus.rglob("*")
        if p.is_file() and p.suffix.lower() in devdesc.SUPPORTED_SUFFIXES
    )


def vendors(corpus: Path) -> dict[str, str]:
    """saved_name -> vendor, from SOURCES.tsv."""
    path = corpus / "SOURCES.tsv"
    if not path.exists():
        return {}
    with path.open(encoding="utf-8") as fh:
        return {row["saved_name"]: row["vendor"] for row in csv.DictReader(fh, delimiter="\t")}


def measure(path: Path, corpus: Path, vendor: str) -> dict[str, Any]:
    rel = path.relative_to(corpus).as_posix()
    row: dict[str, Any] = {"file": rel, "vendor": vendor, "ok": False}
    t0 = time.perf_counter()
    try:
        result = devdesc.read_file(path)
    except ServodeskError as exc:
        row.update(error=str(exc), import_s=time.perf_counter() - t0)
        return row
    p = result.profile
    t1 = time.perf_counter()
    _, back = export_again(p)
    t2 = time.perf_counter()
    diff = first_difference(p.model_dump(), back.model_dump())
    problems = check_profile(p)
    row.update(
        ok=diff is None and not problems,
        fieldbus=p.fieldbus,
        pdo_kind=p.pdo.kind,
        objects=len(p.objects),
        variables=len(p.variables),
        warnings=len(result.warnings),
        problems=problems[:3],
        roundtrip=diff or "same",
        import_s=round(t1 - t0, 4),
        roundtrip_s=round(t2 - t1, 4),
    )
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="machine-readable output")
    ap.add_argument("--corpus", type=Path, default=DEFAULT_CORPUS, help="the corpus folder")
    args = ap.parse_args(argv)
    corpus: Path = args.corpus
    if not corpus.is_dir():
        print(f"bench_corpus: error: no corpus at {corpus}", file=sys.stderr)
        hint = "the shared corpus sits beside the repository (../shared/corpus)"
        print(f"  hint: {hint}", file=sys.stderr)
        return 2
    names = vendors(corpus)
    rows = [
        measure(p, corpus, names.get(p.relative_to(corpus).as_posix(), "?"))
        for p in corpus_files(corpus)
    ]
    ok = sum(1 for r in rows if r["ok"])
    summary = {
        "files": len(rows),
        "imported": ok,
        "success_rate": round(ok / len(rows), 4) if rows else 0.0,
        "import_s_total": round(sum(r["import_s"] for r in rows), 3),
        "import_s_max": round(max((r["import_s"] for r in rows), default=0.0), 4),
    }
    if args.json:
        json.dump({"summary": summary, "files": rows}, sys.stdout, indent=2)
        sys.stdout.write("\n")
        return 0 if ok == len(rows) else 1
    print(f"{'file':44} {'vendor':28} {'objs':>5} {'warn':>4} {'import':>8}  round trip")
    for r in rows:
        if "objects" not in r:
            print(f"{r['file']:44} {r['vendor'][:28]:28}  FAILED: {r['error']}")
            continue
        print(
            f"{r['file']:44} {r['vendor'][:28]:28} {r['objects']:>5} {r['warnings']:>4} "
            f"{r['import_s'] * 1000:>6.0f}ms  {r['roundtrip']}"
        )
    print(
        f"{ok}/{len(rows)} import, pass the profile check and re-import to the same profile "
        f"({summary['success_rate']:.0%}); import time total {summary['import_s_total']} s, "
        f"slowest {summary['import_s_max']} s"
    )
    return 0 if ok == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
