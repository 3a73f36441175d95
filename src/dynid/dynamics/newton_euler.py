"""Batched Newton-Euler inverse dynamics of a modified-DH tree (Khalil's formulation).

Forward recursion of velocities and accelerations (gravity enters as dV0 = -g), then
a backward recursion of the link wrenches, from which every joint takes the
component along or about its own z axis. External wrenches act on chosen links.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..kinematics.forward import KinematicState, cross, dot, forward_kinematics, joint_array, to_local, to_world
from ..model.tree import FIXED, PRISMATIC, REVOLUTE, ModelError, Tree

Array = np.ndarray


@dataclass(frozen=True)
class Wrench:
    """A wrench exerted BY the environment ON link `link`.

    values: (N, 6) or (6,): force (Fx, Fy, Fz) then moment (Mx, My, Mz) about `point`;
    point: coordinates, in frame `link`, of the point the moment is taken about
    (default: the origin of frame `link`); frame: the frame whose axes the components
    are expressed in (default: frame `link`; 0 for the ground frame).
    """

    link: int
    values: Array
    point: Sequence[float] = (0.0, 0.0, 0.0)
    frame: int | None = None


def external_wrenches(tree: Tree, st: KinematicState, wrenches: Sequence[Wrench] | None) -> dict[int, tuple]:
    """Sum the wrenches per link as (force, moment about O_link) in frame-0 orientation, (3, N) each."""
    out: dict[int, tuple] = {}
    N = st.N
    for i, w in enumerate(wrenches or ()):
        if not isinstance(w, Wrench):
            raise ModelError(f"wrenches[{i}] is a {type(w).__name__}; pass dynid.Wrench(link, values, point, frame)")
        if not 1 <= w.link <= tree.n:
            raise ModelError(f"wrenches[{i}]: link {w.link} does not exist (1..{tree.n})")
        e = w.link if w.frame is None else w.frame
        if not 0 <= e <= tree.n:
            raise ModelError(f"wrenches[{i}]: frame {e} does not exist (0..{tree.n})")
        vals = np.asarray(w.values, dtype=float)
        if vals.shape not in ((6,), (N, 6)):
            raise ModelError(f"wrenches[{i}] on link {w.link}: values must be (6,) or ({N}, 6); got {vals.shape}")
        if not np.isfinite(vals).all():
            k = int(np.argwhere(~np.isfinite(vals.reshape(-1, 6)))[0, 0])
            raise ModelError(f"wrenches[{i}] on link {w.link}: non-finite value at sample {k}")
        vals = vals.T if vals.ndim == 2 else vals[:, None]
        Re = st.Rc[e]
        F, M = to_world(Re, vals[:3]), to_world(Re, vals[3:])
        rp = to_world(st.Rc[w.link], np.asarray(w.point, dtype=float))
        M = M + cross(rp, F)
        F, M = np.broadcast_to(F, (3, N)), np.broadcast_to(M, (3, N))
        if w.link in out:
            F, M = out[w.link][0] + F, out[w.link][1] + M
        out[w.link] = (F, M)
    return out


def inertia_tensor(p: Array) -> Array:
    """3x3 inertia from (XX, XY, XZ, YY, YZ, ZZ, ...)."""
    return np.array([[p[0], p[1], p[2]], [p[1], p[3], p[4]], [p[2], p[4], p[5]]])


def link_wrench(st: KinematicState, j: int, p: Array) -> tuple[Array, Array]:
    """Force and moment about O_j (frame-0 orientation) that link j's motion requires, (3, N) each."""
    Rc, w, dw, dv = st.Rc[j], st.omega(j), st.domega(j), st.dv[j]
    ms = to_world(Rc, p[6:9])
    F = p[9] * dv + cross(dw, ms) + cross(w, cross(w, ms))
    J = inertia_tensor(p)
    wl, dwl = to_local(Rc, w), to_local(Rc, dw)
    nl = np.tensordot(J, dwl, axes=1) + cross(wl, np.tensordot(J, wl, axes=1))
    return F, to_world(Rc, nl) + cross(ms, dv)


def backward_recursion(
    tree: Tree, st: KinematicState, F: list, M: list, Nsamp: int
) -> Array:
    """Accumulate link wrenches towards the base; returns joint forces (n, N)."""
    tau = np.zeros((tree.n, Nsamp))
    F, M = list(F), list(M)
    for f in reversed(tree.frames):
        j, a = f.j, f.ant
        if F[j] is None:
            continue
        z = st.Rc[j][2]
        if f.sigma == REVOLUTE:
            tau[j - 1] = dot(z, M[j])
        elif f.sigma == PRISMATIC:
            tau[j - 1] = dot(z, F[j])
        if a > 0:
            mj = M[j] + cross(st.dP[j], F[j])
            F[a] = F[j] if F[a] is None else F[a] + F[j]
            M[a] = mj if M[a] is None else M[a] + mj
    return tau


