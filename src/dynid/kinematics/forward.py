"""Batched geometric and kinematic models of a modified-DH tree.

Internally samples run along the LAST axis (a vector is (3, N), a rotation is stored
by columns as (3, 3, N)) so that every elementary operation streams over contiguous
memory; the public functions take and return arrays with samples FIRST, (N, ...).

Everything is expressed in the orientation of frame 0, but positions enter only as
differences P_j - P_a(j) computed from the local geometry: a vehicle kilometres from
the origin keeps the precision of one at the origin.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..model.tree import PRISMATIC, REVOLUTE, ModelError, Tree
from .per_tree import PerTree

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


def combine(coeffs: Sequence[float], cols: Sequence[Array]) -> Array | None:
    """sum_c coeffs[c] * cols[c] for constant coefficients, skipping zeros; None if all are zero."""
    out = None
    for k, x in zip(coeffs, cols, strict=True):
        if k == 0.0:
            continue
        term = x if k == 1.0 else -x if k == -1.0 else k * x
        out = term if out is None else out + term
    return out


def to_world(Rc: Sequence[Array], v: Array) -> Array:
    """R v for a rotation given by its columns (x, y, z), each (3, N), and v (3, N) or (3,)."""
    if v.ndim == 1:
        out = combine(v, Rc)
        return np.zeros_like(Rc[0]) if out is None else out
    return Rc[0] * v[0] + Rc[1] * v[1] + Rc[2] * v[2]


def to_local(Rc: Sequence[Array], v: Array) -> Array:
    """R^T v for a rotation given by its columns and v (3, N)."""
    return np.stack([dot(Rc[0], v), dot(Rc[1], v), dot(Rc[2], v)])


def _clean(M: Array) -> Array:
    """Round entries within 1e-12 of 0 or +-1: cos(pi/2) is 6e-17 in floating point, 0 in the geometry."""
    M = M.copy()
    for v in (0.0, 1.0, -1.0):
        M[np.abs(M - v) < 1e-12] = v
    return M


def _signed_permutation(M: Array) -> tuple[tuple[int, float], ...] | None:
    """For M with one +-1 per column and zeros elsewhere: column c of A M is sign_c * A[:, k_c]."""
    if not (np.isin(M, (0.0, 1.0, -1.0)).all() and (np.abs(M).sum(axis=0) == 1).all()):
        return None
    return tuple((int(np.flatnonzero(M[:, c])[0]), float(M[:, c].sum())) for c in range(3))


def frame_plan(tree: Tree) -> list:
    """Per-frame constants (E_j, its signed permutation or None, u_j), computed once per tree (`PerTree`).

    E_j = Rot(z, gamma) Rot(x, alpha) for a revolute frame, times Rot(z, theta) otherwise;
    u_j = Rot(z, gamma) (d, 0, b), the origin of frame j in a(j) when r = 0.
    """
    return _FRAME_PLANS(tree)


def _frame_plan(tree: Tree) -> list:
    plan: list = [None]
    for f in tree.frames:
        C = _clean(tree.constant_rotation[f.j])
        E = C if f.sigma == REVOLUTE else _clean(C @ np.array(
            [[np.cos(f.theta), -np.sin(f.theta), 0.0], [np.sin(f.theta), np.cos(f.theta), 0.0], [0, 0, 1.0]]))
        u = _clean(tree.constant_offset[f.j][None])[0]
        plan.append((E, _signed_permutation(E), u))
    return plan


_FRAME_PLANS = PerTree(_frame_plan)


def _columns(Ra: Sequence[Array], E: Array, perm) -> list[Array]:
    """Columns of Ra E for a constant E."""
    if perm is not None:
        return [Ra[k] if sgn > 0 else -Ra[k] for k, sgn in perm]
    return [combine(E[:, c], Ra) for c in range(3)]


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
    """Per-frame poses in frame-0 orientation, samples last; lists indexed by frame 0..n.

    Rc[j]: rotation 0R_j as its columns (x_j, y_j, z_j), each (3, N); P[j]: origin (3, N);
    dP[j]: P_j - P_a(j) (3, N), computed from the local geometry. None where not computed.
    """

    Rc: list
    P: list
    dP: list

    @property
    def N(self) -> int:
        return self.P[0].shape[-1]


def needed_frames(tree: Tree, frames: Sequence[int]) -> Array:
    """Mask of the frames on the paths from the base to the given frames."""
    todo = np.zeros(tree.n + 1, dtype=bool)
    for k in frames:
        todo[tree.ancestors[k]] = True
    return todo


def joint_trig(tree: Tree, q: Array, frames: Sequence[int]) -> dict[int, tuple[Array, Array]]:
    """cos and sin of theta_j + q_j (each (N,)) of the revolute frames among `frames`, q samples-last (n, N): what
    `forward_kinematics` computes for them, for a caller that keeps them (`forward_kinematics`' trig)."""
    out = {}
    for j in frames:
        if tree.sigma[j] == REVOLUTE:
            th = tree.frames[j - 1].theta + q[j - 1]
            out[j] = (np.cos(th), np.sin(th))
    return out


def forward_kinematics(tree: Tree, q: Array, *, frames: Sequence[int] | None = None,
                       rows: slice = slice(None), trig: Mapping[int, tuple[Array, Array]] | None = None
                       ) -> KinematicState:
    """Poses of the frames in frame 0; q samples-last (n, N) as from `joint_array`.

    frames: compute only these frames and their ancestors (others stay None).
    rows: the frame-0 components kept of every origin and axis (default all): slice(2, 3), the heights and the
    axes' z components alone, each (1, N), the same numbers as the whole pose's row 2 (row i of 0R_j is row i of
    0R_a(j) times constants and the joint's cos, sin: the rows propagate apart) for a third of the work.
    Constant rotations that are signed permutations (alpha, gamma multiples of pi/2)
    cost nothing: the frame's columns are the parent's, reordered.
    trig: frame -> (cos, sin) of its theta + q (`joint_trig` of these q's), for the revolute frames whose column
    of q the caller knows unchanged since it computed them (a pass with a few joints moved): not computed again.
    """
    n, N = tree.n, q.shape[1]
    todo = needed_frames(tree, range(1, n + 1) if frames is None else frames)
    plan = frame_plan(tree)
    eye = np.eye(3)[rows]
    zero = np.zeros((len(eye), N))
    Rc: list = [[np.broadcast_to(eye[:, c, None], zero.shape) for c in range(3)]] + [None] * n
    P: list = [zero] + [None] * n
    dP: list = [zero] + [None] * n
    for f in tree.frames:
        j, a = f.j, f.ant
        if not todo[j]:
            continue
        E, perm, u = plan[j]
        D = _columns(Rc[a], E, perm)
        if f.sigma == REVOLUTE:
            if trig is not None and j in trig:
                c, s = trig[j]
            else:
                th = f.theta + q[j - 1]
                c, s = np.cos(th), np.sin(th)
            Rj = [c * D[0] + s * D[1], c * D[1] - s * D[0], D[2]]
        else:
            Rj = D
        d = combine(u, Rc[a])
        r = f.r + q[j - 1] if f.sigma == PRISMATIC else f.r
        if np.any(r != 0.0):
            d = r * Rj[2] if d is None else d + r * Rj[2]
        if d is None:
            d = zero
        Rc[j], dP[j], P[j] = Rj, d, P[a] + d
    return KinematicState(Rc, P, dP)


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
    rp = to_world(st.Rc[frame], np.asarray(point, dtype=float))
    return rp, st.P[frame] + rp


def check_frame(tree: Tree, frame: int, what: str = "frame") -> None:
    if not 0 <= frame <= tree.n:
        raise ModelError(f"{what} {frame} does not exist in model {tree.name!r} (frames 0..{tree.n})")


def jacobian(
    tree: Tree, q: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0
) -> Array:
    """Geometric Jacobian of a point fixed in `frame` (default its origin), (N, 6, n).

    Rows: linear velocity of the point, then angular velocity of the frame, with
    components in frame `expressed_in` (default 0). Column j is the effect of qd_j.
    """
    check_frame(tree, frame)
    check_frame(tree, expressed_in, "expressed_in frame")
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
    if expressed_in != 0:  # only the ancestors' columns are non-zero: rotate those
        Re = st.Rc[expressed_in]
        cols = [j - 1 for j in tree.ancestors[frame]]
        J[:3, cols], J[3:, cols] = _local_cols(Re, J[:3, cols]), _local_cols(Re, J[3:, cols])
    out = np.moveaxis(J, -1, 0)
    return out[0] if single else out


def point_velocity(
    tree: Tree, q: Array, qd: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0,
    state: KinematicState | None = None,
) -> tuple[Array, Array]:
    """J qd without J: the linear velocity of a point fixed in `frame` and the frame's angular velocity,
    each (N, 3), components in frame `expressed_in`; only the frame's ancestors are visited. state: q's
    `forward_kinematics` with frame and expressed_in among its frames, when the caller has it (several frames'
    velocities from one pass; q is then not read)."""
    check_frame(tree, frame)
    check_frame(tree, expressed_in, "expressed_in frame")
    qds, single = joint_array(qd, tree, "qd")
    if state is None:
        qs, _ = joint_array(q, tree, "q")
        state = forward_kinematics(tree, qs, frames=[frame, expressed_in])
    elif state.Rc[frame] is None or state.Rc[expressed_in] is None or qds.shape[1] != state.N:
        raise ModelError(f"point_velocity: the state given lacks frame {frame} or {expressed_in}, or is not of qd's "
                         f"{qds.shape[1]} samples; compute it with forward_kinematics(tree, q, frames=[...])")
    st = state
    _, Pp = _point(st, frame, point)
    v, w = np.zeros((3, qds.shape[1])), np.zeros((3, qds.shape[1]))
    for j in tree.ancestors[frame]:
        zq = st.Rc[j][2] * qds[j - 1]
        if tree.sigma[j] == REVOLUTE:
            v += cross(zq, Pp - st.P[j])
            w += zq
        elif tree.sigma[j] == PRISMATIC:
            v += zq
    if expressed_in != 0:
        v, w = to_local(st.Rc[expressed_in], v), to_local(st.Rc[expressed_in], w)
    return (v.T[0], w.T[0]) if single else (v.T, w.T)


def _local_cols(Rc: Array, V: Array) -> Array:
    """R^T applied to each column of V (3, n, N): out[c, j] = column c of R . V[:, j]."""
    return np.einsum("cin,ijn->cjn", np.asarray(Rc), V, optimize=True)


__all__ = [
    "KinematicState",
    "check_frame",
    "combine",
    "cross",
    "dot",
    "forward_kinematics",
    "frame_plan",
    "jacobian",
    "joint_array",
    "joint_trig",
    "needed_frames",
    "point_velocity",
    "to_local",
    "to_world",
    "transforms",
]
