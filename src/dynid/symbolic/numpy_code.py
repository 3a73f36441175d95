"""NumPy code generation from a Program: one function per model, batched over samples.

Samples first on the way in and out like the numeric engine (the results read-only views),
evaluated block by block as three-address code over preallocated rows (see below for why).
"""

from __future__ import annotations

import ast
import re

from ..dynamics import trig
from ..model.tree import Tree
from ..pysource import parse
from .codegen import _ARGS, _TITLES, _eq_text, _prod, format_poly
from .expr import Poly, Program, SymbolicError, _key, is_const, neg, symbols_of, trivial

# The generated kernel is three-address code over preallocated rows (measured on PUMA 560 and the
# car, N = 20000; NumPy costs about 0.3 us per call plus 0.1-0.3 ns per element here):
# - samples are evaluated CHUNK at a time, every intermediate a row of one scratch array, rows
#   reused last-freed-first (still in cache); every operation writes into a row with out=, so
#   nothing is allocated per operation (NumPy temporaries of tens of kB make malloc trim and
#   grow its heap, a page fault per 4 kB, which tripled the cost of some blocks);
# - outputs are rows of a (size, N) buffer, the last operation writing straight into them; the
#   caller gets the transposed view (N, *shape); rows no equation writes stay zero; an output
#   equal to an earlier one (or to its negative) is copied;
# - big output buffers are pooled (fresh pages cost a fault and a zero fill each: for a small
#   model as long as the evaluation itself), see _buffer in _RUNTIME below; results are read-only
#   views, so that a reused buffer's zero rows (four fifths of the car's) need no clearing, which
#   cost a tenth of the car's evaluation (READONLY = False: writeable results, rows cleared);
# - sine and cosine of an angle are computed together, the steps of dynamics.trig one ufunc each
#   (np.sin and np.cos are scalar libm calls here, 9-13 ns each).
CHUNK = 8192
POOL_MIN = 1 << 20  # bytes: smaller outputs get plain np.zeros
POOL_SIZE = 2  # buffers kept per output array of a model (one per thread of the car pipeline)
READONLY = True  # evaluate's results are read-only views (see _buffer); False: writeable, zero rows cleared
_UFUNCS = {ast.Add: "_add", ast.Sub: "_sub", ast.Mult: "_mul"}
_WORD = re.compile(r"[A-Za-z_][A-Za-z_0-9]*")

_RUNTIME = f'''
_add, _sub, _mul, _neg, _sign = np.add, np.subtract, np.multiply, np.negative, np.sign
CHUNK = {CHUNK}  # samples per block
READONLY = {READONLY}  # results read-only: a reused buffer's zero rows need no clearing
POOL_MIN = {POOL_MIN}  # bytes from which an output buffer is pooled
POOL_SIZE = {POOL_SIZE} * N_OUTPUTS
_POOL = []  # [buffer, weak reference to the root of the results last made on it]
_POOL_LOCK = threading.Lock()


def _buffer(size, N, zero_rows):
    """(buffer, root): a writeable (size, N) output buffer, zero in zero_rows (the kernel writes every other row),
    and the array over the same memory that the caller's results are views of.

    Fresh pages cost a page fault and a zero fill each, about as long as evaluating a small
    model, so up to POOL_SIZE big buffers are kept, and one is handed out again only once no
    result made on it is alive. The root is made over a memoryview of the buffer, so NumPy's
    views of it stop collapsing their base at it: every array made from a result refers to
    the root, and a weak reference to the root says whether any is alive (with READONLY, a
    read-only memoryview, which no view can make writeable: the zero rows stay zero).
    """
    if size * N * 8 < POOL_MIN:
        buf = np.zeros((size, N))
        return buf, buf
    with _POOL_LOCK:
        free = [item for item in _POOL if item[1] is None or item[1]() is None]
        for item in free:
            if item[0].shape == (size, N):
                buf = item[0]
                if not READONLY:  # results went out writeable: the caller may have written into them
                    for a, b in zero_rows:
                        buf[a:b] = 0.0
                break
        else:
            buf = np.zeros((size, N))
            item = free[0] if free else [None, None]
            item[0] = buf
            if not free and len(_POOL) < POOL_SIZE:
                _POOL.append(item)
        view = memoryview(buf)
        root = np.asarray(view.toreadonly() if READONLY else view)
        item[1] = weakref.ref(root)  # busy while the caller fills it (it holds the root), then while results live
    return buf, root


def _result(root, shape):
    """(N, *shape) view of a (size, N) root, read-only with READONLY."""
    if READONLY:
        root.flags.writeable = False
    return np.moveaxis(root.reshape(shape + (root.shape[1],)), -1, 0)


def release():
    """Free the pooled output buffers."""
    with _POOL_LOCK:
        _POOL.clear()
'''


