"""Ordinary least squares (paper §5.2, eq. (6)-(7))."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from numpy.typing import ArrayLike

from .quality import POOR_FACTOR
from .result import IdentificationResult
from .streaming import one_block


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

    The rows are one block of the estimator core (`StreamingLS`): this is its `solve` on them, so a batch and a
    stream of the same rows share every step after the block's QR.
    """
    return one_block(W, Y, names, labels=labels, a_priori=a_priori, truth=truth, known=known, rank_tol=rank_tol,
                     poor_factor=poor_factor).solve()
