"""Tire characteristics from the track tests: cornering and longitudinal slip stiffness against vertical load, and
the lateral Magic-Formula curve where the tests reach its nonlinear range (issue 31, the paper's "further work").

Input: the estimated joints and the filtered wheel wrenches of `estimate.estimate_joints` (a `CarTrajectory`).
Per wheel and sample (`tire_samples`):

- the ISO wheel (W) axes: x along the line where the wheel plane meets the road (z0 = 0, flat), z the road's
  normal, y = z × x (left). Tire characteristics are given in these axes (a flat-track machine's), not in the
  wheel's own frame: on the MuJoCo car the body roll tilts the wheels 4.3° to the road in the spiral, and the
  wheel frame's Fy then holds sin(4.3°) of Fz: +16 % against the pure-slip curve at the same slip angle, where
  the W axes agree to 0.5 %;
- slip angle α = atan2(v_y, max(|v_x|, 1 m/s)) and slip ratio κ = (v_x - R ω) / max(|v_x|, 1 m/s) (> 0 braking)
  of the wheel centre's velocity in W axes (`kinematics.forward.point_velocity`), ω the wheel's spin rate, R the
  vehicle file's wheel radius; the free-rolling slip κ0 the fit finds gives the effective rolling radius
  R (1 - κ0);
- Fx, Fy, Fz: the ground's force on the wheel in W axes, γ the wheel's inclination to the road.

Sign conventions of the results (SAE/ISO practice): Fy = -F(α), Fx = -F(κ): a positive slip angle (the wheel
centre moving to the left of its heading) gives a force to the right; cornering stiffness and slip stiffness are
given positive, in N/rad (SI, results.json) and in N/deg and N per unit slip (the sheet's units).

The fits (`fit_tire_curves`), per axle (both wheels together: the load transfer spreads their loads) and per
tire where the data allow:

- lateral, pure slip: samples with |κ - κ free rolling| <= KAPPA_PURE (the spiral's front inner wheel spins up
  to κ = -0.07 driving, and combined slip then lowers its Fy), speed >= MIN_SPEED (the slips' noise grows as 1/v). The
  Magic Formula Fy = -D sin(C atan(B x - E (B x - atan(B x)))), x = α + Sh, with the load dependence
  D = μ Fz, μ = μ0 (1 + pD2 dfz), cornering stiffness K = B C D = k0 Fz (1 + pK2 dfz), dfz = Fz / Fz0 - 1,
  Fz0 the axle's mean load in the tests. Fitted when the tests reach the nonlinear range (the largest |Fy| is
  below NONLINEAR of the linear law's there), else the linear law K α alone on |α| <= LINEAR_ALPHA (over larger
  slips a line is the curve's secant: -7.8 % on the quick demo's rear axle at 3.7°). E is fitted only when the
  tests pass the curve's peak (it shapes the curve beyond it), else fixed at 0; a load term only when the loads
  spread over LOAD_SPREAD of Fz0.
- longitudinal: samples with |α| <= ALPHA_PURE and speed >= MIN_SPEED, with the free-rolling samples (|Fx| <=
  FREE_ROLLING Fz) at any slip angle: Fx = -Kx (κ - κ0(Fz)), Kx = kx0 Fz (1 + pKx2 dfz), κ0(Fz) = κ0 + κ0_fz
  (Fz / Fz_free - 1), fitted as κ = κ0(Fz) - Fx / Kx (the slip is the noisy side: `fit_longitudinal`). The
  free-rolling slip moves with the load because the effective rolling radius R / (1 - κ0) shrinks with it; Fz0
  is the mean load of the samples that brake or drive (|Fx| >= SLIPPING Fz: only they see Kx), and Kx is given
  per unit of the slip counted with the effective radius, (κ - κ0) / (1 - κ0). Straight-line braking holds one
  slip for seconds (about 0.03 at 6 m/s²): Kx is the secant to that slip, not the slope at zero, and no Magic
  Formula is fitted (its peak is not reached; an ABS stop would).

Nonlinear least squares: `scipy.optimize.least_squares` (trust region reflective, bounds keeping C in [MF_C_BOUNDS]
and E <= 1, from a few starts; on SUBSAMPLE x 2 samples or more, as an hour's, the starts descend on every k-th
sample and only the best end, or the few within BASIN of it, is polished on all: `_subsample_ends`; the longitudinal
law starts at its closed-form optimum, `_longitudinal_start`); on more than BLOCKS_ABOVE samples the polish is
Levenberg-Marquardt's with JᵀJ and Jᵀr summed block by block (`_polish_in_blocks`), not scipy's on all rows. Memory:
the samples once (the run's parts gathered in the fit's order, `TireSamples.ordered`), each fit's selection made
when it runs and carrying only the fields it reads, and beyond that O(n) vectors (the residual, the runs' and
instants' labels), no n × p matrix: on 3 h of benchmarks/bench_fleet.py's workload (871k samples, 70 MB) the fit's
traced peak over its sorted samples was 0.40 GB, now 0.10 GB (2 threads). And the samples bounded: a run gathers at
most MAX_SAMPLES (`sample_steps`: every m-th of the cut-off's samples, m chosen from the plan before the map; m = 1,
the same samples, under the budget), in parts the map's fold joins without copying (`SampleParts`). Measured
2026-11-29 (issue 28, h-thru2, an hour's 290k wheel samples of benchmarks/bench_pipeline.py's workload, one thread,
min of 5 fits, 3 alternated processes, load 11 on the 2-core EPYC): 1.90-2.17 -> 0.75-0.88 s CPU; the demo plans'
and the MuJoCo car's curves moved by at most 1.1e-7 σ (2.9e-6 relative), the hour's by 1e-4 σ (the old fit's own
starts ended up to 2.4e-4 σ apart on the demo's samples). σ = sqrt(diag(s² (JᵀJ)⁻¹ τ)) with J the Jacobian at the
solution, s² = ‖r‖² / (n - p), and τ = 1 + 2 Σ ρ_k the residual's integrated autocorrelation (over each wheel's run
of consecutive samples, summed while ρ_k > 0): the samples are 4 Hz low-passed signals read at 5 × the cut-off, so
consecutive residuals are not independent; times the simultaneity factor (`simultaneity_factor`): an axle's two
wheels share the chassis velocity's estimate and its error in their slips. It assumes the model right (no bias:
combined slip, camber thrust, relaxation length and the filters' lag are not modelled), the slips and loads exact
but for noise (errors in α and κ bias slopes down by their variance's share: 0.3 % on the MuJoCo car's sensor
files), the residual stationary with one variance, J alike for the wheels of one instant, and the solution inside
its bounds (a parameter at a bound gets no σ).
"""

from __future__ import annotations

import csv
import io
import math
import os
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from ..car_frames import CORNER_TAGS
from ..kinematics.forward import forward_kinematics, joint_array, point_velocity
from .engineering import Quantity
from .template import WHEELS, tire

Array = np.ndarray

AXLES = {"front": (2, 3), "rear": (0, 1)}
MIN_SPEED = 10.0  # m/s: the slips' noise grows as 1/v (a 0.05 m/s speed error is a slip of 0.012 at 15 km/h)
KAPPA_PURE = 0.01  # |κ| at most for pure lateral slip: the MuJoCo car's Fy is then within 0.5 % of pure slip
ALPHA_PURE = math.radians(0.5)  # |α| at most for pure longitudinal slip
LINEAR_ALPHA = math.radians(2.0)  # the linear range of the per-tire cornering stiffness
NONLINEAR = 0.95  # the tests reach the nonlinear range when |Fy| at the largest slips is below 95 % of K |α|
LOAD_SPREAD = 0.3  # a load term is fitted only when the loads spread over 30 % of the nominal load
FREE_ROLLING = 0.02  # |Fx| <= 0.02 Fz: a wheel rolling free (the free-rolling slip's samples)
SLIPPING = 0.1  # |Fx| >= 0.1 Fz: a wheel braking or driving (a slip of about 0.005, 5x the free-rolling scatter)
MF_C_BOUNDS = (1.0, 2.0)
MIN_POINTS = 20
DEG = math.pi / 180.0


class TireCurveError(ValueError):
    """The tire data cannot give the asked curve (too few samples, no slip, a bad option)."""


# ------------------------------------------------------------------------------------------------------- samples
@dataclass(frozen=True)
class TireSamples:
    """Per-wheel samples of the tests (N,) each: test name, corner index (0 rl, 1 rr, 2 fl, 3 fr), time (s, in
    the test), the slips, the wheel's inclination to the road γ (rad), the wheel centre's forward speed (m/s)
    and the ground's force on the wheel in ISO wheel (W) axes (N)."""

    test: Array
    corner: Array
    t: Array
    alpha: Array
    kappa: Array
    gamma: Array
    vx: Array
    fx: Array
    fy: Array
    fz: Array

    def __len__(self) -> int:
        return len(self.t)

    def merge(self, other: TireSamples) -> TireSamples:
        """self's samples then other's."""
        return TireSamples(*(np.concatenate([getattr(self, f), getattr(other, f)]) for f in _FIELDS))

    def select(self, mask: Array, fields: Sequence[str] | None = None) -> TireSamples:
        """The samples of mask (a boolean mask, indices or a slice). fields: the measured fields to copy (default:
        all); the others, and those absent here, are `_absent` (a NaN view of no memory): a fit's selection
        carries what it reads."""
        keys = [getattr(self, f)[mask] for f in _KEYS]
        n = len(keys[0])
        measured = [getattr(self, f) for f in _FIELDS[len(_KEYS):]]
        return TireSamples(*keys, *(_absent(n) if _is_absent(a) or (fields is not None and f not in fields)
                                    else a[mask] for f, a in zip(_FIELDS[len(_KEYS):], measured, strict=True)))

    @staticmethod
    def ordered(parts: Sequence[TireSamples]) -> TireSamples:
        """The parts' samples, merged in turn (`merge`) and sorted by test, wheel and time as the fit takes them
        (a stable sort: the same as merging them then sorting), each field gathered once: no intermediate merge,
        and the fit then makes no sorted copy."""
        if not parts:
            return empty_samples()
        keys = [np.concatenate([getattr(s, f) for s in parts]) for f in ("t", "corner")]
        names = _test_names(parts)  # once: each part's every name made a Python object
        order = np.lexsort((*keys, np.concatenate([_test_codes(s.test, names) for s in parts])))
        del keys  # the keys' arrays let go before the fields' are gathered
        return TireSamples(*(np.concatenate([getattr(s, f) for s in parts])[order] for f in _FIELDS))


