"""What a first run compiles, function by function, and for how long.

Run:  python benchmarks/profile_cold_start.py [--command "demo --out {tmp}/demo"] [--top 30]

Runs one dynid command in this process with empty caches (a fresh DYNID_CACHE and NUMBA_CACHE_DIR) and
listens to Numba's compile events: each compiled function's own time (its compile less the compiles it
triggered, e.g. a callee typed for the first time), wall and CPU (CPU: comparable on a loaded machine),
the number of its specialisations, and the whole run's wall and CPU time. The command's output is
dropped. The simulator's kernel compiles in a forked process while the vehicle loads
(vehicle.sim.car.prebuild_kernel), where this listener does not hear it (its CPU is in the run's, as a
child's): --in-process compiles it here instead, so that every compile is listed. `bench_cold_start.py`
times cold against warm from outside; this says where the difference goes.
Measured 2026-11-27 (`simulate sine`, a 2-core EPYC loaded ~6x, so read the CPU column): the simulator
(derivative, simulate, driver, the generated models) and the engine's inverse dynamics `_idm_kernel`
(which the rest state needs) lead; the kinematic tables, the tires and the LU solve follow.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import time
from collections import defaultdict

import numpy as np


def _cpu() -> float:
    """This process's CPU seconds and its finished children's (the kernel's prebuild)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--command", default="demo --out {tmp}/demo",
                    help="the dynid command line ({tmp}: this run's temporary folder)")
    ap.add_argument("--top", type=int, default=30)
    ap.add_argument("--in-process", action="store_true",
                    help="no kernel prebuild in another process: the simulator's kernel compiles here, and is listed")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["DYNID_CACHE"] = f"{tmp}/dynid"  # before numba and dynid are imported: both read them once
        os.environ["NUMBA_CACHE_DIR"] = f"{tmp}/numba"
        wall0, cpu0 = time.perf_counter(), _cpu()
        from numba.core import event

        own: dict[str, np.ndarray] = defaultdict(lambda: np.zeros(2))  # wall, CPU
        count: dict[str, int] = defaultdict(int)
        stack: list[list[np.ndarray]] = []  # per running compile: [start, time of the compiles it triggered]

        def now() -> np.ndarray:
            return np.array([time.perf_counter(), time.process_time()])

        class Listener(event.Listener):
            def on_start(self, ev) -> None:
                stack.append([now(), np.zeros(2)])

            def on_end(self, ev) -> None:
                start, inner = stack.pop()
                spent = now() - start
                fn = getattr(ev.data.get("dispatcher"), "py_func", None)
                name = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', '?')}"
                own[name] += spent - inner
                count[name] += 1
                if stack:
                    stack[-1][1] += spent

        event.register("numba:compile", Listener())
        from dynid.cli.main import main as dynid

        if args.in_process:  # both callers: the demo command (before its vehicle check) and simulated_car
            import dynid.pipeline.demo as demo
            import dynid.vehicle.sim.car as car

            demo.prebuild_kernel = car.prebuild_kernel = lambda: False

        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = dynid(args.command.format(tmp=tmp).split())
        wall, cpu = time.perf_counter() - wall0, _cpu() - cpu0
    if code:
        sys.exit(f"dynid {args.command} failed (exit {code})")
    total = sum(own.values(), np.zeros(2))
    print(f"dynid {args.command}: cold {wall:.1f} s wall, {cpu:.1f} s CPU; Numba compiling {total[0]:.1f} s wall, "
          f"{total[1]:.1f} s CPU ({len(own)} functions)")
    print(f"{'wall s':>7} {'CPU s':>7} {'times':>5}  function, its own compile (generated modules: dynid_simk_* the "
          "simulator's kernel, dynid_blk_* the identification's blocks)")
    for name, s in sorted(own.items(), key=lambda kv: -kv[1][1])[:args.top]:
        print(f"{s[0]:7.2f} {s[1]:7.2f} {count[name]:5d}  {name}")


if __name__ == "__main__":
    main()
