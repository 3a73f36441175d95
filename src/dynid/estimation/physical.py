"""Physically consistent weighted least squares (method "wls-pc") and the feasibility of a base estimate.

The data identify base parameters b (q of them); whether a body is physically realisable is a property of
its standard parameters s (p >= q), with ``b = K s`` (the regrouping of `dynamics.base`). So the decision
variables are the standard parameters, and the estimate is the semidefinite program

    min_s  (K s - b_w)ᵀ C_w⁻¹ (K s - b_w)
    s.t.   J_j(s) - margin · I4  positive semidefinite      (each body j)
           s_i >= 0                                         (rotor inertia IA, viscous FV, Coulomb FS)
           (K s)_k = x_k                                    (base parameters declared known)

with b_w, C_w = s_w² (W_pᵀ W_p)⁻¹ the WLS estimate and covariance (paper eq. (8)-(10), W_p the rows weighted
by 1/σ_j). Up to a constant the objective is the WLS objective ||P (Y - W K s)||² / s_w²: the weights are
WLS's, and the objective reads as a chi-square in the WLS's own metric (its increase over WLS is how many
"σ²" the constraints cost). J_j is the 4x4 pseudo-inertia (Wensing, Kim, Slotine, "Linear matrix
inequalities for physically consistent inertial parameter identification", IEEE RA-L 2017):

    J = [[Σ, h], [hᵀ, m]],   Σ = tr(I)/2 · I3 - I,   h = (MX, MY, MZ),   m = M,

I the inertia matrix about O_j in frame j (XX XY XZ; XY YY YZ; XZ YZ ZZ). J ⪰ 0 if and only if some
non-negative mass distribution has these moments; J ≻ 0 is exactly `model.consistency.check_body`'s three
conditions (M > 0, inertia at the centre of mass positive definite, strict triangle inequalities).

Solved with cvxpy and Clarabel (interior point), the optional `pc` extra: ``pip install cvxpy clarabel``; the
feasibility check of an estimate (every robot identification's) is given to Clarabel directly, without cvxpy.
This module works on arrays and names (K, the positions of each body's ten parameters, the non-negative
ones); `pipeline.run` builds them from a tree and its base parameters.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from ._checks import as_groups, group_rows, prepare
from .errors import IdentificationError
from .lsq import LSQSolution
from .method import Method
from .noise import SIGMA_FLOOR
from .quality import POOR_FACTOR
from .result import IdentificationResult
from .streaming import StreamingLS, one_block

MARGIN = 1e-6
"""J_j ⪰ MARGIN · I4 (SI units: kg, kg·m, kg·m²) rather than J_j ⪰ 0.