class _Slots:
    """Rows of the kernel's scratch array: a free list, the last freed taken first (still in cache)."""

    def __init__(self) -> None:
        self.free: list[str] = []
        self.count = 0

    def take(self) -> str:
        if self.free:
            return self.free.pop()
        self.count += 1
        return f"_t{self.count - 1}"

    def give(self, slot: str) -> None:
        self.free.append(slot)


def _signed(node: ast.expr, negated: set[str]) -> tuple[ast.expr, bool]:
    """(node without unary minus, negated): minus signs moved up through products and sums, or
    into a numeric factor; names in `negated` hold the opposite of their value. IEEE arithmetic
    is symmetric in sign, so the values are the same, with fewer operations."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        inner, neg_ = _signed(node.operand, negated)
        return inner, not neg_
    if isinstance(node, ast.Name):
        return node, node.id in negated
    if not isinstance(node, ast.BinOp):
        return node, False
    left, nl = _signed(node.left, negated)
    right, nr = _signed(node.right, negated)
    if isinstance(node.op, ast.Mult):
        negative = nl != nr
        for side in (left, right):
            if negative and isinstance(side, ast.Constant):
                side.value = -side.value
                negative = False
        return ast.BinOp(left, ast.Mult(), right), negative
    if isinstance(node.op, ast.Sub):
        nr = not nr
    if nl == nr:
        return ast.BinOp(left, ast.Add(), right), nl
    if nr:
        return ast.BinOp(left, ast.Sub(), right), False
    return ast.BinOp(right, ast.Sub(), left), False


class _Kernel:
    """Emits the statements of the kernel: each operation one ufunc call writing into a row."""

    def __init__(self) -> None:
        self.slots = _Slots()
        self.lines: list[str] = []
        self.temps: set[str] = set()
        self.rows: dict[str, str] = {}  # named intermediate -> its row
        self.numbers: dict[str, str] = {}  # number text -> module-level 0-d array name
        self.loaded: set[str] = set()  # inputs copied into rows
        self.negated: set[str] = set()  # intermediates whose row holds the opposite of their value

    # -- expressions
    def value(self, text: str) -> tuple[str, bool]:
        """Emit text into a temporary row (or nothing for a name or a number): (operand, negated)."""
        node, negated = _signed(parse(text, mode="eval").body, self.negated)
        return self._operand(node), negated

    def into(self, text: str, dst: str, sign_free: bool = False) -> bool:
        """Emit dst = text, the last operation writing into dst; with sign_free, dst may get the
        opposite value instead of a negation pass: returns whether it did."""
        node, negated = _signed(parse(text, mode="eval").body, self.negated)
        if negated and not (sign_free and isinstance(node, ast.BinOp)):
            v = self._operand(node)
            self._release(v)
            self.lines.append(f"_neg({v}, {dst})")
            return False
        if isinstance(node, ast.BinOp):
            a, b = self._operand(node.left), self._operand(node.right)
            self._release(a)
            self._release(b)
            self.lines.append(f"{_UFUNCS[type(node.op)]}({a}, {b}, {dst})")
        else:
            self.lines.append(f"{dst}[...] = {ast.unparse(node)}")
        return negated

    def _operand(self, node: ast.expr) -> str:
        if isinstance(node, ast.Constant):  # a 0-d array: a Python float costs a conversion per call
            return self.numbers.setdefault(repr(float(node.value)), f"_c{len(self.numbers)}")
        if not isinstance(node, ast.BinOp):
            return ast.unparse(node)
        a, b = self._operand(node.left), self._operand(node.right)
        out = a if a in self.temps else b if b in self.temps else self._temp()
        if out != a:
            self._release(a)
        if out != b:
            self._release(b)
        self.lines.append(f"{_UFUNCS[type(node.op)]}({a}, {b}, {out})")
        return out

    def _temp(self) -> str:
        t = self.slots.take()
        self.temps.add(t)
        return t

    def _release(self, operand: str) -> None:
        if operand in self.temps:
            self.temps.discard(operand)
            self.slots.give(operand)

    # -- equations
    def name(self, name: str) -> None:
        """Give a named intermediate a row (until `drop`)."""
        self.rows[name] = self.slots.take()
        self.lines.append(f"{name} = {self.rows[name]}")

    def drop(self, name: str) -> None:
        self.slots.give(self.rows.pop(name))

    def load(self, names: set[str], loads: dict[str, str]) -> None:
        """Copy the inputs among names that are read more than once, once, into rows."""
        for x in sorted(names):
            if x in loads and x not in self.rows and x not in self.loaded:
                self.loaded.add(x)
                self.name(x)
                self.lines.append(f"np.copyto({x}, {loads[x]})")

    def equation(self, name: str, text: str) -> None:
        self.name(name)
        if self.into(text, name, sign_free=True):
            self.negated.add(name)

    def function(self, names: dict[str, str], text: str) -> None:
        """names: {kind: name} for sign, sin or cos, or {"sin": S, "cos": C} of the same argument."""
        for name in names.values():
            self.name(name)
        x, negated = self.value(text)
        if negated:
            self._release(x)
            t = self._temp()
            self.lines.append(f"_neg({x}, {t})")
            x = t
        if len(names) == 2:
            w = [self._temp() for _ in range(trig.numpy_rows())]
            self.lines.append(f"_sincos({x}, {names['sin']}, {names['cos']}, _K, {', '.join(w)})")
            for t in w:
                self._release(t)
        else:
            (k, name), = names.items()
            self.lines.append(f"{'_sign' if k == 'sign' else 'np.' + k}({x}, {name})")
        self._release(x)


def _out_list(prog: Program) -> list[tuple[str, tuple[int, ...], list]]:
    """(name, shape, entries) of every output array: out, then the extra outputs (Q)."""
    outs = [("out", tuple(prog.shape), prog.outputs)]
    return outs + [(name, tuple(shape), entries) for name, (shape, entries) in prog.extra_outputs.items()]


def _flat(idx: tuple[int, ...], shape: tuple[int, ...]) -> int:
    k = 0
    for i, s in zip(idx, shape, strict=True):
        k = k * s + i
    return k


def _zero_runs(shape: tuple[int, ...], entries) -> tuple[tuple[int, int], ...]:
    """[start, stop) runs of the flat entries no output writes."""
    written = {_flat(idx, shape) for idx, _ in entries}
    runs: list[tuple[int, int]] = []
    for k in range(_prod(shape)):
        if k in written:
            continue
        if runs and runs[-1][1] == k:
            runs[-1] = (runs[-1][0], k + 1)
        else:
            runs.append((k, k + 1))
    return tuple(runs)


_RESERVED = {"q", "qd", "qdd", "X", "XT", "wrench", "out", "Q", "np", "sys", "threading", "weakref", "evaluate",
             "release", "CHUNK", "POOL_MIN", "POOL_SIZE", "READONLY", "MODEL", "HASH", "KEY", "SHAPE", "N_SITES",
             "N_OUTPUTS", "ROWS", "COLS", "PARAMETERS", "DEFAULT_X", *_ARGS}


def _check_names(prog: Program) -> None:
    for name in [*prog.inputs, *prog.constants, *(eq.name for eq in prog.equations)]:
        if name in _RESERVED or name.startswith("_"):
            raise SymbolicError(f"symbol {name!r} of the {prog.model} model clashes with a name of the generated "
                                "NumPy code (rename the parameter or coupling)")


def to_numpy(prog: Program, tree: Tree | None = None, model_hash: str = "") -> str:
    """Source of a module with `evaluate(...)` batched over samples (arrays (N, ...)).

    evaluate returns read-only arrays (N, *shape) that are views of C-ordered (size, N) buffers
    (one row per entry: `W.transpose(1, 2, 0)` is C-contiguous; copy to modify), and may hand a
    buffer out again once every array returned on it has been dropped. Sines and cosines are
    dynamics.trig's (within an ulp of libm, the bits of the C and LLVM kernels'), everything else is
    the same floating-point operations as the equations.
    """
    _check_names(prog)
    outs = _out_list(prog)
    loads = _input_loads(prog, outs)
    body, kernel = _np_body(prog, outs, loads)
    numbers = [f"{name} = np.array({text})" for text, name in kernel.numbers.items()]
    L = _np_header(prog, tree, model_hash, outs, numbers, any(eq.kind in ("sin", "cos") for eq in prog.equations))
    L += _np_evaluate(prog, outs, kernel.slots.count)
    L += ["", "", *_np_kernel(prog, outs, loads, kernel.slots.count), *("    " + x for x in body)]
    L += ["", "", f"{prog.model} = evaluate"]
    return "\n".join(L) + "\n"


def _np_header(prog: Program, tree: Tree | None, model_hash: str, outs, numbers: list[str], sincos: bool) -> list[str]:
    meta = prog.meta
    L = [f'"""{_TITLES.get(prog.model, prog.model)} of {meta.get("tree", "?")}, generated by dynid.symbolic.',
         "",
         f"Operations per sample: {prog.ops()}. Do not edit: regenerate instead.",
         '"""', "", "import threading", "import weakref", "", "import numpy as np", "",
         f"MODEL = {prog.model!r}", f"HASH = {model_hash!r}", f"SHAPE = {tuple(prog.shape)!r}",
         f"N_SITES = {len(meta.get('sites', []))}", f"N_OUTPUTS = {len(outs)}"]
    if prog.model == "regressor":
        L += [f"ROWS = {tuple(meta['rows'])!r}", f"COLS = {tuple(meta['cols'])!r}"]
    if tree is not None:
        L.append(f"PARAMETERS = {tuple(tree.parameter_names)!r}")
        L.append(f"DEFAULT_X = np.array({[float(x) for x in tree.parameters]!r})")
    L += [f"{k} = {v!r}" for k, v in prog.constants.items()]
    L += numbers  # the equations' numbers as 0-d arrays (a float argument costs a conversion per call)
    L += [f"_ZERO_{name} = {_zero_runs(shape, entries)!r}  # rows no equation writes"
          for name, shape, entries in outs]
    L += _RUNTIME.split("\n")
    if sincos:
        L += ["", *trig.numpy_source("_sincos").split("\n")]
    return [*L, ""]


