"""`dynid excite MODEL --out traj.csv`: an optimised excitation trajectory for identification.

    dynid excite tx40 --limits tx40-limits.toml --out traj.csv
    dynid excite robot.toml --limits limits.toml --period 10 --harmonics 5 --fs 200 --noise 0.5 --out traj.csv

The limits file (TOML) gives one number per moving joint in each of four lists, all required:

    q_min   = [-2.9, -2.0, -2.3, -4.5, -2.0, -4.5]   # rad (m for a prismatic joint)
    q_max   = [ 2.9,  2.0,  2.3,  4.5,  2.0,  4.5]
    qd_max  = [ 2.0,  2.0,  2.5,  3.0,  3.0,  4.0]   # rad/s (m/s)
    qdd_max = [ 8.0,  8.0, 10.0, 12.0, 12.0, 15.0]   # rad/s² (m/s²)

Without --limits, conservative stand-ins are used (±2.5 rad, 1.5 rad/s, 5 rad/s²; prismatic
±0.25 m, 0.25 m/s, 1 m/s²) and a note says so. Writes the trajectory (time, q, qd, qdd of each
moving joint, sampled at --fs over --duration) as CSV and its Fourier coefficients as `<stem>.toml`
beside it, both atomically; prints the condition numbers and the expected %σ of each base parameter.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from ..atomic import add_force, refuse_overwrite, write_atomic
from .progress import report as say  # the starts as a bar with its time left on a terminal
from .usage import command


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `excite` to the top-level `dynid` sub-commands."""

    p = command(
        subparsers, "excite", help="optimise a periodic excitation trajectory (Fourier series) for identification",
        description="Optimise a finite Fourier series trajectory that minimises the condition number of the "
                    "base-parameter regressor within the joint limits (Swevers et al. 1997), write it as CSV "
                    "with its coefficients as TOML, and print the expected %σ of each base parameter.",
        examples=["dynid excite tx40 --limits limits.toml --out traj.csv",
                  "dynid excite robot.toml --limits limits.toml --period 10 --harmonics 5 --fs 200 --out traj.csv"])
    p.add_argument("model", help="model file (TOML) or a shipped example: puma560, tx40, floating_tree")
    p.add_argument("--out", required=True, help="output CSV file; the coefficients go to <stem>.toml beside it")
    add_force(p)
    p.add_argument("--period", type=float, default=10.0, help="period T of the trajectory, s (default 10)")
    p.add_argument("--harmonics", type=int, default=5, help="number of harmonics L of the series (default 5)")
    p.add_argument("--limits", default=None,
                   help="limits file (TOML: per-joint lists q_min, q_max, qd_max, qdd_max; all required); "
                        "default: stand-ins ±2.5 rad, 1.5 rad/s, 5 rad/s² (prismatic ±0.25 m, 0.25 m/s, 1 m/s²)")
    p.add_argument("--fs", type=float, default=100.0, help="sample rate of the CSV and of the %%σ figures, Hz "
                                                           "(default 100)")
    p.add_argument("--duration", type=float, default=None,
                   help="duration of the CSV and of the %%σ figures, s (default: one period; whole periods "
                        "allow averaging the data over periods)")
    p.add_argument("--noise", default="0.5",
                   help="torque noise standard deviation, N·m (N for a prismatic joint): one value, or one "
                        "per moving joint separated by commas (default 0.5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    p.add_argument("--scale", choices=("columns", "none"), default="columns",
                   help="criterion: condition number with each regressor column scaled to unit norm (columns, "
                        "default: independent of the parameters' units) or of the plain regressor (none)")
    p.add_argument("--starts", type=int, default=20, help="random starts drawn (default 20)")
    p.add_argument("--refine", type=int, default=3, help="best random starts refined by SLSQP (default 3)")
    p.add_argument("--maxiter", type=int, default=100, help="SLSQP iterations per refined start (default 100)")
    p.add_argument("--samples", type=int, default=None,
                   help="samples per period of the optimisation grid (default max(100, 20 L + 20)); the "
                        "limits are verified on a grid ten times denser")
    p.add_argument("--free-start", action="store_true",
                   help="do not impose qd = qdd = 0 at t = 0 (by default the trajectory starts at rest)")
    p.set_defaults(func=cmd_excite)


def _noise(text: str) -> list[float]:
    from ..estimation.excitation import ExcitationError  # start-up: the library, 1-5 s (--help 0.1 s)

    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ExcitationError(f"--noise: {text!r} is not a number or a comma-separated list of numbers") from None
    if not values or any(not (v > 0 and math.isfinite(v)) for v in values):
        raise ExcitationError(f"--noise: the standard deviations must be positive numbers, got {text!r}")
    return values


MAX_HARMONICS = 50  # a finite Fourier series for identification has a few (Swevers: 5); more is a slip
MAX_SAMPLES = 100_000  # per period on the optimisation grid (verified on ten times that)
MAX_BYTES = 2 << 30  # the regressor the %σ figures are computed from, over --duration at --fs


def _check_sizes(args: argparse.Namespace, joints: int, params: int, error: type[Exception]) -> None:
    """Sizes refused before any work, with the memory they would take: never an out-of-memory error later."""
    if args.harmonics > MAX_HARMONICS:
        raise error(f"--harmonics {args.harmonics}: at most {MAX_HARMONICS} (an exciting trajectory has a few, "
                    "5 by default)")
    if args.samples is not None and not 1 <= args.samples <= MAX_SAMPLES:
        raise error(f"--samples {args.samples}: give 1 to {MAX_SAMPLES} samples per period (default "
                    "max(100, 20 L + 20))")
    duration = args.period if args.duration is None else args.duration
    rows = duration * args.fs
    need = rows * joints * params * 8.0
    if need > MAX_BYTES:
        given = f"--duration {duration:g} s" if args.duration is not None else f"--period {duration:g} s (the duration)"
        raise error(f"{given} at --fs {args.fs:g} Hz: {rows:.3g} samples, whose regressor would "
                    f"take {need / 2**30:.3g} GiB (at most {MAX_BYTES / 2**30:g}); give a shorter --duration or a "
                    "lower --fs")


