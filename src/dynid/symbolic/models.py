"""Customised symbolic Newton-Euler over a modified-DH tree, and the models built on it.

One forward recursion (Khalil's formulation, names from his book):

    WI_j = jR_i W_i                       W_j = WI_j + qd_j z         (revolute)
    WP_j = jR_i WP_i + qdd_j z + WI_j x qd_j z
    DV_ab,j = W_a W_b                     U_j = [WP_j x] + [W_j x][W_j x]
    VSP_j = VP_i + U_i iP_j               VP_j = jR_i VSP_j (+ qdd_j z + 2 W_j x qd_j z, prismatic)
    F_j = M_j VP_j + U_j MS_j             No_j = J_j WP_j + W_j x (J_j W_j) + MS_j x VP_j

gravity entering as VP_0 = -g; then a backward recursion of the link forces E_j and
moments N_j (FDI/NDI the child's wrench moved to its antecedent) and GAM_j, the joint
force. The identification model projects each link's wrench per unit parameter on the
unit twists of its ancestors' joints moved to the link's frame (JW/JV), and the inertia
matrix uses composite links. Every model is a `Program` of named intermediate
equations; see expr.py for the zero/one bookkeeping.
"""

from __future__ import annotations

import inspect
import keyword
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..dynamics.regressor import resolve_cols as _engine_cols
from ..dynamics.regressor import resolve_rows as _engine_rows
from ..model.tree import FIXED, INERTIAL, LOAD_TERMS, PRISMATIC, REVOLUTE, ModelError, Tree
from .expr import ONE, ZERO, OpCount, Poly, Program, SymbolicError, add, const, cross, dot, mul, neg, scale, sub, sym
from .geometry import Geometry, axis_sym

PARAMETER_MODES = ("symbolic", "numeric")
MODELS = ("dgm", "idm", "regressor", "inertia")


@dataclass(frozen=True)
class WrenchSite:
    """Where an external wrench acts, fixed at generation time (its values are inputs).

    The wrench is exerted BY the environment ON link `link`: force then moment about
    `point` (coordinates in frame `link`), components expressed in frame `frame`
    (default: `link`; 0 for the ground frame). Same convention as dynid.Wrench.
    """

    link: int
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame: int | None = None


def identifier(name: str, taken: set[str]) -> str:
    """A code identifier for a parameter name (the name itself when it is one)."""

    if name.isidentifier() and not keyword.iskeyword(name) and name.isascii():
        return name
    base = "P_" + "".join(ch if ch.isalnum() and ch.isascii() else "_" for ch in name)
    out, k = base, 1
    while out in taken:
        k += 1
        out = f"{base}_{k}"
    return out


