"""Sine and cosine of one angle together, fdlibm's way: the one definition every target's code comes from.

Why our own: libm's sin and cos are a call each (10 to 15 ns), scalar, and cannot be vectorised across
samples; these steps are about four times faster in the numeric engine and run as vector instructions in
the generated kernels. Every generated target evaluates the same IEEE operations in the same order with no
contraction into FMA (the generated C where its compiler is told so: symbolic.codegen), so they agree to the bit
on any CPU, within an ulp of libm; the engine's, contracted
into FMA like its kernels where the CPU has it, within an ulp of them:

- the Numba engine (dynamics.compiled._sincos) runs `python_function()`, the source `python_source()`;
- the generated NumPy modules run `numpy_source()` (one ufunc per step over a row of samples);
- the generated C's `_block` functions run `c_source()` lane by lane (GCC and clang vectorise it across samples);
  its per-sample functions call libm, which a scalar function runs faster than the steps (symbolic.codegen);
- the LLVM block kernels (symbolic.blocks) emit one vector instruction per step of `STEPS`, and the scalar LLVM
  models (symbolic.llvm_code: the simulator's) one scalar instruction, both through llvm_code.Emitter.sincos;
- the generated per-sample Python (symbolic.numba_backend.HEADER's _sin and _cos) runs `python_source()`.

The steps (three-address, `STEPS`): k = round(x 2/pi) by adding and subtracting 1.5 * 2^52; r = x - k pi/2
with pi/2 in two parts (the first of 33 bits, so that k * PIO2_1 is exact for |k| < 2^20); then fdlibm's
__kernel_sin and __kernel_cos polynomials on |r| <= pi/4 (sn, cs). The quadrant k mod 4 then picks and signs
them (`QUADRANT`), each target in its own idiom (selects, a table, exact small-integer arithmetic): the same
values, a pick and a sign change being exact. An angle of LIMIT or more in magnitude, or NaN, takes libm's
values instead (k * PIO2_1 would no longer be exact).

A change to the steps reaches the generated code at once (the generator's fingerprint hashes this file) and
`python_function`'s own machine code, but not the engine's kernels that inline it, which Numba caches under
dynamics/compiled.py's stamp: change or touch that file too.

Accuracy: 1 ulp of max(|y|, 1/2) against libm (measured over 1e5 angles, tests/dynamics/test_trig.py): absolute
near the zeros of sine and cosine, where the two-part pi/2 (86 bits) leaves an error of |k| 2^-87.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ..pysource import compile_source

# fdlibm's constants (e_rem_pio2.c, k_sin.c, k_cos.c)
INVPIO2 = 6.36619772367581382433e-01  # 2/pi
PIO2_1 = 1.57079632673412561417e+00  # the first 33 bits of pi/2
PIO2_1T = 6.07710050650619224932e-11  # pi/2 - PIO2_1
ROUND = 6755399441055744.0  # 1.5 * 2^52: (t + ROUND) - ROUND is t rounded to an integer (|t| < 2^51)
SIN = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
       2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)  # S1..S6
COS = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
       -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)  # C1..C6
LIMIT = 1.0e5  # |x| from which libm's values are taken

CONSTANTS: dict[str, float] = {"INVPIO2": INVPIO2, "PIO2_1": PIO2_1, "PIO2_1T": PIO2_1T, "ROUND": ROUND,
                               "HALF": 0.5, "ONE": 1.0,
                               **{f"S{i + 1}": a for i, a in enumerate(SIN)},
                               **{f"C{i + 1}": a for i, a in enumerate(COS)}}
OPS = {"add": "+", "sub": "-", "mul": "*"}
# (sin, cos) of x = k pi/2 + r for k mod 4 = 0, 1, 2, 3, as (value, sign): sin r is sn, cos r is cs
QUADRANT = ((("sn", 1), ("cs", 1)), (("cs", 1), ("sn", -1)), (("sn", -1), ("cs", -1)), (("cs", -1), ("sn", 1)))

Step = tuple[str, str, str, str]  # (result, op, a, b): op in OPS; a, b: "x", an earlier result or a CONSTANTS name


def _steps() -> tuple[Step, ...]:
    out: list[Step] = []

    def op(name: str, kind: str, a: str, b: str) -> str:
        out.append((name, kind, a, b))
        return name

    def horner(prefix: str, coef: str, n: int) -> str:
        """c1 + z (c2 + z (... + z cn)), innermost first."""
        p = op(f"{prefix}{n}", "mul", "z", f"{coef}{n}")
        for i in range(n - 1, 0, -1):
            p = op(f"{prefix}{i}", "add", f"{coef}{i}", p)
            if i > 1:
                p = op(f"{prefix}{i}z", "mul", "z", p)
        return p

    op("k", "sub", op("kr", "add", op("kx", "mul", "x", "INVPIO2"), "ROUND"), "ROUND")
    op("r", "sub", op("r1", "sub", "x", op("kp1", "mul", "k", "PIO2_1")), op("kp2", "mul", "k", "PIO2_1T"))
    op("z", "mul", "r", "r")
    # __kernel_sin: r + z r (S1 + z (S2 + ... + z S6))
    op("sn", "add", "r", op("snt", "mul", op("zr", "mul", "z", "r"), horner("ps", "S", 6)))
    # __kernel_cos: w + (((1 - w) - hz) + z z (C1 + ... + z C6)), hz = z / 2, w = 1 - hz
    op("w", "sub", "ONE", op("hz", "mul", "HALF", "z"))
    pc = horner("pc", "C", 6)
    tail = op("cst", "add", op("cw2", "sub", op("cw1", "sub", "ONE", "w"), "hz"), op("cz", "mul",
                                                                                    op("zz", "mul", "z", "z"), pc))
    op("cs", "add", "w", tail)
    return tuple(out)


STEPS: tuple[Step, ...] = _steps()


def _literal(a: str) -> str:
    return repr(CONSTANTS[a]) if a in CONSTANTS else a  # repr: the shortest text that reads back as the same double


def _assignments(fmt: str) -> list[str]:
    return [fmt.format(name=n, a=_literal(a), op=OPS[o], b=_literal(b)) for n, o, a, b in STEPS]


def python_source(name: str = "sincos") -> str:
    """`def name(x): return sin x, cos x` of one float (scalar Python, compiled by Numba)."""
    body = _assignments("    {name} = {a} {op} {b}")
    return "\n".join([
        f"def {name}(x):",
        '    """(sin x, cos x): the steps of dynid.dynamics.trig."""',
        f"    if not abs(x) < {LIMIT!r}:",
        "        return math.sin(x), math.cos(x)",
        *body,
        "    quadrant = int(k) & 3  # selects, not branches: the quadrants of real angles are unpredictable",
        "    odd = (quadrant & 1) != 0",
        "    a, b = (cs if odd else sn), (sn if odd else cs)",
        "    return (-a if quadrant & 2 else a), (-b if (quadrant + 1) & 2 else b)", ""])


def python_function(name: str = "sincos") -> Callable[[float], tuple[float, float]]:
    """python_source's function, compiled as if defined in this module (Numba's disk cache keys on the file that
    defines a function, so that a change to the steps here invalidates its machine code, and a cached load
    imports the module named by `__name__`)."""
    ns: dict = {"math": math, "__name__": __name__}
    exec(compile_source(python_source(name), __file__), ns)
    return ns[name]


def numpy_source(name: str = "_sincos") -> str:
    """`def name(x, s, c, k, t0, t1, ...)`: s, c = sin x, cos x over rows of samples (float64), with k an int64
    and t0.. float64 scratch rows of the same length (`numpy_rows()` of them). The module defining it needs
    `np`; in a chunk with an angle out of range, those samples alone take libm's values."""
    alloc, count = _numpy_allocation()
    scratch = [f"t{i}" for i in range(count)]
    at = {n: scratch[alloc[n]] for n, _, _, _ in STEPS}
    at["x"] = "x"
    consts = sorted({v for _, _, a, b in STEPS for v in (a, b) if v in CONSTANTS})
    fn = {"add": "np.add", "sub": "np.subtract", "mul": "np.multiply"}
    sn, cs, kq = at["sn"], at["cs"], at["k"]
    qs = next(r for r in scratch if r not in (sn, cs, kq))
    # constants as 0-d arrays: a float argument costs a conversion per ufunc call
    L = [f"_TRIG_{c} = np.array({CONSTANTS[c]!r})" for c in consts]
    # cos(k pi/2) and sin(k pi/2) by k mod 4, from QUADRANT: sin x = sn cos(k pi/2) + cs sin(k pi/2)
    cos_k = [float(sign) if v == "sn" else 0.0 for (v, sign), _ in QUADRANT]
    sin_k = [float(sign) if v == "cs" else 0.0 for (v, sign), _ in QUADRANT]
    L += [f"_TRIG_QC = np.array({cos_k!r})  # cos(k pi/2)", f"_TRIG_QS = np.array({sin_k!r})  # sin(k pi/2)",
          "", "",
          f"def {name}(x, s, c, k, {', '.join(scratch)}):",
          '    """s, c = sin x, cos x (rows): the steps of dynid.dynamics.trig, one ufunc each."""',
          f"    far = not (x.max(initial=0.0) < {LIMIT!r} and x.min(initial=0.0) > {-LIMIT!r})  # or NaN",
          "    if far:  # rare: those samples from libm, the others as usual",
          f"        bad = ~(np.abs(x) < {LIMIT!r})",
          "        xf = x[bad]",
          "        x = np.where(bad, 0.0, x)"]
    for n, o, a, b in STEPS:
        if (n, o, b) == ("kr", "add", "ROUND"):  # (t + ROUND) - ROUND is t rounded to even: one np.rint
            continue
        if (n, o, a, b) == ("k", "sub", "kr", "ROUND"):
            L.append(f"    np.rint({at['kx']}, {at['k']})")
            continue
        L.append(f"    {fn[o]}({at.get(a, f'_TRIG_{a}')}, {at.get(b, f'_TRIG_{b}')}, {at[n]})")
    # the quadrant: k + ROUND holds k mod 4 in its lowest bits; sin x = sn cos(k pi/2) + cs sin(k pi/2), whose
    # terms are products by 0 and +-1 (exact), and cos x = cs cos(k pi/2) - sn sin(k pi/2)
    L += [f"    np.add({kq}, _TRIG_ROUND, {kq})", f"    np.bitwise_and({kq}.view(np.int64), 3, out=k)",
          f"    np.take(_TRIG_QC, k, out={kq}, mode='clip')", f"    np.take(_TRIG_QS, k, out={qs}, mode='clip')",
          f"    np.multiply({sn}, {kq}, s)", f"    np.multiply({cs}, {qs}, c)", "    np.add(s, c, s)",
          f"    np.multiply({cs}, {kq}, c)", f"    np.multiply({sn}, {qs}, {kq})", f"    np.subtract(c, {kq}, c)",
          "    if far:", "        s[bad] = np.sin(xf)", "        c[bad] = np.cos(xf)", ""]
    return "\n".join(L)


