"""Compiled (Numba) inverse dynamics and identification model: the default numeric engine.

The batched NumPy engine (newton_euler, regressor) streams each operation over all
samples; here the loop over samples runs inside machine code and every sample walks
the tree once, with its per-frame quantities in registers and L1 cache. The kernels
are generic: the tree enters as flat arrays (antecedents, sigma, constant rotations
and offsets, inertial parameters, joint terms, couplings, wrench sites), so they are
compiled once per machine, whatever the model, and cached on disk (numba cache=True:
next to this file when it is writable, else under Numba's user cache directory, or
NUMBA_CACHE_DIR when set).

- `inverse_dynamics`: Khalil's Newton-Euler in link frames; only the frames on the
  paths to links with mass or an external wrench are visited.
- `regressor`: per link k the 6 x 10 block of force and moment (about a per-sample
  reference point O*, the centroid of the link origins: precision does not depend
  on where the system is) per unit inertial parameter, in frame-0 orientation, put
  at its output columns; then each requested row j is the projection of those blocks
  on joint j's axis, over the runs of consecutive columns that belong to j's
  descendants (long vectorized loops, sequential writes). Only requested rows and
  columns are computed. Entries outside that structure (links that are not
  descendants of the row's joint, joint terms of other joints, rows of fixed frames)
  are never written, so a caller's zeroed `out` buffer keeps its zeros and can be
  reused for the same rows and columns; inertia columns on prismatic rows lie
  inside the runs and receive an exact 0.

The NumPy engine stays the reference (backend="numpy"); without numba every call
falls back to it (see newton_euler.resolve_backend).
"""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Sequence

import numpy as np

from ..kinematics.forward import frame_plan, joint_array
from ..kinematics.per_tree import PerTree
from ..model.tree import CURVE_TERMS, FIXED, INERTIAL, LOAD_TERMS, REVOLUTE, Tree
from . import trig

try:  # numba is a runtime dependency, but an install without it must still work
    from numba import njit as _njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False

Array = np.ndarray
# FVPL FVPH FVNL FVNH: the viscous curve's slopes (model.tree), the knee in the regressor kernel's t_w
_TERM_CODE = {"IA": 0, "FV": 1, "FS": 2, "OFF": 3, "K": 4, "KQ": 5, "FVPL": 6, "FVPH": 7, "FVNL": 8, "FVNH": 9}
_SMOOTH_FS = 10  # an FS term whose law is tanh or sigmoid (the regressor kernel's term kind)
_COUPLING_CODE = {"K": 0, "IA": 1, "FV": 2, "FS": 3}
# fused multiply-add only: no reassociation (_sincos, which relies on the order of operations, has none)
_FASTMATH = {"contract"}


def _jit(fn):
    """njit with an on-disk cache; nogil so that threads calling the engine run in parallel."""
    return _njit(cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)(fn) if HAVE_NUMBA else fn


def _inline(fn):
    """A helper that takes arrays, inlined into its caller by Numba: a real call would pass each array
    as a struct and reference-count it, which costs more than the helper's arithmetic."""
    return _njit(inline="always", cache=True, error_model="numpy", fastmath=_FASTMATH)(fn) if HAVE_NUMBA else fn


# ----------------------------------------------------------------------------------------
# small vector helpers (inlined by LLVM)
# ----------------------------------------------------------------------------------------


@_jit
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@_jit
def _mul(R, j, x0, x1, x2):
    """R[j] x."""
    return (R[j, 0, 0] * x0 + R[j, 0, 1] * x1 + R[j, 0, 2] * x2,
            R[j, 1, 0] * x0 + R[j, 1, 1] * x1 + R[j, 1, 2] * x2,
            R[j, 2, 0] * x0 + R[j, 2, 1] * x1 + R[j, 2, 2] * x2)


@_jit
def _mul_t(R, j, x0, x1, x2):
    """R[j]^T x."""
    return (R[j, 0, 0] * x0 + R[j, 1, 0] * x1 + R[j, 2, 0] * x2,
            R[j, 0, 1] * x0 + R[j, 1, 1] * x1 + R[j, 2, 1] * x2,
            R[j, 0, 2] * x0 + R[j, 1, 2] * x1 + R[j, 2, 2] * x2)


# sine and cosine together: dynamics.trig's steps, the ones every generated target runs, within an ulp of
# libm and about four times faster than math.sin + math.cos, which would otherwise be a quarter of the
# inverse dynamics of a 42-frame tree. Contracted into FMA like the kernels (uncontracted, a PUMA's inverse
# dynamics took 0.30 us a sample instead of 0.26): within an ulp of the generated targets, which agree to the bit.
# Its one signature given, so that it is compiled (or loaded) here with its own flags: compiled lazily, its first
# compile came from whichever kernel called it first and Numba cached that code as its own
_sincos = (_njit("UniTuple(float64, 2)(float64)", cache=True, nogil=True, error_model="numpy", fastmath=_FASTMATH)(
    trig.python_function("_sincos")) if HAVE_NUMBA else trig.python_function("_sincos"))


@_jit
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@_inline
def _local_rotation(R, E, j, revolute, th):
    """R[j] = aR_j = E_j Rot(z, th) (E_j alone when not revolute)."""
    if revolute:
        s, c = _sincos(th)
        for i in range(3):
            e0, e1 = E[j, i, 0], E[j, i, 1]
            R[j, i, 0] = c * e0 + s * e1
            R[j, i, 1] = c * e1 - s * e0
            R[j, i, 2] = E[j, i, 2]
    else:
        for i in range(3):
            for k in range(3):
                R[j, i, k] = E[j, i, k]


