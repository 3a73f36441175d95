"""Per-sample time of dynid's regressor and inverse dynamics against Pinocchio.

Run:  python benchmarks/bench_numeric.py [--samples 10000]

Pinocchio (`computeJointTorqueRegressor`, `rnea`) is called per sample from Python, as
a user without a batched engine would, writing into its preallocated `data`; dynid is
called once on all samples (default engine: compiled with Numba, single thread; the
NumPy engine is shown for reference). Both run in this process on the same trees, so
each speed-up is a ratio of figures measured in the same run. Lines:

- inverse dynamics: `model.inverse_dynamics(q, qd, qdd)` (a new (N, n) result).
- regressor, out= reused: `model.regressor(..., out=W)` with one zeroed W reused across
  calls, as Pinocchio reuses `data.jointTorqueRegressor` (the fair comparison).
- regressor, fresh array: `model.regressor(...)` allocating a new zeroed W per call; for
  the full car W is N x 42 x 442 doubles (1.5 GB at N = 10 000) and the first touch of
  its pages by the OS costs more than the arithmetic.
- 2 threads: the same call on the two halves of the samples in two threads (the kernels
  release the GIL), writing into halves of the reused W; reported apart from the targets.
- block kernels (issue 16): the generated models evaluated 8 samples side by side in vector
  registers (`dynid.symbolic.blocks`, what `GeneratedRegressor` runs for the car pipeline):
  inverse dynamics with the parameter values built in (as Pinocchio's model has them), the
  PUMA's full regressor and the car's 14 x 48 identification model, into reused buffers.

Also measures the first call in a fresh process with an empty Numba cache (compilation)
and with the cache filled. Prints a table and writes benchmarks/results/numeric.json.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from itertools import pairwise
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

from oracles import PinModel, random_states  # noqa: E402
from results_file import write_results  # noqa: E402

import dynid  # noqa: E402
from dynid import Model  # noqa: E402
from dynid.vehicle import car_template  # noqa: E402
from dynid.vehicle.template import EQUATION_ROWS, paper_parameter_names  # noqa: E402

FIRST_CALL = """
import time, numpy as np, dynid
t = time.perf_counter()
m = dynid.load_model("puma560"); q = np.zeros((2, 6))
m.inverse_dynamics(q, q, q); m.regressor(q, q, q)
print(time.perf_counter() - t)
"""


def best_of(f, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def per_sample_pinocchio(pm: PinModel, fn, q, qd, qdd) -> float:
    import pinocchio as pin

    c = pm.cols
    Q, V, A = q[:, c].copy(), qd[:, c].copy(), qdd[:, c].copy()
    f = getattr(pin, fn)

    def run():
        for s in range(Q.shape[0]):
            f(pm.model, pm.data, Q[s], V[s], A[s])

    return best_of(run) / Q.shape[0]


def threaded(fn, N: int, threads: int = 2):
    """Run fn(slice) on `threads` contiguous parts of the samples at once."""
    bounds = np.linspace(0, N, threads + 1).astype(int)
    parts = [slice(int(a), int(b)) for a, b in pairwise(bounds)]
    with ThreadPoolExecutor(threads) as pool:
        def run():
            list(pool.map(fn, parts))
        return best_of(run)


def bench_regressor(model: Model, q, qd, qdd, rows=None, cols=None, *, fresh: bool = True) -> dict:
    """Per-sample µs: out= reused, 2 threads into the reused buffer, and (optionally) fresh arrays."""
    N = q.shape[0]
    res = {}
    if fresh:
        res["fresh"] = 1e6 * best_of(lambda: model.regressor(q, qd, qdd, rows=rows, cols=cols), repeat=2) / N
    W = np.zeros((N, model.n if rows is None else len(rows), model.tree.p if cols is None else len(cols)))
    model.regressor(q, qd, qdd, rows=rows, cols=cols, out=W)  # touch the pages once
    res["reused"] = 1e6 * best_of(lambda: model.regressor(q, qd, qdd, rows=rows, cols=cols, out=W)) / N
    res["threads2"] = 1e6 * threaded(
        lambda sl: model.regressor(q[sl], qd[sl], qdd[sl], rows=rows, cols=cols, out=W[sl]), N) / N
    return res


def bench_blocks(model: Model, q, qd, qdd, rows=None, cols=None) -> dict:
    """Per-sample µs of the generated block kernels (dynid.symbolic.blocks: samples side by side in vector
    registers): inverse dynamics with the tree's parameter values built in, and the regressor (of the rows
    and columns given, else the whole one), each writing into a reused output buffer."""
    from dynid.symbolic.blocks import aligned_zeros, block_model

    N = q.shape[0]
    res = {}
    opts = {} if rows is None else {"rows": list(rows), "cols": list(cols)}
    for key, kernel in (("block_idm_us", block_model(model.tree, "idm", parameters="numeric")),
                        ("block_regressor_us", block_model(model.tree, "regressor", **opts))):
        kernel(q[:2], qd[:2], qdd[:2])  # generate and compile, or load, outside the timing
        out = {k: aligned_zeros(size, N) for k, size in kernel.outputs.items()}
        kernel(q, qd, qdd, out=out)  # touch the pages once
        res[key] = 1e6 * best_of(lambda k=kernel, o=out: k(q, qd, qdd, out=o), repeat=7) / N
    return res


def bench(name: str, model: Model, N: int, rows=None, cols=None) -> dict:
    pm = PinModel(model.tree)
    q, qd, qdd = random_states(model.tree, N, seed=0)
    Np = min(N, 3000)
    res = {"model": name, "frames": model.n, "samples": N, "threads_note": "2 threads over sample halves"}
    res["pin_rnea_us"] = 1e6 * per_sample_pinocchio(pm, "rnea", q[:Np], qd[:Np], qdd[:Np])
    res["pin_regressor_us"] = 1e6 * per_sample_pinocchio(pm, "computeJointTorqueRegressor", q[:Np], qd[:Np], qdd[:Np])
    model.inverse_dynamics(q[:2], qd[:2], qdd[:2])  # compile or load the kernels outside the timings
    model.regressor(q[:2], qd[:2], qdd[:2])
    res["dynid_idm_us"] = 1e6 * best_of(lambda: model.inverse_dynamics(q, qd, qdd)) / N
    res["dynid_idm_threads2_us"] = 1e6 * threaded(lambda sl: model.inverse_dynamics(q[sl], qd[sl], qdd[sl]), N) / N
    res["numpy_idm_us"] = 1e6 * best_of(lambda: model.inverse_dynamics(q, qd, qdd, backend="numpy")) / N
    res["idm_speedup"] = res["pin_rnea_us"] / res["dynid_idm_us"]
    r = bench_regressor(model, q, qd, qdd)
    res["dynid_regressor_us"], res["dynid_regressor_fresh_us"] = r["reused"], r["fresh"]
    res["dynid_regressor_threads2_us"] = r["threads2"]
    res["regressor_speedup"] = res["pin_regressor_us"] / res["dynid_regressor_us"]
    res["regressor_fresh_speedup"] = res["pin_regressor_us"] / res["dynid_regressor_fresh_us"]
    if rows is not None:
        r = bench_regressor(model, q, qd, qdd, rows, cols)
        res["dynid_regressor_restricted_us"], res["dynid_regressor_restricted_fresh_us"] = r["reused"], r["fresh"]
        res["dynid_regressor_restricted_threads2_us"] = r["threads2"]
        res["restricted_shape"] = [len(rows), len(cols)]
        res["restricted_speedup"] = res["pin_regressor_us"] / res["dynid_regressor_restricted_us"]
        res["restricted_fresh_speedup"] = res["pin_regressor_us"] / res["dynid_regressor_restricted_fresh_us"]
    res.update(bench_blocks(model, q, qd, qdd, rows, cols))
    res["block_regressor_shape"] = [model.n, model.tree.p] if rows is None else [len(rows), len(cols)]
    res["block_idm_speedup"] = res["pin_rnea_us"] / res["block_idm_us"]
    res["block_regressor_speedup"] = res["pin_regressor_us"] / res["block_regressor_us"]
    return res


def first_call_seconds(cache_dir: str | None) -> float:
    """Import + first inverse dynamics and regressor in a new process (NUMBA_CACHE_DIR = cache_dir)."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def print_table(results: list[dict], compile_s: dict) -> None:
    head = f"{'model':<24} {'what':<44} {'dynid µs':>9} {'Pinocchio µs':>13} {'speed-up':>9}  target"
    print(head)
    print("-" * len(head))

    def line(r, what, ours, theirs, tgt=""):
        print(f"{r['model']:<24} {what:<44} {ours:>9.2f} {theirs:>13.2f} {theirs / ours:>8.1f}x  {tgt}")

    for r in results:
        car = r["frames"] == 42
        line(r, "inverse dynamics (vs rnea)", r["dynid_idm_us"], r["pin_rnea_us"], ">= 2x")
        line(r, "regressor, all rows/cols, out= reused", r["dynid_regressor_us"], r["pin_regressor_us"],
             ">= 5x" if car else "")
        line(r, "regressor, all rows/cols, fresh array", r["dynid_regressor_fresh_us"], r["pin_regressor_us"])
        if "restricted_speedup" in r:
            shape = f"{r['restricted_shape'][0]} x {r['restricted_shape'][1]}"
            line(r, f"regressor, {shape}, out= reused", r["dynid_regressor_restricted_us"],
                 r["pin_regressor_us"], ">= 20x")
            line(r, f"regressor, {shape}, fresh array", r["dynid_regressor_restricted_fresh_us"],
                 r["pin_regressor_us"])
    print("\ngenerated block kernels (issue 16: samples side by side in vector registers), same run:")
    for r in results:
        car = r["frames"] == 42
        shape = f"{r['block_regressor_shape'][0]} x {r['block_regressor_shape'][1]}"
        line(r, "inverse dynamics, block kernel (vs rnea)", r["block_idm_us"], r["pin_rnea_us"],
             ">= 10x" if car else "")
        line(r, f"regressor {shape}, block kernel (vs full)", r["block_regressor_us"], r["pin_regressor_us"],
             ">= 140x and <= 0.5 µs" if car else "")
    print("\nfor reference, not targets:")
    for r in results:
        line(r, "inverse dynamics, NumPy engine", r["numpy_idm_us"], r["pin_rnea_us"])
        line(r, "inverse dynamics, 2 threads", r["dynid_idm_threads2_us"], r["pin_rnea_us"])
        line(r, "regressor, all, out= reused, 2 threads", r["dynid_regressor_threads2_us"], r["pin_regressor_us"])
        if "restricted_speedup" in r:
            line(r, "regressor, restricted, out= reused, 2 threads", r["dynid_regressor_restricted_threads2_us"],
                 r["pin_regressor_us"])
    print(f"\nfirst call in a new process (import, model, ID + regressor): {compile_s['cold']:.1f} s with an "
          f"empty Numba cache (compilation), {compile_s['warm']:.1f} s with the cache filled")


