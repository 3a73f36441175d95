"""What the declared sensor zero offsets add to a car identification's CPU time (issue 28 item 3: <= 30 %).

Run:  python benchmarks/bench_offsets.py [--demo FOLDER] [--minutes 10 60] [--rounds 3]

Each log is identified by `dynid identify --workers 1` (one thread) three ways, alternated round by round: with the
vehicle suite's 36 offsets estimated from each test's data (the default), with them propagated alone
(`[uncertainty] estimate = false`) and without them (`offsets = "none"`); the figure is each child's CPU time
(user + sys, imports and report included: what a user waits for on a loaded machine), the least of the rounds.
The logs: the demo's files (`--demo`: a `dynid demo --out` folder; else simulated, 1-2 min) and bench_pipeline.py's
12 s manoeuvre repeated for each of `--minutes` (60 s segments).

Measured 2026-11-29 (issue 28, h-offsets at fd92e1c; 2 cores shared, load averages 8 to 14; CPU s of the whole
command, each mode against its own "none" run alternated with it; min of 3 rounds at the demo and 10 min, 1 round
at 1 h):

    log       offsets estimated (default)     offsets propagated alone (estimate = false)
    demo       7.4 against 6.9   (+7 %)        7.7 against 7.9   (-2 %, 1 round)
    10 min    13.1 against 7.9   (+66 %)      12.4 against 10.2  (+22 %, 1 round)
    1 h       63.9 against 23.2  (+175 %)     29.1 against 25.1  (+16 %)

The estimated offsets' cost grows with the log: each segment's rows need their 36 columns C (`offset_residuals`),
12 of them a staged moved pass of the joints (0.36 s of CPU per 60 s segment: attitude, heights, velocity at the
full rate) and its equations and decimation (0.2 s), the 24 wheel loads' one decimation (0.06 s), against 0.44 s for
the segment's own work (cProfile on the 10 min log, `time.process_time`). The propagation alone runs on
`offset_segments` segments per test: a fixed cost.

Then (h-off1p, 2026-11-29): the 7 offsets that move the joints linearly (3 accelerometers, 4 height lasers) take b
times the pass's response to a unit offset (two low-pass calls per segment) instead of a staged pass each; the load
offsets' unit rows come from one forward pass of the four tires; the moved residuals' W x is an einsum. On one 60 s
segment of the 10 min log (`offset_residuals` of the 36, process_time, min of 5): 0.46 -> 0.38 s at load ~5 (the 7
passes 0.072 -> 0.008 s, the rows of the 12 0.124 -> 0.111 s, the loads 0.036 -> 0.032 s); in 4 alternations of the
two commits' processes at load 7-12, 0.445-0.478 against 0.368-0.387 s (-17 %; the segment's main pass 0.10-0.11 s
on both). This benchmark's figure, the two commits alternated round by round in
one run (min of 3, load 8-16: the "none" runs, the same code, spread by 15 %):

    log       69ee46f: estimated against none    h-off1p: estimated against none
    demo        7.84 against 6.85 (+15 %)          7.90 against 7.08 (+12 %)
    10 min     13.97 against 9.00 (+55 %)         12.00 against 7.70 (+56 %)

Still far from the issue's 30 %: what is left per 60 s segment is the 5 attitude channels' staged passes (gyros
and inclinometers, 0.034 s each: their offsets move the rotation, which every later stage reads; a third of it is
the zero-phase filter, already 8 columns a call) and the rows of the 12 moved trajectories (9 ms each).

Then (h-mrows, 2026-11-29): the moved trajectories' residual changes without W and Y apart (`vehicle.CarResidual`:
W x summed over W's 126 live entries straight from the regressor's buffer, the known parameters with the base
ones), each less the segment's own residual on the coarse samples, all 12 through ONE decimation (14 columns each;
the dry-friction columns' full-rate part cancels where the dampers' rates are the segment's, so their set is no
longer made per segment); the aerodynamic wrench reused for the accelerometers; the 24 wheel loads' unit rows
stacked in their entry-major layout and only their 132 nonzero columns of 336 decimated. The columns C to round-off
of the old ones (against the whole-pass oracle: 0.536 of the test's tolerance, old 0.533; the car-truth tables
within 6.3e-11). One 60 s segment of the 10 min log (process_time, min of 12, ffe91d6 and the branch alternated,
load 8-9): the 12 moved trajectories' rows (their JointsPass.moved stages apart) 123-126 -> 75-89 ms, the loads'
28-31 -> 17-23 ms, offset_residuals 352-356 -> 277-329 ms (the moved stages 181-213 ms on both: now 2/3 of it).
This benchmark's figure, the two commits alternated in one run (dynid identify --workers 1, CPU s, load 6.5-10;
the "none" runs are the same code on both sides and spread by 40 %, so the offsets' own cost is best read as
estimated minus the least "none" of the run, 6.87 s at 10 min):

    log       ffe91d6: estimated against none       h-mrows: estimated against none
    10 min    11.98 against 6.87 (+74 %)             11.12 against 7.41 (+50 %)   (min of 4 rounds; pairwise
              the estimated runs 0.15, 0.85, 0.83, 0.97 s apart: the offsets' added 5.1 -> 4.3 s)
    1 h       42.29 against 17.09 (+147 %)           37.26 against 16.98 (+119 %) (1 round, load 7-9)

Still above 30 %: per 60 s segment the 5 attitude channels' staged passes (JointsPass.moved, ~0.19 s of the ~0.3 s
that the offsets add) are the rest; the rows' part left is the 13 regressor evaluations (kernel ~1.2 ms each,
bound by writing W's live entries) and 9 aerodynamic wrenches (1.5 ms each). A generated inverse dynamics with the
parameters given (W x without W) would take the rows' part down further, at the price of one more kernel to compile
on a first run (issue 28 item 4): not tried.

Measured 2026-11-29 (14:12-14:15 UTC, a quiet machine: load 1.1-1.8; main with h-mrows, h-joints4 and h-fault, each
tree's own script, `--minutes 10 --rounds 1 --modes estimated none`, 2 alternations): ffe91d6 estimated 12.26, 12.54
against none 6.83, 8.15 (+79 %, +54 %); this tree 9.70, 10.77 against 7.24, 6.96 (+34 %, +55 %): the estimated runs
10.2 against 12.4 s (-18 %); the offsets add ~+45 % at 10 min (the 'none' runs, the same code, spread by 19 %).

Then (h-offs, 2026-11-29, load 3-9 throughout): one 60 s segment of the 10 min log (process_time, min of 7):
offset_residuals 0.25-0.29 s against 0.075-0.087 s for the segment's joints and rows; of it the 24 loads 17 ms, the 5
attitude passes 133-150 ms (each ~29 ms, line profile: the attitude 11, the tire poses' kinematics and spline 3.4 and
4.5, the heights 4, the velocity and deflections 7: a dozen NumPy passes over the 38k samples each), the 7 other
staged passes 17-20 ms, the 12 moved trajectories' rows 68-76 ms (per trajectory `CarResidual` 3.1 ms: the regressor
1.2, its live sums and copies 1.6; the aerodynamic wrench 1.7 for 9 of them). A moved pass's joints now keep the
columns the stages write as views (42.5 MB of copies per segment: `_Moved` 7.0-7.2 -> 0.9-1.0 ms; offset_residuals'
peak 78.7 -> 83.0 MB by tracemalloc, the views holding their stages' arrays; the columns C equal to the bit, the
car-truth tables and the MuJoCo car's results unchanged). Tried and dropped: the 5 attitude passes side by side (the
stages as generators of their low-pass requests, each request of all five in one call: C equal to the bit; their
low-passes 36 -> 30 ms in 27 -> 8 calls, the calls not as latency-bound as alone in a bench, while the five passes'
arrays alive together (+42 MB at offset_residuals' peak, 79 -> 121 MB by tracemalloc) made the passes slower in each
of 4 alternations, 147-169 -> 162-181 ms); an attitude pass's tire poses as row 2 of its 0R6 times the tire frames in
frame 6 (kept from the pass): the forward kinematics' 2.6 ms per pass, but the frames in frame 6 need its whole rows
once per segment (5.8 ms: ~4 ms saved in all) and C's columns moved by up to 8e-10 of their scale (the pitch rate's:
their round-off redrawn, no longer the same operations as the segment's own pass); the spline evaluated in NumPy
(equal to the bit): 4.2-4.7 against SciPy's 1.6 ms. This benchmark (each tree's own script, `--minutes 10 --rounds 1
--modes estimated none`, 4 alternations, load 5-9; CPU s, min): 17cb88d estimated 10.39 against none 6.57 (+58 %),
h-offs 9.59 against 6.64 (+44 %); the 'none' runs, the same code, spread over 6.57-8.54 s: the change, ~2 % of the
offsets' work, is below this machine's noise. Where an hour stands (17cb88d, `--minutes 60 --rounds 1 --modes
estimated none`, load 7.1): estimated 37.95 s against none 19.04 s (+99 %). 30 % there is 0.095 s of offsets per 60 s
segment, against 0.26-0.29 s above (0.31 s in the hour's run): only compiled stages would reach it (the attitude pass
in one kernel: its sin, cos and tan then differ from NumPy's at round-off, so the main pass must run it too, and C's
round-off is redrawn as above; W x without W for the rows).

Then (h-offs, second round, 2026-11-29): the attitude and velocity stages' elementwise NumPy lines in two compiled
passes that the segment's own pass and the moved ones share, the sines and cosines left to NumPy (`_euler_compiled`:
the Euler rates, their trapezoidal integrals, the inclinometers' part left, the yaw rate and its integral;
`_velocity_compiled`: v_c - w6 x pc, R6 rel, the vertical part, v0 and the tire deflections, written straight into
the low-pass's input), and an attitude pass's tire poses take the 20 corner joints' cos and sin from the segment's
pass (`forward_kinematics(..., trig=)`). The same operations in the same order: on a 60 s segment of the 10 min log
the segment's q, qd, qdd, W, Y and the 36 columns C are f15571e's bit for bit; the car-truth tables (240 numbers) and
the MuJoCo car's results (3005) equal. Per call, in one process with the kernel on and off alternated (min of 15 x 6,
load 2.3): `_attitude` 8.56 -> 7.30 ms, `_velocity` 4.40 -> 3.10 ms; `_tire_poses` of an attitude pass 6.0-6.5 ->
5.1-5.6 ms (processes alternated, load 8.5). offset_residuals of the segment (process_time, min of 7, f15571e and
this branch's processes alternated 4 times, load 2.6-4.0): 295-318 -> 264-285 ms (-7 %; the segment's own joints and
rows 65-71 -> 62-67 ms). A first run compiles the two kernels: 0.23 and 0.37 s of CPU (an empty NUMBA_CACHE_DIR;
0.46 s before the velocity kernel's branches were cut), loaded in ~3 ms each afterwards. This benchmark (each tree's
own script, `--minutes 10 --rounds 2 --modes estimated none`, 2 alternations, load 3.7-9.2; CPU s, min of 2):

    log       f15571e: estimated against none       h-offs: estimated against none
    demo        5.59, 5.16 against 5.10, 4.82        5.37, 5.20 against 5.04, 4.76
    10 min      9.23, 8.82 against 6.35, 5.93        8.72, 8.40 against 5.51, 6.17

the estimated runs -5 %, the offsets' added work over the least 'none' of the run (5.51 s) 3.3-3.7 -> 2.9-3.2 s:
still +52-58 % at 10 min. Tried and dropped: a first-order (tangent) propagation of an attitude offset: the columns'
even part (C(b) + C(-b)) / 2, second order in b, is 0.2 % (roll rate) to 31 % (yaw rate: 0.6 rad of drift a minute)
of each column's largest, 3e-5 to 6e-2 of the residual's scale against the test's 1e-13; the chassis rotation's
products compiled (its six sines and cosines are its time: 1.82 -> 1.72 ms, not worth a compile); the heights'
R6 p products (an (N, 3) x (3, 4) matmul: OpenBLAS's fused sums are not the loop's, 29 203 of 152 000 entries
differ, so the main pass's bits would move) left to NumPy. What is left per attitude pass (~21-23 ms): 5 low-pass
calls (~7 ms, two of them the 2-column crossover's, latency-bound), the tire poses' spline (construction and
evaluation ~3.2 ms), 10 sines, cosines and tangents of 38k samples (~2.3 ms), the forward kinematics (~1.5 ms).
Measured 2026-11-29 (19:23-19:25 UTC, load 1.2-1.7; `--minutes 10 --rounds 1 --modes estimated none`, main (the
attitude and velocity compiled) and f15571e alternated twice): main estimated 10.42, 11.01 s against f15571e's 10.65,
12.77; the "none" runs, the same code, 6.28-8.52 s (the host's drift): against the run's least "none" (6.64 s) main
+57 %, +66 %, f15571e +60 %, +92 %. The demo: main -12 %, +15 %; f15571e +2 %, +11 %.

Then (h-att, 2026-11-29, load 3.3-6.7; tried, not kept): the 5 attitude channels' moved passes with their first stage
in lockstep (each low-pass call taking every pass's columns: 2 -> 10, 6 -> 30; the same bits, C and the car-truth
tables equal) gained 1.7 % of offset_residuals in one process (215.8 -> 212.1 ms, min of 15) and nothing measurable
between processes (228-259 against 220-265 ms): a wide call's fill of its C-order work array is half its time (32
columns 2.9 ms against the kernel's 2.0), and the columns come from memory. Not kept: +186 lines for that. Also tried
and dropped, each the same bits: the tire poses' spline evaluated in NumPy (2.1-2.4 ms against SciPy's 1.6); the 9
moved trajectories' aerodynamic wrenches stacked into one call (20.8 ms against 9 x 1.5: the kinematics' arrays leave
the cache); the five passes' splines in one construction (6.9 against 5 x 1.5 ms to build, 9.5 against 5 x 1.8 to
evaluate); the 12 CarResidual calls stacked (53.6-57.1 ms against 27.4-28.9, and other bits). What is left per 60 s
segment (load ~5): the 12 staged passes 131 ms (gyros 20 ms each, inclinometers 22.5-23.4, accelerometers 0.5,
lasers 1.2-1.4), each moved trajectory's rows 2.1 ms (+1.5 for an aerodynamic wrench), the loads 17 ms: every stage
a few NumPy or filter passes at the memory's pace, so 30 % (~0.07-0.1 s per segment) needs the attitude pass fused
into compiled stages (first-run compile time and redrawn round-off, as weighed above).
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests"), str(HERE.parent / "tests" / "vehicle")]

from bench_pipeline import CONFIG, write_hour  # noqa: E402
from results_file import write_results  # noqa: E402

MODES = ("estimated", "propagated", "none")


def _variants(text: str) -> dict[str, str]:
    """The config's text for each mode: its [uncertainty] table replaced (the vehicle suite's offsets by default)."""
    head = re.sub(r"\n\[uncertainty\][^\[]*", "\n", text)
    return {"estimated": head, "propagated": head + "\n[uncertainty]\nestimate = false\n",
            "none": head + '\n[uncertainty]\noffsets = "none"\n'}


def _cpu(config: Path, out: Path) -> float:
    """The CPU seconds (user + sys) of one `dynid identify` child, one thread."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = {**os.environ, "PYTHONPATH": str(HERE.parent / "src")}
    proc = subprocess.run([sys.executable, "-m", "dynid.cli.main", "identify", str(config), "--out", str(out),
                           "--workers", "1"], capture_output=True, text=True, env=env)
    if proc.returncode:
        sys.exit(f"{config}: the identification failed:\n{proc.stderr[-3000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demo", type=Path, help="a `dynid demo --out` folder (default: simulate the demo)")
    ap.add_argument("--minutes", type=float, nargs="*", default=[10.0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--modes", nargs="*", default=list(MODES), choices=MODES)
    args = ap.parse_args()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        logs: dict[str, Path] = {}
        demo = Path(tmp) / "demo"
        demo.mkdir()
        if args.demo is not None:
            (demo / "data").symlink_to((args.demo / "data").resolve())
            text = (args.demo / "identify.toml").read_text()
        else:
            from dynid.pipeline.demo import simulate_tests, write_demo

            text = write_demo(demo, simulate_tests()).read_text()
        logs["demo"] = demo
        for m in args.minutes:
            folder = Path(tmp) / f"{m:g}min"
            folder.mkdir()
            data = write_hour(folder, m, "parquet")
            text_m = CONFIG.format(file=data.name)
            logs[f"{m:g} min"] = folder
            for mode, t in _variants(text_m).items():
                (folder / f"{mode}.toml").write_text(t)
        for mode, t in _variants(text).items():
            (demo / f"{mode}.toml").write_text(t)
        for name, folder in logs.items():
            cpu: dict[str, list[float]] = {mode: [] for mode in args.modes}
            for _ in range(args.rounds):
                for mode in args.modes:
                    cpu[mode].append(_cpu(folder / f"{mode}.toml", folder / f"out_{mode}_{len(cpu[mode])}"))
            best = {mode: min(v) for mode, v in cpu.items()}
            load = os.getloadavg()[0]
            line = "  ".join(f"{mode} {best[mode]:6.2f} s" + (f" ({100 * (best[mode] / best['none'] - 1):+.0f} %)"
                                                             if "none" in best and mode != "none" else "")
                             for mode in args.modes)
            print(f"{name:>8}: {line}   (CPU, min of {args.rounds}; load {load:.1f})", flush=True)
            results[name] = {"cpu_s": cpu, "load": load}
    write_results("offsets", results)


if __name__ == "__main__":
    main()
