"""Excitation design: an optimised periodic trajectory for identification (Swevers et al. 1997).

Each moving joint j follows a finite Fourier series of base pulsation w_f = 2 pi / T and
L harmonics,

    q_j(t)   = q0_j + sum_l  a_jl / (w_f l) sin(w_f l t) - b_jl / (w_f l) cos(w_f l t)
    qd_j(t)  =        sum_l  a_jl cos(w_f l t) + b_jl sin(w_f l t)
    qdd_j(t) =        sum_l -a_jl w_f l sin(w_f l t) + b_jl w_f l cos(w_f l t)

so q, qd and qdd are exact (no differentiation of measured data) and periodic: the data of
K periods can be averaged into one, which divides the noise variance by K.

The coefficients minimise the condition number of the base-parameter regressor W_B stacked
over the N samples of one period, (N * joints, base) rows, optionally after scaling each
column to unit norm (``scale="columns"``: the criterion then does not depend on the units of
the parameters; ``scale="none"``: Gautier's and Swevers' plain criterion). Joint limits are
linear in the coefficients, so they are imposed exactly on the optimisation grid as linear
inequalities of SLSQP (tightened by ``margin``), then verified on a grid ten times denser; a
trajectory that overshoots between grid points has its oscillation scaled down until it
fits. Optionally the trajectory starts at rest (qd = qdd = 0 at t = 0, two linear equalities
per joint), so a controller can start it from standstill.

The gradient of log cond is analytic in W (the first and last singular vectors); the
derivative of W with respect to each sample's state is taken by finite differences of the
model's regressor, all samples at once (W at sample k depends only on that sample's q, qd,
qdd): 5 * joints + 1 regressor evaluations of the N samples per gradient. Coulomb friction
columns (FS, sign(qd)) make the criterion discontinuous: during the optimisation they use
the smooth surrogate tanh(qd / v_s), v_s = ``smooth`` times the joint's velocity limit; every
reported figure (condition numbers, expected standard deviations) uses the exact sign.

`expected_uncertainty` gives the closed form of the weighted least-squares covariance of the
base parameters, (sum_j W_j^T W_j / sigma_j^2)^-1, for a given torque noise per joint, sample
rate and duration, and the a priori %σ = 100 sigma / |X_B|.

This module takes the model as an argument (anything with ``tree``, ``regressor`` and
``base_parameters``, like `dynid.Model`): the estimation layer imports no model layer.
"""

from __future__ import annotations

import difflib
import math
import time
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import scipy.linalg
import scipy.optimize
from threadpoolctl import threadpool_limits

from ..progress import Count
from ..textfiles import read_toml
from .errors import IdentificationError

Array = np.ndarray

LIMIT_KEYS = ("q_min", "q_max", "qd_max", "qdd_max")
DENSE_FACTOR = 10  # the verification grid is this many times denser than the optimisation grid


class ExcitationError(IdentificationError):
    """A limits file, a limit or a design setting that cannot be used, said in one line."""


class ModelLike(Protocol):
    """What the design needs of a model (`dynid.Model` has it)."""

    tree: Any

    def regressor(self, q: Array, qd: Array, qdd: Array, wrenches: Any = None, rows: Any = None,
                  cols: Any = None) -> Any: ...

    def base_parameters(self, rows: Any = None, cols: Any = None, seed: int = 0) -> Any: ...


# ------------------------------------------------------------------------------------------ limits


