"""The engine's regressor signature served by generated NumPy code (several times faster on big trees).

`GeneratedRegressor(tree)(q, qd, qdd, wrenches, rows, cols)` returns what
`Model.regressor` returns with wrenches, (W, Q), from the generated identification model of
exactly those rows, columns and wrench sites (generated once, cached on disk by a hash of
the model; tested against the engine to 1e-10). Unlike the engine's, W (N, rows, cols) and
Q (N, rows) are read-only views (samples first) of (entries, N) buffers that a later call
reuses once they are dropped: copy them to modify (`car_identification` only reads W and
copies Q).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..dynamics import Wrench
from ..model.tree import Tree
from .cache import numpy_module
from .models import WrenchSite


class GeneratedRegressor:
    """A drop-in for `Model.regressor(q, qd, qdd, wrenches, rows, cols)` on one tree."""

    def __init__(self, tree: Tree) -> None:
        self.tree = tree

    def __call__(
        self,
        q: np.ndarray,
        qd: np.ndarray,
        qdd: np.ndarray,
        wrenches: Sequence[Wrench],
        rows: Sequence[int],
        cols: Sequence[str | int],
    ) -> tuple[np.ndarray, np.ndarray]:
        names = [c if isinstance(c, str) else self.tree.parameter_names[c] for c in cols]
        sites = [WrenchSite(w.link, tuple(float(x) for x in w.point), w.frame) for w in wrenches]
        mod = numpy_module(self.tree, "regressor", rows=list(rows), cols=names, wrenches=sites)
        q = np.atleast_2d(np.asarray(q, dtype=float))
        N = q.shape[0]
        values = np.stack([np.broadcast_to(np.asarray(w.values, dtype=float), (N, 6)) for w in wrenches], axis=1)
        return mod.evaluate(q, qd, qdd, values)
