"""Identification rows of the car: the paper's 14 equations, decimated in parallel per equation group."""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..dynamics import BaseParameters, Model, Wrench
from ..dynamics.newton_euler import coulomb
from ..io.units import unit_factor
from ..signals import decimate_parallel, lowpass
from ..vehicle import (
    DAMPERS,
    EQUATION_ROWS,
    WHEELS,
    Aerodynamics,
    CarResidual,
    aero_wrench,
    car_base_parameters,
    car_identification,
)
from ..vehicle.dampers import KneeSearch
from ..vehicle.equations import group_name, load_rows
from ..vehicle.estimate import CarTrajectory, CoarseTrajectory, required_channels
from ..vehicle.instruments import suspension_loads, suspension_response
from ..vehicle.sensors import CORNER_TAGS
from ..vehicle.template import CHASSIS
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
    instruments: Mapping[str, float] | None = None,
    keep: np.ndarray | None = None,
    equations: Sequence[int] | None = None,
    friction_lowpass: int | None = None,
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
    instruments: parameter values (the previous estimate): the system's Z (IDIM-IV) is then W of the
    trajectory whose clearances are the suspensions' simulated response to the measured loads
    (`vehicle.instruments`), conditioned exactly as W; min_speed then applies to the simulated rates.
    keep: the rows to keep (the `kept` mask of another system of the same samples) instead of min_speed's.
    equations: the joints whose equations are kept (default: all 14); e.g. without height lasers the tire
    equations are identities (the deflections come from the loads) and are left out.
    friction_lowpass: the order of the low-pass (at `cutoff`) the loads went through: the dry-friction columns s(qd)
    go through it too, before the decimation. The loads hold the friction force low-passed (a step at a reversal
    spread over about 1 / cutoff), and a column s(qd) without it does not: Gautier's parallel filtering wants W and Y
    through the same filters. None: not (the columns are s(qd) decimated only).
    """
    decimate = tuple(decimate or ())
    k, rest = coarse_step(traj, fs, decimate, cutoff)
    coarse = _every(traj, k)
    aw = aero_wrench(model, coarse.q, coarse.qd, aero) if aero is not None else None
    eq = car_identification(model, coarse.q, coarse.qd, coarse.qdd, coarse.wheel_wrenches, aw, base=base,
                            regressor=regressor)
    lp = None if friction_lowpass is None or cutoff is None else (cutoff, friction_lowpass)
    W, Y = _decimated(eq, [traj.qd], fs, k, rest, decimate, model.tree, lp)
    W, Y = W[:, 0], Y[:, 0]
    Z, sim = None, traj
    if instruments is not None:
        sim = _simulated_suspensions(model.tree, traj, coarse, eq, instruments)
        sc = _every(sim, k)
        sim_eq = car_identification(model, sc.q, sc.qd, sc.qdd, coarse.wheel_wrenches, aw, base=base,
                                    regressor=regressor)
        Z = _decimated(sim_eq, [sim.qd], fs, k, rest, decimate, model.tree, lp)[0][:, 0]
    rows, n = len(eq.rows), W.shape[0]
    step = k * (int(np.prod(rest)) if rest else 1)
    t = traj.t[::step][:n]
    labels = eq.groups.reshape(rows, -1)[:, 0]
    if keep is None:
        keep = np.ones((rows, n), dtype=bool)
        if equations is not None:
            keep[[i for i, j in enumerate(eq.rows) if j not in equations]] = False
        for j, v in (min_speed or {}).items():
            if j in eq.rows:
                # rows chosen on the instruments' clearance rate when there are instruments: chosen on the measured
                # one, the kept rows' noise would lean with the rate's sign, and the instruments would see it
                keep[eq.rows.index(j)] = np.abs(sim.qd[::step, j - 1][:n]) >= v
        keep = keep.reshape(-1)

    def stacked(A):
        return None if A is None else A.transpose(1, 0, 2).reshape(rows * n, -1)[keep]

    sys = GroupedSystem(stacked(W), Y.T.reshape(-1)[keep], np.repeat(labels, n)[keep], np.tile(t, rows)[keep],
                        stacked(Z), keep)
    return sys, eq.base


def knee_rows(sys: GroupedSystem, traj: CarTrajectory, fs: float, decimate: tuple[int, ...], cutoff: float | None,
              search: KneeSearch, dampers: Sequence[int]) -> None:
    """Add to `search` each damper's group rows of `sys` (car_system's rows of traj, the linear law) with the
    candidate curves' columns (`KneeSearch.hinges`) computed and decimated as W is, and the rows' rates."""
    decimate = tuple(decimate or ())
    k, rest = coarse_step(traj, fs, decimate, cutoff)
    rate = traj.qd[::k][:, [d - 1 for d in dampers]]
    cols = np.concatenate([rate, *(search.hinges(rate[:, i]) for i in range(len(dampers)))], axis=1)
    if rest:
        cols, _ = decimate_parallel(cols, None, rest, fs / k)
    rows = len(sys.kept) // cols.shape[0] if sys.kept is not None else None
    width = 1 + 2 * search.grid.size
    for i, d in enumerate(dampers):
        sel = sys.groups == group_name(d)
        mask = sys.kept.reshape(rows, -1)[EQUATION_ROWS.index(d)]
        H = cols[:, len(dampers) + i * width: len(dampers) + (i + 1) * width][mask]
        search.add(d, sys.W[sel], sys.Y[sel], H, cols[mask, i])


def _every(traj: CarTrajectory, k: int) -> CarTrajectory:
    """Every k-th sample; the joints copied samples-first (C order: the estimator's are column-major, and the
    generated regressor reads a sample's joints together: one cache line each instead of one per joint)."""
    if k == 1:
        return traj
    q, qd, qdd = (np.ascontiguousarray(a[::k]) for a in (traj.q, traj.qd, traj.qdd))
    return CarTrajectory(traj.t[::k], q, qd, qdd, traj.wheel_wrenches[::k],
                         None if traj.spin_torques is None else traj.spin_torques[::k], traj.steering_wheel[::k])


def car_moved_rows(
    model: Model,
    traj: CarTrajectory,
    moved: Iterable[CarTrajectory | CoarseTrajectory],
    fs: float,
    keep: np.ndarray,
    decimate: tuple[int, ...] = (5, 10),
    base: str | BaseParameters = "generic",
    aero: Aerodynamics | None = None,
    regressor=None,
    cutoff: float | None = None,
    friction_lowpass: int | None = None,
    x: np.ndarray | None = None,
) -> list[tuple[np.ndarray, np.ndarray]] | list[np.ndarray]:
    """(W, Y) of each moved trajectory (traj with some input changed: a sensor offset's), the rows `keep` selects
    (`car_system(model, m, ..., keep=keep)`'s, the other arguments `car_system`'s), all in one evaluation of the
    equations and one parallel decimation. The equations are computed on traj's coarse samples (its wheel spin
    chooses the step: an offset's effect on it is far below the margin of that choice); a moved trajectory may come
    on those samples already (`CoarseTrajectory`, on every `coarse_step(traj, ...)[0]`-th).

    x: parameter values (one per column of W): then each trajectory's change of the residual Y − W x of those rows
    from traj's alone (`_moved_residuals`: what the offsets' estimate needs, their columns C = Δ(Y − W x0),
    `estimation.offsets`)."""
    decimate = tuple(decimate or ())
    k, rest = coarse_step(traj, fs, decimate, cutoff)
    lp = None if friction_lowpass is None or cutoff is None else (cutoff, friction_lowpass)
    keep = np.asarray(keep, dtype=bool)
    if x is not None:
        return _moved_residuals(model, traj, moved, fs, keep, np.asarray(x, dtype=float), k, rest, decimate, base,
                                aero, regressor, lp)
    # a few trajectories per evaluation, taken from `moved` as they come (it may make them one by one): the
    # equations' arrays, the regressor's pooled buffers and the trajectories alive stay the size of one long
    # segment's, whatever the number of offsets
    per = max(1, MOVED_SAMPLES // max(1, len(traj.t[::k])))
    out = []
    pending = iter(moved)
    while chunk := list(itertools.islice(pending, per)):
        coarse = [m.traj if isinstance(m, CoarseTrajectory) else _every(m, k) for m in chunk]
        if any(len(c.t) != len(traj.t[::k]) for c in coarse):
            raise ValueError(f"car_moved_rows: a moved trajectory on other samples than every {k}-th of traj's "
                             "(JointsPass.moved(..., every=coarse_step(...)[0]))")
        q, qd, qdd, ww = (np.concatenate([getattr(c, a) for c in coarse])
                          for a in ("q", "qd", "qdd", "wheel_wrenches"))
        aw = aero_wrench(model, q, qd, aero) if aero is not None else None
        eq = car_identification(model, q, qd, qdd, ww, aw, base=base, regressor=regressor)
        W, Y = _decimated(eq, [m.qd for m in chunk], fs, k, rest, decimate, model.tree, lp)
        rows, m = len(eq.rows), W.shape[0]
        out += [(W[:, v].transpose(1, 0, 2).reshape(rows * m, -1)[keep], Y[:, v].T.reshape(-1)[keep])
                for v in range(len(coarse))]
        del chunk, coarse, q, qd, qdd, ww, aw, eq, W, Y
    return out


def _moved_residuals(model: Model, traj: CarTrajectory, moved: Iterable[CarTrajectory | CoarseTrajectory], fs: float,
                     keep: np.ndarray, x: np.ndarray, k: int, rest: tuple[int, ...], decimate: tuple[int, ...],
                     base: str | BaseParameters, aero: Aerodynamics | None, regressor,
                     lp: tuple[float, int] | None) -> list[np.ndarray]:
    """`car_moved_rows` with x: each moved trajectory's change of the residual Y − W x on the rows `keep` selects,
    from traj's, equal to the difference of `car_system(model, m, ..., keep=keep)`'s and traj's Y − W x to round-off
    (k, rest: `coarse_step`'s; lp: (cut-off, order) of the dry-friction columns' low-pass, or None).

    W x is formed before the decimation (it is linear), on the equations' coarse samples, without W and Y apart
    (`vehicle.CarResidual`), and traj's residual is subtracted there: the changes of all the trajectories then go
    through one parallel decimation, one column per equation each (the difference first: its round-off is that of
    the change, not of the residual). The dry-friction columns, which `car_system` builds at the full rate, are left
    out of W x on the coarse samples; their full-rate part cancels in the difference where the moved trajectory's
    damper rates are traj's (the offsets that do not reach the dampers: all of the suites'), else it is added from
    both trajectories' full-rate rates. The aerodynamic wrench is traj's where the chassis' joints are (an
    accelerometer's offset moves their accelerations alone)."""
    bp = car_base_parameters(model.tree, base) if isinstance(base, str) else base
    friction = _friction_entries(bp.names, EQUATION_ROWS) if k > 1 or lp else []
    coarse_x = np.array(x, dtype=float)
    coarse_x[[c for c, _, _ in friction]] = 0.0  # their full-rate part stands for them (`_decimated`)
    residual = CarResidual(model, coarse_x, bp, regressor)
    chassis = sorted({*model.tree.ancestors[CHASSIS], CHASSIS})
    chassis = np.array(chassis) - 1

    def aero_of(c: CarTrajectory) -> Wrench | None:
        return None if aero is None else aero_wrench(model, c.q, c.qd, aero)

    c0 = _every(traj, k)
    aw0 = aero_of(c0)
    r0 = residual(c0.q, c0.qd, c0.qdd, c0.wheel_wrenches, aw0)
    joints = [j - 1 for _, _, j in friction]
    changes, rates = [], []  # rates: (index, full-rate rates) of the trajectories whose damper rates moved
    for m in moved:  # one at a time (each is the size of the segment's), their changes kept
        c = m.traj if isinstance(m, CoarseTrajectory) else _every(m, k)
        if len(c.t) != len(c0.t):
            raise ValueError(f"car_moved_rows: a moved trajectory on other samples than every {k}-th of traj's "
                             "(JointsPass.moved(..., every=coarse_step(...)[0]))")
        same = np.array_equal(c.q[:, chassis], c0.q[:, chassis]) and np.array_equal(c.qd[:, chassis],
                                                                                   c0.qd[:, chassis])
        changes.append(residual(c.q, c.qd, c.qdd, c.wheel_wrenches, aw0 if same else aero_of(c)) - r0)
        if any(not np.array_equal(m.qd[:, j], traj.qd[:, j]) for j in joints):
            rates.append((len(changes) - 1, m.qd))
    if not changes:
        return []
    V, rows = len(changes), len(EQUATION_ROWS)
    D = np.stack(changes, axis=1).reshape(len(c0.t), V * rows)
    del changes
    if rest:
        D, _ = decimate_parallel(D, None, rest, fs / k)
    D = D.reshape(-1, V, rows)
    if rates:  # their dry friction's full-rate columns moved: − Δs(qd) x
        sets = _friction_columns([traj.qd, *(qd for _, qd in rates)], joints, fs, decimate, model.tree, lp)
        for (v, _), dec in zip(rates, sets[1:], strict=True):
            n = min(len(dec), D.shape[0])
            for i, (c, row, _) in enumerate(friction):
                D[:n, v, row] -= (dec[:n, i] - sets[0][:n, i]) * x[c]
    # the rows group by group (car_system's stacking), the kept ones
    return list(D.transpose(1, 2, 0).reshape(V, -1)[:, keep])


MOVED_SAMPLES = 4096  # coarse samples per evaluation of `car_moved_rows` (a 60 s segment has 3750 at 62.5 Hz)


def car_load_changes(
    model: Model,
    traj: CarTrajectory,
    moved: Sequence[tuple[int, int, float]],
    fs: float,
    keep: np.ndarray,
    decimate: tuple[int, ...] = (5, 10),
    cutoff: float | None = None,
) -> list[np.ndarray]:
    """ΔY of the rows `keep` selects (`car_system`'s, the other arguments its own) for each (wheel, component, b):
    that wheel-wrench component of traj moved by b (N or N·m; wheels and components in `car_identification`'s
    order). W does not depend on the loads and Y is linear in them (`vehicle.equations.load_rows`): ΔY is b times
    the rows' change per unit load, through the same decimation, all in one pass."""
    if not moved:
        return []
    decimate = tuple(decimate or ())
    k, rest = coarse_step(traj, fs, decimate, cutoff)
    unit = load_rows(model, traj.q[::k], EQUATION_ROWS)  # (n, rows, 4, 6), samples contiguous per entry
    n, rows = unit.shape[:2]
    entries = np.moveaxis(unit, 0, -1)  # (rows, 4, 6, n): a view, each entry's samples read in a stream
    dY = np.stack([b * entries[:, wheel, comp] for wheel, comp, b in moved]).reshape(-1, n)  # (moved x rows, n)
    if rest:
        # a wheel's wrench reaches the chassis', its damper's and its tire's rows alone: the others' columns are zero
        # throughout, and so decimated (61 % of them on the paper's car)
        live = np.flatnonzero(np.any(dY != 0, axis=1))
        dec, _ = decimate_parallel((dY[live] if live.size else dY[:1]).T, None, rest, fs / k)
        dY = np.zeros((dY.shape[0], len(dec)))
        dY[live] = dec.T[:live.size]
    dY = dY.reshape(len(moved), rows, -1)
    keep = np.asarray(keep, dtype=bool)
    return list(dY.reshape(len(moved), -1)[:, keep])


def coarse_step(traj: CarTrajectory, fs: float, decimate: tuple[int, ...], cutoff: float | None
                 ) -> tuple[int, tuple[int, ...]]:
    """k, the step of the samples the equations are computed on, and the rest of the decimation (`car_system`)."""
    # the wheels' diametral-inertia columns oscillate at twice the spin frequency: keep it below the new Nyquist
    spin = 2 * np.abs(traj.qd[:, [w - 1 for w in WHEELS]]).max() / (2 * np.pi) if len(traj.t) else 0.0
    total = int(np.prod(decimate)) if decimate else 1
    k = None
    if cutoff is not None:  # the coarsest rate, a divisor of the whole factor, whose Nyquist frequency clears both
        needed = max(5 * cutoff, spin / 0.9)
        k = next((d for d in range(total - 1, 1, -1) if total % d == 0 and fs / (2 * d) >= needed), None)
    # W there, the rest of the decimation in one stage
    return (1, decimate) if k is None else (k, (total // k,))


def _decimated(eq, qd_full: Sequence[np.ndarray], fs: float, k: int, rest: tuple[int, ...],
               decimate: tuple[int, ...], tree, lowpass_fs: tuple[float, int] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """W (n, V, rows, p) and Y (n, V, rows) of V trajectories' equations (eq: their coarse samples one after
    the other, V = len(qd_full)) computed on every k-th sample, decimated by `rest` (W's live entries and Y of
    all V through one parallel filter); the dry-friction columns from each one's full-rate qd_full, by its joint's
    Coulomb law (`tree.friction_law`), low-passed first at lowpass_fs = (cutoff, order) when given."""
    rows, p = len(eq.rows), eq.per_sample.shape[2]
    V = len(qd_full)
    W4 = eq.per_sample.reshape(V, -1, rows, p)  # (V, N, rows, p)
    N = W4.shape[1]
    # only the (row, column) pairs that are not structural zeros (126 of the paper's 14 x 48) and Y go
    # through the filter, gathered as one (N, V (live + rows)) array
    live_r, live_c = np.nonzero(np.any(W4 != 0, axis=(0, 1)))
    nl = live_r.size
    both = np.empty((N, V, nl + rows))
    both[:, :, :nl] = W4[:, :, live_r, live_c].transpose(1, 0, 2)
    both[:, :, nl:] = eq.Y.reshape(rows, V, N).transpose(2, 1, 0)
    both = both.reshape(N, -1)
    if rest:
        both, _ = decimate_parallel(both, None, rest, fs / k)
    both = both.reshape(both.shape[0], V, nl + rows)
    W = np.zeros((both.shape[0], V, rows, p))
    W[:, :, live_r, live_c] = both[:, :, :nl]
    Y = both[:, :, nl:]
    if k > 1 or lowpass_fs:  # s(qd) is not band-limited: dry-friction columns at the full rate, decimated in parallel
        fs_cols = _friction_entries(eq.names, eq.rows)
        if fs_cols:
            sets = _friction_columns(qd_full, [j - 1 for _, _, j in fs_cols], fs, decimate, tree, lowpass_fs)
            for v, dec in enumerate(sets):
                n = min(len(dec), W.shape[0])
                for i, (c, r, _) in enumerate(fs_cols):
                    W[:n, v, r, c] = dec[:n, i]
    return W, Y


def _friction_entries(names: Sequence[str], rows: Sequence[int]) -> list[tuple[int, int, int]]:
    """(column, row index, joint) of W's dry-friction columns FSj whose joint j has an equation among rows."""
    return [(c, rows.index(int(n[2:])), int(n[2:])) for c, n in enumerate(names)
            if n.startswith("FS") and n[2:].isdigit() and int(n[2:]) in rows]


def _friction_columns(qd_full: Sequence[np.ndarray], joints: Sequence[int], fs: float, decimate: tuple[int, ...],
                      tree, lowpass_fs: tuple[float, int] | None) -> list[np.ndarray]:
    """Each trajectory's dry-friction columns s(qd) of `joints` (0-based), decimated from the full rate (low-passed
    first at lowpass_fs): one set per distinct full-rate velocity of those joints (an offset that does not reach them
    shares the unmoved trajectory's), all through one filter."""
    which: list[int] = []
    fresh: list[np.ndarray] = []
    for a in qd_full:
        cols = a[:, joints]
        i = next((j for j, d in enumerate(fresh) if np.array_equal(d, cols)), None)
        if i is None:
            fresh.append(cols)
            i = len(fresh) - 1
        which.append(i)
    signs = np.concatenate([np.stack([coulomb(d[:, i], tree.friction_law(j + 1)) for i, j in enumerate(joints)],
                                     axis=1) for d in fresh], axis=1)
    if lowpass_fs:
        signs = lowpass(signs, fs, lowpass_fs[0], order=lowpass_fs[1], axis=0)
    dec = decimate_parallel(signs, None, decimate, fs)[0]
    return [dec[:, i * len(joints):(i + 1) * len(joints)] for i in which]


def _simulated_suspensions(tree, traj: CarTrajectory, coarse: CarTrajectory, eq, values: Mapping[str, float]):
    """traj with the dampers' q, qd, qdd replaced by the identified suspensions' response to the measured loads
    (the loads from the equations of the coarse samples), started from the estimated state at the first sample."""
    cols = np.array(DAMPERS) - 1
    load = suspension_loads(tree, eq, values, coarse.qdd)
    qs, qds, qdds = suspension_response(tree, values, coarse.t, load, traj.t, traj.q[0, cols], traj.qd[0, cols])
    q, qd, qdd = traj.q.copy(), traj.qd.copy(), traj.qdd.copy()
    q[:, cols], qd[:, cols], qdd[:, cols] = qs, qds, qdds
    return CarTrajectory(traj.t, q, qd, qdd, traj.wheel_wrenches, traj.spin_torques, traj.steering_wheel)


@dataclass(frozen=True)
class SensorOffsets:
    """The sensor zero offsets propagated to σ total: channel -> (1 σ, the suite's unit of the channel), where they
    came from ("vehicle": the vehicle's sensor suite, each channel's bias; "config": [uncertainty] offsets; "none":
    turned off there), the vehicle and the segments per identification test on which they are evaluated."""

    source: str
    values: dict[str, tuple[float, str]]
    vehicle: str
    segments: int

    def si(self) -> dict[str, float]:
        """channel -> 1 σ in SI (what the channels are read in)."""
        return {q: v * unit_factor(u, channel=q)[0] for q, (v, u) in self.values.items()}

    def to_dict(self, estimates: dict[str, tuple[float, float]] | None = None) -> dict:
        """results.json's "sensor_offsets"; estimates: "test: channel" -> the offset the data read and its σ, in
        units of the declared σ (estimation.offsets), given in the channel's unit."""
        out = {"source": self.source, "vehicle": self.vehicle, "segments": self.segments,
               "estimated": bool(estimates),
               "channels": [{"channel": q, "value": v, "unit": u} for q, (v, u) in self.values.items()]}
        if estimates:
            out["estimates"] = []
            for source, (u, s) in estimates.items():
                test, channel = source.rsplit(": ", 1)
                v, unit = self.values[channel]
                out["estimates"].append({"test": test, "channel": channel, "value": u * v, "std": s * v,
                                         "unit": unit})
        return out

    def listing(self) -> str:
        """The values grouped by value and unit, the four corners of a channel in one name: "0.5 mm:
        laser_height_* (* = rl, rr, fl, fr)"."""
        groups: dict[tuple[float, str], list[str]] = {}
        for q, vu in self.values.items():
            groups.setdefault(vu, []).append(q)
        starred = False
        parts = []
        for (v, u), names in groups.items():
            shown = []
            for q in names:
                tag = next((t for t in CORNER_TAGS if f"_{t}" in q), None)
                star = q.replace(f"_{tag}", "_*", 1) if tag else q
                if tag and all(star.replace("_*", f"_{t}", 1) in names for t in CORNER_TAGS):
                    starred = True
                    q = star
                if q not in shown:
                    shown.append(q)
            parts.append(f"{v:g} {u}: {', '.join(shown)}")
        return "; ".join(parts) + (f" (* = {', '.join(CORNER_TAGS)})" if starred else "")


def sensor_offsets(settings, vehicle) -> SensorOffsets:
    """The offsets a car's identification propagates: the config's [uncertainty] offsets (CarSettings.offsets: a
    table, or {} for none) or, by default (None), the vehicle's sensor suite's zero offsets (the channels the
    estimator reads whose `bias` is not 0)."""
    suite = vehicle.suite
    label = f"{vehicle.name} ({vehicle.source})" if vehicle.source else vehicle.name
    if settings.offsets is None:
        read = required_channels(spin=False, suite=suite)
        values = {c.name: (c.bias, c.unit) for c in suite if c.bias > 0 and c.name in read}
        return SensorOffsets("vehicle", values, label, settings.offset_segments)
    values = {q: (v, suite.units[q]) for q, v in settings.offsets.items()}
    return SensorOffsets("config" if values else "none", values, label, settings.offset_segments)
