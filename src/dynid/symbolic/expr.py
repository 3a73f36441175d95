"""A small polynomial expression layer and the symbol manager of a generated model.

Why not sympy objects all the way: a Newton-Euler model is thousands of tiny
expressions (two or three products of symbols), and sympy's automatic evaluation costs
tens of microseconds per node and hides which terms are exact zeros and ones. Here an
expression is a polynomial in named symbols with float coefficients,

    {monomial: coefficient},  monomial = sorted tuple of symbol names (repeats = powers)

so that a zero is an empty dict, a unit coefficient is exactly 1.0, and no zero term is
ever created. The `Program` names an intermediate variable only for a non-trivial
expression (more than one term, or one term that is not +-symbol), reuses a name when
the same expression (or its negative) comes again, and keeps the equations in the order
they must be evaluated. `to_sympy` converts for users who want sympy objects.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

Poly = dict[tuple[str, ...], float]

ZERO: Poly = {}
ONE: Poly = {(): 1.0}
FUNCTIONS = ("sin", "cos", "sign", "tanh")  # tanh: smooth Coulomb friction (Tree.friction_shape)


class SymbolicError(ValueError):
    """A model the symbolic generator cannot handle, with what and why."""


# ----- polynomial arithmetic -----------------------------------------------------------
def const(c: float) -> Poly:
    return {(): float(c)} if c != 0.0 else {}


def sym(name: str) -> Poly:
    return {(name,): 1.0}


def add(*ps: Poly) -> Poly:
    out: Poly = {}
    for p in ps:
        for m, c in p.items():
            v = out.get(m, 0.0) + c
            if v == 0.0:
                out.pop(m, None)
            else:
                out[m] = v
    return out


def sub(a: Poly, b: Poly) -> Poly:
    return add(a, scale(b, -1.0))


def scale(p: Poly, c: float) -> Poly:
    if c == 0.0:
        return {}
    if c == 1.0:
        return p
    return {m: v * c for m, v in p.items()}


def neg(p: Poly) -> Poly:
    return {m: -v for m, v in p.items()}


def mul(a: Poly, b: Poly) -> Poly:
    if not a or not b:
        return {}
    if len(b) == 1 and () in b:
        return scale(a, b[()])
    if len(a) == 1 and () in a:
        return scale(b, a[()])
    out: Poly = {}
    for ma, ca in a.items():
        for mb, cb in b.items():
            m = tuple(sorted(ma + mb)) if ma and mb else (ma or mb)
            v = out.get(m, 0.0) + ca * cb
            if v == 0.0:
                out.pop(m, None)
            else:
                out[m] = v
    return out


def dot(a: Iterable[Poly], b: Iterable[Poly]) -> Poly:
    return add(*(mul(x, y) for x, y in zip(a, b, strict=True)))


def cross(a: list[Poly], b: list[Poly]) -> list[Poly]:
    return [
        sub(mul(a[1], b[2]), mul(a[2], b[1])),
        sub(mul(a[2], b[0]), mul(a[0], b[2])),
        sub(mul(a[0], b[1]), mul(a[1], b[0])),
    ]


def is_const(p: Poly) -> bool:
    return not p or (len(p) == 1 and () in p)


def const_value(p: Poly) -> float:
    return p.get((), 0.0) if is_const(p) else float("nan")


def trivial(p: Poly) -> bool:
    """Zero, a constant, or +-one symbol: never worth a name."""
    if len(p) > 1:
        return False
    if not p:
        return True
    (m, c), = p.items()
    return len(m) == 0 or (len(m) == 1 and c in (1.0, -1.0))


def symbols_of(p: Poly) -> set[str]:
    return {s for m in p for s in m}


def substitute(p: Poly, values: Mapping[str, Poly]) -> Poly:
    """Replace symbols by polynomials (used by the regrouping, on small expressions)."""
    out: Poly = {}
    for m, c in p.items():
        term: Poly = {(): c}
        for s in m:
            term = mul(term, values.get(s, {(s,): 1.0}))
        out = add(out, term)
    return out


def _key(p: Poly) -> tuple:
    return tuple(sorted(p.items()))


# ----- operation counts --------------------------------------------------------------------
@dataclass
class OpCount:
    """Multiplications (a division counts as one), additions (subtractions too), functions."""

    mult: int = 0
    add: int = 0
    func: int = 0

    def __add__(self, other: OpCount) -> OpCount:
        return OpCount(self.mult + other.mult, self.add + other.add, self.func + other.func)

    def __str__(self) -> str:
        return f"{self.mult} mult, {self.add} add, {self.func} functions"


def poly_ops(p: Poly) -> OpCount:
    """Operations of p as printed (factored, see `factored`)."""
    _, mults, adds = factored(p)
    return OpCount(mults, adds, 0)


_FACTOR_CACHE: dict[tuple, tuple[str, int, int]] = {}


def factored(p: Poly) -> tuple[str, int, int]:
    """(text, multiplications, additions) of p with common factors taken out greedily,
    e.g. S2*WP22 - S2*DV132 + C2*WP12 -> S2*(WP22 - DV132) + C2*WP12. Signs are free."""
    if not p:
        return "0.0", 0, 0
    key = tuple(p.items())
    hit = _FACTOR_CACHE.get(key)
    if hit is None:
        pieces = _pieces(list(p.items()))
        hit = _join(pieces)
        if len(_FACTOR_CACHE) > 200_000:
            _FACTOR_CACHE.clear()
        _FACTOR_CACHE[key] = hit
    return hit


def _num(c: float) -> str:
    return repr(float(c))


def _pieces(terms: list[tuple[tuple[str, ...], float]]) -> list[tuple[bool, str, int, int, bool]]:
    """Signed pieces (negative, text, mults, adds, is_sum) whose sum is the terms."""
    if len(terms) == 1:
        m, c = terms[0]
        factors = list(m)
        if not factors:
            return [(c < 0, _num(abs(c)), 0, 0, False)]
        if abs(c) != 1.0:
            factors.insert(0, _num(abs(c)))
        return [(c < 0, "*".join(factors), len(factors) - 1, 0, False)]
    counts: dict[object, int] = {}
    for m, c in terms:
        for s in dict.fromkeys(m):  # not set(m): its order, hence the tie-breaks, would follow PYTHONHASHSEED
            counts[s] = counts.get(s, 0) + 1
        if abs(c) != 1.0 and m:
            counts[abs(c)] = counts.get(abs(c), 0) + 1
    best, n = None, 1
    for s, k in counts.items():
        if k > n:
            best, n = s, k
    if best is None:
        out = []
        for t in terms:
            out += _pieces([t])
        return out
    inner, rest = [], []
    for m, c in terms:
        if isinstance(best, float):
            if abs(c) == best and m:
                inner.append((m, c / best))
            else:
                rest.append((m, c))
        elif best in m:
            lst = list(m)
            lst.remove(best)
            inner.append((tuple(lst), c))
        else:
            rest.append((m, c))
    q = _pieces(inner)
    fac = _num(best) if isinstance(best, float) else best
    if len(q) == 1:
        neg_, text, mu, ad, is_sum = q[0]
        if text == "1.0":
            piece = (neg_, fac, 0, 0, False)
        else:
            piece = (neg_, f"{fac}*({text})" if is_sum else f"{fac}*{text}", mu + 1, ad, False)
    else:
        negs = sum(1 for x in q if x[0])
        flip = negs * 2 > len(q)
        if flip:
            q = [(not x[0], *x[1:]) for x in q]
        text, mu, ad = _join(q)
        piece = (flip, f"{fac}*({text})", mu + 1, ad, False)
    return [piece] + (_pieces(rest) if rest else [])


def _join(pieces: list[tuple[bool, str, int, int, bool]]) -> tuple[str, int, int]:
    """Sum of signed pieces, a positive one first when there is one."""
    pieces = sorted(pieces, key=lambda x: x[0])  # stable: positives first
    neg0, text0, mults, adds = pieces[0][0], pieces[0][1], pieces[0][2], pieces[0][3]
    out = ("-" if neg0 else "") + text0
    for negative, text, mu, ad, _ in pieces[1:]:
        out += (" - " if negative else " + ") + text
        mults += mu
        adds += ad + 1
    return out, mults, adds


# ----- the symbol manager ------------------------------------------------------------------
@dataclass
class Equation:
    """name = rhs (kind 'poly') or name = kind(rhs) for kind in sin, cos, sign, tanh."""

    name: str
    rhs: Poly
    kind: str = "poly"

    def ops(self) -> OpCount:
        c = poly_ops(self.rhs)
        if self.kind != "poly":
            c.func += 1
        return c


@dataclass
class Program:
    """A straight-line symbolic model: inputs, constants, equations, outputs.

    inputs: symbol name -> (array, index) telling where the generated code reads it,
    e.g. ('q', 2) for q3, ('X', 17) for a parameter, ('wrench', (site, component)).
    constants: symbolic geometric constants -> numeric value (defined once in code).
    outputs: list of (index tuple, Poly) in the output array of shape `shape`.
    """

    model: str
    shape: tuple[int, ...]
    inputs: dict[str, tuple[str, object]] = field(default_factory=dict)
    constants: dict[str, float] = field(default_factory=dict)
    equations: list[Equation] = field(default_factory=list)
    outputs: list[tuple[tuple[int, ...], Poly]] = field(default_factory=list)
    extra_outputs: dict[str, tuple[tuple[int, ...], list[tuple[tuple[int, ...], Poly]]]] = field(default_factory=dict)
    meta: dict[str, object] = field(default_factory=dict)
    _by_value: dict[tuple, str] = field(default_factory=dict, repr=False)
    _names: set[str] = field(default_factory=set, repr=False)

    # -- building
    def input(self, name: str, source: tuple[str, object]) -> Poly:
        if name not in self.inputs:
            self._claim(name)
            self.inputs[name] = source
        return sym(name)

    def constant(self, name: str, value: float) -> Poly:
        if name not in self.constants:
            self._claim(name)
            self.constants[name] = float(value)
        return sym(name)

    def define(self, name: str, p: Poly) -> Poly:
        """Name p if it is not trivial; the same expression (or its negative) keeps its first name."""
        if trivial(p):
            return p
        key = _key(p)
        found = self._by_value.get(key)
        if found is not None:
            return sym(found)
        found = self._by_value.get(_key(neg(p)))
        if found is not None:
            return {(found,): -1.0}
        self._claim(name)
        self.equations.append(Equation(name, p))
        self._by_value[key] = name
        return sym(name)

    def function(self, name: str, kind: str, arg: Poly) -> Poly:
        """name = kind(arg), introduced once per distinct call."""
        if kind not in FUNCTIONS:
            raise SymbolicError(f"unknown function {kind!r}")
        if is_const(arg):
            x = const_value(arg)
            return const({"sin": math.sin, "cos": math.cos, "sign": lambda v: (v > 0) - (v < 0),
                          "tanh": math.tanh}[kind](x))
        key = (kind, _key(arg))
        found = self._by_value.get(key)
        if found is not None:
            return sym(found)
        self._claim(name)
        self.equations.append(Equation(name, arg, kind))
        self._by_value[key] = name
        return sym(name)

    def _claim(self, name: str) -> None:
        if name in self._names:
            raise SymbolicError(
                f"symbol {name!r} is defined twice in the {self.model} model; a parameter or coupling name "
                "probably clashes with an intermediate variable name (rename it)"
            )
        self._names.add(name)

    # -- finishing
    def all_outputs(self) -> list[Poly]:
        out = [p for _, p in self.outputs]
        for _, entries in self.extra_outputs.values():
            out += [p for _, p in entries]
        return out

    def prune(self) -> Program:
        """Drop the equations no output needs (in place), and unused constants; returns self."""
        need: set[str] = set()
        for p in self.all_outputs():
            need |= symbols_of(p)
        kept = []
        for eq in reversed(self.equations):
            if eq.name in need:
                kept.append(eq)
                need |= symbols_of(eq.rhs)
        kept.reverse()
        self.equations = kept
        self.constants = {k: v for k, v in self.constants.items() if k in need}
        self.meta["used_inputs"] = sorted(k for k in self.inputs if k in need)
        return self

    def ops(self) -> OpCount:
        """Operation count of the equations and outputs (constants and input reads are free)."""
        total = OpCount()
        for eq in self.equations:
            total = total + eq.ops()
        for p in self.all_outputs():
            total = total + poly_ops(p)
        return total

    def to_sympy(self) -> tuple[list, list]:
        """([(Symbol, expr), ...] equations, [(index, expr), ...] outputs) as sympy objects."""
        import sympy  # start-up: sympy 1 s

        cache: dict[str, sympy.Symbol] = {}

        def s(name: str) -> sympy.Symbol:
            if name not in cache:
                cache[name] = sympy.Symbol(name, real=True)
            return cache[name]

        def conv(p: Poly) -> sympy.Expr:
            terms = []
            for m, c in p.items():
                t = sympy.Float(c) if c not in (1.0, -1.0) or not m else sympy.Integer(int(c))
                for name in m:
                    t = t * s(name)
                terms.append(t)
            return sympy.Add(*terms)

        fn = {"sin": sympy.sin, "cos": sympy.cos, "sign": sympy.sign, "tanh": sympy.tanh}
        eqs = [(s(e.name), conv(e.rhs) if e.kind == "poly" else fn[e.kind](conv(e.rhs))) for e in self.equations]
        return eqs, [(idx, conv(p)) for idx, p in self.outputs]
