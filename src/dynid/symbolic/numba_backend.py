"""Per-sample scalar Python code from a Program, compiled by Numba, cached on disk.

The NumPy backend (numpy_code.to_numpy) is batched: every intermediate is an (N,) array,
which is right for an identification over thousands of samples and wrong for a
simulator that needs one sample at a time inside an integration loop. This backend
writes what `to_c` writes, in Python: one function per model taking one sample,

    def <name>(q, qd, qdd, X, wrench, out[, Q]):     # the arrays the model reads
        S4 = _sin(q4)                                # Khalil's intermediate variables
        ...
        out[k] = ...                                 # flat row-major output, zeros included

with _sin and _cos dynamics.trig's steps (HEADER: every generated target's sine and cosine, the same bits in
Python, in Numba and from LLVM IR), and q, qd, qdd (n,), X (p,) (only with symbolic parameters), wrench
(sites, 6), out and any extra output flat float64 arrays. The module source is written atomically to
`cache_dir()/numba/<name>_<hash>.py` (hash of the model and of this generator) and
imported from there (cache.load_module), so that `numba.njit(cache=True)` can keep the machine code next
to it: the first run compiles (seconds), the next ones load. Without numba the same
functions run as plain Python (about 100x slower), with a warning.

`compile_source` does the same for any source the caller assembles (the simulator puts
its generated models and its integration kernel in one module so that Numba can inline
across them and cache the whole).
"""

from __future__ import annotations

import ast
import ctypes
import hashlib
import importlib
import pickle
import threading
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from .. import pysource
from ..dynamics import trig
from ..model.tree import Tree
from .cache import generator_fingerprint, load_entry, load_module, model_hash, module_path
from .codegen import _ARGS, _eq_text, format_poly
from .expr import Program, SymbolicError
from .llvm_code import UnsupportedSourceError, function_ir, library_state, load_library, native_library, parse_function
from .models import build

BACKEND_VERSION = "1"


class NumbaMissingWarning(RuntimeWarning):
    """numba is not installed: generated code runs as plain Python (slow but correct)."""


def have_numba() -> bool:
    try:
        importlib.import_module("numba")
    except ImportError:
        return False
    return True


def jit(fn):
    """numba.njit(cache=True) when numba is importable, else the function itself (with a warning once)."""
    try:
        from numba import njit  # start-up: numba 0.5 s
    except ImportError:
        _warn_missing()
        return fn
    return njit(cache=True)(fn)


def internal_copy(dispatcher: Callable) -> Callable:
    """A copy of a jitted function for jitted callers only: its options, without entry points (_NO_ENTRIES), kept
    as LLVM IR for its callers (link_only), not cached (compile_source's `internal`)."""
    from numba import njit  # start-up: numba 0.5 s

    from .link_only import LinkOnlyCompiler

    options = {k: v for k, v in dispatcher.targetoptions.items() if k != "nopython"}  # njit sets it (and warns)
    return njit(**options, no_cpython_wrapper=True, no_cfunc_wrapper=True,
                pipeline_class=LinkOnlyCompiler)(dispatcher.py_func)


_WARNED = [False]


def _warn_missing() -> None:
    if not _WARNED[0]:
        _WARNED[0] = True
        warnings.warn("numba is not installed: dynid's generated per-sample code runs as plain Python, about 100x "
                      "slower; install numba (pip install numba)", NumbaMissingWarning, stacklevel=3)


def _prod(shape) -> int:
    out = 1
    for s in shape:
        out *= s
    return out


def _flat(idx, shape) -> int:
    k = 0
    for i, s in zip(idx, shape, strict=True):
        k = k * s + i
    return k


def arguments(prog: Program) -> list[str]:
    """Input arrays of the per-sample function, in order: those of the model kind (q, qd, qdd as the
    kind takes them; X and wrench only when the code reads them), or for a custom Program the ones it reads."""
    used = {prog.inputs[k][0] for k in prog.meta.get("used_inputs", prog.inputs)}
    kind = _ARGS.get(prog.model)
    if kind is None:
        return [a for a in ("q", "qd", "qdd", "X", "wrench") if a in used or a == "q"]
    return [a for a in kind if a in ("q", "qd", "qdd") or a in used]


