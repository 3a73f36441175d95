"""LLVM IR for the generated straight-line functions, so that Numba compiles them in a fraction of the time.

Why: Numba types and lowers every Python statement through its generic machinery, about 1 to 3 ms
of CPU per operation. The simulator's generated models (numba_backend.scalar_source) have 2,000 to
4,000 operations each, which made them most of a new vehicle's first run (measured on the compact
SUV: car_kin 2.5 s, car_idm 3.4 s, car_inertia 5.5 s of CPU; three times as much on the
Peugeot 406, whose models are larger). Their source is a tiny language:

    x = <expr>                 expr: names, numbers, + - * (binary), unary -, _sin, _cos, _sign,
    out[k] = <expr>                  reads a[i] and a[i, j] of the array arguments
    out[:] = 0.0
    return 0

with _sin and _cos dynamics.trig's sine and cosine (numba_backend.HEADER defines them from its python_source).
`function_ir` translates it into LLVM IR, operation by operation in Python's evaluation order, with
no fast-math flags and Numba's own forms (unary minus as -0.0 - x), sine and cosine of one angle together as
the steps of trig.STEPS (`Emitter.sincos`, which the vector kernels share): the same IEEE operations in the same
order as Numba's compile of that source, hence the same numbers, on any CPU (no contraction into FMA).
LLVM builds that IR in well under a second. `straight_line(fn, symbol)` returns the Numba intrinsic that calls
it, taking the function's array arguments as one tuple; anything outside the language raises
`UnsupportedSourceError` (numba_backend then compiles the Python function as before).

`Emitter` is the walk of that language which this scalar back-end and the vector one (blocks) share; `call_ir`
and `lazy_text` their link into Numba. The IR is written as text, not with llvmlite's IR builder
(`llvmlite.ir`): the builder makes a Python object per instruction and then prints the same text, which
LLVM parses just the same; measured on the simulator's three models (car_kin, car_idm, car_inertia: 685 to
1,709 statements), it took 69, 112 and 186 ms to build them against 21, 40 and 29 ms for the text, for the
same 0.14 to 0.46 s of LLVM parsing, optimisation and code generation (best of 7, a loaded 2-core machine).
`python benchmarks/bench_llvm_ir.py` measures it again (builder 1.9-3.2x the text's build, 29 Nov, and the same
functions to the bit).
"""

from __future__ import annotations

import ast
import functools
import inspect
import math
import struct
import textwrap
import threading
from abc import ABC, abstractmethod
from collections.abc import Callable

from ..dynamics import trig
from ..pysource import parse

_BINARY = {ast.Add: "fadd", ast.Sub: "fsub", ast.Mult: "fmul"}
_DECLARATIONS = ("declare double @llvm.sin.f64(double)", "declare double @llvm.cos.f64(double)",
                 "declare double @llvm.fabs.f64(double)", "declare void @llvm.memset.p0.i64(ptr, i8, i64, i1)")


class UnsupportedSourceError(ValueError):
    """The source is not a straight-line function of the generated language (see the module doc)."""


def _double(x: float) -> str:
    """An exact LLVM double constant (the bits in hex: no decimal round trip)."""
    return f"0x{struct.unpack('<Q', struct.pack('<d', x))[0]:016X}"


