"""Every command the wheel ships runs with the wheel's dependencies (issue 50).

``servodesk bench scope`` imported httpx, a development dependency, and failed after a plain
``pip install servodesk``, and only once it reached that import. scripts/check_wheel.py (run
by ``make wheel`` on the built wheel) reads the imports of every shipped module; here the same
check runs on the sources the wheel is built from, against pyproject's dependencies, and on
small modules that show what it catches and what it lets through.
"""

from __future__ import annotations

import importlib.util
import sys
import tomllib
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]


def check_wheel() -> ModuleType:
    spec = importlib.util.spec_from_file_location("check_wheel", REPO / "scripts/check_wheel.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["check_wheel"] = module  # dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


def runtime_requires() -> list[str]:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    return list(project["dependencies"])


def test_shipped_modules_import_only_the_wheels_dependencies() -> None:
    cw = check_wheel()
    root = REPO / "backend"
    modules = [
        (str(p.relative_to(root)), p.read_text(encoding="utf-8"))
        for p in sorted((root / "servodesk").rglob("*.py"))
    ]
    foreign, uninstalled = cw.foreign_imports(modules, runtime_requires())
    assert not uninstalled, f"runtime dependencies not installed here (make setup): {uninstalled}"
    assert not foreign, "shipped modules import what the wheel does not install:\n" + "\n".join(
        str(f) for f in foreign
    )
    # The scope bench is among them (the command that failed).
    assert any(path == "servodesk/benchmarks/scope.py" for path, _ in modules)


def test_a_development_dependency_is_caught_where_a_command_would_fail() -> None:
    cw = check_wheel()
    source = """
from typing import TYPE_CHECKING

import numpy

if TYPE_CHECKING:
    from playwright.sync_api import Page  # types only: never imported at run time

try:
    import uvloop_or_not  # optional: the module works without it
except ImportError:
    uvloop_or_not = None


def bench() -> None:
    import httpx  # reached only when the command runs

    from pytest import approx
"""
    foreign, _ = cw.foreign_imports([("servodesk/x.py", source)], ["numpy>=1.26"])
    assert [(f.line, f.module) for f in foreign] == [(16, "httpx"), (18, "pytest")]
    # numpy is a runtime dependency; without it declared, its import is foreign too.
    foreign, _ = cw.foreign_imports([("servodesk/x.py", "import numpy\n")], [])
    assert [f.module for f in foreign] == ["numpy"]
