"""A first run's head starts (issue 28): the identification compiled while the simulator's kernel builds
(pipeline.first_run through vehicle.sim.car.while_kernel_builds), in a forked child (first_run.WarmUp) that goes on
while the demo simulates; the rest state solved once per process.

Oracles: the identification's own compile events in a fresh process (after the warm-up, identifying the demo's
files compiles nothing of dynid's); the rest state's own Newton solve (`_solve_rest`, uncached); the rest state
solved with the compiled engine (the code before statics.REST_ENGINE); a warm run's results against a cold one's.
"""

import contextlib
import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

from dynid.atomic import Terminated
from dynid.pipeline.first_run import WarmUp
from dynid.vehicle import statics
from dynid.vehicle.sim import car


def test_rest_state_is_solved_once_and_handed_out_as_copies(monkeypatch):
    tree = car.sim_tree()  # the simulator's truth
    solves = []
    solve = statics._solve_rest
    monkeypatch.setattr(statics, "_solve_rest", lambda *a: solves.append(a) or solve(*a))
    monkeypatch.setattr(statics, "_SOLVED", type(statics._SOLVED)())
    first = statics.rest_state(tree)
    first.q[:] = np.nan  # a caller's edit must not reach the next caller
    again = statics.rest_state(tree)
    assert len(solves) == 1
    oracle = solve(tree, statics.default_tables(), False, 0.0)
    assert np.array_equal(again.q, oracle.q) and np.array_equal(again.loads, oracle.loads)
    # what the solution depends on is in the key: another mass, the dampers held, another steering angle
    heavier = tree.with_values({"M6": tree.values["M6"] + 100.0})
    statics.rest_state(heavier)
    statics.rest_state(tree, fix_dampers=True)
    statics.rest_state(tree, steering_wheel=0.1)
    assert len(solves) == 4
    assert statics.rest_state(heavier).loads.sum() > oracle.loads.sum() + 900.0  # 100 kg more on the ground


class _Build:
    def __init__(self, log):
        self.log = log

    def wait(self):
        self.log.append("wait")


def test_tasks_run_while_a_build_is_awaited_and_never_fail_the_run(monkeypatch):
    log = []
    key = car._kernel_key()
    monkeypatch.setitem(car._PREBUILD, key, _Build(log))
    car.while_kernel_builds(lambda: log.append("task"))
    car.while_kernel_builds(lambda: 1 / 0)  # dropped: a head start only
    car.while_kernel_builds(lambda: log.append("after"))
    car.kernel_module()
    assert log == ["task", "after", "wait"]
    car.kernel_module()  # nothing awaited, nothing left to run
    assert log == ["task", "after", "wait"]


def test_a_build_whose_wait_is_interrupted_is_killed_at_exit(monkeypatch):
    """Oracle: the kernel's process table. A TERM (or a Ctrl-C to this process alone) while the run waits for the
    kernel's build raises out of kernel_module(); the build stays listed, so that what runs at exit
    (`_stop_prebuilds`) kills and reaps it, not left compiling (or a zombie) after the run ended. Before, the build
    was taken off the list before its wait. The build: a forked child that sleeps, in a `_Build` of its pid."""
    pid = os.fork()
    if pid == 0:  # the build: longer than the test
        try:
            time.sleep(60)
        finally:
            os._exit(0)
    build = object.__new__(car._Build)
    build.pid, build.proc = pid, None
    monkeypatch.setitem(car._PREBUILD, car._kernel_key(), build)
    with _reaping(pid) as alive:
        with _terminated_after(0.3), pytest.raises(Terminated):
            car.kernel_module()
        car._stop_prebuilds()  # as at exit
    assert alive == [False]


@contextlib.contextmanager
def _terminated_after(seconds: float):
    """Terminated raised after `seconds`, by an alarm's handler, as dynid's TERM handler raises it."""

    def interrupt(_signum, _frame):
        raise Terminated(signal.SIGTERM)

    old = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, seconds)
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@contextlib.contextmanager
def _reaping(pid: int):
    """Yields a list that holds, once the block is left, whether this process's child `pid` was still running then;
    one still running is killed (the old code's: not left behind by the test)."""
    alive = []
    try:
        yield alive
    finally:
        alive.append(_running(pid))
        if alive[0]:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)


