"""Benchmark: the paper's three tests (60 s of driving) simulated with the sensor suite.

    python benchmarks/bench_simulator.py

sine steering 20 s at 90 km/h, spiral 30 s at 70 km/h, straight-line braking 10 s from
100 km/h; each run gives the 59 sensor channels at 625 Hz (ideal channels from the
engine, then the error model). Prints the real-time factor (target >= 20x: <= 3 s),
the compile time (first run, in a fresh cache, in a subprocess) and the cached start-up,
the peak memory (max RSS); writes benchmarks/results/simulator.json.

First-run figures from before f4a2040 (27 Nov) do not compare with later ones: this benchmark then set only
DYNID_CACHE, so the engine's Numba functions (`_idm_kernel`, `_table_joints`, `eval_table`, `magic_formula`: ~5.5 s
of CPU, for the rest state) were loaded from the __pycache__ beside their source, warm after any earlier run. That,
not the shared kernel (7590bbd), made fddb8ab's "first run" 7.5-8.6 s against main's 12.1-13.8. Measured 29 Nov
(the start-up of a fresh interpreter: CarSimulator() and its first call, CPU with the kernel's build process, 3
runs alternated, load 10-15): engine cache warm, fddb8ab 11.5 s, main 10.1 s; both caches empty, fddb8ab 16.4 s,
main 15.5 s. Since then CarSimulator() itself starts the kernel's build in another process (car.prebuild_kernel),
as the demo did, so that a first run's two halves (kernel; rest state and models) overlap on two cores: the first
call then loads the kernel instead of compiling it (CPU 15.2 s, parent 7.8 + build 6.9-7.5).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE)]

from results_file import write_results  # noqa: E402

TESTS = (("sine", 20.0), ("spiral", 30.0), ("braking", 10.0))


def drive() -> dict:
    import numpy as np

    from dynid.vehicle.sensors import paper_suite
    from dynid.vehicle.sim import CarSimulator

    t0 = time.perf_counter()
    sim = CarSimulator()
    setup = time.perf_counter() - t0
    sim.run("sine", duration=0.01)  # first call: loads (or compiles) the machine code
    startup = time.perf_counter() - t0
    suite = paper_suite()
    out = {"setup_s": setup, "startup_s": startup, "compile": vars(sim.compile_info), "tests": {}}
    total_sim = total_sensors = 0.0
    for name, dur in TESTS:
        t1 = time.perf_counter()
        r = sim.run(name, duration=dur)
        t2 = time.perf_counter()
        suite.measure(r.ideal_channels(), np.random.default_rng(0))
        t3 = time.perf_counter()
        total_sim += t2 - t1
        total_sensors += t3 - t2
        out["tests"][name] = {"duration_s": dur, "simulate_s": t2 - t1, "sensors_s": t3 - t2}
    driving = sum(d for _, d in TESTS)
    out.update(driving_s=driving, simulate_s=total_sim, sensors_s=total_sensors, total_s=total_sim + total_sensors,
               real_time_factor=driving / (total_sim + total_sensors),
               peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)
    return out


def main() -> None:
    if "--child" in sys.argv:
        print(json.dumps(drive()))
        return
    with tempfile.TemporaryDirectory() as cache:  # first run: empty caches (dynid's and Numba's), everything compiled
        env = {**os.environ, "DYNID_CACHE": cache, "NUMBA_CACHE_DIR": f"{cache}/numba"}
        t0 = time.perf_counter()
        cold = json.loads(subprocess.run([sys.executable, __file__, "--child"], env=env, check=True,
                                         capture_output=True, text=True).stdout)
        cold["wall_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        warm = json.loads(subprocess.run([sys.executable, __file__, "--child"], env=env, check=True,
                                         capture_output=True, text=True).stdout)
        warm["wall_s"] = time.perf_counter() - t0
    res = {"command": "python benchmarks/bench_simulator.py", "tests": [list(t) for t in TESTS],
           "first_run_compile_s": cold["startup_s"], "cached_startup_s": warm["startup_s"], "cached": warm,
           "first": cold, "cpu_count": os.cpu_count()}
    print(f"60 s of driving (sine 20 s, spiral 30 s, braking 10 s) with the sensor suite: "
          f"{warm['total_s']:.2f} s (simulate {warm['simulate_s']:.2f} s, sensors {warm['sensors_s']:.2f} s), "
          f"real-time factor {warm['real_time_factor']:.1f}x (target >= 20x)")
    print(f"compile: first run {cold['startup_s']:.1f} s (empty cache); cached start-up {warm['startup_s']:.2f} s")
    print(f"peak memory (max RSS): {warm['peak_rss_mb']:.0f} MB")
    write_results("simulator", res)


if __name__ == "__main__":
    main()