class Builder:
    """The symbolic recursions of one tree into one Program (memoised per frame)."""

    def __init__(
        self,
        tree: Tree,
        model: str,
        shape: tuple[int, ...],
        geometry: str = "numeric",
        parameters: str = "symbolic",
        wrenches: Sequence[WrenchSite] = (),
    ) -> None:
        check_tree(tree)
        if parameters not in PARAMETER_MODES:
            raise SymbolicError(f"parameters must be one of {PARAMETER_MODES}, got {parameters!r}")
        self.tree = tree
        self.prog = Program(model, shape)
        self.geo = Geometry(tree, self.prog, geometry)
        self.param_mode = parameters
        self.sites = check_sites(tree, wrenches)
        self.n = tree.n
        self._W: dict[int, list[Poly]] = {0: [ZERO] * 3}
        self._WI: dict[int, list[Poly]] = {}
        self._WP: dict[int, list[Poly]] = {0: [ZERO] * 3}
        self._VP: dict[int, list[Poly]] = {}
        self._DV: dict[int, dict[tuple[int, int], Poly]] = {}
        self._U: dict[int, list[list[Poly]]] = {}
        self._jac: dict[tuple[int, int], tuple[list[Poly], list[Poly]]] = {}
        self._ids: dict[str, str] = {}
        taken: set[str] = set()
        for name in tree.parameter_names:
            self._ids[name] = identifier(name, taken)
            taken.add(self._ids[name])
        self.prog.meta["parameter_identifiers"] = dict(self._ids)

    # ----- inputs ----------------------------------------------------------------------------
    def param(self, name: str) -> Poly:
        if self.param_mode == "numeric":
            return const(self.tree.values.get(name, 0.0))
        return self.prog.input(self._ids[name], ("X", self.tree.index[name]))

    def frame_params(self, j: int) -> dict[str, Poly]:
        return {p: self.param(f"{p}{j}") for p in INERTIAL}

    # ----- forward recursion ---------------------------------------------------------------
    def sigma(self, j: int) -> int:
        return self.tree.frames[j - 1].sigma

    def ant(self, j: int) -> int:
        return self.tree.frames[j - 1].ant

    def wi(self, j: int) -> list[Poly]:
        if j not in self._WI:
            self._WI[j] = self.geo.name3("WI", j, self.geo.down(j, self.w(self.ant(j))))
        return self._WI[j]

    def w(self, j: int) -> list[Poly]:
        """Angular velocity of link j in frame j."""
        if j not in self._W:
            wi = self.wi(j)
            if self.sigma(j) == REVOLUTE:
                self._W[j] = [wi[0], wi[1], self.prog.define(f"W3{j}", add(wi[2], self.geo.qd(j)))]
            else:
                self._W[j] = wi
        return self._W[j]

    def wp(self, j: int) -> list[Poly]:
        """Angular acceleration of link j in frame j."""
        if j not in self._WP:
            v = self.geo.down(j, self.wp(self.ant(j)))
            if self.sigma(j) == REVOLUTE:
                wi, qd = self.wi(j), self.geo.qd(j)
                v = [add(v[0], mul(qd, wi[1])), sub(v[1], mul(qd, wi[0])), add(v[2], self.geo.qdd(j))]
            self._WP[j] = self.geo.name3("WP", j, v)
        return self._WP[j]

    def dv(self, j: int) -> dict[tuple[int, int], Poly]:
        """Products W_a W_b of link j (Khalil's DV)."""
        if j not in self._DV:
            w = self.w(j)
            self._DV[j] = {
                (a, b): self.prog.define(f"DV{a + 1}{b + 1}{j}", mul(w[a], w[b])) for a in range(3) for b in range(a, 3)
            }
        return self._DV[j]

    def u(self, j: int) -> list[list[Poly]]:
        """U_j = [WP x] + [W x][W x], entries U{r}{c}{j}."""
        if j == 0:
            return [[ZERO] * 3 for _ in range(3)]
        if j not in self._U:
            d, wp = self.dv(j), self.wp(j)
            U = [
                [neg(add(d[1, 1], d[2, 2])), sub(d[0, 1], wp[2]), add(d[0, 2], wp[1])],
                [add(d[0, 1], wp[2]), neg(add(d[0, 0], d[2, 2])), sub(d[1, 2], wp[0])],
                [sub(d[0, 2], wp[1]), add(d[1, 2], wp[0]), neg(add(d[0, 0], d[1, 1]))],
            ]
            self._U[j] = [[self.prog.define(f"U{r + 1}{c + 1}{j}", U[r][c]) for c in range(3)] for r in range(3)]
        return self._U[j]

    def vp(self, j: int) -> list[Poly]:
        """Linear acceleration of O_j minus gravity, in frame j."""
        if j == 0:
            return [neg(g) for g in self.geo.gravity()]
        if j not in self._VP:
            i = self.ant(j)
            U, P = self.u(i), self.geo.pos(j)
            vsp = self.geo.name3("VSP", j, [add(self.vp(i)[r], dot(U[r], P)) for r in range(3)])
            v = self.geo.down(j, vsp)
            if self.sigma(j) == PRISMATIC:
                w, qd = self.w(j), self.geo.qd(j)
                v = [add(v[0], scale(mul(qd, w[1]), 2.0)), sub(v[1], scale(mul(qd, w[0]), 2.0)),
                     add(v[2], self.geo.qdd(j))]
            self._VP[j] = self.geo.name3("VP", j, v)
        return self._VP[j]

    def link_wrench(self, j: int) -> tuple[list[Poly], list[Poly]]:
        """(F_j, No_j): the force and the moment about O_j that link j's motion needs."""
        p = self.frame_params(j)
        XX, XY, XZ, YY, YZ, ZZ = (p[k] for k in ("XX", "XY", "XZ", "YY", "YZ", "ZZ"))
        MS = [p["MX"], p["MY"], p["MZ"]]
        if not any(p.values()):
            return [ZERO] * 3, [ZERO] * 3
        vp = self.vp(j)
        F = [ZERO] * 3
        if any(MS) or p["M"]:
            U = self.u(j)
            F = [add(mul(p["M"], vp[r]), dot(U[r], MS)) for r in range(3)]
        No = cross(MS, vp)
        if any((XX, XY, XZ, YY, YZ, ZZ)):
            # Khalil's form: JW = J W named once, then J WP + W x JW
            wp, w = self.wp(j), self.w(j)
            rows = ([XX, XY, XZ], [XY, YY, YZ], [XZ, YZ, ZZ])
            jw = self.geo.name3("JW", j, [dot(r, w) for r in rows])
            wjw = cross(w, jw)
            No = [add(No[r], dot(rows[r], wp), wjw[r]) for r in range(3)]
        return self.geo.name3("F", j, F), self.geo.name3("No", j, No)

    # ----- external wrenches -----------------------------------------------------------------
    def site_wrench(self, s: int) -> tuple[list[Poly], list[Poly]]:
        """(force, moment about O_k) of site s in frame k, as polys of the wrench inputs."""
        site = self.sites[s]
        k = site.link
        tag = self.site_tag(s)
        comps = ("FX", "FY", "FZ", "CX", "CY", "CZ")
        vals = [self.prog.input(f"{c}{tag}", ("wrench", (s, i))) for i, c in enumerate(comps)]
        F, M = vals[:3], vals[3:]
        e = k if site.frame is None else site.frame
        if e != k:
            Rk, Re = self.geo.abs_rot(k), self.geo.abs_rot(e)
            kRe = [[add(*(mul(Rk[m][r], Re[m][c]) for m in range(3))) for c in range(3)] for r in range(3)]
            kRe = [[self.prog.define(f"RE{r + 1}{c + 1}{tag}", kRe[r][c]) for c in range(3)] for r in range(3)]
            F = self.geo.name3("FE", 0, [dot(kRe[r], F) for r in range(3)], tag)
            M = self.geo.name3("CE", 0, [dot(kRe[r], M) for r in range(3)], tag)
        p = [const(v) for v in site.point]
        if any(p):
            M = self.geo.name3("CO", 0, [add(M[r], x) for r, x in enumerate(cross(p, F))], tag)
        return F, M

    def site_tag(self, s: int) -> str:
        k = self.sites[s].link
        before = sum(1 for t in self.sites[:s] if t.link == k)
        return f"{k}" if before == 0 else f"{k}_{before + 1}"

    # ----- joint terms ------------------------------------------------------------------------
    def joint_column(self, term: str, j: int) -> Poly:
        g = self.geo
        match term:
            case "IA":
                return g.qdd(j)
            case "FV":
                return g.qd(j)
            case "FS":
                shape, vs = self.tree.friction_law(j)
                if shape == "sign":
                    return self.prog.function(f"SGN{j}", "sign", g.qd(j))
                # tanh(qd / w), w = vs (tanh) or 2 vs (sigmoid): the numeric engines' form
                return self.prog.function(f"TNH{j}", "tanh", scale(g.qd(j), 1.0 / (vs if shape == "tanh" else 2 * vs)))
            case "OFF":
                return ONE
            case "K":
                return g.q(j)
            case "KQ":
                return mul(g.q(j), g.q(j))
            case "FVPL" | "FVPH" | "FVNL" | "FVNH":
                return self.curve_column(term, j)
        raise SymbolicError(f"unknown joint term {term!r}")

    def curve_column(self, term: str, j: int) -> Poly:
        """A viscous curve slope's column (model.tree) from hinges max(x, 0) = (x + x sign(x)) / 2 and
        min(x, 0) = (x - x sign(x)) / 2: clip(qd, 0, v+) = max(qd, 0) - max(qd - v+, 0), and its mirror."""
        lo, hi = self.tree.knee(j)
        qd = self.geo.qd(j)
        positive = term.startswith("FVP")
        knee = hi if positive else lo
        side = 1.0 if positive else -1.0

        def hinge(x: Poly, tag: str) -> Poly:  # max(x, 0) (positive side) or min(x, 0)
            s = self.prog.function(f"SGN{tag}{j}", "sign", x)
            return self.prog.define(f"HNG{tag}{j}", scale(add(x, scale(mul(x, s), side)), 0.5))

        beyond = hinge(self.prog.define(f"QDK{'P' if positive else 'N'}{j}", sub(qd, const(knee))),
                       "KP" if positive else "KN") if math.isfinite(knee) else ZERO
        if term in ("FVPH", "FVNH"):
            return beyond
        return sub(hinge(qd, "P" if positive else "N"), beyond)

    def coupling_value(self, ci: int) -> Poly:
        """f_kind of coupling ci: sum c_i q_i (K), qdd (IA), qd (FV), sign(sum c_i qd_i) (FS)."""
        c = self.tree.couplings[ci]
        src = {"K": self.geo.q, "IA": self.geo.qdd, "FV": self.geo.qd, "FS": self.geo.qd}[c.kind]
        s = add(*(scale(src(j), float(v)) for j, v in c.coeffs.items()))
        if c.kind == "FS":
            return self.prog.function(f"SGNC{ci + 1}", "sign", self.prog.define(f"QPC{ci + 1}", s))
        return self.prog.define(f"{c.kind}C{ci + 1}", s)

    # ----- unit twists of the joints, moved to a descendant frame ------------------------------
    def jac(self, j: int, k: int) -> tuple[list[Poly], list[Poly]]:
        """Unit twist of joint j in frame k at O_k (k a descendant of j): JW (angular), JV (linear)."""
        key = (j, k)
        if key not in self._jac:
            if k == j:
                self._jac[key] = axis_sym(self.sigma(j))
            else:
                i = self.ant(k)
                a, b = self.jac(j, i)
                P = self.geo.pos(k)
                a2 = self.geo.down(k, a)
                b2 = self.geo.down(k, add3(b, cross(a, P)))
                sfx = f"_{j}_{k}"
                self._jac[key] = (
                    [self.prog.define(f"JW{c + 1}{sfx}", a2[c]) for c in range(3)],
                    [self.prog.define(f"JV{c + 1}{sfx}", b2[c]) for c in range(3)],
                )
        return self._jac[key]

    def param_blocks(self, k: int) -> dict[str, tuple[list[Poly], list[Poly]]]:
        """Moment about O_k and force of link k per unit inertial parameter: name -> (No, F)."""
        wp, d, vp = self.wp(k), self.dv(k), self.vp(k)
        U = self.u(k)
        z3 = [ZERO] * 3
        pre = self.prog.define
        d11m22 = pre(f"DD12{k}", sub(d[0, 0], d[1, 1]))
        d22m33 = pre(f"DD23{k}", sub(d[1, 1], d[2, 2]))
        d33m11 = pre(f"DD31{k}", sub(d[2, 2], d[0, 0]))
        return {
            "XX": ([wp[0], d[0, 2], neg(d[0, 1])], z3),
            "XY": ([sub(wp[1], d[0, 2]), add(wp[0], d[1, 2]), d11m22], z3),
            "XZ": ([add(wp[2], d[0, 1]), d33m11, sub(wp[0], d[1, 2])], z3),
            "YY": ([neg(d[1, 2]), wp[1], d[0, 1]], z3),
            "YZ": ([d22m33, sub(wp[2], d[0, 1]), add(wp[1], d[0, 2])], z3),
            "ZZ": ([d[1, 2], neg(d[0, 2]), wp[2]], z3),
            "MX": ([ZERO, neg(vp[2]), vp[1]], [U[0][0], U[1][0], U[2][0]]),
            "MY": ([vp[2], ZERO, neg(vp[0])], [U[0][1], U[1][1], U[2][1]]),
            "MZ": ([neg(vp[1]), vp[0], ZERO], [U[0][2], U[1][2], U[2][2]]),
            "M": (z3, vp),
        }

    # ----- wrenches per unit parameter on the joints above ------------------------------------
    def projected(
        self, k: int, wrenches: dict[str, tuple[list[Poly], list[Poly]]], stop: int, row_of: dict[int, int]
    ) -> dict[tuple[int, str], Poly]:
        """(joint j, key) -> generalized force on the row joints j above k of each wrench (moment
        about O_k, force) given in frame k: moved back frame by frame to `stop` (an ancestor of k,
        or k) and read on each joint passed, then projected on the joints above `stop` through
        their unit twists moved to `stop`."""
        out: dict[tuple[int, str], Poly] = {}
        i = k
        while True:
            if i in row_of and self.sigma(i) != FIXED:
                for key, (No, F) in wrenches.items():
                    out[i, key] = No[2] if self.sigma(i) == REVOLUTE else F[2]
            if i == stop:
                break
            wrenches = {key: self.moved_up(i, No, F, key) for key, (No, F) in wrenches.items()}
            i = self.ant(i)
        for j in self.tree.ancestors[stop]:
            if j != stop and j in row_of and self.sigma(j) != FIXED:
                a, v = self.jac(j, stop)
                for key, (No, F) in wrenches.items():
                    out[j, key] = add(dot(a, No), dot(v, F))
        return out

    def moved_up(self, k: int, No: list[Poly], F: list[Poly], tag: str) -> tuple[list[Poly], list[Poly]]:
        """(moment about O_i, force) in frame i = a(k) of a wrench given about O_k in frame k."""
        g = self.geo
        f = g.name3("FB", k, g.up(k, F), f"_{tag}")
        return g.name3("NB", k, add3(g.up(k, No), cross(g.pos(k), f)), f"_{tag}"), f