@_inline
def _curve(kind, v, knee):
    """The viscous curve's column of kind 6 FVPL clip(v, 0, knee), 7 FVPH max(v - knee, 0), 8 FVNL
    clip(v, knee, 0) or 9 FVNH min(v - knee, 0) (knee: v+ for 6 and 7, v- for 8 and 9)."""
    if kind == 6:
        return min(max(v, 0.0), knee)
    if kind == 7:
        return max(v - knee, 0.0)
    if kind == 8:
        return max(min(v, 0.0), knee)
    return min(v - knee, 0.0)


@_inline
def _joint_terms(tau_row, q, qd, qdd, jt, has_jt, fs_w, knee):
    """IA qdd + FV qd + FS s(qd) + OFF + K q + KQ q² + the viscous curve added to tau_row (one sample); s = sign
    where fs_w[j] is 0, else tanh(qd / fs_w[j]) (fs_w: vs for tanh, 2 vs for sigmoid, see _friction_widths);
    knee[j]: (v-, v+) of the curve (_curve)."""
    for j in range(1, jt.shape[0]):
        if has_jt[j]:
            x, v, a = q[j - 1], qd[j - 1], qdd[j - 1]
            c = _sign(v) if fs_w[j] == 0.0 else math.tanh(v / fs_w[j])
            tau_row[j - 1] += jt[j, 0] * a + jt[j, 1] * v + jt[j, 2] * c + jt[j, 3] + (jt[j, 4] + jt[j, 5] * x) * x
            if jt[j, 6] != 0.0 or jt[j, 7] != 0.0 or jt[j, 8] != 0.0 or jt[j, 9] != 0.0:
                lo, hi = knee[j, 0], knee[j, 1]
                tau_row[j - 1] += (jt[j, 6] * _curve(6, v, hi) + jt[j, 7] * _curve(7, v, hi)
                                   + jt[j, 8] * _curve(8, v, lo) + jt[j, 9] * _curve(9, v, lo))


@_inline
def _coupling_value(kind, ptr0, ptr1, joint, coef, q, qd, qdd):
    """c . q (K), c . qdd (IA), c . qd (FV) or sign(c . qd) (FS) for one sample."""
    acc = 0.0
    for i in range(ptr0, ptr1):
        j = joint[i] - 1
        acc += coef[i] * (q[j] if kind == 0 else qdd[j] if kind == 1 else qd[j])
    return _sign(acc) if kind == 3 else acc


@_inline
def _world_rotations(R, Rw, ant, world, n):
    """0R_j = 0R_a aR_j for the frames flagged in `world` (an ancestor-closed set)."""
    for j in range(1, n + 1):
        if world[j]:
            a = ant[j]
            for i in range(3):
                r0, r1, r2 = Rw[a, i, 0], Rw[a, i, 1], Rw[a, i, 2]
                for k in range(3):
                    Rw[j, i, k] = r0 * R[j, 0, k] + r1 * R[j, 1, k] + r2 * R[j, 2, k]


# ----------------------------------------------------------------------------------------
# inverse dynamics kernel
# ----------------------------------------------------------------------------------------


