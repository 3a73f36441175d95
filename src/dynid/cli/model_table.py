"""The geometric table of a tree in SYMORO's layout, shared by `dynid model show` and the vehicle commands."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # no model layer (NumPy) at import: `dynid --help` stays quick
    from ..model import Tree

SIGMA = {0: "R", 1: "P", 2: "F"}


def format_table(tree: Tree) -> str:
    """The geometric table in SYMORO's layout (angles in degrees where that reads better)."""
    head = f"{'j':>3} {'a(j)':>4} {'sigma':>5} {'gamma':>9} {'b':>8} {'alpha':>9} {'d':>8} {'theta':>9} {'r':>8}"
    lines = [head]
    for f in tree.frames:
        th = f"q{f.j}" + (f"{math.degrees(f.theta):+.4g}°" if f.theta else "") if f.sigma == 0 else _deg(f.theta)
        r = f"q{f.j}" + (f"{f.r:+.4g}" if f.r else "") if f.sigma == 1 else f"{f.r:.4g}"
        lines.append(
            f"{f.j:>3} {f.ant:>4} {SIGMA[f.sigma]:>5} {_deg(f.gamma):>9} {f.b:>8.4g} {_deg(f.alpha):>9} "
            f"{f.d:>8.4g} {th:>9} {r:>8}"
        )
    return "\n".join(lines)


def _deg(a: float) -> str:
    return f"{math.degrees(a):.4g}°" if a else "0"
