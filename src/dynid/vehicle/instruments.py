"""Instruments for IDIM-IV on the car: the suspensions simulated with the previous estimate, driven by the
measured loads.

Least squares on the damper equations is biased by the noise of the clearance channels: the same noisy
q, qd and sign(qd) stand in W. IDIM-IV (Gautier) replaces them, in the instruments Z, by the trajectory
of a simulation of the identified model driven by the measured inputs. For a corner d that simulation is
its damper equation with everything the measured loads and the chassis motion give moved to the right:

    m_d qdd_d + h_d qd_d + fs_d tanh(qd_d / v_s) + ks_d q_d + off_d + Σ_bars kar (q_d - q_opposite) = S_d(t)

(h_d qd_d: the damper's curve where it has one, car_model.car_template(damper_knees=...): its columns are
nonlinear in the rate, so the cameras' noise biases least squares on them more than on h; the instruments
remove that bias as they do h's).

S_d = Y_d - (the row's other terms at the estimate) + m_d qdd_d,measured: the projection of the measured
wheel wrench and of the wheel's inertial load from the chassis motion (the wheel mass column of the row
is m_d (qdd_d + a(t)), a from the chassis and tabulated joints; its qdd_d part stays on the left, so that
the clearance's own noise does not drive the simulation). On the true trajectory and parameters S_d is
exactly the left side: the simulation gives the true clearances back (tested). Since S_d comes from the
wheel-force transducers and the inertial unit, not from the clearance cameras, the simulated clearances
carry none of the cameras' noise.

The chassis and tire equations keep their own regressor as instrument (least squares there): their
columns do not depend on the clearances, and instrumenting them would take the whole car driven open
loop by the measured forces, whose planar motion has no restoring force.

The smooth dry-friction law (v_s = 2 mm/s, as the simulator's) keeps the integration well posed at
reversal; past a few v_s it is the identification model's fs sign(qd).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.interpolate import CubicSpline

from ..model.tree import CURVE_TERMS, ModelError, Tree
from .equations import CarEquations
from .template import DAMPERS, WHEELS

FRICTION_SPEED = 0.002  # m/s

try:
    from numba import njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False


def _spring_columns(tree: Tree, d: int) -> set[str]:
    """The names of damper d's own terms (K, FV or its curve's slopes, FS, OFF) and of the anti-roll bars that act
    on it."""
    own = {f"K{d}", f"FV{d}", f"FS{d}", f"OFF{d}", *(f"{t}{d}" for t in CURVE_TERMS)}
    return own | {c.name for c in tree.couplings if c.kind == "K" and d in c.coeffs}


def suspension_loads(tree: Tree, eq: CarEquations, values: Mapping[str, float], qdd: np.ndarray) -> np.ndarray:
    """(N, 4) S_d of the module doc for the dampers (9, 18, 27, 36), from the equations of the samples (eq),
    the parameter values (the estimate; names of eq.names or of the tree) and the measured qdd (N, 42)."""
    x = np.array([float(values.get(n, tree.values.get(n, 0.0))) for n in eq.names])
    W = eq.per_sample
    N = W.shape[0]
    Y = eq.Y.reshape(len(eq.rows), N)
    out = np.empty((N, len(DAMPERS)))
    for k, d in enumerate(DAMPERS):
        r = eq.rows.index(d)
        other = np.array([n not in _spring_columns(tree, d) for n in eq.names])
        mass = _wheel_mass(tree, values, k)
        out[:, k] = Y[r] - W[:, r, other] @ x[other] + mass * qdd[:, d - 1]
    return out


def _wheel_mass(tree: Tree, values: Mapping[str, float], k: int) -> float:
    name = f"M{WHEELS[k]}"
    return float(values.get(name, tree.values.get(name, 0.0)))


def suspension_response(tree: Tree, values: Mapping[str, float], t_load: np.ndarray, load: np.ndarray,
                        t: np.ndarray, q0: np.ndarray, qd0: np.ndarray) -> tuple[np.ndarray, ...]:
    """The dampers' clearances, rates and accelerations (each (len(t), 4)) of the module doc's equation,
    driven by `load` (S_d sampled at t_load, interpolated by a cubic spline), from q0, qd0 (4,) at t[0].
    RK4 on the clock t (uniform)."""
    ks = np.array([_value(values, tree, f"K{d}") for d in DAMPERS])
    # each damper's curve: slopes (bump low, bump high, rebound low, rebound high) about its knees (v-, v+); h is
    # the curve of four equal slopes without knees, h qd computed exactly (h min(qd, inf) + h max(qd - inf, 0))
    slopes = np.array([[_value(values, tree, f"{t}{d}") for t in CURVE_TERMS] if f"FVPL{d}" in tree.index
                       else [_value(values, tree, f"FV{d}")] * 4 for d in DAMPERS])
    knees = np.array([tree.knee(d) for d in DAMPERS])
    h = slopes.max(axis=1)
    fs = np.array([_value(values, tree, f"FS{d}") for d in DAMPERS])
    off = np.array([_value(values, tree, f"OFF{d}") for d in DAMPERS])
    mass = np.array([_wheel_mass(tree, values, k) for k in range(len(DAMPERS))])
    present = np.array([[f"{t}{d}" in tree.index for t in CURVE_TERMS] if f"FVPL{d}" in tree.index else [True] * 4
                        for d in DAMPERS])
    if not (np.all(mass > 0) and np.all(slopes[present] > 0) and np.all(fs >= 0)):
        raise ModelError("the suspension simulation for the instruments needs wheel masses > 0, damping > 0 (each "
                         f"slope of a curve) and dry friction >= 0; the estimate has M {mass}, h {slopes.tolist()}, fs "
                         f"{fs}: use method = \"wls\"")
    K = np.diag(ks)
    for c in tree.couplings:
        if c.kind == "K" and all(j in DAMPERS for j in c.coeffs):
            v = np.array([c.coeffs.get(d, 0.0) for d in DAMPERS])
            K += _value(values, tree, c.name) * np.outer(v, v)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    # sub-steps so that the stiffest rate (damping and the friction law's slope over the mass) stays inside
    # RK4's stability region with margin
    rate = float(np.max((h + fs / FRICTION_SPEED) / mass + np.sqrt(np.abs(np.diag(K)) / mass)))
    sub = max(1, int(np.ceil(rate * dt / 1.0)))
    grid = t[0] + np.arange((len(t) - 1) * 2 * sub + 1) * (dt / (2 * sub))
    S = CubicSpline(t_load, load, axis=0)(grid) if len(t_load) > 3 else np.interp(grid, t_load, load)
    q = np.empty((len(t), 4))
    qd = np.empty((len(t), 4))
    qdd = np.empty((len(t), 4))
    _integrate(np.ascontiguousarray(S), np.asarray(q0, float), np.asarray(qd0, float), K, slopes, knees, fs, off,
               mass, FRICTION_SPEED, dt / sub, sub, q, qd, qdd)
    return q, qd, qdd


def _value(values: Mapping[str, float], tree: Tree, name: str) -> float:
    return float(values.get(name, tree.values.get(name, 0.0)))


def _integrate(S, q0, qd0, K, P, kn, fs, off, m, vs, dt, sub, q, qd, qdd):  # pragma: no cover - compiled
    """RK4 of m qdd + c(qd) + fs tanh(qd / vs) + K q + off = S(t); S on a grid of half steps; c the curve of
    slopes P (n, 4: bump low, bump high, rebound low, rebound high) about the knees kn (n, 2: v-, v+)."""
    n = q.shape[0]
    nc = q0.shape[0]
    x = q0.copy()
    v = qd0.copy()
    a = np.empty(nc)

    def accel(x, v, s, out):
        for i in range(nc):
            c = v[i]
            if c >= 0.0:
                damp = P[i, 0] * min(c, kn[i, 1]) + P[i, 1] * max(c - kn[i, 1], 0.0)
            else:
                damp = P[i, 2] * max(c, kn[i, 0]) + P[i, 3] * min(c - kn[i, 0], 0.0)
            f = s[i] - off[i] - damp - fs[i] * np.tanh(v[i] / vs)
            for j in range(nc):
                f -= K[i, j] * x[j]
            out[i] = f / m[i]

    k1v, k2v, k3v, k4v = np.empty(nc), np.empty(nc), np.empty(nc), np.empty(nc)
    for i in range(n):
        accel(x, v, S[2 * sub * i], a)
        q[i] = x
        qd[i] = v
        qdd[i] = a
        if i == n - 1:
            break
        for s in range(sub):
            g = 2 * (sub * i + s)
            accel(x, v, S[g], k1v)
            accel(x + 0.5 * dt * v, v + 0.5 * dt * k1v, S[g + 1], k2v)
            accel(x + 0.5 * dt * (v + 0.5 * dt * k1v), v + 0.5 * dt * k2v, S[g + 1], k3v)
            accel(x + dt * (v + 0.5 * dt * k2v), v + dt * k3v, S[g + 2], k4v)
            x = x + dt * v + dt * dt / 6.0 * (k1v + k2v + k3v)
            v = v + dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)


if HAVE_NUMBA:
    _integrate = njit(cache=True, nogil=True)(_integrate)
