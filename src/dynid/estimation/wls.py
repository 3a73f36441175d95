"""Gautier's weighted least squares (paper §5.2, eq. (8)-(10)).

Each equation group j (one equation kind: chassis x, roll, a damper, a tire, a joint...) has its
own noise level. It is estimated by solving that group alone on the parameters it can identify,
``sigma_j = ||Y_j - W_j X_j|| / sqrt(n_j - p_j)`` (eq. (8)); the rows of group j are then
weighted by ``1 / sigma_j`` (eq. (9)) and the weighted system is solved by least squares (eq. (10)).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike

from ._checks import as_groups, group_rows, norm_ratio, prepare
from .errors import EstimationWarning, IdentificationError
from .lsq import pivoted_qr, solve_lsq
from .method import Method
from .quality import POOR_FACTOR
from .result import IdentificationResult, build_result

SIGMA_FLOOR = 1e-12
"""Relative floor on a group's noise level: ``sigma_j >= SIGMA_FLOOR * rms(Y_j)``.

Noise-free (simulated) data give ``sigma_j = 0`` or round-off; the weight ``1/sigma_j`` would be
infinite or meaningless, so such a group gets the floor instead, with an ``EstimationWarning``.
``rms(Y_j) = ||Y_j|| / sqrt(n_j)``; if Y_j is all zero the rms of the whole Y is used, and 1 if that
is zero too. Noise-free groups then weigh alike relative to their own scale, and the estimate of
noise-free data is still exact.
"""


@dataclass(frozen=True)
class GroupFit:
    """Result of solving one equation group alone (paper eq. (8)).

    group : its label. n_rows : n_j. parameters : names of the p_j parameters it identifies
    (non-zero columns, independent within the group, chosen by pivoted QR), in the caller's order.
    sigma : the noise level used (units of Y_j). raw_sigma : the value of eq. (8) before the floor.
    floored : True when the floor replaced raw_sigma.
    """

    group: str
    n_rows: int
    parameters: tuple[str, ...]
    sigma: float
    raw_sigma: float
    floored: bool


def fit_group(
    group: str,
    A: np.ndarray,
    b: np.ndarray,
    names: Sequence[str],
    *,
    n_rows: int | None = None,
    rank_tol: float | None = None,
    sigma_floor: float = SIGMA_FLOOR,
    fallback_rms: float = 1.0,
) -> GroupFit:
    """Solve one group alone and return its noise level.

    A : (rows, q) the group's rows of W (or a compressed triangular factor of ``[W_j | Y_j]``, with
    ``n_rows`` the group's true row count); b : (rows,) its Y (or compressed right-hand side);
    names : the q parameter names; fallback_rms : scale for the floor if ``Y_j`` is all zero.
    Raises ``IdentificationError`` naming the group if ``n_j <= p_j``.
    """
    n = A.shape[0] if n_rows is None else int(n_rows)
    nz = np.flatnonzero(np.linalg.norm(A, axis=0) > 0)
    fac = pivoted_qr(A[:, nz], b, n_rows=n, rank_tol=rank_tol)
    r = fac.rank
    chosen = nz[fac.piv[:r]]
    params = tuple(names[i] for i in sorted(chosen))
    if n <= r:
        raise IdentificationError(
            f"equation group {group!r} has {n} rows for the {r} parameters it identifies ({', '.join(params)}): "
            "its noise level sigma_j = ||Y_j - W_j X_j|| / sqrt(n_j - p_j) needs more rows than parameters; "
            "add samples of this group (a longer test, or less decimation: a config's [conditioning] decimate "
            "divides the samples by its factors' product; a lower min_speed), merge it with another group, or pass "
            "group_sigmas",
            parameters=params,
            group=group,
        )
    res = np.asarray(b, dtype=float)
    if r:
        assert fac.qtb is not None
        z = sla.solve_triangular(fac.r[:r, :r], fac.qtb[:r])
        res = res - (A[:, chosen] / fac.norms[fac.piv[:r]]) @ z
    raw = float(np.linalg.norm(res) / np.sqrt(n - r))
    rms = float(np.linalg.norm(b) / np.sqrt(n))
    floor = sigma_floor * (rms if rms > 0 else (fallback_rms if fallback_rms > 0 else 1.0))
    floored = not raw >= floor
    return GroupFit(group, n, params, floor if floored else raw, raw, floored)


def warn_floored(fits: Mapping[str, GroupFit], stacklevel: int = 3) -> None:
    """One ``EstimationWarning`` listing the groups whose noise level was floored."""
    low = [f for f in fits.values() if f.floored]
    if low:
        warnings.warn(
            "equation group(s) with a zero or round-off noise level (noise-free data?): "
            + ", ".join(f"{f.group!r} (sigma_j = {f.raw_sigma:.3g}, floored to {f.sigma:.3g})" for f in low)
            + f"; the floor is {SIGMA_FLOOR:g} x rms(Y_j) by default (sigma_floor)",
            EstimationWarning,
            stacklevel=stacklevel,
        )


def group_noise(
    W: ArrayLike,
    Y: ArrayLike,
    groups: ArrayLike,
    names: Sequence[str],
    *,
    known: Mapping[str, float] | None = None,
    rank_tol: float | None = None,
    sigma_floor: float = SIGMA_FLOOR,
) -> dict[str, GroupFit]:
    """Per-group fits (paper eq. (8)), ``{group: GroupFit}`` in order of first appearance.

    W : (m, p); Y : (m,); groups : (m,) label per row; names : p names; known : fixed parameters
    (moved to the right-hand side first). Warns (``EstimationWarning``) for floored groups.
    """
    pb = prepare(W, Y, names, known=known)
    fits = _group_fits(pb.split.W_est, pb.split.Y_est, as_groups(groups, pb.W.shape[0]), pb.split.est_names,
                       rank_tol, sigma_floor)
    warn_floored(fits)
    return fits


def _group_fits(
    A: np.ndarray, y: np.ndarray, groups: np.ndarray, names: Sequence[str], rank_tol: float | None, sigma_floor: float
) -> dict[str, GroupFit]:
    overall = float(np.linalg.norm(y) / np.sqrt(max(y.size, 1)))
    return {
        g: fit_group(g, A[idx], y[idx], names, rank_tol=rank_tol, sigma_floor=sigma_floor, fallback_rms=overall)
        for g, idx in group_rows(groups).items()
    }


def checked_sigmas(group_sigmas: Mapping[str, float], present: Sequence[str]) -> dict[str, float]:
    """User-given ``{group: sigma_j}``: exactly the groups present, each finite and > 0."""
    missing = [g for g in present if g not in group_sigmas]
    extra = [g for g in group_sigmas if g not in present]
    if missing or extra:
        raise IdentificationError(
            f"group_sigmas must give one sigma per equation group present; missing {missing}, unknown {extra}",
            group=(missing or extra)[0],
        )
    out = {}
    for g in present:
        s = float(group_sigmas[g])
        if not (np.isfinite(s) and s > 0):
            raise IdentificationError(f"group_sigmas[{g!r}] must be finite and > 0, got {group_sigmas[g]!r}", group=g)
        out[g] = s
    return out


def wls(
    W: ArrayLike,
    Y: ArrayLike,
    groups: ArrayLike,
    names: Sequence[str],
    *,
    labels: Mapping[str, str] | None = None,
    a_priori: Mapping[str, float] | None = None,
    truth: Mapping[str, float] | None = None,
    known: Mapping[str, float] | None = None,
    group_sigmas: Mapping[str, float] | None = None,
    rank_tol: float | None = None,
    sigma_floor: float = SIGMA_FLOOR,
    poor_factor: float = POOR_FACTOR,
) -> IdentificationResult:
    """Weighted least squares with per-group noise levels (paper eq. (8)-(10)).

    W : (m, p); Y : (m,); groups : (m,) equation group of each row (e.g. "chassis_x", "roll",
    "susp9", "tire15", "joint1"); names : p parameter names; labels, a_priori, truth, known,
    rank_tol, poor_factor : as in ``ols``. group_sigmas : ``{group: sigma_j}`` to use instead of
    estimating them (units of Y); sigma_floor : see ``SIGMA_FLOOR``.

    Returns X_w with ``C = s_w^2 (W_p^T W_p)^-1`` where ``W_p = P W``, ``P = diag(1/sigma_j)`` and
    s_w is the standard deviation of the weighted residual (dimensionless, ≈ 1 when the sigma_j are
    right); ``result.weights`` is ``{group: sigma_j}``.
    """
    pb = prepare(W, Y, names, labels=labels, a_priori=a_priori, truth=truth, known=known)
    g = as_groups(groups, pb.W.shape[0])
    A, y, est = pb.split.W_est, pb.split.Y_est, pb.split.est_names
    rows = group_rows(g)
    if group_sigmas is None:
        fits = _group_fits(A, y, g, est, rank_tol, sigma_floor)
        warn_floored(fits)
        sigmas = {k: f.sigma for k, f in fits.items()}
    else:
        sigmas = checked_sigmas(group_sigmas, list(rows))
    row_sigma = np.empty(A.shape[0])
    for k, idx in rows.items():
        row_sigma[idx] = sigmas[k]
    sol = solve_lsq(A / row_sigma[:, None], y / row_sigma, est, rank_tol=rank_tol, context="W (weighted)")
    return build_result(
        sol,
        names=pb.names,
        estimated_names=est,
        known=pb.split.known,
        labels=pb.labels,
        a_priori=pb.a_priori,
        truth=pb.truth,
        method=Method.WLS,
        weights=sigmas,
        relative_residual=norm_ratio(np.linalg.norm(y - A @ sol.x), np.linalg.norm(pb.Y)),
        poor_factor=poor_factor,
    )