@dataclass(frozen=True)
class Limits:
    """Joint limits of the moving joints, in their order: rad or m, /s, /s²."""

    q_min: Array
    q_max: Array
    qd_max: Array
    qdd_max: Array

    def __post_init__(self) -> None:
        arrays = [np.atleast_1d(np.asarray(getattr(self, k), dtype=float)) for k in LIMIT_KEYS]
        m = arrays[0].size
        for key, a in zip(LIMIT_KEYS, arrays, strict=True):
            if a.ndim != 1 or a.size != m:
                raise ExcitationError(f"limits: {key} has {a.size} values, q_min has {m}")
            if not np.all(np.isfinite(a)):
                raise ExcitationError(f"limits: {key} must be finite numbers, got {a.tolist()}")
            object.__setattr__(self, key, a)
        bad = np.flatnonzero(self.q_max <= self.q_min)
        if bad.size:
            raise ExcitationError(f"limits: q_max must exceed q_min (joint {bad[0] + 1}: "
                                  f"{self.q_min[bad[0]]:g} .. {self.q_max[bad[0]]:g})")
        for key in ("qd_max", "qdd_max"):
            a = getattr(self, key)
            if np.any(a <= 0):
                raise ExcitationError(f"limits: {key} must be positive, got {a.tolist()}")

    @property
    def m(self) -> int:
        return int(self.q_min.size)

    @classmethod
    def from_dict(cls, data: dict, joints: int, source: str = "limits") -> Limits:
        """From a table with the four per-joint lists; every key is required (no silent default)."""
        unknown = [k for k in data if k not in LIMIT_KEYS]
        if unknown:
            close = difflib.get_close_matches(str(unknown[0]), LIMIT_KEYS, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ExcitationError(f"{source}: unknown key {unknown[0]!r}{hint}; the keys are {', '.join(LIMIT_KEYS)}")
        missing = [k for k in LIMIT_KEYS if k not in data]
        if missing:
            raise ExcitationError(f"{source}: missing {', '.join(missing)} (per-joint lists of {joints} numbers: "
                                  f"{', '.join(LIMIT_KEYS)})")
        values = {}
        for k in LIMIT_KEYS:
            v = data[k]
            if not isinstance(v, list) or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in v):
                raise ExcitationError(f"{source}: {k} must be a list of numbers, got {v!r}")
            if len(v) != joints:
                raise ExcitationError(f"{source}: {k} has {len(v)} values; the model has {joints} moving joints")
            values[k] = np.array(v, dtype=float)
        try:
            return cls(**values)
        except ExcitationError as exc:
            raise ExcitationError(f"{source}: {str(exc).removeprefix('limits: ')}") from None

    @classmethod
    def from_toml(cls, path: str | Path, joints: int) -> Limits:
        """Read a limits file (TOML, keys q_min, q_max, qd_max, qdd_max: lists, one number per moving joint)."""
        return cls.from_dict(read_toml(path, "limits file", ExcitationError), joints, source=str(path))

    @classmethod
    def default(cls, prismatic: Sequence[bool]) -> Limits:
        """Conservative stand-ins when no limits are given: ±2.5 rad, 1.5 rad/s, 5 rad/s² (revolute);
        ±0.25 m, 0.25 m/s, 1 m/s² (prismatic). A real robot's limits must replace them."""
        p = np.asarray(prismatic, dtype=bool)
        return cls(q_min=np.where(p, -0.25, -2.5), q_max=np.where(p, 0.25, 2.5),
                   qd_max=np.where(p, 0.25, 1.5), qdd_max=np.where(p, 1.0, 5.0))

    def violation(self, q: Array, qd: Array, qdd: Array) -> float:
        """The largest overshoot of any limit over the samples (m, as a fraction of that limit's range);
        <= 0 when every limit holds."""
        half = (self.q_max - self.q_min) / 2
        v = [np.max((q - self.q_max) / half), np.max((self.q_min - q) / half),
             np.max(np.abs(qd) / self.qd_max - 1), np.max(np.abs(qdd) / self.qdd_max - 1)]
        return float(max(v))


# ------------------------------------------------------------------------------- Fourier series


def fourier_basis(t: Array, harmonics: int, period: float) -> tuple[Array, Array, Array]:
    """(Sq, Sqd, Sqdd), each (N, 1 + 2L): q_j(t) = Sq @ [q0_j, a_j1..a_jL, b_j1..b_jL], and so on."""
    t = np.asarray(t, dtype=float).reshape(-1)
    wf = 2 * np.pi / period
    wl = wf * np.arange(1, harmonics + 1)  # (L,)
    s, c = np.sin(np.outer(t, wl)), np.cos(np.outer(t, wl))
    one, zero = np.ones((t.size, 1)), np.zeros((t.size, 1))
    Sq = np.hstack([one, s / wl, -c / wl])
    Sqd = np.hstack([zero, c, s])
    Sqdd = np.hstack([zero, -s * wl, c * wl])
    return Sq, Sqd, Sqdd


