"""Base parameters by symbolic regrouping (Khalil's rules), completed and checked numerically.

Khalil's general rules, applied from the last frame to the first: a part of link j whose
dynamics does not depend on q_j can be moved to its antecedent a(j):

- revolute j: the body J = diag(YY_j, YY_j, 0), MS = (0, 0, MZ_j), M = M_j, symmetric
  about z_j, moves to a(j); what stays is XXR_j = XX_j - YY_j, XY, XZ, YZ, ZZ, MX, MY;
- prismatic j: the rotational inertia XX_j..ZZ_j (no mass) moves to a(j);
- fixed j: the whole link moves to a(j).

Moving a body (J, MS, M) given about O_j in frame j to frame i uses the parallel-axis
transfer with R = iR_j and P = iP_j at q_j = 0:

    M' = M,  MS' = R MS + M P,
    J' = R J R^T + M (|P|^2 I - P P^T) - (b P^T + P b^T - 2 (P.b) I),   b = R MS.

Geometric constants stay symbolic (D3, RL4, CA5 ...) or numeric as chosen. Moved into
frame 0, a body has no effect. The rules do not cover the special cases near the base
(links whose motion is restricted, rotor inertias equal to a link's ZZ column, ...):
those are found by a numeric QR on the regressor of the remaining parameters, and
their regrouping coefficients are numbers (marked "numeric").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..model.tree import INERTIAL, PRISMATIC, REVOLUTE, Tree
from .cache import numpy_module
from .expr import ONE, ZERO, Poly, Program, SymbolicError, add, const, dot, mul, neg, scale, sub, sym
from .geometry import Geometry


@dataclass(frozen=True)
class SymbolicBaseParameters:
    """The base parameters of a tree, with their regrouping relations.

    names: the base parameters (named after the standard parameter each keeps, in the
    model's order); relations[name]: the base parameter as a linear combination of the
    standard parameters (a Poly whose monomials are one parameter times geometric
    constants); numeric: base parameters whose relation needed the numeric completion;
    eliminated: standard parameters with no effect or regrouped into others.
    """

    tree: Tree
    names: tuple[str, ...]
    relations: dict[str, Poly]
    numeric: tuple[str, ...]
    eliminated: tuple[str, ...]
    constants: dict[str, float]

    @property
    def rank(self) -> int:
        return len(self.names)

    def matrix(self) -> np.ndarray:
        """B (rank, p) with X_B = B X, geometric constants replaced by their values."""
        idx = self.tree.index
        B = np.zeros((self.rank, self.tree.p))
        for r, name in enumerate(self.names):
            for m, c in self.relations[name].items():
                v, col = c, None
                for s in m:
                    if s in idx:
                        col = idx[s]
                    else:
                        v *= self.constants[s]
                if col is None:
                    raise SymbolicError(f"relation of {name} has a term without a parameter: {m}")
                B[r, col] += v
        return B

    def values(self, X: np.ndarray) -> np.ndarray:
        return self.matrix() @ np.asarray(X, dtype=float)

    def expression(self, name: str, digits: int = 6) -> str:
        """A relation as text, grouped by standard parameter: ZZ2 + IA2 + D3**2*M3 ..."""
        by_param: dict[str, list[tuple[tuple[str, ...], float]]] = {}
        idx = self.tree.index
        for m, c in self.relations[name].items():
            par = next(s for s in m if s in idx)
            rest = list(m)
            rest.remove(par)
            by_param.setdefault(par, []).append((tuple(rest), c))
        out = []
        for par in sorted(by_param, key=lambda s: idx[s]):
            terms = by_param[par]
            if len(terms) == 1:
                m, c = terms[0]
                coef = ([] if abs(c) == 1.0 else [f"{abs(c):.{digits}g}"]) + _powers(m)
                out.append(("-" if c < 0 else "+", "*".join([*coef, par])))
                continue
            inner = []
            for m, c in terms:
                f = _powers(m)
                cs = [] if abs(c) == 1.0 and f else [f"{abs(c):.{digits}g}"]
                inner.append(("- " if c < 0 else "+ ") + "*".join(cs + f))
            body = " ".join(inner)
            body = body[2:] if body.startswith("+ ") else "-" + body[2:]
            out.append(("+", f"({body})*{par}"))
        text = " ".join(f"{s} {t}" for s, t in out)
        return text[2:] if text.startswith("+ ") else "-" + text[2:]

    def __str__(self) -> str:
        lines = [f"{self.rank} base parameters of {self.tree.name}"]
        for name in self.names:
            flag = "  (numeric)" if name in self.numeric else ""
            lines.append(f"  {name:>8}R = {self.expression(name)}{flag}")
        if self.eliminated:
            lines.append(f"  regrouped or without effect: {' '.join(self.eliminated)}")
        return "\n".join(lines)


def _powers(m: tuple[str, ...]) -> list[str]:
    out = []
    for s in dict.fromkeys(m):
        k = m.count(s)
        out.append(s if k == 1 else f"{s}**{k}")
    return out


def _transfer(R: list[list[Poly]], P: list[Poly], J: list[list[Poly]], MS: list[Poly], M: Poly) -> dict[str, Poly]:
    """Parameters (J, MS, M) of a body in frame j, moved to frame i (see the module doc)."""
    b = [dot(R[r], MS) for r in range(3)]
    RJ = [[dot(R[r], [J[0][c], J[1][c], J[2][c]]) for c in range(3)] for r in range(3)]
    pp, pb = dot(P, P), dot(P, b)
    out = {"M": M}
    for r, name in enumerate(("MX", "MY", "MZ")):
        out[name] = add(b[r], mul(M, P[r]))
    for name, (r, c) in {"XX": (0, 0), "XY": (0, 1), "XZ": (0, 2), "YY": (1, 1), "YZ": (1, 2), "ZZ": (2, 2)}.items():
        par = neg(mul(P[r], P[c])) if r != c else sub(pp, mul(P[r], P[r]))
        ms = neg(add(mul(b[r], P[c]), mul(P[r], b[c])))
        if r == c:
            ms = add(ms, scale(pb, 2.0))
        out[name] = add(dot(RJ[r], R[c]), mul(M, par), ms)
    return out


def rules(tree: Tree, geometry: str = "numeric") -> tuple[dict[str, Poly], set[str], dict[str, float]]:
    """Apply the general rules; returns (relations, removed parameters, geometric constants)."""
    prog = Program("regrouping", ())
    geo = Geometry(tree, prog, geometry)
    rel: dict[str, Poly] = {name: sym(name) for name in tree.parameter_names}
    removed: set[str] = set()
    for f in reversed(tree.frames):
        j, i = f.j, f.ant
        p = {k: rel[f"{k}{j}"] for k in INERTIAL}
        zero3 = [ZERO, ZERO, ZERO]
        if f.sigma == REVOLUTE:
            J = [[p["YY"], ZERO, ZERO], [ZERO, p["YY"], ZERO], [ZERO, ZERO, ZERO]]
            MS, M = [ZERO, ZERO, p["MZ"]], p["M"]
            rel[f"XX{j}"] = sub(p["XX"], p["YY"])
            gone = ("YY", "MZ", "M")
        elif f.sigma == PRISMATIC:
            J = [[p["XX"], p["XY"], p["XZ"]], [p["XY"], p["YY"], p["YZ"]], [p["XZ"], p["YZ"], p["ZZ"]]]
            MS, M = zero3, ZERO
            gone = ("XX", "XY", "XZ", "YY", "YZ", "ZZ")
        else:
            J = [[p["XX"], p["XY"], p["XZ"]], [p["XY"], p["YY"], p["YZ"]], [p["XZ"], p["YZ"], p["ZZ"]]]
            MS, M = [p["MX"], p["MY"], p["MZ"]], p["M"]
            gone = INERTIAL
        for k in gone:
            removed.add(f"{k}{j}")
        if i == 0:
            continue
        C = geo.const_rot(j)
        # a revolute joint's moved body is symmetric about z_j: its angle does not matter
        ct, st = geo.angle_cs("T", j, f.theta) if f.sigma != REVOLUTE else (ONE, ZERO)
        Rz = [[ct, neg(st), ZERO], [st, ct, ZERO], [ZERO, ZERO, ONE]]
        R = [[add(*(mul(C[r][k], Rz[k][c]) for k in range(3))) for c in range(3)] for r in range(3)]
        cg, sg = geo.angle_cs("G", j, f.gamma)
        ca, sa = geo.angle_cs("A", j, f.alpha)
        d, b, r0 = geo.length("D", j, f.d), geo.length("B", j, f.b), geo.length("RL", j, f.r)
        z = [mul(sg, sa), neg(mul(cg, sa)), ca]
        P = [add(mul(cg, d), mul(r0, z[0])), add(mul(sg, d), mul(r0, z[1])), add(b, mul(r0, z[2]))]
        moved = _transfer(R, P, J, MS, M)
        for k, v in moved.items():
            if v:
                rel[f"{k}{i}"] = add(rel[f"{k}{i}"], v)
    return rel, removed, dict(prog.constants)


def base_parameters(
    tree: Tree, geometry: str = "numeric", samples: int | None = None, seed: int = 0, tol: float = 1e-9
) -> SymbolicBaseParameters:
    """Base parameters of the full identification model (all rows and columns)."""

    rel, removed, constants = rules(tree, geometry)
    names = tree.parameter_names
    cand = [k for k in names if k not in removed]
    if samples is None:
        samples = max(40, 3 * tree.p // max(1, tree.n) + 20)
    q, qd, qdd = random_states(tree, samples, seed)
    # the generated regressor (exact to round-off) gives the numeric completion
    W = numpy_module(tree, "regressor", geometry=geometry).evaluate(q, qd, qdd).reshape(-1, tree.p)
    # the rules must hold exactly: W X = W_cand X_B for any X
    probe = SymbolicBaseParameters(tree, tuple(cand), rel, (), (), constants)
    B = probe.matrix()
    X = np.random.default_rng(seed + 1).normal(size=tree.p)
    lhs, rhs = W @ X, W[:, [tree.index[c] for c in cand]] @ (B @ X)
    if np.abs(lhs - rhs).max() > 1e-8 * max(1.0, np.abs(lhs).max()):
        raise SymbolicError(
            f"model {tree.name!r}: the regrouping rules do not reproduce the regressor (internal error)"
        )
    Wc = W[:, [tree.index[c] for c in cand]]
    norms = np.linalg.norm(Wc, axis=0)
    scale_ = norms.max() if norms.size else 1.0
    live = [k for k in range(len(cand)) if norms[k] > 1e-12 * scale_]
    Ws = Wc[:, live] / norms[live]
    Rm = scipy.linalg.qr(Ws, mode="r")[0]
    diag = np.abs(np.diag(Rm)) if Rm.shape[0] >= Rm.shape[1] else np.zeros(len(live))
    indep = [live[k] for k in range(len(live)) if diag[k] > tol]
    dep = [live[k] for k in range(len(live)) if diag[k] <= tol]
    numeric: set[str] = set()
    if dep:
        beta = np.linalg.lstsq(Wc[:, indep], Wc[:, dep], rcond=None)[0]
        beta = np.round(beta, 10)
        for r, i in enumerate(indep):
            for s, k in enumerate(dep):
                if beta[r, s] != 0.0:
                    rel[cand[i]] = add(rel[cand[i]], scale(rel[cand[k]], float(beta[r, s])))
                    numeric.add(cand[i])
    base = tuple(cand[i] for i in indep)
    eliminated = tuple(k for k in names if k not in base)
    return SymbolicBaseParameters(tree, base, {k: rel[k] for k in base}, tuple(k for k in base if k in numeric),
                                  eliminated, constants)


def random_states(tree: Tree, samples: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random (q, qd, qdd), (samples, n): angles over the full turn, lengths about +-0.5 m."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(samples, tree.n))
    prism = tree.sigma[1:] == PRISMATIC
    q[:, prism] = rng.normal(scale=0.5, size=(samples, int(prism.sum())))
    return q, rng.normal(size=(samples, tree.n)), rng.normal(size=(samples, tree.n))


__all__ = ["SymbolicBaseParameters", "base_parameters", "const", "rules"]