def _np_evaluate(prog: Program, outs, n_slots: int) -> list[str]:
    args = _ARGS[prog.model]
    n_sites = len(prog.meta.get("sites", []))
    sig = [f"{a}=None" if a in ("X", "wrench") else a for a in args]
    L = [f"def evaluate({', '.join(sig)}):", f'    """{_doc(prog)}"""',
         "    q = np.asarray(q, dtype=float)", "    single = q.ndim == 1", "    q = np.atleast_2d(q)",
         "    N = q.shape[0]"]
    for a in args:
        if a in ("qd", "qdd"):
            L.append(f"    {a} = np.atleast_2d(np.asarray({a}, dtype=float))")
            L.append(f"    if {a}.shape != q.shape:")
            L.append(f'        raise ValueError(f"{a} has shape {{{a}.shape}}; q has shape {{q.shape}}")')
    if "X" in args:
        L.append("    X = DEFAULT_X if X is None else np.asarray(X, dtype=float)")
        L.append("    XT = X.T")
    if "wrench" in args and n_sites:
        L.append("    if wrench is None:")
        L.append(f'        raise ValueError("this model has {n_sites} wrench site(s): pass wrench (N, {n_sites}, 6)")')
        L.append(f"    wrench = np.asarray(wrench, dtype=float).reshape(-1, {n_sites}, 6)")
        L.append(f"    wrench = np.broadcast_to(wrench, (N, {n_sites}, 6))")
    for name, shape, _ in outs:
        L.append(f"    {name}, _{name}_root = _buffer({_prod(shape)}, N, _ZERO_{name})")
    L.append("    m = max(1, -(-N // max(1, -(-N // CHUNK))))  # equal blocks of at most CHUNK samples")
    L.append(f"    T = np.empty(({max(n_slots, 1)}, m))  # a row per live intermediate")
    L.append("    K = np.empty(m, dtype=np.int64)")
    L.append("    for s in range(0, N, m):")
    L.append("        e = min(N, s + m)")
    call = [f"{a}[s:e]" for a in ("q", "qd", "qdd") if a in args]
    if "X" in args:
        call.append("XT if XT.ndim == 1 else XT[:, s:e]")
    if "wrench" in args and n_sites:
        call.append("wrench[s:e]")
    call += [f"{name}[:, s:e]" for name, _, _ in outs]
    call += ["T[:, :e - s]", "K[:e - s]"]
    L.append(f"        _kernel({', '.join(call)})")
    for name, shape, _ in outs:  # (size, N) -> (N, *shape), a view
        L.append(f"    {name} = _result(_{name}_root, {shape!r})")
    names = [name for name, _, _ in outs]
    if len(names) == 1:
        L.append("    return out[0] if single else out")
    else:
        L.append(f"    return ({', '.join(x + '[0]' for x in names)}) if single else ({', '.join(names)})")
    return L