@dataclass(frozen=True)
class FourierTrajectory:
    """A finite Fourier series per moving joint (module docstring).

    joints: the frame numbers of the moving joints (1-based), n: the model's frame count (the
    arrays returned have one column per frame, fixed frames at 0); q0 (m,), a and b (m, L).
    """

    period: float
    q0: Array
    a: Array
    b: Array
    joints: tuple[int, ...]
    n: int

    @property
    def harmonics(self) -> int:
        return int(self.a.shape[1])

    @property
    def wf(self) -> float:
        """Base pulsation, rad/s."""
        return 2 * np.pi / self.period

    def coefficients(self) -> Array:
        """(m, 1 + 2L): [q0, a_1..a_L, b_1..b_L] per joint."""
        return np.hstack([self.q0[:, None], self.a, self.b])

    @classmethod
    def from_coefficients(cls, C: Array, period: float, joints: Sequence[int], n: int) -> FourierTrajectory:
        C = np.asarray(C, dtype=float)
        L = (C.shape[1] - 1) // 2
        return cls(period, C[:, 0].copy(), C[:, 1:1 + L].copy(), C[:, 1 + L:].copy(), tuple(joints), n)

    def evaluate_joints(self, t: Array) -> tuple[Array, Array, Array]:
        """q, qd, qdd of the moving joints, (N, m) each."""
        Sq, Sqd, Sqdd = fourier_basis(t, self.harmonics, self.period)
        C = self.coefficients()
        return Sq @ C.T, Sqd @ C.T, Sqdd @ C.T

    def evaluate(self, t: Array) -> tuple[Array, Array, Array]:
        """q, qd, qdd with one column per frame of the model, (N, n) each (fixed frames 0)."""
        return tuple(self._full(x) for x in self.evaluate_joints(t))  # type: ignore[return-value]

    def _full(self, x: Array) -> Array:
        out = np.zeros((x.shape[0], self.n))
        out[:, np.array(self.joints) - 1] = x
        return out

    def to_toml(self, extra: dict[str, object] | None = None) -> str:
        """The coefficients as TOML, with the formula, so a controller can reproduce the trajectory."""
        f = float.__repr__
        lines = [
            "# Excitation trajectory (dynid excite): a finite Fourier series per joint, periodic of period T,",
            "#   q_j(t)   = q0_j + sum_{l=1..L} a_jl/(wf l) sin(wf l t) - b_jl/(wf l) cos(wf l t)",
            "#   qd_j(t)  =        sum_l a_jl cos(wf l t) + b_jl sin(wf l t)",
            "#   qdd_j(t) =        sum_l -a_jl wf l sin(wf l t) + b_jl wf l cos(wf l t)",
            "# with wf = 2 pi / T; rad (m for a prismatic joint), s. Row i of q0, a, b is joint joints[i].",
            f"period = {f(float(self.period))}",
            f"wf = {f(float(self.wf))}",
            f"harmonics = {self.harmonics}",
            f"joints = [{', '.join(str(j) for j in self.joints)}]",
            f"q0 = [{', '.join(f(float(v)) for v in self.q0)}]",
            "a = [",
            *[f"  [{', '.join(f(float(v)) for v in row)}]," for row in self.a],
            "]",
            "b = [",
            *[f"  [{', '.join(f(float(v)) for v in row)}]," for row in self.b],
            "]",
        ]
        for key, value in (extra or {}).items():
            lines.append(f"{key} = {_toml_value(value)}")
        return "\n".join(lines) + "\n"

    @classmethod
    def from_toml(cls, text: str, n: int) -> FourierTrajectory:
        d = tomllib.loads(text)
        a, b = np.array(d["a"], dtype=float), np.array(d["b"], dtype=float)
        return cls(float(d["period"]), np.array(d["q0"], dtype=float), a, b, tuple(d["joints"]), n)


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf" if v < 0 else "nan")
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return '"' + str(v).replace("\\", "\\\\").replace('"', '\\"') + '"'


def feasible_scale(q0: Array, osc: tuple[Array, Array, Array], limits: Limits) -> float:
    """The largest s with q0 + s osc_q, s osc_qd, s osc_qdd within the limits at every sample
    (osc: the oscillating part's q, qd, qdd, (N, m)); 0 when q0 itself is outside."""
    oq, oqd, oqdd = osc
    if np.any(q0 < limits.q_min) or np.any(q0 > limits.q_max):
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(oq > 0, (limits.q_max - q0) / oq, np.inf)
        lo = np.where(oq < 0, (limits.q_min - q0) / oq, np.inf)
        v = limits.qd_max / np.abs(oqd)
        acc = limits.qdd_max / np.abs(oqdd)
    return float(min(up.min(), lo.min(), v.min(), acc.min()))


# ------------------------------------------------------------------------------------------ design


@dataclass(frozen=True)
class ExcitationDesign:
    """An optimised trajectory and its figures (exact sign(qd) friction in every figure).

    cond: the criterion (condition number, with the design's column scaling) on the optimisation
    grid; cond_start: the same for the best random start (each start is scaled to the limits);
    cond_starts: every random start's; violation: the largest overshoot of a limit on the dense
    verification grid (<= 0: none), as a fraction of the limit.
    """

    trajectory: FourierTrajectory
    limits: Limits
    base_names: tuple[str, ...]
    base_columns: tuple[int, ...]
    base_values: Array
    scale: str
    samples: int
    cond: float
    cond_start: float
    cond_starts: tuple[float, ...]
    cond_unscaled: float
    cond_columns: float
    violation: float
    shrink: float
    iterations: int
    seconds: float
    messages: tuple[str, ...] = field(default=())


