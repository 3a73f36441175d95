"""Where an identification's time goes, stage by stage, per hour of 625 Hz car data, against this machine's limits.

Run:  python benchmarks/profile_car.py [--minutes 10] [--cpu] [--threads 1]

Writes `--minutes` of the sensor suite's channels (Parquet, as bench_pipeline.py: a 12 s manoeuvre repeated),
then runs the car identification in this process on ONE thread (every segment in turn, so each stage's time is
its own, not shared with a second core) with timers around the pipeline's functions:

- plan: each test's pass over the time stamps (`sources.plan_car_test`);
- read: decoding a segment's channels (`sources.read_segment`);
- compensation: undoing the sensors' declared dynamics (`vehicle.estimate.compensated_channels`);
- joints: `joints_pass` (attitude fusion, kinematic tables, zero-phase filters, derivatives);
- regressor: the generated 14-equation identification model (`GeneratedRegressor`);
- equations: the rest of `car_identification` (the wheel wrenches' and gravity's rows);
- decimation: the parallel decimation of W and Y (`car._decimated`);
- rows, other: the rest of `car_system` (aerodynamics, row selection, stacking);
- QR: the streamed least squares' factor updates (`StreamingLS.add`);
- tire samples: the tire curves' slips and forces (`vehicle.tire_curves.tire_samples`);
- data health: the segment's scan of its channels and the wiring's sums (`pipeline.health.segment_health`);
- segments, other: the rest of `reduce_car_segment`.
Each stage's time is its own: a timed function's time without the timed calls it makes (wherever it is called
from, e.g. the compensation inside or outside `estimate_joints`).
- offsets, error draws, delays: what the sensor offsets' propagation, the model-fit verdict's error draws and
  the channel delays' estimate add (each on 2 segments per test, whatever its length: a fixed cost, reported
  per test);
- solve and report: the rest of `identify` (solve, validation, the delays' further steps, notes), and
  `write_outputs` (tables, figures, report.html): fixed costs, in seconds.

--threads N runs the stages' segments on `LocalScheduler(N)` as an identification does (its heap set-up and trims
with it), each stage's CPU then summed over the threads; every stage also prints its own minor page faults and
system CPU (getrusage of the thread running it).

Each stage prints its seconds per hour of data and, where this run measures one, its limit on this machine:
the bytes the stage must touch over the memory bandwidth (a large copy, measured here) for read and
decimation, and the arithmetic over one core's peak (benchmarks/roofline.py) for the regressor (its
operations counted on the SYMORO-style model) and the QR (2 n p^2 per block of n rows, p columns).
Writes benchmarks/results/profile_car.json.

Measured (issue 28, --minutes 10 --cpu, CPU s per hour of data, one thread; main at d8e0370, then branch h-thru,
in turn, on a 2-core AMD EPYC shared with ~5 other sessions at load averages of 4 to 6: every figure inflated
and noisy, stages whose code did not change moved by up to 20 %): joints 4.46 -> 4.05 (the final branch: the
corners' differences and integrals in one compiled pass, the chassis rotation written in place, 12 low-pass
calls per pass -> 8), total 8.93 -> 9.12 in that run (read 1.25 -> 1.49, tire samples 0.48 -> 0.58: unchanged
code, the load). The same comparison by min of 15 passes of one 60 s segment (/tmp scripts, alternated
processes): joints 4.90 and 5.01 -> 4.28 and 4.16, rows 1.25 -> 1.18, compensation unchanged. A run with three
more kernels (tire poses, Euler rates, rotation) read joints 4.59 -> 3.35, but they cost 2-5 s of compile each
on a first run for 1-2 ms per pass: left out (the cold start). Rows, results.json and every parameter are
main's to the bit (the tire curves' σ to 4e-16: their instants' labels are integers now, their groups summed in
another order). Not in the table: the tire curves' fit after the segments (1 hour's samples: 2.48 -> 1.94 s).

Measured 2026-11-27 (issue 28, h-thru2; --minutes 5 --cpu, main 07e3a6a then branch h-thru2 in turn, bench_fleet's
workload; the 2-core EPYC at load averages 10 to 13, so every wall figure here is several times an idle one and
only the CPU columns compare): the segments' stages 14.99 -> 14.94 CPU s per hour (their code unchanged: joints
7.79 / 7.37, read 1.02 / 1.13, decimation 1.24 / 1.36, compensation 1.30 / 1.35); the tire curves' fit per hour
CPU 8.20 -> 7.36 s, wall 97.0 -> 29.1 s (its fits on 2 threads now: the loaded machine's figure, not a ratio to
quote). Before, this profile ran with the offsets estimated (the default): each segment then evaluated each
offset's moved rows, 24 of 39 s of a 10 min identification (cProfile, one thread), hidden in the fixed line.
The whole hour, cProfile of main (one thread, inline, 60 min): the segments 83 % (joints 32 %,
reading 14 %, rows 13 %, the data health 9 %, compensation 6 %, tire samples 4 %), the tire fit 15 %
(4.4-4.9 CPU s: 14 least-squares problems on 290k wheel samples), the rest 5 %.

Measured 2026-11-28 (issue 28, h-health; --minutes 10 --cpu, ae30552 then the branch in turn, 4 rounds, load
averages 5 to 7 on the 2-core EPYC; medians, CPU s per hour): read 1.91 -> 1.14 (0.60: the Arrow schema once per
file, not per column; the cached Parquet columns views of the decoded buffers, not copies; a window's shared time
stamps cut and concatenated once, not per channel; a segment's stamps merged without refitting the plan's clock;
no x * 1.0; the fresh arrays' page faults were most of it), data health 2.26 -> 2.00 (0.89: its set-up once per
process, its scan's passes shared). A segment's read (10 min file, 55 channels) against a plain pyarrow read of
the same rows: 45 -> 26 ms, pyarrow 21 ms (it decodes; the rest is the SI products and the finite-value checks).
The data health's set-up (`car_scans`, the vertical axis: the vehicle's suite rebuilt per access) was 2-3.5 ms of
a segment's 20: the scan of the channels' values (about ten NumPy passes each) is the rest.

Measured 2026-11-29 (issue 28, h-joints; main b872084 then the branch in turn, --minutes 5 --cpu, load averages 4 to
10 on the 2-core EPYC, CPU s per hour, medians): joints 4.99 -> 3.80 and compensation 1.16 -> 0.85 (3 rounds, load
4-6); at load 6-10 (7 rounds) joints 4.63-5.05 -> 4.29-4.71, the rounds' spread as large as the change. One 60 s
segment alone (38412 samples, min of 20 passes, processes alternated): joints_pass 86-93 -> 61-69 ms, its page faults
10238 -> 3238 per pass (sys 26 -> 14 ms); a segment's reduce with the suite's 36 offsets 1.04, 1.16 -> 0.81, 0.92 s.
Where it went: channels written column by column into (N, C) C-order matrices (a cache line per sample per channel:
the corners' 41-column filter input, the compensation's groups) now stacked as rows; the tire poses' forward
kinematics on frame 0's row 2 alone (9.5 -> 3.0 ms); 8 low-pass calls -> 6 (a call on 1-2 columns costs the
recursion's latency, 0.6-0.8 ms); the IMU acceleration carried to O6 in one compiled pass (5 ms; its compile 0.4-0.6
s, once per machine); border_samples cached. Every output bit-identical to main's. What is left per 60 s segment
(~62 ms): the zero-phase filter 10 ms (its 41-column call near one core's arithmetic peak, 5 small calls bound by
the recursion's latency, 2 of them the attitude's sequential crossover), the attitude 6.5 ms (14 sin, cos, tan of
38k samples), the first writes of q, qd, qdd (3 x 13 MB: page faults, ~5 ms, inside the corners' pass), the tire
poses 9 ms (forward kinematics 2.5, spline 5), the velocity 3 ms.

Measured 2026-11-29 (issue 28, h-joints2; main fd92e1c then the branch in turn; this machine an Intel Xeon with
AVX-512, 2 cores, at load averages 6 to 15: every figure inflated, only alternated ones compare). This profile,
--minutes 10 --cpu, 4 rounds, CPU s per hour: compensation 0.98, 1.22, 0.95, 0.86 -> 1.13, 0.90, 1.04, 0.99; joints
4.55, 4.56, 4.00, 4.03 -> 4.66, 3.69, 4.16, 4.42; total 9.84, 10.82, 9.51, 9.24 -> 11.03, 8.80, 10.16, 10.26: at that
load 10 segments a run do not resolve the changes below. Alone (thread CPU, /tmp scripts, processes alternated):
compensated_channels, 3 segments in turn with 32 MB touched between calls, medians of 30: 40.4, 28.4, 26.3 ->
26.8, 21.5, 21.2 ms (load 8-10); min of 20 on one segment: 17.0, 17.5, 18.3 -> 11.8, 12.7, 15.3 ms (load 6-7.5,
the kernel's block then 64 rows), with the committed 256 rows at load 11: 21.5-23.6 -> 19.0-20.5 ms (6 rounds,
one 25.1);
joints_pass alone (compensated channels given), min of 20: 71.5, 84.2, 71.6, 71.7, 67.9, 86.5 -> 62.4, 63.3, 63.6,
68.7, 62.4, 71.7 ms (load 11-15). Every output bit-identical to main (4379 arrays: 3 hour segments, the demo's 44,
moved passes). What changed: the band limits undone for all 55 channels in one kernel pass, each channel with its
own filter, the samples moved through a block of 256 rows (one sample of every channel's row per step took 8.5 ms
for the 28-channel group alone, 23 ms for 55); the attitude's signed columns written one by one (2.6 -> 0.9 ms),
its yaw rate on the last refinement alone; the 6- and 7-column low-pass calls given 8 columns (the kernel runs
channels in vectors of 8: 2.1-2.7 -> 1.6 ms a call). What is left, one 60 s segment (load ~8-11): the corners' and
loads' 41-column low-pass 8.2 ms (np.stack of the channels 1.6, the finite check 1.0, the copy into the filter's
work array 2.0, the kernel 4.2; 41 columns cost what 48 do); the attitude ~10 ms (the crossover's two 2-column calls
0.9 each, latency-bound; the rotation 1.9; the trig: NumPy 2.4 runs sin and cos as SIMD on AVX-512, 0.29, 0.155 and
tan 0.055 ms per 38k samples, the 13 calls ~2.4 ms, so dynamics/trig.py's sine and cosine in a compiled pass would
gain at most ~2 ms here for a new kernel's first-run compile (~0.5-1 s; more where NumPy calls libm, AVX2): not
done); the compensation's np.stack 2.4, kernel 4-8 (its block transposition, memory-bound, most of it) and the
channels' advance 3 ms (load 12). The page faults: with mallopt (M_MMAP_THRESHOLD 32 MB, M_TRIM_THRESHOLD 512 MB) a
pass's sys CPU went 15.5 -> 0 ms and its faults 2855 -> 1, but its user CPU grew by as much (calloc then clears
reused heap): no net gain, not pursued.
Measured 2026-11-29 (issue 28, h-joints3; 69ee46f then the branch in turn, --minutes 10 --cpu, CPU s per hour, the
2-core Xeon). The final branch, 6 alternated rounds at load averages 2 to 6: joints 3.50, 3.60, 3.25, 3.53, 3.38, 3.22
-> 3.33, 3.20, 3.06, 3.01, 3.50, 3.33 (medians 3.44 -> 3.27); tire samples 0.47, 0.49, 0.44, 0.48, 0.46, 0.47 -> 0.39,
0.37, 0.35, 0.35, 0.35, 0.38 (medians 0.47 -> 0.36). One process holding 69ee46f's estimate.py and tire_curves.py
beside the branch's, alternated on one 60 s segment (thread CPU, 60 passes each, 3 runs, load 2.4-4): joints_pass
medians 53.8, 56.1, 55.5 -> 51.2, 54.1, 53.2 ms (minima 48.5, 51.5, 50.3 -> 48.2, 47.6, 48.4); tire_samples medians
6.45, 6.29, 6.34 -> 5.85, 5.68, 5.81 ms. What changed, each bit-identical (hashes of 6400 arrays from 264 calls of
joints_pass, moved, tire_samples and compensated_channels over this hour with the suite's offsets and the 406 demo
plan; car.py and mj.py: 0 of 240 and 0 of 3005 numbers differ): one finite-value scan of the 57 channels the pass
reads, up front, naming the channel and sample, instead of each filter's, difference's and integral's own (nested
timers: 2.25 ms of scans -> 0.85 + 0.17); a camera channel scanned for saturation only when its least or largest sample
reaches a limit (0.78 -> 0.38 ms); the small low-pass calls' columns written into the filter's work array
(`signals.lowpass_columns`), not concatenated then copied; tire_samples' wheels concatenated once, its joint rates
transposed once. Tried and left: the 43-column call through lowpass_columns (the channels written into the work array
by blocks of ~768 KB) is faster alone (12.4 -> 7.9-10.3 ms, load ~10) but not in the pass, whose page faults went 3970
-> 6200-6700 (the stacked 13 MB array freed each pass serves the later stages' arrays from the heap): pass medians
53.5-55.3 with the stack, 55.5-58.6 without; a fused kernel reading the channels as rows (copy, odd extension and
forward pass in one sweep, the same bits) was no faster than copy + kernel (43 columns 4.3-6.3 against 4.0-8.3 ms); the
tire poses' spline evaluated by NumPy at the integer samples (bit-identical to SciPy's) took 2.9-3.6 ms against SciPy's
1.6-2.7. What is left per 60 s segment: the filter kernel ~8.5 ms, the first writes of fresh arrays (~4000 page faults,
~15 ms of system time per pass), the tire poses' spline (SciPy's construction 2.4, evaluation 1.6-2.7 ms) and forward
kinematics 2.5-3.3 ms, the attitude ~5 ms.
Measured 2026-11-29 (issue 28, h-thru2; main fd92e1c then the branch in turn, --minutes 10 --cpu, 2 rounds, load
averages 10 to 15 on the 2-core EPYC: every stage moved by up to 30 % between rounds, code unchanged or not, so the
stage figures below are the targeted measures, not this table's). The tire curves' fit (after the segments, an hour's
290k wheel samples): its own CPU per hour in this table 2.89, 2.11 -> 1.23, 1.56 s; alone (one thread, min of 5 fits, 3
alternated processes, load 11) 1.90-2.17 -> 0.75-0.88 s. Where it went (cProfile on CPU time, one thread): the
longitudinal laws 0.64 s (6 fits of 73-145k samples, 22-26 evaluations each with 2-point Jacobians: now started at their
closed-form optimum, 1 evaluation), the Magic Formula's 6 starts per axle 0.46 s (all ending at one point: now descended
on every 5th sample, the best end polished on all in 3-4 evaluations), the per-tire fits' 2-point Jacobians, and 7
conversions of the test names to strings (astype(str), 0.14 s). The demo plans' and the MuJoCo car's tire numbers moved
by at most 1.1e-7 σ (2.9e-6 relative; mj.py: 438 tire numbers and the 4 slip stiffness figures of the engineering sheet
differ, every identified parameter bit-identical; car.py: 0 of 240 differ). What is left of the fit (~0.8 s): the least
squares 0.37 s (the closed-form Jacobian 0.18), the samples' selections and sorts ~0.3 s. The data health's channel
scan, tried and reverted: a fresh array of a 60 s block (300 KB) is page-faulted in anew in a fresh process
(abs(diff(y)) 465 us against diff(y) 33 us); with the holds' lengths in one array, the steps' sizes in place and the
steps and pairs in per-thread scratch arrays, one segment's 55 channels scanned alone went 18.1-20.8 -> 10.7-14.5 ms
(min of 30, 3 alternated processes), but `segment_health` on 5 captured segments of the hour (pickled, one thread, min
of 10, 3 alternated processes, load 10) read 0.83-0.93 s per hour before and 0.85-0.90 after: in a process that has
freed large arrays, glibc serves such blocks from its heap without faults, and the gain was the benchmark's. What is
left there is NumPy's passes (about ten per channel): one compiled pass for min, max, the holds and the steps' bounds is
the lever (its compile once per machine: not tried). The hour end to end (bench_fleet.py --hours 1 --workers --repeat 3,
CPU s medians of 3; its docstring): main 1.03 x fddb8ab's throughput in CPU terms at the start (load 11), the branch
1.12 x fddb8ab's and 1.09 x main's at the end (all three in one run, load 3 to 6); the 3 x target is far (the segments'
stages: 8.6-12.3 CPU s per hour in this table's rounds, of the hour's 12.8-14.4 end to end: joints, compensation, read,
decimation).

Measured 2026-11-29 (issue 28, h-fault; ffe91d6 then the branch in turn, --minutes 10 --cpu --threads 2, 3 rounds,
13:45-13:48 UTC, load averages 1.2 to 2.7; CPU s per hour, medians): the stages 11.14 (11.14, 12.22, 10.00) -> 8.38
(11.18, 8.38, 7.88), joints 5.24 -> 3.57, compensation 1.83 -> 1.06; their minor page faults 217-237k -> 12-23k per
hour, their system CPU 2.44-4.39 -> 0.25-0.56 s. On one thread (--threads 1, the main thread's heap) they had none
to lose: 0 faults, 0.10 s system. What changed (pipeline.heap.tune_threads, made by LocalScheduler): the threads on
one glibc arena (each thread's own grew in heaps of at most 64 MB, unmapped when free), the heap's free top kept
until the map's end instead of handed back beyond glibc's adaptive threshold and every 8th segment, pyarrow's
reads on that heap rather than its mimalloc pool (car runs never switched it). perf of the hour on 2 threads (one
run each, load ~11; the settings made by mallopt and the environment): the kernel's clear_page 17 % of the samples
-> 4.5 %.

Measured 2026-11-29 (issue 28, h-footer: a Parquet file's footer parsed once per process while the file is unchanged,
`io.windows.FOOTER_FILES`). Before, "the Arrow schema once per file" above meant once per opening of the file, and every
window's row groups not in the block cache, every read of a plan's clock from the file and the planning pass's null
check opened it anew, pyarrow parsing its footer (every row group's column chunks) each time: 12 parses for an
identification of 10 min, 43 for 1 h, 228 for 6 h, 1 after (pyarrow's opens counted). An opening of the suite's file,
its footer parsed (60 columns, min of 20-30, CPU): 10 min 0.42 ms, 1 h 1.45 ms, 6 h 9.2 ms (210 row groups, a 1.55 MB
footer): ~2.1 CPU s of a 6 h identification's ~64. One segment's read alone (`sources.read_segment` of the plan's middle
segment, decoded blocks dropped before each pass, so every block opens the file: an upper bound, in a run a segment's
first block is often the last one's, cached; thread CPU, min of 30-40 passes, 2d7417f and the branch in alternated
processes, load averages 5 to 7): 10 min 26.8, 28.6, 27.5 -> 27.4, 26.2, 25.0 ms; 1 h 9.10, 9.15, 8.94, 9.14 -> 7.77,
7.38, 7.54, 7.94 ms; 6 h 31.6, 32.0, 32.4 -> 15.0, 13.9, 18.7 ms. This table at --minutes 10 --cpu (4 alternated rounds,
load 6.4 to 7.1) cannot resolve a 10 min file's 5 ms: read 0.64, 0.85, 0.72, 0.70 -> 0.83, 0.78, 0.74, 0.69 s per hour,
the rounds' spread. bench_fleet.py --hours 1 --workers --repeat 3 --vs <2d7417f>/src (load 7.1 to 7.3): CPU 11.02
(11.49, 11.02, 11.02) against 11.29 (12.79, 11.40, 11.29) s, 1.03 x (the hour's 43 parses are ~0.06 s of it: mostly the
load), peak 0.61 against 0.62 GB. A footer kept costs ~8 times its size in the file in memory (~11 MB for 6 h of the
suite), one per file, against one per read in flight before. The 6 h identification whole (inline, one thread, the 1 h
file's row groups written 6 times; whole processes, 3 each, alternated, load 0.5 to 3): CPU 52.2, 59.3, 60.4 against
52.5, 59.6, 65.6 s (0.99 x, the parses' 2 s within the runs' spread); peak 879, 887, 907 against 843, 865, 886 MiB, the
ranges overlapping; likely the footer kept (~12 MB for 6 h), alive after the segments (where the peak falls not
checked)."""