def _np_kernel(prog: Program, outs, loads: dict[str, str], n_slots: int) -> list[str]:
    """The kernel's signature, the inputs read in place, the rows (its body comes from _np_body)."""
    args = _ARGS[prog.model]
    n_sites = len(prog.meta.get("sites", []))
    kargs = [a for a in ("q", "qd", "qdd") if a in args]
    if "X" in args:
        kargs.append("XT")
    if "wrench" in args and n_sites:
        kargs.append("wrench")
    kargs += [name for name, _, _ in outs]
    L = [f"def _kernel({', '.join([*kargs, '_T', '_K'])}):",
         '    """One block of samples: every operation writes into a row of _T (or of an output)."""']
    used = prog.meta.get("used_inputs", sorted(prog.inputs))
    for name in sorted(used, key=lambda k: (str(prog.inputs[k][0]), str(prog.inputs[k][1]))):
        if name not in loads:  # read once (a strided column) or a parameter: no copy
            L.append(f"    {name} = {_input_source(prog, name)}")
    if n_slots:
        L.append(f"    {', '.join(f'_t{i}' for i in range(n_slots))}{',' if n_slots == 1 else ''} = _T")
    return L


def _input_source(prog: Program, name: str) -> str:
    src, idx = prog.inputs[name]
    if src == "X":
        return f"XT[{idx}, ...]"  # a 0-d array (or a row): a NumPy scalar costs a conversion per call
    if src == "wrench":
        return f"wrench[:, {idx[0]}, {idx[1]}]"
    return f"{src}[:, {idx}]"


