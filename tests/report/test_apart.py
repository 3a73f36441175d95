"""report.apart: a value computed in a forked child, or here when it cannot be. Oracles: the process ids (where it
ran), the value computed here, and the kernel's process table (a dropped child is gone)."""

import os
import subprocess
import sys
import textwrap
import threading

import pytest

from dynid.report.apart import Apart

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork: Linux only")


def in_a_fresh_process(body: str) -> None:
    """Run `body` in a new interpreter: Apart forks only from a process of one thread, and a test worker may hold
    threads that earlier test files left (thread pools), which made these tests depend on the files' order."""
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]


@linux
def test_the_value_is_computed_in_another_process_and_equals_this_ones():
    in_a_fresh_process("""
        import os
        import numpy as np
        from dynid.report.apart import Apart
        a = np.random.default_rng(1).normal(size=(300, 40))
        job = Apart(lambda: (os.getpid(), a @ a.T))
        pid, value = job.result()
        assert pid != os.getpid()
        assert np.array_equal(value, a @ a.T)  # the same bits: the same code on a copy of the same memory
    """)


@linux
def test_the_childs_collections_leave_the_inherited_heap_alone():
    """gc.freeze before the fork: a collection in the child does not scan the objects it inherited, so it does not
    write into (copy) their pages: the kernel's count of the child's page faults during gc.collect() stays far
    under the heap's pages (old code: about one per page, ~9000 here); this process collects its objects again
    (unless it had frozen them itself)."""
    in_a_fresh_process("""
        import gc, resource
        from dynid.report.apart import Apart
        heap = [[i] for i in range(400_000)]  # tracked objects: ~40 MB, ~10k pages

        def faults_of_a_collection():
            before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
            gc.collect()
            return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before, gc.get_freeze_count()

        faults, frozen = Apart(faults_of_a_collection).result()
        assert frozen >= len(heap) and faults < 1000, (faults, frozen)
        assert gc.get_freeze_count() == 0  # here: unfrozen after the fork
        gc.freeze()  # a freeze of this process's own stays as it was
        frozen = gc.get_freeze_count()
        assert Apart(lambda: 1).result() == 1 and gc.get_freeze_count() >= frozen > 0
    """)


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
@pytest.mark.parametrize("end", ["del job; gc.collect()", "job.cancel(); job.cancel()"], ids=["dropped", "cancelled"])
def test_a_dropped_or_cancelled_job_leaves_no_child_running_and_its_work_undone(end):
    """A job dropped uncollected (the caller raised), or cancelled (at once, even while a caller that raised still
    holds it in its frame: the folder its child writes into is about to be removed): its child killed and reaped,
    its work never done; a second cancel does nothing."""
    in_a_fresh_process(f"""
        import gc, os, tempfile, time
        from pathlib import Path
        from dynid.report.apart import Apart
        mark = Path(tempfile.mkdtemp()) / "late"
        job = Apart(lambda: (time.sleep(1.0), mark.write_text("written")))
        pid = job.pid
        assert pid is not None
        {end}
        try:  # killed and reaped: no such child any more
            os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            pass
        else:
            raise AssertionError("the job's child is still there")
        time.sleep(1.5)
        assert not mark.exists()
    """)