from __future__ import annotations

import argparse
import contextlib
import functools
import os
import resource
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

from bench_pipeline import write_hour  # noqa: E402
from results_file import write_results  # noqa: E402

CONFIG = """
[model]
template = "peugeot406"

[[tests]]
name = "one hour"
file = "{file}"

[conditioning]
segment = 60.0

[identification]  # the hour repeats a 12 s manoeuvre with still wheel forces (throughput, not accuracy):
data_health = "warn"  # its dead channels are said, not a stop
"""
# bench_fleet's workload (issue 28's measure): the offsets not propagated. With them estimated (the default), every
# segment, not two per test, evaluates each offset's moved rows: on 10 min that was 24 of 39 s (cProfile, main
# 07e3a6a), a per-hour cost the fixed costs below do not show; their "offsets" line is one segment's, measured
# with the suite's offsets (CONFIG alone)
NO_OFFSETS = '[uncertainty]\noffsets = "none"\n'

CLOCK = time.perf_counter  # --cpu: time.thread_time (this thread's CPU time: a loaded machine's waits left out)
SPENT: dict[str, float] = defaultdict(float)
FAULTS: dict[str, int] = defaultdict(int)  # each stage's own minor page faults (this thread's: RUSAGE_THREAD)
SYSTEM: dict[str, float] = defaultdict(float)  # each stage's own system CPU time (the faults' cost, mostly)
COUNT: dict[str, int] = defaultdict(int)
_LOCAL = threading.local()  # .nested: time, faults, system time of the timed calls inside each running timed call
_LOCK = threading.Lock()  # the totals added to from the --threads workers