def add3(a: list[Poly], b: list[Poly]) -> list[Poly]:
    return [add(x, y) for x, y in zip(a, b, strict=True)]


def check_tree(tree: Tree) -> None:
    if not isinstance(tree, Tree):
        raise SymbolicError(f"expected a dynid.model.Tree, got {type(tree).__name__}")
    if tree.n == 0:
        raise SymbolicError(f"model {tree.name!r} has no frames: nothing to generate")
    for f in tree.frames:
        for col in ("gamma", "b", "alpha", "d", "theta", "r"):
            v = getattr(f, col)
            if not np.isfinite(v):
                raise SymbolicError(f"model {tree.name!r}, frame {f.j}: {col} = {v} is not finite")
    for c in tree.couplings:
        if not c.coeffs:
            raise SymbolicError(f"model {tree.name!r}, coupling {c.name!r} acts on no joint")


def check_sites(tree: Tree, sites: Sequence[WrenchSite]) -> list[WrenchSite]:
    out = []
    for i, s in enumerate(sites):
        if not isinstance(s, WrenchSite):
            raise SymbolicError(
                f"wrenches[{i}] is a {type(s).__name__}; pass dynid.symbolic.WrenchSite(link, point, frame)"
            )
        if not 1 <= s.link <= tree.n:
            raise SymbolicError(f"wrench site {i}: link {s.link} does not exist (1..{tree.n})")
        if s.frame is not None and not 0 <= s.frame <= tree.n:
            raise SymbolicError(f"wrench site {i}: frame {s.frame} does not exist (0..{tree.n})")
        if len(s.point) != 3 or not np.isfinite(np.asarray(s.point, dtype=float)).all():
            raise SymbolicError(f"wrench site {i}: point must be 3 finite numbers, got {s.point!r}")
        out.append(WrenchSite(s.link, tuple(float(v) for v in s.point), s.frame))
    return out


