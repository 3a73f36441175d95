"""Instrumental variables: Gautier's IDIM-IV on the weighted, grouped system.

Least squares on Y = W X + ρ is biased when W itself is built from noisy measurements
(errors in the variables: the noise in a damper's clearance rate shrinks its dry friction
and inflates its damping). The instrumental-variable estimate replaces Wᵀ in the normal
equations by Zᵀ, with Z an instrument matrix of W's shape that is correlated with W's
noise-free part and not with the noise: in IDIM-IV, Z is W computed on the trajectory of a
simulation of the model with the previous estimate, driven by the measured inputs. With the
equation groups weighted as in WLS (1/σ_g, paper eq. (9)):

    X̂ = A⁻¹ Σ_g Z_gᵀ Y_g / σ_g²,    A = Σ_g Z_gᵀ W_g / σ_g²,
    C = s² A⁻¹ (Σ_g Z_gᵀ Z_g / σ_g²) A⁻ᵀ,    s² = Σ_g ‖Y_g − W_g X̂‖² / σ_g² / (n − q),

the usual asymptotic covariance of an IV estimator (with Z = W it is exactly the WLS one).
σ_g is the IV residual's own, ‖Y_g − W_g X̂‖ / √(n_g − p_g), iterated with X̂.

The sums are accumulated group by group while streaming (`InstrumentSums`); the residual
norms come from the least-squares accumulator of the same rows (`StreamingLS`), so W is never
held whole.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ._checks import as_groups, as_matrix, as_vector
from .errors import IdentificationError


@dataclass
class InstrumentSums:
    """Per equation group, Zᵀ W, Zᵀ Y and Zᵀ Z over the estimated columns (a known parameter's column
    belongs to the right-hand side, for W; an instrument has no use for it).

    columns : positions of the estimated parameters among W's columns; known_columns, known_values :
    the others and their fixed values.
    """

    columns: np.ndarray
    known_columns: np.ndarray
    known_values: np.ndarray
    terms: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)

    def add(self, W: ArrayLike, Y: ArrayLike, Z: ArrayLike, groups: ArrayLike) -> None:
        """Rows of the system (W, Y) and their instruments Z (same shape as W), grouped."""
        W = as_matrix(W, what="W chunk")
        Z = as_matrix(Z, what="instrument chunk Z")
        if Z.shape != W.shape:
            raise IdentificationError(f"instruments Z have shape {Z.shape}, W {W.shape}: one instrument per entry")
        y = as_vector(Y, W.shape[0], "Y chunk")
        g = as_groups(groups, W.shape[0])
        y = y - W[:, self.known_columns] @ self.known_values
        We, Ze = W[:, self.columns], Z[:, self.columns]
        for name in dict.fromkeys(g.tolist()):
            r = g == name
            zw, zy, zz = Ze[r].T @ We[r], Ze[r].T @ y[r], Ze[r].T @ Ze[r]
            if name in self.terms:
                a, b, c = self.terms[name]
                zw, zy, zz = zw + a, zy + b, zz + c
            self.terms[name] = (zw, zy, zz)
            self.rows[name] = self.rows.get(name, 0) + int(r.sum())

    def merge(self, other: InstrumentSums) -> InstrumentSums:
        """A new accumulator with both one's sums (same columns): segments reduced apart, combined."""
        terms = dict(self.terms)
        for g, (zw, zy, zz) in other.terms.items():
            terms[g] = (zw + terms[g][0], zy + terms[g][1], zz + terms[g][2]) if g in terms else (zw, zy, zz)
        rows = {g: self.rows.get(g, 0) + other.rows.get(g, 0) for g in dict.fromkeys([*self.rows, *other.rows])}
        return InstrumentSums(self.columns, self.known_columns, self.known_values, terms, rows)

    def normal(self, sigmas: dict[str, float]) -> np.ndarray:
        """A = Σ_g Z_gᵀ W_g / σ_g² (the matrix the estimate and the offsets' propagation solve with)."""
        return sum((zw / sigmas[g] ** 2 for g, (zw, _, _) in self.terms.items()),
                   np.zeros((len(self.columns),) * 2))

    def solve(self, sigmas: dict[str, float], names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X̂, A⁻¹ and S = Σ Zᵀ Z / σ² for the weights σ_g (every group of the sums must have one)."""
        missing = [g for g in self.terms if g not in sigmas]
        if missing:
            raise IdentificationError(f"no noise level for equation group(s) {missing} of the instruments")
        q = len(self.columns)
        A, b, S = np.zeros((q, q)), np.zeros(q), np.zeros((q, q))
        for g, (zw, zy, zz) in self.terms.items():
            w = 1.0 / sigmas[g] ** 2
            A += w * zw
            b += w * zy
            S += w * zz
        # rows scaled by the instruments' norms, columns by the scaled A's: A mixes units (kg, N/m, N.s/m, ...)
        dz = 1.0 / np.sqrt(np.where(np.diag(S) > 0, np.diag(S), 1.0))
        n = np.linalg.norm(dz[:, None] * A, axis=0)
        dw = 1.0 / np.where(n > 0, n, 1.0)
        As = dz[:, None] * A * dw[None, :]
        sv = np.linalg.svd(As, compute_uv=False)
        if sv[-1] <= 1e3 * q * np.finfo(float).eps * sv[0]:
            k = int(np.argmin(n))
            raise IdentificationError(
                f"the instruments do not identify every parameter (Zᵀ W singular, condition "
                f"{sv[0] / max(sv[-1], 1e-300):.3g}); the weakest is {names[k]!r}: use method = \"wls\", or add "
                "tests that excite it", parameters=[names[k]])
        Ainv = dw[:, None] * np.linalg.inv(As) * dz[None, :]
        return Ainv @ b, Ainv, S


def iv_covariance(Ainv: np.ndarray, S: np.ndarray, s2: float) -> np.ndarray:
    """s² A⁻¹ S A⁻ᵀ (see the module doc)."""
    C = s2 * Ainv @ S @ Ainv.T
    return 0.5 * (C + C.T)
