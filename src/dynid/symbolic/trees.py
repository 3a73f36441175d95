"""Trees for exercising the generator: a car-shaped 42-frame tree and random trees.

The car-shaped tree has the paper's structure and numbering (DESIGN.md section 5) with
plausible, not measured, geometry: frames 1-3 translate the chassis along the ground
axes, 4-5 yaw and pitch, 6 rolls (z6 longitudinal); each corner k uses frames
7+9k..15+9k: half track and half wheelbase (fixed), damper (prismatic, elastic,
viscous, dry friction, offset), steering, camber, a fixed frame, kingpin, the wheel
(revolute) and the tire deflection (prismatic, elastic) hung on the kingpin frame, so
that a(15) = 13. Anti-roll bars couple the dampers 9-18 (karr) and 27-36 (karf).
Its identification model is the paper's 14 equations x 48 parameters (CAR_ROWS, CAR_COLS).
"""

from __future__ import annotations

import math

import numpy as np

from ..model.tree import INERTIAL, JOINT_TERMS, Coupling, Frame, Tree

CAR_ROWS = (1, 2, 3, 4, 5, 6, 9, 18, 27, 36, 15, 24, 33, 42)
_WHEELS = (14, 23, 32, 41)
_DAMPERS = (9, 18, 27, 36)
_TIRES = (15, 24, 33, 42)
CAR_COLS = (
    tuple(f"{p}6" for p in INERTIAL)
    + tuple(f"{t}{j}" for j in _DAMPERS for t in ("K", "FV", "FS", "OFF"))
    + tuple(f"{p}{j}" for j in _WHEELS for p in ("XX", "YY", "ZZ", "M"))
    + tuple(f"K{j}" for j in _TIRES)
    + ("karf", "karr")
)


def car_like_tree() -> Tree:
    """The paper's 42-frame car structure with plausible values (see the module doc)."""
    h = math.pi / 2
    frames = [
        Frame(1, 0, 1, gamma=h, alpha=h),
        Frame(2, 1, 1, gamma=h, alpha=h),
        Frame(3, 2, 1, gamma=h, alpha=h),
        Frame(4, 3, 0),
        Frame(5, 4, 0, alpha=h),
        Frame(6, 5, 0, alpha=h),
    ]
    values: dict[str, float] = {
        "XX6": 6810.44, "XY6": 12.0, "XZ6": -445.9, "YY6": 6567.0, "YZ6": 8.0, "ZZ6": 668.56,
        "MX6": 537.24, "MY6": 5.81, "MZ6": 2368.21, "M6": 1685.0,
    }
    joint_terms: dict[int, tuple[str, ...]] = {}
    for k in range(4):
        o = 9 * k
        side = 1.0 if k % 2 == 0 else -1.0
        front = k >= 2
        frames += [
            Frame(7 + o, 6, 2, d=0.75 * side),  # half track along x6
            Frame(8 + o, 7 + o, 2, r=2.7 if front else 0.0),  # half wheelbase along z6
            Frame(9 + o, 8 + o, 1, alpha=-h, r=-0.3),  # damper clearance
            Frame(10 + o, 9 + o, 0, theta=0.0),  # steering about the damper axis
            Frame(11 + o, 10 + o, 0, alpha=h, d=0.05),  # camber
            Frame(12 + o, 11 + o, 2, alpha=-h, d=0.02, theta=h),  # wheel-carrier offset
            Frame(13 + o, 12 + o, 0, alpha=0.2, r=0.03),  # kingpin
            Frame(14 + o, 13 + o, 0, alpha=h, d=0.04 * side),  # wheel spin
            Frame(15 + o, 13 + o, 1, gamma=0.1, b=0.01, alpha=-h, d=0.04 * side),  # tire deflection
        ]
        d, w, t = 9 + o, 14 + o, 15 + o
        joint_terms[d] = ("FV", "FS", "OFF", "K")
        joint_terms[t] = ("K",)
        values.update({f"K{d}": 22000.0 if not front else 20000.0, f"FV{d}": 4200.0 if not front else 3200.0,
                       f"FS{d}": 20.0, f"OFF{d}": 300.0, f"K{t}": 200000.0})
        values.update({f"XX{w}": 0.9, f"YY{w}": 0.9, f"ZZ{w}": 1.6, f"M{w}": 20.0, f"MZ{w}": 0.1})
        values.update({f"M{10 + o}": 8.0, f"MZ{10 + o}": 1.2, f"ZZ{10 + o}": 0.3, f"XX{10 + o}": 0.2,
                       f"YY{10 + o}": 0.2, f"M{13 + o}": 3.0, f"MX{13 + o}": 0.1, f"XX{13 + o}": 0.05,
                       f"YY{13 + o}": 0.06, f"ZZ{13 + o}": 0.06})
    couplings = (Coupling("karf", "K", {27: 1.0, 36: -1.0}), Coupling("karr", "K", {9: 1.0, 18: -1.0}))
    values.update({"karf": 19780.0, "karr": 19185.0})
    return Tree("car-like 42-frame tree", tuple(frames), joint_terms=joint_terms, couplings=couplings, values=values)