def _thread_usage() -> tuple[int, float]:
    """This thread's minor page faults and system CPU seconds so far."""
    r = resource.getrusage(resource.RUSAGE_THREAD)
    return r.ru_minflt, r.ru_stime


def timed(owner, name: str, stage: str) -> None:
    """Wrap owner.name (a module's function or a class's method) to add its own time to SPENT[stage]: the time of
    the timed calls it makes is theirs, not its (each stage counted once, wherever it is called from)."""
    fn = getattr(owner, name)

    @functools.wraps(fn)
    def wrapper(*a, **k):
        nested = _LOCAL.__dict__.setdefault("nested", [])
        t, (f, st) = CLOCK(), _thread_usage()
        nested.append([0.0, 0, 0.0])
        try:
            return fn(*a, **k)
        finally:
            spent, (f1, st1) = CLOCK() - t, _thread_usage()
            inner = nested.pop()
            with _LOCK:
                SPENT[stage] += spent - inner[0]
                FAULTS[stage] += f1 - f - inner[1]
                SYSTEM[stage] += st1 - st - inner[2]
                COUNT[stage] += 1
            if nested:
                outer = nested[-1]
                outer[0] += spent
                outer[1] += f1 - f
                outer[2] += st1 - st

    setattr(owner, name, wrapper)
    # a module that imported the function by name (`from ..vehicle.estimate import joints_pass`) calls its own
    # reference: replaced too, or the stage reads 0 and its time lands in the caller's
    for mod_name, module in list(sys.modules.items()):
        if mod_name.startswith("dynid.") and module is not owner and getattr(module, name, None) is fn:
            setattr(module, name, wrapper)


