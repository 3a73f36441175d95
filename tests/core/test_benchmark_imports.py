"""Every benchmark's imports resolve from the folders it puts on sys.path itself.

Benchmarks borrow test helpers (a trajectory, a robot file, the Pinocchio oracle), some of them inside functions,
and nothing else runs them: when the tests were grouped by layer, profile_car, bench_pipeline, bench_fleet,
bench_health and bench_robot_memory failed at such an import, and no test said so. Each benchmark runs here in a
child process up to its own sys.path set-up (its module level, not its main()), then every module named by an
import anywhere in its source (module or function level, child scripts in strings excluded) must be found.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
SCRIPTS = sorted(BENCHMARKS.glob("*.py"))

CHILD = """
import importlib.util, runpy, sys
path, names = sys.argv[1], sys.argv[2:]
sys.argv = [path]
runpy.run_path(path, run_name="not_main")  # its module level: imports and sys.path, not main()
missing = [n for n in names if importlib.util.find_spec(n) is None]
print(" ".join(missing))
"""


def imported_modules(source: str) -> list[str]:
    """The top-level module of every absolute import statement in `source` (at any depth of the code)."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return sorted(names - {"__future__"})


def test_the_scanner_sees_function_level_imports():
    src = "import os\ndef f():\n    from test_helper import thing\n    import numpy.linalg\n"
    assert imported_modules(src) == ["numpy", "os", "test_helper"]


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.name for p in SCRIPTS])
def test_benchmark_imports_resolve(script: Path):
    names = imported_modules(script.read_text())
    out = subprocess.run([sys.executable, "-c", CHILD, str(script), *names], capture_output=True, text=True,
                         cwd=BENCHMARKS.parent, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == [], f"{script.name}: imports not found: {out.stdout.strip()}"
