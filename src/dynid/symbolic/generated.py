"""The engine's regressor signature served by generated code (several times faster on big trees).

`GeneratedRegressor(tree)(q, qd, qdd, wrenches, rows, cols)` returns what
`Model.regressor` returns with wrenches, (W, Q), from the generated identification model of
exactly those rows, columns and wrench sites (generated once, cached on disk by a hash of
the model; tested against the engine and Pinocchio). With numba, the block kernel
(`blocks`: samples side by side in vector registers, about 5 times the generated NumPy's
speed on the car's 14 x 48 model); without, the generated NumPy module. Unlike the engine's,
W (N, rows, cols) and Q (N, rows) are read-only views (samples first) of (entries, N) buffers
that a later call reuses once they are dropped: copy them to modify (`car_identification`
only reads W and copies Q).
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Sequence

import numpy as np

from ..dynamics import Wrench
from ..model.tree import Tree
from .blocks import BlockKernel, aligned_zeros, block_model
from .cache import numpy_module
from .models import WrenchSite
from .numba_backend import have_numba


class _Pool:
    """Output buffers handed out again once no result made on them is alive (fresh pages cost a fault and a
    zero fill each, about as long as the kernel).

    Only the kernel writes into a buffer; the caller's results are views of a root array made over a read-only
    memoryview of it. NumPy collapses a view's base up to that root and no further (its base is no array), so
    every array made from a result refers to the root, and a weak reference to the root says whether any is
    alive; and no view can be made writeable again, so a reused buffer's zero rows (four fifths of the car's
    W) stay zero without clearing."""

    def __init__(self, keep: int = 8) -> None:
        self.keep = keep  # buffers kept (per output and thread of the car pipeline, a few shapes)
        self.items: list[list] = []  # [buffer, weak reference to the root of the results last made on it]
        self.lock = threading.Lock()

    def get(self, size: int, N: int) -> tuple[np.ndarray, np.ndarray]:
        """(buffer, root): a (size, N) buffer for the kernel, zero wherever the kernel does not write, and the
        read-only array over the same memory to make the results from (the buffer is busy while it lives)."""
        with self.lock:
            free = [item for item in self.items if item[1]() is None]
            item = next((it for it in free if it[0].shape == (size, N)), None)
            if item is None:
                item = free[0] if free else [None, None]
                item[0] = aligned_zeros(size, N)
                if not free and len(self.items) < self.keep:
                    self.items.append(item)
            root = np.asarray(memoryview(item[0]).toreadonly())
            item[1] = weakref.ref(root)
            return item[0], root


class GeneratedRegressor:
    """A drop-in for `Model.regressor(q, qd, qdd, wrenches, rows, cols)` on one tree."""

    def __init__(self, tree: Tree) -> None:
        self.tree = tree
        self._pool = _Pool()
        self._kernels: dict[tuple, BlockKernel] = {}  # by rows, columns and sites: no hash of the tree per call

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
        options = {"rows": list(rows), "cols": names, "wrenches": sites}
        q = np.atleast_2d(np.asarray(q, dtype=float))
        N = q.shape[0]
        values = (np.stack([np.broadcast_to(np.asarray(w.values, dtype=float), (N, 6)) for w in wrenches], axis=1)
                  if wrenches else np.zeros((N, 0, 6)))
        key = (tuple(rows), tuple(names), tuple(sites))
        kernel = self._kernels.get(key)
        if kernel is None and have_numba():
            kernel = self._kernels[key] = block_model(self.tree, "regressor", **options)
        if kernel is None or not kernel.available:
            return numpy_module(self.tree, "regressor", **options).evaluate(q, qd, qdd, values)
        return self.evaluate(kernel, q, qd, qdd, values)

    def evaluate(self, kernel: BlockKernel, q, qd, qdd, values) -> tuple[np.ndarray, ...]:
        """(W, Q) of a regressor BlockKernel as read-only (N, ...) views of pooled buffers."""
        N = q.shape[0]
        qd, qdd = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (qd, qdd))
        for name, a in (("qd", qd), ("qdd", qdd)):
            if a.shape != q.shape:
                raise ValueError(f"{name} has shape {a.shape}; q has shape {q.shape}")
        bufs = {k: self._pool.get(size, N) for k, size in kernel.outputs.items()}
        kernel(q, qd, qdd, wrench=values if kernel.n_sites else None, out={k: b for k, (b, _) in bufs.items()})
        shapes = {"out": kernel.shape, "Q": kernel.shape[:1]}
        res = [np.moveaxis(root.reshape(*shapes[k], N), -1, 0) for k, (_, root) in bufs.items()]
        return tuple(res) if len(res) > 1 else (res[0], np.zeros((N, kernel.shape[0])))
