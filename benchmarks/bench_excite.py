"""Wall time of `dynid excite` on a 7-axis arm (target: <= 60 s), and what the design buys.

Run:  python benchmarks/bench_excite.py [--harmonics 5] [--period 10]

No 7-axis model ships with dynid, so this builds one: a KUKA iiwa-like arm in modified DH
(alpha 0, -pi/2, pi/2, pi/2, -pi/2, -pi/2, pi/2; r offsets 0.34, 0.4, 0.4, 0.126 m on frames
1, 3, 5, 7), plausible link masses (4.0 ... 0.3 kg, 20 kg in all) with their centres of mass and
inertias (physically consistent: the inertia about O_j is the central one plus the parallel-axis
term), and per joint a rotor inertia IA, viscous FV, Coulomb FS and offset OFF; limits of the
iiwa's order (±170/±120 deg, 85 to 135 deg/s, accelerations 3 to 6 rad/s²). It runs the command
line in a fresh process, as a user would (`python -m dynid.cli.main excite ...`; includes loading
the compiled engine from the cache), then reads the written coefficients back and prints the
condition number of the optimised trajectory next to that of random Fourier trajectories scaled to
the same limits (median of five seeds), every figure computed here from the files and the model.
Writes benchmarks/results/excite.json.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE)]

from results_file import write_results  # noqa: E402

# link: mass kg, centre of mass in frame j (m), central principal inertias kg m²
LINKS = [
    (4.0, (0.0, -0.03, -0.12), (0.02, 0.02, 0.008)),
    (4.0, (0.0, -0.06, 0.03), (0.02, 0.008, 0.02)),
    (3.0, (0.0, 0.03, -0.13), (0.015, 0.015, 0.005)),
    (2.7, (0.0, 0.067, 0.034), (0.012, 0.005, 0.012)),
    (1.7, (0.0, -0.02, -0.1), (0.008, 0.007, 0.003)),
    (1.8, (0.0, 0.0006, 0.0004), (0.004, 0.004, 0.003)),
    (0.3, (0.0, 0.0, 0.02), (0.0005, 0.0005, 0.0008)),
]
ALPHA = ["0", "-pi/2", "pi/2", "pi/2", "-pi/2", "-pi/2", "pi/2"]
R = [0.34, 0.0, 0.4, 0.0, 0.4, 0.0, 0.126]
IA = [0.5, 0.5, 0.3, 0.3, 0.1, 0.1, 0.05]
FV = [5.0, 5.0, 3.0, 3.0, 1.5, 1.0, 0.5]
FS = [4.0, 4.0, 2.5, 2.5, 1.2, 0.8, 0.4]
OFF = [0.2, -0.3, 0.1, 0.1, -0.05, 0.02, 0.01]
DEG = np.pi / 180
LIMITS = {
    "q_min": [-170 * DEG, -120 * DEG, -170 * DEG, -120 * DEG, -170 * DEG, -120 * DEG, -175 * DEG],
    "q_max": [170 * DEG, 120 * DEG, 170 * DEG, 120 * DEG, 170 * DEG, 120 * DEG, 175 * DEG],
    "qd_max": [85 * DEG, 85 * DEG, 100 * DEG, 75 * DEG, 130 * DEG, 135 * DEG, 135 * DEG],
    "qdd_max": [3.0, 3.0, 4.0, 4.0, 5.0, 6.0, 6.0],
}


def arm_toml() -> str:
    """The iiwa-like model file."""
    lines = ['name = "iiwa-like 7-axis arm"', "gravity = [0.0, 0.0, -9.81]", "frames = ["]
    for j in range(7):
        lines.append(f'  [{j + 1}, {j}, 0, 0.0, 0.0, "{ALPHA[j]}", 0.0, 0.0, {R[j]}],')
    lines.append("]")
    for j, (m, c, i) in enumerate(LINKS):
        c = np.array(c)
        J = np.diag(i) + m * (c @ c * np.eye(3) - np.outer(c, c))  # about O_j: central + parallel axis
        values = {"XX": J[0, 0], "XY": J[0, 1], "XZ": J[0, 2], "YY": J[1, 1], "YZ": J[1, 2], "ZZ": J[2, 2],
                  "MX": m * c[0], "MY": m * c[1], "MZ": m * c[2], "M": m,
                  "IA": IA[j], "FV": FV[j], "FS": FS[j], "OFF": OFF[j]}
        lines.append(f"[parameters.{j + 1}]")
        lines += [f"{k} = {float(v)!r}" for k, v in values.items()]
    return "\n".join(lines) + "\n"


def limits_toml() -> str:
    return "".join(f"{k} = [{', '.join(repr(float(v)) for v in vals)}]\n" for k, vals in LIMITS.items())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--harmonics", type=int, default=5, help="harmonics (default 5)")
    ap.add_argument("--period", type=float, default=10.0, help="period, s (default 10)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    args = ap.parse_args()

    import dynid
    from dynid.estimation.excitation import FourierTrajectory, Limits, condition_number, random_trajectory

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "arm.toml").write_text(arm_toml())
        (tmp / "limits.toml").write_text(limits_toml())
        cmd = [sys.executable, "-m", "dynid.cli.main", "excite", str(tmp / "arm.toml"), "--limits",
               str(tmp / "limits.toml"), "--out", str(tmp / "traj.csv"), "--harmonics", str(args.harmonics),
               "--period", str(args.period), "--seed", str(args.seed)]
        t0 = time.perf_counter()
        run = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if run.returncode:
            sys.exit(f"dynid excite failed:\n{run.stderr}")
        model = dynid.load_model(tmp / "arm.toml")
        side = (tmp / "traj.toml").read_text()
        traj = FourierTrajectory.from_toml(side, model.n)
        best_start = tomllib.loads(side)["cond_best_random_start"]
    limits = Limits(**{k: np.array(v) for k, v in LIMITS.items()})
    samples = max(100, 20 * args.harmonics + 20)
    out = {"wall_s": wall, "best_random_start_columns": best_start, "harmonics": args.harmonics,
           "period_s": args.period, "samples": samples}
    base = model.base_parameters()
    randoms = [random_trajectory(model, limits, period=args.period, harmonics=args.harmonics, seed=100 + s)
               for s in range(5)]
    for scale in ("columns", "none"):
        opt = condition_number(model, traj, samples, scale, base.columns)
        rand = [condition_number(model, r, samples, scale, base.columns) for r in randoms]
        out[scale] = {"optimised": opt, "random_median": float(np.median(rand)), "random": rand}
    print(f"{model.name}: 7 joints, {base.rank} base parameters, L = {args.harmonics}, T = {args.period:g} s")
    print(f"dynid excite wall time: {wall:.1f} s (target <= 60 s)")
    print(f"{'criterion':<28} {'random (median of 5)':>22} {'optimised':>12} {'ratio':>8}")
    for scale, label in (("columns", "cond, columns scaled"), ("none", "cond, plain regressor")):
        r, o = out[scale]["random_median"], out[scale]["optimised"]
        print(f"{label:<28} {r:22.4g} {o:12.4g} {r / o:8.1f}")
    print(f"(the design minimised the columns-scaled criterion; its best of 20 random starts: {best_start:.4g})")
    write_results("excite", out)


if __name__ == "__main__":
    main()
