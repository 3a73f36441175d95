"""Aerodynamic wrench on the chassis from coefficient tables versus sideslip (paper §3.2).

Coefficients are in ISO 8855 vehicle axes (x forward, y left, z up) at a reference point
fixed in the chassis (default: mid-wheelbase, on the centreline, at ground level in the
design position): with q = ½ ρ V², V the speed of the reference point in the chassis'
horizontal plane (no wind) and β = atan2(v_left, v_forward) its sideslip,

    drag  Fx = -q S Cx(β)      side  Fy = q S Cy(β)      lift  Fz = q S Cz(β)
    roll  Mx = q S L Cl(β)     pitch My = q S L Cm(β)    yaw   Mz = q S L Cn(β)

S the frontal area, L the reference length (the wheelbase). The tables are interpolated
by cubic splines (C2); a sideslip outside them raises an error naming it (a car moving
backwards faster than `min_speed` is outside), and below `min_speed` β is taken as 0.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ..dynamics import Model, Wrench
from ..kinematics.forward import point_velocity
from ..model.tree import ModelError
from .geometry import CarGeometry, demo_geometry
from .template import CHASSIS

COEFFICIENTS = ("cx", "cy", "cz", "cl", "cm", "cn")
# frame 6 components of a vector given in ISO vehicle axes (x forward, y left, z up)
ISO_TO_FRAME6 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
_BETA = np.radians(np.linspace(-90.0, 90.0, 37))


def _default(name: str) -> np.ndarray:
    s, c = np.sin(_BETA), np.cos(_BETA)
    return {
        "cx": 0.31 * c * (1.0 + 3.0 * s**2),  # 0.31 head-on, +7 % at 10° yaw, 0 broadside
        "cy": -1.2 * s,  # -0.021 per degree, opposing the sideslip
        "cz": 0.12 + 0.3 * s**2,  # a little lift, more in a cross wind
        "cl": -0.10 * s,
        "cm": 0.03 - 0.10 * s**2,
        "cn": -0.25 * s,  # destabilising: the centre of pressure is ahead
    }[name]


class AeroError(ModelError):
    """Aerodynamic data that cannot be used, or a sideslip outside the tables."""


@dataclass(frozen=True)
class Aerodynamics:
    """Air density (kg/m³), frontal area (m²), reference length (m), coefficient tables versus β (rad)."""

    rho: float = 1.225
    area: float = 2.0
    length: float = 2.70
    beta: np.ndarray = field(default_factory=lambda: _BETA.copy())
    cx: np.ndarray = field(default_factory=lambda: _default("cx"))
    cy: np.ndarray = field(default_factory=lambda: _default("cy"))
    cz: np.ndarray = field(default_factory=lambda: _default("cz"))
    cl: np.ndarray = field(default_factory=lambda: _default("cl"))
    cm: np.ndarray = field(default_factory=lambda: _default("cm"))
    cn: np.ndarray = field(default_factory=lambda: _default("cn"))
    point: Sequence[float] | None = None  # reference point in frame 6; None: from the geometry
    min_speed: float = 1.0
    # the tables' splines, built once with the tables (every segment's rows and every offset's evaluate them)
    _splines: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        b = np.asarray(self.beta, dtype=float)
        if b.ndim != 1 or b.size < 4 or not (np.diff(b) > 0).all():
            raise AeroError("aerodynamic tables: beta must be at least 4 strictly increasing sideslip angles (rad)")
        for name in COEFFICIENTS:
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != b.shape or not np.isfinite(v).all():
                raise AeroError(f"aerodynamic table {name}: need {b.size} finite values (one per beta); got {v.shape}")
        for name in ("rho", "area", "length"):
            if not getattr(self, name) > 0:
                raise AeroError(f"aerodynamics: {name} = {getattr(self, name)} must be positive")
        object.__setattr__(self, "_splines", tuple(CubicSpline(self.beta, getattr(self, n)) for n in COEFFICIENTS))

    def coefficients(self, beta: np.ndarray) -> np.ndarray:
        """(N, 6) coefficients Cx Cy Cz Cl Cm Cn at the sideslips beta (N,)."""
        beta = np.atleast_1d(np.asarray(beta, dtype=float))
        lo, hi = self.beta[0], self.beta[-1]
        bad = (beta < lo) | (beta > hi)
        if bad.any():
            i = int(np.argmax(bad))
            raise AeroError(
                f"aerodynamic tables: sideslip β = {np.degrees(beta[i]):.4g}° at sample {i} is outside the tables "
                f"[{np.degrees(lo):.4g}°, {np.degrees(hi):.4g}°] (is the car reversing?)"
            )
        return np.stack([spline(beta) for spline in self._splines], axis=1)


def reference_point(geometry: CarGeometry | None = None) -> np.ndarray:
    """Mid-wheelbase, centreline, ground level in the design position, in frame 6."""
    g = demo_geometry() if geometry is None else geometry
    return np.array([g.wheel_centre_height - g.wheel_radius, 0.0, 0.5 * (g.front.position + g.rear.position)])


def aero_wrench(
    model: Model, q: np.ndarray, qd: np.ndarray, aero: Aerodynamics | None = None,
    geometry: CarGeometry | None = None,
) -> Wrench:
    """The aerodynamic wrench on the chassis (link 6) at the reference point, in frame 6 axes."""
    aero = Aerodynamics() if aero is None else aero
    p = reference_point(geometry) if aero.point is None else np.asarray(aero.point, dtype=float)
    q, qd = np.atleast_2d(q), np.atleast_2d(qd)
    v, _ = point_velocity(model.tree, q, qd, CHASSIS, point=p, expressed_in=CHASSIS)  # frame 6: up, right, forward
    forward, left = v[:, 2], -v[:, 1]
    V2 = forward**2 + left**2
    slow = aero.min_speed**2 > V2
    beta = np.where(slow, 0.0, np.arctan2(left, forward))
    C = aero.coefficients(beta)
    qS = 0.5 * aero.rho * V2 * aero.area
    F_iso = qS[:, None] * np.stack([-C[:, 0], C[:, 1], C[:, 2]], axis=1)
    M_iso = (qS * aero.length)[:, None] * C[:, 3:]
    values = np.concatenate([F_iso @ ISO_TO_FRAME6.T, M_iso @ ISO_TO_FRAME6.T], axis=1)
    return Wrench(CHASSIS, values, point=tuple(p), frame=CHASSIS)
