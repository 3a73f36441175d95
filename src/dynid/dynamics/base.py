"""Base parameters by the numeric method (Gautier 1991).

W is sampled at random postures, velocities and accelerations and stacked. A column
that lies in the span of the columns before it is not identifiable on its own: it is
regrouped into them. With the parameters ordered link by link (XX..M, IA, FV, FS,
OFF, K), the kept columns are those of the base set, and the regrouping relations are

    X_B = X_1 + beta X_2,   beta = R11^-1 R12   (W_2 = W_1 beta)

so that W X = W_1 X_B for every X. A column with no effect at all is eliminated.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..model.tree import PRISMATIC, REVOLUTE, ModelError, Tree
from ..resources import budget_text, memory_budget
from .regressor import regressor, resolve_cols, resolve_rows

Array = np.ndarray


@dataclass(frozen=True)
class BaseParameters:
    """The base set of a model's identification model.

    names: the base parameters (each named after the standard parameter it keeps);
    columns: their column indices in the model's parameter vector; expressions: the
    regrouping relation of each, as a named linear combination with rounded
    coefficients; beta: (rank, len(regrouped)) exact coefficients; regrouped: the
    parameters folded into others; eliminated: parameters with no effect.
    """

    names: tuple[str, ...]
    columns: tuple[int, ...]
    expressions: tuple[str, ...]
    beta: Array
    regrouped: tuple[str, ...]
    regrouped_columns: tuple[int, ...]
    eliminated: tuple[str, ...]

    @property
    def rank(self) -> int:
        return len(self.names)

    def values(self, X: Array) -> Array:
        """Base parameter values X_B = X_1 + beta X_2 of a full parameter vector X."""
        X = np.asarray(X, dtype=float)
        return X[list(self.columns)] + self.beta @ X[list(self.regrouped_columns)]

    def __str__(self) -> str:
        lines = [f"{self.rank} base parameters"]
        lines += [f"  {name:>8} = {expr}" for name, expr in zip(self.names, self.expressions, strict=True)]
        if self.eliminated:
            lines.append(f"  no effect (eliminated): {' '.join(self.eliminated)}")
        return "\n".join(lines)


def random_states(tree: Tree, samples: int, seed: int = 0) -> tuple[Array, Array, Array]:
    """Random (q, qd, qdd), (samples, n): angles over the full turn, lengths around 0 +- 1 m; the velocity of a
    joint with knees (Tree.knees) on their scale (standard deviation twice the larger finite knee)."""
    rng = np.random.default_rng(seed)
    n = tree.n
    q = rng.normal(size=(samples, n))
    q[:, tree.sigma[1:] == REVOLUTE] = rng.uniform(-np.pi, np.pi, size=(samples, int((tree.sigma == REVOLUTE).sum())))
    q[:, tree.sigma[1:] == PRISMATIC] *= 0.5
    qd = rng.normal(size=(samples, n))
    for j, knees in tree.knees.items():  # a viscous curve's pieces all visited: velocities on its knees' scale
        finite = [abs(v) for v in knees if np.isfinite(v)]
        if finite:
            qd[:, j - 1] *= 2.0 * max(finite)
    return q, qd, rng.normal(size=(samples, n))


def base_parameters(
    tree: Tree,
    rows: Sequence[int] | None = None,
    cols: Sequence[str | int] | None = None,
    samples: int | None = None,
    seed: int = 0,
    tol: float = 1e-9,
    decimals: int = 6,
) -> BaseParameters:
    """Base parameters of the rows (equations) and columns (parameters) chosen, default all.

    tol: a column is dependent when its part orthogonal to the previous columns is below
    tol times its norm (columns are scaled to unit norm first).
    """
    R, C = resolve_rows(tree, rows), resolve_cols(tree, cols)
    if samples is None:
        samples = max(40, 3 * len(C) // max(1, len(R)) + 20)
    need = 2 * samples * len(R) * len(C) * 8  # W and its scaled copy; the QR works in place on the copy
    if need > memory_budget():
        raise ModelError(
            f"the base-parameter analysis of {tree.name!r} ({len(R)} equations x {len(C)} parameters, {samples} "
            f"random states) needs {need / 2**30:.1f} GiB, more than {budget_text()}; analyse it by "
            "parts (rows=, cols=) or describe a smaller tree")
    q, qd, qdd = random_states(tree, samples, seed)
    # a few dozen random states: the NumPy engine (30 ms on the car's 42 x 442), not the compiled one, whose
    # first compile costs a new user 10 to 30 s (issue 28 item 4) when nothing else of the run needs it; the
    # same numbers to round-off (the engines agree to ~1e-15; the tests hold them to each other)
    W = np.asarray(regressor(tree, q, qd, qdd, rows=R, cols=C, backend="numpy")).reshape(-1, len(C))
    norms = np.linalg.norm(W, axis=0)
    scale = norms.max() if norms.size else 1.0
    zero = norms <= 1e-12 * scale
    Ws = W[:, ~zero] / norms[~zero]
    Rm = scipy.linalg.qr(Ws, mode="r")[0]
    diag = np.zeros(Ws.shape[1])  # beyond the number of rows every column is dependent
    diag[: min(Ws.shape)] = np.abs(np.diag(Rm))
    live = np.flatnonzero(~zero)
    indep = live[diag > tol]
    dep = live[diag <= tol]
    W1, W2 = W[:, indep], W[:, dep]
    beta = np.linalg.lstsq(W1, W2, rcond=None)[0] if dep.size else np.zeros((indep.size, 0))
    beta[np.abs(beta) < 1e-10] = 0.0  # round-off of the sampled solve, not a regrouping
    names = tree.parameter_names
    col_names = [names[C[i]] for i in range(len(C))]
    exprs = []
    for r, i in enumerate(indep):
        terms = [col_names[i]]
        for s, k in enumerate(dep):
            b = float(np.round(beta[r, s], decimals))
            if b != 0.0:
                terms.append(f"{'-' if b < 0 else '+'} {_coef(abs(b))}{col_names[k]}")
        exprs.append(" ".join(terms))
    return BaseParameters(
        names=tuple(col_names[i] for i in indep),
        columns=tuple(C[i] for i in indep),
        expressions=tuple(exprs),
        beta=beta,
        regrouped=tuple(col_names[k] for k in dep),
        regrouped_columns=tuple(C[k] for k in dep),
        eliminated=tuple(col_names[k] for k in np.flatnonzero(zero)),
    )


def _coef(b: float) -> str:
    return "" if b == 1.0 else f"{b:g}*"
