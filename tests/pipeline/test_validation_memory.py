"""Validation tests do not accumulate memory (issue 30, item 3: 200 validation tests once took 1.2 GB).

- the threads' scheduler folds results as they arrive: the same shape (so the same bits) as `tree_fold`, whatever
  order the jobs finish in.
- a robot config with many validation tests, run in a child (tracemalloc, one worker so that the chunks in flight
  at the peak are the same in both runs): the peak of `identify` grows with the number of validation tests by no
  more than each test's plan (its clock and its file's index, held until the map ends), and the outputs' peak not
  at all beyond the report's own noise (it draws the same first few tests); the tests' factors are folded per
  role as they arrive (`run.robot_systems`), the cross validation comes from the streamed factors (`StreamingLS`).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest
from test_data_health import robot_log

from dynid.pipeline.schedulers import LocalScheduler, tree_fold


def test_the_threads_fold_has_tree_folds_shape():
    """Jobs finishing in a shuffled order (their sleeps), two keys: each key's fold as `tree_fold` of its results in
    the jobs' order (a combine that writes its shape: the same string is the same tree)."""
    rng = np.random.default_rng(1)
    n = 37
    delays = rng.uniform(0, 0.004, n)
    jobs = list(range(n))

    def work(j):
        time.sleep(delays[j])
        return str(j)

    def combine(a, b):
        return f"({a} {b})"

    got = LocalScheduler(3).map_reduce(work, jobs, lambda j: j % 3 == 0, combine)
    for key in (True, False):
        assert got[key] == tree_fold([str(j) for j in jobs if (j % 3 == 0) == key], combine)


CHILD = """
import json, sys, tracemalloc
from pathlib import Path
from dynid.pipeline.config import load_config
from dynid.pipeline.run import identify, write_outputs
from dynid.pipeline.schedulers import LocalScheduler
identify(load_config(sys.argv[1]))  # imports and caches outside the measure
tracemalloc.start()
run = identify(load_config(sys.argv[2]), scheduler=LocalScheduler(1))
peak = tracemalloc.get_traced_memory()[1]
tracemalloc.reset_peak()
write_outputs(run, Path(sys.argv[3]), "memory")
outputs = tracemalloc.get_traced_memory()[1]
s = run.identify
print(json.dumps({"peak": peak, "outputs": outputs,
                  "test_rows": s.W.nbytes + s.Y.nbytes + s.t.nbytes + s.groups.nbytes,
                  "shown": list(run.validate), "cross": run.errors["cross"]}))
"""


def _config(folder, n_validation: int):
    text = (folder / "robot.toml").read_text()
    tests = "".join(f'[[tests]]\nname = "check {i}"\nrole = "validate"\n'
                    'files = { q = "log.csv", tau = "log.csv" }\n\n' for i in range(n_validation))
    path = folder / f"robot_{n_validation}.toml"
    path.write_text(text.replace("[channels]", tests + "[channels]"))
    return path


@pytest.mark.slow
@pytest.mark.e2e
def test_one_worker_reads_a_staged_functions_next_job_ahead():
    """Oracle: `tree_fold` of the function's plain results in the jobs' order (a combine that writes its shape). On
    one worker a `Staged` function's first stage of job i + 1 starts on another thread when job i's finish, on the
    calling thread, says it is ready, not before (each finish but the last waits for it: on a scheduler that ran
    the stages one after the other it would time out), the finishes in the jobs' order."""
    import threading

    from dynid.pipeline.schedulers import Staged

    n, caller = 9, threading.get_ident()
    started = [threading.Event() for _ in range(n)]
    where: dict[str, set[int]] = {"first": set(), "finish": set()}
    order = []

    def first(j):
        started[j].set()
        where["first"].add(threading.get_ident())
        return str(j)

    def finish(j, got, ready):
        assert got == str(j)
        if j + 1 < n:
            assert not started[j + 1].is_set(), f"job {j + 1}'s first stage started before job {j} was ready"
            ready()
            assert started[j + 1].wait(30), f"job {j + 1}'s first stage not started while job {j} finishes"
            ready()  # a second call starts nothing more
        where["finish"].add(threading.get_ident())
        order.append(j)
        return got

    def combine(a, b):
        return f"({a} {b})"

    got = LocalScheduler(1).map_reduce(Staged(first, finish), list(range(n)), lambda j: j % 2, combine)
    assert got == {k: tree_fold([str(j) for j in range(n) if j % 2 == k], combine) for k in (0, 1)}
    assert order == list(range(n))
    assert where["finish"] == {caller} and caller not in where["first"]
    assert Staged(first, finish)(n - 1) == str(n - 1)  # called plainly (any other scheduler): finish(job, first(job))


def test_peak_memory_does_not_grow_with_the_validation_tests(tmp_path):
    from dynid.pipeline.run import SHOWN_VALIDATION

    robot_log(tmp_path, noise=0.5)
    warm = _config(tmp_path, 0)
    few, many = SHOWN_VALIDATION + 2, SHOWN_VALIDATION + 18
    out = {}
    for n in (few, many):
        args = [str(warm), str(_config(tmp_path, n)), str(tmp_path / f"o{n}")]
        proc = subprocess.run([sys.executable, "-c", CHILD, *args], capture_output=True, text=True, timeout=900)
        assert proc.returncode == 0, proc.stderr[-2000:]
        out[n] = json.loads(proc.stdout.strip().splitlines()[-1])
    one_test = out[few]["test_rows"]  # a validation test's rows are the identification test's (the same log)
    samples = len((tmp_path / "log.csv").read_text().splitlines()) - 1
    extra = many - few
    # what a validation test legitimately holds until the map ends: its plan (the clock and the CSV index's stamps
    # and line offsets, 8 bytes a sample each) and a few kB of job, health and names; measured 41 to 55 kB a test
    # (3000 samples). Before, each test's per-joint factors waited for the end (210 kB a test); accumulating the
    # rows would add a test's rows (1.7 MB) per test
    per_test = 3 * 8 * samples + 16 * 2**10
    growth = out[many]["peak"] - out[few]["peak"]
    assert growth < extra * per_test, (growth, extra * per_test, out[few]["peak"], out[many]["peak"])
    # the outputs draw and write the same first SHOWN_VALIDATION tests: their peak varies by the report's own
    # allocations (measured +-2 MB between runs, either way), far below the extra tests' rows (16 x 1.7 MB)
    assert out[many]["outputs"] - out[few]["outputs"] < 2 * one_test, (out[few]["outputs"], out[many]["outputs"])
    assert len(out[many]["shown"]) == SHOWN_VALIDATION
    # the same log in every test: the cross errors over 10 or 26 copies are the same numbers
    assert out[many]["cross"] == pytest.approx(out[few]["cross"], rel=1e-9)
    notes = json.loads((tmp_path / f"o{many}" / "results.json").read_text())
    assert "health" in notes
