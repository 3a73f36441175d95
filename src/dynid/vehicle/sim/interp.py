"""The kinematic tables and aerodynamic tables as piecewise polynomials a compiled loop can evaluate.

The kinematic tables' packing and evaluation live in `vehicle.table_poly` (the estimator uses
them too); the aerodynamic coefficients are cubic splines of the sideslip angle.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from ...symbolic.numba_backend import jit
from ..aero import COEFFICIENTS
from ..table_poly import Packed, _cell, pack
from ..tables import TABLE_NAMES, KinematicTables


def pack_tables(tables: KinematicTables) -> Packed:
    """(xb (16, MX+1), yb (16, MY+1), nx (16,), ny (16,), coef (16, MX, MY, 4, 4)); table index 4 * corner + name."""
    return pack([tables.table(k, n) for k in range(4) for n in TABLE_NAMES])


def pack_aero(aero) -> tuple[np.ndarray, np.ndarray]:
    """(beta breakpoints (m+1,), coefficients (6, m, 4)) of the aerodynamic tables' cubic splines
    (the same splines as dynid.vehicle.aero: scipy CubicSpline, not-a-knot), highest power first."""

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
