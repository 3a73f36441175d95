"""Batched Newton-Euler inverse dynamics of a modified-DH tree (Khalil's formulation).

Forward recursion of velocities and accelerations (gravity enters as dV0 = -g), then
a backward recursion of the link wrenches, from which every joint takes the
component along or about its own z axis. External wrenches act on chosen links.

Two engines compute the same models: "numba" (compiled.py, per-sample machine code,
the default when numba is installed) and "numpy" (this module and regressor.py,
batched array operations, the reference). `resolve_backend` chooses.
"""

from __future__ import annotations

import functools
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..kinematics.forward import forward_kinematics, joint_array, to_local, to_world
from ..kinematics.motion import Motion, Vec, local_motion, matvec, scale, umul, vadd, vcross
from ..model.tree import FIXED, NO_KNEES, PRISMATIC, REVOLUTE, SIGN_LAW, ModelError, Tree
from .mimic import follow, project

Array = np.ndarray
CHUNK = 2048  # samples per pass: keeps the per-frame arrays in cache (1-2k measured best)
BACKENDS = ("numba", "numpy")
_WARNED: list[bool] = [False]


def resolve_backend(backend: str | None = None) -> str:
    """The engine to run: `backend` if given, else $DYNID_BACKEND, else "numba" when numba is installed.

    "numba" without a working numba falls back to "numpy" (with one warning): same results, slower.
    """
    b = backend if backend is not None else (os.environ.get("DYNID_BACKEND", "").strip().lower() or "numba")
    if b not in BACKENDS:
        where = "backend" if backend is not None else "DYNID_BACKEND"
        raise ModelError(f"{where} = {b!r}: use one of {BACKENDS}")
    if b == "numba" and not _numba_works():
        if not _WARNED[0]:
            _WARNED[0] = True
            warnings.warn("numba is not installed: dynid's dynamics run on the NumPy engine (same results, "
                          "several times slower); pip install numba", RuntimeWarning, stacklevel=3)
        return "numpy"
    return b


@functools.cache
def _numba_works() -> bool:
    from . import compiled  # start-up: numba 0.5 s; imports numba on first use; without it HAVE_NUMBA is False

    return compiled.HAVE_NUMBA


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


def check_wrenches(tree: Tree, wrenches: Sequence[Wrench] | None, N: int) -> list[tuple[int, int, Array, Array]]:
    """Validate the wrenches; returns (link, frame, values (6, N or 1), point (3,)) per wrench."""
    out = []
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
        point = np.asarray(w.point, dtype=float)
        if point.shape != (3,) or not np.isfinite(point).all():
            raise ModelError(f"wrenches[{i}] on link {w.link}: point must be 3 finite coordinates")
        out.append((w.link, e, vals.T if vals.ndim == 2 else vals[:, None], point))
    return out


def local_wrenches(tree: Tree, q: Array, checked: list) -> dict[int, tuple[Vec, Vec]]:
    """Sum the wrenches per link as (force, moment about O_link) in the link's frame."""
    out: dict[int, tuple[Vec, Vec]] = {}
    other = [(k, e) for k, e, _, _ in checked if e != k]
    st = forward_kinematics(tree, q, frames=[x for pair in other for x in pair]) if other else None
    for k, e, vals, point in checked:
        F, M = vals[:3], vals[3:]
        if e != k:
            F, M = to_local(st.Rc[k], to_world(st.Rc[e], F)), to_local(st.Rc[k], to_world(st.Rc[e], M))
        Fv: Vec = [F[0], F[1], F[2]]
        Mv = vadd([M[0], M[1], M[2]], vcross([None if x == 0.0 else float(x) for x in point], Fv))
        if k in out:
            Fv, Mv = vadd(out[k][0], Fv), vadd(out[k][1], Mv)
        out[k] = (Fv, Mv)
    return out


def slice_wrenches(wrenches: Sequence[Wrench] | None, sl: slice, N: int) -> list[Wrench]:
    """The wrenches restricted to samples sl (values given per sample are sliced)."""
    out = []
    for w in wrenches or ():
        v = np.asarray(w.values, dtype=float)
        out.append(Wrench(w.link, v[sl] if v.ndim == 2 and v.shape[0] == N else v, w.point, w.frame))
    return out


