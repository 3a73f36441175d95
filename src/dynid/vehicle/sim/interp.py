"""The kinematic tables and aerodynamic tables as piecewise polynomials a compiled loop can evaluate.

The template's tables are scipy splines (bicubic B-splines in damper travel u and
steering-wheel angle h, or cubic splines in u). Inside a cell of the data grid each is
one bicubic polynomial, so it is stored exactly as 16 coefficients per cell in the
cell's normalised coordinates (s, r) in [0, 1]^2, fitted from 4 x 4 samples of the
scipy spline (exact to round-off; `test_simulator` checks against scipy). A table of u
alone is a bicubic of degree 0 in r on one steering cell [-10, 10] rad.
"""

from __future__ import annotations

import numpy as np

from ...symbolic.numba_backend import jit
from ..tables import TABLE_NAMES, KinematicTables

_NODES = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0])
_VINV = np.linalg.inv(np.vander(_NODES, 4, increasing=True))


def pack_tables(tables: KinematicTables) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(xb (16, MX+1), yb (16, MY+1), nx (16,), ny (16,), coef (16, MX, MY, 4, 4)); table index 4 * corner + name."""
    tabs = [tables.table(k, n) for k in range(4) for n in TABLE_NAMES]
    grids = []
    for t in tabs:
        xb = np.asarray(t.travel, dtype=float)
        yb = np.array([-10.0, 10.0]) if t.steering is None else np.asarray(t.steering, dtype=float)
        grids.append((xb, yb))
    MX = max(g[0].size for g in grids) - 1
    MY = max(g[1].size for g in grids) - 1
    n = len(tabs)
    XB, YB = np.zeros((n, MX + 1)), np.zeros((n, MY + 1))
    NX, NY = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    C = np.zeros((n, MX, MY, 4, 4))
    for i, (t, (xb, yb)) in enumerate(zip(tabs, grids, strict=True)):
        XB[i, : xb.size], YB[i, : yb.size] = xb, yb
        NX[i], NY[i] = xb.size - 1, yb.size - 1
        for a in range(xb.size - 1):
            xs = xb[a] + _NODES * (xb[a + 1] - xb[a])
            for b in range(yb.size - 1):
                if t.steering is None:
                    v = np.repeat(t(xs)[:, None], 4, axis=1)
                else:
                    ys = yb[b] + _NODES * (yb[b + 1] - yb[b])
                    U, H = np.meshgrid(xs, ys, indexing="ij")
                    v = t._spline.ev(U.ravel(), H.ravel()).reshape(4, 4)
                C[i, a, b] = _VINV @ v @ _VINV.T
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


def pack_aero(aero) -> tuple[np.ndarray, np.ndarray]:
    """(beta breakpoints (m+1,), coefficients (6, m, 4)) of the aerodynamic tables' cubic splines
    (the same splines as dynid.vehicle.aero: scipy CubicSpline, not-a-knot), highest power first."""
    from scipy.interpolate import CubicSpline

    from ..aero import COEFFICIENTS

    x = np.asarray(aero.beta, dtype=float)
    C = np.stack([CubicSpline(x, np.asarray(getattr(aero, n), dtype=float)).c.T for n in COEFFICIENTS])
    return x, np.ascontiguousarray(C)


@jit
def eval_ppoly(x, C, j, v):
    """Cubic spline j of (x, C) at v (x[0] <= v <= x[-1])."""
    i = _cell(x, x.size - 1, v)
    d = v - x[i]
    c = C[j, i]
    return ((c[0] * d + c[1]) * d + c[2]) * d + c[3]
