"""Benchmark of dynid.symbolic: generation times, operation counts, generated code speed.

Run: python benchmarks/bench_symbolic.py   (writes benchmarks/results/symbolic.json)

- generation time of every model (fresh, no cache) for PUMA 560, TX40 and the
  car-shaped 42-frame tree (6 virtual frames 3P+3R, 4 corners of 9 frames);
- operation counts, and the 6R arm with IA, FV, FS and a tool wrench (RX90 table);
- per-sample time of the generated NumPy regressor (batched, N = 20000, results dropped as
  they come, as a caller looping over batches does: the module reuses their buffers) against
  pinocchio.computeJointTorqueRegressor called per sample on the same tree, also with the
  module's results writeable (READONLY = False: a reused buffer's zero rows cleared each
  call) and with no buffer reuse (POOL_MIN huge: fresh zeroed pages each call, as for a caller
  keeping every result), and of the generated C compiled with -O2 (called through ctypes);
- samples side by side (issue 16): the generated C `_block` (8 samples per vectorised loop, -O2 and
  -O3 -march=native), and the Numba block kernel (dynid.symbolic.blocks, vector IR, what
  GeneratedRegressor runs), each with its ratio to Pinocchio and to the C `_batch` of this run,
  and its fraction of this core's measured peak (benchmarks/roofline.py).
"""

from __future__ import annotations

import ctypes
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import dynid
from dynid.model import Frame, Tree
from dynid.symbolic import WrenchSite, build, expr, idm, to_c, to_numpy
from dynid.symbolic.regroup import base_parameters
from dynid.vehicle import car_template
from dynid.vehicle.template import EQUATION_ROWS as CAR_ROWS
from dynid.vehicle.template import paper_parameter_names

CAR_COLS = tuple(paper_parameter_names())

HERE = Path(__file__).parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]  # tests/: the Pinocchio oracle (oracles.PinModel)

from results_file import write_results  # noqa: E402

MODELS = ("dgm", "idm", "regressor", "inertia")


def rx90() -> Tree:
    h = math.pi / 2
    frames = (Frame(1, 0, 0), Frame(2, 1, 0, alpha=h), Frame(3, 2, 0, d=0.45), Frame(4, 3, 0, alpha=-h, r=0.45),
              Frame(5, 4, 0, alpha=h), Frame(6, 5, 0, alpha=-h))
    return Tree("RX90 (6R)", frames, joint_terms={j: ("IA", "FV", "FS") for j in range(1, 7)})


def timed_build(tree: Tree, model: str, **opts):
    expr._FACTOR_CACHE.clear()
    t0 = time.perf_counter()
    prog = build(tree, model, **opts)
    prog.ops()  # counting is part of generating
    return prog, time.perf_counter() - t0


def numpy_fn(prog, tree, **settings):
    """The generated module's evaluate, with module settings (READONLY, CHUNK) overridden."""
    ns: dict = {}
    exec(compile(to_numpy(prog, tree), "<generated>", "exec"), ns)
    ns.update(settings)
    return ns["evaluate"]


def per_sample(fn, N: int, repeat: int = 5) -> float:
    fn()
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best / N


def pinocchio_per_sample(tree: Tree, q, qd, qdd) -> float | None:
    try:
        import pinocchio as pin
        from oracles import PinModel
    except Exception:  # pinocchio missing: report None
        return None
    pm = PinModel(tree)
    c = pm.cols
    qs, qds, qdds = (np.ascontiguousarray(a[:, c]) for a in (q, qd, qdd))
    N = q.shape[0]

    def run():
        for s in range(N):
            pin.computeJointTorqueRegressor(pm.model, pm.data, qs[s], qds[s], qdds[s])

    return per_sample(run, N, repeat=3)


