"""pyproject.toml declares what the code imports, and imports what it declares.

Every third-party top-level module imported anywhere in ``bench/`` (lazy imports in
functions included) belongs to a distribution in ``[project] dependencies``, and every
runtime dependency is imported somewhere in ``bench/``; what ``tests/`` and
``benchmarks/`` import is declared at run time or in the ``test`` extra. Imports are
read with :mod:`ast`, module names mapped to distributions with
:func:`importlib.metadata.packages_distributions` (the installed environment).
"""

from __future__ import annotations

import ast
import importlib.metadata as md
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OWN = {"bench", "tests", "benchmarks", "__future__"}
#: third-party modules bench/ may import without declaring them, and the one file that may
PLUGIN_ONLY = {"pytest": "bench/pytest_plugin.py"}  # loaded by pytest itself (entry point pytest11)


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement(req: str) -> tuple[str, set[str]]:
    """``(normalized name, extras)`` of a requirement string such as ``python-can[multicast]>=4.3``."""
    m = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*(?:\[([^\]]*)\])?", req)
    assert m, req
    return _norm(m.group(1)), {e.strip() for e in (m.group(2) or "").split(",") if e.strip()}


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _imports(folder: str) -> dict[str, set[str]]:
    """Third-party top-level module -> files of ``folder`` importing it (a script's sibling
    module, found on the script's own directory, is no third party)."""
    found: dict[str, set[str]] = {}
    for f in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                own = top in OWN or (f.parent / f"{top}.py").is_file()
                if top not in sys.stdlib_module_names and not own:
                    found.setdefault(top, set()).add(str(f.relative_to(ROOT)))
    return found


def _distributions(module: str) -> set[str]:
    dists = md.packages_distributions().get(module)
    assert dists, f"{module!r} is imported but no installed distribution provides it"
    return {_norm(d) for d in dists}


def test_bench_imports_exactly_its_runtime_dependencies():
    runtime = dict(_requirement(r) for r in _project()["dependencies"])
    used: set[str] = set()
    for module, files in _imports("bench").items():
        if module in PLUGIN_ONLY:
            assert files == {PLUGIN_ONLY[module]}, f"{module} imported outside {PLUGIN_ONLY[module]}: {files}"
            continue
        dists = _distributions(module)
        assert dists & runtime.keys(), f"{module} ({', '.join(sorted(files))}) is not declared: {sorted(dists)}"
        used |= dists
    unused = sorted(set(runtime) - used)
    assert not unused, f"declared but never imported in bench/: {unused}"


def test_udp_multicast_needs_python_can_with_its_multicast_extra():
    runtime = dict(_requirement(r) for r in _project()["dependencies"])
    assert "udp_multicast" in (ROOT / "bench" / "transport" / "udp.py").read_text()
    assert "multicast" in runtime["python-can"], "udp_multicast packs messages with msgpack: python-can[multicast]"


def test_tests_and_benchmarks_import_only_what_is_declared():
    project = _project()
    declared = {_requirement(r)[0] for r in project["dependencies"]}
    test_extra = {_requirement(r)[0] for r in project["optional-dependencies"]["test"]}
    for folder in ("tests", "benchmarks"):
        for module, files in _imports(folder).items():
            dists = _distributions(module)
            assert dists & (declared | test_extra), f"{module} ({sorted(files)[0]}...) is not declared"
    assert "pynmea2" in test_extra and "pynmea2" not in declared  # the tests' NMEA reference, not the bench's
    assert "zstandard" not in declared  # mcap brings the compression it needs
