"""Systematic uncertainty: the sensors' zero offsets (biases) propagated to the estimates.

The least-squares standard deviations (paper eq. (9)) describe the scatter of white
equation noise. A sensor's zero offset does not average out: it is the same on every
sample of a test, and it moves the estimates by a fixed amount. Given each offset's
standard deviation b_k (a datasheet figure, or the repeatability of the zeroing), the
first-order change of the (weighted) least-squares estimate X̂ = A⁻¹ Wᵀ Ω Y when an offset
of b_k changes W by ΔW and Y by ΔY is

    ΔX_k = A⁻¹ Σ_g [W_gᵀ (ΔY_g − ΔW_g X̂) + ΔW_gᵀ (Y_g − W_g X̂)] / σ_g²,   A = Σ_g W_gᵀ W_g / σ_g²

(σ_g = 1 for OLS), and with independent offsets (zeroed anew before each test) the
covariance of the estimates they cause is C_sys = Σ_k ΔX_k ΔX_kᵀ, to be added to the
statistical one (the GUM's combined standard uncertainty).

Because the bracket is linear in X̂, the caller accumulates its vectors and matrices per
source and group while streaming the data (`BiasAccumulator`), before X̂ is known;
`propagate` finishes once the weights and X̂ are.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class SystematicUncertainty:
    """The estimates' uncertainty from the declared sensor offsets.

    names : the estimated parameters (order of `covariance`).
    covariance : (q, q) Σ_k ΔX_k ΔX_kᵀ.
    shifts : {source: ΔX_k (q,)}, the estimates' change for a one-σ offset of each source
    (a source is a channel of one test: "test name: channel").
    """

    names: tuple[str, ...]
    covariance: np.ndarray
    shifts: dict[str, np.ndarray]

    @property
    def std(self) -> np.ndarray:
        """(q,) standard deviations, order `names`."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def main_source(self, name: str) -> str:
        """The source whose offset moves parameter `name` most ("" without sources)."""
        k = self.names.index(name)
        if not self.shifts:
            return ""
        return max(self.shifts, key=lambda s: abs(self.shifts[s][k]))


@dataclass
class BiasAccumulator:
    """Per source and equation group, the sums of `propagate`'s bracket: Wᵀ ΔY, Wᵀ ΔW, ΔWᵀ Y, ΔWᵀ W
    over the estimated columns (a known parameter's column belongs to the right-hand side).

    columns : positions of the estimated parameters among W's columns; known_columns, known_values :
    the others and their fixed values.
    """

    columns: np.ndarray
    known_columns: np.ndarray
    known_values: np.ndarray
    terms: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)

    def add(self, source: str, W: ArrayLike, Y: ArrayLike, dW: ArrayLike, dY: ArrayLike, groups: ArrayLike,
            scale: float = 1.0, Z: ArrayLike | None = None, dZ: ArrayLike | None = None) -> None:
        """Rows (W, Y and their changes for the source's one-σ offset), grouped; `scale` multiplies
        their sums (a sample of a long test's segments standing for all of it). For an instrumental-variable
        estimate X̂ = A⁻¹ Zᵀ Ω Y, give the instruments Z and their change dZ: the bracket is then
        Zᵀ (ΔY − ΔW X̂) + ΔZᵀ (Y − W X̂) (least squares is the case Z = W)."""
        self.add_many([source], W, Y, [dW], [dY], groups, scale, Z, None if dZ is None else [dZ])

    def add_many(self, sources: Sequence[str], W: ArrayLike, Y: ArrayLike, dW: Sequence[ArrayLike | None],
                 dY: Sequence[ArrayLike], groups: ArrayLike, scale: float = 1.0, Z: ArrayLike | None = None,
                 dZ: Sequence[ArrayLike | None] | None = None) -> None:
        """`add` of several sources on the same rows (their changes dW[k], dY[k], dZ[k] in the order of
        `sources`), the rows split by group once; a dW[k] (and dZ[k]) of None: W (and Z) unchanged."""
        W, Y = np.asarray(W, dtype=float), np.asarray(Y, dtype=float)
        Z = W if Z is None else np.asarray(Z, dtype=float)
        groups = np.asarray(groups)
        kc, kv = self.known_columns, self.known_values
        Y = Y - W[:, kc] @ kv
        split = []
        for g in dict.fromkeys(groups.tolist()):
            rows = np.flatnonzero(groups == g)
            split.append((g, rows, W[rows][:, self.columns], Z[rows][:, self.columns], Y[rows]))
        dZ = [None] * len(sources) if dZ is None else dZ
        for source, dWk, dYk, dZk in zip(sources, dW, dY, dZ, strict=True):
            dYk = np.asarray(dYk, dtype=float)
            if dWk is not None:
                dWk = np.asarray(dWk, dtype=float)
                dYk = dYk - dWk[:, kc] @ kv
            dZk = dWk if dZk is None else np.asarray(dZk, dtype=float)  # least squares: Z = W
            per = self.terms.setdefault(source, {})
            for g, rows, We, Ze, Yg in split:
                # bracket = a - B x with a = Zᵀ ΔY + ΔZᵀ Y, B = Zᵀ ΔW + ΔZᵀ W
                a = Ze.T @ dYk[rows]
                B = np.zeros((len(self.columns), len(self.columns)))
                if dWk is not None:
                    B = B + Ze.T @ dWk[rows][:, self.columns]
                if dZk is not None:
                    dZe = dZk[rows][:, self.columns]
                    a, B = a + dZe.T @ Yg, B + dZe.T @ We
                a, B = scale * a, scale * B
                if g in per:
                    a, B = a + per[g][0], B + per[g][1]
                per[g] = (a, B)

    def merge(self, other: BiasAccumulator) -> BiasAccumulator:
        """A new accumulator with both one's sums (same columns): segments reduced apart, combined."""
        terms = {s: dict(per) for s, per in self.terms.items()}
        for source, per in other.terms.items():
            mine = terms.setdefault(source, {})
            for g, (a, B) in per.items():
                mine[g] = (a + mine[g][0], B + mine[g][1]) if g in mine else (a, B)
        return BiasAccumulator(self.columns, self.known_columns, self.known_values, terms)


def propagate(
    normal: np.ndarray,
    accumulator: BiasAccumulator,
    x: ArrayLike,
    names: tuple[str, ...],
    group_sigmas: Mapping[str, float] | None = None,
) -> SystematicUncertainty:
    """ΔX_k for every source and their covariance.

    normal : (q, q) A of the weighted system solved (Σ Zᵀ W / σ² for instrumental variables);
    x : (q,) the estimates; group_sigmas : the weights σ_g (None: OLS, all 1).
    """
    x = np.asarray(x, dtype=float)
    shifts = {}
    for source, per in accumulator.terms.items():
        g = sum((a - B @ x) / (1.0 if group_sigmas is None else group_sigmas[grp]) ** 2
                for grp, (a, B) in per.items())
        shifts[source] = np.linalg.solve(normal, g)
    q = len(names)
    cov = sum((np.outer(d, d) for d in shifts.values()), np.zeros((q, q)))
    return SystematicUncertainty(tuple(names), cov, shifts)
