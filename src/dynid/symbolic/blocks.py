"""Generated kernels that evaluate LANES samples side by side, from vector LLVM IR compiled through Numba.

Why: the per-sample code (numba_backend, C) runs one sample's straight line with scalar
instructions; the NumPy code streams each operation over thousands of
samples through memory. Here each of the model's intermediate variables is a vector of LANES
samples held in registers, every operation one vector instruction, so the arithmetic runs at
the vector units' width with no trip through memory (issue 16).

`block_ir(source, symbol, lanes, shared)` translates a per-sample function of
`numba_backend.scalar_source` (the language of `llvm_code`) into a function

    void symbol(i64 N, ptr desc)     desc: int64 per argument [data address, strides in bytes]

looping over the N samples LANES at a time: each input read by one gather of its lanes, with
any strides (a column of q, a Fortran-ordered or sliced array), the block after next
prefetched; outputs stored as vectors into entry-major (size, N) buffers, whose rows no
equation writes are left alone (zero). When a buffer's address and row stride are multiples
of 64 bytes (`aligned_zeros`), each store is one whole cache line, written non-temporally
(no read for ownership: the PUMA regressor at N = 20 000 went from 0.25 to 0.07 us per
sample); otherwise, and for a last partial block (whose missing lanes repeat its last
sample), the block goes through a zeroed (size, LANES) scratch whose valid lanes are then
copied. Arithmetic is the source's, operation by
operation, with no fast-math flag (no contraction into FMA, no reassociation), so that the
numbers do not depend on the CPU's instruction set: they are the per-sample code's, sine and
cosine included (dynamics.trig's steps, llvm_code.Emitter.sincos, in vector form: the generated
NumPy's and C's to the bit, within an ulp of libm); a lane whose angle is 1e5 or more, or NaN,
takes libm's values.

`block_model(tree, model, **options)` generates, caches on disk (the source beside Numba's
machine code, numba_backend.compile_source) and returns a `BlockKernel`.
"""

from __future__ import annotations

import ast
import inspect
import threading
from collections.abc import Callable, Sequence

import numpy as np

from ..model.tree import Tree
from .cache import model_hash
from .llvm_code import Emitter, UnsupportedSourceError, _double, call_ir, lazy_text, parse_function
from .models import build
from .numba_backend import arguments, compile_source, scalar_source, source_key

LANES = 8  # samples per vector: a cache line per store (non-temporal); 4 and 16 measured slower on both models
# one generation (and one parse of a generated source) at a time: CPython 3.11's ast.parse is not safe
# from two threads at once (SystemError "AST constructor recursion depth mismatch"), and the car
# pipeline's two threads ask for the same kernel at their first segment
_GENERATION_LOCK = threading.RLock()
_PREFETCHES = 48  # per input array and block: its rows' cache lines (8 rows of 42 doubles: 42 lines)
_SLOTS = 4  # int64 per argument in the descriptor: address, then up to three strides (bytes)