def scalar_source(prog: Program, name: str | None = None) -> str:
    """Source of `def <name>(inputs..., out, extras...)` for one sample (see the module doc)."""
    name = name or prog.model
    if not name.isidentifier():
        raise SymbolicError(f"function name {name!r} is not a Python identifier")
    args = arguments(prog)
    outs = ["out", *prog.extra_outputs]
    L = [f"def {name}({', '.join(args + outs)}):",
         f'    """{prog.model} of {prog.meta.get("tree", "?")}, one sample; {prog.ops()}.',
         f"    out: flat row-major {list(prog.shape)}"
         + "".join(f", {k}: flat {list(s)}" for k, (s, _) in prog.extra_outputs.items()) + '."""']
    for k, v in prog.constants.items():
        L.append(f"    {k} = {v!r}")
    used = prog.meta.get("used_inputs", sorted(prog.inputs))
    for sym_name in sorted(used, key=lambda k: (str(prog.inputs[k][0]), str(prog.inputs[k][1]))):
        src, idx = prog.inputs[sym_name]
        if src == "wrench":
            L.append(f"    {sym_name} = wrench[{idx[0]}, {idx[1]}]")
        else:
            L.append(f"    {sym_name} = {src}[{idx}]")
    for eq in prog.equations:
        rhs = _eq_text(eq, "numpy")
        if eq.kind in ("sin", "cos"):  # dynamics.trig's (HEADER), as every target's
            rhs = "_" + rhs
        elif eq.kind == "sign":
            rhs = "_sign" + rhs[len("sign"):]
        L.append(f"    {eq.name} = {rhs}")
    for oname, shape, entries in [("out", tuple(prog.shape), prog.outputs)] + [
            (k, tuple(s), e) for k, (s, e) in prog.extra_outputs.items()]:
        flat = {_flat(idx, shape): p for idx, p in entries}
        size = _prod(shape)
        if len(flat) < size // 4:  # sparse (an inertia matrix): clear, then write the nonzero entries
            L.append(f"    {oname}[:] = 0.0")
            L += [f"    {oname}[{k}] = {format_poly(p)}" for k, p in sorted(flat.items())]
        else:
            L += [f"    {oname}[{k}] = {format_poly(flat[k]) if k in flat else '0.0'}" for k in range(size)]
    L.append("    return 0")
    return "\n".join(L) + "\n"


HEADER = '''"""Generated by dynid.symbolic.numba_backend. Do not edit: regenerate instead."""

import math  # noqa: F401

import numpy as np  # noqa: F401


def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


''' + trig.python_source("_sincos") + '''


def _sin(x):
    return _sincos(x)[0]


def _cos(x):
    return _sincos(x)[1]

'''


# what a function only jitted code calls goes without: the Python entry (unboxing each argument: large for a
# function of many arrays) and the C entry, each lowered by Numba and optimised and emitted by LLVM; and without
# its own module optimisation and machine code (link_only: its callers link its IR, optimise and emit it), so it
# is not cached (its code is, in its callers')
_NO_ENTRIES = "no_cpython_wrapper=True, no_cfunc_wrapper=True, pipeline_class=LinkOnlyCompiler"


def _footer(names: list[str], mod_name: str, straight: dict[str, list[str]], error_model: str = "python",
            internal: Sequence[str] = ()) -> str:
    """jit every name; those in `straight` (name -> its arguments) through their LLVM IR (llvm_code):
    a thin jitted wrapper calls the intrinsic, so that Python and jitted callers see one dispatcher.
    `internal` (compile_source): jitted without entry points, the imported ones from their Python function."""
    model = "" if error_model == "python" else f", error_model={error_model!r}"
    opts = f"cache=True{model}"
    lines = ["", f"JITTED = {tuple(names)!r}", "try:", "    from numba import njit",
             "except ImportError:", "    NUMBA = False", "else:", "    NUMBA = True",
             *(f"    {f} = njit({opts})({f})" for f in ("_sign", "_sincos", "_sin", "_cos"))]
    if any(n in internal for n in names):
        lines.append("    from dynid.symbolic.link_only import LinkOnlyCompiler")
    # an imported dispatcher's copy keeps its own options (error model...), not this module's; it is not cached:
    # Numba's cache of it (by its file and name, not its flags) is the original's, which Python calls; the copy's
    # code is cached in its callers'
    copies = [n for n in internal if n not in names]
    if copies:
        lines.append("    from dynid.symbolic.numba_backend import internal_copy")
    lines += [f"    {n} = internal_copy({n})" for n in copies]
    lines += [f"    {n} = njit({model[2:] + ', ' if model else ''}{_NO_ENTRIES})({n})" if n in internal
              else f"    {n} = njit({opts})({n})" for n in names if n not in straight]
    if straight:
        lines.append("    from dynid.symbolic.llvm_code import straight_line")
    for n, args in straight.items():
        a = ", ".join(args)
        lines += ["", f"    _ir_{n} = straight_line({n}, {f'{mod_name}.{n}'!r})", "",
                  f"    @njit({opts})", f"    def {n}({a}):  # noqa: F811 - replaces the Python version",
                  f"        return _ir_{n}(({a},))"]
    return "\n".join(lines) + "\n"


