"""The kinematic tables as piecewise polynomials a compiled loop evaluates.

Inside a cell of a table's data grid its spline (bicubic B-spline in damper travel u and
steering-wheel angle h, or cubic in u) is one bicubic polynomial, so it is stored exactly
as 16 coefficients per cell in the cell's normalised coordinates (s, r) in [0, 1]^2: its
Taylor coefficients at the cell's corner, read from scipy's own representation (the
derivative B-splines of the FITPACK spline, whose coefficients are differences of the
spline's; CubicSpline's piecewise coefficients). Each derivative then carries the error
scipy's carries, eps times the size of the lower derivatives that are differenced
(tested against scipy). A table of u alone is a bicubic of degree 0 in r on one steering
cell [-10, 10] rad.

Not fitted to samples of the spline at 4 x 4 nodes per cell (as before): that is a finite
difference, which leaves f_uu an error of ~1e3 eps |f| / wx^2 (1e-9 on the front steering
tables, 0.7 rad on 1 cm cells, where f_uu is 1e-12), whatever the arithmetic.

Two users: the simulator's step kernel (`eval_table`, one sample) and the estimator's
`KinematicTables.joints` (`table_joints`, a whole record: several times faster than
scipy's per-call evaluation, and without the GIL).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline

from ..symbolic.numba_backend import jit

try:
    from numba import njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False

_FACT = np.array([1.0, 1.0, 2.0, 6.0])  # m!
Packed = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def pack(tabs) -> Packed:
    """(xb (T, MX+1), yb (T, MY+1), nx (T,), ny (T,), coef (T, MX, MY, 4, 4)) of a sequence of
    KinematicTable; coef[t, a, b, m, k] multiplies s^m r^k in cell (a, b) of table t."""

    grids = [(np.asarray(t.travel, dtype=float),
              np.array([-10.0, 10.0]) if t.steering is None else np.asarray(t.steering, dtype=float)) for t in tabs]
    MX = max(g[0].size for g in grids) - 1
    MY = max(g[1].size for g in grids) - 1
    n = len(tabs)
    XB, YB = np.zeros((n, MX + 1)), np.zeros((n, MY + 1))
    NX, NY = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    C = np.zeros((n, MX, MY, 4, 4))
    for i, (t, (xb, yb)) in enumerate(zip(tabs, grids, strict=True)):
        XB[i, : xb.size], YB[i, : yb.size] = xb, yb
        nx, ny = xb.size - 1, yb.size - 1
        NX[i], NY[i] = nx, ny
        wx, wy = np.diff(xb), np.diff(yb)
        if t.steering is None:  # CubicSpline on the grid: c[3 - m, a] multiplies (u - xb[a])^m
            C[i, :nx, 0, :, 0] = t._spline.c[::-1].T * wx[:, None] ** np.arange(4)
            continue
        # f = sum c_ij B_i(u) B_j(h), knots among the grid points (FITPACK, s = 0): in cell (a, b)
        # coef[m, k] = d^m/du^m d^k/dh^k f(xb[a], yb[b]) wx^m wy^k / (m! k!). As FITPACK's parder: the
        # coefficients are differenced along h then u first (a derivative B-spline's coefficients are
        # differences of the spline's), then evaluated (B-splines at a knot from the right: the cell's piece).
        # Evaluating first and differencing the values would lose eps |f| / w per derivative.
        tx, ty, c = t._spline.tck
        along_h = BSpline(ty, c.reshape(tx.size - 4, ty.size - 4).T, 3)  # coefficients: vectors over u
        for k in range(4):
            dk = along_h.derivative(k) if k else along_h
            along_u = BSpline(tx, dk.c.T, 3)
            for m in range(4):
                dmk = (along_u.derivative(m) if m else along_u)(xb[:-1])  # (nx, coefficients of d^k/dh^k)
                v = BSpline(dk.t, dmk.T, dk.k)(yb[:-1]).T  # (nx, ny)
                C[i, :nx, :ny, m, k] = v * (wx[:, None] ** m / _FACT[m]) * (wy[None, :] ** k / _FACT[k])
    return XB, YB, NX, NY, C


@jit
def _cell(b, n, x):
    """Index of the cell of breakpoints b[0..n] holding x (clamped: callers check the range)."""
    lo, hi = 0, n - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if b[mid] <= x:
            lo = mid
        else:
            hi = mid - 1
    return lo


@jit
def eval_table(XB, YB, NX, NY, C, i, u, h, out):
    """Table i at (u, h): out[0:6] = f, f_u, f_h, f_uu, f_uh, f_hh; returns 1 if (u, h) is off the grid."""
    nx, ny = NX[i], NY[i]
    bad = 0
    if u < XB[i, 0] - 1e-12 or u > XB[i, nx] + 1e-12 or h < YB[i, 0] - 1e-12 or h > YB[i, ny] + 1e-12:
        bad = 1
    a = _cell(XB[i], nx, u)
    b = _cell(YB[i], ny, h)
    wx = XB[i, a + 1] - XB[i, a]
    wy = YB[i, b + 1] - YB[i, b]
    s = (u - XB[i, a]) / wx
    r = (h - YB[i, b]) / wy
    c = C[i, a, b]
    ps = (1.0, s, s * s, s * s * s)
    dps = (0.0, 1.0, 2.0 * s, 3.0 * s * s)
    ddps = (0.0, 0.0, 2.0, 6.0 * s)
    pr = (1.0, r, r * r, r * r * r)
    dpr = (0.0, 1.0, 2.0 * r, 3.0 * r * r)
    ddpr = (0.0, 0.0, 2.0, 6.0 * r)
    f = fu = fh = fuu = fuh = fhh = 0.0
    for m in range(4):
        for k in range(4):
            cc = c[m, k]
            if cc == 0.0:
                continue
            f += cc * ps[m] * pr[k]
            fu += cc * dps[m] * pr[k]
            fh += cc * ps[m] * dpr[k]
            fuu += cc * ddps[m] * pr[k]
            fuh += cc * dps[m] * dpr[k]
            fhh += cc * ps[m] * ddpr[k]
    out[0] = f
    out[1] = fu / wx
    out[2] = fh / wy
    out[3] = fuu / (wx * wx)
    out[4] = fuh / (wx * wy)
    out[5] = fhh / (wy * wy)
    return bad


def _table_joints(XB, YB, NX, NY, C, steering, u_cols, out_cols, q, qd, qdd, h, hd, hdd):  # pragma: no cover
    """For each table t: the joint in row out_cols[t] of q, qd, qdd (42, N) (joints first: the transposes of
    column-major (N, 42) arrays, so that a one-sample call and a long record share one layout and one compile) from
    the damper row u_cols[t] and the steering wheel (h, hd, hdd) by the chain rule; steering[t] = 0 for a table of u
    alone (h neither checked nor used). Returns -1, or t * N + n for the first sample n off table t's grid.
    Measured signals are smooth: each sample's cell is first looked for where the last one was."""
    N = q.shape[1]
    for t in range(u_cols.size):
        cu, cj = u_cols[t], out_cols[t]
        nx, ny = NX[t], NY[t]
        xb, yb = XB[t], YB[t]
        a = b = 0
        for n in range(N):
            u, ud, udd = q[cu, n], qd[cu, n], qdd[cu, n]
            if not (xb[0] - 1e-12 <= u <= xb[nx] + 1e-12):  # also a NaN
                return t * N + n
            if not (xb[a] <= u < xb[a + 1]):
                a = _cell(xb, nx, u)
            wx = xb[a + 1] - xb[a]
            s = (u - xb[a]) / wx
            if not steering[t]:  # a cubic in s (the r terms of a table of u alone are round-off)
                c0, c1, c2, c3 = C[t, a, 0, 0, 0], C[t, a, 0, 1, 0], C[t, a, 0, 2, 0], C[t, a, 0, 3, 0]
                fu = (c1 + s * (2.0 * c2 + 3.0 * s * c3)) / wx
                fuu = (2.0 * c2 + 6.0 * s * c3) / (wx * wx)
                q[cj, n] = c0 + s * (c1 + s * (c2 + s * c3))
                qd[cj, n] = fu * ud
                qdd[cj, n] = fuu * ud * ud + fu * udd
                continue
            hn = h[n]
            if not (yb[0] - 1e-12 <= hn <= yb[ny] + 1e-12):
                return t * N + n
            if not (yb[b] <= hn < yb[b + 1]):
                b = _cell(yb, ny, hn)
            wy = yb[b + 1] - yb[b]
            r = (hn - yb[b]) / wy
            c = C[t, a, b]
            # p_m(r) = sum_k c[m, k] r^k and its r-derivatives, then the cubic in s of each
            f = fu = fuu = fh = fuh = fhh = 0.0
            for m in range(3, -1, -1):
                p = c[m, 0] + r * (c[m, 1] + r * (c[m, 2] + r * c[m, 3]))
                dp = c[m, 1] + r * (2.0 * c[m, 2] + 3.0 * r * c[m, 3])
                ddp = 2.0 * c[m, 2] + 6.0 * r * c[m, 3]
                fuu = fuu * s + 2.0 * fu
                fu = fu * s + f
                f = f * s + p
                fuh = fuh * s + fh
                fh = fh * s + dp
                fhh = fhh * s + ddp
            fu, fh, fuu, fuh, fhh = fu / wx, fh / wy, fuu / (wx * wx), fuh / (wx * wy), fhh / (wy * wy)
            q[cj, n] = f
            qd[cj, n] = fu * ud + fh * hd[n]
            qdd[cj, n] = fuu * ud * ud + 2.0 * fuh * ud * hd[n] + fhh * hd[n] * hd[n] + fu * udd + fh * hdd[n]
    return -1


table_joints = njit(cache=True, nogil=True)(_table_joints) if HAVE_NUMBA else None