def inertia_tensor(p: Array) -> Array:
    """3x3 inertia from (XX, XY, XZ, YY, YZ, ZZ, ...)."""
    return np.array([[p[0], p[1], p[2]], [p[1], p[3], p[4]], [p[2], p[4], p[5]]])


def link_wrench(mo: Motion, j: int, p: Array) -> tuple[Vec, Vec]:
    """Force and moment about O_j, in frame j, that link j's motion requires (Newton-Euler)."""
    ms: Vec = [None if x == 0.0 else float(x) for x in p[6:9]]
    w, dw, dv = mo.w[j], mo.dw[j], mo.dv[j]
    F = vadd([scale(float(p[9]), x) for x in dv], umul(mo.u(j), ms))
    J = inertia_tensor(p)
    return F, vadd(matvec(J, dw), vcross(w, matvec(J, w)), vcross(ms, dv))


def backward_recursion(tree: Tree, mo: Motion, F: list, M: list) -> Array:
    """Accumulate link wrenches (frame-local Vecs) towards the base; returns joint forces (n, N)."""
    tau = np.zeros((tree.n, mo.N))
    F, M = list(F), list(M)
    for f in reversed(tree.frames):
        j, a = f.j, f.ant
        if F[j] is None:
            continue
        x = M[j][2] if f.sigma == REVOLUTE else F[j][2] if f.sigma == PRISMATIC else None
        if x is not None:
            tau[j - 1] = x
        if a > 0:
            fa = mo.rot[j].to_parent(F[j])
            ma = vadd(mo.rot[j].to_parent(M[j]), vcross(mo.offset[j], fa))
            F[a] = fa if F[a] is None else vadd(F[a], fa)
            M[a] = ma if M[a] is None else vadd(M[a], ma)
    return tau


def joint_terms(tree: Tree, X: Array, q: Array, qd: Array, qdd: Array, *, inertia_only: bool = False) -> Array:
    """IA qdd + FV qd + FS s(qd) + OFF + K q + KQ q² + the viscous curve per joint (s: the joint's Coulomb law;
    the curve: model.tree's module doc), plus the couplings, (n, N)."""
    tau = np.zeros_like(q)
    idx = tree.index
    for j, terms in tree.joint_terms.items():
        for t in terms:
            x = X[idx[f"{t}{j}"]]
            if x != 0.0 and (t == "IA" or not inertia_only):
                tau[j - 1] += x * joint_term_column(t, q[j - 1], qd[j - 1], qdd[j - 1], tree.friction_law(j),
                                                    tree.knee(j))
    for c in tree.couplings:
        x = X[idx[c.name]]
        if x == 0.0 or (inertia_only and c.kind != "IA"):
            continue
        tau += coupling_column(c, q, qd, qdd, tree.n) * x
    return tau


def joint_term_column(term: str, q: Array, qd: Array, qdd: Array,
                      law: tuple[str, float] = SIGN_LAW, knees: tuple[float, float] = NO_KNEES) -> Array:
    """Generalized force of joint j per unit of its term IA, FV, FS, OFF, K, KQ or a viscous curve slope FVPL,
    FVPH, FVNL, FVNH, (N,); law: the (shape, vs) of its FS term (Tree.friction_law); knees: (v-, v+) of its
    curve (Tree.knee)."""
    match term:
        case "IA":
            return qdd
        case "FV":
            return qd
        case "FS":
            return coulomb(qd, law)
        case "OFF":
            return np.ones_like(q)
        case "K":
            return q
        case "KQ":
            return q * q
        case "FVPL":  # the slope on 0 < qd < v+
            return np.clip(qd, 0.0, knees[1])
        case "FVPH":  # beyond v+
            return np.maximum(qd - knees[1], 0.0)
        case "FVNL":  # on v- < qd < 0
            return np.clip(qd, knees[0], 0.0)
        case "FVNH":  # below v-
            return np.minimum(qd - knees[0], 0.0)
    raise ModelError(f"unknown joint term {term!r}")


