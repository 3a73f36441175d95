"""`dynid demo`: the paper's experiment on the simulated Peugeot 406 (or another vehicle file), end to end.

The simulated car (the vehicle file's [truth] set) is driven through five tests and recorded
by its sensor suite (Table 1, seeded noise): a sine steer at 90 km/h, a spiral and a
straight-line braking from 100 km/h, for identification, and a double lane change and a
step steer, for cross-validation (vehicle.notes.TEST_PLAN says why the braking moved). The logger files,
their sidecars and the identification config are written to `<out>/data` and
`<out>/identify.toml` (run `dynid identify` on it again, or edit it); the identification
prints the paper's tables with the a priori, true and estimated values and %σ, and writes
the report, the figures and results.json.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Collection, Sequence
from pathlib import Path

from ..atomic import remove_temporaries, write_atomic
from ..progress import notice_if_slow
from ..report.apart import Apart, can_fork
from ..report.figures import preload
from ..shipped import DEMO_VEHICLE
from ..vehicle.description import VehicleError, load_vehicle
from ..vehicle.notes import TEST_PLAN
from ..vehicle.sim import CarSimulator
from ..vehicle.sim.car import kernel_cached, prebuild_kernel, while_kernel_builds
from ..vehicle.sim.recording import write_test
from .config import load_config
from .first_run import WarmUp, warm_identification
from .run import IdentificationRun, identify

Progress = Callable[[str], None]

TESTS = (  # name, file, manoeuvre and its parameters, role, duration (s) full / quick
    ("sine steering 90 km/h", "sine", "sine", {}, "identify", 20.0, 12.0),
    ("spiral 70 km/h", "spiral", "spiral", {}, "identify", 30.0, 15.0),
    ("straight-line braking from 100 km/h", "braking", "braking", {}, "identify", 10.0, 10.0),
    ("double lane change 50 km/h", "lane", "lane", {}, "identify", 8.0, 8.0),
    ("step steer 80 km/h", "step", "step", {}, "validate", 8.0, 8.0),
    ("braking from 80 km/h at 4 m/s²", "braking80", "braking", {"speed": 80.0, "deceleration": 4.0,
                                                                 "front_share": 0.65}, "validate", 8.0, 8.0),
)


def demo_config(files: dict[str, str], vehicle: str, offsets: dict[str, float]) -> str:
    """The demo's identification config: its tests' files (test key -> path relative to the config), the vehicle (a
    shipped name or a vehicle file's absolute path, whose name the header says) and the zero offsets (1 σ)."""
    name = load_vehicle(vehicle).name
    lines = [f"# The simulated {name} of `dynid demo`: rerun with `dynid identify identify.toml --out DIR`.",
             "# Identified on the sine, spiral, braking (its heave separates the springs from the anti-roll bars)",
             "# and a lane change, cross-validated on a step steer and a gentler braking.",
             "", "[model]", "# the car: a shipped vehicle's name or a vehicle file (its geometry, tables, a priori and",
             "# known values: the wheels, weighed on a bench)", f"vehicle = {json.dumps(vehicle)}", ""]
    for (name, key, _, _, role, _, _), path in zip(TESTS, files.values(), strict=True):
        lines += ["[[tests]]", f'name = "{name}"', f'role = "{role}"', f'file = "{path}"']
        lines += [f'truth = "{Path(path).with_suffix(".json").as_posix()}"', ""] if key == "sine" else [""]
    return "\n".join(lines + conditioning_toml(offsets))


def conditioning_toml(offsets: dict[str, float], estimate: bool = True) -> list[str]:
    """The demo's conditioning, method and zero offsets (channel -> 1 σ, channel units) as a config's lines;
    estimate: each test's offsets estimated from its data (false: propagated only)."""
    offsets_text = ", ".join(f"{k} = {v!r}" for k, v in offsets.items())
    how = ("estimated from each test's data (their 1 sigma the prior); what the data leave is in %σ total"
           if estimate else "propagated to %σ total")
    return ["[conditioning]", "cutoff = 4.0", "order = 4", "decimate = [5, 10]", "attitude_crossover = 0.2", "",
            "[identification]", 'method = "wls"', 'base = "generic"', "",
            "[uncertainty]",
            f"# the sensors' zero offsets (1 sigma, channel units: the suite's figures), {how}",
            f"offsets = {{ {offsets_text} }}", *([] if estimate else ["estimate = false"]), ""]


def simulated_car(vehicle: str = DEMO_VEHICLE):
    """The simulator of a vehicle (a shipped name or a vehicle file) driven with its [truth] set."""

    prebuild_kernel()  # a first run: the simulator's kernel compiles in another process while the vehicle loads
    v = load_vehicle(vehicle)
    if v.truth is None:
        raise VehicleError(f"{v.source}: no [truth] set: a simulation needs the parameters to drive with (give "
                           "[truth], e.g. the a priori values: copy [a_priori] there)")
    return CarSimulator(v.truth, v.geometry, v.tables, v.aero, steering_ratio=v.steering_ratio,
                        damper_knees=v.damper_knees, name=v.name)


# a car's models loaded from the cache take about a second: a build still running after SLOW_BUILD_S is generating
# them (a new vehicle, a new dynid, an empty cache), which is said then, and only then
SLOW_BUILD_S = 3.0
# what a user waits for on a first run, measured 29 Nov after the rest state moved to the NumPy engine (statics.
# REST_ENGINE: no engine compile): a cold `dynid demo` with each message stamped, CPU seconds on a 2-core machine loaded
# 7-13x, which inflates them (a free machine's wall time is about these or less). This process reaches the written
# files at 10.7 s of CPU cold against 4.0 s warm (+6.7: "building the car" 7.0 s, the car's models generated and the
# identification compiled, pipeline.first_run), while the kernel's build takes 7.1 s in a forked process (vehicle.sim.
# car.prebuild_kernel): the two end together, so a first demo takes ~7 s more than a later one (said as 8; the whole
# run 16.6 s CPU here cold, 10.3 s warm; 69ee46f, with the engine's compile: 21.4 s, +11.6 s to the files), the longest
# silent step ~7 s (said as 8). Then the identification's warm-up moved to a forked child (pipeline.first_run.WarmUp),
# which takes this process's core while it sleeps for the kernel and goes on while it simulates: one cold demo each,
# f15571e then this, messages stamped with this process's CPU (load 2-5): "writing the 6 logger files" at 7.8 s
# against 4.5 s (a warm run 4.0), the kernel's build 5.3 and 5.8 s of CPU; this process now waits for the kernel alone
# (the warm-up's overrun of it, 0.3-0.7 s of CPU before, off the critical path). A new vehicle once the kernel is
# cached: `dynid simulate sine` of the compact SUV after one of the 406, 4.4 s against 12.5 s before the kernel was
# shared (whole-process timing, 3 pairs)
FIRST_RUN_S, GENERATE_S, COMPILE_S, NEW_VEHICLE_S = 8, 8, 8, 2
FIRST_RUN = (f"first run: dynid compiles its simulator and identification for this machine (about {FIRST_RUN_S} s "
             "more than a later run on a free 2-core machine; cached for later runs)")
GENERATING = (f"building the car: the simulator's kernel compiles on the other core while the car's models are "
              f"generated and, in a demo, the identification compiles (once per dynid version, about {GENERATE_S} s "
              f"on a free machine; a new vehicle's models about {NEW_VEHICLE_S} s; cached for later runs)")
COMPILING = (f"compiling the simulator's kernel (first run only, about {COMPILE_S} s on a free core; cached for "
             "later runs)")
LOADING = f"loading the simulator's compiled kernel (about {COMPILE_S} s of compiling if it is not cached)"


def compile_notice(sim: CarSimulator) -> str | None:
    """What to say before the simulator's first call (None: nothing, its kernel is cached)."""
    pending = compile_pending(sim)
    return None if pending is False else COMPILING if pending else LOADING


def compile_pending(sim) -> bool | None:
    """Whether the simulator's first call will compile its kernel: numba has no cache index for it yet (True),
    has one (False), or cannot tell (None: numba absent, or its internals changed)."""
    cached = kernel_cached(sim.module)
    return None if cached is None else not cached


def simulate_tests(quick: bool = False, progress: Progress | None = None, simulation_progress=None,
                   vehicle: str = DEMO_VEHICLE) -> dict:
    """The demo's tests driven by the simulated car: file key -> SimulationResult (noise-free motion)."""
    say = progress or (lambda _m: None)
    sim = _ready_simulator(say, vehicle)
    return {test[1]: _drive(sim, test, quick, say, simulation_progress) for test in TESTS}


def _ready_simulator(say: Progress, vehicle: str) -> CarSimulator:
    """The vehicle's simulator, its kernel compiled or loaded (said when that takes a while)."""
    say("building the simulated car")
    with notice_if_slow(SLOW_BUILD_S, GENERATING, say):
        sim = simulated_car(vehicle)
    notice = compile_notice(sim)
    if notice:  # numba compiles at the first call: seconds of silence unless announced
        say(notice)
    sim.run(TESTS[0][2], duration=2 * sim.settings.dt, **TESTS[0][3])  # two samples: compiles, or loads the cache
    return sim


def _drive(sim: CarSimulator, test: tuple, quick: bool, say: Progress, simulation_progress=None):
    """One of TESTS driven (its short duration if quick), said and shown as it goes."""
    name, _, man, params, _, full, short = test
    duration = short if quick else full
    say(f"simulating {name} ({duration:g} s of driving)")
    report, close = simulation_progress(duration) if simulation_progress else (None, lambda: None)
    try:
        return sim.run(man, duration=duration, progress=report, **params)
    finally:
        close()


# A warm demo drives and writes its tests on one core while the other idles (the kernel holds the GIL): a forked
# process (report.apart) takes a share of them. Each test costs about its duration (simulation and file alike: the
# full plan's 84 s of driving 2.1 s of CPU, 29 Nov); this process also imports matplotlib for the report meanwhile
# (0.45 s of CPU, as much as FORK_HEAD_START_S of driving), which would otherwise wait on the report's path. A warm
# demo with and without the share, 4 alternated pairs at load 1.7-2.3 (whole processes, medians): wall 6.93 -> 5.80 s
# (pair ratio 0.85), CPU 8.46 -> 8.55 s (+1.9 %: the pages both processes write are copied).
FORK_HEAD_START_S = 18.0


def forked_share(durations: Sequence[float], head_start: float = FORK_HEAD_START_S) -> list[int]:
    """The tests (indices) a forked process drives: the split whose longer side is the shortest, this process's
    side counting `head_start` seconds of driving more (its other work); on a tie, the fewer forked."""
    n = len(durations)
    best: tuple[float, int, int] | None = None
    for mask in range(1 << n):
        forked = sum(d for i, d in enumerate(durations) if mask >> i & 1)
        key = (max(head_start + sum(durations) - forked, forked), bin(mask).count("1"), mask)
        best = key if best is None or key < best else best
    assert best is not None
    return [i for i in range(n) if best[2] >> i & 1]


# On a busy machine the second process finds no free core: it adds CPU (+2.3 % of a warm demo: 4 alternated pairs
# at load 4.3, no wall time gained) instead of taking wall time off. It is forked only when the machine's idle time
# while this process builds the car (0.4 s warm) adds up to IDLE_CORES of a core, this process's own core aside.
IDLE_CORES = 0.5


def cpu_times(cpus: Collection[int] | None = None) -> tuple[int, int] | None:
    """The (idle, total) CPU time so far in clock ticks of the cores `cpus` (their /proc/stat lines; None: the
    machine's, all cores); None where unknown."""
    wanted = None if cpus is None else {f"cpu{c}" for c in cpus}
    idle = total = 0
    try:
        with open("/proc/stat") as f:
            for line in f:
                name, *fields = line.split()
                if not name.startswith("cpu"):
                    break  # the cpu lines come first
                if (name != "cpu") if wanted is None else (name not in wanted):
                    continue
                ticks = [int(x) for x in fields]
                if len(ticks) < 5:
                    return None
                idle += ticks[3] + ticks[4]  # idle + iowait; user .. steal (guest time is inside user)
                total += sum(ticks[:8])
    except (OSError, ValueError):
        return None
    return (idle, total) if total else None


def idle_cores(before: tuple[int, int] | None, after: tuple[int, int] | None, cores: int) -> float:
    """How many of `cores` were idle on average between two `cpu_times()` readings (0 when unknown)."""
    if before is None or after is None or after[1] <= before[1]:
        return 0.0
    return cores * (after[0] - before[0]) / (after[1] - before[1])


def simulate_and_write(out: Path, quick: bool = False, seed: int = 406, progress: Progress | None = None,
                       simulation_progress=None, vehicle: str = DEMO_VEHICLE, share: bool | None = None) -> Path:
    """`write_demo(out, simulate_tests(...))`, the same files, with a share of the tests driven and written by a
    forked process where one can be (`report.apart.can_fork`) and is worth it (share; None: when a core was idle
    while the car was built, IDLE_CORES), while this process drives the others and imports the report's plotting;
    returns the config's path."""
    say = progress or (lambda _m: None)
    # the cores this process may run on (taskset, a container's cpuset): the machine's others idle are no use to it
    cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    before = cpu_times(cpus)
    sim = _ready_simulator(say, vehicle)
    if share is None:
        cores = len(cpus) if cpus is not None else os.cpu_count() or 1
        share = cores > 1 and idle_cores(before, cpu_times(cpus), cores) >= IDLE_CORES
    suite = load_vehicle(vehicle).suite
    (out / "data").mkdir(parents=True, exist_ok=True)
    durations = [short if quick else full for *_, full, short in TESTS]
    forked = forked_share(durations) if share and can_fork() else []

    def drive_and_write(indices: Sequence[int], tell: Progress, bars=None) -> None:
        results = {i: _drive(sim, TESTS[i], quick, tell, bars) for i in indices}
        if bars is not None:  # this process: said once its share is driven
            say(f"writing the {len(TESTS)} logger files (the sensor suite, seeded noise) to data/ and identify.toml")
        for i, result in results.items():
            write_test(result, out / _file(TESTS[i][1], "csv"), seed=seed + i, noise=True, suite=suite)

    other = None
    if forked:
        names = ", ".join(TESTS[i][0] for i in forked)
        say(f"simulating {names} ({sum(durations[i] for i in forked):g} s of driving) in a second process")
        other = Apart(lambda: drive_and_write(forked, lambda _m: None))
    try:
        drive_and_write([i for i in range(len(TESTS)) if i not in forked], say, simulation_progress or _no_bar)
        if other is not None:
            preload()  # the report's plotting imported while the other process finishes (report.figures)
            other.result()  # its files written (or, had it failed, written here now)
            # a child killed in the middle of a file (kill -9, the kernel's OOM killer) left its temporary beside it;
            # no writer is left in data/ now
            remove_temporaries(out / "data")
    except BaseException:
        if other is not None:
            other.cancel()  # no file written into a folder the caller removes
        raise
    return _write_config(out, {t[1]: _file(t[1], "csv") for t in TESTS}, suite, noise=True, vehicle=vehicle)


def _no_bar(_duration: float):
    return None, lambda: None


def _file(key: str, fmt: str) -> str:
    return f"data/{key}.{fmt}"


def write_demo(out: Path, results: dict, seed: int = 406, noise: bool = True, fmt: str = "csv",
               vehicle: str = DEMO_VEHICLE) -> Path:
    """The logger files of the simulated tests (sensor noise seeded by seed + the test's index, or none) and
    the identification config in `out` (for `vehicle`: a shipped name, or a vehicle file, written as an absolute
    path); returns the config's path."""

    suite = load_vehicle(vehicle).suite  # the sensors the vehicle file says are fitted
    data = out / "data"
    data.mkdir(parents=True, exist_ok=True)
    files = {}
    for i, (key, result) in enumerate(results.items()):
        path, _ = write_test(result, data / f"{key}.{fmt}", seed=seed + i, noise=noise, suite=suite)
        files[key] = path.relative_to(out).as_posix()
    return _write_config(out, files, suite, noise, vehicle)


def _write_config(out: Path, files: dict[str, str], suite, noise: bool, vehicle: str) -> Path:
    """identify.toml in `out`: the tests' files (key -> path relative to out), the suite's offsets if noisy."""
    offsets = {c.name: c.bias for c in suite if c.bias} if noise else {}
    where = Path(vehicle).resolve().as_posix() if vehicle.endswith(".toml") else vehicle
    return write_atomic(out / "identify.toml", demo_config(files, where, offsets))


def run_demo(out: Path, quick: bool = False, seed: int = 406, progress: Progress | None = None,
             simulation_progress=None, vehicle: str = DEMO_VEHICLE) -> IdentificationRun:
    """Simulate, write the files and the config, identify; returns the identification."""
    say = progress or (lambda _m: None)
    warm = None
    if prebuild_kernel():  # a first run: the identification compiles in a child on idle time (pipeline.first_run)
        def task() -> None:
            warm_identification(vehicle, demo_config, [t[1] for t in TESTS])

        warm = WarmUp(task)  # it starts once this process waits for the kernel; without fork, runs here then
        while_kernel_builds(warm.go if warm.started else task)
    try:
        share = None if warm is None else False  # a first run's warm-up child has the other core: no share then
        config = simulate_and_write(out, quick, seed, say, simulation_progress, vehicle, share)
    except BaseException:
        if warm is not None:
            warm.finish(timeout=0.0)  # no identification to come: the child killed at once
        raise
    if warm is not None:
        warm.finish()  # its compiles are in the disk caches: the identification loads them
    run = identify(load_config(config), progress=say)
    run.notes = TEST_PLAN + run.notes
    return run
