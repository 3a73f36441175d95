"""LLVM IR of the generated straight-line models written as text, or built with llvmlite's IR builder? (issue 25,
item 3: "built with llvmlite's IR builder ... unless a benchmark says otherwise")

Run:  python benchmarks/bench_llvm_ir.py [--vehicle peugeot406] [--repeat 7]

The simulator's three generated models of a shipped vehicle (car_kin, car_idm, car_inertia: numba_backend's
straight-line language, `vehicle.sim.car._models_source`) are turned into an LLVM module two ways, in this process:

- text: `symbolic.llvm_code.function_ir`, what dynid runs (an f-string per instruction);
- builder: the same walk written here with `llvmlite.ir` (an object per instruction, the module printed at the end),
  the same operations in the same order (Numba's forms: unary minus as -0.0 - x, memset for out[:] = 0.0, selects
  for the sign; sine and cosine as a call of one copy of dynamics.trig's steps, llvm_code.Emitter.sincos).

Each is timed to build (best of --repeat) and to parse, verify, optimise and compile to machine code by Numba's code
generator (`llvm_code.native_library`, the step that follows either way; best of 3). Both modules' functions are then
called on the same random inputs through ctypes: their outputs must be equal bit for bit, or the comparison is void.

Measured 29 Nov 04:15 UTC (2-core AMD EPYC, load average ~4: other sessions), the 406: build text 9.7 / 18.7 / 47.0 ms
against builder 26.8 / 48.1 / 128.1 ms (2.6-2.8x) for car_kin / car_idm / car_inertia (685, 997, 1,709 statements);
build + LLVM to machine code 123 / 186 / 692 ms against 161 / 246 / 939 ms; outputs equal to the bit. The text stays.
"""

from __future__ import annotations

import argparse
import ast
import ctypes
import math
import time

import numpy as np
from llvmlite import ir

from dynid.dynamics import trig
from dynid.symbolic.llvm_code import function_ir, native_library, parse_function
from dynid.vehicle.description import load_vehicle
from dynid.vehicle.sim.car import CarSimulator, _models_source

F64 = ir.DoubleType()
I64 = ir.IntType(64)
PTR = ir.PointerType(F64)
_BINARY = {ast.Add: "fadd", ast.Sub: "fsub", ast.Mult: "fmul"}


def builder_ir(source: str, symbol: str) -> str:
    """`function_ir`'s module, built with llvmlite's IR builder."""
    fn = parse_function(source)
    args = [a.arg for a in fn.args.args]
    module = ir.Module()
    sig = ir.FunctionType(ir.VoidType(), [t for _ in args for t in (PTR, I64, I64)])
    func = ir.Function(module, sig, symbol)
    func.linkage = "weak_odr"
    func.attributes.add("nounwind")
    b = ir.IRBuilder(func.append_basic_block("entry"))
    param = {a: func.args[3 * k: 3 * k + 3] for k, a in enumerate(args)}
    libm = {k: ir.Function(module, ir.FunctionType(F64, [F64]), f"llvm.{k}.f64") for k in ("sin", "cos", "fabs")}
    pairs: dict[int, tuple[ir.Value, ir.Value]] = {}
    i8 = ir.IntType(8)
    memset = ir.Function(module, ir.FunctionType(ir.VoidType(), [ir.PointerType(i8), i8, I64, ir.IntType(1)]),
                         "llvm.memset.p0i8.i64")
    env: dict[str, ir.Value] = {}

    def address(node: ast.Subscript) -> ir.Value:
        data, _, cols = param[node.value.id]
        idx = [i.value for i in (node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice])]
        flat = ir.Constant(I64, idx[0]) if len(idx) == 1 else b.add(b.mul(ir.Constant(I64, idx[0]), cols),
                                                                      ir.Constant(I64, idx[1]))
        return b.gep(data, [flat], inbounds=True)

    def expr(node: ast.expr) -> ir.Value:
        if isinstance(node, ast.Constant):
            return ir.Constant(F64, float(node.value))
        if isinstance(node, ast.Name):
            return env[node.id]
        if isinstance(node, ast.BinOp):
            left, right = expr(node.left), expr(node.right)
            return getattr(b, _BINARY[type(node.op)])(left, right)
        if isinstance(node, ast.UnaryOp):
            x = expr(node.operand)
            return b.fsub(ir.Constant(F64, -0.0), x) if isinstance(node.op, ast.USub) else x
        if isinstance(node, ast.Subscript):
            return b.load(address(node))
        f = node.func
        x = expr(node.args[0])
        if f.id in ("_sin", "_cos"):
            if id(x) not in pairs:
                pairs[id(x)] = sincos(x)
            return pairs[id(x)][f.id == "_cos"]
        zero = ir.Constant(F64, 0.0)
        low = b.select(b.fcmp_ordered("<", x, zero), ir.Constant(F64, -1.0), zero)
        return b.select(b.fcmp_ordered(">", x, zero), ir.Constant(F64, 1.0), low)

    pair_type = ir.LiteralStructType([F64, F64])
    sincos_fn = None

    def sincos(x: ir.Value) -> tuple[ir.Value, ir.Value]:
        """llvm_code's: a call of the module's one internal, not inlined, copy of the steps (sincos_body)."""
        nonlocal sincos_fn
        if sincos_fn is None:
            sincos_fn = ir.Function(module, ir.FunctionType(pair_type, [F64]), "dynid_sincos")
            sincos_fn.linkage = "internal"
            sincos_fn.attributes.add("noinline")
            sincos_fn.attributes.add("nounwind")
            sincos_body(ir.IRBuilder(sincos_fn.append_basic_block("entry")), sincos_fn)
        pair = b.call(sincos_fn, [x])
        return b.extract_value(pair, 0), b.extract_value(pair, 1)

    def sincos_body(b: ir.IRBuilder, func: ir.Function) -> None:
        """llvm_code.Emitter.sincos: dynamics.trig's steps, the quadrant by selects, libm out of range."""
        x = func.args[0]
        ok = b.fcmp_ordered("<", b.call(libm["fabs"], [x]), ir.Constant(F64, trig.LIMIT))
        val = {"x": b.select(ok, x, ir.Constant(F64, 0.0))}
        for name, op, u, v in trig.STEPS:
            val[name] = getattr(b, f"f{op}")(*(val[w] if w in val else ir.Constant(F64, trig.CONSTANTS[w])
                                               for w in (u, v)))
        quad = b.and_(b.fptosi(val["k"], I64), ir.Constant(I64, 3))

        def bit(w: ir.Value, m: int) -> ir.Value:
            return b.icmp_signed("!=", b.and_(w, ir.Constant(I64, m)), ir.Constant(I64, 0))

        odd = bit(quad, 1)
        s1, c1 = b.select(odd, val["cs"], val["sn"]), b.select(odd, val["sn"], val["cs"])
        s2 = b.select(bit(quad, 2), b.fneg(s1), s1)
        c2 = b.select(bit(b.add(quad, ir.Constant(I64, 1)), 2), b.fneg(c1), c1)
        here, slow, done = b.block, func.append_basic_block(), func.append_basic_block()
        b.cbranch(ok, done, slow)
        b.position_at_end(slow)
        s3, c3 = b.call(libm["sin"], [x]), b.call(libm["cos"], [x])
        b.branch(done)
        b.position_at_end(done)
        out = []
        for fast, far in ((s2, s3), (c2, c3)):
            phi = b.phi(F64)
            phi.add_incoming(fast, here)
            phi.add_incoming(far, slow)
            out.append(phi)
        pair = b.insert_value(b.insert_value(ir.Constant(pair_type, ir.Undefined), out[0], 0), out[1], 1)
        b.ret(pair)

    for st in fn.body:
        if isinstance(st, ast.Return):
            b.ret_void()
            break
        if isinstance(st, ast.Expr):
            continue  # the docstring
        target = st.targets[0]
        if isinstance(target, ast.Name):
            env[target.id] = expr(st.value)
        elif isinstance(target.slice, ast.Slice):  # out[:] = 0.0
            data, n, _ = param[target.value.id]
            b.call(memset, [b.bitcast(data, ir.PointerType(i8)), ir.Constant(i8, 0), b.mul(n, ir.Constant(I64, 8)),
                            ir.Constant(ir.IntType(1), 0)])
        else:
            value = expr(st.value)
            b.store(value, address(target))
    return str(module)


