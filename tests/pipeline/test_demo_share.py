"""`dynid demo`'s tests driven and written by two processes (pipeline.demo.simulate_and_write): the same files as
one process writes them, and the share each takes.

Oracles: the files `write_demo(simulate_tests())` writes in one process (the code before the share, to the byte);
the process ids that wrote each file; the shares worked out by hand from the plans' durations; idle time given.
"""

import subprocess
import sys
import textwrap

import pytest

from dynid.pipeline.demo import FORK_HEAD_START_S, IDLE_CORES, TESTS, cpu_times, forked_share, idle_cores

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork, /proc/stat: Linux only")


def test_the_forked_share_balances_the_plans_by_hand():
    full = [t[5] for t in TESTS]  # 20 30 10 8 8 8 s
    quick = [t[6] for t in TESTS]  # 12 15 10 8 8 8 s
    assert FORK_HEAD_START_S == 18.0
    # full: sine + spiral forked, 50 s, against 34 + 18 here (no split has its longer side under 52)
    assert forked_share(full) == [0, 1]
    # quick: spiral, lane, step, braking80 forked, 39 s, against 22 + 18 = 40 here (no three tests make 39-40 s)
    assert forked_share(quick) == [1, 3, 4, 5]
    assert forked_share([5.0], head_start=0.0) == []  # a tie: the fewer forked
    assert forked_share([5.0], head_start=10.0) == [0]


@pytest.mark.slow
@linux
def test_the_shared_files_are_one_processs_files_to_the_byte(tmp_path):
    # a fresh interpreter: the share forks only from a process of one thread (a test worker may hold thread pools)
    body = f"""
        import os
        from pathlib import Path
        import dynid.pipeline.demo as demo

        root = Path({str(tmp_path)!r})
        one = demo.write_demo(root / "one", demo.simulate_tests(quick=True))
        log = root / "writers.txt"
        write = demo.write_test

        def logged(result, path, **kw):
            with open(log, "a") as f:
                f.write(f"{{Path(path).stem}} {{os.getpid()}}\\n")
            return write(result, path, **kw)

        demo.write_test = logged
        two = demo.simulate_and_write(root / "two", quick=True, share=True)
        assert two.read_text() == one.read_text()
        names = sorted(p.name for p in (root / "one" / "data").iterdir())
        assert names == sorted(p.name for p in (root / "two" / "data").iterdir()) and len(names) == 12
        for n in names:
            assert (root / "one" / "data" / n).read_bytes() == (root / "two" / "data" / n).read_bytes(), n
        writers = dict(line.split() for line in log.read_text().splitlines())
        forked = {{demo.TESTS[i][1] for i in demo.forked_share([t[6] for t in demo.TESTS])}}
        assert {{k for k, pid in writers.items() if int(pid) != os.getpid()}} == forked, writers
        assert len(writers) == len(demo.TESTS)
    """
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]


def test_idle_cores_from_two_readings():
    assert idle_cores((100, 1000), (150, 1100), cores=2) == 1.0  # half the ticks idle: one core of two
    assert idle_cores((100, 1000), (100, 1100), cores=2) == 0.0
    assert idle_cores(None, (150, 1100), cores=2) == idle_cores((1, 2), (1, 2), cores=2) == 0.0  # unknown: none


@linux
def test_cpu_times_reads_the_machines_ticks():
    a = cpu_times()
    sum(i * i for i in range(300_000))  # some ticks of this process's
    b = cpu_times()
    assert a is not None and b is not None and 0 <= a[0] <= a[1] <= b[1] and a[0] <= b[0]


# a fresh interpreter's demo with the simulation stubbed: each test's file holds the id of the process that wrote it
STUBBED = """
import os
from pathlib import Path
import dynid.pipeline.demo as demo

demo._ready_simulator = lambda say, vehicle: None
demo._drive = lambda sim, test, quick, say, bars=None: test[1]
demo.preload = lambda: None


def write_test(result, path, **kw):
    Path(path).write_text(str(os.getpid()))


demo.write_test = write_test
"""