@dataclass(frozen=True)
class SampleParts:
    """Wheel samples in parts, as a run's segments gathered them (`tire_samples` each), joined by `merge` without
    copying a sample: a map's fold (`pipeline.reduce.combine`) joins lists, and the fit gathers the parts once
    (`samples`). Merged as arrays, each level of the fold copied every sample gathered so far, and its last combines
    held them twice (the map's end, where an hour's run peaks)."""

    parts: tuple[TireSamples, ...] = ()

    def __len__(self) -> int:
        return sum(len(p) for p in self.parts)

    def merge(self, other: SampleParts) -> SampleParts:
        """self's parts then other's."""
        return SampleParts(self.parts + other.parts)

    def samples(self) -> TireSamples:
        """The parts' samples in the fit's order (`TireSamples.ordered`)."""
        return TireSamples.ordered(self.parts)


_FIELDS = ("test", "corner", "t", "alpha", "kappa", "gamma", "vx", "fx", "fy", "fz")
_KEYS = ("test", "corner", "t")  # a sample's test, wheel and time: every selection carries them
LATERAL_FIELDS = ("alpha", "fy", "fz")  # what the lateral fits read (`fit_lateral`, `fit_tire`)
LONGITUDINAL_FIELDS = ("kappa", "vx", "fx", "fz")  # and the longitudinal ones (`fit_longitudinal`)


_NAN = np.array(np.nan)  # the one value every absent field views
_NAN.flags.writeable = False


def _absent(n: int) -> Array:
    """A field a selection does not carry: n NaNs, read-only, in no memory (a broadcast view of _NAN)."""
    return np.broadcast_to(_NAN, (n,))


def _is_absent(a: Array) -> bool:
    """Whether a is an `_absent` field (a view of _NAN: not any broadcast array a caller may give)."""
    return isinstance(a, np.ndarray) and a.strides == (0,) and np.may_share_memory(a, _NAN)


def _carries(s: TireSamples, fields: Sequence[str], what: str) -> None:
    """Raise when s does not carry a field that `what` reads (an `_absent` one: its NaNs would be read as data), or
    carries one with a value that is not finite (one NaN slip made a lateral fit's μ0 2.9e-4, silently)."""
    absent = [f for f in fields if _is_absent(getattr(s, f))]
    if absent:
        raise TireCurveError(f"{what} reads {', '.join(absent)}, which these samples do not carry (a selection of "
                             "other fields, `TireSamples.select(mask, fields)`): select them with these fields too")
    for f in fields:
        bad = ~np.isfinite(getattr(s, f))
        if bad.any():
            i = int(np.argmax(bad))
            raise TireCurveError(f"{what}: {f} is not finite at {int(bad.sum())} of {len(s)} samples, the first "
                                 f"sample {i} (wheel {s.corner[i]}, t = {s.t[i]:.3f} s): remove or repair them")


PER_PERIOD = 5  # wheel samples per period of the cut-off: the loads and joints are low-passed at it
MAX_SAMPLES = 2**20  # a run's wheel samples at most (84 MB; 3.6 h of 625 Hz logs at a 4 Hz cut-off): `sample_steps`


