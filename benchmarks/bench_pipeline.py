"""One hour of 625 Hz car data through `dynid identify`: reading, conditioning, decimating, identifying.

Run:  python benchmarks/bench_pipeline.py [--minutes 60] [--format parquet]

Builds an hour of the sensor suite's channels (a 12 s manoeuvre of the simulator's sensor
definition, repeated: throughput, not accuracy, is measured here), writes it once (not
timed), then runs `dynid identify` on it in a child process and reports the wall time of
each stage (from the progress lines), the total, and the child's peak resident memory.
Targets: reading + conditioning + decimating <= 20 s (issue 6), identification (everything after
reading: joints, equations, decimation, least squares) <= 10 s (issue 7), peak <= 2 GB.
Writes benchmarks/results/pipeline.json.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
# the tests' helpers (tests/) and the estimator test's trajectory (tests/vehicle/, the tests being grouped by layer)
sys.path[:0] = [str(HERE), str(HERE.parent / "tests"), str(HERE.parent / "tests" / "vehicle")]

from results_file import write_results  # noqa: E402


def manoeuvre_channels() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """12 s of the sensor suite's noise-free channels along a known smooth trajectory (the estimator test's)."""
    from test_vehicle_estimate import smooth_drive

    _, t, _, _, _, _, channels = smooth_drive()
    return t, channels


def write_hour(folder: Path, minutes: float, fmt: str) -> Path:
    from dynid.io import Channel, Recording, write_recording
    from dynid.vehicle.sensors import paper_suite

    t0, ch = manoeuvre_channels()
    reps = int(np.ceil(minutes * 60 / 12))
    t = np.arange(len(t0) * reps) / 625.0
    units = paper_suite().units
    rec = Recording.from_channels([Channel(k, units[k], np.tile(v, reps), t) for k, v in ch.items() if k in units])
    return write_recording(rec, folder / f"hour.{fmt}")


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

[uncertainty]  # the streaming of the hour is timed: the offsets' propagation, a fixed cost (two segments per test,
offsets = "none"  # docs/tutorial.md "Sensor zero offsets"), left out as before they became the default
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--format", default="parquet", choices=["parquet", "csv", "mf4"])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        t = time.perf_counter()
        data = write_hour(folder, args.minutes, args.format)
        print(f"wrote {args.minutes:g} min of 625 Hz channels ({data.stat().st_size / 1e6:.0f} MB {args.format}) "
              f"in {time.perf_counter() - t:.1f} s (not timed)")
        cfg = folder / "identify.toml"
        cfg.write_text(CONFIG.format(file=data.name))
        child = ("import sys, time\n"
                 "from dynid.pipeline.config import load_config\n"
                 "from dynid.pipeline.run import identify\n"
                 "t0 = time.perf_counter()\n"
                 "def say(m): print(f'{time.perf_counter() - t0:8.2f} {m}', flush=True)\n"
                 f"run = identify(load_config({str(cfg)!r}), progress=say)\n"
                 "say('done')\n"
                 # the child's own high-water mark: ru_maxrss starts at the parent's (which built the hour) at fork
                 "print('maxrss_kb', next(ln for ln in open('/proc/self/status') if ln.startswith('VmHWM:'))"
                 ".split()[1])\n")
        t = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True)
        if proc.returncode:
            sys.exit(f"the identification failed:\n{proc.stderr[-3000:]}")
        out = proc.stdout
        total = time.perf_counter() - t
    lines = out.splitlines()
    stamps = [(float(ln.split()[0]), ln.split(maxsplit=1)[1]) for ln in lines if ln[:8].strip()[:1].isdigit()]
    read = next(s for s, m in stamps if ": read " in m)
    estimating = next(s for s, m in stamps if m.startswith("estimating"))
    done = next(s for s, m in stamps if m == "done")
    peak = int(next(ln for ln in lines if ln.startswith("maxrss_kb")).split()[1]) / 1e6
    res = {"minutes": args.minutes, "format": args.format, "read_s": read,
           "condition_and_decimate_s": estimating - read, "least_squares_s": done - estimating,
           "identification_s": done - read, "total_s": done, "process_s": total, "peak_rss_gb": peak,
           "machine": os.uname().machine, "cpus": os.cpu_count()}
    print(f"reading the file (config, checks, units)       {res['read_s']:7.2f} s")
    print(f"joints, 14 equations, parallel decimation      {res['condition_and_decimate_s']:7.2f} s")
    print(f"weighted least squares                         {res['least_squares_s']:7.2f} s")
    print(f"identification (everything after reading)     {res['identification_s']:7.2f} s   target <= 10 s")
    print(f"total: reading, conditioning, decimating, LS   {res['total_s']:7.2f} s   target <= 20 s"
          f"   (process with imports {total:.1f} s)")
    print(f"peak resident memory                           {peak:7.2f} GB   target <= 2 GB")
    write_results("pipeline", res)


if __name__ == "__main__":
    main()
