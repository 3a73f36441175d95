"""Gautier's weighted least squares (paper §5.2, eq. (8)-(10)).

Each equation group j (one equation kind: chassis x, roll, a damper, a tire, a joint...) has its
own noise level. It is estimated by solving that group alone on the parameters it can identify,
``sigma_j = ||Y_j - W_j X_j|| / sqrt(n_j - p_j)`` (eq. (8)); the rows of group j are then
weighted by ``1 / sigma_j`` (eq. (9)) and the weighted system is solved by least squares (eq. (10)).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from numpy.typing import ArrayLike

from .noise import SIGMA_FLOOR, GroupFit
from .quality import POOR_FACTOR
from .result import IdentificationResult
from .streaming import one_block


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
    (moved to the right-hand side first). Warns (``EstimationWarning``) for floored groups. The fits run on each
    group's factor of one `StreamingLS` block (`StreamingLS.group_fits`).
    """
    return one_block(W, Y, names, groups, known=known, rank_tol=rank_tol).group_fits(sigma_floor)


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

    The rows are one block of the estimator core (`StreamingLS`): this is its `solve_weighted` on them (the groups'
    fits on their factors, then the weighted factors stacked), as a stream of the same rows would be solved.
    """
    return one_block(W, Y, names, groups, labels=labels, a_priori=a_priori, truth=truth, known=known,
                     rank_tol=rank_tol, poor_factor=poor_factor).solve_weighted(group_sigmas, sigma_floor)
