"""The paper's car as a 42-frame modified-DH tree, numbered as in the paper.

Ground frame 0: x0 to the right and y0 forward at zero yaw, z0 up (the paper's Table 1
calls q1 the lateral and q2 the longitudinal position), gravity (0, 0, -9.81).

  j     joint            role                  axis (design position, all q = 0)
  1-3   P  x, y, z       free (virtual)        x0, y0, z0: frame 3 has the ground's axes
  4     R  yaw           free (virtual)        z0 (up); q4 > 0 turns the car to the left
  5     R  pitch         free (virtual)        the car's right axis; q5 > 0 nose up
  6     R  roll          free, the CHASSIS     z6 forward; q6 > 0 lowers the right side
Chassis frame 6: x6 up, y6 right, z6 forward, origin O6 on the rear axle (see geometry.py).

Corner k = 0 rear left, 1 rear right, 2 front left, 3 front right uses frames
7+9k .. 15+9k (base b = 7+9k); s = -1 on the left, +1 on the right:
  b     P  half track      constant             outward lateral axis; value in r, q = 0
  b+1   P  half wheelbase  constant             outward longitudinal axis; value in r, q = 0
  b+2   P  damper          elastic ks h fs off  damper axis, UP (towards the top mount):
                           clearance            q > 0 is bump (the wheel moves towards the body);
                                                q = 0 is the design position
  b+3   R  steering        measured/tabulated   x6 (up) through the wheel centre; > 0 to the left
  b+4   R  camber          measured/tabulated   s * wheel heading; > 0 top of the wheel outboard
  b+5   R  caster          tabulated            y6 (right); > 0 tilts the hub's kingpin axis top
                                                rearward (side-view rotation of the hub). At
                                                q(b+6) = 0 this axis is the spin axis, so caster
                                                does not move the wheel plane: it turns the hub
                                                frame, the kingpin axis and the tire-deflection axis
  b+6   R  kingpin         tabulated            the kingpin axis (inclination and caster of
                                                AxleGeometry, at kingpin_offset inboard of the
                                                wheel centre): the hub turning about its kingpin
  b+7   R  wheel spin      no known torque      the wheel's axle pointing LEFT: q' > 0 rolling
                           (the WHEEL body)     forward; origin at the wheel centre
  b+8   P  tire deflection elastic kt; a = b+6  the hub's up axis in the wheel plane; origin at
                                                the contact point, wheel_radius - q below the
                                                wheel centre: q > 0 compresses the tire
Frame b+8 is hung on the hub (a(b+8) = b+6, not the spinning wheel), so the measured
ground wrench applied to it is seen by every equation above it, and its equation reads
kt * q = Fz (the force along its axis). Its axes are the non-spinning wheel frame of the
dynamometric wheels: x forward in the wheel plane, y left along the axle, z up.

Constants: the half track and half wheelbase (and every offset) live in the MDH
constants (r, b, d, ...) computed from CarGeometry; their q columns stay ZERO. This keeps
the geometry in the model and lets a trajectory carry only what moves.

Parameters (the paper's labels): chassis XX6..M6; damper K9/FV9/FS9/OFF9 labelled
ks9/h9/fs9/off9; wheels XX14 YY14 ZZ14 M14 (about the wheel centre, z14 the axle); tires
K15 labelled kt15; anti-roll bars karr (K coupling q9 - q18) and karf (q27 - q36).
Links 1-5 and 7-13, 15 are massless (their parameters exist but are zero and not identified).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..car_frames import CHASSIS, CORNER_FRAMES, DAMPERS, TIRES, base, damper, tire, wheel
from ..car_frames import WHEELS as WHEELS  # the car's modules name these from here
from ..car_frames import tabulated as tabulated
from ..model.tree import PRISMATIC, REVOLUTE, Coupling, Frame, Tree
from .geometry import CarGeometry, side

CORNERS = ("rear left", "rear right", "front left", "front right")
ROLES = ("half track", "half wheelbase", "damper", "steering", "camber", "caster", "kingpin", "wheel", "tire")
FREE_JOINTS = (1, 2, 3, 4, 5, 6)
CHASSIS_GROUPS = ("x", "y", "z", "yaw", "pitch", "roll")
FRAMES = 42
# a corner's frames are numbered by ..car_frames (base, damper, wheel, tire, tabulated; DAMPERS, WHEELS, TIRES), a leaf
# that a config's reader names them from without loading this layer; ROLES has one entry per frame of a corner
CONSTANT_JOINTS = tuple(j for k in range(4) for j in (base(k), base(k) + 1))
EQUATION_ROWS = (*FREE_JOINTS, *DAMPERS, *TIRES)


def corner_of(frame: int) -> int:
    """The corner (index into CORNERS) a frame belongs to."""
    for k in range(len(CORNERS)):
        if base(k) <= frame < base(k) + CORNER_FRAMES:
            return k
    raise ValueError(f"frame {frame} is not in a corner ({base(0)}..{FRAMES})")


def role(frame: int) -> str:
    """What a frame is: 'x', 'roll', 'damper', 'wheel', ..."""
    if frame <= CHASSIS:
        return CHASSIS_GROUPS[frame - 1]
    return ROLES[frame - base(corner_of(frame))]


def paper_parameter_names() -> tuple[str, ...]:
    """The paper's 48 parameters in its order X6 X9 X14 X15 X18 ... X42 Xar, by dynid name."""
    names = [f"{p}6" for p in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")]
    for k in range(4):
        d, w, t = damper(k), wheel(k), tire(k)
        names += [f"K{d}", f"FV{d}", f"FS{d}", f"OFF{d}"]
        names += [f"XX{w}", f"YY{w}", f"ZZ{w}", f"M{w}"]
        names.append(f"K{t}")
    return (*names, "karf", "karr")


# a damper's curve (car_template(damper_knees=...)): its four slopes, model.tree's viscous curve terms on the
# clearance, whose positive direction is BUMP (q > 0 compresses the suspension): FVPL / FVPH the bump slopes below /
# above the bump knee, FVNL / FVNH the rebound slopes below / above the rebound knee (in speed)
CURVE_LABELS = {"FVPL": "hbl", "FVPH": "hbh", "FVNL": "hrl", "FVNH": "hrh"}
CURVE_MEANINGS = {"FVPL": "bump, low speed", "FVPH": "bump, high speed", "FVNL": "rebound, low speed",
                  "FVNH": "rebound, high speed"}


def labels() -> dict[str, str]:
    out: dict[str, str] = {}
    for d in DAMPERS:
        out.update({f"K{d}": f"ks{d}", f"FV{d}": f"h{d}", f"FS{d}": f"fs{d}", f"OFF{d}": f"off{d}"})
        out.update({f"{t}{d}": f"{lab}{d}" for t, lab in CURVE_LABELS.items()})
    for t in TIRES:
        out.update({f"K{t}": f"kt{t}", f"OFF{t}": f"off{t}", f"KQ{t}": f"ktq{t}", f"KFY{t}": f"ktfy{t}"})
    return out


# what each parameter is, in a chassis engineer's words: the quantity by the kind of parameter and the role of its
# frame, the corner from the frame (the anti-roll bars: the axle of the dampers they couple)
_CHASSIS_AXES = {"XX": "yaw inertia about O6", "YY": "pitch inertia about O6", "ZZ": "roll inertia about O6",
                 "XY": "product of inertia xy6", "XZ": "product of inertia xz6", "YZ": "product of inertia yz6"}
_QUANTITY = {
    ("damper", "K"): ("spring", "N/m"), ("damper", "FV"): ("damping", "N·s/m"),
    ("damper", "FS"): ("dry friction", "N"), ("damper", "OFF"): ("spring preload (offset)", "N"),
    ("tire", "K"): ("tire vertical stiffness", "N/m"), ("tire", "OFF"): ("tire load offset", "N"),
    ("tire", "KQ"): ("tire progressive stiffness (q² term)", "N/m²"),
    ("tire", "KFY"): ("tire stiffness change with lateral force (-Fy² q term)", "1/(N·m)"),
    ("wheel", "M"): ("wheel mass", "kg"), ("wheel", "XX"): ("wheel inertia, diametral", "kg·m²"),
    ("wheel", "YY"): ("wheel inertia, diametral", "kg·m²"), ("wheel", "ZZ"): ("wheel inertia, spin", "kg·m²"),
    **{("damper", t): (f"damping slope, {m}", "N·s/m") for t, m in CURVE_MEANINGS.items()},
}


@dataclass(frozen=True)
class Meaning:
    """What a parameter of the car is: its corner ("rear left", ..., "front axle", "chassis"), the quantity
    ("spring", "damper", "tire vertical stiffness", "chassis inertia, yaw (about x6, up)", ...) and its SI unit."""

    corner: str
    quantity: str
    unit: str

    def text(self) -> str:
        """ "spring, rear left" """
        return f"{self.quantity}, {self.corner}"


def meaning(name: str) -> Meaning | None:
    """The corner, quantity and unit of a parameter of the car template (dynid name or the paper's label); None for
    a name that is not one (a robot's, a base parameter's combination)."""
    name = {label: n for n, label in labels().items()}.get(name, name)
    for bar, couples in (("karr", (0, 1)), ("karf", (2, 3))):
        if name == bar:
            axle = CORNERS[couples[0]].split()[0]
            return Meaning(f"{axle} axle", "anti-roll bar", "N/m")
    kind = name.rstrip("0123456789")
    if not kind or kind == name:
        return None
    j = int(name[len(kind):])
    if j == CHASSIS:
        if kind == "M":
            return Meaning("chassis", "sprung mass", "kg")
        if kind in ("MX", "MY", "MZ"):
            return Meaning("chassis", f"first moment {kind[1].lower()}6", "kg·m")
        if kind in _CHASSIS_AXES:
            return Meaning("chassis", _CHASSIS_AXES[kind], "kg·m²")
        return None
    if not base(0) <= j <= FRAMES:
        return None
    found = _QUANTITY.get((role(j), kind))
    return None if found is None else Meaning(CORNERS[corner_of(j)], *found)


# ----- design poses and their MDH rows -------------------------------------------------

@dataclass(frozen=True)
class _Pose:
    """A frame's design pose in frame-6 coordinates: origin and axes x, z (y = z cross x)."""

    origin: np.ndarray
    x: np.ndarray
    z: np.ndarray

    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, 0], T[:3, 2] = self.x, self.z
        T[:3, 1] = np.cross(self.z, self.x)
        T[:3, 3] = self.origin
        return T