def sample_steps(tests: Sequence[tuple[float, Sequence[int]]], cutoff: float, budget: int | None = None) -> list[int]:
    """Each test's step between wheel samples (`tire_samples`' step, from each segment's first sample), chosen before
    the map so that a run gathers at most `budget` wheel samples whatever its logs' length (the fit's memory bounded):
    PER_PERIOD samples per period of the cut-off (Hz), times one whole factor m for all the tests, the least whose
    count (4 wheels per instant, each segment's whole window counted: a bound) is within the budget. Under it, m = 1:
    the samples, and so the curves, of a run without a budget. Above it the fit sees every m-th sample: its σ come
    from those, their autocorrelation factor τ counted on them (consecutive samples of a 4 Hz low-passed signal at
    20 Hz are not independent: thinned, τ drops and σ grows by less than √m). tests: (fs in Hz, the segments'
    lengths in samples) per test; budget None: MAX_SAMPLES."""
    budget = MAX_SAMPLES if budget is None else budget
    if not budget >= 4:
        raise TireCurveError(f"budget = {budget!r} wheel samples: give at least 4 (one instant of the 4 wheels)")
    base = [max(1, round(fs / (PER_PERIOD * cutoff))) for fs, _ in tests]
    longest = max((n for _, lengths in tests for n in lengths), default=1)

    def count(m: int) -> int:
        return 4 * sum(-(-n // (b * m)) for (_, lengths), b in zip(tests, base, strict=True) for n in lengths)

    m = max(1, -(-count(1) // budget))
    while count(m) > budget and min(base) * m < longest:  # each segment's ceil: a step further may be needed
        m += 1
    return [b * m for b in base]


def tire_samples(model, traj, test: str, wheel_radius: float, t0: float = 0.0, step: int = 1) -> TireSamples:
    """The slips and W-axis forces of the four wheels on every `step`-th sample of `traj` (a `CarTrajectory` of the
    42-frame template; its wheel_wrenches the ground's wrench on each wheel in the tire frame: x forward in the
    wheel plane, y left, z up). t0: the trajectory's first sample's time in the test (s); wheel_radius (m): the
    radius the slip ratio is counted with."""
    if not wheel_radius > 0:
        raise TireCurveError(f"wheel_radius = {wheel_radius!r} m: give the wheel's radius (> 0)")
    if step < 1:
        raise TireCurveError(f"step = {step!r}: give a whole number >= 1")
    q, qd = np.asarray(traj.q)[::step], np.asarray(traj.qd)[::step]
    F = np.asarray(traj.wheel_wrenches)[::step, :, :3]
    n = len(q)
    tires = [tire(k) for k in range(4)]
    # one pass for the tire frames and the wheel centres: each frame's pose is the same whichever others are asked
    st = forward_kinematics(model.tree, joint_array(q, model.tree, "q")[0], frames=[*tires, *WHEELS])
    qd_rows = np.asfortranarray(qd)  # point_velocity's joints-first copy made once here, not once per wheel
    out = []
    for k, (w, f) in enumerate(zip(WHEELS, tires, strict=True)):
        R = np.stack([np.asarray(np.broadcast_to(c, (3, n))) for c in st.Rc[f]], axis=1)  # (3, 3, n) columns
        R = np.moveaxis(R, -1, 0)  # (n, 3, 3): 0R_tire
        v, _ = point_velocity(model.tree, q, qd_rows, w, state=st)  # wheel centre, frame 0 (the spin leaves it unmoved)
        y_wheel = R[:, :, 1]
        x_w = np.cross(y_wheel, [0.0, 0.0, 1.0])  # the wheel plane's line on the road
        x_w /= np.linalg.norm(x_w, axis=1)[:, None]
        y_w = np.cross([0.0, 0.0, 1.0], x_w)
        force = np.einsum("nij,nj->ni", R, F[:, k])  # frame 0
        vx, vy = np.einsum("ni,ni->n", v, x_w), np.einsum("ni,ni->n", v, y_w)
        den = np.maximum(np.abs(vx), 1.0)
        omega = qd[:, w - 1]
        out.append((np.full(n, k), t0 + np.asarray(traj.t)[::step],
                    np.arctan2(vy, den), (vx - wheel_radius * omega) / den, np.arcsin(np.clip(y_wheel[:, 2], -1, 1)),
                    vx, np.einsum("ni,ni->n", force, x_w), np.einsum("ni,ni->n", force, y_w), force[:, 2]))
    # the four wheels' samples in turn (`TireSamples.merge`'s order), each field concatenated once; every sample's
    # test the one str (np.full made a str per sample from the name's array: 57 B each, 16 MB an hour of data)
    names = np.empty(4 * n, dtype=object)
    names.fill(test)
    return TireSamples(names, *(np.concatenate(f) for f in zip(*out, strict=True)))


def empty_samples() -> TireSamples:
    return TireSamples(np.empty(0, dtype=object), *(np.empty(0) for _ in _FIELDS[1:]))


# --------------------------------------------------------------------------------------------- Magic Formula
def magic_formula(x: Array, B: Array | float, C: Array | float, D: Array | float, E: Array | float) -> Array:
    """Pacejka's pure-slip curve D sin(C atan(B x - E (B x - atan(B x)))) (its slope at 0 is B C D)."""
    bx = B * x
    if np.ndim(E) == 0 and E == 0 and np.isfinite(bx).all():  # E (bx - atan(bx)) is 0: the same bits, one atan less
        return D * np.sin(C * np.arctan(bx))
    return D * np.sin(C * np.arctan(bx - E * (bx - np.arctan(bx))))


def peak_slip(B: float, C: float, E: float) -> float:
    """The slip of the curve's peak: C atan(u) = π/2 with u = B x - E (B x - atan(B x)); inf when C <= 1 (no peak)."""
    if C <= 1.0:
        return math.inf
    u = math.tan(math.pi / (2 * C))
    lo, hi = 0.0, 1.0
    f = lambda z: z - E * (z - math.atan(z)) - u  # noqa: E731 (increasing in z for E <= 1)
    while f(hi) < 0:
        hi *= 2
        if hi > 1e6:
            return math.inf
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi) / B


@dataclass
class Fit:
    """A least-squares fit: names, values, covariance (its assumptions in the module doc), residual RMS, the
    residual's autocorrelation factor τ, the number of samples, parameters held fixed (name -> value) and those
    that ended at a bound (no σ)."""

    names: list[str]
    values: Array
    cov: Array
    rms: float
    tau: float
    n: int
    fixed: dict[str, float] = field(default_factory=dict)
    at_bound: list[str] = field(default_factory=list)

    @property
    def std(self) -> Array:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    def value(self, name: str) -> float:
        if name in self.fixed:
            return self.fixed[name]
        return float(self.values[self.names.index(name)])

    def sigma(self, name: str) -> float:
        if name in self.fixed:
            return 0.0
        return float(self.std[self.names.index(name)])

    def propagate(self, f, eps: float = 1e-6) -> tuple[float, float]:
        """f(params dict) and its first-order σ (central differences on the fitted values)."""
        x = np.asarray(self.values, dtype=float)

        def at(v: Array) -> float:
            return float(f({**self.fixed, **dict(zip(self.names, v, strict=True))}))

        g = np.zeros(len(x))
        for i in range(len(x)):
            h = eps * max(abs(x[i]), 1e-3)
            up, dn = x.copy(), x.copy()
            up[i] += h
            dn[i] -= h
            g[i] = (at(up) - at(dn)) / (2 * h)
        return at(x), float(math.sqrt(max(g @ self.cov @ g, 0.0)))


def autocorrelation_factor(r: Array, runs: Array | None = None, max_lag: int = 200) -> float:
    """τ = 1 + 2 Σ ρ_k of the residual r over its runs of consecutive samples (runs: a label per sample, each run's
    samples contiguous; a lag never crosses two runs), the sum stopped at the first ρ_k <= 0 (at least 1)."""
    r = np.asarray(r, dtype=float)
    labels = np.zeros(len(r)) if runs is None else np.asarray(runs)
    r = r - r.mean()
    var = float(r @ r)
    if var == 0.0:
        return 1.0
    tau = 1.0
    for k in range(1, min(max_lag, len(r) - 1)):
        ok = labels[:-k] == labels[k:]  # runs are contiguous: both ends in one run
        rho = float(r[:-k][ok] @ r[k:][ok]) / var
        if rho <= 0:
            break
        tau += 2 * rho
    return tau


def simultaneity_factor(r: Array, instants: Array | None) -> float:
    """Σ_g (Σ_{i in g} r_i)² / Σ r_i² over the groups g of simultaneous samples (instants: a label per sample, the
    same for the wheels of one axle at one time), at least 1: how much the wheels' residuals at one instant move
    together. An axle's two wheels share the chassis velocity's estimate, hence its error in their slips (on the
    MuJoCo car's noise/ their residuals correlate at 0.89): counted as independent, they were counted twice."""
    if instants is None or len(r) == 0:
        return 1.0
    r = np.asarray(r, dtype=float) - float(np.mean(r))
    var = float(r @ r)
    if var == 0.0:
        return 1.0
    _, g = np.unique(np.asarray(instants), return_inverse=True)
    sums = np.bincount(g, weights=r)
    return max(1.0, float(sums @ sums) / var)


def _least_squares(fun, starts: Sequence[Array], lower: Array, upper: Array, names: list[str],
                   runs: Array | None, fixed: dict[str, float], instants: Array | None = None, jac=None) -> Fit:
    """The best of the starts, and its covariance (module doc); jac: fun's Jacobian (default: finite differences)."""
    span = upper - lower
    margin = np.where(np.isfinite(span), 1e-9 * span, 0.0)
    best = None
    for x0 in starts:
        x0 = np.clip(np.asarray(x0, dtype=float), lower + margin, upper - margin)
        try:
            r = least_squares(fun, x0, jac="2-point" if jac is None else jac, bounds=(lower, upper), method="trf",
                              x_scale="jac", max_nfev=200)
        except ValueError:
            continue
        if np.all(np.isfinite(r.fun)) and (best is None or r.cost < best.cost):
            best = r
    if best is None:
        raise TireCurveError("the tire curve fit found no finite solution from any start")
    J = best.jac

    def gram(free: Array) -> Array:
        Jf = J[:, free]
        return Jf.T @ Jf

    return _fit_at(best.x, best.fun, gram, lower, upper, names, runs, fixed, instants)


def _fit_at(x: Array, r: Array, gram, lower: Array, upper: Array, names: list[str], runs: Array | None,
            fixed: dict[str, float], instants: Array | None) -> Fit:
    """The fit at its solution x: residual r (n,), gram(free) JᵀJ of the free parameters' columns (those not at a
    bound), σ as the module doc says."""
    span = upper - lower
    margin = np.where(np.isfinite(span), 1e-9 * span, 0.0)
    n, p = len(r), len(x)
    if n <= p:
        raise TireCurveError(f"the tire curve fit has {n} samples for {p} parameters")
    s2 = float(r @ r) / (n - p)
    tau = autocorrelation_factor(r, runs) * simultaneity_factor(r, instants)
    tol = 1e3 * margin
    near = np.isfinite(span) & ((x - lower <= tol) | (upper - x <= tol))
    cov = np.full((p, p), np.nan)
    free = ~near
    if free.any():
        try:
            cf = np.linalg.pinv(gram(free)) * s2 * tau
        except np.linalg.LinAlgError:
            cf = np.full((free.sum(), free.sum()), np.nan)
        idx = np.flatnonzero(free)
        cov[np.ix_(idx, idx)] = cf
    cov[near, :] = 0.0
    cov[:, near] = 0.0
    return Fit(names, x, cov, math.sqrt(float(r @ r) / n), tau, n, fixed,
               [nm for nm, b in zip(names, near, strict=True) if b])


BLOCK = 2**15  # rows of a block of the polish on every sample: its Jacobian 0.25 MB per parameter
BLOCKS_ABOVE = 2 * BLOCK  # fits on more samples than this are polished in blocks (an hour's: 46k-145k)
STEP_SIGMA = 1e-7  # the polish stops when its next step moves the parameters by less than this many σ
MAX_STEPS = 50


def _least_squares_rows(problem, n: int, starts: Sequence[Array], lower: Array, upper: Array, names: list[str],
                        runs: Array | None, fixed: dict[str, float], instants: Array | None = None) -> Fit:
    """`_least_squares` of problem(rows) -> (fun, jac), the residual and Jacobian of those rows (a slice) of the
    n samples: on more than BLOCKS_ABOVE, polished in blocks (`_polish_in_blocks`), else (or when that declines)
    scipy's solver on all rows."""
    if n > BLOCKS_ABOVE:
        fit = _polish_in_blocks(problem, n, starts, lower, upper, names, runs, fixed, instants)
        if fit is not None:
            return fit
    fun, jac = problem(slice(None))
    return _least_squares(fun, starts, lower, upper, names, runs, fixed, instants, jac)


def _polish_in_blocks(problem, n: int, starts: Sequence[Array], lower: Array, upper: Array, names: list[str],
                      runs: Array | None, fixed: dict[str, float], instants: Array | None) -> Fit | None:
    """The best of the starts' Levenberg-Marquardt descents with JᵀJ, Jᵀr and rᵀr summed block by block (BLOCK rows at a
    time): beyond the residual (n,) the memory is a block's, where scipy's solver holds J (n × p), its scaled copy,
    the SVD's U and the residuals (an hour's longitudinal fit of 145k samples: ~20 MB). Each descent steps until its
    Gauss-Newton step would move the parameters by less than STEP_SIGMA σ (the change of the cost it predicts, ½ z²
    s², z in σ without τ): the optimum to that, where scipy's tolerance (ftol 1e-8 on the cost) stops up to
    sqrt(1e-8 n) σ short of it. The starts are the ends of descents on a subsample (or a closed-form optimum): 1-4
    steps; a step within the floats' resolution of every parameter ends a descent too (data without noise, whose
    σ is round-off). None (the caller then runs scipy's solver on all rows) when a step would leave the bounds'
    interior (a parameter at a bound: scipy's bounded solver says which) or a descent fails to converge in
    MAX_STEPS."""
    blocks = [slice(i, min(i + BLOCK, n)) for i in range(0, n, BLOCK)]
    span = upper - lower
    margin = np.where(np.isfinite(span), 1e-9 * span, 0.0)
    inner_lo, inner_hi = lower + 1e3 * margin, upper - 1e3 * margin  # `_fit_at`'s "at a bound" left out

    def sums(x: Array) -> tuple[Array, Array, float]:
        A, g, c = np.zeros((len(x), len(x))), np.zeros(len(x)), 0.0
        for b in blocks:
            fun, jac = problem(b)
            r, J = fun(x), jac(x)
            A += J.T @ J
            g += J.T @ r
            c += float(r @ r)
        return A, g, 0.5 * c

    best = None
    for x0 in starts:
        x = np.clip(np.asarray(x0, dtype=float), lower + margin, upper - margin)
        if np.any(x <= inner_lo) or np.any(x >= inner_hi):
            return None
        A, g, c = sums(x)
        lam, done = 0.0, False
        for _ in range(MAX_STEPS):
            if not (np.isfinite(c) and np.all(np.isfinite(A)) and np.all(np.isfinite(g))):
                return None
            d = np.sqrt(np.diag(A))
            d[d == 0] = 1.0
            As, gs = A / np.outer(d, d), g / d
            try:
                h = np.linalg.solve(As + lam * np.eye(len(x)), -gs)
            except np.linalg.LinAlgError:
                return None
            s2 = 2 * c / max(n - len(x), 1)
            if lam == 0.0 and -(gs @ h) <= STEP_SIGMA**2 * s2:  # the Gauss-Newton step's ½ z² s² (z in σ)
                done = True
                break
            xn = x + h / d
            # a Gauss-Newton step within the floats' resolution of every parameter (1e-13 of it, ~500 of its last
            # bits; scipy's xtol is 1e-8): the optimum as the floats tell it. Only where σ itself is that small (data
            # without noise, σ under 1e-6 of a value) does this stop a step short of STEP_SIGMA σ
            if lam == 0.0 and np.all(np.abs(xn - x) <= 1e-13 * np.abs(x)):
                done = True
                break
            if np.any(xn <= inner_lo) or np.any(xn >= inner_hi):
                return None
            An, gn, cn = sums(xn)
            # a Gauss-Newton step whose predicted change of the cost is below the cost's own rounding (rᵀr summed:
            # 1e-13 of it and more) is taken on the gradient's word: the cost cannot tell it from no change
            blind = lam == 0.0 and -(gs @ h) <= 1e-10 * c
            if np.isfinite(cn) and (cn <= c or blind):
                x, A, g, c, lam = xn, An, gn, cn, (0.0 if lam <= 1e-6 else lam / 10)
            else:
                lam = 1e-3 if lam == 0.0 else 10 * lam
                if lam > 1e8:
                    return None
        if not done:
            return None
        if best is None or c < best[2]:
            best = (x, A, c)
    if best is None:
        return None
    x, A, _ = best
    r = np.empty(n)
    for b in blocks:
        r[b] = problem(b)[0](x)
    return _fit_at(x, r, lambda free: A[np.ix_(free, free)], lower, upper, names, runs, fixed, instants)


def fit_magic_formula(x: Array, F: Array, runs: Array | None = None, E: float | None = None) -> Fit:
    """B, C, D, E of F = magic_formula(x, B, C, D, E) by nonlinear least squares, σ as the module doc says
    (runs: see `autocorrelation_factor`; None: independent samples). E: held at this value when given."""
    x, F = np.asarray(x, dtype=float), np.asarray(F, dtype=float)
    if x.shape != F.shape or x.ndim != 1:
        raise TireCurveError(f"slips and forces must be two 1-D arrays of one length; got {x.shape} and {F.shape}")
    if len(x) < MIN_POINTS or not np.all(np.isfinite(x)) or not np.all(np.isfinite(F)):
        raise TireCurveError(f"the Magic Formula needs at least {MIN_POINTS} finite samples; got {len(x)}")
    if np.ptp(x) == 0:
        raise TireCurveError("the slips do not vary: no curve can be fitted")
    i = np.argsort(np.abs(x))[: max(5, len(x) // 10)]
    slope = float(np.polyfit(x[i], F[i], 1)[0]) if np.ptp(x[i]) > 0 else 1.0
    Dm = float(np.max(np.abs(F))) * math.copysign(1.0, slope)
    names = ["B", "C", "D"] + ([] if E is not None else ["E"])
    fixed = {} if E is None else {"E": float(E)}

    def fun(p: Array) -> Array:
        B, C, D = p[:3]
        return magic_formula(x, B, C, D, p[3] if E is None else E) - F

    lower = np.array([1e-6, 0.5, -np.inf] + ([] if E is not None else [-10.0]))
    upper = np.array([np.inf, 3.0, np.inf] + ([] if E is not None else [1.0]))
    starts = []
    for C0 in (1.3, 1.6, 1.9):
        for E0 in ((0.0, -1.0, 0.5) if E is None else (E,)):
            B0 = abs(slope / (C0 * Dm)) if Dm else 10.0
            starts.append([B0, C0, Dm] + ([] if E is not None else [E0]))
    return _least_squares(fun, starts, lower, upper, names, runs, fixed)


# ------------------------------------------------------------------------------------------------- the curves
@dataclass
class LateralCurve:
    """One axle's or tire's lateral law: the fit (parameters k0 [N/rad per N], mu0, C, E, Sh [rad], pK2, pD2 as
    fitted or fixed), the nominal load Fz0 (N), whether the Magic Formula was fitted (else linear), and the
    ranges of the samples used."""

    fit: Fit
    fz0: float
    magic: bool
    alpha_range: tuple[float, float]
    fz_range: tuple[float, float]
    peak_reached: bool
    fz_mean: float = float("nan")  # the samples' mean load (N)

    def force(self, alpha: Array, fz: Array) -> Array:
        return lateral_force(self.fit_params(), self.fz0, np.asarray(alpha, float), np.asarray(fz, float),
                             self.magic)

    def fit_params(self) -> dict[str, float]:
        return {**self.fit.fixed, **dict(zip(self.fit.names, (float(v) for v in self.fit.values), strict=True))}

    def stiffness(self, fz: float) -> tuple[float, float]:
        """Cornering stiffness (N/rad) at load fz (N) and its σ."""
        return self.fit.propagate(lambda p: _stiffness(p, self.fz0, fz))

    def coefficients(self, fz: float) -> dict[str, tuple[float, float]]:
        """B (1/rad), C, D (N), E at load fz with their σ (the Magic Formula only)."""
        out = {}
        for name, f in (("B", lambda p: _stiffness(p, self.fz0, fz) / (p["C"] * _mu(p, self.fz0, fz) * fz)),
                        ("C", lambda p: p["C"]), ("D", lambda p: _mu(p, self.fz0, fz) * fz), ("E", lambda p: p["E"])):
            out[name] = self.fit.propagate(f)
        return out


def _mu(p: Mapping[str, float], fz0: float, fz: Array | float, dfz: Array | None = None) -> Array | float:
    return p["mu0"] * (1 + p.get("pD2", 0.0) * (np.asarray(fz) / fz0 - 1 if dfz is None else dfz))


def _stiffness(p: Mapping[str, float], fz0: float, fz: Array | float, dfz: Array | None = None) -> Array | float:
    return p["k0"] * np.asarray(fz) * (1 + p.get("pK2", 0.0) * (np.asarray(fz) / fz0 - 1 if dfz is None else dfz))


def lateral_force(p: Mapping[str, float], fz0: float, alpha: Array, fz: Array, magic: bool = True,
                  dfz: Array | None = None) -> Array:
    """Fy (N, ground on wheel, W axes) at slip angle alpha (rad) and load fz (N): -K x (linear) or the Magic
    Formula with K = B C D, x = alpha + Sh (parameters: `LateralCurve`). dfz: fz / fz0 - 1 when the caller has
    it (a fit evaluates it once, not twice per call)."""
    x = alpha + p.get("Sh", 0.0)
    K = _stiffness(p, fz0, fz, dfz)
    if not magic:
        return -K * x
    D = _mu(p, fz0, fz, dfz) * fz
    C = p["C"]
    return -magic_formula(x, K / (C * D), C, D, p["E"])


LATERAL_PARAMETERS = ("k0", "mu0", "C", "Sh", "E", "pK2", "pD2")


def lateral_force_jacobian(p: Mapping[str, float], fz0: float, alpha: Array, fz: Array, dfz: Array) -> Array:
    """d Fy / d (k0, mu0, C, Sh, E, pK2, pD2) of the Magic Formula `lateral_force` (N, 7), in closed form: a fit's
    Jacobian in one evaluation instead of one per parameter (finite differences were half of the lateral fits'
    time). With u = (1 - E) B x + E atan(B x) and Fy = -D sin(C atan u), B x = K x / (C D)."""
    k0, mu0, C, E = p["k0"], p["mu0"], p["C"], p["E"]
    pK2, pD2 = p.get("pK2", 0.0), p.get("pD2", 0.0)
    x = alpha + p.get("Sh", 0.0)
    dK_dk0 = fz * (1 + pK2 * dfz)
    dD_dmu0 = fz * (1 + pD2 * dfz)
    K, D = k0 * dK_dk0, mu0 * dD_dmu0
    bx = K * x / (C * D)
    at = np.arctan(bx)
    u = bx - E * (bx - at)
    au = np.arctan(u)
    cos_ = np.cos(C * au)
    dF_dbx = -D * cos_ * C / (1 + u * u) * ((1 - E) + E / (1 + bx * bx))  # through u
    dF_dD = -np.sin(C * au) - dF_dbx * bx / D  # D's own factor, and through B = K / (C D)
    dF_dK = dF_dbx * x / (C * D)
    out = np.empty((np.size(x), len(LATERAL_PARAMETERS)))
    out[:, 0] = dF_dK * dK_dk0
    out[:, 1] = dF_dD * dD_dmu0
    out[:, 2] = -D * cos_ * au - dF_dbx * bx / C
    out[:, 3] = dF_dbx * K / (C * D)
    out[:, 4] = D * cos_ * C / (1 + u * u) * (bx - at)
    out[:, 5] = dF_dK * k0 * fz * dfz
    out[:, 6] = dF_dD * mu0 * fz * dfz
    return out


@dataclass
class LongitudinalLaw:
    """One axle's or tire's longitudinal law Fx = -Kx (κ - κ0), Kx = kx0 Fz (1 + pKx2 dfz): the fit (kx0 per N,
    kappa0, pKx2), the nominal load, the sample ranges."""

    fit: Fit
    fz0: float
    kappa_range: tuple[float, float]
    fz_range: tuple[float, float]
    fz_free: float = 0.0  # the free-rolling samples' mean load, kappa0_fz's reference (N)
    kappa_seen: float = 0.0  # the mean |κ - κ0| of the braking or driving samples: Kx is the secant to it

    def free_rolling_slip_at(self, fz: Array) -> Array:
        """κ0 at each load of fz (N), the fitted values."""
        return self.fit.value("kappa0") + self.fit.value("kappa0_fz") * (np.asarray(fz) / self.fz_free - 1)

    def free_rolling_slip(self, fz: float) -> tuple[float, float]:
        """κ0 at the load fz (the effective rolling radius R / (1 - κ0) shrinks with the load), and its σ."""
        return self.fit.propagate(lambda p: p["kappa0"] + p.get("kappa0_fz", 0.0) * (fz / self.fz_free - 1))

    def stiffness(self, fz: float) -> tuple[float, float]:
        """Kx at the load fz (N per unit slip), the slip counted with the effective rolling radius at that load
        (Pacejka's, and the simulators' truth: κ_e = (κ - κ0) / (1 - κ0)), and its σ."""
        return self.fit.propagate(lambda p: p["kx0"] * fz * (1 + p.get("pKx2", 0.0) * (fz / self.fz0 - 1))
                                  * (1 - p["kappa0"] - p.get("kappa0_fz", 0.0) * (fz / self.fz_free - 1)))


def _runs(s: TireSamples) -> Array:
    """A label per sample of its wheel's run of consecutive samples (a test's wheel; a gap in time starts anew)."""
    out = np.zeros(len(s), dtype=int)
    if len(s) == 0:
        return out
    dt = np.diff(s.t)
    step = np.median(np.abs(dt)) if len(dt) else 1.0
    # a new run where the test or the wheel changes (compared as arrays: a string key per sample cost 20 ms per
    # 100k samples) or time jumps
    other = (s.test[1:] != s.test[:-1]) | (s.corner[1:] != s.corner[:-1])
    new = np.r_[True, other | (np.abs(dt - step) > 0.5 * step)]
    return np.cumsum(new)


def _instants(s: TireSamples) -> Array:
    """A label per sample of its instant (its test and time): the wheels' samples at one time share it."""
    if len(s) == 0:
        return np.zeros(0, dtype=int)
    # the test's index and the time in whole microseconds (the samples' times are multiples of the logger's
    # period, far from a half microsecond: the rounding is never a tie); integers, not a string per sample
    test = _test_codes(s.test)
    micro = np.round(np.asarray(s.t, dtype=float) * 1e6).astype(np.int64)
    micro -= micro.min()
    return np.unique(test * (int(micro.max()) + 1) + micro, return_inverse=True)[1]


def _test_names(parts: Sequence[TireSamples]) -> list:
    """The tests' names of every part, sorted as strings (`_test_codes`' order)."""
    return sorted(set().union(*(set(s.test.tolist()) for s in parts)), key=str)


def _test_codes(test: Array, names: list | None = None) -> Array:
    """Per sample, its test name's index among the names sorted (int64): the order of the names as strings, without
    converting every sample's name (`astype(str)` of an hour's 290k object names cost 20-25 ms a call, 7 calls).
    names: the sorted names to index in (default: test's own). Without names, integers are taken as such indices
    already (the fit's selections carry them: `_fit_tire_curves`); with names, a caller's integer names are indexed
    in them as any (their values are no indices in names: `slip_reach`'s names[code])."""
    test = np.asarray(test)
    if names is None:
        if test.dtype.kind in "iu":
            return test.astype(np.int64)
        names = sorted(set(test.tolist()), key=str)
    codes = np.zeros(len(test), dtype=np.int64)
    for i, name in enumerate(names[1:], 1):  # a few tests: one comparison pass each
        codes[test == name] = i
    return codes


def _ordered(s: TireSamples) -> TireSamples:
    """The samples sorted by test, wheel and time (segments arrive in any order from the workers); s itself when
    it is so already (a stable sort leaves it as it is: no copy of an hour's samples)."""
    codes = _test_codes(s.test)
    if _sorted(codes, s.corner, s.t):
        return s
    return s.select(np.lexsort((s.t, s.corner, codes)))


def _sorted(codes: Array, corner: Array, t: Array) -> bool:
    """Whether the keys (test code, wheel, time) never decrease from one sample to the next."""
    if len(t) < 2:
        return True
    dc, dk, dt = np.diff(codes), np.diff(corner), np.diff(t)
    return bool(np.all((dc > 0) | ((dc == 0) & ((dk > 0) | ((dk == 0) & (dt >= 0))))))


def free_rolling_slip(s: TireSamples) -> Array:
    """Per sample, its wheel's free-rolling slip ratio: the median κ where |Fx| <= 2 % of Fz at speed; for a wheel
    that rolls free on fewer than MIN_POINTS samples (a driven wheel: the demo's front ones, 27-83 samples, none in
    one seed of ten), its axle's, else every wheel's (0 when no wheel rolls free). The wheel radius the slips are
    counted with is the geometric one; a tire rolls on a different effective radius (dynid's 406: about -0.02 of
    slip), and pure slip is about that. Before the fall-back, a wheel without a free-rolling sample had κ0 = 0:
    its pure-slip selection (|κ - κ0| <= KAPPA_PURE) kept 61 of its ~1000 samples, its cornering stiffness 24 % off."""
    free = (np.abs(s.fx) <= FREE_ROLLING * np.abs(s.fz)) & (s.vx >= MIN_SPEED)
    out = np.zeros(len(s))
    for k in np.unique(s.corner):
        m = s.corner == k
        axle = np.isin(s.corner, next((c for c in AXLES.values() if k in c), (k,)))
        for pool in (m, axle, np.ones(len(s), dtype=bool)):
            if (free & pool).sum() >= MIN_POINTS:
                out[m] = float(np.median(s.kappa[free & pool]))
                break
    return out


def pure_lateral(s: TireSamples) -> TireSamples:
    """The samples in pure lateral slip: |κ - κ free rolling| <= KAPPA_PURE, at speed, loaded."""
    return s.select((np.abs(s.kappa - free_rolling_slip(s)) <= KAPPA_PURE) & (s.vx >= MIN_SPEED) & (s.fz > 0))


def pure_longitudinal(s: TireSamples) -> TireSamples:
    return s.select((np.abs(s.alpha) <= ALPHA_PURE) & (s.vx >= MIN_SPEED) & (s.fz > 0))


def fit_lateral(s: TireSamples, magic: bool | None = None) -> LateralCurve:
    """The lateral law of these (pure lateral) samples: the Magic Formula with load dependence when the samples
    reach the nonlinear range (magic None: decided from the data, module doc), else linear."""
    _carries(s, LATERAL_FIELDS, "the lateral law")
    if len(s) < MIN_POINTS:
        raise TireCurveError(f"{len(s)} pure-slip samples: the lateral law needs at least {MIN_POINTS}")
    a, fz, fy = s.alpha, s.fz, s.fy
    if np.ptp(a) < 0.2 * DEG:
        raise TireCurveError(f"the slip angle spans {np.degrees(np.ptp(a)):.2f}°: no cornering in these tests")
    fz0 = float(np.mean(fz))
    spread = float(np.ptp(fz) / fz0)
    load = spread >= LOAD_SPREAD
    runs, instants = _runs(s), _instants(s)
    # the linear law on the linear range: the start of the Magic Formula and the nonlinearity test
    lin = np.abs(a) <= LINEAR_ALPHA
    if lin.sum() < MIN_POINTS:
        lin = np.abs(a) <= np.quantile(np.abs(a), 0.5)
    linear = _fit_linear(a[lin], fz[lin], fy[lin], fz0, load, runs[lin], instants[lin])
    p = {**linear.fixed, **dict(zip(linear.names, linear.values, strict=True))}
    K_all = _stiffness(p, fz0, fz)
    big = np.abs(a) >= np.quantile(np.abs(a), 0.95)
    ratio = float(np.sum(np.abs(fy[big])) / np.sum(np.abs(K_all[big] * (a[big] + p["Sh"]))))
    if magic is None:
        magic = ratio < NONLINEAR
    if not magic:  # the slope at zero from the linear range: over larger slips a line is the curve's secant
        return LateralCurve(linear, fz0, False, (float(a[lin].min()), float(a[lin].max())),
                            (float(fz[lin].min()), float(fz[lin].max())), False, fz0)
    fit = _fit_magic_lateral(a, fz, fy, fz0, load, runs, p, E=0.0, instants=instants)
    q = {**fit.fixed, **dict(zip(fit.names, fit.values, strict=True))}
    Bn = q["k0"] / (q["C"] * q["mu0"])
    peak = peak_slip(Bn, q["C"], q["E"])
    reached = bool(np.max(np.abs(a + q["Sh"])) >= 1.1 * peak)
    if reached:  # beyond the peak: E shapes the curve there, and the data say it
        fit = _fit_magic_lateral(a, fz, fy, fz0, load, runs, q, E=None, instants=instants)
    return LateralCurve(fit, fz0, True, (float(a.min()), float(a.max())), (float(fz.min()), float(fz.max())),
                        reached, fz0)


def fit_tire(s: TireSamples, axle: LateralCurve | None) -> LateralCurve:
    """One tire's lateral law: the axle's curve shape (C, mu0, E, pD2 of its Magic Formula) with the tire's own
    cornering stiffness (k0, Sh, and pK2 when its loads spread); linear on |alpha| <= LINEAR_ALPHA when the axle
    has no Magic Formula."""
    _carries(s, LATERAL_FIELDS, "a tire's lateral law")
    if axle is None or not axle.magic:
        return fit_lateral(s.select(np.abs(s.alpha) <= LINEAR_ALPHA), magic=False)
    if len(s) < MIN_POINTS:
        raise TireCurveError(f"{len(s)} pure-slip samples: the lateral law needs at least {MIN_POINTS}")
    a, fz, fy = s.alpha, s.fz, s.fy
    load = float(np.ptp(fz) / axle.fz0) >= LOAD_SPREAD
    shape = {n: axle.fit.value(n) for n in ("C", "mu0", "E", "pD2")}
    names = ["k0", "Sh"] + (["pK2"] if load else [])
    fixed = shape | ({} if load else {"pK2": 0.0})

    cols = [LATERAL_PARAMETERS.index(n) for n in names]

    def problem(rows: slice) -> tuple:
        a_, fz_, fy_ = a[rows], fz[rows], fy[rows]
        dfz = fz_ / axle.fz0 - 1  # the same every call: once

        def fun(v: Array) -> Array:
            return lateral_force({**fixed, **dict(zip(names, v, strict=True))}, axle.fz0, a_, fz_, dfz=dfz) - fy_

        def jac(v: Array) -> Array:  # closed form: a 2-point Jacobian cost p more passes per step
            return lateral_force_jacobian({**fixed, **dict(zip(names, v, strict=True))}, axle.fz0, a_, fz_,
                                          dfz)[:, cols]

        return fun, jac

    starts = [[axle.fit.value("k0"), axle.fit.value("Sh")] + ([axle.fit.value("pK2")] if load else [])]
    lower, upper = np.array([1e-3, -0.1] + ([-0.9] if load else [])), np.array([200.0, 0.1] + ([5.0] if load else []))
    if len(a) >= 2 * SUBSAMPLE:  # the descent from the axle's values on a subsample, polished on all (as the axle's)
        starts = _subsample_ends(*problem(slice(None, None, len(a) // SUBSAMPLE)), starts, lower, upper)
    fit = _least_squares_rows(problem, len(a), starts, lower, upper, names, _runs(s), fixed)
    return LateralCurve(fit, axle.fz0, True, (float(a.min()), float(a.max())), (float(fz.min()), float(fz.max())),
                        axle.peak_reached, float(np.mean(fz)))


def _fit_linear(a: Array, fz: Array, fy: Array, fz0: float, load: bool, runs: Array,
                instants: Array | None = None) -> Fit:
    names = ["k0", "Sh"] + (["pK2"] if load else [])
    fixed = {} if load else {"pK2": 0.0}

    dfz = fz / fz0 - 1  # the same every call: once

    def fun(v: Array) -> Array:
        p = dict(zip(names, v, strict=True))
        return lateral_force({**fixed, **p}, fz0, a, fz, magic=False, dfz=dfz) - fy

    k0 = float(-np.sum(fy * a * fz) / max(np.sum((a * fz) ** 2), 1e-12))
    start = [k0, 0.0] + ([0.0] if load else [])
    lower = np.array([-np.inf, -0.1] + ([-0.9] if load else []))
    upper = np.array([np.inf, 0.1] + ([5.0] if load else []))
    return _least_squares(fun, [start], lower, upper, names, runs, fixed, instants)


def _fit_magic_lateral(a: Array, fz: Array, fy: Array, fz0: float, load: bool, runs: Array,
                       start: Mapping[str, float], E: float | None, instants: Array | None = None) -> Fit:
    names = ["k0", "mu0", "C", "Sh"] + ([] if E is not None else ["E"]) + (["pK2", "pD2"] if load else [])
    fixed = ({} if E is None else {"E": E}) | ({} if load else {"pK2": 0.0, "pD2": 0.0})

    def problem(rows: slice) -> tuple:
        a_, fz_, fy_ = a[rows], fz[rows], fy[rows]
        dfz = fz_ / fz0 - 1  # the same every call: once
        cols = [LATERAL_PARAMETERS.index(n) for n in names]

        def fun(v: Array) -> Array:
            return lateral_force({**fixed, **dict(zip(names, v, strict=True))}, fz0, a_, fz_, dfz=dfz) - fy_

        def jac(v: Array) -> Array:
            return lateral_force_jacobian({**fixed, **dict(zip(names, v, strict=True))}, fz0, a_, fz_, dfz)[:, cols]

        return fun, jac

    lo = {"k0": 1e-3, "mu0": 0.05, "C": MF_C_BOUNDS[0], "Sh": -0.1, "E": -10.0, "pK2": -0.9, "pD2": -0.9}
    hi = {"k0": 200.0, "mu0": 5.0, "C": MF_C_BOUNDS[1], "Sh": 0.1, "E": 1.0, "pK2": 5.0, "pD2": 5.0}
    mu_seen = float(np.max(np.abs(fy) / fz))
    starts = []
    for C0 in (1.2, 1.4, 1.7):
        for m in (1.05, 1.3):
            for E0 in ((0.0, -1.0) if E is None else (E,)):
                x = {**dict(start), "mu0": max(m * mu_seen, 0.1), "C": C0, "E": E0}
                x.setdefault("pK2", 0.0)
                x.setdefault("pD2", 0.0)
                starts.append([x.get(n, 0.0) for n in names])
    lower, upper = np.array([lo[n] for n in names]), np.array([hi[n] for n in names])
    if len(a) >= 2 * SUBSAMPLE:  # the starts' descents on a subsample, the one basin (or the few) polished on all
        starts = _subsample_ends(*problem(slice(None, None, len(a) // SUBSAMPLE)), starts, lower, upper)
    return _least_squares_rows(problem, len(a), starts, lower, upper, names, runs, fixed, instants)


SUBSAMPLE = 8000  # samples of a multi-start's descents: every k-th of an hour's ~46k per axle
BASIN = 0.01  # the subsample's ends within 1 % of its best cost are each polished on every sample


def _subsample_ends(fun, jac, starts: Sequence[Array], lower: Array, upper: Array) -> list[Array]:
    """The distinct ends of the starts' descents on a subsample (fun, jac: its residual and Jacobian) whose cost is
    within BASIN of the best: the starts of the fit on every sample. The starts guard against a local minimum; on
    an hour's samples each full descent cost 5-7 evaluations of 46k samples, and all 6 starts ended in one point
    (costs equal to 7 digits). From a subsample's end (every k-th sample: the same curve, k times fewer samples),
    the full problem's optimum is 2-4 evaluations away, and it is the same optimum (the solver's tolerance apart)
    unless two basins' costs differ by less than BASIN on the subsample: both are polished then."""
    span = upper - lower
    margin = np.where(np.isfinite(span), 1e-9 * span, 0.0)
    ends = []
    for x0 in starts:
        x0 = np.clip(np.asarray(x0, dtype=float), lower + margin, upper - margin)
        try:
            r = least_squares(fun, x0, jac=jac, bounds=(lower, upper), method="trf", x_scale="jac", max_nfev=200)
        except ValueError:
            continue
        if np.all(np.isfinite(r.fun)):
            ends.append(r)
    if not ends:
        return list(starts)  # every start failed on the subsample: the full problem says so (or finds one)
    best = min(r.cost for r in ends)
    kept: list[Array] = []
    for r in sorted(ends, key=lambda r: r.cost):
        if r.cost <= best * (1 + BASIN) and not any(np.allclose(r.x, x, rtol=1e-4, atol=1e-9) for x in kept):
            kept.append(r.x)
    return kept


def fit_longitudinal(s: TireSamples, free: TireSamples | None = None) -> LongitudinalLaw:
    """Fx = -Kx (κ - κ0(Fz)) on these (pure longitudinal) samples and the free-rolling samples `free` (|Fx| <=
    FREE_ROLLING Fz at any slip angle: they fix the free-rolling slip's load line κ0(Fz); module doc)."""
    _carries(s, LONGITUDINAL_FIELDS, "the longitudinal law")
    if free is not None:
        _carries(free, LONGITUDINAL_FIELDS, "the longitudinal law's free-rolling samples")
    if free is None or len(free) == 0:
        both, pure = _ordered(s), np.ones(len(s), dtype=bool)
    else:
        both = s.merge(free)
        pure = np.r_[np.ones(len(s), dtype=bool), np.zeros(len(free), dtype=bool)]
        order = np.lexsort((both.t, both.corner, _test_codes(both.test)))  # stable: at one key, s's sample first
        both, pure = both.select(order), pure[order]
    return _fit_longitudinal(both, pure)


def _fit_longitudinal(both: TireSamples, pure: Array) -> LongitudinalLaw:
    """`fit_longitudinal` on its samples and the free-rolling ones together, ordered by test, wheel and time (both),
    pure: which are the pure longitudinal ones. One selection of the wheels' samples, not two then their merge."""
    k_pure, fx_pure, fz_pure = both.kappa[pure], both.fx[pure], both.fz[pure]
    if len(k_pure) < MIN_POINTS:
        raise TireCurveError(f"{len(k_pure)} pure-slip samples: the longitudinal law needs at least {MIN_POINTS}")
    if np.ptp(k_pure) < 0.005:
        raise TireCurveError(f"the slip ratio spans {np.ptp(k_pure):.4f}: no braking or traction in these tests")
    # the stiffness is seen only where the wheel brakes or drives: the free-rolling samples fix κ0 alone. Its
    # nominal load and whether a load term is fitted come from those samples' loads, not from all: over all, the
    # spiral's load transfer (free rolling) spread the loads, a load term was fitted from one braking's nearly
    # constant load, and the stiffness at the mean of all loads was an extrapolation through it (+8 % front,
    # +14 % rear on the MuJoCo car's noise/, pKx2 on its bound)
    slipping = np.abs(fx_pure) >= SLIPPING * fz_pure
    seen = fz_pure[slipping] if slipping.sum() >= MIN_POINTS else fz_pure
    fz0 = float(np.mean(seen))
    lo, hi = np.quantile(seen, [0.1, 0.9])  # the ramps' few samples between two loads do not make a spread
    load = float((hi - lo) / fz0) >= LOAD_SPREAD
    # the effective rolling radius shrinks with the load (the tire's deflection): counted with one radius, the
    # free-rolling slip moves with the load (dynid's 406: -0.005 per kN), and a braking's load transfer then moved
    # the front slips one way and the rear's the other (+8 % and -14 % in Kx on the demo). The free-rolling
    # samples of every test (the spiral's and the sine's lateral load transfer) give that line
    k, fz, fx = both.kappa, both.fz, both.fx
    rolling = np.abs(fx) <= FREE_ROLLING * fz
    fzf = float(np.mean(fz[rolling])) if rolling.sum() >= MIN_POINTS else fz0
    lo, hi = np.quantile(fz[rolling], [0.1, 0.9]) if rolling.sum() >= MIN_POINTS else (fzf, fzf)
    radius_load = float((hi - lo) / fzf) >= LOAD_SPREAD
    names = ["kx0", "kappa0"] + (["pKx2"] if load else []) + (["kappa0_fz"] if radius_load else [])
    fixed = ({} if load else {"pKx2": 0.0}) | ({} if radius_load else {"kappa0_fz": 0.0})

    # regressed the other way round, slip on force: the slip ratio is the noisy side (a speed sensor's 1 km/h is a
    # slip of 0.014 at 20 m/s, a third of a braking's), the filtered force's noise a few N. Forward, the noise in
    # the regressor halves the stiffness (the MuJoCo car's sensor files); reversed, it is the residual's. Each
    # residual weighted by the speed over 20 m/s: the slip's noise goes as 1/v
    weight = both.vx / 20.0

    def problem(rows: slice) -> tuple:
        k_, fz_, fx_, weight_ = k[rows], fz[rows], fx[rows], weight[rows]
        load_free, load_nominal = fz_ / fzf - 1, fz_ / fz0 - 1  # the same every call: once

        def fun(v: Array) -> Array:
            p = {**fixed, **dict(zip(names, v, strict=True))}
            # a term held at 0 adds nothing: left out (its product is ±0, its sum the other term: the same bits)
            k0 = p["kappa0"] + p["kappa0_fz"] * load_free if radius_load else p["kappa0"]
            kx = p["kx0"] * fz_ * (1 + p["pKx2"] * load_nominal) if load else p["kx0"] * fz_
            return (k0 - fx_ / kx - k_) * weight_

        def jac(v: Array) -> Array:
            p = {**fixed, **dict(zip(names, v, strict=True))}
            g = 1 + p["pKx2"] * load_nominal if load else 1.0
            fx_kx = fx_ / (p["kx0"] * fz_ * g)  # the residual's fx / Kx
            cols = {"kx0": fx_kx * weight_ / p["kx0"], "kappa0": weight_,
                    "pKx2": fx_kx * weight_ * load_nominal / g if load else None,
                    "kappa0_fz": load_free * weight_}
            return np.stack([cols[n] for n in names], axis=1)

        return fun, jac

    # the start: the closed-form optimum (without the load term) on every k-th sample when they are many (its
    # matrix n x 3 and the solver's copies of it), polished on all in blocks (`_least_squares_rows`)
    sub = slice(None, None, max(1, len(k) // SUBSAMPLE)) if len(k) > BLOCKS_ABOVE else slice(None)
    start = _longitudinal_start(k[sub], fz[sub], fx[sub], weight[sub], fz[sub] / fzf - 1, load, radius_load)
    fit = _least_squares_rows(problem, len(k), [start],
                              np.array([1e-3, -0.1] + ([-0.9] if load else []) + ([-0.5] if radius_load else [])),
                              np.array([1e3, 0.1] + ([5.0] if load else []) + ([0.5] if radius_load else [])),
                              names, _runs(both), fixed, _instants(both))
    law = LongitudinalLaw(fit, fz0, (float(k_pure.min()), float(k_pure.max())),
                          (float(fz_pure.min()), float(fz_pure.max())), fzf)
    if slipping.any():
        law.kappa_seen = float(np.mean(np.abs(k_pure[slipping] - law.free_rolling_slip_at(fz_pure[slipping]))))
    return law


def _longitudinal_start(k: Array, fz: Array, fx: Array, weight: Array, load_free: Array, load: bool,
                        radius_load: bool) -> list[float]:
    """The longitudinal fit's start: without the load term (pKx2 = 0) the model κ = κ0 + κ0_fz dfz - (1 / kx0) Fx / Fz
    is linear in κ0, κ0_fz and 1 / kx0, so its weighted least squares in closed form is the optimum itself (with the
    load term, pKx2 = 0 and the rest from it). The solver then only confirms it: on an hour's fits 1 evaluation (its
    gradient test met at the start) where the ratio of sums start took 22-26, each with a 2-point Jacobian (3
    passes): 0.17 s per fit of 145k samples."""
    cols = [-(fx / fz) * weight, weight] + ([load_free * weight] if radius_load else [])
    A = np.stack(cols, axis=1)
    sol = np.linalg.lstsq(A, k * weight, rcond=None)[0]
    if not (np.all(np.isfinite(sol)) and sol[0] > 0):  # no stiffness in these samples: the ratio of sums
        kx = float(-np.sum(fx * k * fz) / max(np.sum((k * fz) ** 2), 1e-12))
        return [kx, 0.0] + ([0.0] if load else []) + ([0.0] if radius_load else [])
    return [1.0 / float(sol[0]), float(sol[1])] + ([0.0] if load else []) + ([float(sol[2])] if radius_load else [])


# ------------------------------------------------------------------------------------------------- the result
@dataclass
class TireCurves:
    """The tire characteristics of one identification: per axle the lateral curve and the longitudinal law, per
    tire the linear cornering stiffness, per test and wheel the slip ranges reached, what could not be fitted and
    why, and the wheel radius the slip ratios are counted with."""

    wheel_radius: float
    lateral: dict[str, LateralCurve] = field(default_factory=dict)
    longitudinal: dict[str, LongitudinalLaw] = field(default_factory=dict)
    per_tire: dict[str, LateralCurve] = field(default_factory=dict)
    longitudinal_per_tire: dict[str, LongitudinalLaw] = field(default_factory=dict)
    reach: list[dict] = field(default_factory=list)
    missing: dict[str, str] = field(default_factory=dict)
    samples: TireSamples | None = None  # the pure-slip samples, for the report's figure
    seconds: float = 0.0  # the fit's wall time
    cpu_seconds: float = 0.0  # and its processor time (the machine's other loads left out)

    def to_dict(self) -> dict:
        """results.json's "tires" (SI: N/rad, N per unit slip, rad; and the sheet's N/deg)."""
        out: dict = {"conventions": ("ISO wheel (W) axes: x the wheel plane's line on the road, z the road's "
                                     "normal, y left; Fy = -F(alpha), Fx = -F(kappa); alpha = atan2(vy, max(|vx|, "
                                     "1 m/s)), kappa = (vx - R omega) / max(|vx|, 1 m/s) > 0 braking, of the wheel "
                                     "centre"), "wheel_radius_m": self.wheel_radius,
                     "selection": {"min_speed_m_s": MIN_SPEED, "lateral_max_abs_kappa": KAPPA_PURE,
                                   "longitudinal_max_abs_alpha_deg": math.degrees(ALPHA_PURE)},
                     "lateral": {}, "longitudinal": {}, "per_tire": {}, "reach": self.reach,
                     "not_fitted": self.missing, "fit_seconds": self.seconds,
                     "fit_cpu_seconds": self.cpu_seconds}
        for name, c in self.lateral.items():
            out["lateral"][name] = _lateral_dict(c)
        for name, c in self.per_tire.items():
            out["per_tire"][name] = _lateral_dict(c)
        out["longitudinal_per_tire"] = {}
        for key, laws in (("longitudinal", self.longitudinal), ("longitudinal_per_tire", self.longitudinal_per_tire)):
            for name, law in laws.items():
                out[key][name] = self._longitudinal_dict(law)
        return out

    def _longitudinal_dict(self, law: LongitudinalLaw) -> dict:
        kx, skx = law.stiffness(law.fz0)
        k0, sk0 = law.free_rolling_slip(law.fz0)
        return {"model": "linear (secant over the slip range)", "fz0_N": law.fz0,
                "slip_stiffness_N_per_unit_slip": kx, "slip_stiffness_std": skx, "secant_to_slip": law.kappa_seen,
                "free_rolling_slip": k0, "free_rolling_slip_std": sk0,
                "free_rolling_slip_per_unit_dfz": law.fit.value("kappa0_fz"),
                "free_rolling_slip_per_unit_dfz_std": law.fit.sigma("kappa0_fz"), "free_rolling_fz_N": law.fz_free,
                "effective_rolling_radius_m": self.wheel_radius / (1 - k0),
                "effective_rolling_radius_std": self.wheel_radius * sk0 / (1 - k0) ** 2,
                "kappa_range": list(law.kappa_range), "fz_range_N": list(law.fz_range),
                "parameters": _params(law.fit), "rms_N": law.fit.rms, "samples": law.fit.n, "tau": law.fit.tau,
                "stiffness_vs_load": [{"fz_N": f, "value": v, "std": s}
                                      for f in _loads(law.fz0) for v, s in [law.stiffness(f)]]}

    def rows(self) -> list[list]:
        """tires.csv's rows: key, axle or tire, quantity, unit, value, std."""
        rows = []
        for curves in (self.lateral, self.per_tire):
            for name, c in curves.items():
                for f in _loads(c.fz0):
                    v, s = c.stiffness(f)
                    rows.append([f"cornering_stiffness_{name}_{f:.0f}N", name, f"cornering stiffness at {f:.0f} N",
                                 "N/deg", v * DEG, s * DEG])
                if c.magic:
                    for k, (v, s) in c.coefficients(c.fz0).items():
                        unit = {"B": "1/rad", "C": "", "D": "N", "E": ""}[k]
                        rows.append([f"mf_{k}_{name}", name, f"Magic Formula {k} at {c.fz0:.0f} N", unit, v, s])
                    for k in ("mu0", "pK2", "pD2"):
                        rows.append([f"mf_{k}_{name}", name, k, "", c.fit.value(k), c.fit.sigma(k)])
                rows.append([f"alpha_offset_{name}", name, "slip angle offset Sh", "deg",
                             math.degrees(c.fit.value("Sh")), math.degrees(c.fit.sigma("Sh"))])
        for name, law in {**self.longitudinal, **self.longitudinal_per_tire}.items():
            for f in _loads(law.fz0):
                v, s = law.stiffness(f)
                rows.append([f"slip_stiffness_{name}_{f:.0f}N", name, f"longitudinal slip stiffness at {f:.0f} N",
                             "N per unit slip", v, s])
            k0, sk0 = law.free_rolling_slip(law.fz0)
            rows.append([f"rolling_radius_{name}", name, f"effective rolling radius at {law.fz0:.0f} N", "m",
                         self.wheel_radius / (1 - k0), self.wheel_radius * sk0 / (1 - k0) ** 2])
        return rows

    def quantities(self) -> list:
        """The engineering sheet's tire figures (`vehicle.engineering.Quantity`): per axle the cornering stiffness
        (N/deg) and the longitudinal slip stiffness (N per unit slip) at the axle's nominal load, with σ."""

        out = []
        for name, c in self.lateral.items():
            v, s = c.stiffness(c.fz0)
            out.append(Quantity(f"cornering_stiffness_{name}", "tires", f"cornering stiffness, {name} axle", "N/deg",
                                v * DEG, s * DEG, f"per tire, at {c.fz0:.0f} N (tires.csv: other loads, each tire)"))
        for name, law in self.longitudinal.items():
            v, s = law.stiffness(law.fz0)
            out.append(Quantity(f"slip_stiffness_{name}", "tires", f"longitudinal slip stiffness, {name} axle",
                                "N per unit slip", v, s, f"per tire, at {law.fz0:.0f} N, its load when braking or "
                                f"driving (the secant to its mean slip then, {law.kappa_seen:.3f})"))
        return out

    def csv(self) -> str:
        """tires.csv (`rows`)."""

        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["key", "axle_or_tire", "quantity", "unit", "value", "std"])
        for key, who, q, unit, v, s in self.rows():
            w.writerow([key, who, q, unit, f"{v:.8g}", f"{s:.4g}"])
        return buf.getvalue()

    def text(self) -> str:
        """The terminal's compact block."""
        lines = [f"Tire characteristics (ISO wheel axes; fitted in {self.seconds:.2f} s, {self.cpu_seconds:.2f} s "
                 "of processor):"]
        for name, c in self.lateral.items():
            v, s = c.stiffness(c.fz0)
            a0, a1 = np.degrees(c.alpha_range)
            line = (f"  {name:<5} cornering stiffness {v * DEG:8.1f} ± {s * DEG:.1f} N/deg at {c.fz0:.0f} N; "
                    f"alpha {a0:+.1f}..{a1:+.1f} deg")
            if c.magic:
                co = c.coefficients(c.fz0)
                line += ("; MF B {:.2f} C {:.3f} D {:.0f} N E {:.2f}".format(*(co[k][0] for k in "BCDE"))
                         + ("" if c.peak_reached else " (peak not reached: D extrapolated, E fixed)"))
            lines.append(line)
        for name, law in self.longitudinal.items():
            v, s = law.stiffness(law.fz0)
            k0 = law.free_rolling_slip(law.fz0)[0]
            lines.append(f"  {name:<5} slip stiffness {v:9.0f} ± {s:.0f} N per unit slip at {law.fz0:.0f} N "
                         f"(secant to kappa {law.kappa_seen:.3f}); rolling radius "
                         f"{self.wheel_radius / (1 - k0):.4f} m")
        for name, c in self.per_tire.items():
            fz = c.fz_mean
            v, s = c.stiffness(fz)
            how = "the axle's curve shape" if c.magic else f"|alpha| <= {math.degrees(LINEAR_ALPHA):g} deg"
            lines.append(f"  tire {name:<2} cornering stiffness {v * DEG:7.1f} ± {s * DEG:.1f} N/deg at {fz:.0f} N "
                         f"({how})")
        if self.longitudinal_per_tire:
            lines.append("  slip stiffness per tire (N per unit slip, at its load braking or driving): " + "; ".join(
                f"{name} {law.stiffness(law.fz0)[0]:.0f} ± {law.stiffness(law.fz0)[1]:.0f} at {law.fz0:.0f} N"
                for name, law in self.longitudinal_per_tire.items()))
        tests: dict[str, list[str]] = {}
        for r in self.reach:
            if "lateral_regime" in r and r["wheel"] in ("rl", "fl"):  # one wheel per axle: the pair is symmetric
                use = f", {100 * r['peak_force_used']:.0f} % of peak" if "peak_force_used" in r else ""
                tests.setdefault(r["test"], []).append(
                    f"{'front' if r['wheel'] == 'fl' else 'rear'} {r['alpha_deg'][0]:+.1f}..{r['alpha_deg'][1]:+.1f}"
                    f" deg ({r['lateral_regime']}{use})")
        for test, parts in tests.items():
            lines.append(f"  reach, {test}: " + "; ".join(parts))
        for what, why in self.missing.items():
            lines.append(f"  {what}: not fitted ({why})")
        return "\n".join(lines)


def _loads(fz0: float) -> list[float]:
    return [0.5 * fz0, fz0, 1.5 * fz0]


def _params(fit: Fit) -> list[dict]:
    out = [{"name": n, "value": float(v), "std": float(s), "at_bound": n in fit.at_bound}
           for n, v, s in zip(fit.names, fit.values, fit.std, strict=True)]
    out += [{"name": n, "value": float(v), "std": 0.0, "fixed": True} for n, v in fit.fixed.items()]
    return out


def _lateral_dict(c: LateralCurve) -> dict:
    k, sk = c.stiffness(c.fz_mean)
    out = {"model": "magic formula" if c.magic else "linear", "fz0_N": c.fz0, "mean_load_N": c.fz_mean,
           "cornering_stiffness_N_per_rad": k, "cornering_stiffness_std": sk,
           "cornering_stiffness_N_per_deg": k * DEG, "cornering_stiffness_N_per_deg_std": sk * DEG,
           "alpha_range_deg": [math.degrees(x) for x in c.alpha_range], "fz_range_N": list(c.fz_range),
           "peak_reached": c.peak_reached, "parameters": _params(c.fit), "rms_N": c.fit.rms, "samples": c.fit.n,
           "tau": c.fit.tau,
           "stiffness_vs_load": [{"fz_N": f, "N_per_deg": v * DEG, "std": s * DEG}
                                 for f in _loads(c.fz0) for v, s in [c.stiffness(f)]]}
    if c.magic:
        out["coefficients_at_fz0"] = {k: {"value": v, "std": s} for k, (v, s) in c.coefficients(c.fz0).items()}
        q = c.fit_params()
        out["peak_slip_angle_deg"] = math.degrees(peak_slip(q["k0"] / (q["C"] * q["mu0"]), q["C"], q["E"]))
    return out


def slip_reach(s: TireSamples, codes: Array | None = None) -> list[dict]:
    """Per test and wheel: the slip angle and slip ratio ranges (speed >= MIN_SPEED) and the loads. codes: the
    samples' `_test_codes` when the caller has them (compared, not the names: 20 ms per 100k names)."""
    _carries(s, ("alpha", "kappa", "gamma", "vx", "fz"), "the slip reach")
    out = []
    fast = s.vx >= MIN_SPEED  # a mask, not a copy of the samples
    names = _test_names([s])
    codes = _test_codes(s.test, names) if codes is None else codes
    _, first = np.unique(codes[fast], return_index=True)
    for c in codes[fast][np.sort(first)]:  # the tests in the order they first come
        test = names[c]
        of_test = fast & (codes == c)
        for k, tag in enumerate(CORNER_TAGS):
            m = of_test & (s.corner == k)
            if not m.any():
                continue
            out.append({"test": test, "wheel": tag,
                        "alpha_deg": [float(np.degrees(s.alpha[m].min())), float(np.degrees(s.alpha[m].max()))],
                        "kappa": [float(s.kappa[m].min()), float(s.kappa[m].max())],
                        "fz_N": [float(s.fz[m].min()), float(s.fz[m].max())],
                        "inclination_deg": float(np.degrees(np.max(np.abs(s.gamma[m]))))})
    return out


def _regime(curves: TireCurves, row: dict) -> dict:
    """Which part of its axle's lateral curve a test's wheel reached: "linear" (|Fy| within 5 % of K |α| at the
    largest |α|), "nonlinear" or "beyond the peak", and the share of the peak force used (Magic Formula only)."""
    axle = next((a for a, ks in AXLES.items() if CORNER_TAGS.index(row["wheel"]) in ks), None)
    c = curves.lateral.get(axle)
    if c is None:
        return {}
    a = math.radians(max(abs(x) for x in row["alpha_deg"]))
    fz = float(np.mean(row["fz_N"]))
    p = c.fit_params()
    fy = abs(float(c.force(np.array([-a]), np.array([fz]))[0]))
    linear = abs(float(_stiffness(p, c.fz0, fz))) * a
    out: dict = {"lateral_regime": "linear" if linear == 0 or fy >= 0.95 * linear else "nonlinear"}
    if c.magic:
        D = float(_mu(p, c.fz0, fz)) * fz
        out["peak_force_used"] = fy / D
        if a > peak_slip(float(_stiffness(p, c.fz0, fz)) / (p["C"] * D), p["C"], p["E"]):
            out["lateral_regime"] = "beyond the peak"
    return out


def fit_tire_curves(samples: TireSamples, wheel_radius: float, workers: int | None = None) -> TireCurves:
    """Every curve the samples support (module doc); what they do not is said in `missing`. BLAS on one thread:
    the problems are a few thousand rows by a few columns, where threads cost more than they give (on a loaded
    machine, 3 s of wall time against 0.4 s). The independent fits (each axle's lateral law and then its tires',
    each axle's and tire's longitudinal law) run on `workers` threads (default: up to 2, as the segments' map):
    their arithmetic is NumPy's on arrays of tens of thousands of samples, which releases the GIL, and each fit
    is the same sequence of operations as in turn, so the curves are the same bits."""
    _carries(samples, _FIELDS[len(_KEYS):], "the tire curves' fit")

    with threadpool_limits(limits=1, user_api="blas"):
        return _fit_tire_curves(samples, wheel_radius, workers or min(2, os.cpu_count() or 1))


def _lateral_chain(s: TireSamples, mask: Array, axle: str, corners: tuple[int, ...]) -> list[tuple[str, str, object]]:
    """The axle's lateral law on s's samples of mask (its pure lateral slip), then each of its tires' (which take
    the axle's shape): (kind, key, curve or the reason it is missing), in the order the results list them. The
    samples selected here, when the task runs: not every task's held from the start."""
    out: list[tuple[str, str, object]] = []
    curve = None
    lat = s.select(mask, LATERAL_FIELDS)
    try:
        curve = fit_lateral(lat)
        out.append(("lateral", axle, curve))
    except TireCurveError as exc:
        out.append(("missing", f"{axle} lateral", str(exc)))
    for k in corners:
        try:
            out.append(("per_tire", CORNER_TAGS[k], fit_tire(lat.select(lat.corner == k), curve)))
        except TireCurveError as exc:
            out.append(("missing", f"tire {CORNER_TAGS[k]} lateral", str(exc)))
    return out


def _longitudinal_one(s: TireSamples, pure: Array, rolling: Array, kind: str, key: str, missing: str
                      ) -> tuple[str, str, object]:
    """`fit_longitudinal` on s's samples of the masks pure (pure longitudinal slip) and rolling (free rolling, the
    others): one selection of both, in s's order (that of test, wheel and time), made when the task runs."""
    both = pure | rolling
    sel = s.select(both, LONGITUDINAL_FIELDS)
    if len(sel) > 1 and np.any(sel.t[1:] == sel.t[:-1]):  # two samples at one key: the pure one first, as merged
        order = np.lexsort((~pure[both], sel.t, sel.corner, _test_codes(sel.test)))
        sel, both = sel.select(order), pure[both][order]
    else:
        both = pure[both]
    try:
        return kind, key, _fit_longitudinal(sel, both)
    except TireCurveError as exc:
        return "missing", missing, str(exc)


def _fit_tire_curves(samples: TireSamples, wheel_radius: float, workers: int = 1) -> TireCurves:

    t0, c0 = time.perf_counter(), time.process_time()
    # each test as its index among the names sorted (`_test_codes`), once: for the order, the reach and the tasks
    names = _test_names([samples])
    codes = _test_codes(samples.test, names)
    s = samples
    if not _sorted(codes, s.corner, s.t):  # `_ordered`
        order = np.lexsort((s.t, s.corner, codes))
        s, codes = s.select(order), codes[order]
    out = TireCurves(wheel_radius, reach=slip_reach(s, codes))
    # the pure lateral slip's samples (`pure_lateral`), the wheels' free-rolling slips found once for them and for
    # the samples kept
    pure_y = np.abs(s.kappa - free_rolling_slip(s)) <= KAPPA_PURE
    fast = (s.vx >= MIN_SPEED) & (s.fz > 0)
    # masks of s, each task selecting its samples when it runs (`pure_lateral`, `pure_longitudinal`): selected all
    # at once, the tasks' copies were 3 times the samples (an hour's 290k: 70 MB)
    lat, lon = pure_y & fast, (np.abs(s.alpha) <= ALPHA_PURE) & fast
    # the free-rolling samples at any slip angle (those of lon left out: each sample once): κ0's load line
    rolling = (np.abs(s.fx) <= FREE_ROLLING * s.fz) & fast & (np.abs(s.alpha) > ALPHA_PURE)
    # the tasks' selections from the samples with each test as its index among the names sorted and the wheel as a
    # byte (`_test_codes`): an hour's object names cost 8 bytes a sample in every copy, and their comparisons 20 ms
    # per 100k; the measured fields shared, not copied
    coded = TireSamples(codes.astype(np.min_scalar_type(len(names))), s.corner.astype(np.int8),
                        *(getattr(s, f) for f in _FIELDS[2:]))
    # the fits, each axle's lateral chain first (the longest), then the longitudinal laws
    tasks = [(_lateral_chain, coded, lat & np.isin(s.corner, corners), axle, corners)
             for axle, corners in AXLES.items()]
    for axle, corners in AXLES.items():
        on = np.isin(s.corner, corners)
        tasks.append((_longitudinal_one, coded, lon & on, rolling & on, "longitudinal", axle, f"{axle} longitudinal"))
        tasks += [(_longitudinal_one, coded, lon & (s.corner == k), rolling & (s.corner == k),
                   "longitudinal_per_tire", CORNER_TAGS[k], f"tire {CORNER_TAGS[k]} longitudinal") for k in corners]
    if workers > 1:
        with ThreadPoolExecutor(min(workers, len(tasks))) as pool:
            done = [f.result() for f in [pool.submit(*t) for t in tasks]]
    else:
        done = [t[0](*t[1:]) for t in tasks]
    found = {}
    for d in done:
        for kind, key, value in d if isinstance(d, list) else [d]:
            found[kind, key] = value
    # the results in the order a fit in turn gave them: per axle its lateral law, longitudinal law, then per tire
    for axle, corners in AXLES.items():
        slots = [("lateral", axle, f"{axle} lateral"), ("longitudinal", axle, f"{axle} longitudinal")]
        for k in corners:
            slots += [("per_tire", CORNER_TAGS[k], f"tire {CORNER_TAGS[k]} lateral"),
                      ("longitudinal_per_tire", CORNER_TAGS[k], f"tire {CORNER_TAGS[k]} longitudinal")]
        for kind, key, missing in slots:
            if ("missing", missing) in found:
                out.missing[missing] = found["missing", missing]
            else:
                getattr(out, kind)[key] = found[kind, key]
    for r in out.reach:
        r.update(_regime(out, r))
    out.samples = s.select((pure_y | (np.abs(s.alpha) <= ALPHA_PURE)) & (s.vx >= MIN_SPEED))
    out.seconds, out.cpu_seconds = time.perf_counter() - t0, time.process_time() - c0
    return out


__all__ = ["ALPHA_PURE", "KAPPA_PURE", "MAX_SAMPLES", "MIN_SPEED", "Fit", "LateralCurve", "LongitudinalLaw",
           "SampleParts", "TireCurveError", "TireCurves", "TireSamples", "autocorrelation_factor", "empty_samples",
           "fit_lateral", "fit_longitudinal", "fit_magic_formula", "fit_tire_curves", "lateral_force", "magic_formula",
           "peak_slip", "sample_steps", "simultaneity_factor", "slip_reach", "tire_samples"]
