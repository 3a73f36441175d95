"""The identified car in a vehicle engineer's terms: masses, centre of gravity, inertia about it in ISO 8855
axes, static axle loads and roll stiffness, each with its first-order propagated standard uncertainty.

Pure functions of the parameter values (SI, frame 6: x6 up, y6 right, z6 forward, origin O6 on the rear axle
midway between the rear wheel centres, at their height in the design position) and the vehicle geometry.

- M6 is the SPRUNG mass: the chassis body alone, what the chassis equations weigh above the suspensions. The
  car's total mass adds the four wheel bodies (the unsprung corners: in the template every other corner frame
  is massless), known from a bench or estimated.
- Heights are above flat ground at design ride height (every joint variable zero): the wheel centres at the
  unloaded tire radius above the ground, x6 = wheel_centre_height_m.
- Inertia: I = ∫(|r|² 1 - r rᵀ) dm, products as the matrix's entries (Ixz = -∫xz dm), like XZ6; moved from O6
  to the centre of gravity G by the parallel-axis theorem, then to ISO 8855 vehicle axes (x forward = z6,
  y left = -y6, z up = x6).
- Roll stiffness of an axle (suspension only, tires in series not counted): a body roll φ moves the wheel
  centres ±tφ vertically relative to the body (t the half track); each wheel centre moves along its damper
  axis, whose vertical component is c, so the clearances move ±tφ/c and the springs and bar store
  ½(ks_l + ks_r)(tφ/c)² + ½ k_ar (2tφ/c)²: K_φ = (ks_l + ks_r + 4 k_ar) t² / c² (N·m/rad).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .geometry import CarGeometry
from .template import DAMPERS, WHEELS

G = 9.81  # m/s², the template's gravity
ISO_FROM_6 = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])  # rows: ISO x, y, z in frame 6


@dataclass(frozen=True)
class Quantity:
    """One engineering figure: value and standard uncertainty (NaN when not propagated) in `unit`."""

    key: str
    group: str
    label: str
    unit: str
    value: float
    std: float = float("nan")
    note: str = ""


# key -> (group, label, unit, note); the order is the report's
QUANTITIES: dict[str, tuple[str, str, str, str]] = {
    "mass_total": ("Masses", "total mass", "kg", "sprung + unsprung"),
    "mass_sprung": ("Masses", "sprung mass (chassis, M6)", "kg", "the table's M6"),
    "mass_unsprung": ("Masses", "unsprung mass (four wheels)", "kg", ""),
    "cg_behind_front": ("Centre of gravity, whole car", "behind the front axle", "m", ""),
    "cg_ahead_rear": ("Centre of gravity, whole car", "ahead of the rear axle", "m", ""),
    "cg_height": ("Centre of gravity, whole car", "height above the ground", "m", "design ride height"),
    "cg_lateral": ("Centre of gravity, whole car", "lateral offset (left +)", "m", "ISO y"),
    "cgs_behind_front": ("Centre of gravity, sprung mass", "behind the front axle", "m", ""),
    "cgs_ahead_rear": ("Centre of gravity, sprung mass", "ahead of the rear axle", "m", ""),
    "cgs_height": ("Centre of gravity, sprung mass", "height above the ground", "m", "design ride height"),
    "cgs_lateral": ("Centre of gravity, sprung mass", "lateral offset (left +)", "m", "ISO y"),
    "Ixx": ("Inertia of the sprung mass about its CoG (ISO 8855)", "roll Ixx", "kg·m²", ""),
    "Iyy": ("Inertia of the sprung mass about its CoG (ISO 8855)", "pitch Iyy", "kg·m²", ""),
    "Izz": ("Inertia of the sprung mass about its CoG (ISO 8855)", "yaw Izz", "kg·m²", ""),
    "Ixz": ("Inertia of the sprung mass about its CoG (ISO 8855)", "roll–yaw product Ixz", "kg·m²",
            "matrix entry, -∫xz dm"),
    "Ixy": ("Inertia of the sprung mass about its CoG (ISO 8855)", "roll–pitch product Ixy", "kg·m²",
            "matrix entry, -∫xy dm"),
    "Iyz": ("Inertia of the sprung mass about its CoG (ISO 8855)", "pitch–yaw product Iyz", "kg·m²",
            "matrix entry, -∫yz dm"),
    "Ixx_total": ("Inertia of the whole car about its CoG (ISO 8855)", "roll Ixx", "kg·m²", "wheels included"),
    "Iyy_total": ("Inertia of the whole car about its CoG (ISO 8855)", "pitch Iyy", "kg·m²", "wheels included"),
    "Izz_total": ("Inertia of the whole car about its CoG (ISO 8855)", "yaw Izz", "kg·m²", "wheels included"),
    "front_share": ("Static axle loads (level ground)", "front axle share", "%", "whole car"),
    "front_share_sprung": ("Static axle loads (level ground)", "front axle share of the sprung mass", "%", ""),
    "front_load": ("Static axle loads (level ground)", "front axle load", "N", ""),
    "rear_load": ("Static axle loads (level ground)", "rear axle load", "N", ""),
    "roll_front": ("Roll stiffness (springs + anti-roll bar)", "front axle", "N·m/rad", "tires not counted"),
    "roll_rear": ("Roll stiffness (springs + anti-roll bar)", "rear axle", "N·m/rad", "tires not counted"),
    "roll_total": ("Roll stiffness (springs + anti-roll bar)", "total", "N·m/rad", ""),
    "roll_front_share": ("Roll stiffness (springs + anti-roll bar)", "front share", "%", ""),
}


def _inertia(v: Mapping[str, float], j: int) -> np.ndarray:
    g = lambda n: float(v.get(f"{n}{j}", 0.0))  # noqa: E731 (a local shorthand)
    return np.array([[g("XX"), g("XY"), g("XZ")], [g("XY"), g("YY"), g("YZ")], [g("XZ"), g("YZ"), g("ZZ")]])


def _shift(J: np.ndarray, m: float, r: np.ndarray) -> np.ndarray:
    """Parallel axis: the inertia about a point at -r from the centre of mass (J about G, r = G - point)."""
    return J + m * (float(r @ r) * np.eye(3) - np.outer(r, r))


def _wheel_iso(v: Mapping[str, float], w: int) -> np.ndarray:
    """A wheel's inertia about its centre in ISO axes: frame 14's z is the axle (left), x forward in the wheel
    plane; it spins, so its two diametral moments are averaged."""
    d = 0.5 * (float(v.get(f"XX{w}", 0.0)) + float(v.get(f"YY{w}", 0.0)))
    return np.diag([d, float(v.get(f"ZZ{w}", 0.0)), d])


def damper_vertical(geometry: CarGeometry, front: bool) -> float:
    """c: the vertical (x6) component of the unit damper axis of an axle."""
    ax = geometry.front if front else geometry.rear
    return 1.0 / float(np.sqrt(1.0 + np.tan(ax.damper_lateral_tilt) ** 2 + np.tan(ax.damper_longitudinal_tilt) ** 2))


def car_quantities(values: Mapping[str, float], geometry: CarGeometry) -> dict[str, float]:
    """The engineering figures (QUANTITIES' keys, their units) of one parameter set; missing names are 0."""
    v = values
    m6 = float(v.get("M6", 0.0))
    c6 = np.array([float(v.get(n, 0.0)) for n in ("MX6", "MY6", "MZ6")]) / m6  # sprung CoG in frame 6
    wheel_m = np.array([float(v.get(f"M{w}", 0.0)) for w in WHEELS])
    centres = np.array([geometry.wheel_centre(k) for k in range(4)])
    m = m6 + wheel_m.sum()
    c = (m6 * c6 + wheel_m @ centres) / m  # whole car
    zf, zr, L = geometry.front.position, geometry.rear.position, geometry.wheelbase
    ground = geometry.wheel_centre_height - geometry.wheel_radius  # x6 of the ground at design ride height
    out = {"mass_total": m, "mass_sprung": m6, "mass_unsprung": float(wheel_m.sum())}
    for prefix, p in (("cg", c), ("cgs", c6)):
        out.update({f"{prefix}_behind_front": zf - p[2], f"{prefix}_ahead_rear": p[2] - zr,
                    f"{prefix}_height": p[0] - ground, f"{prefix}_lateral": -p[1]})
    Jg = ISO_FROM_6 @ _shift(_inertia(v, 6), -m6, c6) @ ISO_FROM_6.T  # about O6 -> about G (frame 6) -> ISO
    out.update({"Ixx": Jg[0, 0], "Iyy": Jg[1, 1], "Izz": Jg[2, 2], "Ixz": Jg[0, 2], "Ixy": Jg[0, 1], "Iyz": Jg[1, 2]})
    # the whole car about its own CoG: the sprung body and each wheel moved there
    J = _shift(Jg, m6, ISO_FROM_6 @ (c6 - c))
    for k, w in enumerate(WHEELS):
        J = J + _shift(_wheel_iso(v, w), wheel_m[k], ISO_FROM_6 @ (centres[k] - c))
    out.update({"Ixx_total": J[0, 0], "Iyy_total": J[1, 1], "Izz_total": J[2, 2]})
    share = (c[2] - zr) / L
    out.update({"front_share": 100 * share, "front_share_sprung": 100 * (c6[2] - zr) / L,
                "front_load": m * G * share, "rear_load": m * G * (1 - share)})
    roll = {}
    for axle, (left, right), bar, front in (("front", DAMPERS[2:], "karf", True),
                                            ("rear", DAMPERS[:2], "karr", False)):
        t = (geometry.front if front else geometry.rear).half_track
        k = float(v.get(f"K{left}", 0.0)) + float(v.get(f"K{right}", 0.0)) + 4 * float(v.get(bar, 0.0))
        roll[axle] = k * t**2 / damper_vertical(geometry, front) ** 2
    total = roll["front"] + roll["rear"]
    out.update({"roll_front": roll["front"], "roll_rear": roll["rear"], "roll_total": total,
                "roll_front_share": 100 * roll["front"] / total if total else float("nan")})
    return {k: float(x) for k, x in out.items()}


def jacobian(f: Callable[[Mapping[str, float]], Mapping[str, float]], values: Mapping[str, float],
             names: Sequence[str], keys: Sequence[str], scales: Sequence[float] | None = None) -> np.ndarray:
    """(len(keys), len(names)) ∂f/∂values by central differences, the step 1e-6 of each parameter's scale
    (|value|, or the given scale where the value may be near 0): f is smooth and rational in them."""
    J = np.zeros((len(keys), len(names)))
    base = dict(values)
    for i, n in enumerate(names):
        x = float(base.get(n, 0.0))
        h = 1e-6 * max(abs(x), abs(scales[i]) if scales is not None else 0.0, 1e-9)
        up, down = dict(base), dict(base)
        up[n], down[n] = x + h, x - h
        fu, fd = f(up), f(down)
        J[:, i] = [(fu[k] - fd[k]) / (2 * h) for k in keys]
    return J


def propagated_std(f: Callable[[Mapping[str, float]], Mapping[str, float]], values: Mapping[str, float],
                   names: Sequence[str], covariance: np.ndarray, keys: Sequence[str]) -> np.ndarray:
    """First-order standard uncertainty of f's keys: sqrt(diag(J C Jᵀ)), C the covariance over `names`."""
    scales = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    J = jacobian(f, values, names, keys, scales)
    return np.sqrt(np.clip(np.einsum("ij,jk,ik->i", J, covariance, J), 0.0, None))


def engineering_figures(values: Mapping[str, float], geometry: CarGeometry, names: Sequence[str] = (),
                        covariance: np.ndarray | None = None) -> list[Quantity]:
    """The figures of `car_quantities`, each with its propagated σ (NaN without a covariance); names: the
    parameters the covariance is over (the others, e.g. bench-known wheels, count as exact)."""
    def f(x: Mapping[str, float]) -> dict[str, float]:
        return car_quantities(x, geometry)

    q = f(values)
    keys = list(QUANTITIES)
    std = (propagated_std(f, values, list(names), covariance, keys) if covariance is not None and len(names)
           else np.full(len(keys), np.nan))
    return [Quantity(k, *QUANTITIES[k][:3], value=q[k], std=float(s), note=QUANTITIES[k][3])
            for k, s in zip(keys, std, strict=True)]


__all__ = ["QUANTITIES", "Quantity", "car_quantities", "damper_vertical", "engineering_figures", "jacobian",
           "propagated_std"]