UP, RIGHT, FORWARD = np.eye(3)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _ortho(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The part of x perpendicular to z, normalised (an x axis for a frame whose z is given)."""
    return _unit(x - (x @ z) * z)


def mdh_from_poses(j: int, ant: int, sigma: int, Ta: np.ndarray, Tj: np.ndarray) -> Frame:
    """The MDH row (gamma, b, alpha, d, theta, r) taking pose Ta to pose Tj at q_j = 0.

    Rot(z, gamma) Trans(z, b) Rot(x, alpha) Trans(x, d) Rot(z, theta) Trans(z, r): x' =
    Rot(z, gamma) x_a is the common normal of z_a and z_j; when they are parallel, x' is
    chosen along the offset so that the origin is reachable (b = 0 then, the axial part in r).
    """
    R = Ta[:3, :3].T @ Tj[:3, :3]
    p = Ta[:3, :3].T @ (Tj[:3, 3] - Ta[:3, 3])
    x, z = R[:, 0], R[:, 2]
    ez = np.array([0.0, 0.0, 1.0])
    n = np.cross(ez, z)
    s = np.linalg.norm(n)
    if s > 1e-12:
        xp = n / s
        alpha = float(np.arctan2(s, z[2]))
        b, d, r = np.linalg.solve(np.column_stack([ez, xp, z]), p)
    else:
        alpha = 0.0 if z[2] > 0 else float(np.pi)
        perp = np.array([p[0], p[1], 0.0])
        if np.linalg.norm(perp) > 1e-12:
            xp, d = perp / np.linalg.norm(perp), float(np.linalg.norm(perp))
        else:
            xp, d = np.array([x[0], x[1], 0.0]) / np.linalg.norm(x[:2]), 0.0
        b, r = 0.0, float(p[2] * z[2])
    theta = float(np.arctan2(np.cross(xp, x) @ z, xp @ x))
    if abs(theta) > np.pi / 2 + 1e-9:  # the other common normal reads better: |theta| <= 90°
        xp, alpha, d, theta = -xp, -alpha, -d, theta - np.pi * np.sign(theta)
    gamma = float(np.arctan2(xp[1], xp[0]))
    clean = [0.0 if abs(v) < 1e-14 else float(v) for v in (gamma, b, alpha, d, theta, r)]
    return Frame(j, ant, sigma, *clean)


def design_poses(geometry: CarGeometry) -> dict[int, np.ndarray]:
    """Design poses (q = 0) of frames 6..42 in frame-6 coordinates, 4x4 each."""
    poses: dict[int, np.ndarray] = {CHASSIS: np.eye(4)}
    for k in range(4):
        s, ax = side(k), geometry.axle(k)
        b = base(k)
        W = geometry.wheel_centre(k)
        out_lat, out_long = s * RIGHT, (FORWARD if k >= 2 else -FORWARD)
        damper_axis = _unit(UP - s * np.tan(ax.damper_lateral_tilt) * RIGHT
                            - np.tan(ax.damper_longitudinal_tilt) * FORWARD)
        kingpin_axis = _unit(UP - s * np.tan(ax.kingpin_inclination) * RIGHT - np.tan(ax.caster) * FORWARD)
        on_kingpin = W - s * ax.kingpin_offset * RIGHT
        P7 = np.array([geometry.wheel_centre_height, s * ax.half_track, 0.0])
        seq = [
            _Pose(P7, UP, out_lat),
            _Pose(P7 + ax.position * FORWARD, UP, out_long),
            _Pose(W, _ortho(FORWARD, damper_axis), damper_axis),
            _Pose(W, FORWARD, UP),
            _Pose(W, UP, s * FORWARD),
            _Pose(W, UP, RIGHT),
            _Pose(on_kingpin, _ortho(FORWARD, kingpin_axis), kingpin_axis),
            _Pose(W, FORWARD, -RIGHT),
            _Pose(W - geometry.wheel_radius * UP, FORWARD, UP),
        ]
        for i, pose in enumerate(seq):
            poses[b + i] = pose.matrix()
    return poses


def antecedent(j: int) -> int:
    if j <= 6:
        return j - 1
    r = (j - 7) % 9
    if r == 0:
        return CHASSIS
    if r == 8:
        return j - 2  # the tire hangs on the kingpin (hub) frame, not on the spinning wheel
    return j - 1


def sigma(j: int) -> int:
    if j <= 3:
        return PRISMATIC
    if j <= 6:
        return REVOLUTE
    return PRISMATIC if (j - 7) % 9 in (0, 1, 2, 8) else REVOLUTE


def frames(geometry: CarGeometry) -> tuple[Frame, ...]:
    h = np.pi / 2
    rows = [Frame(1, 0, PRISMATIC, gamma=h, alpha=h), Frame(2, 1, PRISMATIC, gamma=h, alpha=h),
            Frame(3, 2, PRISMATIC, gamma=h, alpha=h), Frame(4, 3, REVOLUTE),
            Frame(5, 4, REVOLUTE, gamma=h, alpha=h), Frame(6, 5, REVOLUTE, gamma=h, alpha=h)]
    poses = design_poses(geometry)
    for j in range(7, FRAMES + 1):
        a = antecedent(j)
        rows.append(mdh_from_poses(j, a, sigma(j), poses[a], poses[j]))
    return tuple(rows)


# the tire equation's law (see car_template): the paper's linear spring, or a progressive one
TIRE_LAWS = ("paper", "progressive")


def car_tree(
    geometry: CarGeometry,
    values: Mapping[str, float],
    name: str = "car",
    tire_offsets: bool = False,
    tire_law: str = "paper",
    damper_knees: Mapping[int, tuple[float, float]] | None = None,
    damper_friction: dict[int, tuple[str, float]] | None = None,
    tire_lateral_force: bool = False,
) -> Tree:
    """The 42-frame tree of the car with these values (name or label -> value; the rest 0): its frames, joint terms
    and couplings, nothing solved. `car_model.car_template` is the one to call: the paper's a priori values by
    default. The options are `car_template`'s."""
    if tire_law not in TIRE_LAWS:
        raise ValueError(f"tire_law must be one of {TIRE_LAWS}; got {tire_law!r}")
    if tire_lateral_force and tire_law != "progressive":
        raise ValueError("tire_lateral_force is an option of the progressive tire law: give tire_law='progressive'")
    knees = dict(damper_knees or {})
    if set(knees) - set(DAMPERS):
        raise ValueError(f"damper_knees: keys must be damper frames {DAMPERS}; got {sorted(knees)}")
    terms = {d: ("FV", "FS", "OFF", "K") for d in DAMPERS}
    for d, (lo, hi) in knees.items():  # an infinite knee: no high-speed slope on that side
        terms[d] = ("FS", "OFF", "K", "FVPL", *(("FVPH",) if math.isfinite(hi) else ()), "FVNL",
                    *(("FVNH",) if math.isfinite(lo) else ()))
    tire_terms = ("OFF", "K") if tire_offsets else ("K",)
    terms.update({t: (*tire_terms, "KQ") if tire_law == "progressive" else tire_terms for t in TIRES})
    couplings = (Coupling("karr", "K", {damper(0): 1.0, damper(1): -1.0}),
                 Coupling("karf", "K", {damper(2): 1.0, damper(3): -1.0}))
    tree = Tree(name, frames(geometry), terms, couplings, {}, frozenset(), labels(), (0.0, 0.0, -9.81),
                knees={d: (float(lo), float(hi)) for d, (lo, hi) in knees.items()},
                friction_shape=dict(damper_friction or {}),
                load_terms=dict.fromkeys(TIRES, ("KFY",)) if tire_lateral_force else {})
    values = dict(values)
    for d in knees:  # a curved damper's h (the paper's a priori, say): the value of each slope not given
        h = [values.pop(n) for n in (f"FV{d}", f"h{d}") if n in values]
        for t in terms[d][3:]:
            if h and f"{t}{d}" not in values and f"{CURVE_LABELS[t]}{d}" not in values:
                values[f"{t}{d}"] = h[-1]
    return tree.with_values(values)
