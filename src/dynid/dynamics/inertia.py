"""Inertia matrix and forward dynamics, from the inverse dynamic model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..kinematics.forward import joint_array
from ..model.tree import FIXED, ModelError, Tree
from .mimic import follow, project
from .newton_euler import (
    Wrench,
    check_parameters,
    inverse_dynamics,
    joint_terms,
    resolve_backend,
    rigid_body_torques,
)

Array = np.ndarray


def inertia_matrix(tree: Tree, q: Array, X: Array | None = None, *, backend: str | None = None) -> Array:
    """M(q), (N, n, n): column i is the inverse dynamics for qdd = e_i, qd = 0, no gravity.

    Includes the rotor inertias IA and inertial couplings; rows and columns of fixed
    frames are zero. All columns are computed in one batched pass over n*N samples.
    backend: "numba", "numpy" or None (see newton_euler.resolve_backend).
    """
    X = tree.parameters if X is None else check_parameters(tree, X)
    if tree.mimic:  # G^T M G on the followed posture: a follower's row and column are 0, its master's carry it
        qf = follow(tree, q, q, q)[0]
        M = inertia_matrix(tree.unconstrained, qf, X, backend=backend)
        every = range(1, tree.n + 1)
        return project(tree, project(tree, M, every, axis=-1), every, axis=-2)
    if resolve_backend(backend) == "numba":
        M, single = _compiled_columns(tree, q, X)
    else:
        M, single = _numpy_columns(tree, q, X)
    fixed = tree.sigma[1:] == FIXED
    M[:, fixed, :] = 0.0
    M[:, :, fixed] = 0.0
    return M[0] if single else M


def _numpy_columns(tree: Tree, q: Array, X: Array) -> tuple[Array, bool]:
    qs, single = joint_array(q, tree, "q")
    n, N = qs.shape
    qrep = np.repeat(qs, n, axis=1)  # sample s, column i at s*n + i
    unit = np.tile(np.eye(n), (1, N))
    zero = np.zeros_like(qrep)
    cols = rigid_body_torques(tree, qrep, zero, unit, X, gravity=False)
    cols += joint_terms(tree, X, qrep, zero, unit, inertia_only=True)
    return cols.reshape(n, N, n).transpose(1, 0, 2), single  # M[s, row, col]


def _compiled_columns(tree: Tree, q: Array, X: Array) -> tuple[Array, bool]:
    from . import compiled  # start-up: numba 0.5 s

    qs, single = compiled.joint_rows(q, tree, "q")
    N, n = qs.shape
    qrep = np.repeat(qs, n, axis=0)  # sample s, column i at s*n + i
    unit = np.tile(np.eye(n), (N, 1))
    tau = compiled.inverse_dynamics(tree, qrep, np.zeros_like(qrep), unit, X, [], gravity=False, inertia_only=True)
    return tau.reshape(N, n, n).transpose(0, 2, 1), single  # tau[s*n + col, row]


def forward_dynamics(
    tree: Tree,
    q: Array,
    qd: Array,
    tau: Array,
    wrenches: Sequence[Wrench] | None = None,
    X: Array | None = None,
    *,
    backend: str | None = None,
) -> Array:
    """Joint accelerations qdd (N, n) produced by the joint forces tau at (q, qd): M qdd = tau - h.

    h is the inverse dynamics at qdd = 0 (gravity, Coriolis, joint terms, wrenches).
    Fixed frames get 0.
    """
    _, single = joint_array(q, tree, "q")
    taus, _ = joint_array(tau, tree, "tau")
    h = inverse_dynamics(tree, q, qd, np.zeros_like(np.asarray(q, dtype=float)), wrenches, X, backend=backend)
    M = inertia_matrix(tree, q, X, backend=backend)
    if single:
        M, h = M[None], h[None]
    move = np.isin(np.arange(1, tree.n + 1), tree.equations)  # not fixed frames, nor mimic joints
    Mm = M[:, move][:, :, move]
    rhs = (taus.T - h)[:, move]
    try:
        sol = np.linalg.solve(Mm, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        cond = np.linalg.cond(Mm)
        s = int(np.argmax(~np.isfinite(cond) | (cond > 1e14)))
        raise ModelError(
            f"the inertia matrix is singular at sample {s} (a massless chain or a singular posture): "
            "forward dynamics is undefined there"
        ) from None
    qdd = np.zeros((Mm.shape[0], tree.n))
    qdd[:, move] = sol
    for j, m in tree.mimic.items():
        qdd[:, j - 1] = m.ratio * qdd[:, m.master - 1]
    return qdd[0] if single else qdd
