"""Check that a built wheel works after a plain ``pip install servodesk``.

Two checks, both on the wheel itself (run by ``make wheel``):

- it carries the UI (with its CJK font and the font's licence) and every profile
  (``servodesk serve`` must work);
- every module it ships imports only the standard library, servodesk, and what the wheel's
  own ``Requires-Dist`` installs (with their dependencies). A command that imports a
  development dependency (pyproject ``[dependency-groups]``, e.g. httpx or pytest) fails for
  every user, and only when it reaches that import, so this reads the imports of every module,
  function-local ones too. Optional imports are allowed: those under ``if TYPE_CHECKING:``
  and those in a ``try`` whose ``except`` catches ImportError (the module works without them).

Which installed distribution provides an import name is read from the environment this script
runs in (``importlib.metadata``), which has the runtime and the development dependencies
installed (``make setup``); a runtime dependency missing from it is reported, not guessed.
"""

from __future__ import annotations

import ast
import importlib.metadata as md
import re
import sys
import zipfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from packaging.requirements import Requirement

#: The exceptions that make an import optional when an ``except`` clause names them.
_IMPORT_ERRORS = {"ImportError", "ModuleNotFoundError", "Exception", "BaseException"}


@dataclass(frozen=True)
class ForeignImport:
    """An import of a module that the wheel's dependencies do not install."""

    path: str
    line: int
    module: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: imports {self.module}"


def _norm(name: str) -> str:
    """A distribution name as PEP 503 compares them."""
    return re.sub(r"[-_.]+", "-", name).lower()


def runtime_closure(requires: Iterable[str]) -> tuple[set[str], list[str]]:
    """The distributions that ``requires`` (Requires-Dist lines, no extras asked) install,
    with their own dependencies; and the ones not installed here (cannot be followed)."""
    seen: set[str] = set()
    missing: list[str] = []
    todo: list[tuple[Requirement, frozenset[str]]] = [
        (Requirement(r), frozenset()) for r in requires
    ]
    while todo:
        req, extras = todo.pop()
        # A dependency under `extra == "x"` counts only when its parent was asked for [x].
        if req.marker is not None and not any(
            req.marker.evaluate({"extra": e}) for e in {"", *extras}
        ):
            continue
        name = _norm(req.name)
        key = f"{name}[{','.join(sorted(req.extras))}]"
        if key in seen:
            continue
        seen.add(key)
        try:
            dist = md.distribution(req.name)
        except md.PackageNotFoundError:
            missing.append(req.name)
            continue
        asked = frozenset(req.extras)
        for sub in dist.requires or []:
            todo.append((Requirement(sub), asked))
    return {k.split("[", 1)[0] for k in seen}, missing


def importable(dists: set[str]) -> set[str]:
    """Top-level import names that these distributions provide."""
    names: set[str] = set()
    for module, owners in md.packages_distributions().items():
        if any(_norm(o) in dists for o in owners):
            names.add(module)
    return names


def _optional(tree: ast.Module) -> set[int]:
    """Ids of the import nodes that are optional (TYPE_CHECKING, or try/except ImportError)."""
    out: set[int] = set()

    def mark(nodes: Iterable[ast.stmt]) -> None:
        for n in nodes:
            for sub in ast.walk(n):
                if isinstance(sub, ast.Import | ast.ImportFrom):
                    out.add(id(sub))

    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            test = node.test
            name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
            if name == "TYPE_CHECKING":
                mark(node.body)
        elif isinstance(node, ast.Try):
            for h in node.handlers:
                caught = h.type
                names = caught.elts if isinstance(caught, ast.Tuple) else [caught]
                if h.type is None or any(
                    isinstance(c, ast.Name) and c.id in _IMPORT_ERRORS for c in names
                ):
                    mark(node.body)
                    break
    return out


def imports_of(source: str, path: str) -> Iterator[tuple[int, str]]:
    """(line, top-level module) of each import a module always needs."""
    tree = ast.parse(source, filename=path)
    optional = _optional(tree)
    for node in ast.walk(tree):
        if id(node) in optional:
            continue
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name.split(".", 1)[0]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.lineno, node.module.split(".", 1)[0]


def foreign_imports(
    modules: Iterable[tuple[str, str]], requires: Iterable[str]
) -> tuple[list[ForeignImport], list[str]]:
    """The imports among ``modules`` ((path, source) pairs) that neither the standard library,
    servodesk, nor ``requires`` provide; and the runtime requirements not installed here."""
    dists, missing = runtime_closure(requires)
    allowed = importable(dists) | set(sys.stdlib_module_names) | {"servodesk", "__future__"}
    found = [
        ForeignImport(path, line, module)
        for path, source in modules
        for line, module in imports_of(source, path)
        if module not in allowed
    ]
    return found, missing


def wheel_requires(wheel: zipfile.ZipFile) -> list[str]:
    """The wheel's Requires-Dist lines (its METADATA)."""
    meta = next(n for n in wheel.namelist() if n.endswith(".dist-info/METADATA"))
    text = wheel.read(meta).decode("utf-8")
    return [
        line.split(":", 1)[1].strip()
        for line in text.splitlines()
        if line.startswith("Requires-Dist:")
    ]


def main(argv: list[str]) -> int:
    wheels = sorted(Path(argv[1] if len(argv) > 1 else "dist").glob("servodesk-*.whl"))
    if not wheels:
        print("check_wheel: no servodesk wheel found", file=sys.stderr)
        return 2
    wheel = zipfile.ZipFile(wheels[-1])
    names = set(wheel.namelist())
    profiles = sorted(p.parent.name for p in Path("profiles").glob("*/profile.yaml"))
    required = [
        "servodesk/web/dist/index.html",
        "servodesk/web/dist/vendor/swagger-ui/swagger-ui-bundle.js",
        # The CJK names' font (issue 48) and its licence, which OFL 1.1 has travel with it.
        "servodesk/web/dist/fonts/servodesk-cjk.woff2",
        "servodesk/web/dist/fonts/OFL.txt",
        "servodesk/py.typed",
        *(f"servodesk/_profiles/{p}/profile.yaml" for p in profiles),
    ]
    missing = [r for r in required if r not in names]
    if missing:
        print(f"check_wheel: {wheels[-1].name} lacks {', '.join(missing)}", file=sys.stderr)
        return 1
    modules = [
        (n, wheel.read(n).decode("utf-8"))
        for n in sorted(names)
        if n.startswith("servodesk/") and n.endswith(".py")
    ]
    foreign, uninstalled = foreign_imports(modules, wheel_requires(wheel))
    if uninstalled:
        print(
            "check_wheel: cannot follow the dependencies of "
            f"{', '.join(sorted(set(uninstalled)))}: not installed here (run make setup)",
            file=sys.stderr,
        )
        return 1
    if foreign:
        print(
            f"check_wheel: {wheels[-1].name} ships modules that import what its dependencies "
            "do not install (a development dependency?); use a runtime dependency or the "
            "standard library, or do not ship the module:",
            file=sys.stderr,
        )
        for f in foreign:
            print(f"  {f}", file=sys.stderr)
        return 1
    print(
        f"check_wheel: {wheels[-1].name} has the UI and {len(profiles)} profiles; its "
        f"{len(modules)} modules import only the standard library and its dependencies"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
