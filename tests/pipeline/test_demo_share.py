"""`dynid demo`'s tests driven and written by two processes (pipeline.demo.simulate_and_write): the same files as
one process writes them, and the share each takes.

Oracles: the files `write_demo(simulate_tests())` writes in one process (the code before the share, to the byte);
the process ids that wrote each file; the shares worked out by hand from the plans' durations.
"""

import subprocess
import sys
import textwrap

import pytest

from dynid.pipeline.demo import FORK_HEAD_START_S, TESTS, forked_share


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
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork: Linux only")
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
        two = demo.simulate_and_write(root / "two", quick=True)
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
