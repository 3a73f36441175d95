"""A first run's head starts (issue 28): the identification compiled while the simulator's kernel builds
(pipeline.first_run through vehicle.sim.car.while_kernel_builds), the rest state solved once per process.

Oracles: the identification's own compile events in a fresh process (after the warm-up, identifying the demo's
files compiles nothing of dynid's); the rest state's own Newton solve (`_solve_rest`, uncached).
"""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

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


def test_tasks_are_dropped_when_the_kernel_is_cached(monkeypatch):
    log = []
    monkeypatch.setattr(car, "kernel_cached", lambda module: True)
    car.while_kernel_builds(lambda: log.append("task"))
    assert car.prebuild_kernel() is False
    assert not car._MEANWHILE and not log


WARM_THEN_IDENTIFY = textwrap.dedent("""
    import sys
    from numba.core import event

    from dynid.pipeline.demo import TESTS, demo_config
    from dynid.pipeline.first_run import warm_identification
    from dynid.pipeline.run import identify

    warm_identification("peugeot406", demo_config, [t[1] for t in TESTS])
    compiled = []

    class Listener(event.Listener):
        def on_start(self, ev):
            fn = getattr(ev.data.get("dispatcher"), "py_func", None)
            compiled.append(f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', '?')}")

        def on_end(self, ev):
            pass

    event.register("numba:compile", Listener())
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