def cmd_excite(args: argparse.Namespace) -> int:
    import numpy as np  # start-up: numpy (--help 0.1 s)

    # start-up: the library, 1-5 s (--help 0.1 s)
    from ..dynamics import load_model
    from ..estimation.excitation import (
        ExcitationError,
        Limits,
        design_excitation,
        expected_uncertainty,
        format_uncertainty,
    )
    from ..io import Channel, Recording, write_recording  # start-up: the library, 1-5 s (--help 0.1 s)

    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise ExcitationError(f"--out {out}: the trajectory is written as CSV, give a .csv file")
    if not out.parent.is_dir():
        raise ExcitationError(f"--out {out}: the folder {out.parent} does not exist")
    side = out.with_suffix(".toml")
    refuse_overwrite([out, side], args.force)
    for name, v in (("--period", args.period), ("--fs", args.fs)):
        if not (v > 0 and math.isfinite(v)):
            raise ExcitationError(f"{name} must be a positive number, got {v}")
    if args.harmonics < 1:
        raise ExcitationError(f"--harmonics must be at least 1, got {args.harmonics}")
    for name, k in (("--starts", args.starts), ("--refine", args.refine), ("--maxiter", args.maxiter)):
        if k < 1:
            raise ExcitationError(f"{name} must be at least 1, got {k}")
    if args.duration is not None and not (args.duration > 0 and math.isfinite(args.duration)):
        raise ExcitationError(f"--duration must be a positive number, got {args.duration}")
    noise = _noise(args.noise)

    model = load_model(args.model)
    tree = model.tree
    moving = [tree.frames[j - 1] for j in tree.equations]  # neither fixed frames nor mimic joints
    if args.limits is None:
        limits = Limits.default([f.sigma == 1 for f in moving])
        print("dynid: no --limits: using the stand-ins ±2.5 rad, 1.5 rad/s, 5 rad/s² (prismatic ±0.25 m, "
              "0.25 m/s, 1 m/s²); give the robot's limits for a trajectory to run on it", file=sys.stderr)
    else:
        limits = Limits.from_toml(args.limits, len(moving))
    _check_sizes(args, len(moving), tree.p, ExcitationError)
    if len(noise) not in (1, len(moving)):
        raise ExcitationError(f"--noise: give one value or {len(moving)} (one per moving joint), got {len(noise)}")

    d = design_excitation(model, limits, period=args.period, harmonics=args.harmonics, samples=args.samples,
                          scale=args.scale, starts=args.starts, optimise=args.refine, maxiter=args.maxiter,
                          seed=args.seed, rest=not args.free_start, progress=say)
    traj = d.trajectory
    duration = args.period if args.duration is None else args.duration
    u = expected_uncertainty(model, traj, noise if len(noise) > 1 else noise[0], args.fs, duration)

    t = np.arange(round(duration * args.fs)) / args.fs
    q, qd, qdd = traj.evaluate_joints(t)
    channels = []
    for kind, x, units in (("q", q, ("rad", "m")), ("qd", qd, ("rad/s", "m/s")), ("qdd", qdd, ("rad/s^2", "m/s^2"))):
        for i, f in enumerate(moving):
            channels.append(Channel(f"{kind}{f.j}", units[f.sigma], x[:, i], t))
    meta = {"source": f"dynid excite {args.model}", "model": tree.name, "period_s": f"{args.period:g}",
            "harmonics": str(args.harmonics), "coefficients": side.name}
    write_recording(Recording(None, {c.name: c for c in channels}, meta), out, format="csv")
    extra: dict[str, object] = {
        "model": tree.name, "seed": args.seed, "scale": d.scale, "start_at_rest": not args.free_start,
        "cond": d.cond, "cond_best_random_start": d.cond_start, "cond_plain": d.cond_unscaled,
        "cond_columns_scaled": d.cond_columns, "q_min": limits.q_min.tolist(), "q_max": limits.q_max.tolist(),
        "qd_max": limits.qd_max.tolist(), "qdd_max": limits.qdd_max.tolist(),
    }
    write_atomic(side, traj.to_toml(extra))

    what = "columns scaled to unit norm" if d.scale == "columns" else "plain regressor"
    print(f"{tree.name}: {len(d.base_names)} base parameters, {len(moving)} joints, period {args.period:g} s, "
          f"{args.harmonics} harmonics, {d.samples} samples per period")
    print(f"condition number ({what}): {d.cond:.4g} optimised, {d.cond_start:.4g} for the best of "
          f"{len(d.cond_starts)} random starts (plain regressor: {d.cond_unscaled:.4g}; columns scaled: "
          f"{d.cond_columns:.4g})")
    shrunk = f"; shrunk by {d.shrink:.4f} to fit between grid points" if d.shrink < 1 else ""
    print(f"limits verified on {10 * d.samples} samples per period: largest use "
          f"{100 * (1 + d.violation):.1f} % of a limit{shrunk} ({d.iterations} SLSQP iterations, "
          f"{d.seconds:.1f} s)")
    sig = ", ".join(f"{v:g}" for v in u.noise)
    print(f"\nExpected standard deviations, {duration:g} s at {args.fs:g} Hz ({u.samples} samples), torque noise "
          f"sigma [{sig}], weighted least squares; a priori values from the model file:")
    print(format_uncertainty(u))
    print(f"\nwrote {out} and {side}")
    return 0