@_jit
def _idm_kernel(q, qd, qdd, ant, sigma, E, u, th0, r0, g, inert, todo, massive, world,
                jt, has_jt, fs_w, knee, cp_ptr, cp_joint, cp_coef, cp_kind, cp_val,
                w_link, w_frame, w_point, w_vals, tau):
    """Newton-Euler per sample into tau (N, n); joint terms and couplings included.

    One function on purpose: split into helpers that take the per-frame arrays (called, or
    inlined by Numba), it measured 1.5 to 2.5 times slower.
    """
    N, n = q.shape[0], ant.shape[0] - 1
    R = np.zeros((n + 1, 3, 3))
    Rw = np.zeros((n + 1, 3, 3))
    for i in range(3):
        Rw[0, i, i] = 1.0
    p = np.zeros((n + 1, 3))
    w = np.zeros((n + 1, 3))
    dw = np.zeros((n + 1, 3))
    dv = np.zeros((n + 1, 3))
    f = np.zeros((n + 1, 3))
    m = np.zeros((n + 1, 3))
    dv[0, 0], dv[0, 1], dv[0, 2] = -g[0], -g[1], -g[2]
    nw = w_link.shape[0]
    for s in range(N):
        for j in range(1, n + 1):  # forward recursion in link frames (Khalil)
            if not todo[j]:
                continue
            a, sj = ant[j], sigma[j]
            _local_rotation(R, E, j, sj == 0, th0[j] + q[s, j - 1])
            rj = r0[j] + q[s, j - 1] if sj == 1 else r0[j]
            p0, p1, p2 = u[j, 0] + rj * E[j, 0, 2], u[j, 1] + rj * E[j, 1, 2], u[j, 2] + rj * E[j, 2, 2]
            p[j, 0], p[j, 1], p[j, 2] = p0, p1, p2
            wa0, wa1, wa2 = w[a, 0], w[a, 1], w[a, 2]
            da0, da1, da2 = dw[a, 0], dw[a, 1], dw[a, 2]
            # dv_a + U_a p = dv_a + dw_a x p + w_a x (w_a x p), then into frame j
            c0, c1, c2 = _cross(wa0, wa1, wa2, p0, p1, p2)
            c0, c1, c2 = _cross(wa0, wa1, wa2, c0, c1, c2)
            e0, e1, e2 = _cross(da0, da1, da2, p0, p1, p2)
            x0, x1, x2 = _mul_t(R, j, dv[a, 0] + c0 + e0, dv[a, 1] + c1 + e1, dv[a, 2] + c2 + e2)
            w0, w1, w2 = _mul_t(R, j, wa0, wa1, wa2)
            y0, y1, y2 = _mul_t(R, j, da0, da1, da2)
            v, acc = qd[s, j - 1], qdd[s, j - 1]
            if sj == 0:  # (jR_a w_a) x z = (w1, -w0, 0)
                y0, y1, y2 = y0 + v * w1, y1 - v * w0, y2 + acc
                w2 += v
            elif sj == 1:
                x0, x1, x2 = x0 + 2.0 * v * w1, x1 - 2.0 * v * w0, x2 + acc
            w[j, 0], w[j, 1], w[j, 2] = w0, w1, w2
            dw[j, 0], dw[j, 1], dw[j, 2] = y0, y1, y2
            dv[j, 0], dv[j, 1], dv[j, 2] = x0, x1, x2
            # link wrench about O_j in frame j (zero for the massless links on the path)
            f[j, 0] = f[j, 1] = f[j, 2] = m[j, 0] = m[j, 1] = m[j, 2] = 0.0
            if massive[j]:
                XX, XY, XZ, YY, YZ, ZZ = inert[j, 0], inert[j, 1], inert[j, 2], inert[j, 3], inert[j, 4], inert[j, 5]
                mx, my, mz, M = inert[j, 6], inert[j, 7], inert[j, 8], inert[j, 9]
                a0, a1, a2 = _cross(w0, w1, w2, mx, my, mz)
                a0, a1, a2 = _cross(w0, w1, w2, a0, a1, a2)
                b0, b1, b2 = _cross(y0, y1, y2, mx, my, mz)
                f[j, 0], f[j, 1], f[j, 2] = M * x0 + a0 + b0, M * x1 + a1 + b1, M * x2 + a2 + b2
                jw0, jw1, jw2 = XX * w0 + XY * w1 + XZ * w2, XY * w0 + YY * w1 + YZ * w2, XZ * w0 + YZ * w1 + ZZ * w2
                a0, a1, a2 = _cross(w0, w1, w2, jw0, jw1, jw2)
                b0, b1, b2 = _cross(mx, my, mz, x0, x1, x2)
                m[j, 0] = XX * y0 + XY * y1 + XZ * y2 + a0 + b0
                m[j, 1] = XY * y0 + YY * y1 + YZ * y2 + a1 + b1
                m[j, 2] = XZ * y0 + YZ * y1 + ZZ * y2 + a2 + b2
        # external wrenches, exerted by the environment on the link: subtracted
        if nw:
            _world_rotations(R, Rw, ant, world, n)
        for i in range(nw):
            k, e = w_link[i], w_frame[i]
            si = s if w_vals.shape[1] > 1 else 0
            F0, F1, F2 = w_vals[i, si, 0], w_vals[i, si, 1], w_vals[i, si, 2]
            M0, M1, M2 = w_vals[i, si, 3], w_vals[i, si, 4], w_vals[i, si, 5]
            if e != k:  # components given in frame e: to frame k through frame 0
                F0, F1, F2 = _mul(Rw, e, F0, F1, F2)
                F0, F1, F2 = _mul_t(Rw, k, F0, F1, F2)
                M0, M1, M2 = _mul(Rw, e, M0, M1, M2)
                M0, M1, M2 = _mul_t(Rw, k, M0, M1, M2)
            c0, c1, c2 = _cross(w_point[i, 0], w_point[i, 1], w_point[i, 2], F0, F1, F2)
            f[k, 0] -= F0
            f[k, 1] -= F1
            f[k, 2] -= F2
            m[k, 0] -= M0 + c0
            m[k, 1] -= M1 + c1
            m[k, 2] -= M2 + c2
        # backward recursion: each joint takes the z component of what its subtree needs
        for j in range(1, n + 1):
            tau[s, j - 1] = 0.0
        for j in range(n, 0, -1):
            if not todo[j]:
                continue
            sj = sigma[j]
            if sj == 0:
                tau[s, j - 1] = m[j, 2]
            elif sj == 1:
                tau[s, j - 1] = f[j, 2]
            a = ant[j]
            if a > 0:
                fa0, fa1, fa2 = _mul(R, j, f[j, 0], f[j, 1], f[j, 2])
                ma0, ma1, ma2 = _mul(R, j, m[j, 0], m[j, 1], m[j, 2])
                c0, c1, c2 = _cross(p[j, 0], p[j, 1], p[j, 2], fa0, fa1, fa2)
                f[a, 0] += fa0
                f[a, 1] += fa1
                f[a, 2] += fa2
                m[a, 0] += ma0 + c0
                m[a, 1] += ma1 + c1
                m[a, 2] += ma2 + c2
        _joint_terms(tau[s], q[s], qd[s], qdd[s], jt, has_jt, fs_w, knee)
        for c in range(cp_kind.shape[0]):
            x = cp_val[c] * _coupling_value(cp_kind[c], cp_ptr[c], cp_ptr[c + 1], cp_joint, cp_coef,
                                            q[s], qd[s], qdd[s])
            for i in range(cp_ptr[c], cp_ptr[c + 1]):
                tau[s, cp_joint[i] - 1] += cp_coef[i] * x


# ----------------------------------------------------------------------------------------
# regressor kernel
# ----------------------------------------------------------------------------------------


@_inline
def _inertia_row(B, m, li, i, x, y, z, ox, oy, oz, w0, w1, w2, d0, d1, d2):
    """Component i of the moments of the six inertia columns: h + om x g with g = R E w, h = R E dw."""
    B[3 + i, m[li, 0]] = d0 * x + w0 * ox
    B[3 + i, m[li, 1]] = d1 * x + d0 * y + w1 * ox + w0 * oy
    B[3 + i, m[li, 2]] = d2 * x + d0 * z + w2 * ox + w0 * oz
    B[3 + i, m[li, 3]] = d1 * y + w1 * oy
    B[3 + i, m[li, 4]] = d2 * y + d1 * z + w2 * oy + w1 * oz
    B[3 + i, m[li, 5]] = d2 * z + w2 * oz