def test_tasks_are_dropped_when_the_kernel_is_cached(monkeypatch):
    log = []
    monkeypatch.setattr(car, "kernel_cached", lambda module: True)
    car.while_kernel_builds(lambda: log.append("task"))
    assert car.prebuild_kernel() is False
    assert not car._MEANWHILE and not log


@pytest.fixture
def forkable(monkeypatch):
    """The warm-up's child made whatever other threads this test process has: an earlier test file on the same
    worker can leave an idle daemon thread behind (Dask's offload pool, for the process's life), and then can_fork()
    refuses, as it must in a run (test_no_fork_beside_another_thread); these tests are of the child's life."""
    import dynid.pipeline.first_run as first_run

    monkeypatch.setattr(first_run, "can_fork", lambda: sys.platform.startswith("linux"))


def _pid_to(path):
    """A warm-up task that writes the pid of the process it runs in."""
    return lambda: path.write_text(str(os.getpid()))


@pytest.mark.usefixtures("forkable")
def test_the_warm_up_runs_in_a_child_once_let_go_and_is_awaited(tmp_path):
    mark = tmp_path / "ran"
    warm = WarmUp(_pid_to(mark))
    assert warm.started
    time.sleep(0.2)
    assert not mark.exists()  # not before go()
    warm.go()
    warm.finish()
    assert mark.exists() and int(mark.read_text()) != os.getpid()  # done by finish(), in another process


@pytest.mark.usefixtures("forkable")
def test_a_warm_up_never_let_go_does_nothing_and_leaves_no_child(tmp_path):
    mark = tmp_path / "ran"
    warm = WarmUp(_pid_to(mark))
    pid = warm.pid
    warm.finish()
    assert not mark.exists()
    with pytest.raises(ChildProcessError):  # reaped
        os.waitpid(pid, os.WNOHANG)


@pytest.mark.usefixtures("forkable")
def test_a_stuck_warm_up_is_killed_after_the_timeout(tmp_path):
    warm = WarmUp(lambda: time.sleep(60))
    pid = warm.pid
    warm.go()
    t = time.monotonic()
    warm.finish(timeout=0.3)
    assert time.monotonic() - t < 10.0  # not the task's 60 s
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)


@pytest.mark.usefixtures("forkable")
def test_a_warm_up_awaited_when_this_process_is_interrupted_is_killed(tmp_path):
    """Oracle: the kernel's process table. A TERM (or a Ctrl-C to this process alone) that arrives while finish()
    waits raises out of it: the child is killed and reaped, not left compiling after this process ended (the old
    finish() dropped the child's pid before its wait, and `__del__` had none left to kill)."""
    warm = WarmUp(lambda: time.sleep(60))
    warm.go()
    with _reaping(warm.pid) as alive, _terminated_after(0.3), pytest.raises(Terminated):
        warm.finish()
    assert alive == [False]


@pytest.mark.usefixtures("forkable")
def test_an_interrupt_just_after_the_child_is_reaped_stays_the_interrupt(tmp_path, monkeypatch):
    """The TERM that arrives as finish()'s wait returns (the child reaped, its account not yet kept) is what finish()
    raises, not the ChildProcessError of a second reaping. Oracle: the exception's type; the interrupt made by a
    wait that reaps the ended child, then raises as dynid's TERM handler does."""
    import dynid.pipeline.first_run as first_run

    warm = WarmUp(lambda: None)
    warm.go()
    real = os.waitpid

    def wait_then_interrupted(pid, options):
        while real(pid, options)[0] == 0:  # the child's end awaited, and reaped
            time.sleep(0.01)
        raise Terminated(signal.SIGTERM)

    monkeypatch.setattr(first_run.os, "waitpid", wait_then_interrupted)
    with pytest.raises(Terminated):
        warm.finish()


def _running(pid: int) -> bool:
    """Whether this process's child `pid` is still running (False: ended and reaped, or never ours)."""
    try:
        return os.waitpid(pid, os.WNOHANG)[0] == 0
    except ChildProcessError:
        return False