def bandwidth() -> float:
    """Bytes per second of a large copy (read + write counted), best of 5."""
    a = np.ones(64 * 2**20 // 8)
    b = np.empty_like(a)
    best = min(_copy_time(a, b) for _ in range(5))
    return 2 * a.nbytes / best


def _copy_time(a, b) -> float:
    t = time.perf_counter()
    np.copyto(b, a)
    return time.perf_counter() - t


class Inline:
    """A scheduler running every job in turn in this thread (the stages' times are then their own)."""

    def __repr__(self) -> str:
        return "1 thread, inline"

    def map_reduce(self, fn, jobs, key, combine, progress=None):
        from dynid.pipeline.schedulers import _by_key, tree_fold

        results = [fn(j) for j in jobs]
        return {k: tree_fold([results[i] for i in idx], combine) for k, idx in _by_key(jobs, key).items()}

    def close(self) -> None:
        pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--cpu", action="store_true", help="the stages' CPU time (one thread), not their wall time: "
                    "comparable on a loaded machine; the fixed costs and limits stay wall times")
    ap.add_argument("--threads", type=int, default=1, help="the stages' segments on this many threads "
                    "(`LocalScheduler`, as an identification runs them; with --cpu each stage's CPU summed over them)")
    args = ap.parse_args()
    global CLOCK
    if args.cpu:
        CLOCK = time.thread_time

    import dynid.pipeline.car as car
    import dynid.pipeline.health as health
    import dynid.pipeline.reduce as reduce
    import dynid.pipeline.run as run
    import dynid.pipeline.sources as sources
    import dynid.vehicle.estimate as estimate
    import dynid.vehicle.tire_curves as tire_curves
    from dynid.estimation.streaming import StreamingLS
    from dynid.pipeline.config import load_config
    from dynid.pipeline.schedulers import LocalScheduler
    from dynid.symbolic.generated import GeneratedRegressor

    threads = LocalScheduler(args.threads)  # made first, as `identify` makes it: it sets the process's heap up
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        data = write_hour(folder, args.minutes, "parquet")
        cfg_file = folder / "identify.toml"
        cfg_file.write_text(CONFIG.format(file=data.name) + NO_OFFSETS)
        cfg = load_config(cfg_file)
        (folder / "offsets.toml").write_text(CONFIG.format(file=data.name))
        with_offsets = load_config(folder / "offsets.toml")
        with contextlib.redirect_stdout(None):
            run.identify(cfg, scheduler=Inline())  # compiled kernels and caches warm, not timed

        kernel_calls: list[tuple[int, tuple]] = []
        original_call = GeneratedRegressor.__call__

        def regressor_call(self, q, qd, qdd, wrenches, rows, cols):
            kernel_calls.append((np.atleast_2d(q).shape[0], (self.tree, tuple(rows), tuple(cols), tuple(wrenches))))
            return original_call(self, q, qd, qdd, wrenches, rows, cols)

        GeneratedRegressor.__call__ = regressor_call
        timed(GeneratedRegressor, "__call__", "regressor")
        timed(run, "plan_car_test", "plan")
        timed(sources, "read_segment", "read")
        timed(estimate, "compensated_channels", "compensation")
        timed(estimate, "joints_pass", "joints")
        timed(car, "car_identification", "equations")
        timed(car, "_decimated", "decimation")
        timed(car, "car_system", "rows other")
        timed(tire_curves, "tire_samples", "tire samples")
        timed(health, "segment_health", "health")
        timed(run, "reduce_car_segment", "segments other")
        rows_seen: list[tuple[int, int]] = []
        original_add = StreamingLS.add

        def add(self, W, Y, groups):
            rows_seen.append(np.shape(W))
            return original_add(self, W, Y, groups)

        StreamingLS.add = add
        timed(StreamingLS, "add", "QR")

        # the stages: every segment once, as the identification's map does, without the per-test extras
        setup = reduce.car_setup(cfg)
        plan = run.plan_car_test(cfg, cfg.tests[0], estimate.required_channels(spin=False, suite=setup.vehicle.suite),
                                 setup.vehicle.suite.units, cfg.car.segment, lambda fs: 0, lambda _m: None)
        windows = [sources.segment_window(plan, lo, hi) for lo, hi in plan.segments]
        jobs = []
        # the part of the test each answers for, as the identification's jobs say
        for i, (w, own) in enumerate(zip(windows, sources.segment_edges(plan), strict=True)):
            jobs.append(reduce.CarJob(cfg, w, "identify", i + 1, health=own))
        if args.threads > 1:  # the identification's own scheduler (its heap trims included), its results dropped
            threads.map_reduce(run.reduce_car_segment, jobs, lambda _j: 0, lambda a, _b: a)
        else:
            for job in jobs:
                run.reduce_car_segment(job)
        staged, staged_faults, staged_sys = dict(SPENT), dict(FAULTS), dict(SYSTEM)
        staged_kernels, staged_rows = list(kernel_calls), list(rows_seen)
        # the whole identification (inline) and its report, timed apart
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(None):
            result = run.identify(cfg, scheduler=Inline())
        identify_s = time.perf_counter() - t0
        out = folder / "out"
        out.mkdir()
        t0 = time.perf_counter()
        run.write_outputs(result, out, "profile")
        report_s = time.perf_counter() - t0

        # the fixed per-test costs: one segment's extras, evaluated alone
        from dynid.pipeline.car import sensor_offsets

        moved = tuple(sensor_offsets(with_offsets.car, setup.vehicle).si().items())
        w = windows[len(windows) // 2]
        extras = {}
        base = reduce.CarJob(cfg, w, "identify", 1)
        for label, job in (("offsets", reduce.CarJob(cfg, w, "identify", 1, moved)),
                           ("error draws", reduce.CarJob(cfg, w, "identify", 1, errors=True)),
                           ("delays", reduce.CarJob(cfg, w, "identify", 1, delays=True))):
            times = []
            for j in (base, job, base, job):
                t = time.perf_counter()
                reduce.reduce_car_segment(j)
                times.append(time.perf_counter() - t)
            extras[label] = max(0.0, min(times[1], times[3]) - min(times[0], times[2]))

    hours = args.minutes / 60.0
    per_hour = {k: v / hours for k, v in staged.items()}
    segments = sum(per_hour.get(k, 0.0) for k in ("read", "compensation", "joints", "regressor", "equations",
                                                   "decimation", "rows other", "QR", "tire samples", "health",
                                                   "segments other"))
    fixed = 2 * sum(extras.values()) * len(cfg.tests)
    rest = identify_s - hours * (segments + per_hour.get("plan", 0.0)) - fixed  # s, whatever the length

    # limits
    bw = bandwidth()
    from roofline import operations, peak_flops

    peak = peak_flops()
    samples = args.minutes * 60 * 625
    channels = len(estimate.required_channels(spin=False))
    read_limit = samples * channels * 8 * 2 / bw / hours  # decoded values written once, read once
    _, (tree, rows, cols, wrenches) = staged_kernels[-1]
    from dynid.symbolic import WrenchSite

    sites = [WrenchSite(x.link, tuple(float(v) for v in x.point), x.frame) for x in wrenches]
    ops, _funcs = operations(tree, "regressor", rows=list(rows), cols=list(cols), wrenches=sites)
    reg_samples = sum(n for n, _ in staged_kernels) / hours
    regressor_limit = reg_samples * ops / peak
    qr_flops = sum(2.0 * n * p * p for n, p in staged_rows) / hours
    qr_limit = qr_flops / peak

    table = [  # (label, key in SPENT, limit s per hour)
        ("plan (time stamps)", "plan", None),
        ("read (decode a segment's channels)", "read", read_limit),
        ("compensation (sensor dynamics undone)", "compensation", None),
        ("joints (attitude, tables, filters, derivatives)", "joints", None),
        ("regressor (generated 14-equation model)", "regressor", regressor_limit),
        ("equations (wrenches, gravity rows)", "equations", None),
        ("decimation (parallel, W and Y)", "decimation", None),
        ("rows, other (aero, selection, stacking)", "rows other", None),
        ("QR (streamed factor updates)", "QR", qr_limit),
        ("tire samples (the tire curves' slips, forces)", "tire samples", None),
        ("data health (the segment's channels scanned)", "health", None),
        ("segments, not in the stages above", "segments other", None),
    ]
    clock = "CPU" if args.cpu else "wall"
    print(f"{args.minutes:g} min of 625 Hz car data, {args.threads} thread(s); {clock} seconds per hour of data "
          f"(memory bandwidth {bw / 1e9:.1f} GB/s, one core's peak {peak / 1e9:.1f} Gop/s, measured now); "
          f"each stage's minor page faults (thousands) and system CPU seconds per hour")
    print(f"  {'stage':<50} {'s / hour':>9} {'limit s':>9} {'x limit':>8} {'k faults':>9} {'sys s':>7}")
    for name, key, limit in table:
        s = per_hour.get(key, 0.0)
        lim = f"{limit:9.3f}" if limit else f"{'-':>9}"
        ratio = f"{s / limit:8.1f}" if limit else f"{'-':>8}"
        print(f"  {name:<50} {s:9.2f} {lim} {ratio} {staged_faults.get(key, 0) / hours / 1e3:9.0f} "
              f"{staged_sys.get(key, 0.0) / hours:7.2f}")
    total = sum(per_hour.get(key, 0.0) for _, key, _ in table)
    print(f"  {'total':<50} {total:9.2f} {'':>9} {'':>8} {sum(staged_faults.values()) / hours / 1e3:9.0f} "
          f"{sum(staged_sys.values()) / hours:7.2f}")
    print("  fixed per identification test (2 segments each, whatever its length), s:")
    for label, s in extras.items():
        print(f"  {'  ' + label:<50} {2 * s:9.2f}")
    print(f"  fixed per identification, s: solve, validation, delay steps, notes, tire fit {rest:.2f}; report (tables, "
          f"figures, report.html) {report_s:.2f}")
    tires = result.tires
    if tires is not None:  # after the segments, on the hour's wheel samples: per hour, not fixed
        print(f"  tire curves' fit (in the line above; its fits on up to 2 threads), per hour: wall "
              f"{tires.seconds / hours:.2f} s, CPU {tires.cpu_seconds / hours:.2f} s")
    print(f"  the whole identification of these {args.minutes:g} min took {identify_s:.1f} s on one thread")
    write_results("profile_car", {"minutes": args.minutes, "clock": clock.lower(),
                                  "per_hour_s": {n: per_hour.get(k, 0.0) for n, k, _ in table},
                                  "faults_per_hour": {n: staged_faults.get(k, 0) / hours for n, k, _ in table},
                                  "system_per_hour_s": {n: staged_sys.get(k, 0.0) / hours for n, k, _ in table},
                                  "limit_per_hour_s": {n: lim for n, _, lim in table if lim},
                                  "per_test_fixed_s": {k: 2 * v for k, v in extras.items()},
                                  "rest_s": rest, "report_s": report_s, "identify_s": identify_s,
                                  "tire_fit_per_hour_s": None if tires is None else tires.seconds / hours,
                                  "tire_fit_cpu_per_hour_s": None if tires is None else tires.cpu_seconds / hours,
                                  "bandwidth_gb_s": bw / 1e9, "peak_gop_s": peak / 1e9,
                                  "regressor_ops_per_sample": ops, "machine": os.uname().machine,
                                  "cpus": os.cpu_count()})


if __name__ == "__main__":
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):  # one thread, BLAS included (as the pipeline's workers)
        main()
