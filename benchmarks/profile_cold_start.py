"""What a first run compiles, function by function, and for how long.

Run:  python benchmarks/profile_cold_start.py [--command "demo --out {tmp}/demo"] [--top 30]

Runs one dynid command in this process with empty caches (a fresh DYNID_CACHE and NUMBA_CACHE_DIR) and
listens to Numba's compile events: each compiled function's own time (its compile less the compiles it
triggered, e.g. a callee typed for the first time), wall and CPU (CPU: comparable on a loaded machine),
the number of its specialisations, and the whole run's wall and CPU time. The command's output is
dropped. The simulator's kernel compiles in a forked process while the vehicle loads
(vehicle.sim.car.prebuild_kernel), where this listener does not hear it (its CPU is in the run's, as a
child's): --in-process compiles it here instead, so that every compile is listed. A first demo's identification
compiles in a forked child too (pipeline.first_run.WarmUp, started with the kernel's build), unheard likewise:
--in-process starts none (no kernel build to wait for), so the identification compiles here, at its first call.
`bench_cold_start.py` times cold against warm from outside; this says where the difference goes.
--phases splits the compiles' CPU by Numba's steps (typing, lowering, entry points, LLVM).
Measured 2026-11-27 (`simulate sine`, a 2-core EPYC loaded ~6x, so read the CPU column): the simulator
(derivative, simulate, driver, the generated models) and the engine's inverse dynamics `_idm_kernel`
(which the rest state needs) lead; the kinematic tables, the tires and the LU solve follow.
Measured 2026-11-29 (`demo --in-process --phases`, 2-core Xeon loaded 1-5x, own CPU s of a compile): of
24.8-27.6 s of CPU, Numba compiles 15.1-15.4 s: the simulator's kernel ~6.5 (derivative 2.7-3.1, driver
1.1, simulate 1.0, lu_solve 0.5-0.6, eval_table 0.6, magic_formula 0.4, reduced_inertia 0.3, the
manoeuvres' helpers 0.5), `_idm_kernel` 2.6-2.9 (with `_sincos`, `_mul`, `_mul_t`, `_cross` 0.4), the
identification's 3.4 (`_table_joints` 0.7-0.8, zero-phase filters 1.3-1.5, `_corners_compiled` 0.4, the
block kernel's `run` 0.8), NumPy's allocations (np.zeros, np.empty: compiled per caller's flags, 19
times) 0.7. By step: typing 4.1, Numba's lowering 3.3, LLVM 6.1 (functions 2.4; linking, module
optimisation, machine code 3.7: a callee's code is optimised and emitted in its own library, then again
in each caller's that links it), entry points 0.5. Every function compiles for one signature (a
dispatcher's `signatures` after the demo) but `blocks._data_address` (3, 0.16 s): no duplicate compiles.
Timeline of a cold demo (kernel in its forked process, machine loaded ~4x): the parent's compiles
(`_table_joints`, `_idm_kernel`, then the identification's while it would wait) are the critical path; the
kernel's build (8.4 s of CPU) had ended before the parent asked for it.
Then (branch h-cold3): the kernel's helpers without entry points (numba_backend.compile_source's `internal`)
and a trivial compile first in the kernel's build process (car._start_numba): --phases 14.4 s of compiles,
entry points 0.46 -> 0.16 s, LLVM 6.1 -> 5.5 s; the build child's CPU 7.3 -> 6.5 s (median of 4, alternated);
what --in-process cannot show (its kernel is not a process's first compile): see car._start_numba.
Then (branch h-cold2): the rest state and the simulator's yaw inertia on the NumPy engine (vehicle.statics.
REST_ENGINE: ~60 single samples were the compiled engine's only use in a demo): `demo --in-process --phases`, 69ee46f
then the branch in one run (load ~13, which inflates both): 35 -> 29 functions compiled (`_idm_kernel`, `_sincos`,
`_mul`, `_mul_t`, `_cross`, `_sign` no longer; NumPy's allocations 19 -> 13 times), compiles 21.0 -> 14.9 s of CPU,
the run 34.1 -> 27.4 s. What is left is what the demo runs: the kernel, the kinematic tables, the filters, the
corners' estimator, the block kernel; `_data_address` (3 signatures, ~0.2 s) the one multiple compile.
Then (branch h-cold): the identification's warm-up in a forked child (pipeline.first_run.WarmUp), let go when this
process starts to wait for the kernel's build. Timeline of one cold demo each (messages and top-level compiles stamped
with this process's CPU s, the children's CPU read at the waits; load 2-5): f15571e: the kernel's build forked at 0.9,
`_table_joints` 0.7, the vehicle loaded at 2.8, then the warm-up here 2.8 -> 6.6 (zero-phase filters 1.5, corners'
estimator and carry 0.9, the block kernel 0.9), the kernel's build (5.3 s) ended before, simulation from 6.6; h-cold:
fork at 1.1, the vehicle loaded at 3.2, then this process sleeps until the kernel's build ends (5.8 s of CPU) while the
warm-up child (4.2 s) compiles beside it and on through the simulation; this process compiles none of the
identification (tests/pipeline/test_cold_start.py) and uses 8.8 s of CPU in all (12.0 before; 10.0 warm). The same
compiles, moved: the total CPU is unchanged; what leaves the critical path is the warm-up's overrun of the kernel's
build (0.3-0.7 s of CPU). What is left on it is the kernel's build itself: a cold demo waits for 1 + ~6 s of CPU
where a warm one simulates after ~2. The kernel's build then forked before `dynid demo` imports the pipeline and the
report (cli.main.cmd_demo): at 0.81-0.85 s of this process's CPU against 0.95-1.01 (3 cold starts each, alternated).
Then (branch h-cold: symbolic.link_only, the kernel's helpers kept as LLVM IR that simulate links, optimises and emits
once, not module-optimised and emitted in libraries of their own): `demo --in-process --phases`, 721f59d and the branch
alternated, 2 rounds (load 5-5.5, so read the CPU): compiles 11.9, 11.2 s of CPU against 11.5, 10.3; LLVM's linking,
module optimisation and machine code 3.31, 3.14 against 2.69, 2.45; the whole run 21.5, 20.7 against 21.1, 19.1 s.
The kernel's build alone (one process, fresh caches, after a trivial compile as the forked build runs it; 4 pairs
alternated, load 4-6): 5.5, 4.9, 5.4, 6.1 s of CPU against 4.7, 4.1, 4.4, 4.4 (LLVM 1.85 -> 1.10 s: module passes
0.67 -> 0.29, machine code 0.63 -> 0.30), the simulations the same bits. What is left of it (~4.0-4.5 s at load 4):
typing 1.6, Numba's lowering 1.7, LLVM 1.1 (the functions' own passes 0.5); derivative's own compile 1.6 s, simulate's
1.0, the driver's family 0.7, NumPy's allocations in simulate 0.3. Tried and not kept (the kernel's build CPU, pairs
alternated): the helpers' function passes skipped too (4.9, 4.9 against 4.2, 4.8 s; the simulation 10 % slower);
simulate without its C entry (4.0, 4.1, 4.0 against 3.9, 4.1, 4.0: nothing); Numba's OPT for the whole kernel: 1
(5.4 s against 6.1 at 3, the simulation 22 % slower), 0 (4.2 s, LLVM's passes 0.14 s, the simulation 10 x slower).
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


# Numba's compile steps, whose CPU --phases splits (the self time of each: a callee compiled inside a caller's typing
# counts in its own steps): (class, method, label)
PHASES = (("numba.core.typeinfer", "TypeInferer", "propagate", "typing"),
          ("numba.core.lowering", "Lower", "lower", "lowering (Numba: LLVM IR built in Python)"),
          ("numba.core.lowering", "Lower", "create_cpython_wrapper", "Python entry points (Numba)"),
          ("numba.core.lowering", "Lower", "create_cfunc_wrapper", "C entry points (Numba)"),
          ("numba.core.codegen", "CPUCodeLibrary", "add_ir_module", "LLVM: functions optimised"),
          ("numba.core.codegen", "CPUCodeLibrary", "finalize", "LLVM: linked, module optimised, machine code"),
          ("numba.core.codegen", "CPUCodeLibrary", "serialize_using_object_code", "disk cache written"))


def split_phases() -> dict[str, float]:
    """Time Numba's compile steps (PHASES) from now on, in this process: label -> CPU s, filled as they run."""
    import importlib

    spent: dict[str, float] = defaultdict(float)
    stack: list[list[float]] = []  # per running step: [start, CPU of the steps it ran]

    def timed(method, label):
        def run(*args, **kwargs):
            stack.append([time.process_time(), 0.0])
            try:
                return method(*args, **kwargs)
            finally:
                start, inner = stack.pop()
                took = time.process_time() - start
                spent[label] += took - inner
                if stack:
                    stack[-1][1] += took
        return run

    for module, cls, method, label in PHASES:
        owner = getattr(importlib.import_module(module), cls)
        setattr(owner, method, timed(getattr(owner, method), label))
    return spent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--command", default="demo --out {tmp}/demo",
                    help="the dynid command line ({tmp}: this run's temporary folder)")
    ap.add_argument("--top", type=int, default=30)
    ap.add_argument("--in-process", action="store_true",
                    help="no kernel prebuild in another process: the simulator's kernel compiles here, and is listed")
    ap.add_argument("--phases", action="store_true",
                    help="also split the compiles' CPU by Numba's steps: typing, lowering, entry points, LLVM")
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
        phases = split_phases() if args.phases else {}
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
    if phases:
        print("CPU s by Numba's step (this process's compiles): " + "; ".join(
            f"{label} {t:.2f}" for label, t in sorted(phases.items(), key=lambda kv: -kv[1])))


if __name__ == "__main__":
    main()