def random_tree(n: int = 42, seed: int = 0, floating: bool = False) -> Tree:
    """A random tree: random antecedents, joint kinds, geometry (some angles multiples of
    pi/2, some zero lengths), parameters, joint terms and two couplings."""
    rng = np.random.default_rng(seed)
    frames = []
    start = 1
    if floating:
        h = math.pi / 2
        frames += [Frame(1, 0, 1, gamma=h, alpha=h), Frame(2, 1, 1, gamma=h, alpha=h),
                   Frame(3, 2, 1, gamma=h, alpha=h), Frame(4, 3, 0), Frame(5, 4, 0, alpha=h), Frame(6, 5, 0, alpha=h)]
        start = 7
    specials = (0.0, math.pi / 2, -math.pi / 2, math.pi)
    for j in range(start, n + 1):
        ant = int(rng.integers(max(0, j - 4), j)) if j > 1 else 0
        sigma = int(rng.choice([0, 0, 0, 1, 1, 2]))

        def ang() -> float:
            return float(rng.choice(specials)) if rng.random() < 0.6 else float(rng.uniform(-math.pi, math.pi))

        def length() -> float:
            return 0.0 if rng.random() < 0.4 else float(rng.uniform(-0.5, 0.5))

        gamma = ang() if rng.random() < 0.3 else 0.0
        b = length() if rng.random() < 0.3 else 0.0
        frames.append(Frame(j, ant, sigma, gamma=gamma, b=b, alpha=ang(), d=length(), theta=ang(), r=length()))
    values: dict[str, float] = {}
    joint_terms: dict[int, tuple[str, ...]] = {}
    moving = [f.j for f in frames if f.sigma != 2]
    for f in frames:
        m = float(rng.uniform(0.5, 3.0))
        c = rng.uniform(-0.1, 0.1, 3)
        A = rng.normal(size=(3, 3))
        J = A @ A.T * 0.05 + m * (c @ c * np.eye(3) - np.outer(c, c))
        for name, v in zip(INERTIAL, (J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2], *(m * c), m), strict=True):
            values[f"{name}{f.j}"] = float(v)
        if f.sigma != 2 and rng.random() < 0.6:
            terms = tuple(t for t in JOINT_TERMS if rng.random() < 0.5)
            if terms:
                joint_terms[f.j] = terms
                values.update({f"{t}{f.j}": float(rng.uniform(0.1, 2.0)) for t in terms})
    a, b, c2, d2 = (int(x) for x in rng.choice(moving, 4, replace=False))
    couplings = (Coupling("kc1", "K", {a: 1.0, b: -1.0}), Coupling("fc2", "FS", {c2: 2.0, d2: 0.5}))
    values.update({"kc1": 10.0, "fc2": 0.3})
    return Tree(f"random tree {n} (seed {seed})", tuple(frames), joint_terms=joint_terms, couplings=couplings,
                values=values)
