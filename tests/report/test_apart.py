"""report.apart: a value computed in a forked child, or here when it cannot be. Oracles: the process ids (where it
ran), the value computed here, and the kernel's process table (a dropped child is gone)."""

import gc
import os
import sys
import threading
import time

import numpy as np
import pytest

from dynid.report.apart import Apart

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork: Linux only")


@linux
def test_the_value_is_computed_in_another_process_and_equals_this_ones():
    here = os.getpid()
    rng = np.random.default_rng(1)
    a = rng.normal(size=(300, 40))
    job = Apart(lambda: (os.getpid(), a @ a.T))
    pid, value = job.result()
    assert pid != here
    assert np.array_equal(value, a @ a.T)  # the same bits: the same code on a copy of the same memory


@linux
def test_a_failing_child_leaves_the_work_to_this_process():
    here = os.getpid()

    def fn():
        if os.getpid() != here:
            raise RuntimeError("the child's failure")
        return "here"

    assert Apart(fn).result() == "here"
    with pytest.raises(ZeroDivisionError):  # an error of fn itself is raised here, as a call here would
        Apart(lambda: 1 / 0).result()


def test_no_fork_beside_another_thread():
    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        job = Apart(os.getpid)
        assert job.pid is None and job.result() == os.getpid()
    finally:
        stop.set()
        t.join()


@linux
def test_a_dropped_job_leaves_no_child_running():
    job = Apart(lambda: time.sleep(60))
    pid = job.pid
    assert pid is not None
    del job
    gc.collect()
    with pytest.raises(ChildProcessError):  # killed and reaped: no such child any more
        os.waitpid(pid, os.WNOHANG)