def numpy_rows() -> int:
    """The number of scratch rows numpy_source's function takes."""
    return _numpy_allocation()[1]


def _numpy_allocation() -> tuple[dict[str, int], int]:
    """The scratch row of every step's result, a row taken again once its value is dead (the result may take an
    operand's row: ufuncs run element by element). sn, cs and k live to the end, with one more row for the
    quadrant."""
    last: dict[str, int] = {}
    for i, (_, _, a, b) in enumerate(STEPS):
        last[a] = last[b] = i
    last["sn"] = last["cs"] = last["k"] = len(STEPS)
    free: list[int] = []
    count = 0
    alloc: dict[str, int] = {}
    for i, (n, _, a, b) in enumerate(STEPS):
        for v in dict.fromkeys((a, b)):  # in order (a set would follow PYTHONHASHSEED)
            if v in alloc and last[v] == i:
                free.append(alloc[v])
        if free:
            alloc[n] = free.pop()
        else:
            alloc[n] = count
            count += 1
    return alloc, max(count, 4)


def c_source() -> str:
    """`static inline void dynid_sincos_lane(double x, double *s, double *c, double *bad)` (C99, no branch:
    the quadrant by exact arithmetic on small integers, so that compilers vectorise a loop of calls)."""
    body = _assignments("    const double {name} = {a} {op} {b};")
    return "\n".join([
        "/* sin and cos of x (1 ulp): the steps of dynid.dynamics.trig; the quadrant m = k - 4 round(k / 4)",
        "   (0, 1, +-2, -1) picks and signs them by exact arithmetic on small integers; *bad counts an x of",
        f"   {LIMIT:g} or more, or NaN, whose result is wrong */",
        "static inline void dynid_sincos_lane(double x, double *s, double *c, double *bad)",
        "{",
        *body,
        f"    const double m = k - 4.0 * ((k * 0.25 + {ROUND!r}) - {ROUND!r});",
        "    const double e = m * m;",
        "    const double odd = e * (4.0 - e) / 3.0, even = 1.0 - odd; /* 1 for m = +-1, else 0 */",
        "    const double a = (6.0 - 7.0 * e + e * e) / 6.0, b = m * (4.0 - e) / 3.0; /* signs: a + b of sin, a - b"
        " of cos */",
        "    *s = (a + b) * (odd * cs + even * sn);",
        "    *c = (a - b) * (odd * sn + even * cs);",
        f"    *bad += fabs(x) < {LIMIT!r} ? 0.0 : 1.0;",
        "}", ""])


__all__ = ["CONSTANTS", "COS", "LIMIT", "QUADRANT", "SIN", "STEPS", "c_source", "numpy_rows", "numpy_source",
           "python_function", "python_source"]
