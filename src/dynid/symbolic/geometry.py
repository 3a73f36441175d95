"""Symbolic geometry of a modified-DH tree: constants, joint rotations, positions, DGM.

Geometric constants are numeric (floats, with sines and cosines of multiples of pi/2
made exact) or symbolic (D3, RL4, B9, CA5/SA5, CG9/SG9, TH7, CT12/ST12, G3), as the
user chooses. Angles that are multiples of pi/2 stay exact even in symbolic mode, as in
SYMORO, so that alpha = pi/2 still removes terms.

Names follow Khalil's book: iR_j entries R{r}{c}{j} (the rotation of frame j in its
antecedent), C{j}/S{j} the cosine and sine of theta_j, 0T_j entries T{r}{c}{j}, and
C23/S23 for the sum of consecutive parallel revolute joints' angles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..model.tree import FIXED, PRISMATIC, REVOLUTE, Tree
from .expr import ONE, ZERO, Poly, Program, SymbolicError, add, const, mul, scale, sym

GEOMETRY_MODES = ("numeric", "symbolic")


def _special(angle: float) -> tuple[float, float] | None:
    """(cos, sin) exactly when the angle is a multiple of pi/2 (to 1e-12 rad)."""
    k = round(angle / (math.pi / 2))
    if abs(angle - k * math.pi / 2) <= 1e-12:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[k % 4]
    return None


def _snap(x: float) -> float:
    for v in (0.0, 1.0, -1.0):
        if abs(x - v) <= 1e-15:
            return v
    return x


@dataclass
class Geometry:
    """Per-frame symbolic geometry on top of a Program (memoised)."""

    tree: Tree
    prog: Program
    mode: str = "numeric"

    def __post_init__(self) -> None:
        if self.mode not in GEOMETRY_MODES:
            raise SymbolicError(f"geometry must be one of {GEOMETRY_MODES}, got {self.mode!r}")
        self.n = self.tree.n
        self._rot: dict[int, list[list[Poly]]] = {}
        self._pos: dict[int, list[Poly]] = {}
        self._cs: dict[int, tuple[Poly, Poly]] = {}
        self._abs_rot: dict[int, list[list[Poly]]] = {}
        self._abs_pos: dict[int, list[Poly]] = {}

    # ----- names ---------------------------------------------------------------------------
    def joined(self, frames: list[int]) -> str:
        """Khalil's concatenation (C23) when every frame number is one digit, else C2_3."""
        return "".join(map(str, frames)) if self.n < 10 else "_".join(map(str, frames))

    # ----- constants -----------------------------------------------------------------------
    def length(self, name: str, j: int, value: float) -> Poly:
        if value == 0.0:
            return ZERO
        if self.mode == "numeric":
            return const(value)
        return self.prog.constant(f"{name}{j}", value)

    def angle_cs(self, name: str, j: int, value: float) -> tuple[Poly, Poly]:
        """(cos, sin) of a constant angle."""
        sp = _special(value)
        if sp is not None:
            return const(sp[0]), const(sp[1])
        if self.mode == "numeric":
            return const(_snap(math.cos(value))), const(_snap(math.sin(value)))
        return (self.prog.constant(f"C{name}{j}", math.cos(value)), self.prog.constant(f"S{name}{j}", math.sin(value)))

    def gravity(self) -> list[Poly]:
        g = self.tree.gravity
        if self.mode == "numeric":
            return [const(v) for v in g]
        return [self.prog.constant(f"G{i + 1}", v) if v != 0.0 else ZERO for i, v in enumerate(g)]

    # ----- joint variables -----------------------------------------------------------------
    def q(self, j: int) -> Poly:
        return self.prog.input(f"q{j}", ("q", j - 1))

    def qd(self, j: int) -> Poly:
        return self.prog.input(f"QP{j}", ("qd", j - 1))

    def qdd(self, j: int) -> Poly:
        return self.prog.input(f"QDP{j}", ("qdd", j - 1))

    def theta_arg(self, j: int) -> Poly:
        """theta_j for a revolute joint: q_j plus its constant offset."""
        f = self.tree.frames[j - 1]
        off = ZERO
        if f.theta != 0.0:
            off = const(f.theta) if self.mode == "numeric" or _special(f.theta) else self.prog.constant(
                f"TH{j}", f.theta
            )
        return add(self.q(j), off)

    def cs(self, j: int) -> tuple[Poly, Poly]:
        """(cos theta_j, sin theta_j)."""
        if j not in self._cs:
            f = self.tree.frames[j - 1]
            if f.sigma == REVOLUTE:
                arg = self.theta_arg(j)
                self._cs[j] = (self.prog.function(f"C{j}", "cos", arg), self.prog.function(f"S{j}", "sin", arg))
            else:
                self._cs[j] = self.angle_cs("T", j, f.theta)
        return self._cs[j]

    def r(self, j: int) -> Poly:
        """r_j, variable for a prismatic joint."""
        f = self.tree.frames[j - 1]
        if f.sigma == PRISMATIC:
            return add(self.q(j), self.length("RL", j, f.r))
        return self.length("RL", j, f.r)

    # ----- one joint -----------------------------------------------------------------------
    def const_rot(self, j: int) -> list[list[Poly]]:
        """C_j = Rot(z, gamma) Rot(x, alpha) as polys."""
        f = self.tree.frames[j - 1]
        cg, sg = self.angle_cs("G", j, f.gamma)
        ca, sa = self.angle_cs("A", j, f.alpha)
        return [
            [cg, scale(mul(sg, ca), -1.0), mul(sg, sa)],
            [sg, mul(cg, ca), scale(mul(cg, sa), -1.0)],
            [ZERO, sa, ca],
        ]

    def rot(self, j: int) -> list[list[Poly]]:
        """iR_j, i = a(j): the axes of frame j in frame a(j), entries R{r}{c}{j}."""
        if j not in self._rot:
            C = self.const_rot(j)
            c, s = self.cs(j)
            Rz = [[c, scale(s, -1.0), ZERO], [s, c, ZERO], [ZERO, ZERO, ONE]]
            R = [[add(*(mul(C[r][k], Rz[k][col]) for k in range(3))) for col in range(3)] for r in range(3)]
            self._rot[j] = [
                [self.prog.define(f"R{r + 1}{col + 1}{j}", R[r][col]) for col in range(3)] for r in range(3)
            ]
        return self._rot[j]

    def pos(self, j: int) -> list[Poly]:
        """iP_j: origin of frame j in frame a(j) = Rot(z, gamma) (d, 0, b) + r_j z_j."""
        if j not in self._pos:
            f = self.tree.frames[j - 1]
            cg, sg = self.angle_cs("G", j, f.gamma)
            ca, sa = self.angle_cs("A", j, f.alpha)
            d, b, r = self.length("D", j, f.d), self.length("B", j, f.b), self.r(j)
            z = [mul(sg, sa), scale(mul(cg, sa), -1.0), ca]
            P = [add(mul(cg, d), mul(r, z[0])), add(mul(sg, d), mul(r, z[1])), add(b, mul(r, z[2]))]
            self._pos[j] = [self.prog.define(f"P{c + 1}{j}", P[c]) for c in range(3)]
        return self._pos[j]

    def down(self, j: int, v: list[Poly]) -> list[Poly]:
        """jR_i v: a vector of frame a(j) in frame j (unnamed result)."""
        R = self.rot(j)
        return [add(*(mul(R[k][r], v[k]) for k in range(3))) for r in range(3)]

    def up(self, j: int, v: list[Poly]) -> list[Poly]:
        """iR_j v: a vector of frame j in frame a(j)."""
        R = self.rot(j)
        return [add(*(mul(R[r][k], v[k]) for k in range(3))) for r in range(3)]

    def name3(self, base: str, j: int, v: list[Poly], suffix: str = "") -> list[Poly]:
        return [self.prog.define(f"{base}{c + 1}{j}{suffix}", v[c]) for c in range(3)]

    # ----- absolute (DGM) --------------------------------------------------------------------
    def _run(self, j: int) -> list[int]:
        """Frames whose z rotations combine into one angle ending at j: consecutive revolute
        joints with alpha = 0 between them (parallel axes), e.g. [2, 3] for C23."""
        run = [j]
        if self.tree.frames[j - 1].sigma != REVOLUTE:
            return run
        k = j
        while True:
            fk = self.tree.frames[k - 1]
            i = fk.ant
            if i == 0 or self.tree.frames[i - 1].sigma != REVOLUTE or _special(fk.alpha) != (1.0, 0.0):
                return run
            run.insert(0, i)
            k = i

    def abs_rot(self, j: int) -> list[list[Poly]]:
        """0R_j, entries T{r}{c}{j}; sums of parallel joints' angles are combined (C23)."""
        if j == 0:
            return [[ONE, ZERO, ZERO], [ZERO, ONE, ZERO], [ZERO, ZERO, ONE]]
        if j in self._abs_rot:
            return self._abs_rot[j]
        run = self._run(j)
        if len(run) == 1:
            base = self.abs_rot(self.tree.frames[j - 1].ant)
            R = self.rot(j)
        else:
            top = run[0]
            base = self.abs_rot(self.tree.frames[top - 1].ant)
            C = self.const_rot(top)
            arg = add(*(self.theta_arg(k) for k in run))
            gam = sum(self.tree.frames[k - 1].gamma for k in run[1:])
            if gam != 0.0:
                arg = add(arg, const(gam))
            name = self.joined(run)
            c = self.prog.function(f"C{name}", "cos", arg)
            s = self.prog.function(f"S{name}", "sin", arg)
            Rz = [[c, scale(s, -1.0), ZERO], [s, c, ZERO], [ZERO, ZERO, ONE]]
            R = [[add(*(mul(C[r][k], Rz[k][col]) for k in range(3))) for col in range(3)] for r in range(3)]
        out = [
            [
                self.prog.define(f"T{r + 1}{c + 1}{j}", add(*(mul(base[r][k], R[k][c]) for k in range(3))))
                for c in range(3)
            ]
            for r in range(3)
        ]
        self._abs_rot[j] = out
        return out

    def abs_pos(self, j: int) -> list[Poly]:
        """0P_j, entries T{r}4{j}."""
        if j == 0:
            return [ZERO, ZERO, ZERO]
        if j not in self._abs_pos:
            i = self.tree.frames[j - 1].ant
            R, p0, P = self.abs_rot(i), self.abs_pos(i), self.pos(j)
            self._abs_pos[j] = [
                self.prog.define(f"T{r + 1}4{j}", add(p0[r], *(mul(R[r][k], P[k]) for k in range(3)))) for r in range(3)
            ]
        return self._abs_pos[j]


def moving(tree: Tree, j: int) -> bool:
    return tree.frames[j - 1].sigma != FIXED


def axis_sym(sigma: int) -> tuple[list[Poly], list[Poly]]:
    """Unit twist of a joint in its own frame: (angular, linear)."""
    z = [ZERO, ZERO, ONE]
    zero = [ZERO, ZERO, ZERO]
    return (z, zero) if sigma == REVOLUTE else (zero, z)


__all__ = ["GEOMETRY_MODES", "Geometry", "axis_sym", "moving", "sym"]
