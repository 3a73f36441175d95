"""`dynid plan --vehicle FILE`: the shortest test plan whose identification meets the engineer's targets.

    dynid plan --vehicle peugeot406
    dynid plan --vehicle my_car.toml --targets targets.toml --out plan

A targets file (TOML) overrides the default targets (bench parity) and the driver's and track's limits:

    [targets]            # cog: mm; the others: % (products: % of the smallest moment); false: no target
    cog = 2.5
    moments = 2.0
    products = 2.0
    springs = 3.0        # springs and anti-roll bars
    dampers = 5.0
    dry_friction = 10.0
    tires = 5.0
    [targets.parameters] # one parameter (dynid name or the paper's label) = %
    ks27 = 2.0
    [targets.quantities] # one engineering quantity (engineering.csv's keys) = % (mm for cg_*)
    Ixx = 1.5
    [limits]
    lateral_acceleration = 7.0       # m/s²
    longitudinal_acceleration = 7.0  # m/s²
    speed = 130.0                    # km/h
    length = 1000.0                  # m, one run
    time = 120.0                     # s of driving the plan may take (default: no limit)

When the standard tests cannot meet every target (or not within `time`), the plan designs an optimised steering-
and-pedal run for the binding target within the same limits (pipeline/plan_input.py) and searches again with it;
--out then holds its steering-robot file (optimised_input.csv: time, steering-wheel angle, pedal) and a plot.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

from ..atomic import staged_folder, write_atomic
from ..shipped import DEMO_VEHICLE
from .progress import report as say
from .usage import UsageError, command


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `plan` to the top-level `dynid` sub-commands."""

    p = command(
        subparsers, "plan", help="the shortest track-test plan whose identification meets the targets",
        description="Simulate the standard track tests (ISO 7401 step and sine steer, ISO 3888-2 lane change, "
                    "ISO 4138 spiral, straight-line braking, ...) with the vehicle's [truth] set and sensor suite "
                    "within the driver's and track's limits, predict the σ total (noise and the sensors' zero "
                    "offsets) of every parameter and engineering quantity for any combination of them, and print "
                    "the shortest plan meeting the targets (default: bench parity: CoG 2.5 mm, moments of "
                    "inertia 2 %, products 2 % of the smallest moment, springs and bars 3 %, dampers 5 %, dry "
                    "friction 10 %, tires 5 %) with a table of what each test identifies.",
        examples=[f"dynid plan --vehicle {DEMO_VEHICLE}",
                  "dynid plan --vehicle car.toml --targets targets.toml --out plan"],
        notes="A targets file has [targets] (cog, moments, products, springs, dampers, dry_friction, tires), "
              "[targets.parameters], [targets.quantities] and [limits] (lateral_acceleration, "
              "longitudinal_acceleration, speed, length); `python -m pydoc dynid.cli.plan_cmds` shows an example.")
    p.add_argument("--vehicle", default=DEMO_VEHICLE,
                   help="a shipped vehicle (dynid vehicle list) or a vehicle file with a [truth] set "
                        f"(default: {DEMO_VEHICLE})")
    p.add_argument("--targets", default=None, help="targets file (TOML; default: bench parity)")
    p.add_argument("--out", default=None,
                   help="folder for plan.txt, plan.json and a rehearsal of the plan on the simulated car (its tests' "
                        "noisy logger files in data/ and identify.toml: `dynid identify DIR/identify.toml` tries it); "
                        "default: print only")
    p.add_argument("--seed", type=int, default=406, help="seed of the rehearsal's sensor noise (default 406)")
    p.add_argument("--repeats", type=int, default=2, help="runs of one test the plan may hold, each a new zeroing "
                                                           "of the sensors (default 2)")
    p.add_argument("--offsets", choices=("estimated", "propagated"), default="estimated",
                   help="the sensors' zero offsets as the identification will treat them: estimated with the "
                        "parameters (identify's default) or propagated ([uncertainty] estimate = false: a larger σ "
                        "total); the rehearsal's config says the same (default estimated)")
    p.set_defaults(func=cmd_plan)


def cmd_plan(args: argparse.Namespace) -> int:
    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..pipeline.plan import load_targets, plan_tests
    from ..vehicle.description import load_vehicle

    if args.repeats < 1:
        raise UsageError(f"--repeats {args.repeats}: give a whole number >= 1")
    spec = load_targets(args.targets)  # bad input refused before anything is simulated
    load_vehicle(args.vehicle)
    out = Path(args.out) if args.out else None
    # the output folder is checked (and staged) before the minute of simulation, swapped in at the end
    with staged_folder(out) if out else contextlib.nullcontext() as stage:
        plan = plan_tests(args.vehicle, spec, repeats=args.repeats, progress=say,
                          estimate=args.offsets == "estimated")
        design = None
        if plan.needs_input:
            # start-up: the input's design (simulator, reduction), only when it is needed
            from ..pipeline.plan_input import optimised_plan

            plan, design = optimised_plan(plan, progress=say)
        text = plan.text()
        print(text)
        if stage is not None:
            write_atomic(stage / "plan.txt", text + "\n")
            write_atomic(stage / "plan.json", json.dumps(plan.to_dict(), indent=1, allow_nan=False))
            plan.rehearsal(stage, args.seed)
            if design is not None:
                # start-up: matplotlib, only when the input is written
                from ..pipeline.plan_input import plot_input, write_robot_file

                write_robot_file(design, stage / "optimised_input.csv")
                plot_input(design, plan.spec.limits, stage / "optimised_input.png")
    if out:
        print(f"\nwrote {out / 'plan.txt'}, {out / 'plan.json'} and the plan's rehearsal ({out / 'data'}, "
              f"{out / 'identify.toml'}: dynid identify {out / 'identify.toml'} --out DIR)", file=sys.stderr)
    return 0