@_inline
def _link_block(B, m, li, Rw, P, om, dom, dv, k, o0, o1, o2):
    """Force and moment about O* per unit inertial parameter of link k (the li-th), frame-0 axes,
    into the columns m[li, 0..9] of B (6, C+1).

    The force rows of the inertia columns are zero and never written. With x, y, z the axes of
    frame k and om, dom, dv its motion: inertia basis E (in frame k) gives the moment
    R (E dw + w x E w) = R E dw + om x (R E w); a first moment along axis x gives the force
    dom x x + om x (om x x) and the moment x x dv; the mass gives the force dv.
    """
    W0, W1, W2 = om[k, 0], om[k, 1], om[k, 2]
    D0, D1, D2 = dom[k, 0], dom[k, 1], dom[k, 2]
    A0, A1, A2 = dv[k, 0], dv[k, 1], dv[k, 2]
    x0, x1, x2 = Rw[k, 0, 0], Rw[k, 1, 0], Rw[k, 2, 0]
    y0, y1, y2 = Rw[k, 0, 1], Rw[k, 1, 1], Rw[k, 2, 1]
    z0, z1, z2 = Rw[k, 0, 2], Rw[k, 1, 2], Rw[k, 2, 2]
    w0, w1, w2 = _mul_t(Rw, k, W0, W1, W2)
    d0, d1, d2 = _mul_t(Rw, k, D0, D1, D2)
    ox0, ox1, ox2 = _cross(W0, W1, W2, x0, x1, x2)
    oy0, oy1, oy2 = _cross(W0, W1, W2, y0, y1, y2)
    oz0, oz1, oz2 = _cross(W0, W1, W2, z0, z1, z2)
    _inertia_row(B, m, li, 0, x0, y0, z0, ox0, oy0, oz0, w0, w1, w2, d0, d1, d2)
    _inertia_row(B, m, li, 1, x1, y1, z1, ox1, oy1, oz1, w0, w1, w2, d0, d1, d2)
    _inertia_row(B, m, li, 2, x2, y2, z2, ox2, oy2, oz2, w0, w1, w2, d0, d1, d2)
    r0, r1, r2 = P[k, 0] - o0, P[k, 1] - o1, P[k, 2] - o2
    _moment_column(B, m[li, 6], x0, x1, x2, ox0, ox1, ox2, W0, W1, W2, D0, D1, D2, A0, A1, A2, r0, r1, r2)
    _moment_column(B, m[li, 7], y0, y1, y2, oy0, oy1, oy2, W0, W1, W2, D0, D1, D2, A0, A1, A2, r0, r1, r2)
    _moment_column(B, m[li, 8], z0, z1, z2, oz0, oz1, oz2, W0, W1, W2, D0, D1, D2, A0, A1, A2, r0, r1, r2)
    l0, l1, l2 = _cross(r0, r1, r2, A0, A1, A2)  # mass: force dv, moment (P_k - O*) x dv
    c = m[li, 9]
    B[0, c], B[1, c], B[2, c] = A0, A1, A2
    B[3, c], B[4, c], B[5, c] = l0, l1, l2


@_inline
def _moment_column(B, c, x0, x1, x2, ox0, ox1, ox2, W0, W1, W2, D0, D1, D2, A0, A1, A2, r0, r1, r2):
    """Column c of a first moment along axis x (ox = om x x): force and moment about O*."""
    a0, a1, a2 = _cross(W0, W1, W2, ox0, ox1, ox2)
    b0, b1, b2 = _cross(D0, D1, D2, x0, x1, x2)
    F0, F1, F2 = a0 + b0, a1 + b1, a2 + b2
    n0, n1, n2 = _cross(x0, x1, x2, A0, A1, A2)
    l0, l1, l2 = _cross(r0, r1, r2, F0, F1, F2)
    B[0, c], B[1, c], B[2, c] = F0, F1, F2
    B[3, c], B[4, c], B[5, c] = n0 + l0, n1 + l1, n2 + l2