class _VectorEmitter(Emitter):
    """One block's instructions: every Python name of the source is a <L x double> SSA value."""

    def __init__(self, args: list[str], outputs: set[str], shared: set[str], lanes: int) -> None:
        super().__init__(args)
        self.outputs, self.shared, self.L = outputs, shared, lanes
        self.V = self.T = f"<{lanes} x double>"
        self.M = f"<{lanes} x i1>"
        self.I = f"<{lanes} x i64>"
        self.S = f"v{lanes}f64"

    def const(self, x: float) -> str:
        if x == 0.0 and str(x)[0] != "-":
            return "zeroinitializer"
        d = _double(float(x))
        return "<" + ", ".join([f"double {d}"] * self.L) + ">"

    def _splat(self, scalar: str) -> str:
        one = self._new(f"insertelement {self.V} poison, double {scalar}, i64 0")
        return self._new(f"shufflevector {self.V} {one}, {self.V} poison, <{self.L} x i32> zeroinitializer")

    # -- memory
    def _offset(self, arr: str, idx: list[int]) -> str:
        """Bytes from the sample's start to element idx of a (per-sample) array: sum idx[d] * stride d."""
        if len(idx) > _SLOTS - 2:
            raise UnsupportedSourceError(f"{arr}: at most {_SLOTS - 2} indices")
        total = "0"
        for d, i in enumerate(idx):
            if i:
                term = self._new(f"mul i64 {i}, %s{d + 1}_{arr}")
                total = term if total == "0" else self._new(f"add i64 {total}, {term}")
        return total

    def load(self, node: ast.Subscript) -> str:
        arr = node.value.id if isinstance(node.value, ast.Name) else ""
        if arr not in self.args or arr in self.outputs:
            raise UnsupportedSourceError(f"read of {ast.unparse(node)}: only input arrays are read")
        off = self._offset(arr, self.index(node))
        if arr in self.shared:  # the same for every sample: one load, broadcast
            ptr = self._new(f"getelementptr inbounds i8, ptr %p_{arr}, i64 {off}")
            return self._splat(self._new(f"load double, ptr {ptr}, align 8"))
        # one gather of the lanes' elements (a vgatherqpd with AVX2 or AVX-512, scalar loads on SSE2)
        L = self.L
        at = self._new(f"add <{L} x i64> %rows_{arr}, {self._splat_i64(off)}")
        ptrs = self._new(f"getelementptr inbounds i8, ptr %p_{arr}, <{L} x i64> {at}")
        true = "<" + ", ".join(["i1 true"] * L) + ">"
        return self._new(f"call {self.V} @llvm.masked.gather.v{L}f64.v{L}p0(<{L} x ptr> {ptrs}, i32 8, "
                         f"<{L} x i1> {true}, {self.V} poison)")

    def _splat_i64(self, x: str) -> str:
        if x == "0":
            return "zeroinitializer"
        one = self._new(f"insertelement <{self.L} x i64> poison, i64 {x}, i64 0")
        return self._new(f"shufflevector <{self.L} x i64> {one}, <{self.L} x i64> poison, "
                         f"<{self.L} x i32> zeroinitializer")

    def store(self, arr: str, k: int, value: str) -> None:
        at = self._new(f"mul i64 {k}, %rs_{arr}")
        ptr = self._new(f"getelementptr inbounds i8, ptr %ob_{arr}, i64 {at}")
        # a full cache line per store (LANES = 8) that nothing reads soon: non-temporal (no read for ownership)
        self.lines.append(f"  store {self.V} {value}, ptr {ptr}, align {8 * self.L}, !nontemporal !0")

    # -- arithmetic
    def _op(self, op: str, a: str, b: str) -> str:
        return self._new(f"{op} {self.V} {a}, {b}")

    def tanh(self, x: str) -> str:
        """Smooth friction laws: rare, libm lane by lane (the engine's numbers)."""
        v = f"{self.V} poison"
        for lane in range(self.L):
            xl = self._new(f"extractelement {self.V} {x}, i64 {lane}")
            t = self._new(f"call double @tanh(double {xl})")
            v = f"{self.V} " + self._new(f"insertelement {v}, double {t}, i64 {lane}")
        return v.split(" ")[-1]

    def iconst(self, n: int) -> str:
        return "zeroinitializer" if n == 0 else "<" + ", ".join([f"i64 {n}"] * self.L) + ">"

    def all_true(self, mask: str) -> str:
        return self._new(f"icmp eq i{self.L} {self._new(f'bitcast {self.M} {mask} to i{self.L}')}, -1")

    def libm(self, x: str, ok: str, s: str, c: str) -> tuple[str, str]:
        """libm lane by lane where ok is false (a branch taken only when some lane is)."""
        V = self.V
        vs, vc = s, c
        for lane in range(self.L):
            xl = self._new(f"extractelement {V} {x}, i64 {lane}")
            okl = self._new(f"extractelement {self.M} {ok}, i64 {lane}")
            sl = self._new(f"call double @llvm.sin.f64(double {xl})")
            cl = self._new(f"call double @llvm.cos.f64(double {xl})")
            sl = self._new(f"select i1 {okl}, double {self._new(f'extractelement {V} {s}, i64 {lane}')}, double {sl}")
            cl = self._new(f"select i1 {okl}, double {self._new(f'extractelement {V} {c}, i64 {lane}')}, double {cl}")
            vs = self._new(f"insertelement {V} {vs}, double {sl}, i64 {lane}")
            vc = self._new(f"insertelement {V} {vc}, double {cl}, i64 {lane}")
        return vs, vc

    # -- statements
    def ret(self) -> None:
        pass  # the loop's latch follows the block's statements

    def assign_element(self, target: ast.Subscript, value: ast.expr) -> None:
        if not (isinstance(target.value, ast.Name) and target.value.id in self.outputs):
            raise UnsupportedSourceError(f"statement {ast.unparse(target)} = {ast.unparse(value)}")
        if isinstance(value, ast.Constant) and type(value.value) in (int, float) and value.value == 0:
            return  # zeros: the output buffers' rows are zero already (and so is the scratch)
        sl = target.slice
        if not (isinstance(sl, ast.Constant) and type(sl.value) is int and sl.value >= 0):
            raise UnsupportedSourceError(f"statement {ast.unparse(target)} = ...: a store to out[k] (flat) only")
        self.store(target.value.id, sl.value, self.expr(value))


