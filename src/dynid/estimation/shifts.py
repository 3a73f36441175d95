"""Nuisance shifts estimated with the parameters: how far a channel group is late, as the equations' residual says.

Moving the data by a small amount h of a nuisance quantity k (a channel group's delay) changes the rows by
(dW_k, dY_k) h to first order. With the estimate X̂ and its weighted residual r0 = Y − W X̂, the residual of
(X̂ + ΔX, δ) is then

    r(ΔX, δ) = r0 − W ΔX − Σ_k δ_k s_k,    s_k = dW_k X̂ − dY_k,

and the weighted least-squares (ΔX, δ) is one Gauss–Newton step of the joint fit of parameters and shifts from
(X̂, 0): δ̂ the shifts the data ask for, cov = s² A⁻¹ (A the weighted normal matrix of [W, s_1 .. s_K], s² the
weighted residual variance after the step) their uncertainty, the curvature of the residual sum of squares
about its minimum. Every quantity is a quadratic form of the rows [W | Y | dW_1 | dY_1 | ...], so the caller
accumulates their Gram matrix per equation group while streaming the data (`ShiftSums`), before X̂ and the
weights are known; `estimate_shifts` finishes.

The shift of the estimates a source's δ̂_k implies, ΔX_k = −(WᵀΩW)⁻¹ WᵀΩ s_k δ̂_k, is what correcting that
source would change (to first order): the bias its mismatch leaves in X̂.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

# a shift whose column, once the parameters' columns are projected out, keeps less than this share of its
# norm is not determined by the equations (it moves nothing the parameters cannot absorb)
UNDETERMINED = 1e-9


@dataclass
class ShiftSums:
    """Per equation group, the Gram matrix of [W | Y | dW_1 | dY_1 | ... | dW_K | dY_K] over the estimated
    columns (a known parameter's column belongs to the right-hand side, as in `BiasAccumulator`), and the rows.

    sources : the K nuisance quantities (order of the blocks); columns, known_columns, known_values : as in
    `BiasAccumulator`."""

    sources: tuple[str, ...]
    columns: np.ndarray
    known_columns: np.ndarray
    known_values: np.ndarray
    gram: dict[str, np.ndarray] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)

    def add(self, W: ArrayLike, Y: ArrayLike, dW: Sequence[ArrayLike], dY: Sequence[ArrayLike],
            groups: ArrayLike) -> None:
        """Rows W (n, p), Y (n,) and, per source, their change per unit of it (dW_k (n, p), dY_k (n,)), grouped."""
        if len(dW) != len(self.sources) or len(dY) != len(self.sources):
            raise ValueError(f"ShiftSums.add: {len(self.sources)} sources, got {len(dW)} dW and {len(dY)} dY")
        W, Y = np.asarray(W, dtype=float), np.asarray(Y, dtype=float)
        kc, kv = self.known_columns, self.known_values
        blocks = [W[:, self.columns], (Y - W[:, kc] @ kv)[:, None]]
        for a, b in zip(dW, dY, strict=True):
            a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
            blocks += [a[:, self.columns], (b - a[:, kc] @ kv)[:, None]]
        M = np.concatenate(blocks, axis=1)
        groups = np.asarray(groups)
        for g in dict.fromkeys(groups.tolist()):
            Mg = M[groups == g]
            G = Mg.T @ Mg
            self.gram[g] = G + self.gram[g] if g in self.gram else G
            self.rows[g] = self.rows.get(g, 0) + len(Mg)

    def merge(self, other: ShiftSums) -> ShiftSums:
        """A new ShiftSums with both one's sums (same sources and columns)."""
        gram, rows = dict(self.gram), dict(self.rows)
        for g, G in other.gram.items():
            gram[g] = G + gram[g] if g in gram else G
            rows[g] = rows.get(g, 0) + other.rows[g]
        return ShiftSums(self.sources, self.columns, self.known_columns, self.known_values, gram, rows)


@dataclass(frozen=True)
class ShiftEstimate:
    """The nuisance shifts the residual asks for: values (K,) in the unit of the perturbation, std (K,) (NaN where
    not determined), determined (K,) bool; parameter_shifts {source: ΔX_k (q,)} over `names` (the estimated
    parameters); parameter_step (q,): the parameters' change in the joint step (ΔX); rss_drop: the weighted
    residual sum of squares the shifts remove, of `rss` before the step."""

    sources: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    determined: np.ndarray
    names: tuple[str, ...]
    parameter_shifts: dict[str, np.ndarray]
    parameter_step: np.ndarray
    rss: float
    rss_drop: float


def estimate_shifts(sums: ShiftSums, x: ArrayLike, names: Sequence[str],
                    group_sigmas: Mapping[str, float] | None = None) -> ShiftEstimate:
    """The Gauss–Newton step of the module doc from the estimate x (q,) of the estimated `names`, each equation
    group weighted by 1 / σ_g² (`group_sigmas`; None: all 1, OLS)."""
    x = np.asarray(x, dtype=float)
    q, K = len(x), len(sums.sources)
    width = (K + 1) * (q + 1)
    # C maps the Gram's columns to [W_1 .. W_q, s_1 .. s_K, r0]
    C = np.zeros((width, q + K + 1))
    C[:q, :q] = np.eye(q)
    for k in range(K):
        o = (k + 1) * (q + 1)
        C[o:o + q, q + k] = x
        C[o + q, q + k] = -1.0
    C[:q, -1] = -x
    C[q, -1] = 1.0
    H = np.zeros((q + K + 1, q + K + 1))
    n = 0
    for g, G in sums.gram.items():
        w = 1.0 if group_sigmas is None else 1.0 / group_sigmas[g] ** 2
        H += w * (C.T @ G @ C)
        n += sums.rows[g]
    Aww, Aws, Ass = H[:q, :q], H[:q, q:q + K], H[q:q + K, q:q + K]
    bw, bs, rr = H[:q, -1], H[q:q + K, -1], float(H[-1, -1])
    # a parameter none of the summed equations holds (a tire's stiffness when only the chassis and suspension
    # equations are summed) stays where it is
    on = np.diag(Aww) > 1e-12 * max(float(np.diag(Aww).max(initial=0.0)), np.finfo(float).tiny)
    Pw = np.zeros((q, K + 1))
    Pw[on] = np.linalg.lstsq(Aww[np.ix_(on, on)], np.concatenate([Aws[on], bw[on, None]], axis=1), rcond=None)[0]
    D = Ass - Aws.T @ Pw[:, :K]  # the shifts' normal matrix with the parameters' columns projected out
    e = bs - Aws.T @ Pw[:, K]
    determined = np.diag(D) > UNDETERMINED * np.maximum(np.diag(Ass), np.finfo(float).tiny)
    values, std = np.full(K, np.nan), np.full(K, np.nan)
    idx = np.flatnonzero(determined)
    drop = 0.0
    if idx.size:
        Dk = D[np.ix_(idx, idx)]
        values[idx] = np.linalg.solve(Dk, e[idx])
        drop = float(e[idx] @ values[idx])
        rss = rr - float(bw @ Pw[:, K]) - drop
        dof = max(n - int(on.sum()) - idx.size, 1)
        std[idx] = np.sqrt(max(rss, 0.0) / dof * np.clip(np.diag(np.linalg.inv(Dk)), 0.0, None))
    shifts = {s: -Pw[:, k] * values[k] for k, s in enumerate(sums.sources) if determined[k]}
    step = Pw[:, K] - Pw[:, idx] @ values[idx]
    return ShiftEstimate(tuple(sums.sources), values, std, determined, tuple(names), shifts, step, rr, drop)


__all__ = ["ShiftEstimate", "ShiftSums", "estimate_shifts"]