class Emitter(ABC):
    """The walk of the generated language that the scalar back-end (here) and the vector one (blocks) share:
    one SSA value %vN per Python name and temporary, operations in Python's evaluation order. A back-end sets
    the value type T and its comparison mask M, and says how a constant is written (`const`), an array element
    read (`load`) and assigned (`assign_element`), how the function returns, how negation and tanh are computed,
    and for sine and cosine (`sincos`, dynamics.trig's steps) whether every lane is in range (`all_true`) and
    libm's values of the lanes that are not (`libm`)."""

    T = "double"  # the value type
    M = "i1"  # its comparison mask
    I = "i64"  # its integer counterpart (the quadrant)
    S = "f64"  # its intrinsics' suffix (llvm.fabs.f64)

    def __init__(self, args: list[str]) -> None:
        self.args = args
        self.env: dict[str, str] = {}
        self.lines: list[str] = []
        self.count = 0
        self.block = "entry"  # the basic block being emitted (sincos branches)
        self.pairs: dict[str, tuple[str, str]] = {}  # argument's value -> (sin, cos): computed together

    def _new(self, text: str) -> str:
        self.count += 1
        name = f"%v{self.count}"
        self.lines.append(f"  {name} = {text}")
        return name

    # -- what a back-end says
    @abstractmethod
    def const(self, x: float) -> str:
        ...

    @abstractmethod
    def load(self, node: ast.Subscript) -> str:
        ...

    @abstractmethod
    def assign_element(self, target: ast.Subscript, value: ast.expr) -> None:
        ...

    @abstractmethod
    def ret(self) -> None:
        ...

    def neg(self, x: str) -> str:
        return self._new(f"fneg {self.T} {x}")

    def iconst(self, n: int) -> str:
        """An integer constant of type I."""
        return str(n)

    def all_true(self, mask: str) -> str:
        """An i1: every lane of the mask is true."""
        return mask

    def libm(self, x: str, ok: str, s: str, c: str) -> tuple[str, str]:
        """(sin, cos): libm's of x where ok is false, s and c elsewhere (emitted only when a lane is out of range)."""
        return (self._new(f"call double @llvm.sin.f64(double {x})"),
                self._new(f"call double @llvm.cos.f64(double {x})"))

    def tanh(self, x: str) -> str:
        raise UnsupportedSourceError("math.tanh")

    # -- shared
    def trig(self, kind: str, x: str) -> str:
        """_sin or _cos (kind) of the value x; its sine and cosine computed together."""
        if x not in self.pairs:
            self.pairs[x] = self.sincos(x)
        return self.pairs[x][0 if kind == "sin" else 1]

    def sincos(self, x: str) -> tuple[str, str]:
        """(sin x, cos x): one instruction per step of dynamics.trig.STEPS, the quadrant by selects (trig.QUADRANT's
        picks and signs: exact); an x out of range (|x| >= trig.LIMIT or NaN) from libm, in a branch taken only
        then (the steps run on 0 instead: k * PIO2_1 would not be exact, fptosi of a huge k poison)."""
        T, M, I, c = self.T, self.M, self.I, self.const
        ax = self._new(f"call {T} @llvm.fabs.{self.S}({T} {x})")
        ok = self._new(f"fcmp olt {T} {ax}, {c(trig.LIMIT)}")
        val = {"x": self._new(f"select {M} {ok}, {T} {x}, {T} {c(0.0)}")}
        for name, op, a, b in trig.STEPS:
            val[name] = self._new(f"f{op} {T} {val[a] if a in val else c(trig.CONSTANTS[a])}, "
                                  f"{val[b] if b in val else c(trig.CONSTANTS[b])}")
        k, sn, cs = val["k"], val["sn"], val["cs"]
        quad = self._new(f"and {I} {self._new(f'fptosi {T} {k} to {I}')}, {self.iconst(3)}")

        def bit(v: str, b: int) -> str:
            return self._new(f"icmp ne {I} {self._new(f'and {I} {v}, {self.iconst(b)}')}, {self.iconst(0)}")

        odd = bit(quad, 1)  # quadrants 1 and 3: sin from cs, cos from sn
        a = self._new(f"select {M} {odd}, {T} {cs}, {T} {sn}")
        b = self._new(f"select {M} {odd}, {T} {sn}, {T} {cs}")
        s = self._new(f"select {M} {bit(quad, 2)}, {T} {self._new(f'fneg {T} {a}')}, {T} {a}")  # 2, 3: -sin
        plus1 = self._new(f"add {I} {quad}, {self.iconst(1)}")
        co = self._new(f"select {M} {bit(plus1, 2)}, {T} {self._new(f'fneg {T} {b}')}, {T} {b}")  # 1, 2: -cos
        allok = self.all_true(ok)
        n, here = self.count, self.block
        self.lines += [f"  br i1 {allok}, label %trig_done{n}, label %trig_slow{n}", f"trig_slow{n}:"]
        vs, vc = self.libm(x, ok, s, co)
        self.lines += [f"  br label %trig_done{n}", f"trig_done{n}:"]
        self.block = f"trig_done{n}"
        return (self._new(f"phi {T} [{s}, %{here}], [{vs}, %trig_slow{n}]"),
                self._new(f"phi {T} [{co}, %{here}], [{vc}, %trig_slow{n}]"))

    @staticmethod
    def index(node: ast.Subscript) -> list[int]:
        """The constant non-negative indices of a subscript."""
        idx = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
        if not all(isinstance(i, ast.Constant) and type(i.value) is int and i.value >= 0 for i in idx):
            raise UnsupportedSourceError(f"index {ast.unparse(node.slice)}: constant non-negative integers only")
        return [i.value for i in idx]

    def sign(self, x: str) -> str:
        """1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0), by selects."""
        T, M, c = self.T, self.M, self.const
        pos, neg = self._new(f"fcmp ogt {T} {x}, {c(0.0)}"), self._new(f"fcmp olt {T} {x}, {c(0.0)}")
        low = self._new(f"select {M} {neg}, {T} {c(-1.0)}, {T} {c(0.0)}")
        return self._new(f"select {M} {pos}, {T} {c(1.0)}, {T} {low}")

    def expr(self, node: ast.expr) -> str:
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            if isinstance(node.value, int) and abs(node.value) > 2**53:
                raise UnsupportedSourceError(f"integer {node.value} not exact as a double")
            return self.const(float(node.value))
        if isinstance(node, ast.Name):
            if node.id not in self.env:
                raise UnsupportedSourceError(f"name {node.id} read before assignment (or an array used as a number)")
            return self.env[node.id]
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            a, b = self.expr(node.left), self.expr(node.right)  # Python's order (pure operations anyway)
            return self._new(f"{_BINARY[type(node.op)]} {self.T} {a}, {b}")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return self.neg(self.expr(node.operand))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.UAdd):
            return self.expr(node.operand)
        if isinstance(node, ast.Subscript):
            return self.load(node)
        if isinstance(node, ast.Call) and len(node.args) == 1 and not node.keywords:
            f = node.func
            if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and (f.value.id, f.attr) == (
                    "math", "tanh"):
                return self.tanh(self.expr(node.args[0]))
            if isinstance(f, ast.Name) and f.id == "_sign":
                return self.sign(self.expr(node.args[0]))
            if isinstance(f, ast.Name) and f.id in ("_sin", "_cos"):
                return self.trig(f.id[1:], self.expr(node.args[0]))
        raise UnsupportedSourceError(f"expression {ast.unparse(node)}")

    def statement(self, node: ast.stmt) -> bool:
        """Emit one statement; False after the return."""
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            return True  # the docstring
        if isinstance(node, ast.Return):
            if not (isinstance(node.value, ast.Constant) and node.value.value == 0):
                raise UnsupportedSourceError("return: only `return 0`")
            self.ret()
            return False
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1):
            raise UnsupportedSourceError(f"statement {ast.unparse(node)}")
        target = node.targets[0]
        if isinstance(target, ast.Name):
            if target.id in self.args:
                raise UnsupportedSourceError(f"assignment to the argument {target.id}")
            self.env[target.id] = self.expr(node.value)
            return True
        if not isinstance(target, ast.Subscript):
            raise UnsupportedSourceError(f"statement {ast.unparse(node)}")
        self.assign_element(target, node.value)
        return True