def _straight_arguments(body: str, names: list[str]) -> dict[str, list[str]]:
    """name -> arguments of the functions of `body` among `names` that llvm_code can translate (numba is
    importable and the source is in its language); the others are compiled by numba from Python."""
    if not names or not have_numba():
        return {}

    out: dict[str, list[str]] = {}
    for node in pysource.parse(body).body:
        if isinstance(node, ast.FunctionDef) and node.name in names:
            try:
                function_ir(ast.get_source_segment(body, node) or "", node.name)
            except UnsupportedSourceError as e:
                warnings.warn(f"{node.name}: compiled by numba from Python ({e})", RuntimeWarning, stacklevel=3)
                continue
            out[node.name] = [a.arg for a in node.args.args]
    return out


def compile_source(body: str | None, names: list[str], key: str, prefix: str = "dynid_nb",
                   straight: Sequence[str] = (), error_model: str = "python",
                   internal: Sequence[str] = ()) -> ModuleType | None:
    """Import (cache.load_module: from the disk cache, or after writing it) a module HEADER + body whose
    functions `names` are jitted with numba.njit(cache=True); key: a hash of everything the body depends on
    (NOT of the text: the generator's factoring order may vary between processes), naming the module.
    `straight`: those of `names` that are generated straight-line code (scalar_source), compiled
    from their LLVM IR (llvm_code: seconds less each than numba's typing of every statement, the
    same numbers). error_model: numba's ("numpy": a division by zero gives inf or NaN instead of raising, so
    Numba types and lowers no check per division; it changes the machine code, so the caller's key must hold it).
    internal: functions only the module's jitted code calls (not Python): of `names`, or dispatchers the body
    imports (recompiled here from their Python functions); compiled without entry points (_NO_ENTRIES), which a
    first run would otherwise lower, optimise and emit for nothing, and kept as LLVM IR that their callers link
    (link_only: not cached themselves, their code is in their callers'; the key must hold the list).

    Functions are compiled lazily by numba (at their first call); `warm` calls them. Without
    numba the module runs as plain Python (NumbaMissingWarning). body None: load from the cache
    only, None when it is not there.
    """

    def source() -> str:
        assert body is not None
        straight_args = _straight_arguments(body, [n for n in straight if n in names])
        return HEADER + body + _footer(names, mod_name, straight_args, error_model, internal)

    mod_name = f"{prefix}_{key}"
    mod = load_module("numba", mod_name, key, None if body is None else source)
    if mod is not None and not getattr(mod, "NUMBA", False):
        _warn_missing()
    return mod


@dataclass(frozen=True)
class NativeFunctions:
    """Generated straight-line functions compiled to machine code (`native_functions`): `address[name]` for a
    compiled caller (llvm_code.address_call), `python[name]` to call one from Python with its arrays (C-contiguous
    float64), `native` False when numba is absent (then the addresses index `python`'s functions, which run as
    plain Python)."""

    address: dict[str, int]
    python: dict[str, Callable]
    native: bool
    library: object = None  # kept alive: the machine code lives as long as its library


_NATIVE_LOCK = threading.Lock()


