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
  ½(ks_l + ks_r)(tφ/c)² + ½ k_ar (2tφ/c)²: K_φ = (ks_l + ks_r + 4 k_ar) t² / c², given in N·m/deg.
- The ride-and-handling sheet (docs/engineering.md derives each formula and states its assumptions): the springs act
  along the damper axis (the template's slide), so a vertical wheel travel z moves the damper z/c (motion ratio 1/c)
  and the wheel rate is ks/c², the bar's in roll 2 k_ar/c², the damping h/c²; ride rate: the wheel rate in series with
  the tire's rate at its static load (kt for the paper's line, the progressive law's tangent there); ride frequency and
  damping ratio per axle on that axle's share of the sprung mass; corner weights on a level scale with no diagonal
  preload (a lateral CoG offset shared as the roll stiffness); roll gradient about the roll axis of the slides (roll
  centre t·tan(lateral tilt) below the ground), pitch gradient about the ground, both with the tires in series and the
  body's weight term.
- The data sheet (`chassis_from_data_sheet`, `chassis_data_sheet`): the chassis CoG (ahead of the rear axle, above
  the ground or the wheel centres, to the left) and inertia at it in ISO 8855 axes, exactly to and from XX6..M6.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .geometry import CarGeometry
from .template import CORNERS, WHEELS, damper, tire

G = 9.81  # m/s², the template's gravity
DEG = float(np.pi / 180)
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


def _key(corner: str) -> str:
    return corner.replace(" ", "_")


AXLES = ("front", "rear")
_BY_AXLE = tuple(c for a in AXLES for c in CORNERS if c.startswith(a))  # front left, front right, rear left, ...


def axle_corners(axle: str) -> tuple[int, int]:
    """The (left, right) corner indices of an axle ("front" or "rear") in the template's CORNERS."""
    left, right = (CORNERS.index(f"{axle} {s}") for s in ("left", "right"))
    return left, right


# the anti-roll bar of each axle (a coupling of its two dampers)
BARS = {"front": "karf", "rear": "karr"}

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
    **{f"corner_{_key(c)}": ("Corner weights (level ground, no diagonal preload)", c, "kg",
                             "scale reading, load / g" if i == 0 else "") for i, c in enumerate(_BY_AXLE)},
    **{f"wheel_rate_{_key(c)}": ("Wheel rates (at the wheel centre, vertical)", f"spring, {c}", "N/m",
                                 "ks / c²" if i == 0 else "") for i, c in enumerate(_BY_AXLE)},
    **{f"tire_rate_{_key(c)}": ("Wheel rates (at the wheel centre, vertical)", f"tire, {c}", "N/m",
                                "at the corner's static load" if i == 0 else "") for i, c in enumerate(_BY_AXLE)},
    "wheel_rate_bar_front": ("Wheel rates (at the wheel centre, vertical)", "anti-roll bar, front (in roll)", "N/m",
                             "2 k_ar / c²; one wheel alone: half"),
    "wheel_rate_bar_rear": ("Wheel rates (at the wheel centre, vertical)", "anti-roll bar, rear (in roll)", "N/m",
                            ""),
    "ride_frequency_front": ("Ride (per axle, tires in series)", "ride frequency, front", "Hz",
                             "on the axle's share of the sprung mass"),
    "ride_frequency_rear": ("Ride (per axle, tires in series)", "ride frequency, rear", "Hz", ""),
    "damping_ratio_front": ("Ride (per axle, tires in series)", "damping ratio, front", "",
                            "viscous h only (damper curves: (hbl + hrl) / 2)"),
    "damping_ratio_rear": ("Ride (per axle, tires in series)", "damping ratio, rear", "", ""),
    "roll_front": ("Roll stiffness (springs + anti-roll bar)", "front axle", "N·m/deg", "tires not counted"),
    "roll_rear": ("Roll stiffness (springs + anti-roll bar)", "rear axle", "N·m/deg", "tires not counted"),
    "roll_total": ("Roll stiffness (springs + anti-roll bar)", "total", "N·m/deg", ""),
    "roll_front_share": ("Roll stiffness (springs + anti-roll bar)", "front share", "%", ""),
    "roll_centre_front": ("Roll and pitch (steady state, tires in series)", "roll centre height, front", "m",
                          "of the damper slides, above the ground"),
    "roll_centre_rear": ("Roll and pitch (steady state, tires in series)", "roll centre height, rear", "m", ""),
    "roll_gradient": ("Roll and pitch (steady state, tires in series)", "roll gradient", "deg/g",
                      "body roll per g of lateral acceleration"),
    "pitch_gradient": ("Roll and pitch (steady state, tires in series)", "pitch gradient", "deg/g",
                       "per g of braking; no anti-dive counted"),
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


def chassis_data_sheet(values: Mapping[str, float], geometry: CarGeometry) -> dict[str, float]:
    """The chassis (sprung mass) as a data sheet gives it, from XX6..M6: mass (kg); CoG ahead of the rear axle,
    behind the front axle, above the ground at design ride height, to the left (m); inertia at the CoG in ISO 8855
    axes (kg·m²), products as the matrix's entries (Ixz = -∫xz dm). Keys as QUANTITIES' (mass_sprung, cgs_*, I*)."""
    v = values
    m6 = float(v.get("M6", 0.0))
    c6 = np.array([float(v.get(n, 0.0)) for n in ("MX6", "MY6", "MZ6")]) / m6
    ground = geometry.wheel_centre_height - geometry.wheel_radius  # x6 of the ground at design ride height
    Jg = ISO_FROM_6 @ _shift(_inertia(v, 6), -m6, c6) @ ISO_FROM_6.T  # about O6 -> about G (frame 6) -> ISO
    return {"mass_sprung": m6, "cgs_behind_front": geometry.front.position - c6[2],
            "cgs_ahead_rear": c6[2] - geometry.rear.position, "cgs_height": c6[0] - ground, "cgs_lateral": -c6[1],
            "Ixx": Jg[0, 0], "Iyy": Jg[1, 1], "Izz": Jg[2, 2], "Ixz": Jg[0, 2], "Ixy": Jg[0, 1], "Iyz": Jg[1, 2]}


def chassis_from_data_sheet(mass: float, cog_ahead_of_rear_axle: float, cog_above_ground: float, cog_left: float,
                            inertia_iso: np.ndarray, geometry: CarGeometry) -> dict[str, float]:
    """XX6 XY6 XZ6 YY6 YZ6 ZZ6 MX6 MY6 MZ6 M6 of a chassis given as a data sheet gives it: its mass (kg), CoG (m:
    ahead of the rear axle, above the ground at design ride height, to the left) and 3x3 inertia at the CoG in ISO
    8855 axes (x forward, y left, z up; kg·m², products as the matrix's entries, Ixz = -∫xz dm). The inverse of
    `chassis_data_sheet`: frame 6 is x6 up, y6 right, z6 forward, origin O6 on the rear axle at the wheel centres'
    height; the inertia is turned to frame 6 and moved from the CoG to O6 by the parallel-axis theorem."""
    ground = geometry.wheel_centre_height - geometry.wheel_radius
    c6 = np.array([ground + cog_above_ground, -cog_left, geometry.rear.position + cog_ahead_of_rear_axle])
    J = np.asarray(inertia_iso, dtype=float)
    J6 = _shift(ISO_FROM_6.T @ (0.5 * (J + J.T)) @ ISO_FROM_6, mass, c6)  # at G (frame 6) -> about O6
    out = {"XX6": J6[0, 0], "XY6": J6[0, 1], "XZ6": J6[0, 2], "YY6": J6[1, 1], "YZ6": J6[1, 2], "ZZ6": J6[2, 2]}
    out.update({"MX6": mass * c6[0], "MY6": mass * c6[1], "MZ6": mass * c6[2], "M6": mass})
    return {k: float(x) for k, x in out.items()}


def _series(a: float, b: float) -> float:
    """Two springs in series."""
    return a * b / (a + b) if a + b else 0.0


def _tire_rate(kt: float, ktq: float, load: float) -> float:
    """dFz/dq of the tire law kt q + ktq q² (+ off) where it carries `load` (above its offset): the tangent
    sqrt(kt² + 4 ktq load) at the root q = (sqrt(...) - kt) / (2 ktq); kt for a line. NaN where the law never
    reaches that load on its rising branch."""
    if ktq == 0.0:
        return kt
    d = kt * kt + 4.0 * ktq * load
    return float(np.sqrt(d)) if d >= 0.0 else float("nan")


def _gradient(moment: float, stiffness: float) -> float:
    """deg per g of a body on an angular stiffness whose weight's arm adds `moment` per radian (m g d): the
    equilibrium angle (m g d) / (K - m g d); NaN when K <= m g d (no equilibrium: the body would not stand)."""
    return moment / (stiffness - moment) / DEG if stiffness > moment else float("nan")


def _ratio(a: float, b: float) -> float:
    """a / b, NaN where b is 0 (a set without tires or springs: no figure rather than an exception)."""
    return a / b if b else float("nan")


def car_quantities(values: Mapping[str, float], geometry: CarGeometry) -> dict[str, float]:
    """The engineering figures (QUANTITIES' keys, their units) of one parameter set; missing names are 0."""
    v = values

    def p(name: str) -> float:
        return float(v.get(name, 0.0))

    sheet = chassis_data_sheet(v, geometry)
    m6 = sheet["mass_sprung"]
    c6 = np.array([p(n) for n in ("MX6", "MY6", "MZ6")]) / m6  # sprung CoG in frame 6
    wheel_m = np.array([p(f"M{w}") for w in WHEELS])
    centres = np.array([geometry.wheel_centre(k) for k in range(4)])
    m = m6 + wheel_m.sum()
    c = (m6 * c6 + wheel_m @ centres) / m  # whole car
    zf, zr, L = geometry.front.position, geometry.rear.position, geometry.wheelbase
    ground = geometry.wheel_centre_height - geometry.wheel_radius  # x6 of the ground at design ride height
    out = {"mass_total": m, "mass_sprung": m6, "mass_unsprung": float(wheel_m.sum())}
    out.update({"cg_behind_front": zf - c[2], "cg_ahead_rear": c[2] - zr, "cg_height": c[0] - ground,
                "cg_lateral": -c[1]})
    out.update(sheet)
    Jg = ISO_FROM_6 @ _shift(_inertia(v, 6), -m6, c6) @ ISO_FROM_6.T
    # the whole car about its own CoG: the sprung body and each wheel moved there
    J = _shift(Jg, m6, ISO_FROM_6 @ (c6 - c))
    for k, w in enumerate(WHEELS):
        J = J + _shift(_wheel_iso(v, w), wheel_m[k], ISO_FROM_6 @ (centres[k] - c))
    out.update({"Ixx_total": J[0, 0], "Iyy_total": J[1, 1], "Izz_total": J[2, 2]})
    share = (c[2] - zr) / L
    share_sprung = (c6[2] - zr) / L
    out.update({"front_share": 100 * share, "front_share_sprung": 100 * share_sprung,
                "front_load": m * G * share, "rear_load": m * G * (1 - share)})
    # the ride-and-handling sheet, axle by axle (docs/engineering.md)
    h_s = c6[0] - ground  # sprung CoG above the ground
    y_s = -c6[1]  # and to the left
    m_axle = {"front": m6 * share_sprung, "rear": m6 * (1 - share_sprung)}
    roll, roll_eff, ride, centre = {}, {}, {}, {}
    for axle in AXLES:
        ax = geometry.front if axle == "front" else geometry.rear
        cv = damper_vertical(geometry, axle == "front")
        t = ax.half_track
        corners = axle_corners(axle)
        ks = [p(f"K{damper(k)}") for k in corners]
        # each tire's stiffness at its static load (level ground, the axle's sprung share and the wheel): the
        # progressive law's tangent there, kt for the paper's line
        load = [(m_axle[axle] / 2 + wheel_m[k]) * G for k in corners]
        kt = [_tire_rate(p(f"K{tire(k)}"), p(f"KQ{tire(k)}"), f - p(f"OFF{tire(k)}")) for k, f in zip(corners, load,
                                                                                                    strict=True)]
        # a damper curve's linear equivalent at small amplitude: the mean of its low-speed bump and rebound slopes
        h = [0.5 * (p(f"FVPL{damper(k)}") + p(f"FVNL{damper(k)}")) if f"FVPL{damper(k)}" in v
             else p(f"FV{damper(k)}") for k in corners]
        bar = p(BARS[axle])
        for k, kk, tt in zip(corners, ks, kt, strict=True):
            out[f"wheel_rate_{_key(CORNERS[k])}"] = kk / cv**2
            out[f"tire_rate_{_key(CORNERS[k])}"] = tt
        out[f"wheel_rate_bar_{axle}"] = 2 * bar / cv**2
        ride[axle] = sum(_series(kk / cv**2, tt) for kk, tt in zip(ks, kt, strict=True))
        damping = sum(h) / cv**2
        out[f"ride_frequency_{axle}"] = float(np.sqrt(max(_ratio(ride[axle], m_axle[axle]), 0.0)) / (2 * np.pi))
        out[f"damping_ratio_{axle}"] = _ratio(damping, 2 * float(np.sqrt(max(ride[axle] * m_axle[axle], 0.0))))
        roll[axle] = (sum(ks) + 4 * bar) * t**2 / cv**2  # N·m/rad
        roll_eff[axle] = _series(roll[axle], sum(kt) * t**2)
        centre[axle] = -t * float(np.tan(ax.damper_lateral_tilt))  # the slides' roll centre, above the ground
        out[f"roll_centre_{axle}"] = centre[axle]
    total = roll["front"] + roll["rear"]
    out.update({"roll_front": roll["front"] * DEG, "roll_rear": roll["rear"] * DEG, "roll_total": total * DEG,
                "roll_front_share": 100 * roll["front"] / total if total else float("nan")})
    # corner weights: each axle's share of the sprung mass, the lateral offset's moment shared as the roll stiffness
    share_roll = _ratio(roll_eff["front"], roll_eff["front"] + roll_eff["rear"])
    for axle, s_roll in (("front", share_roll), ("rear", 1 - share_roll)):
        t = (geometry.front if axle == "front" else geometry.rear).half_track
        for k, sign in zip(axle_corners(axle), (1.0, -1.0), strict=True):
            out[f"corner_{_key(CORNERS[k])}"] = (m_axle[axle] / 2 + sign * m6 * y_s * s_roll / (2 * t)
                                                   + wheel_m[k])
    arm = h_s - (centre["rear"] + (centre["front"] - centre["rear"]) * share_sprung)  # CoG above the roll axis
    out["roll_gradient"] = _gradient(m6 * G * arm, roll_eff["front"] + roll_eff["rear"])
    pitch = L**2 * _series(ride["front"], ride["rear"])  # N·m/rad about the ground, the body free to heave
    out["pitch_gradient"] = _gradient(m6 * G * h_s, pitch)
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


__all__ = ["AXLES", "QUANTITIES", "Quantity", "axle_corners", "car_quantities", "chassis_data_sheet",
           "chassis_from_data_sheet", "damper_vertical", "engineering_figures", "jacobian", "propagated_std"]
