"""Vehicle files: reading one and building its models (warm), a new vehicle's first run, the demo of a shipped one.

Run:  python benchmarks/bench_vehicle.py

1. `load_vehicle` + the template's tree + its Model + the base-parameter analysis, warm (best of 5), for each
   shipped vehicle. Target <= 1 s.
2. A vehicle never run before: the shipped compact SUV with its wheelbase moved by 1 mm (a new tree, so the
   simulator's generated models are built and compiled), `dynid demo --quick --vehicle FILE` in a child process
   with an empty dynid cache (Numba's per-machine cache of the generic kernels kept, as on any second vehicle).
   Target <= 40 s. The same command for the shipped SUV, warm, for reference.
3. `dynid demo --vehicle compact_suv` warm (full test plan). Target <= 30 s.
Writes benchmarks/results/vehicle.json.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE)]

from results_file import write_results  # noqa: E402


def build_models(name: str) -> float:
    from dynid.dynamics import Model
    from dynid.vehicle import car_template
    from dynid.vehicle.description import load_vehicle
    from dynid.vehicle.equations import car_base_parameters

    t = time.perf_counter()
    v = load_vehicle(name)
    tree = car_template(v.geometry, v.a_priori.values, name=v.name)
    tree = tree.with_values(v.known).with_known(set(v.known))
    Model(tree)
    car_base_parameters(tree, "generic")
    return time.perf_counter() - t


def demo(args: list[str], env: dict[str, str] | None = None) -> float:
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "dynid.cli.main", "demo", *args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})})
    if proc.returncode:
        sys.exit(f"dynid demo {' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    return time.perf_counter() - t


def main() -> None:
    from dynid.vehicle.description import shipped_vehicles, vehicle_path

    res: dict[str, float] = {}
    for name in shipped_vehicles():
        build_models(name)  # warm: imports, caches of the base-parameter analysis' kernels
        best = res[f"read and build {name} (warm)"] = min(build_models(name) for _ in range(5))
        print(f"read {name}, build its tree, model and base parameters (warm)  {best:.3f} s   target <= 1 s")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        text = vehicle_path("compact_suv").read_text(encoding="utf-8")
        text = text.replace("wheelbase_m = 2.79", "wheelbase_m = 2.791")
        new = folder / "new_suv.toml"
        new.write_text(text, encoding="utf-8")
        res["first run of a new vehicle (demo --quick, models compiled)"] = demo(
            ["--quick", "--vehicle", str(new), "--out", str(folder / "new")], {"DYNID_CACHE": str(folder / "cache")})
        print(f"a new vehicle's first run: dynid demo --quick --vehicle FILE   "
              f"{res['first run of a new vehicle (demo --quick, models compiled)']:.1f} s   target <= 40 s", flush=True)
        res["shipped SUV, demo --quick, warm"] = demo(["--quick", "--vehicle", "compact_suv", "--out",
                                                       str(folder / "quick")])
        print(f"the same with the shipped SUV, warm                              "
              f"{res['shipped SUV, demo --quick, warm']:.1f} s", flush=True)
        demo(["--vehicle", "compact_suv", "--out", str(folder / "warmup")])
        res["demo --vehicle compact_suv, warm"] = demo(["--vehicle", "compact_suv", "--out", str(folder / "full")])
        print(f"dynid demo --vehicle compact_suv, warm                           "
              f"{res['demo --vehicle compact_suv, warm']:.1f} s   target <= 30 s", flush=True)
    write_results("vehicle", {"command": "python benchmarks/bench_vehicle.py", **res})


if __name__ == "__main__":
    main()
