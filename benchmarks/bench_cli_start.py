"""How long the quick commands take to answer, from a fresh interpreter: `dynid --version`, `dynid --help`,
`dynid vehicle list`.

Run:  python benchmarks/bench_cli_start.py [--runs 5]

Each command runs `--runs` times as a child process (`python -m dynid.cli.main ...`, as the `dynid` script
does), imports included; the median is the figure (the first run also pays for a cold disk cache, the median
does not). Also lists which heavy libraries (numpy, scipy, numba, matplotlib, sympy) each command imported: a
command that needs none should load none. Target (issue 27): each median < 0.5 s. Writes
benchmarks/results/cli_start.json.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE)]

from results_file import write_results  # noqa: E402

COMMANDS = {"--version": ["--version"], "--help": ["--help"], "vehicle list": ["vehicle", "list"]}
HEAVY = ("numpy", "scipy", "numba", "matplotlib", "sympy")
TARGET_S = 0.5

# runs the command as the entry point does, then names the heavy libraries it imported
PROBE = f"""
import atexit, runpy, sys
# at exit: a command that ends normally ends the process in the entry point (cli.main._leave), atexit handlers run
atexit.register(lambda: print("HEAVY:", *[m for m in {HEAVY!r} if m in sys.modules], file=sys.stderr))
sys.argv = ["dynid", *sys.argv[1:]]
runpy.run_module("dynid.cli.main", run_name="__main__")
"""


def once(args: list[str]) -> float:
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "dynid.cli.main", *args], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if proc.returncode:
        sys.exit(f"dynid {' '.join(args)} failed:\n{proc.stderr[-3000:]}")
    return wall


def heavy_imports(args: list[str]) -> list[str]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True)
    line = [ln for ln in proc.stderr.splitlines() if ln.startswith("HEAVY:")]
    return line[-1].split()[1:] if line else ["?"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="runs of each command (default 5)")
    args = ap.parse_args()
    res: dict = {"cpus": os.cpu_count(), "machine": os.uname().machine, "runs": args.runs, "commands": {}}
    print(f"{'command':<20} {'median s':>9} {'min s':>7} {'max s':>7}   heavy imports (target < {TARGET_S:g} s)")
    for name, argv in COMMANDS.items():
        walls = [once(argv) for _ in range(args.runs)]
        heavy = heavy_imports(argv)
        med = statistics.median(walls)
        res["commands"][name] = {"median_s": med, "runs_s": walls, "heavy_imports": heavy}
        print(f"{'dynid ' + name:<20} {med:9.3f} {min(walls):7.3f} {max(walls):7.3f}   {' '.join(heavy) or '-'}",
              flush=True)
    write_results("cli_start", res)


if __name__ == "__main__":
    main()
