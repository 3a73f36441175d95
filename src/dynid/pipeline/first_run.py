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

Where it can fork (Linux, a process of one thread), `WarmUp(task)` forks a child with the kernel's build, which
waits until `go()`: this process calls it once it sleeps until the kernel is built (vehicle.sim.car.
while_kernel_builds), so that the child takes this process's core then and goes on, on the idle core, while this
one simulates and writes the files (one core's work: a warm demo leaves the other mostly idle). Run here, the
warm-up had the wait only, and its overrun was on the critical path. The child compiles into the disk caches;
`finish()`, before the identification, waits for it (at most WAIT_S: a stuck child is killed, and this process
compiles what it left).
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..report.apart import can_fork, fork
from ..symbolic.cache import cache_lock
from ..vehicle.description import load_vehicle
from ..vehicle.estimate import required_channels
from ..vehicle.sim.car import SAMPLE_TIME, compile_lock
from .config import load_config
from .reduce import CarSetup, offset_changes

SECONDS = 2.0  # of synthetic driving: longer than the filters' borders at the demo's cut-off
WAIT_S = 300.0  # the longest the identification waits for the warm-up child (vehicle.sim.car.WAIT_S's reasoning)


class WarmUp:
    """`task()` (a warm-up: its value dropped) in a forked child that starts at `go()` (module doc); `started` False
    where this process cannot fork (another platform, or a second thread: its locks would stay held in the child's
    copy), and then nothing runs."""

    def __init__(self, task: Callable[[], object]) -> None:
        self.pid: int | None = None
        self.fd = -1
        if not can_fork():
            return
        r, w = os.pipe()

        def child() -> None:
            os.close(w)
            null = os.open(os.devnull, os.O_WRONLY)  # its warnings are this process's to give, once
            os.dup2(null, 1)
            os.dup2(null, 2)
            if os.read(r, 1):  # nothing read: this process closed the pipe without go() (it ended)
                task()

        # forked holding the locks the child takes (Numba's compiler lock, the generated modules' loader), as the
        # kernel's build is
        pid = fork(child, (compile_lock(), cache_lock()))
        os.close(r)
        self.pid, self.fd = pid, w

    @property
    def started(self) -> bool:
        return self.pid is not None

    def go(self) -> None:
        """Let the child compile."""
        if self.fd >= 0:
            with contextlib.suppress(OSError):
                os.write(self.fd, b"1")
            self._close()

    def _close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def finish(self, timeout: float = WAIT_S) -> None:
        """Wait for the child (never let go: it leaves at once), killing it after `timeout` (what it compiled is
        cached: each entry is written whole, so a kill leaves no half-written one)."""
        self._close()
        if self.pid is None:
            return
        pid, self.pid = self.pid, None
        end = time.monotonic() + timeout
        ended = False
        try:
            while not (ended := os.waitpid(pid, os.WNOHANG)[0] != 0) and time.monotonic() <= end:
                time.sleep(0.02)
        finally:  # stuck past the timeout, or this process interrupted while it waited (TERM): not left compiling
            if not ended:  # (or reaped by a wait the interrupt then cut short: nothing left to kill or reap)
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                with contextlib.suppress(ChildProcessError):
                    os.waitpid(pid, 0)

    def __del__(self) -> None:  # dropped unfinished (the run raised): no child left running
        with contextlib.suppress(Exception):
            self.finish(timeout=0.0)


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
