"""Code generation from a Program: readable equations and C (header + source); the shared text helpers.

C: a per-sample function and a batched loop, with no dependency but libm; we never run a compiler at run time. The
per-sample functions take libm's sin and cos; the `_block` functions (samples side by side) dynamics.trig's steps,
as every other target, within an ulp of libm's. The NumPy emitter is `numpy_code`, the disk cache of generated NumPy
modules `cache`. Emission is deterministic: the same model gives the same text whatever PYTHONHASHSEED.
"""

from __future__ import annotations

from ..dynamics import trig
from .expr import Poly, Program, _key, factored

GENERATOR_VERSION = "3"
C_LANES = 8  # samples side by side in the _block C functions (see _c_block)
LANGS = ("numpy", "c", "text")
_TITLES = {"dgm": "Direct geometric model", "idm": "Inverse dynamic model", "regressor": "Identification model",
           "inertia": "Inertia matrix"}
# argument lists of each model's generated function
_ARGS = {"dgm": ("q",), "idm": ("q", "qd", "qdd", "X", "wrench"), "regressor": ("q", "qd", "qdd", "wrench"),
         "inertia": ("q", "X")}


# ----- expressions as text ------------------------------------------------------------------------
def format_poly(p: Poly, lang: str = "numpy") -> str:
    """A polynomial as source text, factored (the form the operation counts describe)."""
    return factored(p)[0]


def _fn(kind: str, lang: str) -> str:
    if lang == "c":
        return {"sin": "sin", "cos": "cos", "sign": "dynid_sign", "tanh": "tanh"}[kind]
    if lang == "numpy" and kind == "tanh":  # scalar Python (numba_backend) prefixes only sin and cos with math.
        return "math.tanh"
    return kind


def _eq_text(eq, lang: str) -> str:
    rhs = format_poly(eq.rhs, lang)
    return rhs if eq.kind == "poly" else f"{_fn(eq.kind, lang)}({rhs})"


def _prod(shape) -> int:
    out = 1
    for s in shape:
        out *= s
    return out


# ----- readable equations ------------------------------------------------------------------------
def to_text(prog: Program) -> str:
    """The model as equations a person can check against Khalil's book."""
    meta = prog.meta
    lines = [f"{_TITLES.get(prog.model, prog.model)} of {meta.get('tree', '?')}",
             f"geometry {meta.get('geometry')}, parameters {meta.get('parameters')}; "
             f"operations: {prog.ops()}", ""]
    if prog.constants:
        lines.append("Constants")
        lines += [f"  {k} = {v!r}" for k, v in prog.constants.items()]
        lines.append("")
    lines.append("Equations")
    lines += [f"  {eq.name} = {_eq_text(eq, 'text')}" for eq in prog.equations]
    lines.append("")
    lines.append(f"Outputs {prog.model}{list(prog.shape)}")
    labels = _output_labels(prog)
    lines += [f"  {labels(idx)} = {format_poly(p, 'text')}" for idx, p in prog.outputs]
    for name, (_, entries) in prog.extra_outputs.items():
        lines += [f"  {name}{list(idx)} = {format_poly(p, 'text')}" for idx, p in entries]
    return "\n".join(lines) + "\n"


def _output_labels(prog: Program):
    if prog.model == "regressor":
        rows, cols = prog.meta["rows"], prog.meta["cols"]
        return lambda idx: f"W[{rows[idx[0]]}, {cols[idx[1]]}]"
    if prog.model == "idm":
        return lambda idx: f"tau{idx[0] + 1}"
    if prog.model == "inertia":
        return lambda idx: f"A[{idx[0] + 1}, {idx[1] + 1}]"
    return lambda idx: f"T{idx[0]}[{idx[1] + 1}, {idx[2] + 1}]"


# ----- C ---------------------------------------------------------------------------------------------