def joint_terms(tree: Tree, X: Array, q: Array, qd: Array, qdd: Array, *, inertia_only: bool = False) -> Array:
    """IA qdd + FV qd + FS sign(qd) + OFF + K q per joint, plus the couplings, (n, N)."""
    tau = np.zeros_like(q)
    idx = tree.index
    for j, terms in tree.joint_terms.items():
        for t in terms:
            x = X[idx[f"{t}{j}"]]
            if x != 0.0 and (t == "IA" or not inertia_only):
                tau[j - 1] += x * joint_term_column(t, q[j - 1], qd[j - 1], qdd[j - 1])
    for c in tree.couplings:
        x = X[idx[c.name]]
        if x == 0.0 or (inertia_only and c.kind != "IA"):
            continue
        tau += coupling_column(c, q, qd, qdd, tree.n) * x
    return tau


def joint_term_column(term: str, q: Array, qd: Array, qdd: Array) -> Array:
    """Generalized force of joint j per unit of its term IA, FV, FS, OFF or K, (N,)."""
    match term:
        case "IA":
            return qdd
        case "FV":
            return qd
        case "FS":
            return np.sign(qd)
        case "OFF":
            return np.ones_like(q)
        case "K":
            return q
    raise ModelError(f"unknown joint term {term!r}")


def coupling_column(c, q: Array, qd: Array, qdd: Array, n: int) -> Array:
    """Generalized force per unit parameter of a coupling, (n, N)."""
    joints = np.array(list(c.coeffs)) - 1
    coef = np.array(list(c.coeffs.values()))
    src = {"K": q, "IA": qdd, "FV": qd, "FS": qd}[c.kind]
    s = coef @ src[joints]
    if c.kind == "FS":
        s = np.sign(s)
    col = np.zeros((n, q.shape[1]))
    col[joints] = coef[:, None] * s
    return col


def rigid_body_torques(
    tree: Tree, q: Array, qd: Array, qdd: Array, X: Array, *, gravity: bool = True, wrenches=None
) -> Array:
    """Newton-Euler without joint terms, samples last (n, N)."""
    inert = tree.inertial_block(X)
    loaded = [j for j in range(1, tree.n + 1) if inert[j].any()] + [w.link for w in wrenches or ()]
    st = forward_kinematics(tree, q, qd, qdd, gravity=gravity, frames=loaded)
    F: list = [None] * (tree.n + 1)
    M: list = [None] * (tree.n + 1)
    for j in loaded:
        if inert[j].any():
            F[j], M[j] = link_wrench(st, j, inert[j])
    for k, (Fe, Me) in external_wrenches(tree, st, wrenches).items():
        F[k] = -Fe if F[k] is None else F[k] - Fe
        M[k] = -Me if M[k] is None else M[k] - Me
    return backward_recursion(tree, st, F, M, q.shape[1])


def inverse_dynamics(
    tree: Tree,
    q: Array,
    qd: Array,
    qdd: Array,
    wrenches: Sequence[Wrench] | None = None,
    X: Array | None = None,
) -> Array:
    """Joint forces/torques (N, n) that produce qdd at (q, qd) under gravity and the wrenches.

    tau = M(q) qdd + H(q, qd) + joint terms - J^T F_ext; X defaults to the model's values.
    Fixed frames get 0.
    """
    qs, single = joint_array(q, tree, "q")
    qds, _ = joint_array(qd, tree, "qd")
    qdds, _ = joint_array(qdd, tree, "qdd")
    if not qs.shape == qds.shape == qdds.shape:
        raise ModelError(f"q, qd, qdd must have the same shape; got {np.shape(q)}, {np.shape(qd)}, {np.shape(qdd)}")
    X = tree.parameters if X is None else check_parameters(tree, X)
    tau = rigid_body_torques(tree, qs, qds, qdds, X, wrenches=wrenches) + joint_terms(tree, X, qs, qds, qdds)
    tau[tree.sigma[1:] == FIXED] = 0.0
    return tau[:, 0] if single else tau.T


def check_parameters(tree: Tree, X: object) -> Array:
    X = np.asarray(X, dtype=float)
    if X.shape != (tree.p,):
        raise ModelError(f"parameter vector must have {tree.p} values (model {tree.name!r}); got shape {X.shape}")
    if not np.isfinite(X).all():
        raise ModelError(f"parameter {tree.parameter_names[int(np.argmin(np.isfinite(X)))]} is not finite")
    return X
