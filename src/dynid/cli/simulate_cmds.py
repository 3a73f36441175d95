"""`dynid simulate MANOEUVRE ...`: a simulated test-track file with the paper's sensors.

    dynid simulate sine --out sine.csv
    dynid simulate braking --speed 100 --seed 3 --format parquet --out braking.parquet
    dynid simulate spiral --duration 30 --truth --out spiral.mf4

Writes the file (atomic) and `<stem>.json` beside it (manoeuvre, seed, settings, true
parameters, sensors); progress on stderr. The first run compiles the simulator's kernel (once
per dynid version, about 10 s of CPU on the other core while the car loads) and the car's models
(about 2 s per new vehicle; measured: pipeline.demo.GENERATE_S, NEW_VEHICLE_S); later runs load them
from the cache.
"""

from __future__ import annotations

import argparse
import sys
import time

from ..atomic import OutputError, add_force, refuse_overwrite
from ..progress import Count, notice_if_slow
from ..shipped import DEMO_VEHICLE
from .progress import report as show
from .usage import command

# the names of vehicle.sim.manoeuvres.DEFAULTS, spelt out because importing the simulator for `dynid --help` costs a
# second; tests/cli/test_cli.py holds the two equal
MANOEUVRES = ("sine", "braking", "spiral", "step", "lane", "accel", "fishhook", "random", "static")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `simulate` to the top-level `dynid` sub-commands."""

    p = command(subparsers, "simulate", help="simulate a test-track manoeuvre and write the sensor file",
                description="Drive the simulated car (a vehicle file's [truth] set) through a test-track "
                            "manoeuvre and write what its sensor suite records, with seeded noise, as a logger "
                            "file (CSV, Parquet or MDF4) and <stem>.json beside it (the manoeuvre, seed, "
                            "settings, true parameters and sensors).",
                examples=["dynid simulate sine --out sine.csv",
                          "dynid simulate braking --speed 100 --seed 3 --format parquet --out braking.parquet",
                          "dynid simulate spiral --duration 30 --truth --out spiral.mf4"],
                notes="The first run compiles the simulator's kernel (once per dynid version: about 10 s of CPU, "
                      "on the other core while the car loads) and the car's models (about 2 s per new vehicle, "
                      "measured); later runs load them from the cache.")
    p.add_argument("manoeuvre", help=f"one of {', '.join(MANOEUVRES)}")
    p.add_argument("--speed", type=float, default=None, help="speed, km/h (default: the manoeuvre's)")
    p.add_argument("--duration", type=float, default=None, help="duration, s (default: the manoeuvre's)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    p.add_argument("--format", choices=("csv", "parquet", "mf4"), default=None,
                   help="file format (default: from the extension of --out)")
    p.add_argument("--truth", action="store_true", help="add the noise-free truth channels true_q*, true_qd*, ...")
    p.add_argument("--noise-free", action="store_true", help="sensor channels without noise and bias")
    p.add_argument("--out", required=True, help="output file (.csv, .parquet, .mf4); its sidecar <stem>.json beside it")
    add_force(p)
    p.add_argument("--vehicle", default=DEMO_VEHICLE,
                   help="a shipped vehicle (dynid vehicle list) or a vehicle file with a [truth] set "
                        f"(default: {DEMO_VEHICLE})")
    p.set_defaults(func=cmd_simulate)


def progress_bar(total: float):
    """Simulated seconds out of `total`: a bar on a terminal, a line every tenth otherwise: (report(t), close())."""

    def report(t: float) -> None:
        show(Count("simulating", round(t, 3), round(total, 3), f"simulated {t:.0f} / {total:.0f} s", unit="s"))

    return report, lambda: show.close("simulating")


def cmd_simulate(args: argparse.Namespace) -> int:
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..pipeline.demo import GENERATING, SLOW_BUILD_S, compile_notice, simulated_car

    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..vehicle.description import load_vehicle
    from ..vehicle.sim import ManoeuvreError, SimulationError, manoeuvre
    from ..vehicle.sim.recording import check_output, write_test

    try:
        m = manoeuvre(args.manoeuvre, speed=args.speed, duration=args.duration)
        path, _ = check_output(args.out, args.format)
        refuse_overwrite([path, path.with_suffix(".json")], args.force)
        t0 = time.perf_counter()
        say = show
        say("building the car")
        with notice_if_slow(SLOW_BUILD_S, GENERATING, say):
            sim = simulated_car(args.vehicle)
        notice = compile_notice(sim)
        if notice:  # numba compiles at the first call: seconds of silence unless announced
            say(notice)
        report, close = progress_bar(m.duration)
        t1 = time.perf_counter()
        try:
            result = sim.run(m, progress=report)
        finally:
            close()
        t2 = time.perf_counter()
        path, side = write_test(result, args.out, args.format, seed=args.seed, truth=args.truth,
                                noise=not args.noise_free, suite=load_vehicle(args.vehicle).suite)
    except (ManoeuvreError, SimulationError, OutputError) as exc:
        print(f"dynid: error: {exc}", file=sys.stderr)
        return 2
    print(f"dynid: {m.name}: {m.duration:g} s simulated in {t2 - t1:.2f} s (setup {t1 - t0:.2f} s); "
          f"wrote {path} and {side}", file=sys.stderr)
    return 0
