"""Mimic joints (URDF <mimic>): a joint whose motion is another's, q_s = ratio q_m + offset.

The engine recurses over the tree as if every joint were independent (`Tree.unconstrained`), after setting
each follower's q, qd, qdd from its master's (`follow`). The constraint q = G q_indep + b is linear with a
constant G, so by virtual work the generalized forces of the independent joints are G^T tau: the master's
equation is tau_m + ratio tau_s and the follower has none of its own (`project`, 0 in its column, as a fixed
frame's). The identification model projects the same way, row by row, which keeps W X = tau.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model.tree import ModelError, Tree

Array = np.ndarray


def follow(tree: Tree, q: Array, qd: Array, qdd: Array) -> tuple[Array, Array, Array]:
    """Copies of q, qd, qdd ((N, n) or (n,)) with every follower's column set from its master's."""
    q, qd, qdd = (np.array(a, dtype=float, copy=True) for a in (q, qd, qdd))
    for a, name in ((q, "q"), (qd, "qd"), (qdd, "qdd")):
        if a.ndim not in (1, 2) or a.shape[-1] != tree.n:
            raise ModelError(f"{name} must be (N, {tree.n}) or ({tree.n},) for model {tree.name!r}; got {a.shape}")
    for s, m in tree.mimic.items():
        q[..., s - 1] = m.ratio * q[..., m.master - 1] + m.offset
        qd[..., s - 1] = m.ratio * qd[..., m.master - 1]
        qdd[..., s - 1] = m.ratio * qdd[..., m.master - 1]
    return q, qd, qdd


def rows_needed(tree: Tree, rows: Sequence[int]) -> list[int]:
    """The rows to compute for the equations `rows`: them and the followers of the masters among them."""
    want = set(rows) | {s for s, m in tree.mimic.items() if m.master in set(rows)}
    return sorted(want)


def project(tree: Tree, A: Array, rows: Sequence[int], axis: int) -> Array:
    """A's rows (along `axis`, joint numbers `rows`) with each follower's added into its master's times the
    ratio, and then zero."""
    A = np.array(A, copy=True)
    where = {j: i for i, j in enumerate(rows)}
    moved = np.moveaxis(A, axis, 0)  # a view: writing it writes A
    for s, m in tree.mimic.items():
        if s in where:
            if m.master in where:
                moved[where[m.master]] += m.ratio * moved[where[s]]
            moved[where[s]] = 0.0
    return A