def c_per_sample(prog, stem: str, q, qd, qdd, variant: str = "batch", flags: tuple[str, ...] = ("-O2",)
                 ) -> float | None:
    """Per-sample time of the generated C `<stem>_<model>_<variant>` (batch: per sample; block: 8 samples
    side by side) compiled with `flags`, called once on all samples through ctypes."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        h, c = to_c(prog, prefix=stem, block=variant == "block")
        name = f"{stem}_{prog.model}"
        Path(tmp, f"{name}.h").write_text(h)
        Path(tmp, f"{name}.c").write_text(c)
        lib = Path(tmp, f"{name}.so")
        subprocess.run([cc, *flags, "-shared", "-fPIC", "-o", str(lib), str(Path(tmp, f"{name}.c")), "-lm"],
                       check=True)
        fn = getattr(ctypes.CDLL(str(lib)), f"{name}_{variant}")
        N = q.shape[0]
        P = ctypes.POINTER(ctypes.c_double)
        arrays = [np.ascontiguousarray(a) for a in (q, qd, qdd)]
        out = np.zeros((N, *prog.shape))
        ptrs = [a.ctypes.data_as(P) for a in arrays] + [out.ctypes.data_as(P)]
        return per_sample(lambda: fn(ctypes.c_long(N), *ptrs), N, repeat=20)


# SymPyBotics' generated C regressor of the PUMA 560, as quoted in issue 16 (not measured here: a reference)
SYMPYBOTICS_PUMA_C_US = 0.357


def block_per_sample(tree: Tree, opts: dict, q, qd, qdd) -> float | None:
    """Per-sample time of the generated block kernel (dynid.symbolic.blocks) into a reused buffer."""
    try:
        from dynid.symbolic.blocks import aligned_zeros, block_model

        kernel = block_model(tree, "regressor", **opts)
        if not kernel.available:
            return None
    except ImportError:
        return None
    out = {k: aligned_zeros(size, q.shape[0]) for k, size in kernel.outputs.items()}
    return per_sample(lambda: kernel(q, qd, qdd, out=out), q.shape[0], repeat=7)


def main() -> int:
    res: dict = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
                 "numpy": np.__version__, "cpus": os.cpu_count()}
    trees = {"puma560": dynid.load_model("puma560").tree, "tx40": dynid.load_model("tx40").tree,
             "car42": car_template()}
    gen: dict = {}
    ops: dict = {}
    for key, tree in trees.items():
        gen[key], ops[key] = {}, {}
        for model in MODELS:
            prog, dt = timed_build(tree, model)
            gen[key][model] = dt
            c = prog.ops()
            ops[key][model] = {"mult": c.mult, "add": c.add, "func": c.func, "equations": len(prog.equations)}
        gen[key]["all"] = sum(gen[key][m] for m in MODELS)
    prog, dt = timed_build(trees["car42"], "regressor", rows=CAR_ROWS, cols=CAR_COLS)
    gen["car42"]["regressor_14x48"] = dt
    c = prog.ops()
    ops["car42"]["regressor_14x48"] = {"mult": c.mult, "add": c.add, "func": c.func, "equations": len(prog.equations)}
    for key in ("puma560", "tx40"):
        t0 = time.perf_counter()
        base_parameters(trees[key], geometry="symbolic")
        gen[key]["base_parameters"] = time.perf_counter() - t0
    c = idm(rx90(), wrenches=[WrenchSite(6)]).ops()
    ops["rx90_idm_with_tool_wrench"] = {"mult": c.mult, "add": c.add, "func": c.func,
                                        "target": "<= 389 mult, <= 340 add"}
    for key in ("puma560", "tx40"):
        c = idm(trees[key], wrenches=[WrenchSite(6)]).ops()
        ops[key]["idm_with_tool_wrench"] = {"mult": c.mult, "add": c.add, "func": c.func}
    res["generation_s"] = gen
    res["ops"] = ops

    speed: dict = {}
    rng = np.random.default_rng(0)
    for key, opts in (("puma560", {}), ("car42", {"rows": CAR_ROWS, "cols": CAR_COLS})):
        tree = trees[key]
        prog = build(tree, "regressor", **opts)
        f, fw = numpy_fn(prog, tree), numpy_fn(prog, tree, READONLY=False)
        ff = numpy_fn(prog, tree, POOL_MIN=1 << 62)
        Nn, Np, Nc = 20000, 2000, 20000
        q, qd, qdd = rng.uniform(-np.pi, np.pi, (3, Nn, tree.n))
        t_np = per_sample(lambda f=f, q=q, qd=qd, qdd=qdd: f(q, qd, qdd), Nn, repeat=7)
        t_npw = per_sample(lambda f=fw, q=q, qd=qd, qdd=qdd: f(q, qd, qdd), Nn, repeat=7)
        t_npf = per_sample(lambda f=ff, q=q, qd=qd, qdd=qdd: f(q, qd, qdd), Nn, repeat=7)
        t_pin = pinocchio_per_sample(tree, q[:Np], qd[:Np], qdd[:Np])
        t_c = c_per_sample(prog, key, q[:Nc], qd[:Nc], qdd[:Nc])
        t_cb = c_per_sample(prog, key, q[:Nc], qd[:Nc], qdd[:Nc], "block")
        t_cbn = c_per_sample(prog, key, q[:Nc], qd[:Nc], qdd[:Nc], "block", ("-O3", "-march=native"))
        t_blk = block_per_sample(tree, opts, q, qd, qdd)
        count = prog.ops()
        speed[key] = {"ops": count.mult + count.add, "functions": count.func,
                      "c_block_O2_us": None if t_cb is None else t_cb * 1e6,
                      "c_block_O3_native_us": None if t_cbn is None else t_cbn * 1e6,
                      "numba_block_us": None if t_blk is None else t_blk * 1e6,
                      "numba_block_speedup_vs_pinocchio": None if None in (t_pin, t_blk) else t_pin / t_blk,
                      "c_block_O2_vs_sympybotics_c": None if t_cb is None else SYMPYBOTICS_PUMA_C_US / (t_cb * 1e6),
                      "model": f"regressor {prog.shape[0]}x{prog.shape[1]}", "numpy_us": t_np * 1e6,
                      "numpy_writeable_us": t_npw * 1e6, "numpy_fresh_buffers_us": t_npf * 1e6,
                      "pinocchio_us": None if t_pin is None else t_pin * 1e6,
                      "numpy_speedup_vs_pinocchio": None if t_pin is None else t_pin / t_np,
                      "numpy_writeable_speedup_vs_pinocchio": None if t_pin is None else t_pin / t_npw,
                      "c_O2_us": None if t_c is None else t_c * 1e6}
    res["per_sample"] = speed

    write_results("symbolic", res)  # once here, again with the block kernels' figures below
    print("generation time (s):")
    for key, d in gen.items():
        print(f"  {key:<8} " + "  ".join(f"{m} {v:.3f}" for m, v in d.items()))
    print("operation counts (mult/add/functions):")
    for key, d in ops.items():
        if "mult" in d:
            print(f"  {key}: {d['mult']}/{d['add']}/{d['func']}  (target {d['target']})")
            continue
        print(f"  {key:<8} " + "  ".join(f"{m} {v['mult']}/{v['add']}/{v['func']}" for m, v in d.items()))
    print("per sample (us):")
    for key, d in speed.items():
        pin_s = "n/a" if d["pinocchio_us"] is None else f"{d['pinocchio_us']:.2f}"
        sp = "n/a" if d["numpy_speedup_vs_pinocchio"] is None else f"{d['numpy_speedup_vs_pinocchio']:.1f}x"
        spw = ("n/a" if d["numpy_writeable_speedup_vs_pinocchio"] is None
               else f"{d['numpy_writeable_speedup_vs_pinocchio']:.1f}x")
        c_s = "n/a" if d["c_O2_us"] is None else f"{d['c_O2_us']:.3f}"
        print(f"  {key:<8} {d['model']}: numpy {d['numpy_us']:.3f}  pinocchio {pin_s}  ({sp})  "
              f"numpy writeable {d['numpy_writeable_us']:.3f} ({spw})  fresh buffers "
              f"{d['numpy_fresh_buffers_us']:.3f}  C -O2 {c_s}")
    try:
        from roofline import peak_flops

        peak = peak_flops()
    except ImportError:
        peak = None
    print("samples side by side (issue 16), per sample (us) and ratios measured in this run:")
    for key, d in speed.items():
        def us(v):
            return "n/a" if v is None else f"{v:.3f}"

        pin_us = d["pinocchio_us"]
        print(f"  {key:<8} {d['model']}: Numba block {us(d['numba_block_us'])}"
              + ("" if d["numba_block_speedup_vs_pinocchio"] is None
                 else f" ({d['numba_block_speedup_vs_pinocchio']:.0f}x Pinocchio {pin_us:.2f})")
              + f"  C -O2: _batch {us(d['c_O2_us'])}, _block {us(d['c_block_O2_us'])}"
              + ("" if d["c_O2_us"] is None or d["c_block_O2_us"] is None
                 else f" ({d['c_O2_us'] / d['c_block_O2_us']:.2f}x _batch)")
              + f"  C _block -O3 -march=native {us(d['c_block_O3_native_us'])}")
        if key == "puma560" and d["c_block_O2_us"] is not None:
            print(f"           C _block -O2 vs SymPyBotics' C ({SYMPYBOTICS_PUMA_C_US} us, quoted in issue 16, not "
                  f"measured here): {d['c_block_O2_vs_sympybotics_c']:.2f}x  (target <= 0.30 us)")
        if peak is not None:
            for what in ("numba_block_us", "c_block_O2_us"):
                if d[what] is not None:
                    rate = d["ops"] / (d[what] * 1e-6)
                    d[what.replace("_us", "_fraction_of_peak")] = rate / peak
                    print(f"           roofline {what[:-3]}: {d['ops']} ops + {d['functions']} sin/cos, "
                          f"{rate / 1e9:.2f} Gop/s, {100 * rate / peak:.1f} % of this core's {peak / 1e9:.1f} Gop/s")
    write_results("symbolic", res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
