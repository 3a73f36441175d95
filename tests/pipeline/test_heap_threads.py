"""pipeline.heap.tune_threads through LocalScheduler: the threads' jobs on one glibc arena whose freed top is kept
for the map's next jobs. Oracles: glibc's own count of its arenas (malloc_stats) and the kernel's count of this
process's minor page faults (getrusage), each in a fresh interpreter (the heap's settings are process-wide).

The old heap (an arena per thread, its top handed back beyond glibc's adaptive threshold, a trim every 8th job)
fails both: 3 arenas, and a map's page faults growing with its jobs (238k for 200 jobs, 13k for 8)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dynid.pipeline.heap import _glibc

SRC = str(Path(__file__).resolve().parents[2] / "src")

pytestmark = pytest.mark.skipif(_glibc() is None, reason="the heap's settings are glibc's (mallopt)")

PROBE = """
import ctypes, json, resource, sys
import numpy as np
from dynid.pipeline.schedulers import LocalScheduler

def job(i):  # a car segment's pattern: (N, 42) arrays and channel-sized ones (N = 38412, 60 s at 625 Hz), freed
    big = [np.full((38412, 42), float(i)) for _ in range(4)]
    small = [np.full(38412, float(k)) for k in range(60)]
    return sum(float(b[::97].sum()) for b in big) + sum(float(s[::97].sum()) for s in small)

def faults(n):
    f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    scheduler.map_reduce(job, list(range(n)), lambda j: 0, lambda a, b: a + b)
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0

scheduler = LocalScheduler(2)
faults(8)  # the heap grown once
out = {"8": faults(8), "100": faults(100)}
print(json.dumps(out), flush=True)
sys.stderr.flush()
ctypes.CDLL(None).malloc_stats()  # glibc's "Arena k:" per arena, on stderr
"""


@pytest.fixture(scope="module")
def probe() -> tuple[dict, str]:
    environ = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}
    environ.pop("GLIBC_TUNABLES", None)
    # BLAS starts its threads at NumPy's import, before the scheduler: one, so that a machine of many cores counts
    # the scheduler's arenas alone, not what BLAS threads may have made before it
    environ.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", PROBE], env=environ, check=True, capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1]), proc.stderr


def test_the_threads_share_one_arena(probe):
    _, stats = probe
    assert sum(line.startswith("Arena ") for line in stats.splitlines()) == 1


def test_a_maps_page_faults_do_not_grow_with_its_jobs(probe):
    # after the previous map's trim, the first jobs fault their arrays in (~140 MB for the two running); the later
    # ones reuse the freed heap: 12 x the jobs, not 12 x the faults (THP or 4 kB pages alike: a ratio; the 2000, 8 MB
    # of 4 kB pages, for the interpreter's own small allocations where huge pages leave few faults to compare)
    counts, _ = probe
    assert counts["100"] < 2 * counts["8"] + 2000, counts