class _ScalarEmitter(Emitter):
    """One sample's function: doubles, array elements through pointers (Numba's forms)."""

    def const(self, x: float) -> str:
        return "0.0" if x == 0.0 and math.copysign(1.0, x) > 0 else _double(x)

    def neg(self, x: str) -> str:
        return self._new(f"fsub double -0.0, {x}")  # Numba's negation

    def sincos(self, x: str) -> tuple[str, str]:
        """A call of the module's one copy of Emitter.sincos (_SINCOS)."""
        pair = self._new(f"call {{double, double}} @dynid_sincos(double {x})")
        return (self._new(f"extractvalue {{double, double}} {pair}, 0"),
                self._new(f"extractvalue {{double, double}} {pair}, 1"))

    def ret(self) -> None:
        self.lines.append("  ret void")

    def _address(self, node: ast.Subscript) -> str:
        """Pointer to the element `a[i]` or `a[i, j]` of an array argument (C order: i * ncols + j)."""
        if not (isinstance(node.value, ast.Name) and node.value.id in self.args):
            raise UnsupportedSourceError(f"subscript of {ast.unparse(node.value)}: only array arguments are indexed")
        arr = node.value.id
        idx = self.index(node)
        if len(idx) == 1:
            flat = str(idx[0])
        elif len(idx) == 2:
            row = self._new(f"mul i64 {idx[0]}, %c_{arr}")
            flat = self._new(f"add i64 {row}, {idx[1]}")
        else:
            raise UnsupportedSourceError(f"index {ast.unparse(node.slice)}: one or two dimensions only")
        return self._new(f"getelementptr inbounds double, ptr %a_{arr}, i64 {flat}")

    def load(self, node: ast.Subscript) -> str:
        return self._new(f"load double, ptr {self._address(node)}")

    def assign_element(self, target: ast.Subscript, value: ast.expr) -> None:
        s = target.slice
        if isinstance(s, ast.Slice) and s.lower is s.upper is s.step is None:  # out[:] = 0.0: every element
            arr = target.value.id if isinstance(target.value, ast.Name) else ""
            if not (arr in self.args and isinstance(value, ast.Constant)
                    and type(value.value) in (int, float) and math.copysign(1.0, value.value) > 0
                    and value.value == 0):
                raise UnsupportedSourceError(f"{ast.unparse(target)} = {ast.unparse(value)}: a whole-array store of "
                                             "+0.0 only")
            size = self._new(f"mul i64 %n_{arr}, 8")
            self.lines.append(f"  call void @llvm.memset.p0.i64(ptr %a_{arr}, i8 0, i64 {size}, i1 false)")
            return
        v = self.expr(value)
        self.lines.append(f"  store double {v}, ptr {self._address(target)}")