def _c_lane_equations(prog: Program) -> list[str]:
    """The lanes' straight-line body: each equation a constant, but a sine and a cosine of one argument, which are
    one `dynid_sincos_lane` call, declared before it."""
    by_arg: dict[tuple, dict[str, str]] = {}
    for eq in prog.equations:
        if eq.kind in ("sin", "cos"):
            by_arg.setdefault(_key(eq.rhs), {})[eq.kind] = eq.name
    lines, done = [], set()
    for eq in prog.equations:
        if eq.kind not in ("sin", "cos"):
            text = _eq_text(eq, "c").replace("dynid_sign(", "dynid_sign_lane(")
            lines.append(f"        const double {eq.name} = {text};")
            continue
        key = _key(eq.rhs)
        if key in done:
            continue
        done.add(key)
        names = by_arg[key]
        s_name, c_name = names.get("sin", f"{eq.name}_sin"), names.get("cos", f"{eq.name}_cos")
        lines.append(f"        double {s_name}, {c_name};")
        lines.append(f"        dynid_sincos_lane({format_poly(eq.rhs, 'c')}, &{s_name}, &{c_name}, &bad[k]);")
    return lines


def _c_name(prog: Program, prefix: str) -> str:
    return f"{prefix}_{prog.model}"


def to_c(prog: Program, prefix: str = "dynid", block: bool = False) -> tuple[str, str]:
    """(header, source) of `void <prefix>_<model>(...)` per sample and `<prefix>_<model>_batch`; with
    block, also `<prefix>_<model>_block`, the batch vectorised across samples (see _c_block: for models
    of a few thousand operations; a compiler takes minutes on the full regressor of a 42-frame tree)."""
    fname = _c_name(prog, prefix)
    args = _ARGS[prog.model]
    n_sites = len(prog.meta.get("sites", []))
    params = [f"const double *{a}" for a in args if a != "wrench" or n_sites]
    outs = ["double *out"] + [f"double *{name}" for name in prog.extra_outputs]
    size = 1
    for s in prog.shape:
        size *= s
    guard = f"{fname.upper()}_H"
    strides = _strides(prog)
    hdr = [f"/* {_TITLES.get(prog.model, prog.model)} of {prog.meta.get('tree', '?')}, generated by dynid.symbolic.",
           f"   Operations per sample: {prog.ops()}.",
           "   Arrays are row-major doubles; one sample: q, qd, qdd (n), X (p), wrench (sites x 6),",
           f"   out {list(prog.shape)}. The _batch variant loops over N samples stored one after the other. */",
           f"#ifndef {guard}", f"#define {guard}", "",
           f"#define {fname.upper()}_N {strides['q']}", f"#define {fname.upper()}_SIZE {size}", "",
           f"void {fname}({', '.join(params + outs)});",
           f"void {fname}_batch(long N, {', '.join(params + outs)});"]
    if block:
        hdr += [f"/* _batch, {C_LANES} samples side by side (vectorised by the compiler across samples), the same",
                "   layouts and numbers to an ulp or two (sin and cos are fdlibm's polynomials) */",
                f"void {fname}_block(long N, {', '.join(params + outs)});"]
    hdr += ["", f"#endif /* {guard} */", ""]
    used = set(prog.meta.get("used_inputs", prog.inputs))
    src = [f"/* generated by dynid.symbolic: {prog.model} of {prog.meta.get('tree', '?')} */",
           "#include <math.h>", "#include <stdint.h>", f'#include "{fname}.h"',
           *(["#if defined(__SSE2__)", "#include <emmintrin.h>", "#endif"] if block else []), "",
           "static inline double dynid_sign(double x) { return (double)((x > 0.0) - (x < 0.0)); }", "",
           f"void {fname}({', '.join(params + outs)})", "{"]
    for k, v in prog.constants.items():
        src.append(f"    const double {k} = {v!r};")
    for name in sorted(used, key=lambda k: (str(prog.inputs[k][0]), str(prog.inputs[k][1]))):
        s, idx = prog.inputs[name]
        if s == "wrench":
            idx = idx[0] * 6 + idx[1]
        src.append(f"    const double {name} = {s}[{idx}];")
    # libm's sin and cos, sample by sample: faster here than trig's steps, whose quadrant's branch a scalar
    # function mispredicts (PUMA's regressor 0.57-0.59 against 0.62-0.68 us a sample, one process, both built)
    src += [f"    const double {eq.name} = {_eq_text(eq, 'c')};" for eq in prog.equations]
    src += _c_fill("out", prog.shape, prog.outputs)
    for name, (shape, entries) in prog.extra_outputs.items():
        src += _c_fill(name, shape, entries)
    src += ["}", "", f"void {fname}_batch(long N, {', '.join(params + outs)})", "{",
            "    for (long s = 0; s < N; ++s) {"]
    call = []
    for a in args:
        if a == "wrench" and not n_sites:
            continue
        call.append(f"{a} + s * {strides[a]}" if a != "X" else "X")
    call.append(f"out + s * {size}")
    for name, (shape, _) in prog.extra_outputs.items():
        call.append(f"{name} + s * {_prod(shape)}")
    src += [f"        {fname}({', '.join(call)});", "    }", "}", ""]
    if block:
        src += _c_block(prog, fname, params, outs, strides, size)
    return "\n".join(hdr), "\n".join(src)