Why a margin: a solution on the boundary J ⪰ 0 is a degenerate body (a point, a rod, a plate) that
`check_body` rightly calls not positive definite, and the solver meets its constraints only to its
feasibility tolerance (Clarabel: 1e-8 on data equilibrated to O(1), i.e. about 1e-8 of the largest entry
of J). Why this size: 1e-6 is two orders above that tolerance for a body of order 1 (kg, kg·m²), so the
returned J is strictly positive definite and passes the check; and it means at least 1 mg of mass and
∫ r_a² dm >= 1e-6 kg·m² about each principal axis at the centre of mass, well below what an identification
resolves on an industrial arm (the TX40's smallest inertial base parameter, its wrist's, is 4e-4 kg·m² known
to ~1e-5). It changes the estimate only where a constraint is active, by a relative 1e-6. A tiny robot
(links of grams and millimetres) needs a smaller margin: `margin=`.
"""

ACTIVE_PRICE = 1e-4
"""A constraint is reported active when its shadow price over one natural unit exceeds this fraction of
max(1, chi-square increase): the dual of J_j ⪰ margin·I4 (d chi²/d margin, trace of the dual matrix) times
the body's largest pseudo-inertia eigenvalue; the dual of s_i >= 0 times the standard deviation of the base
parameter s_i enters (divided by its coefficient). Why: a constraint whose release lowers the chi-square by
less than 1e-4 moves the estimate by less than 1e-2 σ (||L Δb||² <= Δchi² for a quadratic objective on a
convex set), so it does not matter; and the interior-point solution's duals of inactive constraints are
complementary-slackness noise, about its gap (1e-8 relative) over the slack, far below."""

_SOLVER_ERROR = ("method \"wls-pc\" needs cvxpy and the Clarabel solver (dynid's optional 'pc' extra): "
                 "pip install cvxpy clarabel")


def require_cvxpy() -> Any:
    """The cvxpy module, or a one-line IdentificationError saying which extra to install."""
    try:
        import clarabel  # noqa: F401  optional: clarabel (the pc extra), the solver cvxpy calls
        import cvxpy  # optional: cvxpy (the pc extra)
    except ImportError:
        raise IdentificationError(_SOLVER_ERROR) from None
    return cvxpy


@dataclass(frozen=True)
class ConsistencyStructure:
    """What the constraints need, as arrays.

    standard_names : the p standard parameters (the SDP's variables).
    base_names : the q' base parameters, rows of K (every base parameter, estimated or known).
    base_map : (q', p) K with ``base = K @ standard``.
    bodies : ``{j: (10 positions of XXj XYj XZj YYj YZj ZZj MXj MYj MZj Mj in standard_names)}`` for the
    bodies to constrain. nonnegative : positions of the terms that must be >= 0 (IA, FV, FS and couplings
    of those kinds).
    """

    standard_names: tuple[str, ...]
    base_names: tuple[str, ...]
    base_map: np.ndarray
    bodies: dict[int, tuple[int, ...]]
    nonnegative: tuple[int, ...] = ()

    def base_values(self, standard: ArrayLike) -> np.ndarray:
        """K @ standard."""
        return self.base_map @ np.asarray(standard, dtype=float)


# J = T @ (XX XY XZ YY YZ ZZ MX MY MZ M), row-major 4x4: the pseudo-inertia is linear in the parameters
_T = np.zeros((16, 10))
for _r, _c, _coef in (
    (0, 0, -0.5), (0, 3, 0.5), (0, 5, 0.5),          # Σxx = (-XX + YY + ZZ) / 2
    (5, 0, 0.5), (5, 3, -0.5), (5, 5, 0.5),          # Σyy
    (10, 0, 0.5), (10, 3, 0.5), (10, 5, -0.5),       # Σzz
    (1, 1, -1.0), (4, 1, -1.0),                      # Σxy = -XY
    (2, 2, -1.0), (8, 2, -1.0),                      # Σxz
    (6, 4, -1.0), (9, 4, -1.0),                      # Σyz
    (3, 6, 1.0), (12, 6, 1.0), (7, 7, 1.0), (13, 7, 1.0), (11, 8, 1.0), (14, 8, 1.0),  # h
    (15, 9, 1.0),                                    # m
):
    _T[_r, _c] = _coef


def pseudo_inertia(p: ArrayLike) -> np.ndarray:
    """The 4x4 pseudo-inertia of one body's 10 parameters (XX XY XZ YY YZ ZZ MX MY MZ M, about O_j)."""
    return (_T @ np.asarray(p, dtype=float)).reshape(4, 4)


@dataclass(frozen=True)
class PhysicalFit:
    """A physically consistent estimate.

    result : the base parameters (`IdentificationResult`, method "WLS-PC"): values K s*, standard
    deviations from the WLS covariance evaluated at the constrained solution (see `note`).
    wls : the plain WLS result of the same data and weights.
    standard : ``{name: value}`` the standard set s* found (consistent with result's values: K s*).
    active : the constraints at their bound, e.g. "body 3 pseudo-inertia", "FV2 >= 0".
    chi2_increase : (b* - b_w)ᵀ C_w⁻¹ (b* - b_w), the objective's rise over WLS in σ² units.
    relative_residual_wls, relative_residual : ||Y - W X|| / ||Y|| of WLS and of the constrained estimate.
    weighted_residual_wls, weighted_residual : ||P (Y - W X)|| of both.
    solver, status, seconds : which solver, its status, and the solve's wall time.
    """

    result: IdentificationResult
    wls: IdentificationResult
    standard: dict[str, float]
    active: tuple[str, ...]
    chi2_increase: float
    relative_residual_wls: float
    relative_residual: float
    weighted_residual_wls: float
    weighted_residual: float
    solver: str
    status: str
    seconds: float
    margin: float = MARGIN
    min_eigenvalues: dict[int, float] = field(default_factory=dict)

    @property
    def fit_worsening_percent(self) -> float:
        """How much larger the relative residual is than WLS's, in %."""
        return 100.0 * (self.relative_residual / self.relative_residual_wls - 1.0) if self.relative_residual_wls \
            else 0.0

    def note(self) -> str:
        """What the terminal and the report print under the table."""
        act = ", ".join(self.active) if self.active else "none"
        std = ("the standard deviations are WLS's (paper eq. (10)) at the constrained solution; no constraint is "
               "active, so they are the estimate's own" if not self.active else
               "the standard deviations are WLS's (paper eq. (10)) at the constrained solution, ignoring the "
               "constraints: along an active constraint the estimate is held at its bound, so they overstate its "
               "spread there and the value is biased towards the bound by design")
        return (f"Physically consistent WLS (wls-pc, {self.solver}, {self.seconds:.2f} s, status {self.status}): "
                f"||Y - W X||/||Y|| = {100 * self.relative_residual:.4g} % against WLS's "
                f"{100 * self.relative_residual_wls:.4g} % (fit {self.fit_worsening_percent:+.3g} %); "
                f"chi-square increase over WLS {self.chi2_increase:.4g} (σ² units); margin J_j >= "
                f"{self.margin:g} I4; active constraints: {act}; {std}.\n")

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON summary (for results.json)."""
        return {
            "solver": self.solver, "status": self.status, "seconds": self.seconds, "margin": self.margin,
            "active_constraints": list(self.active), "chi2_increase": self.chi2_increase,
            "relative_residual": self.relative_residual, "relative_residual_wls": self.relative_residual_wls,
            "fit_worsening_percent": self.fit_worsening_percent,
            "weighted_residual": self.weighted_residual, "weighted_residual_wls": self.weighted_residual_wls,
            "standard_parameters": dict(self.standard),
            "pseudo_inertia_min_eigenvalue": {str(j): v for j, v in self.min_eigenvalues.items()},
            "std": "WLS covariance at the constrained solution" + (" (constraints active: it ignores them)"
                                                                   if self.active else ""),
        }


def _problem(cp: Any, structure: ConsistencyStructure, margin: float):
    """The variables and the constraints common to the estimate and the feasibility check."""
    s = cp.Variable(len(structure.standard_names))
    psd = {j: cp.reshape(_T @ s[list(idx)], (4, 4), order="C") for j, idx in structure.bodies.items()}
    # J is symmetric by construction (_T); the symmetrisation only makes that visible to cvxpy
    cons = {j: (0.5 * (J + J.T) - margin * np.eye(4) >> 0) for j, J in psd.items()}
    nonneg = s[list(structure.nonnegative)] >= 0 if structure.nonnegative else None
    return s, cons, nonneg


def _solve(prob: Any, solver: str, solver_options: Mapping[str, Any] | None) -> None:
    try:
        with warnings.catch_warnings():  # "may be inaccurate": the status says it, and the callers read the status
            warnings.simplefilter("ignore", UserWarning)
            prob.solve(solver=solver, **(solver_options or {}))
    except Exception as exc:  # cvxpy's SolverError and the solvers' own
        raise IdentificationError(f"the physically consistent estimate failed in {solver}: {exc}") from None


def _min_eigs(structure: ConsistencyStructure, s: np.ndarray) -> dict[int, float]:
    return {j: float(np.linalg.eigvalsh(pseudo_inertia(s[list(idx)]))[0]) for j, idx in structure.bodies.items()}


def _active(structure: ConsistencyStructure, s: np.ndarray, body_duals: Mapping[int, np.ndarray],
            nonneg_duals: np.ndarray | None, unit: np.ndarray, chi2: float) -> list[str]:
    """The constraints whose shadow price matters (see ACTIVE_PRICE); unit : (p,) natural unit per parameter."""
    thresh = ACTIVE_PRICE * max(1.0, chi2)
    out = []
    for j, idx in structure.bodies.items():
        lam_max = float(np.linalg.eigvalsh(pseudo_inertia(s[list(idx)]))[-1])
        if float(np.trace(body_duals[j])) * abs(lam_max) > thresh:
            out.append(f"body {j} pseudo-inertia")
    if nonneg_duals is not None:
        out += [f"{structure.standard_names[i]} >= 0" for i, y in zip(structure.nonnegative, nonneg_duals, strict=True)
                if float(y) * unit[i] > thresh]
    return out


def wls_pc(
    W: ArrayLike,
    Y: ArrayLike,
    groups: ArrayLike,
    names: Sequence[str],
    structure: ConsistencyStructure,
    *,
    labels: Mapping[str, str] | None = None,
    a_priori: Mapping[str, float] | None = None,
    truth: Mapping[str, float] | None = None,
    known: Mapping[str, float] | None = None,
    group_sigmas: Mapping[str, float] | None = None,
    rank_tol: float | None = None,
    sigma_floor: float = SIGMA_FLOOR,
    poor_factor: float = POOR_FACTOR,
    margin: float = MARGIN,
    solver: str = "CLARABEL",
    solver_options: Mapping[str, Any] | None = None,
    standard_prior: Mapping[str, float] | None = None,
) -> PhysicalFit:
    """Weighted least squares subject to physical consistency (see the module doc) on a whole system: the rows
    added to a `StreamingLS` as one block, then `wls_pc_streamed`.

    W (m, q) : the base regressor, columns in ``names`` order (every base parameter, known ones too);
    Y, groups, labels, a_priori, truth, known, group_sigmas, rank_tol, sigma_floor, poor_factor : as in
    ``wls``; the other arguments as in `wls_pc_streamed`.
    """
    ls = one_block(W, Y, names, groups, labels=labels, a_priori=a_priori, truth=truth, known=known, rank_tol=rank_tol,
                   poor_factor=poor_factor)
    w = ls.solve_weighted(group_sigmas, sigma_floor)  # `wls` on these rows: the same block, the same solve
    # the weighted rows' factor in one QR of the rows (the same factor as the groups' stacked, to round-off): the
    # second solve of `_closest_to_prior` is sensitive to the last digits of its input (module doc of that
    # function), and this keeps a whole system's answer the one it had before the streamed path
    pb = prepare(W, Y, names, known=known)
    A, y = pb.split.W_est, pb.split.Y_est
    row_sigma = np.empty(A.shape[0])
    for k, idx in group_rows(as_groups(groups, A.shape[0])).items():
        row_sigma[idx] = w.weights[k]
    R = np.linalg.qr(np.column_stack([A / row_sigma[:, None], y / row_sigma]), mode="r")
    return _wls_pc(ls, w, R, structure, margin=margin, solver=solver, solver_options=solver_options,
                   standard_prior=standard_prior)


def wls_pc_streamed(
    ls: StreamingLS,
    structure: ConsistencyStructure,
    *,
    group_sigmas: Mapping[str, float] | None = None,
    sigma_floor: float = SIGMA_FLOOR,
    margin: float = MARGIN,
    solver: str = "CLARABEL",
    solver_options: Mapping[str, Any] | None = None,
    standard_prior: Mapping[str, float] | None = None,
) -> PhysicalFit:
    """Weighted least squares subject to physical consistency (see the module doc) from the per-group factors of
    the rows (`StreamingLS`: ||P (Y - W b)||^2 = ||R_w [b; -1]||^2 with R_w the factor of the groups' R_g / σ_g
    stacked; W is never held).

    ls : the rows' accumulator on the base parameters (its names the structure's base_names; known values, a
    priori values, labels as it holds them); group_sigmas, sigma_floor : as in `StreamingLS.solve_weighted`
    (the weights are WLS's: σ_j from eq. (8) on the unconstrained per-group fits); structure : the map to the
    standard parameters and the constraints; margin : see `MARGIN`; solver : a cvxpy solver name (CLARABEL;
    SCS for an independent check); standard_prior : the standard parameters' a priori values (the model
    file's), by name: the data fix only the base values, so of the consistent standard sets giving the
    estimate, `standard` is the one closest to these (a second solve with the base values held); without it,
    whichever set the solver met first.
    """
    if tuple(ls.names) != structure.base_names:
        raise IdentificationError("wls_pc: names must be the structure's base parameters, in its order")
    w = ls.solve_weighted(group_sigmas, sigma_floor)
    return _wls_pc(ls, w, ls.weighted_factor(w.weights), structure, margin=margin, solver=solver,
                   solver_options=solver_options, standard_prior=standard_prior)


def _wls_pc(ls: StreamingLS, w: IdentificationResult, R: np.ndarray, structure: ConsistencyStructure, *,
            margin: float, solver: str, solver_options: Mapping[str, Any] | None,
            standard_prior: Mapping[str, float] | None) -> PhysicalFit:
    """The constrained estimate from the WLS estimate w of the rows `ls` holds and R, the factor of their weighted
    rows [W_p | Y_p] (estimated columns): ||P(Y - W b)|| = ||R [b; -1]||."""
    cp = require_cvxpy()
    names = ls.names
    if tuple(names) != structure.base_names:
        raise IdentificationError("wls_pc: names must be the structure's base parameters, in its order")
    est = ls.estimated_names
    q = len(est)
    pos = {n: i for i, n in enumerate(names)}
    K_est = structure.base_map[[pos[n] for n in est]]
    b_w = np.array([w.value(n) for n in est])
    s_w = float(w.residual.sigma)
    L = R[:q, :q] / s_w  # C_w⁻¹ = Lᵀ L

    s, cons, nonneg = _problem(cp, structure, margin)
    constraints = list(cons.values()) + ([nonneg] if nonneg is not None else [])
    if ls.known:
        K_known = structure.base_map[[pos[n] for n in ls.known]]
        constraints.append(K_known @ s == np.array(list(ls.known.values())))
    # the objective as L (K s - b_w): zero at WLS, so its value is the chi-square increase itself
    prob = cp.Problem(cp.Minimize(cp.sum_squares((L @ K_est) @ s - L @ b_w)), constraints)
    t0 = time.perf_counter()
    _solve(prob, solver, solver_options)
    seconds = time.perf_counter() - t0
    if s.value is None or prob.status not in ("optimal", "optimal_inaccurate"):
        raise IdentificationError(f"the physically consistent estimate failed: {solver} says {prob.status}"
                                  + (" (the known parameters may contradict the constraints)"
                                     if prob.status.startswith("infeasible") else ""))
    sv = np.asarray(s.value, dtype=float)
    x_std = sv.copy()
    if structure.nonnegative:  # an interior-point solution sits ~1e-9 inside or outside a bound: put it on it
        nn = list(structure.nonnegative)
        x_std[nn] = np.maximum(x_std[nn], 0.0)
    x = structure.base_values(x_std)[[pos[n] for n in est]]
    first = x_std  # the constraints' shadow prices belong to this solve's set
    if standard_prior is not None:
        x_std = _closest_to_prior(cp, structure, margin, x_std, standard_prior, solver, solver_options)
    rss = float(np.linalg.norm(R[:, :q] @ x - R[:, q]) ** 2)
    rss_w = float(w.residual.rss)
    n = ls.n_rows
    dof = n - q
    Rinv = np.linalg.inv(R[:q, :q])
    inv_gram = Rinv @ Rinv.T
    sol = LSQSolution(x, inv_gram, rss, n, dof, rss / dof, rss / dof * inv_gram, w.condition_number)
    res = ls.result_of(sol, Method.WLS_PC, w.weights)
    chi2 = float(np.sum((L @ (x - b_w)) ** 2))
    # a standard parameter's natural unit: the σ of the estimated base parameter it enters, over its coefficient
    sig = np.array([w.std[w.index(n)] for n in est])
    with np.errstate(divide="ignore"):
        ratio = np.where(K_est != 0, sig[:, None] / np.abs(K_est), np.inf)
    unit = np.where(np.isfinite(ratio.min(axis=0)), ratio.min(axis=0), 0.0)
    act = _active(structure, first, {j: np.asarray(c.dual_value) for j, c in cons.items()},
                  None if nonneg is None else np.asarray(nonneg.dual_value), unit, chi2)
    return PhysicalFit(
        result=res, wls=w, standard=dict(zip(structure.standard_names, x_std.tolist(), strict=True)),
        active=tuple(act), chi2_increase=chi2, relative_residual_wls=w.residual.relative_residual,
        relative_residual=res.residual.relative_residual, weighted_residual_wls=float(np.sqrt(rss_w)),
        weighted_residual=float(np.sqrt(rss)), solver=solver, status=str(prob.status), seconds=seconds,
        margin=margin, min_eigenvalues=_min_eigs(structure, x_std))


def _closest_to_prior(cp: Any, structure: ConsistencyStructure, margin: float, first: np.ndarray,
                      prior: Mapping[str, float], solver: str, solver_options: Mapping[str, Any] | None
                      ) -> np.ndarray:
    """Of the consistent standard sets with the first solve's base values, the closest to the prior (each
    parameter's distance relative to its prior size, with a floor of its kind's small size, so that a 1 kg mass
    and a 1e-3 kg.m2 inertia weigh alike). The estimate is unchanged: only what the data cannot see is chosen,
    as a URDF export needs (the first solve once left a UR5 shoulder at 17 kg for 3.7). The sets are
    first + N z with N a basis of K's null space, so the base values hold whatever the solver's tolerance (to
    round-off, and to that tolerance where a non-negative term is put back on its bound); the first solve's set
    is kept if this one fails."""

    names = structure.standard_names
    s0 = np.array([float(prior.get(n, 0.0)) for n in names])
    floor = np.array([_PRIOR_FLOOR.get(n.rstrip("0123456789"), 1e-3) for n in names])
    scale = np.maximum(np.abs(s0), floor)
    N = scipy.linalg.null_space(structure.base_map)
    if N.shape[1] == 0:
        return first
    # in coordinates where the distance's Hessian is the identity: with N / scale = Q R (thin QR), y = R z gives
    # |(first + N z - s0) / scale|^2 = |c + Q y|^2, c = (first - s0) / scale. In z alone the Hessian spans the
    # scales' squares (1 to 1e6), and Clarabel stopped "optimal_inaccurate" 30 % off the optimum (the TX40's first
    # body: M1 6.6 where the prior's 5 kg was reachable)
    Q, Rq = np.linalg.qr(N / scale[:, None])
    keep = np.abs(np.diag(Rq)) > 1e-12 * np.abs(np.diag(Rq)).max()
    Q, Rq = Q[:, keep], Rq[np.ix_(keep, keep)]
    N = N[:, keep]
    y = cp.Variable(Q.shape[1])
    c = (first - s0) / scale
    s = first + N @ scipy.linalg.solve_triangular(Rq, np.eye(Rq.shape[0])) @ y
    # the first solve's margin: where it is active the base values allow no more (the blend below keeps what
    # the solver's tolerance would lose)
    cons = [0.5 * (J + J.T) - margin * np.eye(4) >> 0
            for J in (cp.reshape(_T @ s[list(idx)], (4, 4), order="C") for idx in structure.bodies.values())]
    if structure.nonnegative:
        cons.append(s[list(structure.nonnegative)] >= 0)
    prob = cp.Problem(cp.Minimize(cp.sum_squares(Q.T @ c + y)), cons)
    try:
        _solve(prob, solver, solver_options)
    except IdentificationError:
        return first
    if y.value is None or prob.status not in ("optimal", "optimal_inaccurate"):
        return first
    out = first + N @ scipy.linalg.solve_triangular(Rq, np.asarray(y.value, dtype=float))
    if structure.nonnegative:
        nn = list(structure.nonnegative)
        out[nn] = np.maximum(out[nn], 0.0)
    # the realisable sets with these base values are convex: blend towards the first solve's until every
    # body keeps half the margin (the first solve meets the margin to its tolerance, ~1e-12 below at times)
    for alpha in (1.0, 0.9, 0.5, 0.1):
        mixed = alpha * out + (1 - alpha) * first
        if min(_min_eigs(structure, mixed).values(), default=margin) >= 0.5 * margin:
            return mixed
    return first


# a parameter kind's small size (SI), below which its prior's own size no longer scales the distance
_PRIOR_FLOOR = {"M": 0.1, "MX": 0.01, "MY": 0.01, "MZ": 0.01, "XX": 1e-3, "YY": 1e-3, "ZZ": 1e-3, "XY": 1e-3,
                "XZ": 1e-3, "YZ": 1e-3, "IA": 1e-3, "FV": 1e-2, "FS": 1e-2, "OFF": 1e-2, "K": 1.0,
                "KQ": 1.0, "FVPL": 1e-2, "FVPH": 1e-2, "FVNL": 1e-2, "FVNH": 1e-2}


PRIOR_SPREAD = 0.1
"""`plausible_standard`'s prior: a body's pseudo-inertia in its own units (mass m0, second moments m0 L²,
first moments m0 L) is trusted to this fraction, the 1-σ of a file's mass, of its centre of mass over the link's
size and of its second moments. The data's χ² and these terms are then in the same σ² units."""

PLAUSIBLE_MARGIN = 1e-3
"""`plausible_standard`'s body margin, relative: J_j ⪰ 1e-3 · m0 · diag(L², L², L², 1), every body at least
0.1 % of its a priori mass and of m0 L² about every axis (not a point, a rod or a plate of zero thickness)."""


@dataclass(frozen=True)
class Plausible:
    """The standard set an export writes: `standard` ({name: value}); chi2 : how far its base values K s are
    from the estimate, Σ ((K s - b) / σ)² over the estimated base parameters; worst : the base parameter moved
    most, in σ, and that number; status : the solver's."""

    standard: dict[str, float]
    chi2: float
    worst: tuple[str, float]
    status: str


def plausible_standard(structure: ConsistencyStructure, base_values: Mapping[str, float],
                       base_std: Mapping[str, float], prior: Mapping[str, float],
                       bodies: Mapping[int, tuple[float, float, np.ndarray, np.ndarray]], *,
                       spread: float = PRIOR_SPREAD, margin: float = PLAUSIBLE_MARGIN,
                       solver: str = "CLARABEL") -> Plausible:
    """The physically plausible standard set closest to a model file's (`prior`) that reproduces an estimate
    within its uncertainty: the maximum a posteriori set of a Gaussian prior on each body and the estimate's
    Gaussian likelihood, under constraints,

        min_s  Σ_k ((K s - b)_k / σ_k)²  +  Σ_j ||D_j (J_j(s) - J_j(s0)) D_j||_F² / (spread m0_j)²  +  (joint terms)
        s.t.   J_j(s) ⪰ margin m0_j diag(L_j², L_j², L_j², 1),   lo_j m_j <= h_j <= hi_j m_j,   IA, FV, FS >= 0

    with D_j = diag(1/L_j, 1/L_j, 1/L_j, 1): each body's pseudo-inertia difference in its own units (kg, m), so
    that a kilogram on a 10 kg link and a centimetre on a 0.4 m one weigh by what they are to that link, not
    by their raw numbers; and the box [lo_j, hi_j] (m, frame j) the link's extent, where its centre of mass
    must lie. bodies: frame -> (m0 kg, L m, lo (3,), hi (3,)), from the model file; a body with m0 = 0 gets
    neither prior nor box. A base parameter with σ = 0 (known) is held exactly; a joint term that is a base
    parameter on its own follows the estimate, one that regroups (IA_j into ZZ_j) is held to the prior too
    (relative to its size, `_PRIOR_FLOOR`).
    Where the data determine a body well, the estimate wins; where they cannot see it, the file's values
    stay; an estimate that no plausible body reproduces is met as closely as the σ allow (chi2, worst)."""
    cp = require_cvxpy()
    names = structure.standard_names
    b = np.array([float(base_values[n]) for n in structure.base_names])
    sd = np.array([float(base_std.get(n, 0.0)) for n in structure.base_names])
    s0 = np.array([float(prior.get(n, 0.0)) for n in names])

    K = structure.base_map
    held = sd <= 0
    # s = s_p + N z: the held base values exact to round-off (an equality constraint would hold them only to the
    # solver's tolerance)
    s_p = np.linalg.lstsq(K[held], b[held], rcond=None)[0] if held.any() else np.zeros(len(names))
    N = scipy.linalg.null_space(K[held]) if held.any() else np.eye(len(names))
    z = cp.Variable(N.shape[1])
    s = s_p + N @ z
    terms = [cp.sum_squares(cp.multiply(1.0 / sd[~held], K[~held] @ s - b[~held]))] if (~held).any() else []
    cons = []
    in_body = np.zeros(len(names), dtype=bool)
    for j, idx in structure.bodies.items():
        J = cp.reshape(_T @ s[list(idx)], (4, 4), order="C")
        J = 0.5 * (J + J.T)
        m0, L, lo, hi = bodies.get(j, (0.0, 0.0, None, None))
        if m0 > 0 and L > 0:
            in_body[list(idx)] = True
            D = np.diag([1 / L, 1 / L, 1 / L, 1.0])
            J0 = pseudo_inertia(s0[list(idx)])
            terms.append(cp.sum_squares(D @ (J - J0) @ D) / (spread * m0) ** 2)
            cons.append(J - margin * m0 * np.diag([L * L, L * L, L * L, 1.0]) >> 0)
            h, m = s[list(idx)[6:9]], s[idx[9]]
            cons += [h - lo * m >= 0, hi * m - h >= 0]
        else:
            cons.append(J - MARGIN * np.eye(4) >> 0)
    alone = np.zeros(len(names), dtype=bool)  # a base parameter on its own: the estimate fixes it, no prior
    for row in K[np.count_nonzero(K, axis=1) == 1]:
        alone |= row != 0
    rest = ~in_body & ~alone
    if rest.any():  # regrouped joint terms and bodies without a prior: near the file where the data leave them
        floor = np.array([_PRIOR_FLOOR.get(n.rstrip("0123456789"), 1e-3) for n in names])
        scale = np.maximum(np.abs(s0), floor)[rest]
        terms.append(cp.sum_squares(cp.multiply(1.0 / (spread * scale), s[rest] - s0[rest])))
    if structure.nonnegative:
        cons.append(s[list(structure.nonnegative)] >= 0)
    prob = cp.Problem(cp.Minimize(cp.sum(cp.hstack(terms)) if terms else 0), cons)
    _solve(prob, solver, None)
    if z.value is None or prob.status not in ("optimal", "optimal_inaccurate"):
        raise IdentificationError(f"no physically plausible standard set: {solver} says {prob.status} (the "
                                  "centres of mass may not fit in the links' boxes, or a known value contradicts "
                                  "them)")
    sv = s_p + N @ np.asarray(z.value, dtype=float)
    if structure.nonnegative:
        nn = list(structure.nonnegative)
        sv[nn] = np.maximum(sv[nn], 0.0)
    z = np.zeros(len(b))
    z[~held] = (K[~held] @ sv - b[~held]) / sd[~held]
    k = int(np.argmax(np.abs(z)))
    return Plausible(dict(zip(names, sv.tolist(), strict=True)), float(z @ z),
                     (structure.base_names[k], float(z[k])), str(prob.status))


@dataclass(frozen=True)
class Feasibility:
    """Whether some standard set reproduces given base values and is physically realisable.

    realisable : True when the largest common margin t (J_j ⪰ t I4 for every body, the non-negative terms
    >= 0) reaching those base values is >= `margin`. t : that margin. standard : the standard set attaining
    it (a witness when realisable). tightest : the bodies whose pseudo-inertia sets t.
    """

    realisable: bool
    t: float
    standard: dict[str, float]
    tightest: tuple[int, ...]
    status: str


def feasible_standard(structure: ConsistencyStructure, base_values: Mapping[str, float], *,
                      margin: float = MARGIN, solver: str = "CLARABEL") -> Feasibility:
    """The standard set of largest pseudo-inertia margin whose base values are `base_values` (every base
    parameter): the check of a regrouped estimate (WLS, OLS) for physical consistency.

    max t  s.t.  K s = b,  J_j(s) ⪰ t I4,  s_i >= 0 (IA, FV, FS),  t <= 1 (a body whose parameters are all
    free would make t unbounded; 1 is far above any margin of interest)."""
    b = np.array([float(base_values[n]) for n in structure.base_names])
    if solver == "CLARABEL":
        return _feasible_clarabel(structure, b, margin)
    return _feasible_cvxpy(structure, b, margin, solver)


def _feasible_cvxpy(structure: ConsistencyStructure, b: np.ndarray, margin: float, solver: str) -> Feasibility:
    """`feasible_standard`'s program written in cvxpy (any of its solvers; the oracle of `_feasible_clarabel`)."""
    cp = require_cvxpy()
    s = cp.Variable(len(structure.standard_names))
    t = cp.Variable()
    cons = [structure.base_map @ s == b, t <= 1.0]
    for idx in structure.bodies.values():
        J = cp.reshape(_T @ s[list(idx)], (4, 4), order="C")
        cons.append(0.5 * (J + J.T) - t * np.eye(4) >> 0)
    if structure.nonnegative:
        cons.append(s[list(structure.nonnegative)] >= 0)
    prob = cp.Problem(cp.Maximize(t), cons)
    _solve(prob, solver, None)
    if prob.status in ("infeasible", "infeasible_inaccurate"):  # a non-negative term's base value is negative
        return Feasibility(False, float("-inf"), {}, (), str(prob.status))
    if s.value is None or t.value is None:
        raise IdentificationError(f"the physical-consistency check failed: {solver} says {prob.status}")
    sv = np.asarray(s.value, dtype=float)
    tv = float(t.value)
    eig = _min_eigs(structure, sv)
    tight = tuple(j for j, v in eig.items() if v <= tv + 1e-6 * max(abs(tv), margin))
    return Feasibility(tv >= margin, tv, dict(zip(structure.standard_names, sv.tolist(), strict=True)), tight,
                       str(prob.status))


# cvxpy's names for Clarabel's statuses (what Feasibility.status has said)
_CLARABEL_STATUS = {"Solved": "optimal", "AlmostSolved": "optimal_inaccurate", "PrimalInfeasible": "infeasible",
                    "AlmostPrimalInfeasible": "infeasible_inaccurate", "DualInfeasible": "unbounded",
                    "AlmostDualInfeasible": "unbounded_inaccurate"}
# the upper triangle of a symmetric 4x4, column by column (Clarabel's PSD triangle cone), and its scaling
_TRIU = [(i, j) for j in range(4) for i in range(j + 1)]
_SVEC = np.array([1.0 if i == j else np.sqrt(2.0) for i, j in _TRIU])


def _feasible_clarabel(structure: ConsistencyStructure, b: np.ndarray, margin: float) -> Feasibility:
    """`feasible_standard`'s program given to Clarabel as a conic program, without cvxpy (whose import is 56 MB
    of a robot identification's resident set, every robot run's check): x = (s, t), min -t s.t. K s = b (zero
    cone), 1 - t >= 0 and s_i >= 0 (non-negative cone), svec(J_j(s) - t I4) in the PSD triangle cone."""
    try:
        import clarabel  # optional: clarabel (the pc extra)
        import scipy.sparse as sp  # start-up: scipy.sparse only for the check (clarabel imports it anyway)
    except ImportError:
        raise IdentificationError(_SOLVER_ERROR) from None
    n = len(structure.standard_names)
    K = np.asarray(structure.base_map, dtype=float)
    nonneg = list(structure.nonnegative)
    rows = [np.hstack([K, np.zeros((len(K), 1))])]  # A x + z = rhs, z in the cone
    rhs = [b]
    bound = np.zeros((1 + len(nonneg), n + 1))
    bound[0, n] = 1.0  # z = 1 - t
    bound[np.arange(1, 1 + len(nonneg)), nonneg] = -1.0  # z = s_i
    rows.append(bound)
    rhs.append(np.r_[1.0, np.zeros(len(nonneg))])
    sym = 0.5 * (_T.reshape(4, 4, 10) + _T.reshape(4, 4, 10).transpose(1, 0, 2))  # as cvxpy's 0.5 (J + Jᵀ)
    tri = np.array([sym[i, j] for i, j in _TRIU]) * _SVEC[:, None]  # svec(J) = tri @ p
    eye = np.array([1.0 if i == j else 0.0 for i, j in _TRIU])
    for idx in structure.bodies.values():
        block = np.zeros((len(_TRIU), n + 1))
        block[:, list(idx)] = -tri
        block[:, n] = eye  # z = svec(J(s)) - t svec(I4)
        rows.append(block)
        rhs.append(np.zeros(len(_TRIU)))
    cones = [clarabel.ZeroConeT(len(K)), clarabel.NonnegativeConeT(1 + len(nonneg))]
    cones += [clarabel.PSDTriangleConeT(4) for _ in structure.bodies]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    q = np.zeros(n + 1)
    q[n] = -1.0
    try:
        sol = clarabel.DefaultSolver(sp.csc_matrix((n + 1, n + 1)), q, sp.csc_matrix(np.vstack(rows)),
                                     np.concatenate(rhs), cones, settings).solve()
    except Exception as exc:  # Clarabel's own errors
        raise IdentificationError(f"the physical-consistency check failed in CLARABEL: {exc}") from None
    status = _CLARABEL_STATUS.get(str(sol.status), str(sol.status))
    if status in ("infeasible", "infeasible_inaccurate"):  # a non-negative term's base value is negative
        return Feasibility(False, float("-inf"), {}, (), status)
    if status not in ("optimal", "optimal_inaccurate"):
        raise IdentificationError(f"the physical-consistency check failed: CLARABEL says {status}")
    x = np.asarray(sol.x, dtype=float)
    sv, tv = x[:n], float(x[n])
    eig = _min_eigs(structure, sv)
    tight = tuple(j for j, v in eig.items() if v <= tv + 1e-6 * max(abs(tv), margin))
    return Feasibility(tv >= margin, tv, dict(zip(structure.standard_names, sv.tolist(), strict=True)), tight,
                       status)


__all__ = ["ACTIVE_PRICE", "MARGIN", "PLAUSIBLE_MARGIN", "PRIOR_SPREAD", "ConsistencyStructure", "Feasibility",
           "PhysicalFit", "Plausible", "feasible_standard", "plausible_standard", "pseudo_inertia", "require_cvxpy",
           "wls_pc", "wls_pc_streamed"]