def parse_function(source: str) -> ast.FunctionDef:
    tree = parse(textwrap.dedent(source))
    if len(tree.body) != 1 or not isinstance(tree.body[0], ast.FunctionDef):
        raise UnsupportedSourceError("the source of exactly one function is expected")
    fn = tree.body[0]
    a = fn.args
    if a.vararg or a.kwarg or a.kwonlyargs or a.posonlyargs or a.defaults or fn.decorator_list:
        raise UnsupportedSourceError(f"{fn.name}: plain positional arguments only, no decorators")
    return fn


@functools.cache
def _sincos_function() -> tuple[str, ...]:
    """`{double, double} @dynid_sincos(double %x)`: Emitter.sincos, internal to each module that calls it, not
    inlined: its ~50 instructions and a branch at each of a car model's 19 to 23 angles made LLVM's first compile
    of the simulator's models half as long again (0.96 to 1.47 s of CPU, the compact SUV), and the call costs
    less than the two to libm it replaces."""
    em = _ScalarEmitter([])
    s, c = Emitter.sincos(em, "%x")
    pair = em._new(f"insertvalue {{double, double}} poison, double {s}, 0")
    pair = em._new(f"insertvalue {{double, double}} {pair}, double {c}, 1")
    return ("define internal {double, double} @dynid_sincos(double %x) noinline nounwind {", "entry:", *em.lines,
            f"  ret {{double, double}} {pair}", "}")