@dataclass(frozen=True)
class Uncertainty:
    """Expected standard deviations of the base parameters (closed form of weighted least squares)."""

    names: tuple[str, ...]
    values: Array          # a priori base values X_B (from the model's parameter values)
    sigma: Array           # expected standard deviation of each estimate
    percent: Array         # 100 sigma / |X_B| (inf where X_B = 0)
    samples: int           # samples used (per joint)
    duration: float
    fs: float
    noise: Array           # torque noise sigma per joint


class _Problem:
    """The design problem of one model: its base regressor on a time grid, the criterion and its gradient."""

    def __init__(self, model: ModelLike, limits: Limits, period: float, harmonics: int, samples: int,
                 scale: str, smooth: float, rest: bool, margin: float) -> None:
        tree = model.tree
        self.model, self.limits, self.period, self.L = model, limits, float(period), int(harmonics)
        # the joints with an equation: neither fixed frames nor mimic joints (which follow their master's series)
        self.joints = tuple(getattr(tree, "equations", None) or (f.j for f in tree.frames if f.sigma != 2))
        self.n, self.m = tree.n, len(self.joints)
        if limits.m != self.m:
            raise ExcitationError(f"the limits are for {limits.m} joints; model {tree.name!r} has {self.m} "
                                  "moving joints")
        if scale not in ("none", "columns"):
            raise ExcitationError(f"scale must be 'none' or 'columns', got {scale!r}")
        if harmonics < 1 or period <= 0:
            raise ExcitationError(f"need at least one harmonic and a positive period (got {harmonics}, {period})")
        if samples < 2 * harmonics + 2:
            raise ExcitationError(f"{samples} samples per period cannot resolve {harmonics} harmonics "
                                  f"(need more than {2 * harmonics + 1})")
        self.scale, self.rest, self.margin = scale, rest, margin
        identified = [i for i, name in enumerate(tree.parameter_names) if name not in tree.known]
        self.base = model.base_parameters(rows=list(self.joints), cols=identified)
        self.cols = list(self.base.columns)
        self.base_values = np.asarray(self.base.values(np.asarray(tree.parameters, dtype=float)))
        self.t = np.arange(samples) * (self.period / samples)
        self.S = fourier_basis(self.t, self.L, self.period)
        self.k = 1 + 2 * self.L  # coefficients per joint
        # the smooth surrogate of each Coulomb column: its velocity combination and its smoothing speed
        jpos = {j: i for i, j in enumerate(self.joints)}
        coupling = {c.name: c for c in tree.couplings}
        self.fs_cols: list[tuple[int, Array, float]] = []
        for c_idx, col in enumerate(self.cols):
            name = tree.parameter_names[col]
            combo = np.zeros(self.m)
            if name.startswith("FS") and name[2:].isdigit() and int(name[2:]) in jpos:
                combo[jpos[int(name[2:])]] = 1.0
            elif name in coupling and coupling[name].kind == "FS":
                for j, v in coupling[name].coeffs.items():
                    if j in jpos:
                        combo[jpos[j]] = v
            else:
                continue
            self.fs_cols.append((c_idx, combo, smooth * float(np.abs(combo) @ limits.qd_max)))
        # variables: z = coefficients divided by a typical size, so that SLSQP sees O(1) numbers
        half = (limits.q_max - limits.q_min) / 2
        self.mid = (limits.q_max + limits.q_min) / 2
        size = np.empty((self.m, self.k))
        size[:, 0] = half
        size[:, 1:] = limits.qd_max[:, None] / np.sqrt(self.L)
        self.size = size

    # ---- the regressor of joint states (N, m) -> (N, m, p)
    def regressor(self, q: Array, qd: Array, qdd: Array, smooth: bool) -> Array:
        W = np.asarray(self.model.regressor(self._full(q), self._full(qd), self._full(qdd),
                                            rows=list(self.joints), cols=self.cols))
        if smooth:
            for c_idx, combo, vs in self.fs_cols:
                # sign(s) |tanh(s / vs)| = tanh(s / vs): the column's sign becomes a smooth step
                W[:, :, c_idx] *= np.abs(np.tanh((qd @ combo) / vs))[:, None]
        return W

    def _full(self, x: Array) -> Array:
        out = np.zeros((x.shape[0], self.n))
        out[:, np.array(self.joints) - 1] = x
        return out

    # ---- coefficients <-> variables
    def coeffs(self, z: Array) -> Array:
        return z.reshape(self.m, self.k) * self.size

    def variables(self, C: Array) -> Array:
        return (C / self.size).reshape(-1)

    def states(self, C: Array, S: tuple[Array, Array, Array] | None = None) -> tuple[Array, Array, Array]:
        Sq, Sqd, Sqdd = self.S if S is None else S
        return Sq @ C.T, Sqd @ C.T, Sqdd @ C.T

    # ---- the criterion
    def matrix(self, W: Array) -> tuple[Array, Array]:
        """The stacked (N m, p) matrix whose condition number is the criterion, and the column scale."""
        A = W.reshape(-1, W.shape[-1])
        if self.scale == "none":
            return A, np.ones(A.shape[1])
        d = np.linalg.norm(A, axis=0)
        d = np.where(d > 0, d, 1.0)
        return A / d, d

    def cond(self, C: Array, smooth: bool = False, scale: str | None = None) -> float:
        W = self.regressor(*self.states(C), smooth=smooth)
        old, self.scale = self.scale, scale or self.scale
        try:
            s = np.linalg.svd(self.matrix(W)[0], compute_uv=False)
        finally:
            self.scale = old
        return float(s[0] / s[-1]) if s[-1] > 0 else math.inf

    def log_cond_grad(self, z: Array) -> tuple[float, Array]:
        """log cond of the smooth criterion and its gradient in z."""
        C = self.coeffs(z)
        q, qd, qdd = self.states(C)
        N, m = q.shape
        hq, hv = 1e-6, 1e-6 * self.limits.qd_max
        # all perturbed states in one regressor call: base, q +- h e_j, qd +- h e_j, qdd + e_j
        states = [(q, qd, qdd)]
        for j in range(m):
            e = np.zeros(m)
            e[j] = 1.0
            states += [(q + hq * e, qd, qdd), (q - hq * e, qd, qdd),
                       (q, qd + hv[j] * e, qdd), (q, qd - hv[j] * e, qdd),
                       (q, qd, qdd + e)]  # W is linear in qdd: a forward difference of 1 is exact
        Wall = self.regressor(*(np.vstack(x) for x in zip(*states, strict=True)), smooth=True)
        Wall = Wall.reshape(len(states), N, m, -1)
        W = Wall[0]
        Am, d = self.matrix(W)
        # singular values from the small Gram matrix (p x p): d log s = (A v)^T dA v / s^2
        lam, V = np.linalg.eigh(Am.T @ Am)
        if lam[0] <= 0:
            return math.inf, np.zeros_like(z)
        f = 0.5 * float(np.log(lam[-1] / lam[0]))
        G = np.outer(Am @ V[:, -1], V[:, -1]) / lam[-1] - np.outer(Am @ V[:, 0], V[:, 0]) / lam[0]  # d f / d A
        if self.scale == "columns":  # A = W / d(W), d the column norms
            G = (G - Am * np.sum(G * Am, axis=0)) / d
        G = G.reshape(N, m, -1)
        h = np.empty((3, N, m))  # d f / d (q, qd, qdd) of each sample and joint
        for j in range(m):
            b = 1 + 5 * j
            h[0, :, j] = np.einsum("krc,krc->k", G, Wall[b] - Wall[b + 1]) / (2 * hq)
            h[1, :, j] = np.einsum("krc,krc->k", G, Wall[b + 2] - Wall[b + 3]) / (2 * hv[j])
            h[2, :, j] = np.einsum("krc,krc->k", G, Wall[b + 4] - W)
        Sq, Sqd, Sqdd = self.S
        grad = Sq.T @ h[0] + Sqd.T @ h[1] + Sqdd.T @ h[2]  # (k, m)
        return f, (grad.T * self.size).reshape(-1)

    # ---- limits as linear constraints in z
    def constraints(self) -> list[dict]:
        Sq, Sqd, Sqdd = self.S
        lim, mg = self.limits, self.margin
        half = (lim.q_max - lim.q_min) / 2
        blocks, rhs = [], []
        for j in range(self.m):
            D = self.size[j]
            rows = [(-Sq * D, lim.q_max[j] - mg * half[j]), (Sq * D, -(lim.q_min[j] + mg * half[j])),
                    (-Sqd * D, (1 - mg) * lim.qd_max[j]), (Sqd * D, (1 - mg) * lim.qd_max[j]),
                    (-Sqdd * D, (1 - mg) * lim.qdd_max[j]), (Sqdd * D, (1 - mg) * lim.qdd_max[j])]
            G = np.zeros((6 * len(self.t), self.m * self.k))
            G[:, j * self.k:(j + 1) * self.k] = np.vstack([r[0] for r in rows])
            blocks.append(G)
            rhs.append(np.concatenate([np.full(len(self.t), r[1]) for r in rows]))
        Gi, gi = np.vstack(blocks), np.concatenate(rhs)
        cons = [{"type": "ineq", "fun": lambda z: Gi @ z + gi, "jac": lambda z: Gi}]
        if self.rest:
            Ge = self.rest_matrix()
            cons.append({"type": "eq", "fun": lambda z: Ge @ z, "jac": lambda z: Ge})
        return cons

    def rest_matrix(self) -> Array:
        """qd(0) = 0 and qdd(0) = 0 per joint, as rows acting on z."""
        _, Sqd0, Sqdd0 = fourier_basis(np.zeros(1), self.L, self.period)
        Ge = np.zeros((2 * self.m, self.m * self.k))
        for j in range(self.m):
            Ge[2 * j, j * self.k:(j + 1) * self.k] = Sqd0[0] * self.size[j]
            Ge[2 * j + 1, j * self.k:(j + 1) * self.k] = Sqdd0[0] * self.size[j]
        return Ge

    # ---- random starts, scaled to the limits
    def random_start(self, rng: np.random.Generator) -> Array:
        C = np.zeros((self.m, self.k))
        C[:, 0] = self.mid
        C[:, 1:] = rng.standard_normal((self.m, 2 * self.L))
        if self.rest:  # project onto qd(0) = 0 (sum a = 0) and qdd(0) = 0 (sum l b_l = 0)
            a, b, lw = C[:, 1:1 + self.L], C[:, 1 + self.L:], np.arange(1, self.L + 1.0)
            a -= a.mean(axis=1, keepdims=True)
            b -= np.outer(b @ lw, lw) / (lw @ lw)
        return self.fit_to_limits(C, self.S, margin=self.margin)

    def fit_to_limits(self, C: Array, S: tuple[Array, Array, Array], margin: float = 0.0) -> Array:
        """C with its oscillation scaled to the largest size within the (tightened) limits on the grid S."""
        osc = C.copy()
        osc[:, 0] = 0.0
        lim = self.limits
        half = (lim.q_max - lim.q_min) / 2
        tight = Limits(lim.q_min + margin * half, lim.q_max - margin * half,
                       (1 - margin) * lim.qd_max, (1 - margin) * lim.qdd_max)
        s = feasible_scale(C[:, 0], self.states(osc, S), tight)
        out = osc * s
        out[:, 0] = C[:, 0]
        return out


