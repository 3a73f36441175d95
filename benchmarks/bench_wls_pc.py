"""Physically consistent WLS on the real Stäubli TX40 data: the time of plain WLS and of wls-pc in the same run,
and their ratio (the target: wls-pc <= 10 s). Not a timed test: run it by hand,

    python benchmarks/bench_wls_pc.py

It times the estimator alone (the same conditioned, decimated rows for both) and the whole `identify` pipeline
(reading, conditioning, estimation and the physical-consistency verdict). Needs ../shared/data/tx40 and the pc
extra (pip install cvxpy clarabel)."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from dynid.estimation import wls
from dynid.estimation.physical import wls_pc
from dynid.pipeline.config import load_config
from dynid.pipeline.run import consistency_structure, identify

CONFIG = Path(__file__).resolve().parents[1] / "examples" / "tx40" / "identify.toml"


def _best(f, repeat: int = 7) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    cfg = load_config(CONFIG)
    run = identify(cfg)  # warms the caches (model, numba) and gives the rows
    s = run.identify
    names = list(run.base.names)
    structure = consistency_structure(run.model.tree, run.base)
    wls_pc(s.W, s.Y, s.groups, names, structure)  # imports cvxpy once, as a first call in a session would
    t_wls = _best(lambda: wls(s.W, s.Y, s.groups, names))
    t_pc = _best(lambda: wls_pc(s.W, s.Y, s.groups, names, structure))
    print(f"estimator, {s.W.shape[0]} rows x {len(names)} base parameters:")
    print(f"  WLS     {t_wls:8.3f} s")
    print(f"  wls-pc  {t_pc:8.3f} s   ratio {t_pc / t_wls:.1f}x")
    p_wls = _best(lambda: identify(cfg), 2)
    p_pc = _best(lambda: identify(dataclasses.replace(cfg, method="wls-pc")), 2)
    print("whole identify (read, condition, estimate, verdict):")
    print(f"  WLS     {p_wls:8.3f} s")
    verdict = "met" if p_pc <= 10 else "MISSED"
    print(f"  wls-pc  {p_pc:8.3f} s   ratio {p_pc / p_wls:.2f}x   (target <= 10 s: {verdict})")


if __name__ == "__main__":
    main()
