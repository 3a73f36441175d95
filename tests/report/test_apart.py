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


# given to every fresh process: a job's child `pid` killed and reaped (no such child left), the file `mark` its work
# would write never written (its 1 s sleep is over)
GONE = """
import os as _os, time as _time


def gone_undone(pid, mark):
    try:
        _os.waitpid(pid, _os.WNOHANG)
    except ChildProcessError:
        pass
    else:
        raise AssertionError("the job's child is still there")
    _time.sleep(1.5)
    assert not mark.exists()
"""


def in_a_fresh_process(body: str) -> None:
    """Run `body` in a new interpreter: Apart forks only from a process of one thread, and a test worker may hold
    threads that earlier test files left (thread pools), which made these tests depend on the files' order."""
    out = subprocess.run([sys.executable, "-c", GONE + textwrap.dedent(body)], capture_output=True, text=True,
                         timeout=120)
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
        gone_undone(pid, mark)
    """)


@linux
@pytest.mark.parametrize("when", ["fork", "registered"], ids=["during the fork", "before the job holds its child"])
def test_a_signal_raised_as_the_job_starts_leaves_no_child_running(when):
    """Ctrl-C or TERM while the process forks (they are held across the fork, so their handler raises as they are
    let through, before the caller has the job) or just after it: the child killed and reaped, its work never done.
    Oracle: the kernel's process table and the file the child would have written. Old code: the raise came out of
    fork() with the child's pid lost, and the child ran on (wrote its file into a folder being removed)."""
    in_a_fresh_process(f"""
        import os, signal, tempfile, time
        from pathlib import Path
        import dynid.report.apart as apart

        class Stop(Exception):
            pass

        def stop(_s, _f):
            raise Stop
        signal.signal(signal.SIGINT, stop)
        mark = Path(tempfile.mkdtemp()) / "late"
        children = []
        real_fork, real_finalize = os.fork, apart.weakref.finalize

        def fork():  # the signal arrives while the fork is under way
            pid = real_fork()
            if pid:
                children.append(pid)
                os.kill(os.getpid(), signal.SIGINT)
            return pid

        def finalize(*args):  # the signal arrives just before the job keeps its child
            os.kill(os.getpid(), signal.SIGINT)
            return real_finalize(*args)
        if {when!r} == "fork":
            apart.os.fork = fork
        else:
            apart.os.fork = lambda: children.append(real_fork()) or children[-1]
            apart.weakref.finalize = finalize
        try:
            apart.Apart(lambda: (time.sleep(1.0), mark.write_text("written")))
        except Stop:
            pass
        else:
            raise AssertionError("the signal was not raised")
        pid, = children
        gone_undone(pid, mark)
    """)


@linux
def test_the_child_takes_ctrl_c_and_term_as_this_process_does():
    """The signals held while the job starts are let through in the child (else a Ctrl-C or TERM sent to it would
    wait for its end). Oracle: the child's own signal mask, as the kernel reports it."""
    in_a_fresh_process("""
        import signal
        from dynid.report.apart import Apart
        blocked = Apart(lambda: signal.pthread_sigmask(signal.SIG_BLOCK, set())).result()
        assert signal.SIGINT not in blocked and signal.SIGTERM not in blocked, blocked
    """)
