"""Velocities and accelerations in the link frames (Khalil's recursion), component by component.

A vector is a list of three components, each an (N,) array, a float, or None where it
is structurally zero. Constant rotations that are signed permutations and constant
offsets with few non-zero entries (the common case: alpha, gamma multiples of pi/2,
one of d, b, r non-zero) then cost almost nothing, as in SYMORO's customised models:
a 42-frame tree needs several times fewer operations than with full 3-vectors.

    w_j   = jR_a w_a + qd_j z                       (revolute: sigma_bar = 1)
    dw_j  = jR_a dw_a + qdd_j z + qd_j (jR_a w_a) x z
    dv_j  = jR_a (dv_a + U_a aP_j) + sigma (qdd_j z + 2 qd_j (jR_a w_a) x z)
    U_a   = [dw_a]x + [w_a]x [w_a]x,   dv_0 = -g,   z = (0, 0, 1)

with aR_j = E_j Rot(z, q_j) (revolute) or E_j (otherwise), E_j = Rot(z, gamma) Rot(x, alpha)
[Rot(z, theta) when theta is constant], and aP_j = u_j + r_j E_j z.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model.tree import PRISMATIC, REVOLUTE, ModelError, Tree
from .forward import check_frame, forward_kinematics, frame_plan, joint_array, needed_frames, to_local, to_world

Array = np.ndarray
Comp = Array | float | None
Vec = list[Comp]


def add(*xs: Comp) -> Comp:
    out = None
    for x in xs:
        if x is not None:
            out = x if out is None else out + x
    return out


def mul(a: Comp, b: Comp) -> Comp:
    return None if a is None or b is None else a * b


def scale(k: float, x: Comp) -> Comp:
    """Constant times component, without multiplying by 0 or +-1."""
    if x is None or k == 0.0:
        return None
    return x if k == 1.0 else -x if k == -1.0 else k * x


def sub(a: Comp, b: Comp) -> Comp:
    return add(a, scale(-1.0, b))


def vcross(a: Vec, b: Vec) -> Vec:
    return [sub(mul(a[1], b[2]), mul(a[2], b[1])),
            sub(mul(a[2], b[0]), mul(a[0], b[2])),
            sub(mul(a[0], b[1]), mul(a[1], b[0]))]


def vadd(*vs: Vec) -> Vec:
    return [add(*(v[i] for v in vs)) for i in range(3)]


def matvec(M: Array, x: Vec) -> Vec:
    """Constant 3x3 matrix times vector."""
    return [add(*(scale(float(M[i, k]), x[k]) for k in range(3))) for i in range(3)]


def dense(x: Vec, N: int) -> Array:
    """A vector as a (3, N) array."""
    out = np.zeros((3, N))
    for i in range(3):
        if x[i] is not None:
            out[i] = x[i]
    return out


def is_zero(x: Vec) -> bool:
    return all(c is None for c in x)


@dataclass
class FrameRotation:
    """aR_j = E Rot(z, theta): E constant (a signed permutation when perm is given), (c, s) = theta."""

    E: Array
    perm: tuple | None
    c: Comp = None
    s: Comp = None

    def to_child(self, x: Vec) -> Vec:
        """jR_a x."""
        y = [scale(sgn, x[k]) for k, sgn in self.perm] if self.perm is not None else matvec(self.E.T, x)
        if self.c is None:
            return y
        c, s = self.c, self.s
        return [add(mul(c, y[0]), mul(s, y[1])), sub(mul(c, y[1]), mul(s, y[0])), y[2]]

    def to_parent(self, x: Vec) -> Vec:
        """aR_j x."""
        if self.c is not None:
            c, s = self.c, self.s
            x = [sub(mul(c, x[0]), mul(s, x[1])), add(mul(s, x[0]), mul(c, x[1])), x[2]]
        if self.perm is None:
            return matvec(self.E, x)
        y: Vec = [None, None, None]
        for col, (k, sgn) in enumerate(self.perm):
            y[k] = scale(sgn, x[col])
        return y


def u_matrix(w: Vec, dw: Vec) -> list[list[Comp]]:
    """U = [dw]x + [w]x[w]x (3x3 of components)."""
    wx, wy, wz = w
    xx, yy, zz = mul(wx, wx), mul(wy, wy), mul(wz, wz)
    xy, xz, yz = mul(wx, wy), mul(wx, wz), mul(wy, wz)
    return [[scale(-1.0, add(yy, zz)), sub(xy, dw[2]), add(xz, dw[1])],
            [add(xy, dw[2]), scale(-1.0, add(xx, zz)), sub(yz, dw[0])],
            [sub(xz, dw[1]), add(yz, dw[0]), scale(-1.0, add(xx, yy))]]


def umul(U: list[list[Comp]], x: Vec) -> Vec:
    return [add(*(mul(U[i][k], x[k]) for k in range(3))) for i in range(3)]


@dataclass
class Motion:
    """Per-frame local quantities (lists indexed by frame 0..n; None where not computed).

    rot[j]: aR_j; offset[j]: aP_j in frame a(j); w, dw, dv: angular velocity, angular
    acceleration and acceleration of O_j, in frame j; v: velocity of O_j in frame j
    (only with velocities=True); U[j]: Khalil's U matrix of frame j (computed on demand).
    """

    N: int
    rot: list
    offset: list
    w: list
    dw: list
    dv: list
    v: list | None
    U: list

    def u(self, j: int) -> list[list[Comp]]:
        if self.U[j] is None:
            self.U[j] = u_matrix(self.w[j], self.dw[j])
        return self.U[j]


def local_motion(
    tree: Tree,
    q: Array,
    qd: Array,
    qdd: Array,
    *,
    gravity: bool = True,
    velocities: bool = False,
    frames: Sequence[int] | None = None,
) -> Motion:
    """Forward recursion in link frames; q, qd, qdd samples-last (n, N)."""
    n, N = tree.n, q.shape[1]
    todo = needed_frames(tree, range(1, n + 1) if frames is None else frames)
    plan = frame_plan(tree)
    none3: Vec = [None, None, None]
    g = np.asarray(tree.gravity, dtype=float)
    st = Motion(N, [None] * (n + 1), [None] * (n + 1), [none3] + [None] * n, [none3] + [None] * n,
                [[float(-x) if gravity and x != 0.0 else None for x in g]] + [None] * n,
                [none3] + [None] * n if velocities else None, [None] * (n + 1))
    for f in tree.frames:
        j, a = f.j, f.ant
        if not todo[j]:
            continue
        E, perm, u = plan[j]
        rot = FrameRotation(E, perm)
        if f.sigma == REVOLUTE:
            th = f.theta + q[j - 1]
            rot.c, rot.s = np.cos(th), np.sin(th)
        ez = E[:, 2]
        r: Comp = f.r + q[j - 1] if f.sigma == PRISMATIC else (f.r if f.r != 0.0 else None)
        d: Vec = [add(None if u[i] == 0.0 else float(u[i]), mul(r, None if ez[i] == 0.0 else float(ez[i])))
                  for i in range(3)]
        st.rot[j], st.offset[j] = rot, d
        wa = rot.to_child(st.w[a])
        qdj, qddj = qd[j - 1], qdd[j - 1]
        wz: Vec = [wa[1], scale(-1.0, wa[0]), None]  # (jR_a w_a) x z
        if f.sigma == REVOLUTE:
            st.w[j] = [wa[0], wa[1], add(wa[2], qdj)]
            dwa = rot.to_child(st.dw[a])
            st.dw[j] = [add(dwa[0], mul(qdj, wz[0])), add(dwa[1], mul(qdj, wz[1])), add(dwa[2], qddj)]
        else:
            st.w[j], st.dw[j] = wa, rot.to_child(st.dw[a])
        Ud = None if is_zero(d) or (is_zero(st.w[a]) and is_zero(st.dw[a])) else umul(st.u(a), d)
        dv = rot.to_child(st.dv[a] if Ud is None else vadd(st.dv[a], Ud))
        if f.sigma == PRISMATIC:
            two = 2.0 * qdj
            dv = [add(dv[0], mul(two, wz[0])), add(dv[1], mul(two, wz[1])), add(dv[2], qddj)]
        st.dv[j] = dv
        if st.v is not None:
            va = rot.to_child(vadd(st.v[a], vcross(st.w[a], d)))
            st.v[j] = [va[0], va[1], add(va[2], qdj)] if f.sigma == PRISMATIC else va
    return st


def jdot_qdot(
    tree: Tree, q: Array, qd: Array, frame: int, point: Sequence[float] | None = None, expressed_in: int = 0
) -> Array:
    """J-dot times qd for the point of `jacobian`, (N, 6): its acceleration when qdd = 0, without gravity."""
    check_frame(tree, frame)
    check_frame(tree, expressed_in, "expressed_in frame")
    qs, single = joint_array(q, tree, "q")
    qds, _ = joint_array(qd, tree, "qd")
    if qds.shape != qs.shape:
        raise ModelError(f"q and qd must have the same shape; got {np.shape(q)} and {np.shape(qd)}")
    N = qs.shape[1]
    mo = local_motion(tree, qs, qds, np.zeros_like(qs), gravity=False, frames=[frame])
    p: Vec = [None if x == 0.0 else float(x) for x in (point if point is not None else (0.0, 0.0, 0.0))]
    a_loc = dense(vadd(mo.dv[frame], umul(mo.u(frame), p)), N)
    st = forward_kinematics(tree, qs, frames=[frame, expressed_in])
    a, dw = to_world(st.Rc[frame], a_loc), to_world(st.Rc[frame], dense(mo.dw[frame], N))
    if expressed_in != 0:
        Re = st.Rc[expressed_in]
        a, dw = to_local(Re, a), to_local(Re, dw)
    out = np.concatenate([a, dw]).T
    return out[0] if single else out


__all__ = ["FrameRotation", "Motion", "dense", "jdot_qdot", "local_motion", "matvec", "vadd", "vcross"]
