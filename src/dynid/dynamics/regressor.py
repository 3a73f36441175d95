"""The identification model: W(q, qd, qdd) with W X = tau for every parameter vector X.

Each link's Newton-Euler wrench is linear in its 10 inertial parameters. For link k we
build once the 6 x 10 block B_k of force and moment per unit parameter, the moment
taken about a reference point O* near the system (the centroid of the frame origins,
per sample, so that precision does not depend on where the system is). Joint j, an
ancestor of k, sees the column

    W[j, col(k)] = z_j . N*_k + ((P_j - O*) x z_j) . F_k      (revolute)
    W[j, col(k)] = z_j . F_k                                  (prismatic)

so the cost is one small contraction per (row, link) pair actually requested:
restricting rows and columns (the car uses 14 of 42 rows and 48 of ~440 columns)
removes pairs, and the work drops in proportion.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..kinematics.forward import KinematicState, cross, forward_kinematics, joint_array
from ..kinematics.motion import Motion, Vec, local_motion, vadd, vcross
from ..model.tree import FIXED, INERTIAL, LOAD_TERMS, REVOLUTE, ModelError, Tree
from .mimic import follow, project, rows_needed
from .newton_euler import (
    CHUNK,
    Wrench,
    backward_recursion,
    check_wrenches,
    coupling_column,
    joint_term_column,
    local_wrenches,
    resolve_backend,
    slice_wrenches,
)

Array = np.ndarray

# the product E w of the symmetric basis matrix E of XX, XY, XZ, YY, YZ, ZZ with w: (component, source) pairs
_INERTIA_BASIS = (((0, 0),), ((0, 1), (1, 0)), ((0, 2), (2, 0)), ((1, 1),), ((1, 2), (2, 1)), ((2, 2),))


def resolve_rows(tree: Tree, rows: Sequence[int] | None) -> list[int]:
    """Joint (frame) numbers 1..n; all by default."""
    if rows is None:
        return list(range(1, tree.n + 1))
    out = []
    for r in rows:
        if isinstance(r, bool) or not isinstance(r, int | np.integer) or not 1 <= int(r) <= tree.n:
            raise ModelError(f"row {r!r} is not a joint of model {tree.name!r} (frame numbers 1..{tree.n})")
        out.append(int(r))
    return out


def resolve_cols(tree: Tree, cols: Sequence[str | int] | None) -> list[int]:
    """Column indices of parameters given by name, label or index; all by default."""
    if cols is None:
        return list(range(tree.p))
    out = []
    for c in cols:
        if isinstance(c, str):
            out.append(tree.column(c))
        elif not isinstance(c, bool) and isinstance(c, int | np.integer) and 0 <= int(c) < tree.p:
            out.append(int(c))
        else:
            raise ModelError(f"column {c!r} is not a parameter name or an index 0..{tree.p - 1}")
    return out


def link_block(st: KinematicState, mo: Motion, k: int, ref: Array) -> Array:
    """Force and moment about O* per unit inertial parameter of link k, (6, 10, N), frame-0 orientation.

    Built in frame k (where the structure is sparse) from Khalil's columns, then rotated:
    inertia J: (0, J dw + w x J w); first moment along axis c: (U e_c, e_c x dv); mass: (dv, 0).
    """
    N, Rc = mo.N, st.Rc[k]
    w, dw, dv, U = mo.w[k], mo.dw[k], mo.dv[k], mo.u(k)
    L = np.zeros((6, 10, N))  # the block in frame k
    for i, entries in enumerate(_INERTIA_BASIS):
        Ew: Vec = [None, None, None]
        Edw: Vec = [None, None, None]
        for r, c in entries:
            Ew[r], Edw[r] = w[c], dw[c]
        _put(L[3:, i], vadd(Edw, vcross(w, Ew)))
    for c in range(3):
        _put(L[:3, 6 + c], [U[0][c], U[1][c], U[2][c]])
        _put(L[3:, 6 + c], vcross([1.0 if i == c else None for i in range(3)], dv))
    _put(L[:3, 9], dv)
    B = np.empty_like(L)
    for part in (slice(0, 3), slice(3, 6)):
        Lp = L[part]
        B[part] = Rc[0][:, None] * Lp[0] + Rc[1][:, None] * Lp[1] + Rc[2][:, None] * Lp[2]
    # moments about O* instead of O_k
    B[3:, 6:] += cross((st.P[k] - ref)[:, None, :], B[:3, 6:])
    return B


def _put(out: Array, v: Vec) -> None:
    for i in range(3):
        if v[i] is not None:
            out[i] = v[i]


def joint_axis(tree: Tree, st: KinematicState, j: int, ref: Array) -> Array:
    """The 6-vector that picks joint j's force out of a (force, moment about O*) wrench, (6, N)."""
    z = st.Rc[j][2]
    if tree.sigma[j] == REVOLUTE:
        return np.concatenate([cross(st.P[j] - ref, z), z])
    return np.concatenate([z, np.zeros_like(z)])