def test_no_fork_beside_another_thread(tmp_path):
    """A second thread's locks would stay held in a fork's copy: no child; the caller runs the task itself."""
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        warm = WarmUp(_pid_to(tmp_path / "ran"))
    finally:
        stop.set()
        other.join()
    assert not warm.started
    warm.go()
    warm.finish()
    assert not (tmp_path / "ran").exists()


# a script's lines that list the process's compiles from then on in `compiled` (Numba's compile events)
LISTEN = textwrap.dedent("""
    from numba.core import event

    compiled = []

    class Listener(event.Listener):
        def on_start(self, ev):
            fn = getattr(ev.data.get("dispatcher"), "py_func", None)
            compiled.append(f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', '?')}")

        def on_end(self, ev):
            pass

    event.register("numba:compile", Listener())
""")

WARM_THEN_IDENTIFY = textwrap.dedent("""
    import sys

    from dynid.pipeline.demo import TESTS, demo_config
    from dynid.pipeline.first_run import warm_identification
    from dynid.pipeline.run import identify

    warm_identification("peugeot406", demo_config, [t[1] for t in TESTS])
""") + LISTEN + textwrap.dedent("""
    identify(sys.argv[1])
    print("COMPILED", sorted({c for c in compiled if c.startswith("dynid")}))
""")


@pytest.mark.slow
def test_after_the_warm_up_the_demos_identification_compiles_nothing(tmp_path):
    """The demo's files identified in a fresh process with empty caches after warm_identification: every kernel the
    identification calls was compiled by the warm-up (the same functions, types and generated model)."""
    env = {**os.environ, "DYNID_CACHE": str(tmp_path / "c1" / "dynid"), "NUMBA_CACHE_DIR": str(tmp_path / "c1" / "nb")}
    demo = tmp_path / "demo"
    subprocess.run([sys.executable, "-m", "dynid.cli.main", "demo", "--quick", "--out", str(demo)], env=env,
                   check=True, capture_output=True)
    env = {**env, "DYNID_CACHE": str(tmp_path / "c2" / "dynid"), "NUMBA_CACHE_DIR": str(tmp_path / "c2" / "nb")}
    proc = subprocess.run([sys.executable, "-c", WARM_THEN_IDENTIFY, str(demo / "identify.toml")], env=env,
                          check=True, capture_output=True, text=True)
    line = next(x for x in proc.stdout.splitlines() if x.startswith("COMPILED"))
    assert line == "COMPILED []"


PARENT_COMPILES_OF_A_COLD_DEMO = LISTEN + textwrap.dedent("""
    import sys

    from dynid.cli.main import main

    assert main(["demo", "--quick", "--out", sys.argv[1]]) == 0
    print("COMPILED", sorted({c for c in compiled if c.startswith("dynid")}))
""")


@pytest.mark.slow
def test_a_cold_demos_identification_compiles_in_the_warm_up_child(tmp_path):
    """A cold `dynid demo`: the process that runs it compiles none of the identification's kernels (the zero-phase
    filters, the corners' estimator, the block kernel), the warm-up child did (its compile events, in this process:
    the child's are not heard). Before first_run.WarmUp this process compiled them while it waited for the kernel."""
    env = {**os.environ, "DYNID_CACHE": str(tmp_path / "dynid"), "NUMBA_CACHE_DIR": str(tmp_path / "nb")}
    proc = subprocess.run([sys.executable, "-c", PARENT_COMPILES_OF_A_COLD_DEMO, str(tmp_path / "demo")], env=env,
                          check=True, capture_output=True, text=True)
    line = next(x for x in proc.stdout.splitlines() if x.startswith("COMPILED"))
    assert "dynid.vehicle.table_poly._table_joints" in line  # the listener hears the process's compiles
    for name in ("_zero_phase._filtfilt_columns", "estimate._corners_compiled", "dynid_blk_"):
        assert name not in line
    assert (tmp_path / "demo" / "results.json").exists()