def coulomb(qd: Array, law: tuple[str, float]) -> Array:
    """The Coulomb column s(qd): sign(qd), tanh(qd / vs), or 2 / (1 + exp(-qd / vs)) - 1 computed as
    tanh(qd / (2 vs)) (the same function, without exp's overflow and the cancellation near 0)."""
    shape, vs = law
    if shape == "sign":
        return np.sign(qd)
    return np.tanh(qd / (vs if shape == "tanh" else 2.0 * vs))


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
    checked = check_wrenches(tree, wrenches, q.shape[1])
    inert = tree.inertial_block(X)
    massive = [j for j in range(1, tree.n + 1) if inert[j].any()]
    mo = local_motion(tree, q, qd, qdd, gravity=gravity, frames=massive + [k for k, _, _, _ in checked])
    F: list = [None] * (tree.n + 1)
    M: list = [None] * (tree.n + 1)
    for j in massive:
        F[j], M[j] = link_wrench(mo, j, inert[j])
    for k, (Fe, Me) in local_wrenches(tree, q, checked).items():
        Fe, Me = [scale(-1.0, x) for x in Fe], [scale(-1.0, x) for x in Me]
        F[k], M[k] = (Fe, Me) if F[k] is None else (vadd(F[k], Fe), vadd(M[k], Me))
    return backward_recursion(tree, mo, F, M)


def inverse_dynamics(
    tree: Tree,
    q: Array,
    qd: Array,
    qdd: Array,
    wrenches: Sequence[Wrench] | None = None,
    X: Array | None = None,
    *,
    backend: str | None = None,
) -> Array:
    """Joint forces/torques (N, n) that produce qdd at (q, qd) under gravity and the wrenches.

    tau = M(q) qdd + H(q, qd) + joint terms - J^T F_ext; X defaults to the model's values.
    Fixed frames get 0, and so do mimic joints, whose force is in their master's (see `mimic`; their columns of
    q, qd, qdd are ignored). backend: "numba", "numpy" or None (see `resolve_backend`).
    """
    if tree.mimic:
        q, qd, qdd = follow(tree, q, qd, qdd)
        tau = inverse_dynamics(tree.unconstrained, q, qd, qdd, wrenches, X, backend=backend)
        return project(tree, tau, range(1, tree.n + 1), axis=-1)
    if resolve_backend(backend) == "numba":
        return _compiled_inverse_dynamics(tree, q, qd, qdd, wrenches, X)
    qs, single = joint_array(q, tree, "q")
    qds, _ = joint_array(qd, tree, "qd")
    qdds, _ = joint_array(qdd, tree, "qdd")
    if not qs.shape == qds.shape == qdds.shape:
        raise ModelError(f"q, qd, qdd must have the same shape; got {np.shape(q)}, {np.shape(qd)}, {np.shape(qdd)}")
    X = tree.parameters if X is None else check_parameters(tree, X)
    N = qs.shape[1]
    check_wrenches(tree, wrenches, N)
    tau = joint_terms(tree, X, qs, qds, qdds)
    for n0 in range(0, N, CHUNK):  # chunks small enough for the per-frame arrays to stay in cache
        sl = slice(n0, min(N, n0 + CHUNK))
        tau[:, sl] += rigid_body_torques(tree, qs[:, sl], qds[:, sl], qdds[:, sl], X,
                                         wrenches=slice_wrenches(wrenches, sl, N))
    tau[tree.sigma[1:] == FIXED] = 0.0
    return tau[:, 0] if single else tau.T


def _compiled_inverse_dynamics(tree: Tree, q, qd, qdd, wrenches, X) -> Array:
    from . import compiled  # start-up: numba 0.5 s

    qs, single = compiled.joint_rows(q, tree, "q")
    qds, _ = compiled.joint_rows(qd, tree, "qd")
    qdds, _ = compiled.joint_rows(qdd, tree, "qdd")
    if not qs.shape == qds.shape == qdds.shape:
        raise ModelError(f"q, qd, qdd must have the same shape; got {np.shape(q)}, {np.shape(qd)}, {np.shape(qdd)}")
    X = tree.parameters if X is None else check_parameters(tree, X)
    tau = compiled.inverse_dynamics(tree, qs, qds, qdds, X, check_wrenches(tree, wrenches, qs.shape[0]))
    return tau[0] if single else tau


def check_parameters(tree: Tree, X: object) -> Array:
    X = np.asarray(X, dtype=float)
    if X.shape != (tree.p,):
        raise ModelError(f"parameter vector must have {tree.p} values (model {tree.name!r}); got shape {X.shape}")
    if not np.isfinite(X).all():
        raise ModelError(f"parameter {tree.parameter_names[int(np.argmin(np.isfinite(X)))]} is not finite")
    return X