def roofline(results: list[dict], car: Model) -> dict:
    """Each kernel's distance to this core's measured peak (benchmarks/roofline.py), printed and returned."""
    from roofline import operations, peak_flops, roofline_line

    peak = peak_flops()
    print(f"\nroofline: this core's measured peak {peak / 1e9:.1f} Gop/s (FMA loop, an FMA = 2 ops); operations "
          "counted on the customised symbolic model of the same tree")
    out: dict = {"peak_gops": peak / 1e9, "kernels": {}}
    puma = dynid.load_model("puma560")
    cases = [
        ("PUMA 560 inverse dynamics", puma.tree, "idm", {}, results[0]["dynid_idm_us"]),
        ("PUMA 560 regressor", puma.tree, "regressor", {}, results[0]["dynid_regressor_us"]),
        ("car 42 frames inverse dynamics", car.tree, "idm", {}, results[1]["dynid_idm_us"]),
        (f"car regressor {len(EQUATION_ROWS)} x {len(paper_parameter_names())}", car.tree, "regressor",
         {"rows": list(EQUATION_ROWS), "cols": paper_parameter_names()},
         results[1]["dynid_regressor_restricted_us"]),
        ("PUMA 560 inverse dynamics, block kernel", puma.tree, "idm", {"parameters": "numeric"},
         results[0]["block_idm_us"]),
        ("PUMA 560 regressor, block kernel", puma.tree, "regressor", {}, results[0]["block_regressor_us"]),
        ("car 42 frames inverse dynamics, block kernel", car.tree, "idm", {"parameters": "numeric"},
         results[1]["block_idm_us"]),
        (f"car regressor {len(EQUATION_ROWS)} x {len(paper_parameter_names())}, block kernel", car.tree,
         "regressor", {"rows": list(EQUATION_ROWS), "cols": paper_parameter_names()},
         results[1]["block_regressor_us"]),
    ]
    for name, tree, kind, opts, us in cases:
        ops, funcs = operations(tree, kind, **opts)
        print(roofline_line(name, ops, funcs, us, peak))
        out["kernels"][name] = {"ops": ops, "functions": funcs, "us_per_sample": us,
                                "gops": ops / us / 1e3, "fraction_of_peak": ops / (us * 1e-6) / peak}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        compile_s = {"cold": first_call_seconds(tmp), "warm": first_call_seconds(tmp)}
    car = Model(car_template())
    results = [
        bench("PUMA 560", dynid.load_model("puma560"), args.samples),
        bench("Peugeot 406 (42 frames)", car, args.samples, list(EQUATION_ROWS), paper_parameter_names()),
    ]
    print_table(results, compile_s)
    roof = roofline(results, car)
    print()
    write_results("numeric", {"machine": os.uname().machine, "cpus": os.cpu_count(), "engine": "numba",
                              "first_call_s": compile_s, "results": results, "roofline": roof})


if __name__ == "__main__":
    main()
