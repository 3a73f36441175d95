"""Could the symbolic builder replace the NumPy reference Newton-Euler (issue 25, item 3)?

Run:  python benchmarks/bench_reference_vs_builder.py

The NumPy reference engine (dynamics.newton_euler, regressor: backend="numpy") and the symbolic
builder (symbolic.models) run the same recursion. Making the builder run over a NumPy algebra
(Pinocchio's scalar templates in Python) would evaluate the builder's operations one NumPy call
each, per call of the model. Its best case is the builder's generated NumPy module (the same
operations as three-address code over preallocated rows, no Python bookkeeping between them), and
its per-call overhead is at least the builder's own run time (its Python per operation). Printed
per tree, model and N, all measured in this process on the same samples: the reference engine and
the generated module per sample (best of 5), the builder's time (symbolic, a fresh build), and the
largest difference between the two results (they agree to round-off, not bit for bit: the operations
are ordered differently).
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np

from dynid.dynamics import Model
from dynid.model import example_path, load_tree
from dynid.symbolic import build, expr, to_numpy
from dynid.vehicle import car_template
from dynid.vehicle.template import EQUATION_ROWS, paper_parameter_names


def best(fn, repeat: int = 5) -> float:
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts)


def generated(prog, tree):
    ns: dict = {}
    exec(compile(to_numpy(prog, tree), "<generated>", "exec"), ns)
    return ns["evaluate"]


def main() -> None:
    rng = np.random.default_rng(0)
    car_block = {"rows": list(EQUATION_ROWS), "cols": list(paper_parameter_names())}
    for name, tree, block in (("puma560", load_tree(example_path("puma560")), {}),
                              ("car42", car_template(), car_block)):
        m = Model(tree)
        for model in ("idm", "regressor"):
            expr._FACTOR_CACHE.clear()
            t0 = time.perf_counter()
            prog = build(tree, model, **(block if model == "regressor" else {}))
            t_build = time.perf_counter() - t0
            f = generated(prog, tree)
            for N in (1, 100, 10_000):
                q, qd, qdd = (rng.uniform(-1, 1, (N, tree.n)) for _ in range(3))
                ref = (partial(m.inverse_dynamics, q, qd, qdd, backend="numpy") if model == "idm"
                       else partial(m.regressor, q, qd, qdd, backend="numpy", **block))
                gen = partial(f, q, qd, qdd)
                diff = float(np.max(np.abs(np.asarray(ref()) - np.asarray(gen()))))
                t_ref, t_gen = best(ref), best(gen)
                print(f"{name:8} {model:9} N={N:6}: NumPy reference {t_ref * 1e6 / N:9.3f} us/sample   "
                      f"builder's generated NumPy {t_gen * 1e6 / N:9.3f} us/sample   "
                      f"builder run {t_build * 1e3:7.1f} ms   max |difference| {diff:.1e}", flush=True)


if __name__ == "__main__":
    main()