def function_ir(source: str, symbol: str) -> str:
    """LLVM IR (a module) defining `void @symbol(ptr a, i64 n, i64 c, ...)`: per array argument of the
    function in `source`, its data, its number of elements and its last dimension (C order)."""
    fn = parse_function(source)
    args = [a.arg for a in fn.args.args]
    em = _ScalarEmitter(args)
    for st in fn.body:
        if not em.statement(st):
            break
    else:
        raise UnsupportedSourceError(f"{fn.name}: no `return 0`")
    params = ", ".join(f"ptr %a_{a}, i64 %n_{a}, i64 %c_{a}" for a in args)
    # weak_odr: each library that compiles a call carries a copy, one of which is kept (the symbol is unique per
    # generated module, see numba_backend); not linkonce_odr, which LLVM's linker drops when the caller's module
    # is linked after it; nounwind: no exception leaves it
    return "\n".join([f'define weak_odr void @"{symbol}"({params}) nounwind {{', "entry:", *em.lines, "}",
                      *(_sincos_function() if em.pairs else ()), *_DECLARATIONS]) + "\n"


def lazy_text(build: Callable[[], str]) -> Callable[[], str]:
    """build(), run once at the first call (a generated module's IR is built when Numba first compiles a caller,
    never when a cached caller is loaded), under a lock (two threads may compile callers at once)."""
    texts: list[str] = []
    lock = threading.Lock()

    def text() -> str:
        with lock:
            if not texts:
                texts.append(build())
        return texts[0]

    return text


def call_ir(context, builder, text: str, symbol: str, values: list) -> None:
    """In a Numba intrinsic's codegen: link the IR module `text` into the library being compiled and call its
    `void @symbol(values...)` (parsed again for each caller: a linked module is consumed)."""
    # start-up: numba 0.5 s
    import llvmlite.binding as ll
    from llvmlite import ir
    from numba.core import cgutils

    module = ll.parse_assembly(text)
    module.verify()  # a malformed module would abort the process inside LLVM's passes
    context.active_code_library.add_llvm_module(module)
    fnty = ir.FunctionType(ir.VoidType(), [v.type for v in values])
    builder.call(cgutils.get_or_insert_function(builder.module, fnty, symbol), values)


def straight_line(fn: Callable, symbol: str):
    """A Numba intrinsic `call(arrays)` running `fn`'s source compiled from LLVM IR (see the module doc):
    arrays is the tuple of fn's arguments (C-contiguous float64 arrays); returns 0, as fn does.
    The IR is built when Numba first compiles a call (not when a cached caller is loaded); a source
    outside the language raises UnsupportedSourceError then (numba_backend checks it before choosing this path)."""
    # start-up: numba 0.5 s
    from numba.core import types
    from numba.core.errors import TypingError
    from numba.extending import intrinsic

    nargs = fn.__code__.co_argcount
    ir_text = lazy_text(lambda: function_ir(inspect.getsource(fn), symbol))

    @intrinsic
    def call(typingctx, arrays):
        if not (isinstance(arrays, types.BaseTuple) and len(arrays) == nargs and all(
                isinstance(t, types.Array) and t.dtype == types.float64 and t.layout == "C" for t in arrays)):
            raise TypingError(f"{symbol}: expects a tuple of {nargs} C-contiguous float64 arrays, got {arrays}")

        def codegen(context, builder, sig, llargs):
            values = array_arguments(context, builder, sig.args[0], llargs[0])
            call_ir(context, builder, ir_text(), symbol, values)
            return context.get_constant(types.int64, 0)

        return types.int64(arrays), codegen

    return call