@_jit
def _reg_kernel(q, qd, qdd, ant, sigma, E, u, th0, r0, g, todo, motion, axis, ref,
                links, colmap, r_joint, r_rpos, r_ptr, run_lo, run_hi,
                t_joint, t_kind, t_rpos, t_cpos, t_w,
                c_kind, c_cpos, c_ptr, c_joint, c_coef, c_rpos,
                w_link, w_frame, w_point, w_vals, wq_ptr, wq_joint, wq_rpos, W, Q):
    """Identification model per sample into W (N, R, C) (see the module doc for what is written) and Q (N, R).

    One function, like _idm_kernel, for the same measured reason.
    """
    N, n = q.shape[0], ant.shape[0] - 1
    Rw = np.zeros((n + 1, 3, 3))
    for i in range(3):
        Rw[0, i, i] = 1.0
    P = np.zeros((n + 1, 3))
    om = np.zeros((n + 1, 3))
    dom = np.zeros((n + 1, 3))
    dv = np.zeros((n + 1, 3))
    S = np.zeros((n + 1, 6))
    BB = np.zeros((6, W.shape[2] + 1))  # link blocks at their output columns (+ a spare for the unasked)
    dv[0, 0], dv[0, 1], dv[0, 2] = -g[0], -g[1], -g[2]
    nref = max(ref.shape[0], 1)
    for s in range(N):
        # forward: poses and, along the paths to the links, motion, all in frame-0 axes
        for j in range(1, n + 1):
            if not todo[j]:
                continue
            a, sj = ant[j], sigma[j]
            c, sn = 1.0, 0.0
            if sj == 0:
                sn, c = _sincos(th0[j] + q[s, j - 1])
            for i in range(3):  # row i of 0R_a E_j, then the joint rotation about z
                r0_, r1_, r2_ = Rw[a, i, 0], Rw[a, i, 1], Rw[a, i, 2]
                A0 = r0_ * E[j, 0, 0] + r1_ * E[j, 1, 0] + r2_ * E[j, 2, 0]
                A1 = r0_ * E[j, 0, 1] + r1_ * E[j, 1, 1] + r2_ * E[j, 2, 1]
                Rw[j, i, 0] = c * A0 + sn * A1
                Rw[j, i, 1] = c * A1 - sn * A0
                Rw[j, i, 2] = r0_ * E[j, 0, 2] + r1_ * E[j, 1, 2] + r2_ * E[j, 2, 2]
            z0, z1, z2 = Rw[j, 0, 2], Rw[j, 1, 2], Rw[j, 2, 2]
            rj = r0[j] + q[s, j - 1] if sj == 1 else r0[j]
            d0, d1, d2 = _mul(Rw, a, u[j, 0], u[j, 1], u[j, 2])
            d0, d1, d2 = d0 + rj * z0, d1 + rj * z1, d2 + rj * z2
            P[j, 0], P[j, 1], P[j, 2] = P[a, 0] + d0, P[a, 1] + d1, P[a, 2] + d2
            if not motion[j]:
                continue
            W0, W1, W2 = om[a, 0], om[a, 1], om[a, 2]
            D0, D1, D2 = dom[a, 0], dom[a, 1], dom[a, 2]
            # dv_j = dv_a + dom_a x d + om_a x (om_a x d)
            a0, a1, a2 = _cross(W0, W1, W2, d0, d1, d2)
            a0, a1, a2 = _cross(W0, W1, W2, a0, a1, a2)
            b0, b1, b2 = _cross(D0, D1, D2, d0, d1, d2)
            x0, x1, x2 = dv[a, 0] + a0 + b0, dv[a, 1] + a1 + b1, dv[a, 2] + a2 + b2
            v, acc = qd[s, j - 1], qdd[s, j - 1]
            k0, k1, k2 = _cross(W0, W1, W2, z0, z1, z2)
            if sj == 0:
                W0, W1, W2 = W0 + v * z0, W1 + v * z1, W2 + v * z2
                D0, D1, D2 = D0 + acc * z0 + v * k0, D1 + acc * z1 + v * k1, D2 + acc * z2 + v * k2
            elif sj == 1:
                x0, x1, x2 = x0 + acc * z0 + 2.0 * v * k0, x1 + acc * z1 + 2.0 * v * k1, x2 + acc * z2 + 2.0 * v * k2
            om[j, 0], om[j, 1], om[j, 2] = W0, W1, W2
            dom[j, 0], dom[j, 1], dom[j, 2] = D0, D1, D2
            dv[j, 0], dv[j, 1], dv[j, 2] = x0, x1, x2
        # O*: the centroid of the link origins (0 without links)
        o0 = o1 = o2 = 0.0
        for i in range(ref.shape[0]):
            o0 += P[ref[i], 0]
            o1 += P[ref[i], 1]
            o2 += P[ref[i], 2]
        o0, o1, o2 = o0 / nref, o1 / nref, o2 / nref
        # joint axes as selectors of a (force, moment about O*) wrench
        for j in range(1, n + 1):
            if axis[j]:
                z0, z1, z2 = Rw[j, 0, 2], Rw[j, 1, 2], Rw[j, 2, 2]
                if sigma[j] == 0:
                    S[j, 0], S[j, 1], S[j, 2] = _cross(P[j, 0] - o0, P[j, 1] - o1, P[j, 2] - o2, z0, z1, z2)
                    S[j, 3], S[j, 4], S[j, 5] = z0, z1, z2
                else:
                    S[j, 0], S[j, 1], S[j, 2] = z0, z1, z2
                    S[j, 3] = S[j, 4] = S[j, 5] = 0.0
        # rigid-body columns: the link blocks at their columns, then each requested row over the runs
        # of consecutive columns of its descendants (unsigned bounds: vector loads and stores, see _u64)
        for li in range(links.shape[0]):
            _link_block(BB, colmap, li, Rw, P, om, dom, dv, links[li], o0, o1, o2)
        for ri in range(r_joint.shape[0]):
            j, rp = r_joint[ri], r_rpos[ri]
            s0, s1, s2, s3, s4, s5 = S[j, 0], S[j, 1], S[j, 2], S[j, 3], S[j, 4], S[j, 5]
            for run in range(r_ptr[ri], r_ptr[ri + 1]):
                for c in range(run_lo[run], run_hi[run]):
                    W[s, rp, c] = (s0 * BB[0, c] + s1 * BB[1, c] + s2 * BB[2, c]
                                   + s3 * BB[3, c] + s4 * BB[4, c] + s5 * BB[5, c])
        # joint terms: IA qdd, FV qd, FS sign(qd) or tanh(qd / w), OFF 1, K q on their own row; couplings
        for t in range(t_joint.shape[0]):
            j, kind = t_joint[t] - 1, t_kind[t]
            if kind == 0:
                x = qdd[s, j]
            elif kind == 1:
                x = qd[s, j]
            elif kind == 2:
                x = _sign(qd[s, j])
            elif kind == 3:
                x = 1.0
            elif kind == 4:
                x = q[s, j]
            elif kind == 5:
                x = q[s, j] * q[s, j]
            elif kind <= 9:  # the viscous curve, t_w: its knee
                x = _curve(kind, qd[s, j], t_w[t])
            else:  # _SMOOTH_FS
                x = math.tanh(qd[s, j] / t_w[t])
            W[s, t_rpos[t], t_cpos[t]] = x
        for c in range(c_kind.shape[0]):
            x = _coupling_value(c_kind[c], c_ptr[c], c_ptr[c + 1], c_joint, c_coef, q[s], qd[s], qdd[s])
            for i in range(c_ptr[c], c_ptr[c + 1]):
                if c_rpos[i] >= 0:
                    W[s, c_rpos[i], c_cpos[c]] = c_coef[i] * x
        # generalized force of the external wrenches (the known right-hand side)
        for i in range(w_link.shape[0]):
            k, e = w_link[i], w_frame[i]
            si = s if w_vals.shape[1] > 1 else 0
            F0, F1, F2 = _mul(Rw, e, w_vals[i, si, 0], w_vals[i, si, 1], w_vals[i, si, 2])
            M0, M1, M2 = _mul(Rw, e, w_vals[i, si, 3], w_vals[i, si, 4], w_vals[i, si, 5])
            x0, x1, x2 = _mul(Rw, k, w_point[i, 0], w_point[i, 1], w_point[i, 2])
            c0, c1, c2 = _cross(P[k, 0] + x0 - o0, P[k, 1] + x1 - o1, P[k, 2] + x2 - o2, F0, F1, F2)
            M0, M1, M2 = M0 + c0, M1 + c1, M2 + c2
            for pi in range(wq_ptr[i], wq_ptr[i + 1]):
                j = wq_joint[pi]
                Q[s, wq_rpos[pi]] += (S[j, 0] * F0 + S[j, 1] * F1 + S[j, 2] * F2
                                      + S[j, 3] * M0 + S[j, 4] * M1 + S[j, 5] * M2)


