"""Batched geometric and kinematic models of a modified-DH tree.

Internally samples run along the LAST axis (a vector is (3, N), a rotation is stored
by columns as (3, 3, N)) so that every elementary operation streams over contiguous
memory; the public functions take and return arrays with samples FIRST, (N, ...).

Everything is expressed in the orientation of frame 0, but positions enter only as
differences P_j - P_a(j) computed from the local geometry: a vehicle kilometres from
the origin keeps the precision of one at the origin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model.tree import FIXED, PRISMATIC, REVOLUTE, ModelError, Tree

Array = np.ndarray


def cross(a: Array, b: Array) -> Array:
    """Cross product of (3, ...) arrays along axis 0."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


def dot(a: Array, b: Array) -> Array:
    """Dot product of (3, ...) arrays along axis 0."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def to_world(Rc: Array, v: Array) -> Array:
    """R v for R stored by columns (3, 3, N) and v (3, N) or (3,)."""
    if v.ndim == 1:
        return np.tensordot(v, Rc, axes=1)
    return Rc[0] * v[0] + Rc[1] * v[1] + Rc[2] * v[2]


def to_local(Rc: Array, v: Array) -> Array:
    """R^T v for R stored by columns (3, 3, N) and v (3, N)."""
    return np.stack([dot(Rc[0], v), dot(Rc[1], v), dot(Rc[2], v)])


def joint_array(x: object, tree: Tree, name: str) -> tuple[Array, bool]:
    """Check a joint array (N, n) or (n,) and return it samples-last (n, N), and whether it was one sample."""
    a = np.asarray(x, dtype=float)
    single = a.ndim == 1
    if single:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != tree.n:
        raise ModelError(
            f"{name} must have shape (N, {tree.n}) or ({tree.n},) for model {tree.name!r} "
            f"(one column per frame 1..{tree.n}); got {np.shape(x)}"
        )
    bad = ~np.isfinite(a)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ModelError(f"{name} has a non-finite value ({a[i, j]}) at sample {i}, frame {j + 1}")
    return np.ascontiguousarray(a.T), single


@dataclass
class KinematicState:
    """Per-frame quantities in frame-0 orientation, samples last; lists indexed by frame 0..n.

    Rc[j]: rotation 0R_j by columns (x_j, y_j, z_j), (3, 3, N); P[j]: origin (3, N);
    dP[j]: P_j - P_a(j) (3, N); w, dw: angular velocity, acceleration; v, dv: velocity and
    acceleration of O_j (dv includes -g when gravity is on). None where not computed.
    """

    Rc: list[Array]
    P: list[Array]
    dP: list[Array]
    w: list[Array] | None = None
    dw: list[Array] | None = None
    v: list[Array] | None = None
    dv: list[Array] | None = None

    @property
    def N(self) -> int:
        return self.P[0].shape[-1]


def forward_kinematics(
    tree: Tree,
    q: Array,
    qd: Array | None = None,
    qdd: Array | None = None,
    *,
    gravity: bool = True,
    velocities: bool = False,
    frames: Sequence[int] | None = None,
) -> KinematicState:
    """Forward recursion over the tree; q, qd, qdd samples-last (n, N) as from `joint_array`.

    With qdd, angular and linear accelerations are computed (dv0 = -g when gravity);
    velocities=True also computes v (the linear velocity of each origin).
    frames: compute only these frames and their ancestors (others stay None).
    """
    n, N = tree.n, q.shape[1]
    C, U = tree.constant_rotation, tree.constant_offset
    todo = np.zeros(n + 1, dtype=bool)
    for k in range(1, n + 1) if frames is None else frames:
        todo[tree.ancestors[k]] = True
    eye = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, N))
    zero = np.zeros((3, N))
    Rc: list = [eye] + [None] * n
    P: list = [zero] + [None] * n
    dP: list = [zero] + [None] * n
    acc = qdd is not None
    w = dw = v = dv = None
    if qd is not None:
        w = [zero] + [None] * n
        v = [zero] + [None] * n if velocities else None
    if acc:
        dw = [zero] + [None] * n
        g = np.asarray(tree.gravity, dtype=float)
        dv = [np.broadcast_to((-g if gravity else 0.0 * g)[:, None], (3, N))] + [None] * n

    for f in tree.frames:
        j, a = f.j, f.ant
        if not todo[j]:
            continue
        Ra = Rc[a]
        D = np.tensordot(C[j], Ra, axes=(0, 0))  # D[c] = sum_k C[k, c] Ra[k]: columns of Ra C_j
        if f.sigma == REVOLUTE:
            th = f.theta + q[j - 1]
            c, s = np.cos(th), np.sin(th)
        else:
            c, s = np.cos(f.theta), np.sin(f.theta)
        Rj = np.empty((3, 3, N))
        Rj[0] = c * D[0] + s * D[1]
        Rj[1] = c * D[1] - s * D[0]
        Rj[2] = D[2]
        z = Rj[2]
        r = f.r + q[j - 1] if f.sigma == PRISMATIC else f.r
        d = np.tensordot(U[j], Ra, axes=1) + r * z
        Rc[j], dP[j], P[j] = Rj, d, P[a] + d
        if w is None:
            continue
        wa = w[a]
        if f.sigma == REVOLUTE:
            w[j] = wa + qd[j - 1] * z
        else:
            w[j] = wa
        if v is not None:
            v[j] = v[a] + cross(wa, d) + (qd[j - 1] * z if f.sigma == PRISMATIC else 0.0)
        if not acc:
            continue
        dwa = dw[a]
        dvj = dv[a] + cross(dwa, d) + cross(wa, cross(wa, d))
        if f.sigma == REVOLUTE:
            dw[j] = dwa + qdd[j - 1] * z + qd[j - 1] * cross(wa, z)
        else:
            dw[j] = dwa
            if f.sigma == PRISMATIC:
                dvj += qdd[j - 1] * z + 2.0 * qd[j - 1] * cross(wa, z)
        dv[j] = dvj
    return KinematicState(Rc, P, dP, w, dw, v, dv)


def transforms(tree: Tree, q: Array) -> Array:
    """Homogeneous transforms 0T_j of all frames, (N, n+1, 4, 4) (or (n+1, 4, 4) for one sample)."""
    qs, single = joint_array(q, tree, "q")
    st = forward_kinematics(tree, qs)
    N = qs.shape[1]
    T = np.zeros((N, tree.n + 1, 4, 4))
    T[:, :, 3, 3] = 1.0
    for j in range(tree.n + 1):
        T[:, j, :3, :3] = np.moveaxis(np.broadcast_to(st.Rc[j], (3, 3, N)), -1, 0).transpose(0, 2, 1)
        T[:, j, :3, 3] = np.broadcast_to(st.P[j], (3, N)).T
    return T[0] if single else T


def _point(st: KinematicState, frame: int, point: Sequence[float] | None) -> tuple[Array, Array]:
    """World-orientation offset R_k p of a point fixed in frame k, and its position."""
    if point is None:
        return np.zeros((3, 1)), st.P[frame]
    rp = np.tensordot(np.asarray(point, dtype=float), st.Rc[frame], axes=1)
    return rp, st.P[frame] + rp


def _check_frame(tree: Tree, frame: int, what: str = "frame") -> None:
    if not 0 <= frame <= tree.n:
        raise ModelError(f"{what} {frame} does not exist in model {tree.name!r} (frames 0..{tree.n})")


def jacobian(
    tree: Tree, q: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0
) -> Array:
    """Geometric Jacobian of a point fixed in `frame` (default its origin), (N, 6, n).

    Rows: linear velocity of the point, then angular velocity of the frame, with
    components in frame `expressed_in` (default 0). Column j is the effect of qd_j.
    """
    _check_frame(tree, frame)
    _check_frame(tree, expressed_in, "expressed_in frame")
    qs, single = joint_array(q, tree, "q")
    st = forward_kinematics(tree, qs, frames=[frame, expressed_in])
    N = qs.shape[1]
    _, Pp = _point(st, frame, point)
    J = np.zeros((6, tree.n, N))
    for j in tree.ancestors[frame]:
        z = st.Rc[j][2]
        if tree.sigma[j] == REVOLUTE:
            J[:3, j - 1] = cross(z, Pp - st.P[j])
            J[3:, j - 1] = z
        elif tree.sigma[j] == PRISMATIC:
            J[:3, j - 1] = z
    if expressed_in != 0:
        Re = st.Rc[expressed_in]
        J = np.concatenate([_local_cols(Re, J[:3]), _local_cols(Re, J[3:])])
    out = np.moveaxis(J, -1, 0)
    return out[0] if single else out


def _local_cols(Rc: Array, V: Array) -> Array:
    """R^T applied to each column of V (3, n, N)."""
    return np.stack([(Rc[c][:, None, :] * V).sum(axis=0) for c in range(3)])


def jdot_qdot(
    tree: Tree, q: Array, qd: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0
) -> Array:
    """J-dot times qd for the point of `jacobian`, (N, 6): its acceleration when qdd = 0, without gravity."""
    _check_frame(tree, frame)
    _check_frame(tree, expressed_in, "expressed_in frame")
    qs, single = joint_array(q, tree, "q")
    qds, _ = joint_array(qd, tree, "qd")
    if qds.shape != qs.shape:
        raise ModelError(f"q and qd must have the same shape; got {np.shape(q)} and {np.shape(qd)}")
    st = forward_kinematics(tree, qs, qds, np.zeros_like(qs), gravity=False, frames=[frame, expressed_in])
    rp, _ = _point(st, frame, point)
    w, dw = st.w[frame], st.dw[frame]
    a = st.dv[frame] + cross(dw, rp) + cross(w, cross(w, rp))
    out = np.concatenate([np.broadcast_to(a, (3, qs.shape[1])), np.broadcast_to(dw, (3, qs.shape[1]))])
    if expressed_in != 0:
        Re = st.Rc[expressed_in]
        out = np.concatenate([to_local(Re, out[:3]), to_local(Re, out[3:])])
    out = out.T
    return out[0] if single else out


__all__ = [
    "FIXED", "KinematicState", "cross", "dot", "forward_kinematics", "jacobian", "jdot_qdot",
    "joint_array", "to_local", "to_world", "transforms",
]
