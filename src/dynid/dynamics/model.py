"""`Model`: a tree description together with the algorithms that run on it.

The algorithms are free functions over (tree, arrays) in the kinematics and dynamics
modules; this class only binds them to one tree so that a user writes
`model.inverse_dynamics(q, qd, qdd)`. Arrays are samples first: (N, n), or (n,) for
one sample; q has one column per frame 1..n (fixed frames' columns are ignored).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..kinematics import forward, motion
from ..model import EXAMPLES, example_path, load_tree
from ..model.tree import Tree
from . import base as _base
from . import inertia, newton_euler
from . import regressor as _regressor
from .mimic import follow, project
from .newton_euler import Wrench

Array = np.ndarray


class Model:
    """A multibody tree in modified DH notation with its numeric models."""

    def __init__(self, tree: Tree) -> None:
        self.tree = tree

    def __repr__(self) -> str:
        return f"Model({self.tree.name!r}, {self.tree.n} frames, {self.tree.p} parameters)"

    # description shortcuts
    @property
    def name(self) -> str:
        return self.tree.name

    @property
    def n(self) -> int:
        return self.tree.n

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return self.tree.parameter_names

    @property
    def parameters(self) -> Array:
        return self.tree.parameters

    def with_values(self, values: dict[str, float]) -> Model:
        return Model(self.tree.with_values(values))

    # geometric and kinematic models
    def transforms(self, q: Array) -> Array:
        """0T_j of all frames, (N, n+1, 4, 4); a mimic joint's column of q is ignored (it follows its master)."""
        if self.tree.mimic:
            q = follow(self.tree, q, q, q)[0]
        return forward.transforms(self.tree, q)

    def jacobian(self, q: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0) -> Array:
        """Jacobian (N, 6, n) of a point fixed in `frame`: rows (linear, angular). A mimic joint's column is 0 and
        its master's carries both (J G for the constraint qd_mimic = ratio qd_master)."""
        if not self.tree.mimic:
            return forward.jacobian(self.tree, q, frame, point, expressed_in)
        J = forward.jacobian(self.tree.unconstrained, follow(self.tree, q, q, q)[0], frame, point, expressed_in)
        return project(self.tree, J, range(1, self.n + 1), axis=-1)

    def jdot_qdot(
        self, q: Array, qd: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0
    ) -> Array:
        """J-dot qd (N, 6) of the same point (a mimic joint's columns of q and qd follow its master)."""
        if self.tree.mimic:
            q, qd, _ = follow(self.tree, q, qd, qd)
        return motion.jdot_qdot(self.tree.unconstrained, q, qd, frame, point, expressed_in)

    # dynamic models; backend: "numba" (compiled, the default when numba is installed) or "numpy"
    # (the batched reference engine), see dynamics.newton_euler.resolve_backend
    def inverse_dynamics(
        self,
        q: Array,
        qd: Array,
        qdd: Array,
        wrenches: Sequence[Wrench] | None = None,
        X: Array | None = None,
        *,
        backend: str | None = None,
    ) -> Array:
        """Joint forces tau (N, n); X defaults to the model's parameter values."""
        return newton_euler.inverse_dynamics(self.tree, q, qd, qdd, wrenches, X, backend=backend)

    def regressor(
        self,
        q: Array,
        qd: Array,
        qdd: Array,
        wrenches: Sequence[Wrench] | None = None,
        rows: Sequence[int] | None = None,
        cols: Sequence[str | int] | None = None,
        *,
        out: Array | None = None,
        backend: str | None = None,
    ) -> Array | tuple[Array, Array]:
        """W (N, rows, cols) with W X = tau; with wrenches, (W, Q) and W X = tau + Q.

        out: a preallocated zeroed float64 C-contiguous array of W's shape, filled and returned;
        only entries that can be non-zero are written, so it can be reused for the same rows
        and columns without clearing it (see dynamics.regressor.regressor).
        """
        return _regressor.regressor(self.tree, q, qd, qdd, wrenches, rows, cols, out=out, backend=backend)

    def inertia_matrix(self, q: Array, X: Array | None = None, *, backend: str | None = None) -> Array:
        """M(q), (N, n, n)."""
        return inertia.inertia_matrix(self.tree, q, X, backend=backend)

    def forward_dynamics(
        self,
        q: Array,
        qd: Array,
        tau: Array,
        wrenches: Sequence[Wrench] | None = None,
        X: Array | None = None,
        *,
        backend: str | None = None,
    ) -> Array:
        """qdd (N, n) from the joint forces tau."""
        return inertia.forward_dynamics(self.tree, q, qd, tau, wrenches, X, backend=backend)

    def base_parameters(
        self, rows: Sequence[int] | None = None, cols: Sequence[str | int] | None = None, seed: int = 0
    ) -> _base.BaseParameters:
        """Base parameters with regrouping relations (numeric QR on random samples)."""
        return _base.base_parameters(self.tree, rows, cols, seed=seed)


def load_model(path: str | os.PathLike[str]) -> Model:
    """Load a model file (TOML), or a shipped example by name (puma560, tx40, floating_tree)."""
    if isinstance(path, str) and path in EXAMPLES and not Path(path).exists():
        path = example_path(path)
    return Model(load_tree(path))
