"""`dynid demo`: the paper's experiment on the simulated Peugeot 406, end to end.

The simulated car (the `truth` parameter set) is driven through the paper's tests and
recorded by its sensor suite (Table 1, seeded noise): a sine steer at 90 km/h and a
spiral, for identification, and a straight-line braking from 100 km/h, for
cross-validation. The logger files, their sidecars and the identification config are
written to `<out>/data` and `<out>/identify.toml` (run `dynid identify` on it again, or
edit it); the identification prints the paper's tables with the a priori, true and
estimated values and %σ, and writes the report, the figures and results.json.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..atomic import write_atomic
from .config import load_config
from .run import IdentificationRun, identify

Progress = Callable[[str], None]

TESTS = (  # name, manoeuvre, role, duration (s) full / quick
    ("sine steering 90 km/h", "sine", "identify", 20.0, 12.0),
    ("spiral 70 km/h", "spiral", "identify", 30.0, 15.0),
    ("straight-line braking from 100 km/h", "braking", "validate", 10.0, 10.0),
)


def demo_config(files: dict[str, str], known: dict[str, float], offsets: dict[str, float]) -> str:
    known_text = ", ".join(f"{k} = {v!r}" for k, v in known.items())
    offsets_text = ", ".join(f"{k} = {v!r}" for k, v in offsets.items())
    lines = ["# The simulated Peugeot 406 of `dynid demo`: rerun with `dynid identify identify.toml --out DIR`.",
             "", "[model]", 'template = "peugeot406"', ""]
    for (name, man, role, _, _), path in zip(TESTS, files.values(), strict=True):
        lines += ["[[tests]]", f'name = "{name}"', f'role = "{role}"', f'file = "{path}"']
        lines += [f'truth = "{Path(path).with_suffix(".json").as_posix()}"', ""] if man == "sine" else [""]
    lines += ["[conditioning]", "cutoff = 4.0", "order = 4", "decimate = [5, 10]", "attitude_crossover = 0.2", "",
              "[identification]", 'method = "wls"', 'base = "generic"',
              "# the wheels' masses and inertias, weighed and measured on a bench (see the tutorial)",
              f"known = {{ {known_text} }}", "",
              "[uncertainty]",
              "# the sensors' zero offsets (1 sigma, channel units: the suite's figures), propagated to %σ total",
              f"offsets = {{ {offsets_text} }}", ""]
    return "\n".join(lines)


def run_demo(out: Path, quick: bool = False, seed: int = 406, progress: Progress | None = None,
             simulation_progress=None) -> IdentificationRun:
    """Simulate, write the files and the config, identify; returns the identification."""
    from ..vehicle.sensors import paper_suite
    from ..vehicle.sim import CarSimulator
    from ..vehicle.sim.recording import write_test
    from .car import car_demo_known

    say = progress or (lambda _m: None)
    data = out / "data"
    data.mkdir(parents=True, exist_ok=True)
    say("building the simulated car (the first run compiles its models: about 30 s)")
    sim = CarSimulator()
    files = {}
    for i, (name, man, _, full, short) in enumerate(TESTS):
        duration = short if quick else full
        say(f"simulating {name} ({duration:g} s)")
        report, close = simulation_progress(duration) if simulation_progress else (None, lambda: None)
        try:
            result = sim.run(man, duration=duration, progress=report)
        finally:
            close()
        path, _ = write_test(result, data / f"{man}.csv", seed=seed + i)
        files[man] = path.relative_to(out).as_posix()
    offsets = {c.name: c.bias for c in paper_suite(sim.geometry) if c.bias}
    config = write_atomic(out / "identify.toml", demo_config(files, car_demo_known(sim.tree), offsets))
    return identify(load_config(config), progress=say)
