"""Tire model: Pacejka Magic Formula with combined slip, load dependence and relaxation.

A simplified Magic Formula 5.2 (no shifts, no camber terms), per tire, SI units:

  dfz = (Fz - Fz0) / Fz0
  longitudinal  Fx0 = Dx sin(Cx atan(Bx k - Ex (Bx k - atan(Bx k))))
                Dx = (pDx1 + pDx2 dfz) Fz,  Kx = Bx Cx Dx = Fz (pKx1 + pKx2 dfz) exp(pKx3 dfz)
  lateral       Fy0 = -Dy sin(Cy atan(By a - Ey (By a - atan(By a))))     (opposes the slip)
                Dy = (pDy1 + pDy2 dfz) Fz,  Ky = By Cy Dy = pKy1 Fz0 sin(2 atan(Fz / (pKy2 Fz0)))
  combined slip (cosine weighting)
                Fx = Fx0 cos(Cxa atan(Bxa a)),  Bxa = rBx1 cos(atan(rBx2 k))
                Fy = Fy0 cos(Cyk atan(Byk k)),  Byk = rBy1 cos(atan(rBy2 a))
  aligning      Mz = -t Fy,  t = t0 cos(atan(Bt a)) (pneumatic trail)
  rolling       My = -fr Fz rho tanh(omega Re / 0.3 m/s) (about the axle, at the contact point)

Slips come from first-order relaxation states (the "stretched string" lag): with Vx the
forward velocity of the contact point and Vsx = Vx - omega Re, Vsy = Vy the slip speeds,

  dux/dt = -Vsx - |Vx| ux / sigma_x,   k = ux / sigma_x        (-> -Vsx / |Vx| in steady state)
  duy/dt = -Vsy - |Vx| uy / sigma_y,   a = atan(-uy / sigma_y) (-> atan(Vsy / |Vx|))

so that the slips stay finite at low speed (the tire then acts as a spring), which is
what keeps the explicit integration stable when the car slows down.

Default parameters: a 205/60 R15 91V-class summer tire on dry asphalt, chosen to give
the textbook figures of that size (not a measured tire): nominal load 4 kN; peak friction
1.0 longitudinal, 0.95 lateral, falling 8-10 % per nominal load; longitudinal slip
stiffness 20 Fz per unit slip (80 kN at 4 kN); cornering stiffness about 1000 N/deg at
4 kN, saturating with load; relaxation lengths 0.2 m (longitudinal) and 0.45 m
(lateral); rolling resistance coefficient 0.012; pneumatic trail 35 mm.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ...symbolic.numba_backend import jit

FIELDS = ("Fz0", "pDx1", "pDx2", "Cx", "Ex", "pKx1", "pKx2", "pKx3", "pDy1", "pDy2", "Cy", "Ey", "pKy1", "pKy2",
          "rBx1", "rBx2", "Cxa", "rBy1", "rBy2", "Cyk", "sigma_x", "sigma_y", "fr", "t0", "Bt")


@dataclass(frozen=True)
class MagicFormula:
    """Parameters of one tire (see the module doc); defaults: a 205/60 R15-class tire."""

    Fz0: float = 4000.0
    pDx1: float = 1.0
    pDx2: float = -0.08
    Cx: float = 1.65
    Ex: float = 0.2
    pKx1: float = 20.0
    pKx2: float = 0.0
    pKx3: float = -0.2
    pDy1: float = 0.95
    pDy2: float = -0.10
    Cy: float = 1.3
    Ey: float = -0.5
    pKy1: float = 16.8
    pKy2: float = 1.8
    rBx1: float = 12.0
    rBx2: float = 10.0
    Cxa: float = 1.0
    rBy1: float = 10.0
    rBy2: float = 8.0
    Cyk: float = 1.0
    sigma_x: float = 0.20
    sigma_y: float = 0.45
    fr: float = 0.012
    t0: float = 0.035
    Bt: float = 12.0

    def __post_init__(self) -> None:
        for name in FIELDS:
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"tire parameter {name} = {v} is not finite")
        for name in ("Fz0", "pDx1", "Cx", "pKx1", "pDy1", "Cy", "pKy1", "pKy2", "sigma_x", "sigma_y"):
            if getattr(self, name) <= 0:
                raise ValueError(f"tire parameter {name} = {getattr(self, name)} must be positive")

    def pack(self) -> np.ndarray:
        return np.array([getattr(self, f) for f in FIELDS])

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def cornering_stiffness(self, Fz: float) -> float:
        """dFy/d(alpha) at zero slip, N/rad (positive): Ky of the module doc."""
        return self.pKy1 * self.Fz0 * math.sin(2.0 * math.atan(Fz / (self.pKy2 * self.Fz0)))

    def cornering_stiffness_slope(self, Fz: float) -> float:
        """dKy/dFz (rad^-1): the load sensitivity of the cornering stiffness."""
        x = Fz / (self.pKy2 * self.Fz0)
        return 2.0 * self.pKy1 * math.cos(2.0 * math.atan(x)) / (self.pKy2 * (1.0 + x * x))

    def peak_friction(self, Fz: float) -> tuple[float, float]:
        """(mu_x, mu_y) at the load Fz."""
        dfz = (Fz - self.Fz0) / self.Fz0
        return self.pDx1 + self.pDx2 * dfz, self.pDy1 + self.pDy2 * dfz


@jit
def magic_formula(p, Fz, kappa, alpha, out):
    """Fx, Fy, Mz of one tire into out[0:3] (Fz > 0 N, kappa, alpha rad); p: MagicFormula.pack()."""
    Fz0 = p[0]
    dfz = (Fz - Fz0) / Fz0
    Dx = (p[1] + p[2] * dfz) * Fz
    Cx = p[3]
    Kx = Fz * (p[5] + p[6] * dfz) * math.exp(p[7] * dfz)
    Bx = Kx / (Cx * Dx)
    bk = Bx * kappa
    Fx0 = Dx * math.sin(Cx * math.atan(bk - p[4] * (bk - math.atan(bk))))
    Dy = (p[8] + p[9] * dfz) * Fz
    Cy = p[10]
    Ky = p[12] * Fz0 * math.sin(2.0 * math.atan(Fz / (p[13] * Fz0)))
    By = Ky / (Cy * Dy)
    ba = By * alpha
    Fy0 = -Dy * math.sin(Cy * math.atan(ba - p[11] * (ba - math.atan(ba))))
    Bxa = p[14] * math.cos(math.atan(p[15] * kappa))
    Byk = p[17] * math.cos(math.atan(p[18] * alpha))
    Fx = Fx0 * math.cos(p[16] * math.atan(Bxa * alpha))
    Fy = Fy0 * math.cos(p[19] * math.atan(Byk * kappa))
    out[0] = Fx
    out[1] = Fy
    out[2] = -p[23] * math.cos(math.atan(p[24] * alpha)) * Fy
    return 0