def _input_loads(prog: Program, outs) -> dict[str, str]:
    """Inputs read more than once: copied from their strided column into a row before their first
    use (the column of an (N, n) array is one element per cache line)."""
    texts = [format_poly(eq.rhs) for eq in prog.equations]
    texts += [format_poly(eq.rhs) for eq in prog.equations if eq.kind in ("sin", "cos")]  # _sincos reads x twice
    texts += [format_poly(p) for _, _, entries in outs for _, p in entries]
    count: dict[str, int] = {}
    for text in texts:
        for word in _WORD.findall(text):
            count[word] = count.get(word, 0) + 1
    used = prog.meta.get("used_inputs", sorted(prog.inputs))
    return {x: _input_source(prog, x) for x in used if prog.inputs[x][0] != "X" and count.get(x, 0) > 1}


def _np_body(prog: Program, outs, loads: dict[str, str]) -> tuple[list[str], _Kernel]:
    """The kernel's statements in order: each output right after the last equation it needs,
    each input copied to a row before its first use, each row freed after its last use, sine
    and cosine of an angle together."""
    where = {eq.name: i for i, eq in enumerate(prog.equations)}
    after: dict[int, list[tuple[str, int, Poly]]] = {}
    uses: list[set[str]] = [symbols_of(eq.rhs) for eq in prog.equations]
    pre: set[str] = set()
    for name, shape, entries in outs:
        for idx, p in entries:
            syms = symbols_of(p)
            pos = max((where[x] for x in syms if x in where), default=-1)
            after.setdefault(pos, []).append((name, _flat(idx, shape), p))
            if pos >= 0:
                uses[pos] = uses[pos] | syms
            else:
                pre |= syms
    last: dict[str, int] = {x: -1 for x in sorted(pre)}
    for i, u in enumerate(uses):
        for x in sorted(u):
            last[x] = i
    frees: dict[int, list[str]] = {}
    for x, i in last.items():
        if x in where or x in loads:
            frees.setdefault(i, []).append(x)
    pairs = _function_pairs(prog)
    k = _Kernel()
    seen: dict[tuple, str] = {}
    k.load(pre, loads)
    _emit_outputs(k, after.pop(-1, []), seen)
    for x in sorted(frees.get(-1, [])):
        k.drop(x)
    done: set[str] = set()
    for i, eq in enumerate(prog.equations):
        k.load(uses[i], loads)
        if eq.name not in done:
            k.lines.append(f"# {eq.name} = {_eq_text(eq, 'text')}")
            if eq.kind == "poly":
                k.equation(eq.name, format_poly(eq.rhs))
            else:
                names = pairs.get(eq.name, {eq.kind: eq.name})
                k.function(names, format_poly(eq.rhs))
                done.update(names.values())
        _emit_outputs(k, after.get(i, []), seen)
        for x in sorted(frees.get(i, [])):
            k.drop(x)
    return k.lines, k