@linux
def test_the_tests_are_shared_only_when_a_core_was_idle(tmp_path):
    # the simulation and the files stubbed (each file says which process wrote it); a fresh interpreter: the share
    # forks only from a process of one thread
    body = STUBBED + textwrap.dedent(f"""
        cores = len(os.sched_getaffinity(0))
        for idle, forks in (({IDLE_CORES} - 0.05, False), ({IDLE_CORES} + 0.05, True)):
            ticks = iter([(0, 0), (round(1000 * idle / cores), 1000)])
            demo.cpu_times = lambda cpus=None: next(ticks)
            out = Path({str(tmp_path)!r}) / str(idle)
            demo.simulate_and_write(out)
            pids = {{p.stem: int(p.read_text()) for p in (out / "data").glob("*.csv")}}
            assert len(pids) == len(demo.TESTS)
            assert any(pid != os.getpid() for pid in pids.values()) == forks, (idle, pids)
    """)
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]


@linux
def test_a_child_killed_in_the_middle_of_a_file_leaves_no_temporary(tmp_path):
    """The forked process killed while it writes a file (kill -9, the OOM killer: no Python cleanup runs): this
    process writes that share itself, and data/ holds the tests' files and nothing else (the temporary the child
    left beside its file removed). Oracle: the file names one process writes. Old code: `.spiral.csv.<random>.tmp.csv`
    stayed, and went into the output folder."""
    body = f"""
        import os, signal
        from pathlib import Path
        import dynid.pipeline.demo as demo
        from dynid.atomic import atomic_path

        here = os.getpid()
        demo._ready_simulator = lambda say, vehicle: None
        demo._drive = lambda sim, test, quick, say, bars=None: test[1]
        demo.preload = lambda: None

        def write_test(result, path, **kw):
            with atomic_path(path) as tmp:
                tmp.write_text(result)
                if os.getpid() != here:
                    os.kill(os.getpid(), signal.SIGKILL)

        demo.write_test = write_test
        out = Path({str(tmp_path)!r})
        demo.simulate_and_write(out, share=True)
        names = sorted(p.name for p in (out / "data").iterdir())
        assert names == sorted(f"{{t[1]}}.csv" for t in demo.TESTS), names
    """
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]


@linux
def test_cpu_times_of_some_cores_add_up_to_the_machines():
    """Per-core readings (the process's allowed cores) against the machine's line: the cores' sum, read at once,
    is within a few ticks of it (the two readings are apart by a moment)."""
    import os

    every = range(os.cpu_count() or 1)
    (i0, t0), (i1, t1), (i2, t2) = cpu_times(), cpu_times(every), cpu_times()
    assert t0 - 50 <= t1 <= t2 + 50 and i0 - 50 <= i1 <= i2 + 50
    assert cpu_times({0})[1] < t1 or len(every) == 1  # one core's share of it


@linux
def test_no_share_on_one_allowed_core_of_an_idle_machine(tmp_path):
    """Pinned to one core (taskset -c 0, a container's cpuset), the machine's other cores idle: no share (both
    processes would take turns on that one core, more CPU for no time). Oracle: the writers' process ids. Old code:
    /proc/stat's whole-machine line times the one allowed core read half idle, and forked."""
    body = STUBBED + textwrap.dedent(f"""
        os.sched_setaffinity(0, {{0}})
        ticks = iter([(0, 0), (500, 1000)])  # the machine (2 cores): one idle, one this process's
        demo.cpu_times = lambda cpus=None: next(ticks)
        demo.simulate_and_write(Path({str(tmp_path)!r}))
        pids = {{int(p.read_text()) for p in (Path({str(tmp_path)!r}) / "data").glob("*.csv")}}
        assert pids == {{os.getpid()}}, pids
    """)
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]