def array_arguments(context, builder, tuple_type, packed) -> list:
    """The LLVM values function_ir's convention passes for a tuple of arrays (inside a Numba intrinsic's
    codegen): each array's data pointer, number of elements and last dimension."""
    # start-up: numba 0.5 s (called only while Numba compiles, when it is loaded)
    from numba.core import cgutils

    values = []
    for k, aty in enumerate(tuple_type):
        ary = context.make_array(aty)(context, builder, builder.extract_value(packed, k))
        shape = cgutils.unpack_tuple(builder, ary.shape, aty.ndim)
        values += [ary.data, ary.nitems, shape[-1]]
    return values


@functools.cache
def address_call():
    """A Numba intrinsic `call(address, arrays)`: calls the native `void f(ptr, i64, i64, ...)` at `address` (an
    integer: `native_functions` gives them) with each array's data, number of elements and last dimension
    (function_ir's convention); returns 0. The function is a run-time argument, not a compile-time one, so a
    caller compiled once serves every vehicle's generated models (the simulator's kernel: issue 28)."""
    # start-up: numba 0.5 s
    from llvmlite import ir
    from numba.core import types
    from numba.core.errors import TypingError
    from numba.extending import intrinsic

    @intrinsic
    def call(typingctx, address, arrays):
        if not (isinstance(address, types.Integer) and isinstance(arrays, types.BaseTuple) and all(
                isinstance(t, types.Array) and t.dtype == types.float64 and t.layout == "C" for t in arrays)):
            raise TypingError(f"address_call: expects an integer address and a tuple of C-contiguous float64 "
                              f"arrays, got {address}, {arrays}")

        def codegen(context, builder, sig, llargs):
            values = array_arguments(context, builder, sig.args[1], llargs[1])
            fnty = ir.FunctionType(ir.VoidType(), [v.type for v in values])
            builder.call(builder.inttoptr(llargs[0], fnty.as_pointer()), values)
            return context.get_constant(types.int64, 0)

        return types.int64(address, arrays), codegen

    return call


def native_library(name: str, texts: list[str]):
    """Numba's code library `name` built from the IR modules `texts` (function_ir's), optimised and compiled to
    machine code by Numba's own code generator (its passes, target machine and JIT: the code Numba makes of
    the same IR when a caller links it), with object caching on (`serialize_using_object_code`)."""
    # start-up: numba 0.5 s
    import llvmlite.binding as ll
    from numba.core.compiler_lock import global_compiler_lock
    from numba.core.registry import cpu_target

    with global_compiler_lock:  # Numba's codegen is not reentrant: its own compiles hold the same lock
        lib = cpu_target.target_context.codegen().create_library(name)
        lib.enable_object_caching()
        for text in texts:
            module = ll.parse_assembly(text)
            module.verify()  # a malformed module would abort the process inside LLVM's passes
            lib.add_llvm_module(module)
        lib.finalize()
    return lib


def library_state(lib) -> tuple:
    """What `load_library` needs to load `lib` again without LLVM (its object code), and the codegen it fits."""
    # start-up: numba 0.5 s
    from numba.core.registry import cpu_target

    return cpu_target.target_context.codegen().magic_tuple(), lib.serialize_using_object_code()


def load_library(state: tuple):
    """The code library of `library_state`, or None when it was made for another CPU or code generator."""
    # start-up: numba 0.5 s
    from numba.core.compiler_lock import global_compiler_lock
    from numba.core.registry import cpu_target

    codegen = cpu_target.target_context.codegen()
    magic, serialized = state
    if magic != codegen.magic_tuple():
        return None
    with global_compiler_lock:
        return codegen.unserialize_library(serialized)


__all__ = ["Emitter", "UnsupportedSourceError", "address_call", "call_ir", "function_ir", "lazy_text", "library_state",
           "load_library", "native_library", "parse_function", "straight_line"]