def _strides(prog: Program) -> dict[str, int]:
    n = prog.meta.get("n", 0)
    return {"q": n, "qd": n, "qdd": n, "X": 0, "wrench": 6 * len(prog.meta.get("sites", []))}


def _c_fill(name: str, shape, entries) -> list[str]:
    size = _prod(shape)
    flat = {}
    for idx, p in entries:
        k = 0
        for i, s in zip(idx, shape, strict=True):
            k = k * s + i
        flat[k] = p
    # every entry written once, zeros included (no clearing pass over the output)
    return [f"    {name}[{k}] = {format_poly(flat[k], 'c') if k in flat else '0.0'};" for k in range(size)]


__all__ = ["C_LANES", "GENERATOR_VERSION", "LANGS", "format_poly", "to_c", "to_text"]


# ----- C, samples side by side --------------------------------------------------------------------
# Why: the per-sample function spends its time in scalar arithmetic and libm's sines and cosines. `_block` copies
# C_LANES samples' inputs into lane-major arrays and runs the whole straight-line body as one loop over those lanes,
# with scalar temporaries and only unit-stride accesses, which GCC (-O2 from version 12) and clang vectorise across
# samples; the results go to a lane-major tile and from it to the caller's sample-major `out`. Written so that the
# loop has no branch the vectoriser must refuse (GCC does not if-convert floating-point comparisons under its default
# -ftrapping-math): sine and cosine are dynamics.trig's steps with the quadrant applied by exact arithmetic, sign() is
# a copysign; a lane whose angle is 1e5 or more (or NaN) sends its block to the per-sample code (libm). A tail of
# fewer than C_LANES samples runs through the same code on padded copies: a sample's value does not depend on where it
# falls.
_C_LANE_HELPERS = "\n" + trig.c_source() + """
static inline double dynid_sign_lane(double x) { return copysign(fabs(x) > 0.0 ? 1.0 : 0.0, x); }

/* the first n lane columns of a lane-major tile (size rows of LANES) to n sample-major rows of o; with SSE2,
   a full block two samples and two entries at a time (a 2 x 2 transpose in registers), with streaming stores:
   the output is written once and not read soon, so it skips the cache (no read for ownership) */
static void dynid_tile_store(long n, const double *restrict t, double *restrict o, long size)
{
#if defined(__SSE2__)
    if (n == LANES && size % 2 == 0 && ((uintptr_t)o & 15) == 0) {
        for (int k = 0; k < LANES; k += 2) {
            double *o0 = o + k * size, *o1 = o0 + size;
            for (long e = 0; e < size; e += 2) {
                const __m128d a = _mm_loadu_pd(t + e * LANES + k), b = _mm_loadu_pd(t + (e + 1) * LANES + k);
                _mm_stream_pd(o0 + e, _mm_unpacklo_pd(a, b));
                _mm_stream_pd(o1 + e, _mm_unpackhi_pd(a, b));
            }
        }
        return;
    }
#endif
    for (long k = 0; k < n; ++k)
        for (long e = 0; e < size; ++e)
            o[k * size + e] = t[e * LANES + k];
}

static inline void dynid_store_fence(void)
{
#if defined(__SSE2__)
    _mm_sfence(); /* streaming stores are weakly ordered: visible before the function returns */
#endif
}
"""


