"""The car at rest on flat ground: attitude, tire loads, damper preloads.

At rest the ground pushes each contact point (origin of the tire frame) vertically with
a force F_i, and every free or elastic joint is in equilibrium. Unknowns: height q3,
pitch q5, roll q6, the four damper clearances (unless held at the design position), the
four tire deflections and the four loads; equations: the inverse dynamic model of the
z, pitch, roll, damper and tire joints equals zero (x, y and yaw hold by symmetry of
vertical forces) and each contact point lies on the ground z0 = 0. The tabulated joints
follow the kinematic tables. Solved by Newton's method (scipy `root`) with the engine's
inverse dynamics, so it holds for any geometry and parameter set.

Engine: NumPy's (REST_ENGINE), whatever the default. A solve is ~12 single-sample inverse dynamics and a
batched one per Jacobian (its columns in one call): 0.14 s of CPU against the compiled engine's 0.05 s when that
is cached, where compiling it cost a first `dynid demo` 3.4 s of CPU (the rest state and the simulator's yaw
inertia were its only uses there). Both engines agree to rounding; the solve's tolerance is far coarser.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from ..dynamics import Model, Wrench
from ..model.files import tree_to_toml
from ..model.tree import ModelError, Tree
from .geometry import GeometryError
from .tables import default_tables
from .template import CORNERS, DAMPERS, TIRES, WHEELS

KN = 1000.0
REST_ENGINE = "numpy"  # module doc: no compile for a few single samples


@dataclass(frozen=True)
class RestState:
    """q (42,) at rest; loads (4,) N, the vertical ground force on each tire (rear left first)."""

    q: np.ndarray
    loads: np.ndarray

    @property
    def tire_deflections(self) -> np.ndarray:
        return self.q[np.array(TIRES) - 1]

    @property
    def damper_clearances(self) -> np.ndarray:
        return self.q[np.array(DAMPERS) - 1]


# rest states solved in this process, by the content of what they depend on: a demo asks for the same few (the
# vehicle file's check, its a priori and truth trees, the simulator's) a dozen times, 0.2-0.4 s each
_SOLVED: OrderedDict[bytes, RestState] = OrderedDict()
_SOLVED_KEPT = 16
_SOLVED_LOCK = threading.Lock()


def _rest_key(tree: Tree, tables, fix_dampers: bool, steering_wheel: float) -> bytes | None:
    """The content key of a rest state; None (not kept) for a tree no model file can hold (load terms)."""
    try:
        text = tree_to_toml(tree)
    except ModelError:
        return None
    h = hashlib.sha256(text.encode())
    h.update(repr((tuple(float(g) for g in tree.gravity), bool(fix_dampers), float(steering_wheel))).encode())
    for corner in tables.tables:
        for name in sorted(corner):
            t = corner[name]
            for a in (t.travel, t.values, t.steering):
                h.update(b"-" if a is None else np.ascontiguousarray(a, dtype=float).tobytes() + repr(a.shape).encode())
    return h.digest()


def rest_state(tree: Tree, tables=None, fix_dampers: bool = False, steering_wheel: float = 0.0) -> RestState:
    """Equilibrium at rest on flat ground (q1 = q2 = q4 = 0); raises GeometryError if a wheel floats.

    tables: KinematicTables for the tabulated joints (default: the 406's); fix_dampers: hold
    the dampers at q = 0 (their equations are then not imposed: see `design_preloads`).
    Solved once per process for the same tree and tables (a copy of the same arrays after).
    """

    tables = default_tables() if tables is None else tables
    key = _rest_key(tree, tables, fix_dampers, steering_wheel)
    if key is None:
        return _solve_rest(tree, tables, fix_dampers, steering_wheel)
    with _SOLVED_LOCK:
        rest = _SOLVED.get(key)
    if rest is None:
        rest = _solve_rest(tree, tables, fix_dampers, steering_wheel)
        with _SOLVED_LOCK:
            _SOLVED[key] = rest
            while len(_SOLVED) > _SOLVED_KEPT:
                _SOLVED.popitem(last=False)
    return RestState(rest.q.copy(), rest.loads.copy())


def _solve_rest(tree: Tree, tables, fix_dampers: bool, steering_wheel: float) -> RestState:
    """rest_state's Newton solve."""
    model = Model(tree)
    weight = -tree.gravity[2] * sum(tree.values.get(f"M{j}", 0.0) for j in range(1, tree.n + 1))
    kts = [tree.values.get(f"K{t}", 0.0) for t in TIRES]
    if min(kts) <= 0.0 or weight <= 0.0:
        raise GeometryError(
            f"rest state of {tree.name!r}: needs positive tire stiffnesses and masses; got kt = {kts}, "
            f"total weight {weight:.6g} N"
        )
    damp = [] if fix_dampers else list(DAMPERS)
    rows = [3, 5, 6, *damp, *TIRES]
    nd = len(damp)
    zero = np.zeros(tree.n)

    def states(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The postures (m, n) and loads (m, 4) N of m points X (m, k) of the unknowns."""
        q = np.zeros((len(X), tree.n))
        q[:, [2, 4, 5]] = X[:, :3]
        for i, d in enumerate(damp):
            q[:, d - 1] = X[:, 3 + i]
        for i, t in enumerate(TIRES):
            q[:, t - 1] = X[:, 3 + nd + i]
        zeros = np.zeros_like(q)
        return tables.joints(q, zeros, zeros, steering_wheel)[0], X[:, 3 + nd + 4:] * KN

    def residuals(X: np.ndarray) -> np.ndarray:
        """The equations at m points X (m, k), in one batched call of the engine (m, k)."""
        q, F = states(X)
        up = np.zeros((len(X), 6))
        ws = []
        for i, t in enumerate(TIRES):
            up[:, 2] = F[:, i]
            ws.append(Wrench(t, up.copy(), frame=0))
        zeros = np.zeros_like(q)
        tau = model.inverse_dynamics(q, zeros, zeros, wrenches=ws, backend=REST_ENGINE)[:, np.array(rows) - 1] / KN
        z = model.transforms(q)[:, np.array(TIRES), 2, 3]
        return np.concatenate([tau, z * 1e3], axis=1)

    def residual(x: np.ndarray) -> np.ndarray:
        return residuals(x[None])[0]

    def jacobian(x: np.ndarray) -> np.ndarray:
        """Forward differences with MINPACK's steps (sqrt(eps) |x_j|), all columns in one batched call: the engine's
        cost per call is mostly per call, not per sample."""
        h = np.sqrt(np.finfo(float).eps) * np.abs(x)
        h[h == 0.0] = np.sqrt(np.finfo(float).eps)
        X = np.vstack([x, x + np.diag(h)])
        h = np.diag(X[1:]) - x  # the steps taken, exactly
        f = residuals(X)
        return (f[1:] - f[0]).T / h

    q0 = zero.copy()
    radius = float(np.linalg.norm(model.transforms(q0)[TIRES[0], :3, 3] - model.transforms(q0)[WHEELS[0], :3, 3]))
    defl = weight / 4 / np.mean(kts)
    x0 = np.concatenate([[radius - defl, 0.0, 0.0], np.zeros(nd), np.full(4, defl), np.full(4, weight / 4 / KN)])
    sol = root(residual, x0, jac=jacobian, method="hybr", options={"xtol": 1e-13})
    if not sol.success or np.abs(residual(sol.x)).max() > 1e-7:
        raise GeometryError(f"rest state of {tree.name!r}: no static equilibrium found ({sol.message})")
    q, F = (a[0] for a in states(sol.x[None]))
    floating = [i for i in range(4) if F[i] <= 0.0]
    if floating:
        i = floating[0]
        raise GeometryError(
            f"{tree.name!r}: the {CORNERS[i]} wheel (frame {WHEELS[i]}) would float at rest: its vertical load "
            f"would be {F[i]:.6g} N, a negative tire deflection q{TIRES[i]} = {q[TIRES[i] - 1] * 1e3:.4g} mm; "
            f"the centre of mass is outside the wheels' support: check the axle positions, half tracks and masses"
        )
    return RestState(q, F)


def design_preloads(tree: Tree, tables=None) -> np.ndarray:
    """Damper offsets (4,) that make the design position (all dampers at q = 0) the rest state.

    The tires alone then decide the attitude and how the weight splits between the wheels.
    """
    rest = rest_state(tree, tables, fix_dampers=True)
    zero = np.zeros(tree.n)
    ws = [Wrench(t, np.array([0.0, 0.0, f, 0.0, 0.0, 0.0]), frame=0) for t, f in zip(TIRES, rest.loads, strict=True)]
    tau = Model(tree).inverse_dynamics(rest.q, zero, zero, wrenches=ws, backend=REST_ENGINE)[np.array(DAMPERS) - 1]
    off = np.array([tree.values.get(f"OFF{d}", 0.0) for d in DAMPERS])
    return off - tau