# ----------------------------------------------------------------------------------------
# Python side: flat arrays from the tree, plans, entry points
# ----------------------------------------------------------------------------------------


def _i64(x) -> Array:
    return np.ascontiguousarray(np.asarray(x, dtype=np.int64).reshape(-1))


def _u64(x) -> Array:
    """Unsigned indices: Numba then skips the negative-index wrap-around, which would turn a
    contiguous loop into gathers and scatters."""
    return np.ascontiguousarray(np.asarray(x, dtype=np.uint64).reshape(-1))


def _f64(x, shape=None) -> Array:
    a = np.ascontiguousarray(np.asarray(x, dtype=float))
    return a.reshape(shape) if shape is not None else a


def _ancestor_mask(geo: dict, frames) -> Array:
    """Mask (n+1,) of the frames on the paths from the base to the given frames (geo: `Workspace.geometry`)."""
    idx = np.fromiter(frames, dtype=np.intp)
    anc = geo["anc"]
    return anc[idx].any(axis=0) if idx.size else np.zeros(anc.shape[0], dtype=np.bool_)


def _geometry(tree: Tree) -> dict:
    plan = frame_plan(tree)
    E = np.tile(np.eye(3), (tree.n + 1, 1, 1))
    u = np.zeros((tree.n + 1, 3))
    anc = np.zeros((tree.n + 1, tree.n + 1), dtype=np.bool_)
    for j in range(1, tree.n + 1):
        E[j], u[j] = plan[j][0], plan[j][2]
        anc[j, tree.ancestors[j]] = True
    th0 = np.where(tree.sigma == REVOLUTE, tree.theta0, 0.0)  # theta is folded into E otherwise
    xx = np.array([tree.index[f"XX{j}"] for j in range(1, tree.n + 1)], dtype=np.intp)
    return {"ant": _i64(np.maximum(tree.ant, 0)), "sigma": _i64(tree.sigma), "E": _f64(E), "u": _f64(u),
            "th0": _f64(th0), "r0": _f64(tree.r0), "g": _f64(tree.gravity), "anc": anc,
            "inertial": xx[:, None] + np.arange(10), "fs_w": _friction_widths(tree),
            "knee": _f64([tree.knee(j) for j in range(tree.n + 1)], (tree.n + 1, 2))}


_X_CACHE_SIZE = 8  # parameter vectors kept per tree
_PLAN_CACHE_SIZE = 16  # regressor plans (rows, columns) kept per tree


class Workspace:
    """What the kernels take from one tree besides the samples (the model side of Pinocchio's Model/Data):

    - `geometry`: the tree as flat arrays: ant, sigma, E, u, th0, r0, g, and for the Python side the ancestor
      matrix `anc`, where each link's inertial parameters start (`inertial`), fs_w and knee;
    - `parameter_arrays(X bytes, inertia_only)`: the arrays that depend on the parameter values (the last
      _X_CACHE_SIZE values kept: a model evaluated again and again with the same X pays for them once);
    - `regressor_plan(rows, cols)`: what a requested block of the regressor needs (_PLAN_CACHE_SIZE kept).

    All pure functions of the tree, so one workspace per tree serves every thread (functools.lru_cache is
    thread-safe: no lock of ours); the kernels' per-sample scratch lives inside them. The workspace refers to
    its tree weakly: `workspace(tree)` keeps it beside the tree, never inside it, and never keeps it alive.
    """

    def __init__(self, tree: Tree) -> None:
        self._tree = weakref.ref(tree)
        self.geometry = _geometry(tree)
        self.parameter_arrays = functools.lru_cache(_X_CACHE_SIZE)(self._parameter_arrays)
        self.regressor_plan = functools.lru_cache(_PLAN_CACHE_SIZE)(self._regressor_plan)

    @property
    def tree(self) -> Tree:
        tree = self._tree()
        if tree is None:
            raise ReferenceError("compiled.Workspace: its tree was garbage collected; make one from a live tree")
        return tree

    def _parameter_arrays(self, xb: bytes, inertia_only: bool) -> dict:
        tree, X = self.tree, np.frombuffer(xb)
        inert = np.zeros((tree.n + 1, 10))
        inert[1:] = X[self.geometry["inertial"]]
        massive = inert.any(axis=1)
        jt, has_jt = _joint_coefficients(tree, X, inertia_only)
        return {"inert": inert, "massive": massive, "jt": jt, "has_jt": has_jt,
                "todo": _ancestor_mask(self.geometry, np.flatnonzero(massive)),
                "couplings": _coupling_arrays(tree, X, inertia_only)}

    def _regressor_plan(self, R: tuple[int, ...], Cols: tuple[int, ...]) -> dict:
        return _build_plan(self.tree, self.geometry, list(R), list(Cols))