def _ctypes_caller(address: int, nargs: int) -> Callable:
    proto = ctypes.CFUNCTYPE(None, *([ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64] * nargs))(address)

    def call(*arrays):
        flat = []
        for a in arrays:
            if not (a.dtype == float and a.flags.c_contiguous):
                raise TypeError("a generated native function takes C-contiguous float64 arrays")
            flat += [a.ctypes.data, a.size, a.shape[-1]]
        proto(*flat)
        return 0

    call.prototype = proto  # the ctypes object must outlive the calls
    return call


def native_functions(key: str, sources: Callable[[], dict[str, str]], prefix: str = "dynid_native") -> NativeFunctions:
    """The straight-line functions of `sources()` (name -> scalar_source text: numba_backend's generated
    language) compiled from their LLVM IR (llvm_code.function_ir) by Numba's code generator into one library,
    kept on disk as object code (cache.load_entry: `cache_dir()/numba/<prefix>_<key>.lib`, pickled with the key
    and the codegen's CPU signature: a library made for another CPU is built again); key: a hash of everything
    the sources depend on. No Numba typing at all: a caller compiled once (llvm_code.address_call) takes the
    addresses at run time. Without numba, the functions of a module (load_module) run as plain Python."""
    name = f"{prefix}_{key}"
    with _NATIVE_LOCK:  # one build per process (Numba's code generator runs one at a time anyway)
        if not have_numba():
            _warn_missing()

            def text() -> str:
                texts = sources()
                return HEADER + "\n".join(texts.values()) + f"\nNAMES = {tuple(texts)!r}\n"

            mod = load_module("numba", name, key, text)
            assert mod is not None
            funcs = {n: getattr(mod, n) for n in mod.NAMES}
            return NativeFunctions({n: id(f) for n, f in funcs.items()}, funcs, False)

        def read(path: Path) -> NativeFunctions | None:
            stored = pickle.loads(path.read_bytes())  # our own cache, its key checked
            if stored["key"] != key:
                return None
            lib = load_library(stored["state"])
            return None if lib is None else _native(lib, stored["symbols"])

        def build() -> tuple[bytes, NativeFunctions]:
            texts = sources()
            symbols = {n: (f"{name}.{n}", len(parse_function(src).args.args)) for n, src in texts.items()}
            lib = native_library(name, [function_ir(src, symbols[n][0]) for n, src in texts.items()])
            return pickle.dumps({"key": key, "symbols": symbols, "state": library_state(lib)}), _native(lib, symbols)

        out = load_entry(module_path("numba", name).with_suffix(".lib"), name, read, build)
        assert out is not None
        return out


def _native(lib, symbols: dict[str, tuple[str, int]]) -> NativeFunctions:
    """The NativeFunctions of a code library: symbols, name -> (its symbol, its number of arrays)."""
    address = {n: lib.get_pointer_to_function(sym) for n, (sym, _) in symbols.items()}
    return NativeFunctions(address, {n: _ctypes_caller(address[n], nargs) for n, (_, nargs) in symbols.items()},
                           True, lib)


def source_key(*parts: str) -> str:
    """A short hash of the given texts and of this generator's source (see cache.generator_fingerprint)."""
    h = hashlib.sha256(("\0".join((BACKEND_VERSION, generator_fingerprint(), *parts))).encode())
    return h.hexdigest()[:20]


def numba_model(tree: Tree, model: str, name: str | None = None, **options):
    """The compiled per-sample function of a model (dgm, idm, regressor, inertia) of a tree.

    options: those of dynid.symbolic.build (parameters="numeric" bakes the tree's values in,
    wrenches=[WrenchSite, ...], rows/cols for the regressor). Returns the function; its
    argument list is `arguments(build(...))` (see the module doc).
    """

    name = name or model
    key = source_key(model_hash(tree, model, options), name)
    mod = compile_source(None, [], key, prefix=f"dynid_nb_{model}")
    if mod is None:
        mod = compile_source(scalar_source(build(tree, model, **options), name), [name], key,
                             prefix=f"dynid_nb_{model}")
    return getattr(mod, name)


def cached_module_path(key: str, prefix: str = "dynid_nb") -> Path:
    return module_path("numba", f"{prefix}_{key}")


__all__ = ["BACKEND_VERSION", "NativeFunctions", "NumbaMissingWarning", "arguments", "compile_source", "have_numba",
           "jit", "native_functions", "numba_model", "scalar_source", "source_key"]
