"""Ordinary least squares (paper §5.2, eq. (6)-(7))."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._checks import norm_ratio, prepare
from .lsq import solve_lsq
from .method import Method
from .quality import POOR_FACTOR
from .result import IdentificationResult, build_result


def ols(
    W: ArrayLike,
    Y: ArrayLike,
    names: Sequence[str],
    *,
    labels: Mapping[str, str] | None = None,
    a_priori: Mapping[str, float] | None = None,
    truth: Mapping[str, float] | None = None,
    known: Mapping[str, float] | None = None,
    rank_tol: float | None = None,
    poor_factor: float = POOR_FACTOR,
) -> IdentificationResult:
    """Ordinary least squares ``Y = W X + rho``.

    W : (m, p) observation matrix, column k in the units that make ``W[:, k] * X[k]`` the unit of Y.
    Y : (m,) measured forces/torques. names : the p parameter names (W's column order).
    labels, a_priori, truth : optional ``{name: ...}``, carried into the result.
    known : ``{name: value}`` of parameters fixed by the user: their columns move to the right-hand
    side (``Y <- Y - W_known x_known``) and they are reported as known, not estimated.
    rank_tol : relative rank threshold on the unit-column-scaled W (default ``max(m, p) * eps``).
    poor_factor : the %σ rule of thumb factor (paper §7.2: 20).

    Solved by column-pivoted QR (never the normal equations): ``sigma_rho^2 = ||Y - W X||^2 / (m - q)``,
    ``C = sigma_rho^2 (W^T W)^-1`` computed from R, ``std_i = sqrt(C_ii)``, ``%std_i = 100 std_i / |x_i|``
    (q = number of estimated parameters). Raises ``IdentificationError`` naming the unidentifiable
    parameters if W (without the known columns) is rank-deficient.
    """
    pb = prepare(W, Y, names, labels=labels, a_priori=a_priori, truth=truth, known=known)
    sol = solve_lsq(pb.split.W_est, pb.split.Y_est, pb.split.est_names, rank_tol=rank_tol)
    return build_result(
        sol,
        names=pb.names,
        estimated_names=pb.split.est_names,
        known=pb.split.known,
        labels=pb.labels,
        a_priori=pb.a_priori,
        truth=pb.truth,
        method=Method.OLS,
        weights={},
        relative_residual=norm_ratio(np.sqrt(sol.rss), np.linalg.norm(pb.Y)),
        poor_factor=poor_factor,
    )
