"""The MuJoCo test car of ../shared/data/mujoco-car/ through `dynid identify` with the example's vehicle file
(examples/mujoco_car/): what tests/e2e/test_mujoco_car.py and tests/e2e/test_mujoco_chassis.py share."""

import csv
import json
from pathlib import Path

import pytest
from conftest import SHARED

from dynid.cli.main import main

DATA = SHARED / "data" / "mujoco-car"
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "mujoco_car"
TESTS = {"sine": "sine steering 90 km/h", "spiral": "spiral 70 km/h", "braking": "straight-line braking from 100 km/h"}


def mujoco_truth() -> dict:
    """truth.json, or the test skipped when the data are not beside the repository."""
    if not (DATA / "truth.json").exists():
        pytest.skip(f"the MuJoCo car's data not found at {DATA} (shared/ is beside the repository in CI)")
    return json.loads((DATA / "truth.json").read_text())


EXAMPLE_TIRE = 'tire_law = "progressive"\ntire_lateral_force = true\n'  # the example's [wheels] lines


def identify(tmp: Path, folder: str, tests: list[str], compensate_delays: bool, tire: str = "example",
             conditioning: str = "") -> tuple[dict, dict]:
    """results.json and engineering.csv's values by key, of the example's vehicle on `tests` of `folder`.
    tire: "example" (the file's progressive law with the lateral-force term), "progressive" (without that term) or
    "paper" (the paper's line kt q + off); conditioning: more lines of the config's [conditioning] (TOML)."""
    vehicle = EXAMPLE / "vehicle.toml"
    if tire != "example":
        text = vehicle.read_text()
        assert text.count(EXAMPLE_TIRE) == 1
        lines = {"progressive": 'tire_law = "progressive"\n', "paper": ""}[tire]
        vehicle = tmp / f"vehicle_{tire}.toml"
        (tmp / "kinematics.toml").write_text((EXAMPLE / "kinematics.toml").read_text())  # its [tables] file
        vehicle.write_text(text.replace(EXAMPLE_TIRE, lines))
    lines = ['[model]', f'vehicle = "{vehicle.as_posix()}"']
    for t in tests:
        lines += ["[[tests]]", f'name = "{TESTS[t]}"', 'role = "identify"',
                  f'file = "{(DATA / folder / f"{t}.parquet").as_posix()}"']
    lines += ["[conditioning]", "cutoff = 4.0", "order = 4", "decimate = [5, 10]", "attitude_crossover = 0.2",
              f"compensate_delays = {'true' if compensate_delays else 'false'}", conditioning,
              *([] if "min_speed" in conditioning else ["min_speed = 0.02"]),  # the example's (its comment says why)
              "[identification]", 'method = "wls"', 'base = "generic"', "aero = false"]
    if folder == "ideal":  # the true channel values: no zero offsets to estimate (declared, the estimate would read
        lines += ["[uncertainty]", 'offsets = "none"']  # the model's misfits into them: 0.3 mm of CoG here)
    cfg = tmp / f"{folder}_{'_'.join(tests)}_{tire}{'_c' if conditioning else ''}.toml"
    cfg.write_text("\n".join(lines) + "\n")
    out = tmp / cfg.stem
    assert main(["identify", str(cfg), "--out", str(out)]) == 0
    res = json.loads((out / "results.json").read_text())
    with open(out / "engineering.csv", newline="") as f:
        eng = {r["key"]: float(r["value"]) for r in csv.DictReader(f)}
    return res, eng