workspace = PerTree(Workspace)
workspace.__doc__ = "The `Workspace` of a tree, made at its first use and kept while the tree lives."


def geometry(tree: Tree) -> dict:
    """The tree as flat arrays (`Workspace.geometry`)."""
    return workspace(tree).geometry


def regressor_plan(tree: Tree, R: Sequence[int], Cols: Sequence[int]) -> dict:
    """What the requested block needs, as flat arrays (`Workspace.regressor_plan`)."""
    return workspace(tree).regressor_plan(tuple(R), tuple(Cols))


def _friction_widths(tree: Tree) -> Array:
    """(n+1,) per frame: 0 for the sign law, else w with s(qd) = tanh(qd / w): vs (tanh) or 2 vs (sigmoid)."""
    w = np.zeros(tree.n + 1)
    for j, (shape, vs) in tree.friction_shape.items():
        w[j] = vs if shape == "tanh" else 2.0 * vs
    return w


def _wrench_arrays(checked: list, N: int) -> tuple[Array, Array, Array, Array]:
    """(link, frame, point (nw, 3), values (nw, N or 1, 6)) from newton_euler.check_wrenches."""
    nw = len(checked)
    per_sample = any(vals.shape[1] > 1 for _, _, vals, _ in checked)
    Nv = N if per_sample else 1
    vals = np.empty((nw, Nv, 6))
    for i, (_, _, v, _) in enumerate(checked):
        vals[i] = np.broadcast_to(v.T, (Nv, 6))
    return (_i64([c[0] for c in checked]), _i64([c[1] for c in checked]),
            _f64([c[3] for c in checked], (nw, 3)), vals)


def joint_rows(x: object, tree: Tree, name: str) -> tuple[Array, bool]:
    """A joint array as samples-first (N, n) float64, C-contiguous (no copy when it already is), and
    whether it was one sample; the checks and errors of kinematics.forward.joint_array."""
    a = np.asarray(x, dtype=float)
    single = a.ndim == 1
    if single:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != tree.n or not np.isfinite(a).all():
        joint_array(x, tree, name)  # raises the engine's message (shape, or frame and sample of a NaN)
    if not a.flags.writeable:  # a read-only array is another Numba type: a copy avoids a second compilation
        return np.array(a, order="C"), single
    return np.ascontiguousarray(a), single


def inverse_dynamics(tree: Tree, q: Array, qd: Array, qdd: Array, X: Array, checked: list, *,
                     gravity: bool = True, inertia_only: bool = False) -> Array:
    """tau (N, n) from samples-first (N, n) joint arrays (see joint_rows); X and the wrenches already checked.

    gravity=False and inertia_only=True (IA terms and IA couplings only) serve the inertia matrix.
    """
    ws = workspace(tree)
    geo, xa = ws.geometry, ws.parameter_arrays(X.tobytes(), inertia_only)  # X: float64 (checked)
    N, n = q.shape
    todo, world = xa["todo"], np.zeros(n + 1, dtype=np.bool_)
    if checked:
        todo = todo | _ancestor_mask(geo, [x for c in checked for x in c[:2]])
        world = _ancestor_mask(geo, [x for c in checked if c[0] != c[1] for x in (c[0], c[1])])
    wl, we, wp, wv = _wrench_arrays(checked, N)
    tau = np.empty((N, n))
    _idm_kernel(q, qd, qdd, geo["ant"], geo["sigma"], geo["E"], geo["u"], geo["th0"], geo["r0"],
                geo["g"] if gravity else np.zeros(3), xa["inert"], todo, xa["massive"], world,
                xa["jt"], xa["has_jt"], geo["fs_w"], geo["knee"], *xa["couplings"], wl, we, wp, wv, tau)
    return tau


def _joint_coefficients(tree: Tree, X: Array, inertia_only: bool) -> tuple[Array, Array]:
    jt = np.zeros((tree.n + 1, len(_TERM_CODE)))
    for j, terms in tree.joint_terms.items():
        for t in terms:
            if t == "IA" or not inertia_only:
                jt[j, _TERM_CODE[t]] = X[tree.index[f"{t}{j}"]]
    return jt, jt.any(axis=1)


def _coupling_arrays(tree: Tree, X: Array, inertia_only: bool) -> tuple[Array, ...]:
    """CSR arrays (ptr, joint, coef, kind, value) of the couplings with a non-zero value."""
    used = [c for c in tree.couplings
            if X[tree.index[c.name]] != 0.0 and (c.kind == "IA" or not inertia_only)]
    ptr = np.cumsum([0] + [len(c.coeffs) for c in used])
    joints = [j for c in used for j in c.coeffs]
    coefs = [x for c in used for x in c.coeffs.values()]
    return (_i64(ptr), _i64(joints), _f64(coefs, (len(coefs),)), _i64([_COUPLING_CODE[c.kind] for c in used]),
            _f64([X[tree.index[c.name]] for c in used], (len(used),)))


# ----- regressor -----------------------------------------------------------------------------

