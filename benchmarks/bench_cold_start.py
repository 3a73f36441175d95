"""A new user's first commands: each one cold (empty compile caches) and warm.

Run:  python benchmarks/bench_cold_start.py [--commands demo simulate identify]

Each command runs as a child process, as a user types it, twice:
- cold: with empty DYNID_CACHE and NUMBA_CACHE_DIR, so everything the command needs is
  generated and compiled (the simulator's models, the engine, the block kernels);
- warm: again, with the caches the cold run filled.

The commands:
- demo: `dynid demo` (the six tests simulated and identified, the report written);
- simulate: `dynid simulate sine` (one test);
- identify: `dynid identify` on the demo's files and config, with its own fresh caches, so
  only what the identification compiles is counted.

The time is each child's wall time, imports included, and the ratio cold / warm. Targets: a cold
`dynid demo` <= 40 s, a warm one <= 15 s (issue 16); cold <= 1.3 x warm (issue 28). On a first run the
simulator's kernel compiles in a forked process (vehicle.sim.car.prebuild_kernel): what that buys
depends on a second core being free, so read the ratio of a quiet machine. Writes
benchmarks/results/cold_start.json.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE)]

from results_file import write_results  # noqa: E402

TARGETS = {"demo": (40.0, 15.0)}
RATIO = 1.3  # cold / warm, issue 28


def timed(args: list[str], caches: Path, cwd: Path) -> float:
    env = {**os.environ, "DYNID_CACHE": str(caches / "dynid"), "NUMBA_CACHE_DIR": str(caches / "numba")}
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "dynid.cli.main", *args], cwd=cwd, env=env, capture_output=True,
                          text=True)
    wall = time.perf_counter() - t
    if proc.returncode:
        sys.exit(f"dynid {' '.join(args)} failed:\n{proc.stderr[-3000:]}")
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commands", nargs="+", default=["demo", "simulate", "identify"],
                    choices=["demo", "simulate", "identify"])
    args = ap.parse_args()
    res: dict = {"cpus": os.cpu_count(), "machine": os.uname().machine, "commands": {}}
    print(f"{'command':<40} {'cold s':>8} {'warm s':>8} {'ratio':>6}   target (cold, warm, ratio)")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        lines = {
            "demo": ["demo", "--out", str(work / "demo")],
            "simulate": ["simulate", "sine", "--out", str(work / "sine.csv")],
            "identify": ["identify", str(work / "demo" / "identify.toml"), "--out", str(work / "identified")],
        }
        order = [c for c in ("demo", "simulate", "identify") if c in args.commands]
        if "identify" in order and "demo" not in order:  # its files come from a demo run (not timed)
            timed(lines["demo"], work / "caches-setup", work)
        for name in order:
            caches = work / f"caches-{name}"
            cold = timed(lines[name], caches, work)
            warm = timed(lines[name], caches, work)
            res["commands"][name] = {"cold_s": cold, "warm_s": warm, "ratio": cold / warm}
            target = TARGETS.get(name)
            text = f"<= {target[0]:g} s, <= {target[1]:g} s, <= {RATIO:g}" if target else "-"
            shown = {"demo": "dynid demo", "simulate": "dynid simulate sine",
                     "identify": "dynid identify demo/identify.toml"}[name]
            print(f"{shown:<40} {cold:8.1f} {warm:8.1f} {cold / warm:6.2f}   {text}", flush=True)
    write_results("cold_start", res)


if __name__ == "__main__":
    main()