def design_excitation(
    model: ModelLike,
    limits: Limits,
    *,
    period: float = 10.0,
    harmonics: int = 5,
    samples: int | None = None,
    scale: str = "columns",
    starts: int = 20,
    optimise: int = 3,
    maxiter: int = 200,
    seed: int = 0,
    smooth: float = 0.05,
    rest: bool = True,
    margin: float = 0.005,
    progress: Callable[[str], None] | None = None,
) -> ExcitationDesign:
    """Optimise a Fourier trajectory that minimises the base regressor's condition number within the limits.

    samples: per period on the optimisation grid (default 20 L + 20, at least 100); scale: "columns"
    (unit-norm columns, the default) or "none"; starts: random coefficient sets drawn (seeded), each
    scaled to the limits; optimise: how many of the best starts SLSQP refines (the best result is
    kept); smooth: v_s of the Coulomb surrogate as a fraction of the joint's velocity limit; rest:
    start at rest (qd = qdd = 0 at t = 0); margin: the limits are tightened by this fraction during
    the optimisation so that the dense-grid verification rarely needs to shrink the trajectory.
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    if samples is None:
        samples = max(100, 20 * harmonics + 20)
    if starts < 1 or optimise < 1:
        raise ExcitationError(f"need at least one start and one optimised start (got {starts}, {optimise})")
    # small matrices: BLAS threads only contend with each other (and with other jobs on the machine)
    with threadpool_limits(limits=1, user_api="blas"):
        return _design(model, limits, period, harmonics, samples, scale, starts, optimise, maxiter, seed, smooth,
                       rest, margin, say, t0)


def _design(model: ModelLike, limits: Limits, period: float, harmonics: int, samples: int, scale: str,
            starts: int, optimise: int, maxiter: int, seed: int, smooth: float, rest: bool, margin: float,
            say: Callable[[str], None], t0: float) -> ExcitationDesign:
    pb = _Problem(model, limits, period, harmonics, samples, scale, smooth, rest, margin)
    rng = np.random.default_rng(seed)
    candidates = [pb.random_start(rng) for _ in range(starts)]
    conds = [pb.cond(C) for C in candidates]
    order = np.argsort(conds, kind="stable")
    say(f"{starts} random starts: best condition number {conds[order[0]]:.4g}")
    cons = pb.constraints()
    best_C, best_f, iterations, messages = candidates[order[0]], math.log(conds[order[0]]), 0, []
    refined = min(optimise, starts)
    what = "optimising the best starts"
    say(Count(what, 0, refined, f"optimising the best {refined} start(s) (SLSQP)", unit="start"))
    for rank, i in enumerate(order[:optimise]):
        # a start takes many seconds: its iterations are counted as they run (a second apart at most), so that a
        # bar shows life and its time left before the first start ends
        tick = {"nit": 0, "said": time.perf_counter()}

        def step(_x, rank=rank, tick=tick) -> None:
            tick["nit"] += 1
            if time.perf_counter() - tick["said"] >= 1.0:
                tick["said"] = time.perf_counter()
                say(Count(what, rank, refined, f"start {rank + 1}/{refined}: iteration {tick['nit']}", unit="start",
                          note=f"start {rank + 1}: iteration {tick['nit']}"))

        res = scipy.optimize.minimize(pb.log_cond_grad, pb.variables(candidates[i]), jac=True, method="SLSQP",
                                      constraints=cons, options={"maxiter": maxiter, "ftol": 1e-7}, callback=step)
        iterations += int(res.nit)
        messages.append(str(res.message))
        C = pb.coeffs(res.x)
        # judged on the exact criterion and the limits; SLSQP may stop slightly outside them
        C = pb.fit_to_limits(C, pb.S) if pb.limits.violation(*pb.states(C)) > 0 else C
        f = math.log(pb.cond(C))
        say(Count(what, rank + 1, refined, f"start {rank + 1}/{refined}: condition number {math.exp(f):.4g} "
                  f"({res.nit} iterations, {res.message})", unit="start", note=f"start {rank + 1}: {math.exp(f):.4g}"))
        if f < best_f:
            best_C, best_f = C, f
    # verification on a grid ten times denser; between grid points the series may overshoot a little
    dense = fourier_basis(np.arange(DENSE_FACTOR * samples) * (period / (DENSE_FACTOR * samples)), harmonics, period)
    shrink = 1.0
    if pb.limits.violation(*pb.states(best_C, dense)) > 0:
        fitted = pb.fit_to_limits(best_C, dense)
        nz = np.abs(best_C[:, 1:]) > 0
        shrink = float(np.min(fitted[:, 1:][nz] / best_C[:, 1:][nz])) if nz.any() else 1.0
        best_C = fitted
    traj = FourierTrajectory.from_coefficients(best_C, period, pb.joints, pb.n)
    return ExcitationDesign(
        trajectory=traj, limits=limits, base_names=tuple(pb.base.names), base_columns=tuple(pb.cols),
        base_values=pb.base_values, scale=scale, samples=samples, cond=pb.cond(best_C),
        cond_start=float(conds[order[0]]), cond_starts=tuple(float(c) for c in conds),
        cond_unscaled=pb.cond(best_C, scale="none"), cond_columns=pb.cond(best_C, scale="columns"),
        violation=pb.limits.violation(*pb.states(best_C, dense)), shrink=shrink, iterations=iterations,
        seconds=time.perf_counter() - t0, messages=tuple(messages),
    )


def random_trajectory(model: ModelLike, limits: Limits, *, period: float = 10.0, harmonics: int = 5,
                      seed: int = 0, rest: bool = True, samples: int | None = None) -> FourierTrajectory:
    """A random Fourier trajectory (standard normal coefficients) scaled to the limits on a dense grid:
    the design's random starts, and the baseline an optimised design is compared with."""
    if samples is None:
        samples = max(100, 20 * harmonics + 20)
    pb = _Problem(model, limits, period, harmonics, samples, "none", 0.05, rest, 0.0)
    C = pb.random_start(np.random.default_rng(seed))
    dense = fourier_basis(np.arange(DENSE_FACTOR * samples) * (period / (DENSE_FACTOR * samples)), harmonics, period)
    return FourierTrajectory.from_coefficients(pb.fit_to_limits(C, dense), period, pb.joints, pb.n)