def resolve_rows(tree: Tree, rows: Sequence[int] | None) -> list[int]:
    """The engine's rows, with its error as a SymbolicError."""
    try:
        return _engine_rows(tree, rows)
    except ModelError as exc:
        raise SymbolicError(str(exc)) from None


def resolve_cols(tree: Tree, cols: Sequence[str | int] | None) -> list[int]:
    """The engine's columns, with its error as a SymbolicError."""
    try:
        return _engine_cols(tree, cols)
    except ModelError as exc:
        raise SymbolicError(str(exc)) from None


# ----- the models -------------------------------------------------------------------------------
def dgm(tree: Tree, geometry: str = "numeric") -> Program:
    """0T_j of every frame, output (n+1, 4, 4) per sample (row 0 is the identity)."""
    check_tree(tree)
    b = Builder(tree, "dgm", (tree.n + 1, 4, 4), geometry)
    out = b.prog.outputs
    for j in range(tree.n + 1):
        R, P = b.geo.abs_rot(j), b.geo.abs_pos(j)
        for r in range(3):
            for c in range(3):
                out.append(((j, r, c), R[r][c]))
            out.append(((j, r, 3), P[r]))
        out.append(((j, 3, 3), ONE))
    return finish(b)


def idm(
    tree: Tree, geometry: str = "numeric", parameters: str = "symbolic", wrenches: Sequence[WrenchSite] = ()
) -> Program:
    """Inverse dynamic model: GAM_j, output (n,) per sample (fixed frames give 0)."""
    check_tree(tree)
    b = Builder(tree, "idm", (tree.n,), geometry, parameters, wrenches)
    g, prog = b.geo, b.prog
    n = tree.n
    E: list[list[Poly]] = [[ZERO] * 3 for _ in range(n + 1)]
    N: list[list[Poly]] = [[ZERO] * 3 for _ in range(n + 1)]
    ext: dict[int, tuple[list[Poly], list[Poly]]] = {}
    for s in range(len(b.sites)):
        k = b.sites[s].link
        F, M = b.site_wrench(s)
        if k in ext:
            F, M = add3(ext[k][0], F), add3(ext[k][1], M)
        ext[k] = (F, M)
    for j in range(n, 0, -1):
        F, No = b.link_wrench(j)
        e, m = add3(F, E[j]), add3(No, N[j])
        if j in ext:
            e = [sub(x, y) for x, y in zip(e, ext[j][0], strict=True)]
            m = [sub(x, y) for x, y in zip(m, ext[j][1], strict=True)]
        e, m = g.name3("E", j, e), g.name3("N", j, m)
        i = b.ant(j)
        if i > 0 and (any(e) or any(m)):
            fdi = g.name3("FDI", j, g.up(j, e))
            ndi = g.name3("NDI", j, add3(g.up(j, m), cross(g.pos(j), fdi)))
            E[i], N[i] = add3(E[i], fdi), add3(N[i], ndi)
        sig = b.sigma(j)
        if sig == FIXED:
            continue
        tau = m[2] if sig == REVOLUTE else e[2]
        for t in tree.joint_terms.get(j, ()):
            tau = add(tau, mul(b.param(f"{t}{j}"), b.joint_column(t, j)))
        for ci, c in enumerate(tree.couplings):
            if j in c.coeffs:
                x = b.param(c.name)
                if x:
                    tau = add(tau, scale(mul(x, b.coupling_value(ci)), float(c.coeffs[j])))
        prog.outputs.append(((j - 1,), prog.define(f"GAM{j}", tau)))
    return finish(b)


