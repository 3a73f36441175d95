"""A 42-frame tree shaped like the paper's car, for benchmarks (the real template lives in dynid.vehicle).

Frames 1-3 prismatic (x, y, z), 4-6 revolute (yaw, pitch, roll: 6 is the chassis), then four
corners of nine frames: half track (P), half wheelbase (P), damper (P), steering (R), camber (R),
frame 12 (R), kingpin (R), wheel spin (R), tire deflection (P, hung on the kingpin frame).
Mass on the chassis and the wheels; dampers and tires elastic; two anti-roll couplings.
"""

from __future__ import annotations

import numpy as np

from dynid.model import Coupling, Frame, Tree

ROWS = [1, 2, 3, 4, 5, 6, 9, 18, 27, 36, 15, 24, 33, 42]


def car_like_tree() -> Tree:
    h = np.pi / 2
    frames = [Frame(1, 0, 1, gamma=h, alpha=h), Frame(2, 1, 1, gamma=h, alpha=h), Frame(3, 2, 1, gamma=h, alpha=h),
              Frame(4, 3, 0), Frame(5, 4, 0, alpha=h), Frame(6, 5, 0, alpha=h)]
    values = {"XX6": 6810.0, "YY6": 6567.0, "ZZ6": 668.0, "XZ6": -445.9, "MX6": 537.0, "MZ6": 2368.0, "M6": 1685.0}
    terms: dict[int, tuple[str, ...]] = {}
    for k in range(4):
        b = 7 + 9 * k
        side = 1 if k % 2 == 0 else -1
        frames += [
            Frame(b, 6, 1, alpha=h, r=0.0),
            Frame(b + 1, b, 1, alpha=h, r=0.0),
            Frame(b + 2, b + 1, 1, alpha=h, r=0.0),
            Frame(b + 3, b + 2, 0),
            Frame(b + 4, b + 3, 0, alpha=h),
            Frame(b + 5, b + 4, 0, alpha=-h),
            Frame(b + 6, b + 5, 0, alpha=h, d=0.05 * side),
            Frame(b + 7, b + 6, 0, alpha=-h, r=0.02),
            Frame(b + 8, b + 6, 1, alpha=h),
        ]
        values.update({f"XX{b + 7}": 0.5, f"YY{b + 7}": 0.5, f"ZZ{b + 7}": 0.9, f"M{b + 7}": 15.0,
                       f"K{b + 2}": 22000.0, f"FV{b + 2}": 4200.0, f"FS{b + 2}": 20.0, f"OFF{b + 2}": 500.0,
                       f"K{b + 8}": 2e5})
        terms[b + 2] = ("FV", "FS", "OFF", "K")
        terms[b + 8] = ("K",)
    couplings = (Coupling("karr", "K", {9: 1.0, 18: -1.0}), Coupling("karf", "K", {27: 1.0, 36: -1.0}))
    values.update(karr=19185.0, karf=19780.0)
    return Tree("car-like 42-frame tree", tuple(frames), terms, couplings, values)


def identification_columns(tree: Tree) -> list[str]:
    """The paper's 48 parameters: chassis 10, per damper K FV FS OFF, per wheel XX YY ZZ M, tires K, anti-roll."""
    cols = [f"{p}6" for p in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")]
    for k in range(4):
        b = 7 + 9 * k
        cols += [f"K{b + 2}", f"FV{b + 2}", f"FS{b + 2}", f"OFF{b + 2}"]
        cols += [f"XX{b + 7}", f"YY{b + 7}", f"ZZ{b + 7}", f"M{b + 7}", f"K{b + 8}"]
    return [*cols, "karr", "karf"]
