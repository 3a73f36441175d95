"""What the data health check adds to an identification: on the demo and on one hour of 625 Hz car data; with
--robot, on the TX40's measured files (when ../shared/data/tx40 is there) and on one hour of a TX40's 500 Hz log.

Run:  python benchmarks/bench_health.py [--repeat 3] [--minutes 60] [--skip-hour] [--robot]

Writes, once and not timed, the demo's six tests (the simulated 406 with the sensor suite, `dynid demo`'s
files) and `--minutes` of the sensor suite's channels (Parquet, as bench_pipeline.py: a 12 s manoeuvre
repeated; its still wheel forces are said as warnings, `data_health = "warn"`). Then, in this process,
after one warm-up run of each (imports, the vehicle, the generated models and the files' index loaded),
`identify` on this machine's threads alternately with and without the check, `--repeat` times each:

- with: as `dynid identify` runs (each segment of the first map scans the part of its test it answers for,
  `pipeline.health.segment_health`; the findings judged before the estimate is solved);
- without: the same identification, its jobs carrying no health part and `check_car_tests` a no-op.

A robot's check: each channel read from its file before the map (`check_robot_test`), the joints against the
model gathered by the map's chunks (`gather_joints`) and judged after it (`check_robot_joints`); without: both
no-ops and the chunks gathering nothing. The robot's hour: a TX40 on six sines (plus slow ones) for `--minutes`,
torques from its model plus 0.3 N.m of noise, Parquet.

Alternating the two in one process makes them share the machine's load. Both the wall time and the
process's CPU time (every thread's: the work done, which other processes' load moves far less than the
wall time on a shared machine) are measured; the median of each is compared and the ratios of the
medians printed. The issue's target (issue 30): the check adds at most 10 % to an identification.
Writes benchmarks/results/health.json.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

from bench_pipeline import CONFIG, write_hour  # noqa: E402
from results_file import write_results  # noqa: E402

TARGET = 0.10  # the check adds at most this share of an identification's time (issue 30)


@contextlib.contextmanager
def without_health():
    """The identification with no health gathered in its segments or chunks and no findings judged."""
    import dynid.pipeline.run as run

    saved = (run.reduce_car_segment, run.check_car_tests, run.reduce_robot_chunk, run.check_robot_test,
             run.check_robot_joints)
    car, robot = run.reduce_car_segment, run.reduce_robot_chunk
    run.reduce_car_segment = lambda job: car(dataclasses.replace(job, health=None))
    run.reduce_robot_chunk = lambda job: robot(dataclasses.replace(job, health=False))
    run.check_car_tests = run.check_robot_test = run.check_robot_joints = lambda *a, **k: []
    try:
        yield
    finally:
        (run.reduce_car_segment, run.check_car_tests, run.reduce_robot_chunk, run.check_robot_test,
         run.check_robot_joints) = saved


ROBOT = """[model]
example = "tx40"

[[tests]]
name = "hour"
role = "identify"
files = {{ q = "{file}", tau = "{file}" }}

[channels]
q = {{ channels = ["q1", "q2", "q3", "q4", "q5", "q6"], unit = "rad" }}
tau = {{ channels = ["tau1", "tau2", "tau3", "tau4", "tau5", "tau6"], unit = "N.m" }}

[conditioning]
cutoff = 20.0
order = 4
decimate = [5, 2]
"""


def write_robot_hour(folder: Path, minutes: float) -> Path:
    """`minutes` of a TX40's 500 Hz log (module doc) and its config; returns the config."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from dynid import load_model

    model, fs = load_model("tx40"), 500.0
    t = np.arange(int(minutes * 60 * fs)) / fs
    q = np.stack([0.5 * np.sin(2 * np.pi * (0.3 + 0.1 * j) * t + j) + 0.2 * np.sin(2 * np.pi * 0.07 * (j + 1) * t)
                  for j in range(6)], axis=1)
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    step = 200_000
    tau = np.concatenate([model.inverse_dynamics(q[i:i + step], qd[i:i + step], qdd[i:i + step])
                          for i in range(0, t.size, step)])
    tau += 0.3 * np.random.default_rng(1).standard_normal(tau.shape)
    cols = {"time": t} | {f"q{j + 1}": q[:, j] for j in range(6)} | {f"tau{j + 1}": tau[:, j] for j in range(6)}
    pq.write_table(pa.table(cols), folder / "robot_hour.parquet", row_group_size=65536)
    config = folder / "robot_hour.toml"
    config.write_text(ROBOT.format(file="robot_hour.parquet"))
    return config