def regressor(
    tree: Tree,
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
    """Identification model W, (N, len(rows), len(cols)), such that W X = tau.

    rows: joint (frame) numbers, default all; cols: parameter names, labels or column
    indices, default all. With wrenches, returns (W, Q) where Q (N, len(rows)) is the
    generalized force of the external wrenches: W X = tau + Q, the known right-hand side.

    out: a preallocated float64 array of W's shape ((len(rows), len(cols)) for one sample),
    C-contiguous, filled and returned. The numba engine writes only the entries that can be
    non-zero for these rows and columns and leaves the others as they are: pass a zeroed
    buffer (np.zeros) the first time; reusing it for the same rows and columns keeps its
    zeros. Without out, W is a new zeroed array.
    backend: "numba", "numpy" or None (see newton_euler.resolve_backend). The numba engine
    returns C-contiguous arrays; the numpy engine a view whose memory keeps samples last.
    A mimic joint's row is 0 and its master's carries both (see `mimic`).
    """
    if tree.mimic:
        return _mimic_regressor(tree, q, qd, qdd, wrenches, rows, cols, out, backend)
    if resolve_backend(backend) == "numba":
        return _compiled_regressor(tree, q, qd, qdd, wrenches, rows, cols, out)
    W = _numpy_regressor(tree, q, qd, qdd, wrenches, rows, cols)
    if out is None:
        return W
    Wn = W[0] if isinstance(W, tuple) else W
    check_out(out, Wn.shape)
    np.copyto(out, Wn)
    return (out, W[1]) if isinstance(W, tuple) else out


def _mimic_regressor(tree: Tree, q, qd, qdd, wrenches, rows, cols, out, backend) -> Array | tuple[Array, Array]:
    """The regressor of a tree with mimic joints: the unconstrained one on the followed motion, on the rows asked
    for and the followers of their masters, projected (mimic.project), then the rows asked for."""

    R = resolve_rows(tree, rows)
    need = rows_needed(tree, R)
    q, qd, qdd = follow(tree, q, qd, qdd)
    got = regressor(tree.unconstrained, q, qd, qdd, wrenches, need, cols, backend=backend)
    W, Q = got if isinstance(got, tuple) else (got, None)
    pick = [need.index(j) for j in R]
    W = np.take(project(tree, W, need, axis=-2), pick, axis=-2)
    if Q is not None:
        Q = np.take(project(tree, Q, need, axis=-1), pick, axis=-1)
    if out is not None:
        check_out(out, W.shape)
        np.copyto(out, W)
        W = out
    return (W, Q) if Q is not None else W


def check_out(out: object, shape: tuple[int, ...]) -> None:
    """The `out` buffer must be a writeable float64 C-contiguous array of W's shape."""
    if not isinstance(out, np.ndarray) or out.dtype != np.float64 or out.shape != tuple(shape):
        got = f"{out.dtype} {out.shape}" if isinstance(out, np.ndarray) else type(out).__name__
        raise ModelError(f"out must be a float64 array of shape {tuple(shape)} (samples, rows, cols); got {got}")
    if not out.flags.c_contiguous or not out.flags.writeable:
        raise ModelError("out must be C-contiguous and writeable (allocate it with np.zeros(shape))")


def _compiled_regressor(tree: Tree, q, qd, qdd, wrenches, rows, cols, out) -> Array | tuple[Array, Array]:
    from . import compiled  # start-up: numba 0.5 s

    qs, single = compiled.joint_rows(q, tree, "q")
    qds, _ = compiled.joint_rows(qd, tree, "qd")
    qdds, _ = compiled.joint_rows(qdd, tree, "qdd")
    if not qs.shape == qds.shape == qdds.shape:
        raise ModelError(f"q, qd, qdd must have the same shape; got {np.shape(q)}, {np.shape(qd)}, {np.shape(qdd)}")
    R, Cols = resolve_rows(tree, rows), resolve_cols(tree, cols)
    N = qs.shape[0]
    checked = check_wrenches(tree, wrenches, N) if wrenches is not None else None
    shape = (len(R), len(Cols)) if single else (N, len(R), len(Cols))
    if out is not None:
        check_out(out, shape)
    if len(set(R)) == len(R) and len(set(Cols)) == len(Cols):
        W = np.zeros((N, len(R), len(Cols))) if out is None else out.reshape(N, len(R), len(Cols))
        Q = compiled.regressor(tree, qs, qds, qdds, R, Cols, checked, W)
    else:  # repeated rows or columns: compute each once, then copy
        uR, ri = np.unique(R, return_inverse=True)
        uC, ci = np.unique(Cols, return_inverse=True)
        Wu = np.zeros((N, len(uR), len(uC)))
        Qu = compiled.regressor(tree, qs, qds, qdds, [int(x) for x in uR], [int(x) for x in uC], checked, Wu)
        W, Q = Wu[:, ri][:, :, ci], Qu[:, ri]
        if out is not None:
            out.reshape(W.shape)[...] = W
    if out is not None:
        W = out
    elif single:
        W = W[0]
    if wrenches is None:
        return W
    return W, (Q[0] if single else Q)


def _numpy_regressor(tree: Tree, q, qd, qdd, wrenches, rows, cols) -> Array | tuple[Array, Array]:
    qs, single = joint_array(q, tree, "q")
    qds, _ = joint_array(qd, tree, "qd")
    qdds, _ = joint_array(qdd, tree, "qdd")
    if not qs.shape == qds.shape == qdds.shape:
        raise ModelError(f"q, qd, qdd must have the same shape; got {np.shape(q)}, {np.shape(qd)}, {np.shape(qdd)}")
    R, Cols = resolve_rows(tree, rows), resolve_cols(tree, cols)
    N = qs.shape[1]
    W = np.zeros((len(R), len(Cols), N))
    Q = np.zeros((len(R), N)) if wrenches is not None else None
    plan = _plan(tree, R, Cols)
    for n0 in range(0, N, CHUNK):
        sl = slice(n0, min(N, n0 + CHUNK))
        _fill(tree, plan, qs[:, sl], qds[:, sl], qdds[:, sl], W[:, :, sl], R, Cols)
        if Q is not None:  # generalized force of the wrenches: the backward recursion of them alone
            qc = qs[:, sl]
            checked = check_wrenches(tree, slice_wrenches(wrenches, sl, N), qc.shape[1])
            mo = local_motion(tree, qc, qc, qc, frames=[k for k, _, _, _ in checked])
            F: list = [None] * (tree.n + 1)
            M: list = [None] * (tree.n + 1)
            for k, (Fe, Me) in local_wrenches(tree, qc, checked).items():
                F[k], M[k] = Fe, Me
            Q[:, sl] = backward_recursion(tree, mo, F, M)[np.array(R) - 1]
    W = np.moveaxis(W, -1, 0)
    if Q is None:
        return W[0] if single else W
    return (W[0], Q[:, 0]) if single else (W, Q.T)


def _plan(tree: Tree, R: list[int], Cols: list[int]) -> dict:
    """Which links, pairs and joint-term columns the requested block needs."""
    names = tree.parameter_names
    row_pos = {j: i for i, j in enumerate(R)}
    links: dict[int, tuple[list[int], list[int]]] = {}  # k -> (positions in Cols, parameter offsets 0..9)
    terms: list[tuple[int, int, str]] = []  # (output col, joint, term)
    couplings: list[tuple[int, object]] = []
    by_name = {c.name: c for c in tree.couplings}
    for pos, col in enumerate(Cols):
        name = names[col]
        kind = name.rstrip("0123456789")
        if name in by_name:
            couplings.append((pos, by_name[name]))
        elif kind in INERTIAL:
            k = int(name[len(kind):])
            links.setdefault(k, ([], []))
            links[k][0].append(pos)
            links[k][1].append(INERTIAL.index(kind))
        elif kind not in LOAD_TERMS:  # a load term's column is the measured wrench's: 0 here (model.tree)
            terms.append((pos, int(name[len(kind):]), kind))
    pairs = {}
    ancestors, sigma = tree.ancestors, tree.sigma  # read once: each read is a look-up beside the tree
    for k, (pos, off) in links.items():
        rows = [j for j in ancestors[k] if j in row_pos and sigma[j] != FIXED]
        if rows:
            pairs[k] = (np.array([row_pos[j] for j in rows]), rows, np.array(pos), np.array(off))
    needed = sorted({j for k, (_, rows, _, _) in pairs.items() for j in rows} | set(pairs))
    return {"pairs": pairs, "terms": terms, "couplings": couplings, "row_pos": row_pos, "frames": needed}


def _fill(tree: Tree, plan: dict, q: Array, qd: Array, qdd: Array, W: Array, R: list[int], Cols: list[int]) -> None:
    pairs = plan["pairs"]
    if pairs:
        st = forward_kinematics(tree, q, frames=plan["frames"])
        mo = local_motion(tree, q, qd, qdd, frames=list(pairs))
        ref = sum(st.P[k] for k in pairs) / len(pairs)
        axes = {j: joint_axis(tree, st, j, ref) for j in plan["frames"] if j in plan["row_pos"]}
        for k, (rpos, rows, cpos, off) in pairs.items():
            B = link_block(st, mo, k, ref)[:, off]
            S = np.stack([axes[j] for j in rows])
            W[rpos[:, None], cpos[None, :]] = np.einsum("jsn,scn->jcn", S, B)
    row_pos = plan["row_pos"]
    for pos, j, term in plan["terms"]:
        if j in row_pos:
            W[row_pos[j], pos] = joint_term_column(term, q[j - 1], qd[j - 1], qdd[j - 1], tree.friction_law(j),
                                                   tree.knee(j))
    idx = np.array(R) - 1
    for pos, c in plan["couplings"]:
        W[:, pos] = coupling_column(c, q, qd, qdd, tree.n)[idx]