def _function_pairs(prog: Program) -> dict[str, dict[str, str]]:
    """Sine and cosine of the same argument: name -> {"sin": S, "cos": C} for both names."""
    by_arg: dict[tuple, dict[str, str]] = {}
    for eq in prog.equations:
        if eq.kind in ("sin", "cos"):
            by_arg.setdefault(_key(eq.rhs), {})[eq.kind] = eq.name
    return {name: d for d in by_arg.values() if len(d) == 2 for name in d.values()}


def _emit_outputs(k: _Kernel, entries: list[tuple[str, int, Poly]], seen: dict[tuple, str]) -> None:
    """Output rows; one equal to an earlier one (or to its negative) is copied."""
    for name, flat, p in entries:
        dst = f"{name}[{flat}]"
        if not is_const(p) and not trivial(p):
            key = _key(p)
            if key in seen:
                k.lines.append(f"{dst}[...] = {seen[key]}")
                continue
            nkey = _key(neg(p))
            if nkey in seen:
                k.lines.append(f"_neg({seen[nkey]}, {dst})")
                continue
            seen[key] = dst
        k.into(format_poly(p), dst)


def _doc(prog: Program) -> str:
    s = {"dgm": "q (N, n) -> 0T_j (N, n+1, 4, 4)",
         "idm": "q, qd, qdd (N, n), X (p,) parameters, wrench (N, sites, 6) -> tau (N, n)",
         "regressor": "q, qd, qdd (N, n), wrench (N, sites, 6) -> W (N, rows, cols) [, Q (N, rows)]",
         "inertia": "q (N, n), X (p,) parameters -> A (N, n, n)"}[prog.model]
    return s + ("; a 1-D q gives one sample. Results are read-only views (N first) of (entries, N) buffers that "
                "later calls reuse once dropped: copy them to modify.")


__all__ = ["CHUNK", "READONLY", "to_numpy"]
