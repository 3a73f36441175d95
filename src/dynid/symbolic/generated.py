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

import sys
import threading
from collections.abc import Sequence

import numpy as np

from ..dynamics import Wrench
from ..model.tree import Tree
from .blocks import BlockKernel, aligned_zeros, block_model
from .cache import numpy_module
from .models import WrenchSite
from .numba_backend import have_numba


class _Pool:
    """Output buffers handed out again once nothing refers to them (fresh pages cost a fault and a zero
    fill each, about as long as the kernel). Results are read-only views, so a reused buffer's zero rows
    (four fifths of the car's W) need no clearing unless someone made its memory writeable since.

    A buffer is an `aligned_zeros` view; the views made from it refer to the array that owns the memory
    (NumPy collapses bases): it is free when neither it (being filled) nor its owner (a result alive) has
    a reference from outside the pool."""

    def __init__(self, keep: int = 8) -> None:
        self.keep = keep  # buffers kept (per output and thread of the car pipeline, a few shapes)
        self.items: list[tuple[np.ndarray, np.ndarray]] = []  # (owner, buffer)
        self.lock = threading.Lock()
        probe = aligned_zeros(1, 1)
        items = [(probe.base, probe)]
        del probe
        self.free_counts = (sys.getrefcount(items[0][0]), sys.getrefcount(items[0][1]))  # only the pool refers

    def get(self, size: int, N: int, zero_rows: Sequence[tuple[int, int]]) -> np.ndarray:
        with self.lock:
            free = [i for i in range(len(self.items))
                    if (sys.getrefcount(self.items[i][0]), sys.getrefcount(self.items[i][1])) == self.free_counts]
            for i in free:
                owner, buf = self.items[i]
                if buf.shape == (size, N):
                    if owner.flags.writeable:  # someone made it writeable: its zero rows may have been written
                        for a, b in zero_rows:
                            buf[a:b] = 0.0
                    owner.flags.writeable = True
                    buf.flags.writeable = True
                    return buf
            buf = aligned_zeros(size, N)
            if free:
                self.items[free[0]] = (buf.base, buf)
            elif len(self.items) < self.keep:
                self.items.append((buf.base, buf))
            return buf

    @staticmethod
    def seal(buf: np.ndarray) -> None:
        """Read-only, the owner of its memory too (so that no view of it can be made writeable again)."""
        buf.flags.writeable = False
        buf.base.flags.writeable = False


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
        out = {k: self._pool.get(size, N, kernel.zero_rows[k]) for k, size in kernel.outputs.items()}
        kernel(q, qd, qdd, wrench=values if kernel.n_sites else None, out=out)
        shapes = {"out": kernel.shape, "Q": kernel.shape[:1]}
        res = []
        for k, buf in out.items():
            self._pool.seal(buf)
            res.append(np.moveaxis(buf.reshape(*shapes[k], N), -1, 0))
        return tuple(res) if len(res) > 1 else (res[0], np.zeros((N, kernel.shape[0])))