def regressor(
    tree: Tree,
    rows: Sequence[int] | None = None,
    cols: Sequence[str | int] | None = None,
    geometry: str = "numeric",
    wrenches: Sequence[WrenchSite] = (),
) -> Program:
    """Identification model W, output (len(rows), len(cols)) per sample, W X = tau (+ Q).

    With wrench sites, a second output Q (len(rows),) holds the wrenches' generalized
    forces J^T w, so that W X = tau + Q (the engine's convention).

    A link's wrench per unit parameter is projected on its ancestors' joints either through
    the joints' unit twists moved forward to the link (shared by every link below them: right
    for an arm), or moved back to the nearest frame shared with another link and projected
    there (right for long branches with few parameters, like a car's corners); both are
    built, for W and for Q, and the one with fewer operations is kept.
    """
    best = _regressor(tree, rows, cols, geometry, wrenches, False, False)
    for back_w, back_q in ((True, False), (False, True), (True, True)) if wrenches else ((True, False),):
        prog = _regressor(tree, rows, cols, geometry, wrenches, back_w, back_q)
        if _better(prog.ops(), best.ops()):
            best = prog
    return best


def _better(a: OpCount, b: OpCount) -> bool:
    """Fewer multiplications and additions, none more of either."""
    return a.mult <= b.mult and a.add <= b.add and (a.mult, a.add) != (b.mult, b.add)