def _c_block(prog: Program, fname: str, params: list[str], outs: list[str], strides: dict[str, int],
             size: int) -> list[str]:
    """`<fname>_block(N, ...)`: _batch's inputs, outputs entry-major (see the note above)."""
    B = C_LANES
    args = [p.split("*")[1] for p in params]
    out_lists = [("out", tuple(prog.shape), prog.outputs)] + [
        (k, tuple(sh), e) for k, (sh, e) in prog.extra_outputs.items()]
    out_names = [o for o, _, _ in out_lists]
    per_sample = {a: strides[a] for a in args if a != "X"}
    lane_in = [f"const double *restrict {a}" for a in args]
    lane_out = [f"double *restrict {o}" for o in out_names]
    body = [f"static void {fname}_lanes({', '.join(lane_in + lane_out)}, double *restrict bad)", "{",
            f"    for (int k = 0; k < {B}; ++k) {{"]
    for k, v in prog.constants.items():
        body.append(f"        const double {k} = {v!r};")
    used = set(prog.meta.get("used_inputs", prog.inputs))
    for name in sorted(used, key=lambda k: (str(prog.inputs[k][0]), str(prog.inputs[k][1]))):
        s, idx = prog.inputs[name]
        if s == "wrench":
            idx = idx[0] * 6 + idx[1]
        body.append(f"        const double {name} = X[{idx}];" if s == "X"
                    else f"        const double {name} = {s}[{idx * B} + k];")
    body += _c_lane_equations(prog)
    for o, shape, entries in out_lists:  # a lane-major tile: constant offsets, which the vectoriser needs
        body += [line.replace(f"    {o}[", f"        {o}[{B} * ", 1).replace("] = ", " + k] = ", 1)
                 for line in _c_fill(o, shape, entries)]
    body += ["    }", "}", ""]
    sizes = {o: _prod(sh) for o, sh, _ in out_lists}
    lanes_full = [f"{a}_l" if a in per_sample else a for a in args]
    drv = [f"void {fname}_block(long N, {', '.join(params + outs)})", "{",
           f"    for (long s = 0; s < N; s += {B}) {{",
           f"        const long n = N - s < {B} ? N - s : {B};  /* lanes past n repeat the last sample */"]
    for a, n in per_sample.items():
        drv.append(f"        double {a}_l[{B * n}];")
    drv += [f"        double bad[{B}] = {{0.0}};", f"        for (int k = 0; k < {B}; ++k) {{",
            "            const long t = k < n ? s + k : s + n - 1;"]
    for a, n in per_sample.items():
        drv.append(f"            for (int i = 0; i < {n}; ++i) {a}_l[i * {B} + k] = {a}[t * {n} + i];")
    drv.append("        }")
    for o in out_names:
        drv.append(f"        double {o}_t[{sizes[o] * B}];")
    drv.append(f"        {fname}_lanes({', '.join(lanes_full + [f'{o}_t' for o in out_names])}, bad);")
    for o in out_names:
        drv.append(f"        dynid_tile_store(n, {o}_t, {o} + s * {sizes[o]}, {sizes[o]});")
    drv += ["        double nbad = 0.0;", f"        for (int k = 0; k < {B}; ++k) nbad += bad[k];",
            "        if (nbad != 0.0) {  /* an angle out of the polynomials' range: libm, sample by sample */"]
    call = [f"{a} + t * {per_sample[a]}" if a in per_sample else a for a in args]
    call += [f"{o} + t * {sizes[o]}" for o in out_names]
    drv += ["            for (long t = s; t < s + n; ++t)", f"                {fname}({', '.join(call)});"]
    drv += ["        }", "    }", "    dynid_store_fence();", "}", ""]
    return [_C_LANE_HELPERS.replace("LANES", str(B)), *body, *drv]

