"""Identification rows of the car: the paper's 14 equations, decimated in parallel per equation group."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..dynamics import BaseParameters, Model
from ..signals import decimate_parallel
from ..vehicle import WHEELS, Aerodynamics, aero_wrench, car_identification
from ..vehicle.estimate import CarTrajectory
from .robot import GroupedSystem


def car_system(
    model: Model,
    traj: CarTrajectory,
    fs: float,
    decimate: tuple[int, ...] = (5, 10),
    base: str | BaseParameters = "generic",
    aero: Aerodynamics | None = None,
    regressor=None,
    cutoff: float | None = None,
    min_speed: Mapping[int, float] | None = None,
) -> tuple[GroupedSystem, BaseParameters]:
    """W, Y and groups of one test: each of the 14 equations' columns of W and its Y through the same
    anti-alias filter and decimation (Gautier's parallel decimation), then stacked group by group.
    regressor: see `car_identification` (generated code is several times faster than the engine here).
    cutoff: the low-pass (Hz) every signal of traj went through; when given, W is computed only on every
    k-th sample, k the largest divisor of the whole decimation factor whose reduced Nyquist frequency is
    at least 5 x the cut-off (those signals hold nothing above a few times it, so nothing aliases) and
    above twice the wheel-spin frequency; the rest of the decimation is one parallel stage. The
    dry-friction columns sign(qd), not band-limited, are built at the full rate.
    min_speed: joint (a damper) -> m/s: that joint's rows are left out where its estimated |qd| is below.
    Near a reversal the dry friction is no function of the velocity (it sticks, or follows a law steeper
    than any filter resolves) and the velocity's noise flips sign(qd): those rows would pull fs towards 0
    and let the damping absorb it.
    """
    decimate = tuple(decimate or ())
    full, fs_full, full_decimate = traj, fs, decimate
    # the wheels' diametral-inertia columns oscillate at twice the spin frequency: keep it below the new Nyquist
    spin = 2 * np.abs(traj.qd[:, [w - 1 for w in WHEELS]]).max() / (2 * np.pi) if len(traj.t) else 0.0
    total = int(np.prod(decimate)) if decimate else 1
    k = None
    if cutoff is not None:  # the coarsest rate, a divisor of the whole factor, whose Nyquist frequency clears both
        needed = max(5 * cutoff, spin / 0.9)
        k = next((d for d in range(total - 1, 1, -1) if total % d == 0 and fs / (2 * d) >= needed), None)
    if k is not None:  # W there, the rest of the decimation in one stage
        traj = CarTrajectory(traj.t[::k], traj.q[::k], traj.qd[::k], traj.qdd[::k], traj.wheel_wrenches[::k],
                             None if traj.spin_torques is None else traj.spin_torques[::k], traj.steering_wheel[::k])
        fs, decimate = fs / k, (total // k,)
    aw = aero_wrench(model, traj.q, traj.qd, aero) if aero is not None else None
    eq = car_identification(model, traj.q, traj.qd, traj.qdd, traj.wheel_wrenches, aw, base=base,
                            regressor=regressor)
    rows, N = len(eq.rows), len(traj.t)
    step = int(np.prod(decimate)) if decimate else 1
    W3 = eq.per_sample  # (N, rows, p)
    # only the (row, column) pairs that are not structural zeros (126 of the paper's 14 x 48) and Y go
    # through the filter, gathered as one (N, live + rows) array
    live_r, live_c = np.nonzero(np.any(W3 != 0, axis=0))
    both = np.empty((N, live_r.size + rows))
    both[:, : live_r.size] = W3[:, live_r, live_c]
    both[:, live_r.size :] = eq.Y.reshape(rows, N).T
    if decimate:
        both, _ = decimate_parallel(both, None, decimate, fs)
    W = np.zeros((both.shape[0], rows, W3.shape[2]))
    W[:, live_r, live_c] = both[:, : live_r.size]
    Y = both[:, live_r.size :]
    if full is not traj:  # sign(qd) is not band-limited: dry-friction columns at the full rate, decimated in parallel
        fs_cols = [(c, eq.rows.index(int(n[2:])), int(n[2:])) for c, n in enumerate(eq.names)
                   if n.startswith("FS") and n[2:].isdigit() and int(n[2:]) in eq.rows]
        if fs_cols:
            signs = np.sign(full.qd[:, [j - 1 for _, _, j in fs_cols]])
            dec, _ = decimate_parallel(signs, None, full_decimate, fs_full)
            n = min(len(dec), W.shape[0])
            for i, (c, r, _) in enumerate(fs_cols):
                W[:n, r, c] = dec[:n, i]
    t = traj.t[::step][: W.shape[0]]
    n = W.shape[0]
    labels = eq.groups.reshape(rows, N)[:, 0]
    keep = np.ones((rows, n), dtype=bool)
    for j, v in (min_speed or {}).items():
        if j in eq.rows:
            keep[eq.rows.index(j)] = np.abs(traj.qd[::step, j - 1][:n]) >= v
    keep = keep.reshape(-1)
    sys = GroupedSystem(W.transpose(1, 0, 2).reshape(rows * n, -1)[keep], Y.T.reshape(-1)[keep],
                        np.repeat(labels, n)[keep], np.tile(t, rows)[keep])
    return sys, eq.base


COM_SCALE = 0.2  # m: a first moment's scale is M6 x 0.2 m, so that 5 % of it is 1 cm of centre-of-mass shift


def car_scales(values: Mapping[str, float]) -> dict[str, float]:
    """The engineering scale of the chassis parameters whose value may be near zero: products of inertia
    against the smallest principal moment of the chassis inertia about O6, first moments against a
    centre-of-mass shift (M6 x COM_SCALE). The others are judged against their own value (the default)."""
    v = {n: float(values.get(n, 0.0)) for n in ("XX6", "XY6", "XZ6", "YY6", "YZ6", "ZZ6", "M6")}
    inertia = np.array([[v["XX6"], v["XY6"], v["XZ6"]], [v["XY6"], v["YY6"], v["YZ6"]],
                        [v["XZ6"], v["YZ6"], v["ZZ6"]]])
    out = dict.fromkeys(("XY6", "XZ6", "YZ6"), abs(float(np.linalg.eigvalsh(inertia).min())))
    out.update(dict.fromkeys(("MX6", "MY6", "MZ6"), COM_SCALE * abs(v["M6"])))
    return {n: s for n, s in out.items() if n in values}


def car_sections(names: list[str], tree) -> list[tuple[str, list[str]]]:
    """The paper's tables: chassis (Table 2), suspensions and anti-roll bars (Table 3), wheels, tires (Table 5)."""
    from ..vehicle.template import DAMPERS, TIRES, WHEELS

    def joint(n: str) -> int | None:
        digits = n[len(n.rstrip("0123456789")):]
        return int(digits) if digits else None

    chassis = [n for n in names if joint(n) == 6]
    susp = [n for n in names if joint(n) in DAMPERS] + [n for n in names if joint(n) is None]
    wheels = [n for n in names if joint(n) in WHEELS]
    tires = [n for n in names if joint(n) in TIRES]
    sections = [("Chassis (paper Table 2)", chassis), ("Suspensions and anti-roll bars (paper Table 3)", susp),
                ("Wheels", wheels), ("Tire vertical stiffness (paper Table 5)", tires)]
    return [(title, group) for title, group in sections if group]


def consistency_text(result, base: BaseParameters, tree=None) -> str:
    """Whether the estimated chassis and wheels are physically realisable (only meaningful without regrouping);
    parameters fixed as known take the tree's values."""
    from ..model import check_physical

    if base.regrouped:
        return ("Inertial parameters regroup in this base set (" + ", ".join(base.regrouped)
                + "): the physical-consistency check applies to standard parameters only.")
    values = {n: tree.values.get(n, 0.0) for n in (tree.known if tree is not None else ())}
    values.update(zip(result.names, (float(v) for v in result.values), strict=True))
    problems = check_physical(values, frames=[6, *WHEELS])
    if not problems:
        return "The estimated chassis and wheels are physically realisable (mass > 0, inertia at the centre of " \
               "mass positive definite, triangle inequalities hold)."
    return "NOT physically realisable:\n" + "\n".join(f"  {p}" for p in problems)


def car_demo_known(tree) -> dict[str, float]:
    """The wheels' masses and inertias at the tree's values: weighed and measured on a bench in practice,
    and barely separable from the chassis in track data (see vehicle.equations)."""
    return {f"{p}{w}": tree.values.get(f"{p}{w}", 0.0) for w in WHEELS for p in ("XX", "YY", "ZZ", "M")}


# which standard test excites what (the paper's tests and ISO manoeuvres)
_EXCITATION = (
    (("XX6", "XY6", "XZ6", "MX6"), "roll: a sine steer at speed or a double lane change (ISO 3888-2)"),
    (("YY6", "MZ6"), "pitch: straight-line braking and acceleration"),
    (("ZZ6", "YZ6", "MY6"), "yaw: a sine steer or a step steer (ISO 7401)"),
    (("M6",), "vertical and longitudinal loads: braking, a speed change, a bumpy stretch"),
    (("K9", "K18", "K27", "K36", "FV9", "FV18", "FV27", "FV36", "FS9", "FS18", "FS27", "FS36"),
     "suspension travel in both directions: a sine steer (roll), braking (pitch), a bumpy stretch (heave)"),
    (("OFF9", "OFF18", "OFF27", "OFF36"), "any test: the static preload is always present"),
    (("karf", "karr"), "roll: a sine steer or a spiral to a high lateral acceleration"),
    (("K15", "K24", "K33", "K42"), "load transfer: braking (front/rear), cornering (left/right)"),
)


def excitation_hint(names: list[str]) -> str:
    """Which tests would excite the given parameters (for an unidentifiable-parameter error)."""
    lines = []
    for params, test in _EXCITATION:
        hit = [n for n in names if n in params]
        if hit:
            lines.append(f"  {', '.join(hit)}: {test}")
    wheels = [n for n in names if n[:2] in ("XX", "YY", "ZZ") and n[2:] in ("14", "23", "32", "41")]
    if wheels:
        lines.append(f"  {', '.join(wheels)}: steering that turns the wheels quickly (a step steer, a slalom), "
                     "or declare them known (their effect is small)")
    return "tests that would excite them:\n" + "\n".join(lines) if lines else ""
