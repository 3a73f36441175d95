"""Per-sample time of dynid's batched regressor and inverse dynamics against Pinocchio.

Run:  python benchmarks/bench_numeric.py [--samples 10000]

Pinocchio (`computeJointTorqueRegressor`, `rnea`) is called per sample from Python, as
a user without a batched engine would; dynid is called once on all samples. Both run
in this process on the same trees. Prints a table and writes
benchmarks/results/numeric.json.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

from oracles import PinModel, random_states  # noqa: E402

import dynid  # noqa: E402
from dynid import Model  # noqa: E402
from dynid.vehicle import car_template  # noqa: E402
from dynid.vehicle.template import EQUATION_ROWS, paper_parameter_names  # noqa: E402


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


def bench(name: str, model: Model, N: int, rows=None, cols=None) -> dict:
    pm = PinModel(model.tree)
    q, qd, qdd = random_states(model.tree, N, seed=0)
    Np = min(N, 3000)
    res = {"model": name, "frames": model.n, "samples": N}
    res["pin_rnea_us"] = 1e6 * per_sample_pinocchio(pm, "rnea", q[:Np], qd[:Np], qdd[:Np])
    res["pin_regressor_us"] = 1e6 * per_sample_pinocchio(pm, "computeJointTorqueRegressor", q[:Np], qd[:Np], qdd[:Np])
    res["dynid_idm_us"] = 1e6 * best_of(lambda: model.inverse_dynamics(q, qd, qdd)) / N
    res["dynid_regressor_us"] = 1e6 * best_of(lambda: model.regressor(q, qd, qdd), repeat=2) / N
    res["idm_speedup"] = res["pin_rnea_us"] / res["dynid_idm_us"]
    res["regressor_speedup"] = res["pin_regressor_us"] / res["dynid_regressor_us"]
    if rows is not None:
        t = best_of(lambda: model.regressor(q, qd, qdd, rows=rows, cols=cols))
        res["dynid_regressor_restricted_us"] = 1e6 * t / N
        res["restricted_shape"] = [len(rows), len(cols)]
        res["restricted_speedup"] = res["pin_regressor_us"] / res["dynid_regressor_restricted_us"]
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_000)
    args = ap.parse_args()
    car = Model(car_template())
    results = [
        bench("PUMA 560", dynid.load_model("puma560"), args.samples),
        bench("Peugeot 406 (42 frames)", car, args.samples, list(EQUATION_ROWS), paper_parameter_names()),
    ]
    print(f"{'model':<20} {'what':<28} {'dynid µs':>9} {'Pinocchio µs':>13} {'speed-up':>9}  target")
    for r in results:
        print(f"{r['model']:<20} {'inverse dynamics':<28} {r['dynid_idm_us']:>9.2f} {r['pin_rnea_us']:>13.2f} "
              f"{r['idm_speedup']:>8.1f}x  >= 2x")
        tgt = ">= 5x" if r["frames"] == 42 else ""
        print(f"{r['model']:<20} {'regressor, all rows/cols':<28} {r['dynid_regressor_us']:>9.2f} "
              f"{r['pin_regressor_us']:>13.2f} {r['regressor_speedup']:>8.1f}x  {tgt}")
        if "restricted_speedup" in r:
            what = f"regressor, {r['restricted_shape'][0]} x {r['restricted_shape'][1]}"
            print(f"{r['model']:<20} {what:<28} {r['dynid_regressor_restricted_us']:>9.2f} "
                  f"{r['pin_regressor_us']:>13.2f} {r['restricted_speedup']:>8.1f}x  >= 20x")
    out = HERE / "results" / "numeric.json"
    out.parent.mkdir(exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps({"machine": os.uname().machine, "cpus": os.cpu_count(), "results": results}, indent=2))
    tmp.replace(out)
    print(f"\nwrote {out.relative_to(HERE.parent)}")


if __name__ == "__main__":
    main()
