"""Inertia matrix and forward dynamics, from the inverse dynamic model."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..kinematics.forward import joint_array
from ..model.tree import FIXED, ModelError, Tree
from .newton_euler import Wrench, check_parameters, inverse_dynamics, joint_terms, rigid_body_torques

Array = np.ndarray


def inertia_matrix(tree: Tree, q: Array, X: Array | None = None) -> Array:
    """M(q), (N, n, n): column i is the inverse dynamics for qdd = e_i, qd = 0, no gravity.

    Includes the rotor inertias IA and inertial couplings; rows and columns of fixed
    frames are zero. All columns are computed in one batched pass over n*N samples.
    """
    qs, single = joint_array(q, tree, "q")
    X = tree.parameters if X is None else check_parameters(tree, X)
    n, N = qs.shape
    qrep = np.repeat(qs, n, axis=1)  # sample s, column i at s*n + i
    unit = np.tile(np.eye(n), (1, N))
    zero = np.zeros_like(qrep)
    cols = rigid_body_torques(tree, qrep, zero, unit, X, gravity=False)
    cols += joint_terms(tree, X, qrep, zero, unit, inertia_only=True)
    M = cols.reshape(n, N, n).transpose(1, 0, 2)  # M[s, row, col]
    fixed = tree.sigma[1:] == FIXED
    M[:, fixed, :] = 0.0
    M[:, :, fixed] = 0.0
    return M[0] if single else M


def forward_dynamics(
    tree: Tree,
    q: Array,
    qd: Array,
    tau: Array,
    wrenches: Sequence[Wrench] | None = None,
    X: Array | None = None,
) -> Array:
    """Joint accelerations qdd (N, n) produced by the joint forces tau at (q, qd): M qdd = tau - h.

    h is the inverse dynamics at qdd = 0 (gravity, Coriolis, joint terms, wrenches).
    Fixed frames get 0.
    """
    _, single = joint_array(q, tree, "q")
    taus, _ = joint_array(tau, tree, "tau")
    h = inverse_dynamics(tree, q, qd, np.zeros_like(np.asarray(q, dtype=float)), wrenches, X)
    M = inertia_matrix(tree, q, X)
    if single:
        M, h = M[None], h[None]
    move = tree.sigma[1:] != FIXED
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
    return qdd[0] if single else qdd
