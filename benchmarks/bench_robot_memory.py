"""A robot's identification memory is bounded by its factors, not its rows (issue 25 item 1): peak RSS of
`dynid identify` on a long log of a 7-joint arm (default 1 h at 1 kHz: 3.6 M samples, 14 channels).

    PYTHONPATH=src python benchmarks/bench_robot_memory.py [--seconds 3600] [--rate 1000] [--folder DIR]

The log (the Panda arm of example-robot-data's URDF, five harmonics per joint, torques by its inverse dynamics,
Parquet with a time column) is written once into --folder by a first process (kept for the next run); a second
process runs the identification alone and prints its own peak resident set (ru_maxrss), beside the same
process's RSS after the imports, and the identification's wall time. Target: under 300 MB.

Measured 2026-11-27 on the 2-core machine, busy: 1 h, 251,986 rows of 43 parameters, peak 529 MiB against main's
601 at 77e8e1a (farm-bench medians of 3, A B A B in one run; CPU 0.97 x, wall 1.04 x, noisy), 937 MB at 54648a4 and
1,056 MB at 212feaf (the rows stacked whole). What went: pandas (pyarrow's to_numpy imports it to check for it:
the columns now come from their Arrow buffers, io/parquet_format.to_numpy), the heap the plan's pass over the
stamps left (trimmed after each test's plan), half of each worker's block of the full-rate W (8 MiB; 4 MiB cost
+6.6 % CPU). Not met: the process's floor is ~265 MB before any row, measured as resident-set steps: 172 MB of
imports (NumPy 27, scipy.linalg 28, scipy.signal 48 with the scipy.stats, interpolate and optimize it imports,
Numba 53, dynid 17), pyarrow 29 on the first read, Numba's code generator set up on the first compiled call 47 (its
functions are cached on disk: loading them still builds the target), cvxpy 17 (the physical-consistency check
of a WLS estimate solves for a realisable standard set: `estimation.physical.feasible_standard`, so a robot run
with the pc extra installed does use it). On top: the plan's pass over 3.6 M stamps (`pipeline.timebase.stream`,
`io.windows`' Parquet stamps) holds the stamps and at most two arrays of their size (29 MB each; it held up to
four, and read the file's stamps twice, for q and for tau): that phase peaks at 318 MB against 396 (RSS sampled in one
identify run each, busy), traced 84 MiB against 166 for the plan alone, under the map's, so the process's peak
stays the map's (529 MiB against 542 before, farm-bench medians of 2, A B A B in one run, noisy). During the map
each of the 2 workers holds ~60 MB traced (its chunk's joints, the first stage's output, one block), the clock
29 MB, the Parquet block cache ~22 MB, the plots' rows (`run.PLOT_BYTES`). The levers left are outside the data
path: scipy.signal's import (dynid uses butter and the sosfilt family, which Numba already runs for it), Numba
on a robot's path, the map's per-worker blocks.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ARM = [f"panda_joint{i}" for i in range(1, 8)]
CONFIG = """
[model]
file = "arm.toml"

[[tests]]
name = "long"
files = {{ q = "{log}", tau = "{log}" }}

[channels]
q = {{ channels = {q}, unit = "rad" }}
tau = {{ channels = {tau}, unit = "N*m" }}

[conditioning]
cutoff = 20.0
decimate = [10, 10]
"""

WRITE = """
import sys
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(sys.argv[4]) / "tests"))
from test_urdf import robot_file
from dynid import Model
from dynid.io import Channel, Recording, write_recording
from dynid.model import save_tree
from dynid.model.urdf import import_urdf

folder, seconds, rate = Path(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
arm = import_urdf(robot_file("panda"), joints=[f"panda_joint{i}" for i in range(1, 8)]).tree
save_tree(arm, folder / "arm.toml")
n = int(round(seconds * rate))
t = np.arange(n) / rate
rng = np.random.default_rng(2)
w = 2 * np.pi * 0.1 * np.arange(1, 6)
a, b = rng.normal(0, 0.6, (2, 7, 5)) / np.arange(1, 6)
q, tau = np.empty((n, 7)), np.empty((n, 7))
model = Model(arm)
for s in range(0, n, 200_000):  # a block at a time: the writer's memory is not measured, but kept sane
    tt = t[s:s + 200_000]
    sn, cs = np.sin(np.multiply.outer(tt, w)), np.cos(np.multiply.outer(tt, w))
    q[s:s + 200_000] = sn @ a.T + cs @ b.T
    qd = (cs * w) @ a.T - (sn * w) @ b.T
    qdd = -(sn * w**2) @ a.T - (cs * w**2) @ b.T
    tau[s:s + 200_000] = model.inverse_dynamics(q[s:s + 200_000], qd, qdd)[:, :7]
chans = [Channel(f"q{j + 1}", "rad", q[:, j], t) for j in range(7)]
chans += [Channel(f"tau{j + 1}", "N*m", tau[:, j], t) for j in range(7)]
write_recording(Recording.from_channels(chans), folder / "long.parquet")
"""

RUN = """
import json, resource, sys, time, warnings
from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify
warnings.simplefilter("ignore")
after_imports = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
t0 = time.perf_counter()
run = identify(load_config(sys.argv[1]))
wall = time.perf_counter() - t0
print(json.dumps({"peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "imports_mb": after_imports, "wall_s": wall, "rows": run.result.residual.n_rows,
                  "parameters": len(run.result.estimated_names),
                  "direct_overall": run.errors["direct"]["overall"]}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--folder", type=Path, default=Path(tempfile.gettempdir()) / "dynid_bench_robot_memory")
    args = ap.parse_args()
    root = Path(__file__).resolve().parents[1]
    folder = args.folder / f"{args.seconds:g}s_{args.rate:g}Hz"
    folder.mkdir(parents=True, exist_ok=True)
    if not (folder / "long.parquet").exists():
        print(f"writing the log ({args.seconds:g} s at {args.rate:g} Hz, 7 joints) into {folder}", flush=True)
        subprocess.run([sys.executable, "-c", WRITE, str(folder), str(args.seconds), str(args.rate), str(root)],
                       check=True)
    q = json.dumps([f"q{j}" for j in range(1, 8)])
    tau = json.dumps([f"tau{j}" for j in range(1, 8)])
    (folder / "identify.toml").write_text(CONFIG.format(log="long.parquet", q=q, tau=tau))
    out = subprocess.run([sys.executable, "-c", RUN, str(folder / "identify.toml")], check=True,
                         capture_output=True, text=True).stdout
    r = json.loads(out.strip().splitlines()[-1])
    verdict = "met" if r["peak_mb"] < 300 else "MISSED"
    print(f"robot identification, {args.seconds:g} s at {args.rate:g} Hz, 7 joints: {r['rows']} rows, "
          f"{r['parameters']} parameters, {r['wall_s']:.1f} s")
    print(f"  peak RSS {r['peak_mb']:.0f} MB (after the imports {r['imports_mb']:.0f} MB); target < 300 MB: {verdict}")


if __name__ == "__main__":
    main()