def _build_plan(tree: Tree, geo: dict, R: list[int], Cols: list[int]) -> dict:
    names = tree.parameter_names
    widths = _friction_widths(tree)
    row_pos = {j: i for i, j in enumerate(R)}
    by_name = {c.name: c for c in tree.couplings}
    entries: dict[int, list[tuple[int, int]]] = {}  # link -> [(parameter offset, output column)]
    terms, couplings = [], []
    for pos, col in enumerate(Cols):
        name = names[col]
        kind = name.rstrip("0123456789")
        if name in by_name:
            couplings.append((pos, by_name[name]))
        elif kind in INERTIAL:
            entries.setdefault(int(name[len(kind):]), []).append((INERTIAL.index(kind), pos))
        elif kind not in LOAD_TERMS:  # a load term's column is the measured wrench's: 0 here (model.tree)
            j = int(name[len(kind):])
            if j in row_pos:
                code = _SMOOTH_FS if kind == "FS" and widths[j] != 0.0 else _TERM_CODE[kind]
                # the term's width: the Coulomb law's, or the curve's knee (v+ for FVP*, v- for FVN*)
                w = tree.knee(j)[kind.startswith("FVP")] if kind in CURVE_TERMS else widths[j]
                terms.append((j, code, row_pos[j], pos, w))
    C = len(Cols)
    links = [k for k in sorted(entries) if any(j in row_pos and tree.sigma[j] != FIXED for j in tree.ancestors[k])]
    colmap = np.full((len(links), 10), C, dtype=np.int64)  # unasked parameters go to the spare column C
    for li, k in enumerate(links):
        for off, pos in entries[k]:
            colmap[li, off] = pos
    r_joint, r_rpos, r_ptr, run_lo, run_hi = [], [], [0], [], []
    for j in R:
        if tree.sigma[j] == FIXED:
            continue
        cols = sorted(pos for k in links if j in tree.ancestors[k] for _, pos in entries[k])
        if not cols:
            continue
        r_joint.append(j)
        r_rpos.append(row_pos[j])
        for c in cols:  # maximal runs of consecutive output columns
            if run_hi and len(run_hi) > r_ptr[-1] and run_hi[-1] == c:
                run_hi[-1] = c + 1
            else:
                run_lo.append(c)
                run_hi.append(c + 1)
        r_ptr.append(len(run_lo))
    c_ptr = np.cumsum([0] + [len(c.coeffs) for _, c in couplings])
    axis = np.zeros(tree.n + 1, dtype=np.bool_)
    axis[r_joint] = True
    kernel = (  # the arguments of _reg_kernel that depend only on the rows and columns, in its order
        _i64(links), colmap, _i64(r_joint), _i64(r_rpos), _i64(r_ptr), _u64(run_lo), _u64(run_hi),
        _i64([t[0] for t in terms]), _i64([t[1] for t in terms]), _i64([t[2] for t in terms]),
        _i64([t[3] for t in terms]), _f64([t[4] for t in terms], (len(terms),)),
        _i64([_COUPLING_CODE[c.kind] for _, c in couplings]), _i64([pos for pos, _ in couplings]), _i64(c_ptr),
        _i64([j for _, c in couplings for j in c.coeffs]),
        _f64([x for _, c in couplings for x in c.coeffs.values()], (int(c_ptr[-1]),)),
        _i64([row_pos.get(j, -1) for _, c in couplings for j in c.coeffs]),
    )
    return {"kernel": kernel, "row_pos": row_pos, "todo": _ancestor_mask(geo, links + r_joint),
            "motion": _ancestor_mask(geo, links), "axis": axis, "ref": _i64(links)}


def regressor(tree: Tree, q: Array, qd: Array, qdd: Array, R: Sequence[int], Cols: Sequence[int],
              checked: list | None, out: Array) -> Array:
    """Fill out (N, len(R), len(Cols)) from samples-first joint arrays; returns Q (N, len(R)), the
    generalized force of the wrenches (zero without).

    Only entries that can be non-zero are written (see the module doc).
    """
    ws = workspace(tree)
    geo, plan = ws.geometry, ws.regressor_plan(tuple(R), tuple(Cols))
    N = q.shape[0]
    todo, axis, ref = plan["todo"], plan["axis"], plan["ref"]
    wq: list[list[int]] = []
    if checked:  # the wrenches' rows: moving requested ancestors of each wrench's link
        row_pos = plan["row_pos"]
        wq = [[j for j in tree.ancestors[k] if j in row_pos and tree.sigma[j] != FIXED] for k, _, _, _ in checked]
        extra = [j for r in wq for j in r]
        todo = todo | _ancestor_mask(geo, extra + [x for k, e, _, _ in checked for x in (k, e)])
        axis = axis.copy()
        axis[extra] = True
        if not len(ref):
            ref = _i64([k for k, _, _, _ in checked])
    wl, we, wp, wv = _wrench_arrays(checked or [], N)
    wq_ptr = _i64(np.cumsum([0] + [len(r) for r in wq]))
    wq_joint = _i64([j for r in wq for j in r])
    wq_rpos = _i64([plan["row_pos"][j] for j in wq_joint])
    Q = np.zeros((N, len(R)))
    _reg_kernel(q, qd, qdd, geo["ant"], geo["sigma"], geo["E"], geo["u"], geo["th0"], geo["r0"], geo["g"],
                todo, plan["motion"], axis, ref, *plan["kernel"], wl, we, wp, wv, wq_ptr, wq_joint, wq_rpos, out, Q)
    return Q


__all__ = ["HAVE_NUMBA", "Workspace", "geometry", "inverse_dynamics", "joint_rows", "regressor", "regressor_plan",
           "workspace"]