def timed_runs(config: Path, repeat: int) -> dict:
    """Wall and CPU times (s) of `identify` with and without the check, alternated, after a warm-up run."""
    from dynid.pipeline.config import load_config
    from dynid.pipeline.run import identify

    cfg = load_config(config)
    found = identify(cfg).health  # warm-up: imports, the vehicle, the models, the file's index
    walls: dict[str, list[float]] = {"with": [], "without": []}
    cpus: dict[str, list[float]] = {"with": [], "without": []}
    for k in range(repeat):
        for label in (("with", "without") if k % 2 == 0 else ("without", "with")):
            with without_health() if label == "without" else contextlib.nullcontext():
                t, c = time.perf_counter(), time.process_time()
                identify(cfg)
                walls[label].append(time.perf_counter() - t)
                cpus[label].append(time.process_time() - c)
    med = {k: statistics.median(v) for k, v in walls.items()}
    cpu = {k: statistics.median(v) for k, v in cpus.items()}
    return {"wall_with_s": walls["with"], "wall_without_s": walls["without"], "cpu_with_s": cpus["with"],
            "cpu_without_s": cpus["without"], "median_wall_with_s": med["with"],
            "median_wall_without_s": med["without"], "added_wall": med["with"] / med["without"] - 1.0,
            "median_cpu_with_s": cpu["with"], "median_cpu_without_s": cpu["without"],
            "added_cpu": cpu["with"] / cpu["without"] - 1.0, "findings": len(found or [])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs with and without the check, each (median taken)")
    ap.add_argument("--minutes", type=float, default=60.0, help="length of the long file")
    ap.add_argument("--skip-hour", action="store_true", help="the demo only")
    ap.add_argument("--robot", action="store_true", help="the robot's cases instead of the car's")
    args = ap.parse_args()
    from dynid.pipeline.demo import simulate_tests, write_demo

    res: dict = {"repeat": args.repeat, "cpus": os.cpu_count(), "machine": os.uname().machine, "target": TARGET}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        tx40 = HERE.parent / "examples" / "tx40" / "identify.toml"
        if args.robot:
            cases = {"TX40 measured files (45,000 samples at 5 kHz)": tx40} if (
                HERE.parent.parent / "shared" / "data" / "tx40" / "curr_data.csv").exists() else {}
            if not args.skip_hour:
                cases[f"{args.minutes:g} min of a TX40's 500 Hz log"] = write_robot_hour(folder, args.minutes)
        else:
            cases = {"demo (6 tests, 84 s of data)": write_demo(folder / "demo", simulate_tests())}
        if not args.skip_hour and not args.robot:
            data = write_hour(folder, args.minutes, "parquet")
            config = folder / "hour.toml"
            config.write_text(CONFIG.format(file=data.name))
            cases[f"{args.minutes:g} min of 625 Hz data"] = config
        print(f"identify on this machine's threads, with and without the data health check, alternated "
              f"{args.repeat} time(s) each, medians (s); target: at most +{100 * TARGET:.0f} %")
        for name, config in cases.items():
            r = res[name] = timed_runs(config, args.repeat)
            print(f"  {name} ({r['findings']} finding(s) listed)")
            for what in ("cpu", "wall"):
                added = r[f"added_{what}"]
                print(f"    {what + ' time':<10} with {r[f'median_{what}_with_s']:7.2f}  without "
                      f"{r[f'median_{what}_without_s']:7.2f}  added {100 * added:+6.1f} %"
                      f"  ({'within' if added <= TARGET else 'OVER'} the target)")
    write_results("health_robot" if args.robot else "health", res)


if __name__ == "__main__":
    main()
