"""What the data health check adds to an identification: on the demo and on one hour of 625 Hz car data.

Run:  python benchmarks/bench_health.py [--repeat 3] [--minutes 60] [--skip-hour]

Writes, once and not timed, the demo's six tests (the simulated 406 with the sensor suite, `dynid demo`'s
files) and `--minutes` of the sensor suite's channels (Parquet, as bench_pipeline.py: a 12 s manoeuvre
repeated; its still wheel forces are said as warnings, `data_health = "warn"`). Then, in this process,
after one warm-up run of each (imports, the vehicle, the generated models and the files' index loaded),
`identify` on this machine's threads alternately with and without the check, `--repeat` times each:

- with: as `dynid identify` runs (each segment of the first map scans the part of its test it answers for,
  `pipeline.health.segment_health`; the findings judged before the estimate is solved);
- without: the same identification, its jobs carrying no health part and `check_car_tests` a no-op.

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
    """The identification with no health gathered in its segments and no findings judged."""
    import dynid.pipeline.run as run

    reduce, check = run.reduce_car_segment, run.check_car_tests
    run.reduce_car_segment = lambda job: reduce(dataclasses.replace(job, health=None))
    run.check_car_tests = lambda *a, **k: []
    try:
        yield
    finally:
        run.reduce_car_segment, run.check_car_tests = reduce, check


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
    args = ap.parse_args()
    from dynid.pipeline.demo import simulate_tests, write_demo

    res: dict = {"repeat": args.repeat, "cpus": os.cpu_count(), "machine": os.uname().machine, "target": TARGET}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cases = {"demo (6 tests, 84 s of data)": write_demo(folder / "demo", simulate_tests())}
        if not args.skip_hour:
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
    write_results("health", res)


if __name__ == "__main__":
    main()