def condition_number(model: ModelLike, trajectory: FourierTrajectory, samples: int, scale: str = "columns",
                     cols: Sequence[int] | None = None) -> float:
    """The criterion of a trajectory on `samples` equally spaced samples of one period (exact friction)."""
    tree = model.tree
    joints = list(trajectory.joints)
    if cols is None:
        identified = [i for i, name in enumerate(tree.parameter_names) if name not in tree.known]
        cols = list(model.base_parameters(rows=joints, cols=identified).columns)
    t = np.arange(samples) * (trajectory.period / samples)
    W = np.asarray(model.regressor(*trajectory.evaluate(t), rows=joints, cols=list(cols)))
    A = W.reshape(-1, W.shape[-1])
    if scale == "columns":
        A = A / np.where(np.linalg.norm(A, axis=0) > 0, np.linalg.norm(A, axis=0), 1.0)
    s = np.linalg.svd(A, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else math.inf


def expected_uncertainty(model: ModelLike, trajectory: FourierTrajectory, noise: float | Sequence[float],
                         fs: float, duration: float | None = None) -> Uncertainty:
    """Expected standard deviation of each base parameter estimated by weighted least squares from the
    trajectory sampled at fs Hz for `duration` s (default one period), with torque noise `noise` (one
    sigma per moving joint, or one for all): cov = (sum_j W_j^T W_j / sigma_j^2)^-1, W_j joint j's rows.

    When the duration is a whole number K of periods and a period a whole number of samples, the samples
    repeat: the information matrix is K times one period's (the same as averaging K periods).
    """
    tree = model.tree
    joints = list(trajectory.joints)
    m = len(joints)
    sig = np.broadcast_to(np.asarray(noise, dtype=float), (m,)).copy() if np.ndim(noise) == 0 \
        else np.asarray(noise, dtype=float)
    if sig.shape != (m,) or np.any(sig <= 0) or not np.all(np.isfinite(sig)):
        raise ExcitationError(f"the torque noise needs one positive sigma, or one per joint ({m}); got {noise!r}")
    if fs <= 0 or not math.isfinite(fs):
        raise ExcitationError(f"the sample rate must be positive, got {fs}")
    duration = trajectory.period if duration is None else float(duration)
    total = round(duration * fs)
    if total < 1:
        raise ExcitationError(f"{duration} s at {fs} Hz is not a single sample")
    per_period = trajectory.period * fs
    periods = duration / trajectory.period
    if abs(per_period - round(per_period)) < 1e-9 and abs(periods - round(periods)) < 1e-9 and round(periods) >= 1:
        count, repeat = round(per_period), round(periods)
    else:
        count, repeat = total, 1
    t = np.arange(count) / fs
    identified = [i for i, name in enumerate(tree.parameter_names) if name not in tree.known]
    base = model.base_parameters(rows=joints, cols=identified)
    W = np.asarray(model.regressor(*trajectory.evaluate(t), rows=joints, cols=list(base.columns)))
    Wn = (W / sig[None, :, None]).reshape(-1, W.shape[-1])
    # (WᵀW)⁻¹ = R⁻¹R⁻ᵀ from W = QR, not the inverse of WᵀW: that squares W's condition number (a TX40 design's
    # sigma then moved 2e-4 relative with the last bits of the regressor's sine, enough to reverse a comparison)
    R = np.linalg.qr(Wn, mode="r")
    if R.shape[0] < R.shape[1] or np.any(np.diag(R) == 0.0):
        raise ExcitationError("the trajectory does not excite every base parameter (singular information "
                              "matrix)")
    Rinv = scipy.linalg.solve_triangular(R, np.eye(R.shape[1]))
    cov = (Rinv @ Rinv.T) / repeat
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    values = np.asarray(base.values(np.asarray(tree.parameters, dtype=float)))
    values[np.abs(values) < 1e-12] = 0.0  # round-off of a regrouping (XX6 - YY6 of equal values), not a value
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = np.where(values != 0, 100 * sigma / np.abs(values), np.inf)
    return Uncertainty(names=tuple(base.names), values=values, sigma=sigma, percent=pct, samples=total,
                       duration=duration, fs=float(fs), noise=sig)


def format_uncertainty(u: Uncertainty) -> str:
    """The expected %σ table."""
    lines = [f"{'parameter':>10} {'a priori':>12} {'sigma':>11} {'%sigma':>9}"]
    for name, v, s, p in zip(u.names, u.values, u.sigma, u.percent, strict=True):
        pct = f"{p:9.3g}" if np.isfinite(p) else f"{'-':>9}"
        lines.append(f"{name:>10} {v:12.5g} {s:11.3g} {pct}")
    return "\n".join(lines)