def test_the_rest_state_on_the_reference_engine_matches_the_compiled_engines(monkeypatch):
    """statics.REST_ENGINE (NumPy) against the compiled engine the rest state used before: the same equilibrium to
    the solve's tolerance. Both residuals are the same equations to rounding (a few ulp of torques ~1e4 N.m, in kN:
    ~1e-15); root stops at a relative step of 1e-13 of x (|x| ~ 5: loads in kN, heights in m), so the two solutions
    may differ by ~1e-12 in x; the bounds take 100 x that (loads in N: 1e-9 x 4 kN)."""
    tree = car.sim_tree()
    tables = statics.default_tables()
    assert statics.REST_ENGINE == "numpy"
    ours = statics._solve_rest(tree, tables, False, 0.0)
    monkeypatch.setattr(statics, "REST_ENGINE", "numba")
    before = statics._solve_rest(tree, tables, False, 0.0)
    assert np.abs(ours.q - before.q).max() < 1e-10  # m and rad
    assert np.abs(ours.loads - before.loads).max() < 1e-9 * before.loads.max()
    monkeypatch.setattr(statics, "REST_ENGINE", "numpy")
    preloads = statics.design_preloads(tree)
    monkeypatch.setattr(statics, "REST_ENGINE", "numba")
    monkeypatch.setattr(statics, "_SOLVED", type(statics._SOLVED)())
    assert np.abs(preloads - statics.design_preloads(tree)).max() < 1e-9 * np.abs(preloads).max()


COMPILES_OF_A_SIMULATED_CAR = LISTEN + textwrap.dedent("""
    from dynid.vehicle.sim import car

    car.prebuild_kernel = lambda: False  # the kernel compiles here, listened to
    car.CarSimulator()
    print("COMPILED", sorted({c for c in compiled if c.startswith("dynid.")}))
""")


@pytest.mark.slow
def test_a_first_simulator_compiles_no_engine(tmp_path):
    """A simulator built with empty caches (a first `dynid demo`'s car: rest state, design preloads, yaw inertia)
    compiles nothing of the dynamics engine (dynamics.compiled, ~3.4 s of CPU for ~60 single samples): the
    compile events of a fresh process. Before statics.REST_ENGINE it compiled _idm_kernel and its helpers."""
    env = {**os.environ, "DYNID_CACHE": str(tmp_path / "dynid"), "NUMBA_CACHE_DIR": str(tmp_path / "nb")}
    proc = subprocess.run([sys.executable, "-c", COMPILES_OF_A_SIMULATED_CAR], env=env, check=True,
                          capture_output=True, text=True)
    line = next(x for x in proc.stdout.splitlines() if x.startswith("COMPILED"))
    assert "dynid.vehicle.table_poly._table_joints" in line  # the listener hears the process's compiles
    assert "dynid.dynamics." not in line


def _numbers(path):
    """The numbers of a demo's results.json but its provenance, the tire fit's seconds and paths (times, the run's
    own folders)."""
    res = json.loads(path.read_text())
    res.pop("provenance")
    res["tires"].pop("fit_seconds")
    res["tires"].pop("fit_cpu_seconds")
    return json.dumps(res, sort_keys=True).replace(str(path.parent), "OUT")


@pytest.mark.slow
def test_a_cold_demo_gives_a_warm_ones_results(tmp_path):
    """`dynid demo --quick` with empty caches, then again with the caches it filled: the same results, to the bit
    (what a first run compiles, or does not, changes no number)."""
    env = {**os.environ, "DYNID_CACHE": str(tmp_path / "dynid"), "NUMBA_CACHE_DIR": str(tmp_path / "nb")}
    runs = []
    for name in ("cold", "warm"):
        out = tmp_path / name
        subprocess.run([sys.executable, "-m", "dynid.cli.main", "demo", "--quick", "--out", str(out)], env=env,
                       check=True, capture_output=True)
        runs.append(out)
    assert _numbers(runs[0] / "results.json") == _numbers(runs[1] / "results.json")
    for f in sorted((runs[0] / "data").iterdir()):
        assert f.read_bytes() == (runs[1] / "data" / f.name).read_bytes(), f.name
