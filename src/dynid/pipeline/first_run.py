"""A first `dynid demo`'s identification compiled while the simulator's kernel compiles (issue 28).

On a first run (empty caches) the simulator's kernel compiles in a forked process
(vehicle.sim.car.prebuild_kernel) and this process, once the vehicle is loaded, would sleep
until it ends; the identification then compiles its own kernels (the block kernel of the
vehicle's identification model, the zero-phase filters, the kinematic tables' joints, the
corners' estimator) on the critical path. `warm_identification(vehicle)` runs one segment of
the demo's identification (the config the demo writes, the vehicle's channels, a second of a
car driving straight) through the estimator and the rows, so that those compile in that wait,
into the disk caches and this process. The numbers are thrown away: only the compiled code
stays, the same code the real run calls (same types, same generated model), so the results
do not change. Any error only costs the time: the real run compiles what is missing.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..vehicle.description import load_vehicle
from ..vehicle.estimate import required_channels
from ..vehicle.sim.car import SAMPLE_TIME
from .config import load_config
from .reduce import CarSetup, offset_changes

SECONDS = 2.0  # of synthetic driving: longer than the filters' borders at the demo's cut-off


def warm_identification(vehicle: str, config: Callable[[dict[str, str], str, dict[str, float]], str],
                        keys: Sequence[str]) -> None:
    """Compile what the identification of `vehicle` with the demo's config will call (module doc).
    config: (files: test key -> relative path, vehicle, offsets) -> the config's text (pipeline.demo.demo_config);
    keys: the tests' keys."""
    v = load_vehicle(vehicle)
    offsets = {c.name: c.bias for c in v.suite if c.bias}  # as pipeline.demo.write_demo writes them
    with tempfile.TemporaryDirectory(prefix="dynid-first-run-") as tmp:
        here = Path(tmp)
        (here / "data").mkdir()
        files = {}
        for key in keys:  # the config's loader reads only that the files exist
            for suffix in (".csv", ".json"):
                (here / "data" / f"{key}{suffix}").touch()
            files[key] = f"data/{key}.csv"
        where = Path(vehicle).resolve().as_posix() if vehicle.endswith(".toml") else vehicle
        (here / "identify.toml").write_text(config(files, where, offsets), encoding="utf-8")
        cfg = load_config(here / "identify.toml")
    setup = CarSetup(cfg)
    fs = 1.0 / SAMPLE_TIME
    channels = driving_channels(required_channels(suite=v.suite), v.geometry.wheel_radius, fs)
    compensated = setup.compensated(channels, fs, {})
    joints = setup.joints(channels, fs, {}, compensated)
    sys = setup.rows(joints.traj, fs)
    moved = [(n, b) for n, b in offsets.items() if n in channels]
    if moved:  # the offsets' rows: the one-pass estimator's other stages
        offset_changes(setup, channels, fs, {}, compensated, joints, sys, moved)


def driving_channels(names: list[str], radius: float, fs: float) -> dict[str, np.ndarray]:
    """SI channels of a car at 20 m/s with a small steer and roll (values of no consequence: what compiles depends
    only on the arrays' types, contiguous float64 as pipeline.sources.read_segment gives)."""
    t = np.arange(round(SECONDS * fs)) / fs
    wave = np.sin(2 * np.pi * 0.5 * t)
    out = {}
    for n in names:
        x = 0.01 * wave
        if n in ("correvit_vx", "gnss_vx"):
            x = 20.0 + 0.1 * wave
        elif n.startswith("wheel_speed_"):
            x = (20.0 + 0.1 * wave) / radius
        elif n == "imu_az":
            x = 9.81 + 0.1 * wave
        elif n.endswith("_Fz"):
            x = 3500.0 + 100.0 * wave
        elif n.startswith("laser_height_"):
            x = 0.3 + 0.001 * wave
        out[n] = np.ascontiguousarray(x, dtype=np.float64)
    return out