def _regressor(tree: Tree, rows, cols, geometry: str, wrenches, back_w: bool, back_q: bool) -> Program:
    check_tree(tree)
    R, C = resolve_rows(tree, rows), resolve_cols(tree, cols)
    b = Builder(tree, "regressor", (len(R), len(C)), geometry, "numeric", wrenches)
    names = tree.parameter_names
    b.prog.meta.update(rows=R, cols=[names[c] for c in C])
    row_of = {j: r for r, j in enumerate(R)}
    anc = tree.ancestors
    split = {ci: _split(tree, names[col]) for ci, col in enumerate(C)}
    inertial = {frame for frame, kind in split.values() if kind in INERTIAL}
    meet = _meeting_frames(tree, inertial) if back_w else {k: k for k in inertial}
    entries: dict[int, dict[tuple[int, str], Poly]] = {}
    for ci, col in enumerate(C):
        name = names[col]
        frame, kind = split[ci]
        if kind is None:  # coupling
            c = tree.couplings[[cp.name for cp in tree.couplings].index(name)]
            f = b.coupling_value([cp.name for cp in tree.couplings].index(name))
            for j, v in c.coeffs.items():
                if j in row_of:
                    b.prog.outputs.append(((row_of[j], ci), scale(f, float(v))))
            continue
        if kind in LOAD_TERMS:  # a load term's column is the measured wrench's: 0 here (model.tree)
            continue
        if kind not in INERTIAL:
            if frame in row_of:
                b.prog.outputs.append(((row_of[frame], ci), b.joint_column(kind, frame)))
            continue
        if frame not in entries:
            kinds = {k for fr, k in split.values() if fr == frame and k in INERTIAL}
            blocks = b.param_blocks(frame)
            entries[frame] = b.projected(frame, {k: blocks[k] for k in sorted(kinds)}, meet[frame], row_of)
        for j in anc[frame]:
            entry = entries[frame].get((j, kind))
            if entry:
                b.prog.outputs.append(((row_of[j], ci), entry))
    if b.sites:
        acc = _site_generalized_forces(b, row_of, back_q)
        b.prog.extra_outputs["Q"] = ((len(R),), [((row_of[j],), p) for j, p in acc.items() if p])
    return finish(b)