def best(fn, repeat: int) -> float:
    out = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t)
    return out


def call(lib, symbol: str, arrays: list[np.ndarray]) -> None:
    proto = ctypes.CFUNCTYPE(None, *([ctypes.c_void_p, ctypes.c_int64, ctypes.c_int64] * len(arrays)))
    flat = [v for a in arrays for v in (a.ctypes.data, a.size, a.shape[-1])]
    proto(lib.get_pointer_to_function(symbol))(*flat)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicle", default="peugeot406")
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args()
    v = load_vehicle(a.vehicle)
    sim = CarSimulator(v.truth, v.geometry, v.tables, v.aero, steering_ratio=v.steering_ratio,
                       damper_knees=v.damper_knees)
    sources = _models_source(sim.tree, sim.aero_point)
    rng = np.random.default_rng(0)
    print(f"{a.vehicle}: the simulator's generated models, ms (build: best of {a.repeat}; compile: best of 3)")
    print(f"{'model':12s} {'statements':>10s} {'text':>8s} {'builder':>8s} {'ratio':>6s} {'compile text':>13s} "
          f"{'compile builder':>16s}  outputs")
    for name, src in sources.items():
        statements = len(parse_function(src).body)
        texts = {"text": lambda s=src, n=name: function_ir(s, f"t_{n}"),
                 "builder": lambda s=src, n=name: builder_ir(s, f"b_{n}")}
        build = {k: best(f, a.repeat) for k, f in texts.items()}
        compiled = {k: best(lambda f=f, k=k, n=name: native_library(f"{k}_{n}", [f()]), 3) for k, f in texts.items()}
        libs = {k: native_library(f"{k}_{name}_run", [f()]) for k, f in texts.items()}
        # the arrays each model takes (q, qd, qdd, wrench, and the output last), long enough for any index
        nargs = len(parse_function(src).args.args)
        inputs = [rng.standard_normal((64, 64)) for _ in range(nargs - 1)]
        outs = {}
        for k, lib in libs.items():
            out = np.full((64, 64), np.nan)
            call(lib, f"{k[0]}_{name}", [*(x.copy() for x in inputs), out])
            outs[k] = out
        same = np.array_equal(outs["text"].view(np.int64), outs["builder"].view(np.int64))
        print(f"{name:12s} {statements:10d} {1e3 * build['text']:8.1f} {1e3 * build['builder']:8.1f} "
              f"{build['builder'] / build['text']:6.2f} {1e3 * compiled['text']:13.1f} "
              f"{1e3 * compiled['builder']:16.1f}  {'equal bits' if same else 'DIFFER'}")


if __name__ == "__main__":
    main()