def block_ir(source: str, symbol: str, lanes: int = LANES, shared: Sequence[str] = ("X",)) -> str:
    """LLVM IR (a module) defining `void @symbol(i64 N, ptr desc)` for the per-sample function in `source`
    (see the module doc). desc holds _SLOTS int64 per argument of the function, in order: for an input,
    its address, its sample stride (ignored for `shared` arrays) and the strides of its indices, in bytes;
    for an output (an array the function assigns to), the address of its (size, N) buffer, its row stride,
    and the address of a zeroed (size, lanes) scratch used by the last block when N % lanes != 0."""
    fn = parse_function(source)
    args = [a.arg for a in fn.args.args]
    outputs = {t.value.id for st in fn.body if isinstance(st, ast.Assign) for t in st.targets
               if isinstance(t, ast.Subscript) and isinstance(t.value, ast.Name)}
    em = _VectorEmitter(args, outputs, set(shared) & set(args), lanes)
    em.block = "compute"
    # prefetches of the block after next, spread over the block's statements (issued in one burst, most
    # were dropped: the core tracks a few dozen misses at a time)
    ins = [a for a in args if a not in outputs and a not in em.shared]
    total = _PREFETCHES * len(ins)
    due = [(i * len(fn.body)) // max(total, 1) for i in range(total)]
    done = 0
    for t, st in enumerate(fn.body):
        if not em.statement(st):
            break
        while done < total and due[done] <= t:
            a, c = ins[done % len(ins)], done // len(ins)
            off = em._new(f"mul i64 {c}, %pfs_{a}")
            ptr = em._new(f"getelementptr i8, ptr %pfb_{a}, i64 {off}")
            em.lines.append(f"  call void @llvm.prefetch.p0(ptr {ptr}, i32 0, i32 3, i32 1)")
            done += 1
    else:
        raise UnsupportedSourceError(f"{fn.name}: no `return 0`")
    L = lanes
    head = ["entry:"]
    for a_i, a in enumerate(args):  # the descriptor
        for s in range(_SLOTS):
            head.append(f"  %d{s}_{a}.p = getelementptr inbounds i64, ptr %desc, i64 {a_i * _SLOTS + s}")
            head.append(f"  %d{s}_{a} = load i64, ptr %d{s}_{a}.p, align 8")
        head.append(f"  %p_{a} = inttoptr i64 %d0_{a} to ptr")
        if a in outputs:
            head.append(f"  %rs_{a}.full = add i64 %d1_{a}, 0")
            head.append(f"  %scr_{a} = inttoptr i64 %d2_{a} to ptr")
            head.append(f"  %size_{a} = add i64 %d3_{a}, 0")
        else:
            for s in range(1, _SLOTS - 1):
                head.append(f"  %s{s}_{a} = add i64 %d{s + 1}_{a}, 0")
    # the buffers' vector stores are aligned, non-temporal, full cache lines (LANES * 8 = 64 bytes) when every
    # output's address and row stride are multiples of 64; otherwise every block goes through the scratch
    aligned = "true"
    for a in args:
        if a in outputs:
            head += [f"  %al0_{a} = or i64 %d0_{a}, %d1_{a}", f"  %al1_{a} = and i64 %al0_{a}, {8 * L - 1}",
                     f"  %al_{a} = icmp eq i64 %al1_{a}, 0", f"  %all_{a} = and i1 {aligned}, %al_{a}"]
            aligned = f"%all_{a}"
    head += ["  %last = sub i64 %N, 1", "  %any = icmp sgt i64 %N, 0", "  br i1 %any, label %body, label %exit"]
    body = ["body:", "  %i0 = phi i64 [0, %entry], [%i1, %latch]", "  %rem = sub i64 %N, %i0",
            f"  %full = icmp sge i64 %rem, {L}", f"  %direct = and i1 %full, {aligned}",
            f"  %valid = select i1 %full, i64 {L}, i64 %rem"]
    for lane in range(L):  # lanes past the end repeat the last sample
        body += [f"  %r{lane} = add i64 %i0, {lane}", f"  %c{lane} = icmp sgt i64 %r{lane}, %last",
                 f"  %row{lane} = select i1 %c{lane}, i64 %last, i64 %r{lane}"]
    for a in args:
        if a in outputs:
            body += [f"  %o_{a}.at = mul i64 %i0, 8",
                     f"  %o_{a} = getelementptr inbounds i8, ptr %p_{a}, i64 %o_{a}.at",
                     f"  %ob_{a} = select i1 %direct, ptr %o_{a}, ptr %scr_{a}",
                     f"  %rs_{a} = select i1 %direct, i64 %rs_{a}.full, i64 {8 * L}"]
        elif a not in em.shared:
            body += [f"  %row{lane}_{a} = mul i64 %row{lane}, %d1_{a}" for lane in range(L)]
            prev = "poison"
            for lane in range(L):
                name = f"%rows{lane}_{a}" if lane < L - 1 else f"%rows_{a}"
                body.append(f"  {name} = insertelement <{L} x i64> {prev}, i64 %row{lane}_{a}, i64 {lane}")
                prev = name
    for a in ins:  # where the block after next starts, and the bytes between two of its prefetches
        body += [f"  %pfr0_{a} = add i64 %i0, {2 * L}", f"  %pfc_{a} = icmp sgt i64 %pfr0_{a}, %last",
                 f"  %pfr_{a} = select i1 %pfc_{a}, i64 %last, i64 %pfr0_{a}",
                 f"  %pfo_{a} = mul i64 %pfr_{a}, %d1_{a}",
                 f"  %pfb_{a} = getelementptr i8, ptr %p_{a}, i64 %pfo_{a}",
                 f"  %pfn0_{a} = mul i64 %d1_{a}, {L}", f"  %pfn1_{a} = icmp slt i64 %pfn0_{a}, 4096",
                 f"  %pfn_{a} = select i1 %pfn1_{a}, i64 %pfn0_{a}, i64 4096",
                 f"  %pfs_{a} = sdiv i64 %pfn_{a}, {_PREFETCHES}"]
    body += ["  br label %compute", "compute:"]
    end = ["  br i1 %direct, label %latch, label %tail", "latch:", f"  %i1 = add i64 %i0, {L}",
           "  %more = icmp slt i64 %i1, %N", "  br i1 %more, label %body, label %exit", "tail:"]
    for a in args:  # the valid lanes of the scratch to the buffer (all of its rows: the zero ones are zero)
        if a not in outputs:
            continue
        if a == _first(args, outputs):
            end.append(f"  br label %te_{a}")
        end += [f"te_{a}:",
                f"  %e_{a} = phi i64 [0, %{'tail' if a == _first(args, outputs) else 'tn_' + _prev(args, outputs, a)}]"
                f", [%e1_{a}, %tn_{a}]", f"  br label %tl_{a}", f"tl_{a}:",
                f"  %l_{a} = phi i64 [0, %te_{a}], [%l1_{a}, %tl_{a}]",
                f"  %src0_{a} = mul i64 %e_{a}, {L}", f"  %src1_{a} = add i64 %src0_{a}, %l_{a}",
                f"  %src_{a} = getelementptr inbounds double, ptr %scr_{a}, i64 %src1_{a}",
                f"  %x_{a} = load double, ptr %src_{a}, align 8",
                f"  %dst0_{a} = mul i64 %e_{a}, %rs_{a}.full", f"  %dst1_{a} = add i64 %i0, %l_{a}",
                f"  %dst2_{a} = mul i64 %dst1_{a}, 8", f"  %dst3_{a} = add i64 %dst0_{a}, %dst2_{a}",
                f"  %dst_{a} = getelementptr inbounds i8, ptr %p_{a}, i64 %dst3_{a}",
                f"  store double %x_{a}, ptr %dst_{a}, align 8",
                f"  %l1_{a} = add i64 %l_{a}, 1", f"  %lc_{a} = icmp slt i64 %l1_{a}, %valid",
                f"  br i1 %lc_{a}, label %tl_{a}, label %tn_{a}", f"tn_{a}:",
                f"  %e1_{a} = add i64 %e_{a}, 1", f"  %ec_{a} = icmp slt i64 %e1_{a}, %size_{a}",
                f"  br i1 %ec_{a}, label %te_{a}, label %{_next(args, outputs, a)}"]
    if not outputs:
        end.append("  br label %latch")
    end += ["exit:", "  ret void"]
    decl = [f"declare <{L} x double> @llvm.fabs.v{L}f64(<{L} x double>)", "declare double @llvm.sin.f64(double)",
            "declare void @llvm.prefetch.p0(ptr, i32, i32, i32)", "declare double @tanh(double)",
            f"declare <{L} x double> @llvm.masked.gather.v{L}f64.v{L}p0(<{L} x ptr>, i32, <{L} x i1>, <{L} x double>)",
            "declare double @llvm.cos.f64(double)"]
    # weak_odr and nounwind: see llvm_code.function_ir
    return "\n".join([f'define weak_odr void @"{symbol}"(i64 %N, ptr %desc) nounwind {{', *head, *body,
                      *em.lines, *end, "}", *decl, "!0 = !{i32 1}"]) + "\n"


def _first(args: list[str], outputs: set[str]) -> str:
    return next(a for a in args if a in outputs)


def _prev(args: list[str], outputs: set[str], a: str) -> str:
    outs = [x for x in args if x in outputs]
    return outs[outs.index(a) - 1]


def _next(args: list[str], outputs: set[str], a: str) -> str:
    outs = [x for x in args if x in outputs]
    i = outs.index(a)
    return f"te_{outs[i + 1]}" if i + 1 < len(outs) else "latch"


def block_intrinsic(fn: Callable, symbol: str, lanes: int = LANES, shared: Sequence[str] = ("X",)):
    """A Numba intrinsic `call(N, desc)` running `fn`'s source as block_ir (desc: a C-contiguous int64 array).
    The IR is built when Numba first compiles a caller (not when a cached one is loaded)."""
    # start-up: numba 0.5 s
    from numba.core import types
    from numba.core.errors import TypingError
    from numba.extending import intrinsic

    def build() -> str:
        with _GENERATION_LOCK:
            return block_ir(inspect.getsource(fn), symbol, lanes, shared)

    ir_text = lazy_text(build)

    @intrinsic
    def call(typingctx, n, desc):
        if not (isinstance(n, types.Integer) and isinstance(desc, types.Array) and desc.dtype == types.int64
                and desc.ndim == 1 and desc.layout == "C"):
            raise TypingError(f"{symbol}: expects (N, desc: 1-D C-contiguous int64 array), got ({n}, {desc})")

        def codegen(context, builder, sig, llargs):
            ary = context.make_array(sig.args[1])(context, builder, llargs[1])
            count = context.cast(builder, llargs[0], sig.args[0], types.int64)
            call_ir(context, builder, ir_text(), symbol, [count, ary.data])
            return context.get_constant(types.int64, 0)

        return types.int64(n, desc), codegen

    return call


# ----- the generated module and its caller -------------------------------------------------------------------
_FOOTER = '''

LANES = {lanes}
SYMBOL = {symbol!r}
try:
    from numba import njit as _njit

    from dynid.symbolic.blocks import block_intrinsic as _block_intrinsic
except ImportError:
    run = None
else:
    _run = _block_intrinsic({name}, SYMBOL, LANES)

    @_njit(cache=True, nogil=True)
    def run(N, desc):
        return _run(N, desc)
'''


def _data_address(a):
    return a.ctypes.data


_ADDRESS: list = []


def _address():
    """The address of an array's first element, jitted (a tenth of `a.ctypes.data`'s time: a block kernel's
    call reads five to ten of them)."""
    if not _ADDRESS:
        from numba import njit  # start-up: numba 0.5 s

        _ADDRESS.append(njit(cache=True, nogil=True)(_data_address))
    return _ADDRESS[0]


def aligned_zeros(size: int, N: int, align: int = 64) -> np.ndarray:
    """A zeroed (size, N) float64 array whose address and row stride are multiples of `align` bytes (rows
    padded), which the kernels need for their full-line stores (others work, through a scratch, slowly)."""
    ld = -(-max(N, 1) * 8 // align) * align // 8
    raw = np.zeros(size * ld + align // 8)
    start = (-raw.ctypes.data % align) // 8
    return raw[start:start + size * ld].reshape(size, ld)[:, :N]


class BlockKernel:
    """A generated model evaluated LANES samples side by side (see the module doc).

    `kernel(q, qd, qdd, X=None, wrench=None, out=None)` -> {output name: (size, N) array}: q, qd, qdd
    (N, n) (any strides; those the model reads), X (p,) parameters, wrench (N, sites, 6); out: the
    output buffers to fill, {name: (size, N) float64 with unit sample stride}, zero in the rows the model
    never writes (`zero_rows`); fresh `aligned_zeros` when omitted.
    """

    def __init__(self, module) -> None:
        self.module = module
        self.args: list[str] = list(module.ARGS)
        self.outputs: dict[str, int] = dict(module.OUTPUTS)
        self.zero_rows: dict[str, tuple[tuple[int, int], ...]] = dict(module.ZERO_ROWS)
        self.n, self.n_sites, self.shape = int(module.N), int(module.N_SITES), tuple(module.SHAPE)

    @property
    def available(self) -> bool:
        """False without numba, or for a model outside the block language (the caller then uses the NumPy code)."""
        return getattr(self.module, "run", None) is not None and not hasattr(self.module, "UNSUPPORTED")

    def __call__(self, q: np.ndarray, qd: np.ndarray | None = None, qdd: np.ndarray | None = None,
                 X: np.ndarray | None = None, wrench: np.ndarray | None = None,
                 out: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        if not self.available:
            raise RuntimeError("block kernels need numba")
        q = np.asarray(q, dtype=float)
        if q.ndim != 2:
            raise ValueError(f"q: (N, {self.n}) expected, got shape {q.shape}")
        N = q.shape[0]
        given = {"q": q, "qd": qd, "qdd": qdd, "X": X, "wrench": wrench}
        out = dict(out or {})
        for name, size in self.outputs.items():
            if name not in out:
                out[name] = aligned_zeros(size, N)
            o = out[name]
            if o.dtype != np.float64 or o.shape != (size, N) or (N > 1 and o.strides[1] != 8) or o.strides[0] < 0:
                raise ValueError(f"{name}: a ({size}, {N}) float64 buffer with unit sample stride is expected")
        desc = np.zeros(len(self.args) * _SLOTS, dtype=np.int64)
        keep = []  # the arrays whose addresses desc holds, alive until the call returns
        address = _address()
        direct = N % LANES == 0 and all(address(o) % (8 * LANES) == 0 and o.strides[0] % (8 * LANES) == 0
                                        for o in out.values())
        for i, a in enumerate(self.args):
            d = desc[i * _SLOTS:(i + 1) * _SLOTS]
            if a in self.outputs:
                o = out[a]
                # the scratch: for a last partial block, or every block of a buffer off the cache lines
                scratch = None if direct else aligned_zeros(o.shape[0], LANES, 8 * LANES)
                keep += [o, scratch]
                d[:] = (address(o), o.strides[0], 0 if scratch is None else address(scratch), o.shape[0])
                continue
            arr = given[a]
            if arr is None:
                raise ValueError(f"this model reads {a}")
            arr = np.asarray(arr, dtype=float)
            if a == "X":
                if arr.shape != (arr.size,):
                    raise ValueError(f"X: one parameter vector (p,) expected, got shape {arr.shape}")
                d[:3] = (address(arr), 0, arr.strides[0])
            else:
                want = (N, self.n) if a != "wrench" else (N, self.n_sites, 6)
                if a == "wrench":
                    arr = np.broadcast_to(arr.reshape(-1, self.n_sites, 6) if arr.ndim < 3 else arr, want)
                if arr.shape != want:
                    raise ValueError(f"{a} has shape {arr.shape}; expected {want}")
                d[:1 + arr.ndim] = (address(arr), *arr.strides)
            keep.append(arr)
        self.module.run(N, desc)
        del keep
        return out


def kernel_source(prog, name: str) -> str:
    """The per-sample source the block IR is translated from, and the module's footer."""

    return scalar_source(prog, name) + _FOOTER.format(lanes=LANES, symbol=f"dynid_blk_{name}", name=name)


def block_model(tree: Tree, model: str, **options) -> BlockKernel:
    """The BlockKernel of a model (dgm, idm, regressor, inertia) of a tree; options as for dynid.symbolic.build.

    Generated once, then loaded from the disk cache (source and Numba's machine code)."""

    key = source_key(model_hash(tree, model, options), "blocks", str(LANES))
    name = f"{model}_{key}"
    with _GENERATION_LOCK:
        mod = compile_source(None, [], key, prefix="dynid_blk")
        if mod is None or not hasattr(mod, "ARGS"):
            mod = _generate(tree, model, options, key, name)
    return BlockKernel(mod)


def _generate(tree: Tree, model: str, options: dict, key: str, name: str):
    """Build the model, check that it translates, write and import its module (see block_model)."""

    prog = build(tree, model, **options)
    outs = [("out", tuple(prog.shape), prog.outputs)] + [(k, tuple(s), e) for k, (s, e) in
                                                          prog.extra_outputs.items()]
    meta = {"ARGS": arguments(prog) + [o for o, _, _ in outs],
            "OUTPUTS": {o: int(np.prod(s)) for o, s, _ in outs},
            "ZERO_ROWS": {o: _zero_runs(s, e) for o, s, e in outs},
            "N": tree.n, "N_SITES": len(prog.meta.get("sites", [])), "SHAPE": tuple(prog.shape)}
    text = kernel_source(prog, name)
    try:  # checked now: inside Numba's compilation an error would surface far from its cause
        block_ir(scalar_source(prog, name), "check")
    except UnsupportedSourceError as e:
        meta["UNSUPPORTED"] = str(e)
    text += "".join(f"{k} = {v!r}\n" for k, v in meta.items())
    return compile_source(text, [], key, prefix="dynid_blk")


def _zero_runs(shape: tuple[int, ...], entries) -> tuple[tuple[int, int], ...]:
    """[start, stop) runs of the flat entries no equation writes (a zero polynomial writes nothing either)."""
    written = set()
    for idx, p in entries:
        if p:
            k = 0
            for i, s in zip(idx, shape, strict=True):
                k = k * s + i
            written.add(k)
    runs: list[tuple[int, int]] = []
    for k in range(int(np.prod(shape))):
        if k not in written:
            if runs and runs[-1][1] == k:
                runs[-1] = (runs[-1][0], k + 1)
            else:
                runs.append((k, k + 1))
    return tuple(runs)


__all__ = ["LANES", "BlockKernel", "aligned_zeros", "block_intrinsic", "block_ir", "block_model", "kernel_source"]