def _meeting_frames(tree: Tree, frames: set[int]) -> dict[int, int]:
    """For each frame k of the set: the nearest frame at or above k that is an ancestor of
    another frame of the set (k itself if it is one), else the root-most frame above k."""
    anc = tree.ancestors
    count: dict[int, int] = {}
    for k in frames:
        for a in anc[k]:
            count[a] = count.get(a, 0) + 1
    return {k: next((a for a in reversed(anc[k]) if count[a] >= 2), anc[k][0]) for k in frames}


def _site_generalized_forces(b: Builder, row_of: dict[int, int], back: bool) -> dict[int, Poly]:
    """Q_j = J_j^T w summed over the wrench sites, per row joint j: through the joints' unit
    twists at each site, or (back) the sites' wrenches summed while moved back to the root."""
    anc = b.tree.ancestors
    acc: dict[int, Poly] = {}
    if not back:
        for s, site in enumerate(b.sites):
            F, M = b.site_wrench(s)
            for j in anc[site.link]:
                if j in row_of and b.sigma(j) != FIXED:
                    a, v = b.jac(j, site.link)
                    acc[j] = add(acc.get(j, ZERO), dot(a, M), dot(v, F))
        return acc
    at: dict[int, tuple[list[Poly], list[Poly]]] = {}
    for s, site in enumerate(b.sites):
        F, M = b.site_wrench(s)
        old = at.get(site.link)
        at[site.link] = (add3(old[0], M), add3(old[1], F)) if old else (M, F)
    rows = {j for j in row_of if b.sigma(j) != FIXED}
    for i in range(b.n, 0, -1):  # an antecedent has a smaller number than its children
        if i not in at:
            continue
        M, F = at.pop(i)
        if i in rows:
            acc[i] = add(acc.get(i, ZERO), M[2] if b.sigma(i) == REVOLUTE else F[2])
        a = b.ant(i)
        if a > 0 and rows & set(anc[a]):
            M, F = b.moved_up(i, M, F, "Q")
            old = at.get(a)
            at[a] = (add3(old[0], M), add3(old[1], F)) if old else (M, F)
    return {j: acc[j] for j in sorted(acc)}


def inertia(tree: Tree, geometry: str = "numeric", parameters: str = "symbolic") -> Program:
    """Inertia matrix A(q) by composite links, output (n, n) per sample (fixed frames: 0)."""
    check_tree(tree)
    b = Builder(tree, "inertia", (tree.n, tree.n), geometry, parameters)
    g, prog = b.geo, b.prog
    n = tree.n
    comp: dict[int, dict[str, Poly]] = {}
    for j in range(n, 0, -1):
        p = dict(b.frame_params(j))
        for k in tree.children[j]:
            p = {key: add(p[key], v) for key, v in _transfer(b, k, comp[k]).items()}
        comp[j] = {key: prog.define(f"{key}c{j}", v) for key, v in p.items()}
    A: dict[tuple[int, int], Poly] = {}
    for j in range(1, n + 1):
        sig = b.sigma(j)
        if sig == FIXED:
            continue
        c = comp[j]
        if sig == REVOLUTE:
            f, m = [neg(c["MY"]), c["MX"], ZERO], [c["XZ"], c["YZ"], c["ZZ"]]
        else:
            f, m = [ZERO, ZERO, c["M"]], [c["MY"], neg(c["MX"]), ZERO]
        A[j, j] = m[2] if sig == REVOLUTE else f[2]
        l = j
        while b.ant(l) > 0:
            i = b.ant(l)
            f2 = g.up(l, f)
            f = [prog.define(f"AF{r + 1}_{j}_{i}", f2[r]) for r in range(3)]
            m2 = add3(g.up(l, m), cross(g.pos(l), f))
            m = [prog.define(f"AN{r + 1}_{j}_{i}", m2[r]) for r in range(3)]
            if b.sigma(i) != FIXED:
                A[i, j] = m[2] if b.sigma(i) == REVOLUTE else f[2]
            l = i
    for j, terms in tree.joint_terms.items():
        if "IA" in terms:
            A[j, j] = add(A.get((j, j), ZERO), b.param(f"IA{j}"))
    for c in tree.couplings:
        if c.kind != "IA":
            continue
        x = b.param(c.name)
        for i, ci in c.coeffs.items():
            for j, cj in c.coeffs.items():
                if i <= j:
                    A[i, j] = add(A.get((i, j), ZERO), scale(x, float(ci) * float(cj)))
    for (i, j), v in sorted(A.items()):
        if not v:
            continue
        v = prog.define(f"A{i}_{j}", v)
        prog.outputs.append(((i - 1, j - 1), v))
        if i != j:
            prog.outputs.append(((j - 1, i - 1), v))
    return finish(b)


