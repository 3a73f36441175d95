"""Least-squares core: scaled, column-pivoted QR; rank check naming parameters; covariance from R.

Everything here works on a system ``A x ~ b`` with ``A`` either the full observation matrix
W (m, q) or a compressed triangular factor of ``[W | Y]`` (see ``streaming``): orthogonal
transforms keep column norms, inner products and residual norms, so the decisions (rank,
dependent columns) and results (x, covariance, condition number) are the same; ``n_rows``
always counts the rows of the original W.

Columns are scaled to unit norm before factoring: W mixes units (kg, N/m, N·s/m, ...), and a
rank decision on unscaled columns would call a parameter with small units "dependent".
The scaling does not change the solution; the reported condition number is that of the
unscaled matrix.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ._checks import as_matrix, as_names
from .errors import IdentificationError

_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class PivotedQR:
    """Column-pivoted QR of the unit-column-scaled matrix: ``(A / norms)[:, piv] = Q r``.

    r : (k, q) upper triangular, k = min(rows, q).
    piv : (q,) column order chosen by pivoting.
    norms : (q,) Euclidean norms of the columns of A (0 for a zero column).
    qtb : (k,) ``Q.T @ b``, or None when no right-hand side was given.
    rank : numerical rank: leading pivots with ``|r_ii| > tol * |r_00|``.
    tol : the relative threshold used.
    """

    r: np.ndarray
    piv: np.ndarray
    norms: np.ndarray
    qtb: np.ndarray | None
    rank: int
    tol: float


def default_rank_tol(n_rows: int, q: int) -> float:
    """Relative rank threshold ``max(n_rows, q) * eps`` (the convention of ``numpy.linalg.matrix_rank``)."""
    return max(n_rows, q, 1) * _EPS


def pivoted_qr(
    A: np.ndarray, b: np.ndarray | None = None, *, n_rows: int | None = None, rank_tol: float | None = None
) -> PivotedQR:
    """Rank-revealing QR (LAPACK geqp3) of A with unit-norm columns; Q is applied to b, never formed.

    A tall A is first compressed to the triangular factor of ``[A | b]``; ``r`` and
    ``qtb`` then refer to the compressed system, which has the same least-squares solution,
    residual norm and column geometry.

    A : (rows, q); b : (rows,) or None; n_rows : rows of the original problem (default ``A.shape[0]``)
    for the default tolerance; rank_tol : relative threshold on the pivots (default ``default_rank_tol``).
    """
    rows, q = A.shape
    n = rows if n_rows is None else n_rows
    tol = default_rank_tol(n, q) if rank_tol is None else float(rank_tol)
    if rows > q + 1:
        # Compress first by a plain (blocked, fast) Householder QR of [A | b]: it is column-wise
        # backward stable and keeps norms, inner products and exact zero columns, so pivoting the
        # small (q+1, q+1) factor decides exactly as pivoting A would, at a fraction of the cost.
        Rc = np.linalg.qr(A if b is None else np.column_stack([A, b]), mode="r")
        A, b = Rc[:, :q], (None if b is None else Rc[:, q])
        rows = A.shape[0]
    norms = np.linalg.norm(A, axis=0)
    # a column within round-off of zero next to the largest (a regressor term that cancels in exact arithmetic,
    # e.g. ZZ2 in a TX40's joint-1 rows at 1e-19 of the largest column) is zero: scaled to unit norm it would
    # pass for a parameter and fit the round-off (the joint's sigma_j moved 0.1 % with the last bits of sin/cos)
    norms[norms <= tol * norms.max(initial=0.0)] = 0.0
    scale = np.where(norms > 0, norms, 1.0)
    As = np.where(norms > 0, A / scale, 0.0)
    if q == 0 or rows == 0:
        return PivotedQR(np.zeros((0, q)), np.arange(q), norms, None if b is None else np.zeros(0), 0, tol)
    if b is None:
        r, piv = sla.qr(As, mode="r", pivoting=True)
        qtb = None
    else:
        cq, r, piv = sla.qr_multiply(As, np.asarray(b, dtype=float)[None, :], mode="right", pivoting=True)
        qtb = cq[0]
    d = np.abs(np.diag(r))
    if d.size == 0 or d[0] == 0.0:
        rank = 0
    else:
        small = np.flatnonzero(d <= tol * d[0])
        rank = int(small[0]) if small.size else d.size
    return PivotedQR(r, np.asarray(piv, dtype=int), norms, qtb, rank, tol)


def dependent_columns(fac: PivotedQR, names: Sequence[str]) -> tuple[list[int], dict[str, dict[str, float]]]:
    """Columns that are zero or in the span of the others, and the relations that make them so.

    The pivoted QR gives the rank r. Which parameters to blame is then chosen in the user's
    order: a column is dependent when it lies (within the rank threshold) in the span of the
    earlier independent columns, so the earlier parameters are kept and the later ones are named
    (e.g. a wheel mass that regroups into the chassis mass M6 listed before it). If that ordered
    sweep does not find exactly r independent columns (a borderline, nearly dependent case) the
    trailing pivots of the QR are named instead.

    Returns the dependent column indices (sorted) and ``{name: {kept_name: coefficient}}`` with
    ``column(name) = sum(coefficient * column(kept_name))`` in the unscaled W ({} for a zero column).
    """
    q = len(names)
    r = fac.rank
    if r == q:
        return [], {}
    M = fac.r[:, np.argsort(fac.piv)]  # columns back in user order; same Gram matrix as the scaled A
    thresh = fac.tol * (abs(fac.r[0, 0]) if fac.r.size else 0.0)
    kept: list[int] = []
    dep: list[int] = []
    basis = np.zeros((M.shape[0], 0))
    for j in range(q):
        if fac.norms[j] == 0.0:
            dep.append(j)
            continue
        v = M[:, j].copy()
        for _ in range(2):  # Gram-Schmidt twice is enough for orthogonality to round-off
            v -= basis @ (basis.T @ v)
        nv = float(np.linalg.norm(v))
        if nv > thresh and len(kept) < r:
            kept.append(j)
            basis = np.column_stack([basis, v / nv])
        else:
            dep.append(j)
    if len(kept) != r:
        kept = sorted(int(i) for i in fac.piv[:r] if fac.norms[i] > 0)
        dep = sorted(set(range(q)) - set(kept))
    relations: dict[str, dict[str, float]] = {}
    for j in dep:
        if fac.norms[j] == 0.0 or not kept:
            relations[names[j]] = {}
            continue
        a = np.linalg.lstsq(M[:, kept], M[:, j], rcond=None)[0]
        big = np.abs(a) > 1e-9 * np.max(np.abs(a))
        relations[names[j]] = {
            names[i]: float(ai * fac.norms[j] / fac.norms[i]) for i, ai, keep in zip(kept, a, big, strict=True) if keep
        }
    return dep, relations


def _format_relation(coefs: dict[str, float], limit: int = 6) -> str:
    if not coefs:
        return "zero column: not excited by these data"
    items = sorted(coefs.items(), key=lambda kv: -abs(kv[1]))
    terms = [f"{'-' if c < 0 else '+'} {abs(c):.6g}*{n}" for n, c in items[:limit]]
    text = " ".join(terms).lstrip("+ ")
    if len(items) > limit:
        text += f" + ... ({len(items) - limit} more)"
    return f"its column = {text}"


def rank_deficiency_error(fac: PivotedQR, names: Sequence[str], context: str = "W") -> IdentificationError:
    """The ``IdentificationError`` for a rank-deficient system, naming the unidentifiable parameters."""
    dep, relations = dependent_columns(fac, names)
    bad = [names[j] for j in dep]
    details = "; ".join(f"{n} ({_format_relation(relations[n])})" for n in bad)
    return IdentificationError(
        f"{context} is rank-deficient (rank {fac.rank} for {len(names)} parameters): these parameters cannot be "
        f"identified from these data: {details}. Fix them as known (known={{name: value}}), regroup them into "
        "the parameters their columns combine with, or add tests that excite them.",
        parameters=bad,
        relations=relations,
    )


def check_rank(W: np.ndarray, names: Sequence[str], *, rank_tol: float | None = None) -> None:
    """Raise ``IdentificationError`` naming the unidentifiable parameters if W (m, q) is rank-deficient."""
    nm = as_names(names)
    A = as_matrix(W, nm)
    as_names(nm, A.shape[1])
    fac = pivoted_qr(A, rank_tol=rank_tol)
    if fac.rank < len(nm):
        raise rank_deficiency_error(fac, nm)


@dataclass(frozen=True)
class LSQSolution:
    """Least-squares solution of ``A x ~ b`` (q unknowns, n_rows original rows).

    x : (q,) estimate. inv_gram : (q, q) ``(A.T A)^-1``. rss : ``||b - A x||^2``.
    dof : ``n_rows - q``. sigma2 : ``rss / dof``. covariance : ``sigma2 * inv_gram``.
    condition_number : 2-norm condition number of the unscaled A.
    """

    x: np.ndarray
    inv_gram: np.ndarray
    rss: float
    n_rows: int
    dof: int
    sigma2: float
    covariance: np.ndarray
    condition_number: float

    @property
    def std(self) -> np.ndarray:
        """(q,) standard deviations ``sqrt(diag(covariance))``."""
        return np.sqrt(np.diag(self.covariance))


def solve_lsq(
    A: np.ndarray,
    b: np.ndarray,
    names: Sequence[str],
    *,
    n_rows: int | None = None,
    rank_tol: float | None = None,
    context: str = "W",
) -> LSQSolution:
    """Solve ``min ||b - A x||`` by scaled pivoted QR, with ``C = sigma^2 (A.T A)^-1`` from R.

    A : (rows, q), b : (rows,), names : q parameter names (for error messages).
    Raises ``IdentificationError`` if A is rank-deficient (naming the parameters) or if there are
    not more rows than parameters.
    """
    n = A.shape[0] if n_rows is None else int(n_rows)
    q = len(names)
    dof = n - q
    if dof <= 0:
        raise IdentificationError(
            f"{context} has {n} rows for {q} parameters: least squares needs more rows than parameters "
            "to estimate the noise level; add samples or fix some parameters as known"
        )
    fac = pivoted_qr(A, b, n_rows=n, rank_tol=rank_tol)
    if fac.rank < q:
        raise rank_deficiency_error(fac, names, context)
    assert fac.qtb is not None
    scale = np.where(fac.norms > 0, fac.norms, 1.0)
    R = fac.r[:q, :q]
    z = sla.solve_triangular(R, fac.qtb[:q])
    xs = np.empty(q)
    xs[fac.piv] = z
    x = xs / scale
    res = b - A @ x
    rss = float(res @ res)
    Rinv = sla.solve_triangular(R, np.eye(q))
    G = np.empty((q, q))
    G[np.ix_(fac.piv, fac.piv)] = Rinv @ Rinv.T
    inv_gram = G / np.outer(scale, scale)
    sv = sla.svdvals(R * scale[fac.piv][None, :])
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    sigma2 = rss / dof
    return LSQSolution(x, inv_gram, rss, n, dof, sigma2, sigma2 * inv_gram, cond)