def _transfer(b: Builder, k: int, p: dict[str, Poly]) -> dict[str, Poly]:
    """Inertial parameters of a body given in frame k, expressed about O_i in frame i = a(k)."""
    g, prog = b.geo, b.prog
    R, P = g.rot(k), g.pos(k)
    M = p["M"]
    J = [[p["XX"], p["XY"], p["XZ"]], [p["XY"], p["YY"], p["YZ"]], [p["XZ"], p["YZ"], p["ZZ"]]]
    bv = [prog.define(f"MSR{r + 1}{k}", dot(R[r], [p["MX"], p["MY"], p["MZ"]])) for r in range(3)]
    RJ = [
        [prog.define(f"RJ{r + 1}{c + 1}{k}", dot(R[r], [J[0][c], J[1][c], J[2][c]])) for c in range(3)]
        for r in range(3)
    ]
    pp = dot(P, P)
    pb = dot(P, bv)
    out = {"M": M}
    for r, name in enumerate(("MX", "MY", "MZ")):
        out[name] = add(bv[r], mul(M, P[r]))
    idx = {"XX": (0, 0), "XY": (0, 1), "XZ": (0, 2), "YY": (1, 1), "YZ": (1, 2), "ZZ": (2, 2)}
    for name, (r, c) in idx.items():
        rjr = dot(RJ[r], R[c])
        par = neg(mul(P[r], P[c])) if r != c else sub(pp, mul(P[r], P[r]))
        ms = neg(add(mul(bv[r], P[c]), mul(P[r], bv[c])))
        if r == c:
            ms = add(ms, scale(pb, 2.0))
        out[name] = add(rjr, mul(M, par), ms)
    return out


def _split(tree: Tree, name: str) -> tuple[int, str | None]:
    """(frame, kind) of a standard parameter name, (0, None) for a coupling."""
    coupling_names = {c.name for c in tree.couplings}
    if name in coupling_names:
        return 0, None
    i = len(name)
    while i > 0 and name[i - 1].isdigit():
        i -= 1
    return int(name[i:]), name[:i]


def finish(b: Builder) -> Program:
    prog = b.prog.prune()
    prog.meta["tree"] = b.tree.name
    prog.meta["n"] = b.tree.n
    prog.meta["geometry"] = b.geo.mode
    prog.meta["parameters"] = b.param_mode
    prog.meta["sites"] = list(b.sites)
    return prog


def build(tree: Tree, model: str, **options) -> Program:
    """One of the models by name: dgm, idm, regressor, inertia."""
    fn = {"dgm": dgm, "idm": idm, "regressor": regressor, "inertia": inertia}.get(model)
    if fn is None:
        raise SymbolicError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    if tree.mimic:
        j = min(tree.mimic)
        raise SymbolicError(f"model {tree.name!r} has mimic joints (frame {j} follows frame {tree.mimic[j].master}), "
                            "which the symbolic models do not project; use the numeric engine, or freeze them "
                            "(dynid model import --freeze)")

    allowed = set(inspect.signature(fn).parameters) - {"tree"}
    bad = sorted(set(options) - allowed)
    if bad:
        raise SymbolicError(f"model {model!r} takes no option {', '.join(bad)}; options: {', '.join(sorted(allowed))}")
    return fn(tree, **options)


__all__ = ["MODELS", "PARAMETER_MODES", "Builder", "WrenchSite", "build", "dgm", "idm", "inertia", "regressor",
           "sym"]
